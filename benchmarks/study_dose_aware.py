"""Dose-aware views (issue 38, item 4): a synthetic procedure of 30 runs at LAO 30 / CRA 20 on the parametric patient.

Each run (20 frames, 80 kV, 0.3 mm Cu, 200 x 200 mm at the detector, the kerma model of carmkin.dose.plan) is
taken at the reachable view within 10° of the request that minimizes the predicted PSD given the runs before it
(carmkin.dose.dose_aware_procedure), moving from one to the next by certified motions. Prints the PSD with every
run at the request and with the chosen views, the reduction (acceptance: ≥ 30 %), the views chosen, and the
smallest clearance of the chosen configurations and of the certified motions.

Run: python benchmarks/study_dose_aware.py
"""

from __future__ import annotations

import collections
import time

import numpy as np

import carmkin
from carmkin import dose
from carmkin.patient import ParametricPatient
from carmkin.views import View, plan_view
from carmkin.views.plan import PATH_CLEARANCE, world_for
from carmkin.world import DEFAULT_MARGIN

RUNS, REQUEST, TOLERANCE_DEG, FRAMES = 30, (30.0, 20.0), 10.0, 20


def main() -> int:
    system = carmkin.load_preset("angio-floor")
    patient = ParametricPatient.on_table(system)
    top = system.table.top_center[1] - system.table.top_size[1] / 2
    view = View.from_angles(*REQUEST, [0.0, top - 0.12, 0.0], position=patient, name="LAO 30 CRA 20")
    start = time.perf_counter()
    q0 = plan_view(system, view, patient).q
    proc = dose.dose_aware_procedure(system, [view] * RUNS, patient, dose.Technique(frames=FRAMES),
                                     tolerance_deg=TOLERANCE_DEG, q_start=q0)
    elapsed = time.perf_counter() - start
    chosen = collections.Counter((round(c.primary_deg, 1), round(c.secondary_deg, 1)) for c in proc.choices)
    clearance = world_for(system, patient).clearance(np.array([c.q for c in proc.choices]))
    motion = min(c.motion.min_clearance for c in proc.choices)
    ok = (proc.reduction >= 0.30 and all(c.motion.success for c in proc.choices) and clearance.min() >= DEFAULT_MARGIN
          and motion >= PATH_CLEARANCE)
    print(f"{RUNS} runs of {FRAMES} frames at LAO {REQUEST[0]:g} / CRA {REQUEST[1]:g}, tolerance {TOLERANCE_DEG:g} deg, "
          f"angio-floor, parametric patient ({elapsed:.1f} s)")
    print(f"PSD every run at the request: {proc.psd_requested_gy * 1e3:.1f} mGy; dose-aware: "
          f"{proc.psd_chosen_gy * 1e3:.1f} mGy; reduction {proc.reduction * 100:.1f} % (acceptance >= 30 %)")
    best = max(chosen, key=chosen.get)
    q_best = next(c.q for c in proc.choices if (round(c.primary_deg, 1), round(c.secondary_deg, 1)) == best)
    single = dose.plan_dose(system, [q_best] * RUNS, patient, dose.Technique(frames=FRAMES)).map.psd_gy
    print(f"of which the thinner path: every run at the most chosen view {best}: {single * 1e3:.1f} mGy "
          f"({(1 - single / proc.psd_requested_gy) * 100:.1f} %); the rest is the spread of the entrance fields")
    print("views chosen (primary, secondary deg: runs): "
          + ", ".join(f"({p:g}, {s:g}): {n}" for (p, s), n in chosen.most_common()))
    print(f"largest angle from the request {max(c.angle_deg for c in proc.choices):.2f} deg; smallest clearance of the "
          f"chosen views {clearance.min() * 1e3:.1f} mm (margin {DEFAULT_MARGIN * 1e3:g}); of the certified motions "
          f"{motion * 1e3:.1f} mm (kept {PATH_CLEARANCE * 1e3:g}); all motions found: "
          f"{all(c.motion.success for c in proc.choices)}")
    print("PASS" if ok else "FAIL")
    return 0 if ok else 1


if __name__ == "__main__":
    raise SystemExit(main())
