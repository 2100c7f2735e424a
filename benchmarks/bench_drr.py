"""DRR rendering time (nanodrr on torch) on the bundled chest CT at the preset's detector binned to several
sizes, CPU and (when torch sees one) GPU, with the ratio to the smallest size on the same device in the same
run. Skips (exit 0) without torch, nanodrr or the CT.

Run: python benchmarks/bench_drr.py [--quick]
"""

from __future__ import annotations

import argparse
import statistics
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))
from _timing import row  # noqa: E402

import carmkin  # noqa: E402


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--quick", action="store_true", help="one small size, few repetitions (CI)")
    args = parser.parse_args()
    try:
        import torch  # noqa: F401

        from carmkin.interop import drr

        volume = drr.load_ct()
    except (ImportError, carmkin.CarmkinError) as exc:
        print(f"skipped: {exc}")
        return 0
    system = carmkin.load_preset("siremobile-iso-c3d")
    q = np.where(system.prismatic, 0.5 * (system.lower + system.upper), 0.0)
    T = system.fk(q)
    T_table_ct = volume.in_table("HFS", T[:3, 3] + system.carm.orbital_offset * T[:3, 2])
    scales = (0.25,) if args.quick else (0.25, 0.5, 1.0)
    repeat = 2 if args.quick else 5
    devices = ["cpu"] + (["cuda"] if torch.cuda.is_available() else [])
    print(f"torch {torch.__version__}, {torch.get_num_threads()} CPU threads; CT {volume.hu.shape} voxels; "
          "400 samples per ray")
    for device in devices:
        baseline = None
        for scale in scales:
            renderer = drr.Renderer(system, volume, T_table_ct, scale, 400, device)
            renderer.render(T)  # warm-up (kernel compilation, caches)
            renderer.seconds.clear()
            for _ in range(repeat):
                renderer.render(T)
            seconds = statistics.median(renderer.seconds)
            baseline = baseline or seconds
            label = f"DRR {renderer.size[0]}x{renderer.size[1]} on {device}"
            print(row(label, seconds, baseline if scale != scales[0] else None, unit="ms"))
    return 0


if __name__ == "__main__":
    sys.exit(main())
