"""Views the search calls unreachable, checked by brute force (issue 31): is any of them feasible?

For 5° reach maps (primary −90…90°, secondary −45…45°) of the Iso-C 3D with ``ParametricPatient.on_table``
at two targets and of the motorized preset (table held at mid-range, as ``reach_map`` holds it), every cell
``reach_map`` calls unreachable is given to the oracle of ``tests/views/bruteforce.py`` (the pose IK over a
fine (distance, roll) grid, the singular family over its wigwag, then a local maximisation of the clearance;
none of the search's code).
A view it finds feasible is a miss of the search; the oracle's configuration is confirmed by
``carmkin.robot.validity.check`` at the margin (``reachable``: joints in range and no pair closer than the
margin; the views do not ask for the table in the X-ray cone).

Before the oracle, each map is also searched without the polish between the samples
(``carmkin.views.polish``, ``WINDOW`` < 0): the cells only the polish reaches are the sampled search's misses,
each confirmed by ``validity.check``.

    python benchmarks/bruteforce_views.py            # ≥ 300 unreachable views (5° maps)
    python benchmarks/bruteforce_views.py --quick    # 10° maps, one per preset
Prints "N unreachable views, M feasible by brute force" and exits 1 when M > 0.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

import carmkin
from carmkin.patient import ParametricPatient
from carmkin.robot.validity import check
from carmkin.views import polish, reach_map
from carmkin.views.plan import world_for

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests" / "views"))

import bruteforce  # noqa: E402

#: (preset, target (m, table frame)) of the maps.
MAPS = (
    ("siremobile-iso-c3d", (0.0, 0.0, 0.0)),
    ("siremobile-iso-c3d", (0.05, 0.05, 0.15)),
    ("siremobile-iso-c3d-motorized-table", (0.0, 0.0, 0.0)),
)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="10° maps, one per preset")
    parser.add_argument("--step", type=float, default=None, help="map step (deg; default 5, --quick 10)")
    parser.add_argument("--maps", default=None, help="indices into MAPS, comma-separated (default: all; --quick 0,2)")
    args = parser.parse_args(argv)
    step = args.step or (10.0 if args.quick else 5.0)
    chosen = args.maps or ("0,2" if args.quick else ",".join(str(i) for i in range(len(MAPS))))
    maps = [MAPS[int(i)] for i in chosen.split(",")]
    margin = carmkin.DEFAULT_MARGIN
    total, misses, rescued, start = 0, [], 0, time.perf_counter()
    for preset, target in maps:
        system = carmkin.load_preset(preset)
        patient = ParametricPatient.on_table(system)
        world = world_for(system, patient)
        grid = (np.arange(-90, 90.1, step), np.arange(-45, 45.1, step))
        window, polish.WINDOW = polish.WINDOW, -1.0
        try:
            sampled = reach_map(system, target, *grid, patient, margin=margin)
        finally:
            polish.WINDOW = window
        m = reach_map(system, target, *grid, patient, margin=margin)
        assert not np.any(sampled.reachable & ~m.reachable)
        for i, j in zip(*np.nonzero(m.reachable & ~sampled.reachable)):
            report = check(system, m.q[i, j], patient.obstacles(), margin=margin)
            rescued += 1
            print(f"sampled search missed {preset} target {target} view "
                  f"({m.primary_deg[i]:g}°, {m.secondary_deg[j]:g}°): the polish reaches it at "
                  f"{m.clearance[i, j] * 1e3:.2f} mm, validity.check "
                  f"{'agrees' if report.reachable else 'DISAGREES'}", flush=True)
        cells = list(zip(*np.nonzero(~m.reachable)))
        found = 0
        for i, j in cells:
            verdict = bruteforce.brute(system, world, target, m.directions[i, j], margin)
            if verdict.q is not None:
                report = check(system, verdict.q, patient.obstacles(), margin=margin)
                found += 1
                misses.append((preset, target, m.primary_deg[i], m.secondary_deg[j]))
                print(f"MISS {preset} target {target} view ({m.primary_deg[i]:g}°, {m.secondary_deg[j]:g}°) "
                      f"({m.binding[i, j]}): clearance {verdict.clearance * 1e3:.2f} mm, validity.check "
                      f"{'agrees' if report.reachable else 'DISAGREES'}; "
                      f"q = {np.array2string(verdict.q, precision=17, max_line_width=400)}", flush=True)
        total += len(cells)
        print(f"{preset} target {target}: {len(cells)} of {m.reachable.size} cells unreachable, {found} feasible",
              flush=True)
    print(f"without the polish the sampled search missed {rescued} valid views of these maps (the polish reaches them)")
    print(f"{total} unreachable views, {len(misses)} feasible by brute force "
          f"(margin {margin * 1e3:g} mm, {time.perf_counter() - start:.0f} s)")
    return 1 if misses else 0


if __name__ == "__main__":
    sys.exit(main())
