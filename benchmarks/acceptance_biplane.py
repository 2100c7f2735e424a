"""The acceptance rows of a biplane preset (issue 30), printed one per line:

1. FK of each plane against Pinocchio over 10 000 biplane configurations (uniform in the joint ranges): the
   largest difference of any entry of the source pose (m for the translation) — the bound is 1e-12;
2. every standard view planned as the frontal view with the lateral at 90° (:func:`carmkin.biplane.lateral_view`),
   with a parametric patient on the table (``ParametricPatient.on_table``, 1.75 m, 75 kg, HFS): planned with the
   clearance between the planes, or the typed reason;
3. the planes' clearance at rest (the nearest pair named).

    python benchmarks/acceptance_biplane.py [--preset angio-biplane]
Exits 1 when a row fails its bound (FK above 1e-12, or planes not clear at rest).
"""

from __future__ import annotations

import argparse
import sys

import numpy as np
import pinocchio as pin

from carmkin.biplane import BiplaneWorld, load_biplane, plan_biplane
from carmkin.patient import ParametricPatient
from carmkin.views.standard import STANDARD_VIEWS

#: The acceptance bound of FK against Pinocchio (m, and rotation entries).
FK_BOUND = 1e-12


def fk_row(biplane, samples: int = 10_000, seed: int = 30) -> float:
    rng = np.random.default_rng(seed)
    Q = biplane.lower + rng.random((samples, biplane.nq)) * (biplane.upper - biplane.lower)
    T = biplane.fk(Q)
    worst = 0.0
    for index, system in enumerate((biplane.frontal, biplane.lateral)):
        model, _, _ = system.pinocchio()
        data, frame = model.createData(), model.getFrameId("xray_source")
        for q, pose in zip(biplane.planes_q(Q)[index], T[:, index]):
            pin.framesForwardKinematics(model, data, q)
            worst = max(worst, float(np.abs(data.oMf[frame].homogeneous - pose).max()))
    return worst


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--preset", default="angio-biplane")
    parser.add_argument("--quick", action="store_true", help="accepted for benchmarks/run_all.py; the run is short")
    args = parser.parse_args(argv)
    biplane = load_biplane(args.preset)
    worst = fk_row(biplane)
    print(f"{biplane.name}: FK of both planes vs Pinocchio over 10000 configurations: max |difference| {worst:.2e} "
          f"({'PASS' if worst <= FK_BOUND else 'FAIL'}, bound {FK_BOUND:g})")
    patient = ParametricPatient.on_table(biplane.frontal)
    planned = 0
    for name in STANDARD_VIEWS:
        plan = plan_biplane(biplane, name, 90.0, patient=patient)
        planned += plan.success
        if plan.success:
            print(f"  {name:20s} planned, lateral at {np.degrees(plan.angle):.2f}°, planes {plan.clearance * 1e3:.1f} mm "
                  f"apart ({plan.pair[0]} - {plan.pair[1]})")
        else:
            print(f"  {name:20s} {plan.failure.name}: {plan.reason}")
    print(f"{biplane.name}: {planned} of {len(STANDARD_VIEWS)} standard views planned with a lateral at 90° and a "
          "parametric patient (the others with their reason)")
    rest = BiplaneWorld(biplane).clearance(np.array(biplane.rest))
    print(f"{biplane.name}: planes at rest {rest.planes * 1e3:.1f} mm apart ({rest.pair[0]} - {rest.pair[1]}), "
          f"{'PASS' if rest.planes > 0 else 'FAIL'}")
    return 0 if worst <= FK_BOUND and rest.planes > 0 else 1


if __name__ == "__main__":
    sys.exit(main())
