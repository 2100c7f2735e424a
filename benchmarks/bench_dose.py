"""Skin dose (issue 38): a 50-event procedure on the parametric patient at 5 mm skin resolution.

Times ``carmkin.dose.skin_dose`` on angio-floor: 50 events (AP, LAO/RAO, CRA/CAU views, 80 kV, 0.3 mm Cu, a
200 x 200 mm field) on the parametric patient sampled every 5 mm, the skin sampled once (the cells given as a
``Skin``) and sampled in the call; printed beside the issue's bound (1 s on the developers' machine) as a
ratio, and beside one forward kinematics per event (the floor of any per-event geometry). Then the same 50 views as
a *plan* (``carmkin.dose.plan_dose``: the kerma of each predicted from the water-equivalent thickness of its central
ray), printed as a ratio to the baseline measured in the same run: the map of the same events with their kerma
given (``skin_dose``, the cells given) — the plan's overhead is the kerma model.

Run: python benchmarks/bench_dose.py [--quick]
"""

from __future__ import annotations

import argparse
import time

import numpy as np
from _timing import median_time, row

import carmkin
from carmkin import dose
from carmkin.patient import ParametricPatient

#: The issue's bound (s) for a 50-event map at 5 mm.
BOUND_S = 1.0
SPACING = 0.005


def events(system, n: int = 50) -> list:
    angular, orbital = system.joint_names.index("angular"), system.joint_names.index("orbital")
    out = []
    for i in range(n):
        q = np.zeros(system.nq)
        q[angular] = np.radians(-40.0 + 80.0 * (i % 5) / 4)
        q[orbital] = np.radians(-25.0 + 50.0 * (i // 5 % 3) / 2)
        out.append(dose.Event(q, kvp=80.0, k_irp_gy=0.01, field_mm=(200.0, 200.0), filter={"Cu": 0.3}, name=str(i)))
    return out


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="3 repeats instead of 7")
    repeat = 3 if parser.parse_args().quick else 7
    system = carmkin.load_preset("angio-floor")
    patient = ParametricPatient.on_table(system, chest_z=-0.1)
    ev = events(system)
    skin = dose.from_patient(patient, SPACING)
    dose.skin_dose(system, ev[:1], skin)  # warm: scipy, the tables
    start = time.perf_counter()
    sampled = median_time(lambda: dose.skin_dose(system, ev, patient, spacing=SPACING), repeat=repeat)
    given = median_time(lambda: dose.skin_dose(system, ev, skin), repeat=repeat)
    fk = median_time(lambda: [system.fk(np.asarray(e.q)) for e in ev], repeat=repeat)
    plan = [np.asarray(e.q) for e in ev]
    technique = dose.Technique(kvp=80.0, frames=10, filter={"Cu": 0.3}, field_mm=(200.0, 200.0))
    planned = median_time(lambda: dose.plan_dose(system, plan, patient, technique, skin=skin), repeat=repeat)
    planned_sampled = median_time(lambda: dose.plan_dose(system, plan, patient, technique, spacing=SPACING),
                                  repeat=repeat)
    m = dose.skin_dose(system, ev, skin)
    print(f"{len(ev)} events, {len(skin.points)} skin cells at {SPACING * 1e3:g} mm; PSD {m.psd_gy * 1e3:.1f} mGy, "
          f"overlap up to {m.overlap.max()} ({time.perf_counter() - start:.1f} s in all)")
    print(row("skin_dose, the skin sampled in the call", sampled, BOUND_S, unit="ms"))
    print(row("skin_dose, the cells given (Skin)", given, BOUND_S, unit="ms"))
    print(row("system.fk of the 50 events (floor)", fk, BOUND_S, unit="ms"))
    print(row("plan_dose, 50 planned views, the cells given", planned, given, unit="ms"))
    print(row("plan_dose, the skin sampled in the call", planned_sampled, given, unit="ms"))
    print(f"the 50-view plan's map at 5 mm: {planned_sampled:.3f} s, {planned_sampled / given:.2f} x the map of the same "
          f"events with their kerma given (baseline of this run); bound {BOUND_S:g} s")
    ok = sampled <= BOUND_S and planned_sampled <= BOUND_S
    print(f"{'PASS' if ok else 'FAIL'}: 50 events at 5 mm in {sampled:.3f} s, planned in {planned_sampled:.3f} s "
          f"(bound {BOUND_S:g} s)")
    return 0 if ok else 1


if __name__ == "__main__":
    raise SystemExit(main())
