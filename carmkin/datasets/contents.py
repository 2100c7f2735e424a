"""What a dataset folder holds: its spec (``_dataset.json``), the shards there whole and missing, rows, the
image shape and columns, and the priors' rejection reports summed over the shards."""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

from carmkin.errors import DatasetError
from carmkin.extras import require

from .priors import MIN_ROUND
from .shards import MANIFEST


@dataclass(frozen=True)
class DatasetInfo:
    """``manifest`` (the spec as JSON), ``shards`` expected, ``done`` (indices there whole), ``missing``,
    ``rows`` written, ``image_shape`` (rows, columns), ``columns`` (name: Arrow type), ``proposed`` and
    ``accepted`` poses summed over the shards' rejection reports, ``reasons`` summed, ``empty`` the all-zero
    images (the beam missed the CT) summed over the shards, ``used_parameters`` the prior's parameters as the
    first shard there used them (defaults filled in)."""

    out: str
    manifest: dict
    shards: int
    done: tuple
    missing: tuple
    rows: int
    image_shape: tuple | None
    columns: dict
    proposed: int
    accepted: int
    reasons: dict
    empty: int = 0
    used_parameters: dict | None = None

    def lines(self) -> list[str]:
        m = self.manifest
        out = [f"dataset {self.out}: prior {m['prior']} on {m['preset']}, seed {m['seed']}, "
               f"{m['size'][0]}x{m['size'][1]} px, device {m['device']}",
               f"rows {self.rows} of {m['n']}; shards {len(self.done)} of {self.shards} done"
               + (f" (missing: {', '.join(map(str, self.missing[:10]))}{' ...' if len(self.missing) > 10 else ''})"
                  if self.missing else ""),
               "parameters given: " + (", ".join(f"{k} {json.dumps(v)}" for k, v in sorted(m["parameters"].items()))
                                       or "none (the prior's defaults)")]
        if self.used_parameters:
            out.append("parameters used: " + ", ".join(f"{k} {json.dumps(v)}" for k, v in self.used_parameters.items()
                                                       if k != "sd_source"))
        if self.proposed:
            rejected = ", ".join(f"{k} {v}" for k, v in sorted(self.reasons.items())) or "none"
            out.append(f"proposals: {self.accepted} of {self.proposed} feasible ({self.accepted / self.proposed:.1%}), "
                       f"{self.rows} of them used (each shard proposes in rounds of at least {MIN_ROUND}; the "
                       f"feasible ones beyond its rows are left unused); rejected: {rejected}")
        if self.rows:
            out.append(f"empty images (all zero: the beam misses the CT) {self.empty} of {self.rows}")
        if self.image_shape:
            out.append(f"image {self.image_shape[0]}x{self.image_shape[1]} (rows x columns) float32, row-major")
        out.append("columns " + ", ".join(f"{k} {v}" for k, v in self.columns.items()))
        return out


def info(out) -> DatasetInfo:
    """The :class:`DatasetInfo` of the dataset folder ``out``, or :class:`DatasetError` when it holds none."""
    from .shards import METADATA_KEY

    pq = require("pyarrow.parquet", "datasets")
    folder = Path(out)
    path = folder / MANIFEST
    if not folder.is_dir():
        raise DatasetError(f"{str(folder)!r}: no such folder")
    if not path.is_file():
        raise DatasetError(f"{str(folder)!r} holds no dataset (no {MANIFEST})")
    try:
        manifest = json.loads(path.read_text())
        n, size = int(manifest["n"]), int(manifest["shard_size"])
    except (OSError, ValueError, KeyError) as exc:
        raise DatasetError(f"{str(path)!r} is not a carmkin dataset manifest ({exc})") from None
    shards = -(-n // size)
    done, missing, rows, shape, columns, proposed, accepted, reasons, empty = [], [], 0, None, {}, 0, 0, {}, 0
    used = None
    for k in range(shards):
        shard = folder / f"shard-{k:05d}-of-{shards:05d}.parquet"
        expected = min(size, n - k * size)
        try:
            meta = pq.read_metadata(shard)
            schema = pq.read_schema(shard)
        except (OSError, ValueError):
            missing.append(k)
            continue
        if meta.num_rows != expected or METADATA_KEY not in (schema.metadata or {}):
            missing.append(k)
            continue
        done.append(k)
        rows += meta.num_rows
        extra = json.loads(schema.metadata[METADATA_KEY])
        shape = tuple(extra["image_shape"])
        columns = {f.name: str(f.type) for f in schema}
        report = extra["rejections"]
        if used is None:
            used = extra.get("provenance", {}).get("parameters")
        empty += extra.get("empty_images", {}).get("count", 0)
        proposed, accepted = proposed + report["proposed"], accepted + report["accepted"]
        for key, count in report["reasons"].items():
            reasons[key] = reasons.get(key, 0) + count
    return DatasetInfo(str(folder), manifest, shards, tuple(done), tuple(missing), rows, shape, columns, proposed,
                       accepted, reasons, empty, used)
