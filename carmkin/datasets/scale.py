"""Making a dataset: every input checked before any work, then the shards still missing made by Ray tasks
(each samples, renders and writes one shard) or in this process, with a progress bar (images/s) on stderr.

Ray: ``ray.init()`` in this process by default (a local cluster of this machine's cores, or ``num_cpus``);
``address`` (or the ``RAY_ADDRESS`` environment variable) joins a running cluster — its workers write the
shards, so ``out`` must be a folder they all see. A task asks for one CPU, and one GPU when ``device`` is
``"cuda"`` (one renderer per GPU).
"""

from __future__ import annotations

import os
import sys
import time
from dataclasses import dataclass

from carmkin.errors import DatasetError
from carmkin.extras import require

from .shards import Spec, make_and_write, prepare

EXECUTORS = ("ray", "local")


@dataclass(frozen=True)
class Summary:
    """What a run did: shards made and skipped, images written, seconds, and the folder."""

    out: str
    made: int
    skipped: int
    images: int
    seconds: float

    @property
    def images_per_second(self) -> float:
        return self.images / self.seconds if self.seconds > 0 else 0.0


def check(spec: Spec) -> Spec:
    """The spec's inputs checked (prior and its parameters, n, size, device, extras), before any work."""
    from carmkin.robot.validity import require_system
    from carmkin.validation import integer

    from . import priors
    from .render import binning, check_device, parse_size

    require_system(spec.system, DatasetError)
    priors.check_prior(spec.prior)
    priors.check_parameters(spec.prior, spec.parameters)
    integer(spec.n, "n", low=1, error=DatasetError)
    integer(spec.seed, "seed", low=0, error=DatasetError)
    integer(spec.shard_size, "shard_size", low=1, error=DatasetError)
    integer(spec.n_samples, "n_samples", low=1, high=100_000, error=DatasetError)
    priors.check_whole_groups(spec.prior, spec.parameters, spec.n, spec.shard_size)
    size = parse_size(spec.size)
    binning(spec.system, size)
    for module, extra in (("pyarrow", "datasets"), ("torch", "drr"), ("nanodrr", "drr"), ("nibabel", "drr")):
        require(module, extra)
    check_device(spec.device)
    if spec.volume is None:
        from carmkin.interop.drr import bundled_ct_path

        bundled_ct_path()
    elif not os.path.exists(spec.volume):
        raise DatasetError(f"volume {spec.volume!r} does not exist (a NIfTI CT)")
    import dataclasses

    return dataclasses.replace(spec, size=size)


def generate(spec: Spec, out, *, executor: str = "ray", address: str | None = None, num_cpus: int | None = None,
             progress: bool = True) -> Summary:
    """Make the dataset of ``spec`` in ``out`` (resuming: shards already there whole are skipped)."""
    if executor not in EXECUTORS:
        raise DatasetError(f"executor must be one of {', '.join(EXECUTORS)}, got {executor!r}")
    spec = check(spec)
    if executor == "ray":
        require("ray", "datasets")
    todo = prepare(out, spec)
    skipped = spec.shards - len(todo)
    from tqdm import tqdm
    bar = tqdm(total=sum(spec.rows(k)[1] for k in todo), unit="img", file=sys.stderr, disable=not progress,
               desc="dataset", smoothing=0.1)
    start, images = time.perf_counter(), 0
    try:
        runs = _ray(spec, out, todo, address, num_cpus) if executor == "ray" else (
            make_and_write(out, spec, k) for k in todo)
        for rows in runs:
            images += rows
            bar.update(rows)
    finally:
        bar.close()
    return Summary(str(out), len(todo), skipped, images, time.perf_counter() - start)


def _ray(spec: Spec, out, todo, address, num_cpus):
    """Row counts of the shards ``todo`` as Ray tasks finish them."""
    ray = require("ray", "datasets")
    started = not ray.is_initialized()
    if started:
        address = address or os.environ.get("RAY_ADDRESS") or None
        ray.init(address=address, num_cpus=None if address else num_cpus, include_dashboard=False,
                 log_to_driver=False, configure_logging=False)
    try:
        task = ray.remote(num_cpus=1, num_gpus=1 if spec.device == "cuda" else 0)(make_and_write)
        pending = [task.remote(str(out), spec, k) for k in todo]
        while pending:
            done, pending = ray.wait(pending, num_returns=1)
            yield ray.get(done[0])
    finally:
        if started:
            ray.shutdown()
