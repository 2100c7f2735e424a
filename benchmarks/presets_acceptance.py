"""Issue 30's acceptance for every built-in preset, one row each (carmkin.studies.acceptance does the work):

- FK vs Pinocchio: worst error (m or rad) of every frame over 10 000 random configurations (--quick: 2 000);
- views: the 16 named standard views through the isocentre planned with a parametric patient (1.75 m, 75 kg,
  HFS, on the table top), and the reason of each one unreachable printed below the table;
- map: the reach map of the isocentre, 91 × 46 cells (primary −90…90°, secondary −45…45° at 2°; --quick:
  37 × 19 at 5°) with that patient: its reachable fraction, and its time in one process with the ratio to the
  time of ``siremobile-iso-c3d`` measured in the same run (the baseline);
- sweep: the family's cone-beam CT orbit with that patient (mobile: 190° orbital; angiography: 200° propeller,
  the angular joint), 100 frames (--quick: 30), its swept clearance certified over the whole arc;
- DICOM: XA angles → joints (the view planned) → XA angles on 50 in-range configurations (--quick: 10), the
  worst difference (deg);
- viewer: the meshcat page built offline, every visual body of the URDF drawn.

    python benchmarks/presets_acceptance.py            # the full sizes
    python benchmarks/presets_acceptance.py --quick    # small sizes (benchmarks/run_all.py --quick)

Exit status 1 when a preset misses an acceptance bound (FK above 1e-12, a sweep not certified, a round
trip above 1e-9°, a body missing from the page).
"""

from __future__ import annotations

import argparse
import sys

import numpy as np

import carmkin
from carmkin.studies import acceptance
from carmkin.viz import CArmViewer

from _timing import row

#: The acceptance bounds: FK vs Pinocchio (m or rad) and the DICOM round trip (deg).
FK_BOUND = 1e-12
ROUND_TRIP_BOUND_DEG = 1e-9
#: The preset whose map time is the baseline of the ratios.
BASELINE = "siremobile-iso-c3d"


def missing_bodies(system) -> list[str]:
    """The visual bodies of ``system``'s URDF that the offline viewer's scene does not draw."""
    viewer = CArmViewer(system)
    assert "new MeshCat.Viewer" in viewer.static_html()
    node = viewer.vis.window.tree
    for part in ("meshcat", "carmkin", "robot", "visuals"):
        node = node[part]
    drawn = {name for name, child in node.items() if child.object is not None}
    return sorted({g.name for g in system.pinocchio()[2].geometryObjects} - drawn)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="small sizes (a few seconds per preset)")
    args = parser.parse_args()
    samples, views, trips = (2_000, 30, 10) if args.quick else (10_000, 100, 50)
    primary, secondary = ((np.arange(-90, 91, 5), np.arange(-45, 46, 5)) if args.quick
                          else (acceptance.PRIMARY_DEG, acceptance.SECONDARY_DEG))
    names = carmkin.list_presets()
    names = [BASELINE] + [n for n in names if n != BASELINE]
    header = (f"{'preset':<36}{'family':<12}{'nq':>3}  {'FK vs pin':>9}  {'views':>5}  "
              f"{'map ' + str(len(primary)) + 'x' + str(len(secondary)):>10}  {'sweep':>14}  {'DICOM (deg)':>11}  viewer")
    print(header)
    status, reasons, times = 0, {}, {}
    for name in names:
        system = carmkin.load_preset(name)
        patient = acceptance.patient_on(system)
        fk = acceptance.fk_agreement(system, samples)
        planned = acceptance.standard_views(system, patient)
        reach = acceptance.reach(system, patient, primary, secondary)
        sweep = acceptance.cbct_sweep(system, patient, views)
        trip = acceptance.dicom_round_trip(system, trips)
        missing = missing_bodies(system)
        joint = acceptance.cbct_joint(system)
        times[name] = reach.seconds
        reasons[name] = planned.unreachable()
        certified = sweep.success and sweep.min_clearance >= sweep.margin
        sweep_text = (f"{acceptance.ARC_DEG[joint]:.0f}° {sweep.min_clearance * 1e3:5.1f} mm" if certified
                      else f"{acceptance.ARC_DEG[joint]:.0f}° FAILED")
        print(f"{name:<36}{acceptance.family(system):<12}{system.nq:>3}  {fk:9.2e}  {planned.planned:>2}/{len(planned.plans):<2}  "
              f"{reach.map.fraction * 100:9.1f}%  {sweep_text:>14}  {trip.worst_deg:11.1e}  "
              f"{'all ' + str(len(system.pinocchio()[2].geometryObjects)) if not missing else 'MISSING ' + ','.join(missing)}",
              flush=True)
        if fk > FK_BOUND or not certified or trip.worst_deg > ROUND_TRIP_BOUND_DEG or trip.planned < trip.count or missing:
            status = 1
    for name in names:
        for view, reason in reasons[name].items():
            print(f"  {name}: {view} unreachable: {reason}")
    print(f"\nreach map of the isocentre, {len(primary)} x {len(secondary)} cells, one process, parametric patient:")
    for name in names:
        print(row(f"  {name}", times[name], times[BASELINE], unit="s"))
    return status


if __name__ == "__main__":
    sys.exit(main())
