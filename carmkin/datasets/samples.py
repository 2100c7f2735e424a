"""Pose samples: the configurations a prior drew, their geometry (source pose, P, XA angles, clearance), their
provenance and the prior's rejection report; and the check every sample passes before it is returned.

Frames and units: q (n, nq) in m and rad (the system's joint order); ``source_pose`` (n, 4, 4) the pose of the
``xray_source`` frame in the table frame 0 (m); ``P`` (n, 3, 4) = K [Rᵀ | −Rᵀ p] takes table-frame points (m)
to pixels of the full detector (pixel centres at integers); ``primary_deg`` / ``secondary_deg`` the XA
Positioner Primary (LAO +) and Secondary (CRA +) Angles of the beam for the patient (DICOM PS3.3
C.8.7.5.1.2); ``clearance_m`` the exact minimum signed distance (m) over the pairs validity checks (every
moving C-arm part against the table, the floor and the patient).
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field

import numpy as np

from carmkin.errors import DatasetError
from carmkin.model.params import JOINT_RANGE_TOLERANCE
from carmkin.world.tolerances import DEFAULT_MARGIN

#: P of a sample equals K [R | t] of FK(q) to this relative error (Frobenius, over P's scale).
P_RELATIVE_TOLERANCE = 1e-12


def clearance(system, patient, Q) -> np.ndarray:
    """Exact minimum signed distance (n,) (m) of configurations ``Q`` (n, nq) over the collision pairs of
    ``system`` with ``patient`` (the pairs of :func:`carmkin.robot.validity.check`): the one collision world's
    :meth:`carmkin.world.World.clearance`, the world cached per system and patient as the views keep it."""
    from carmkin.views.plan import world_for

    Q = np.asarray(Q, dtype=float).reshape(-1, system.nq)
    if not len(Q):
        return np.zeros(0)
    return world_for(system, patient).clearance(Q)


def projection_matrices(K, T) -> np.ndarray:
    """P (n, 3, 4) = K [Rᵀ | −Rᵀ p] for source poses T (n, 4, 4) and intrinsics K (3, 3) or, calibrated, one
    per view (n, 3, 3) (batched :func:`carmkin.imaging.projection.projection_from_pose`)."""
    R, p = T[:, :3, :3], T[:, :3, 3]
    Rt = np.transpose(R, (0, 2, 1))
    return K @ np.concatenate((Rt, -np.einsum("nij,nj->ni", Rt, p)[:, :, None]), axis=2)


def xa_angles(T, patient_pose) -> tuple[np.ndarray, np.ndarray]:
    """XA (primary, secondary) (deg, arrays (n,)) of source poses T (n, 4, 4) for a patient whose LPS frame
    has the pose ``patient_pose`` (4, 4) in the table frame: the beam in LPS is (sin p cos s, −cos p cos s,
    sin s) (the batched :func:`carmkin.interop.dicom.xa_angles`, same gimbal rule: primary 0 at s = ±90°)."""
    d = T[:, :3, 2] @ np.asarray(patient_pose)[:3, :3]
    secondary = np.degrees(np.arcsin(np.clip(d[:, 2], -1.0, 1.0)))
    horizontal = np.hypot(d[:, 0], d[:, 1])
    with np.errstate(invalid="ignore"):
        primary = np.where(horizontal > 1e-12, np.degrees(np.arctan2(d[:, 0], -d[:, 1])), 0.0)
    return primary, secondary


def patient_frame(patient) -> np.ndarray:
    """Pose (4, 4) of the patient's LPS frame in the table frame: the model's, else HFS at the origin."""
    from carmkin.imaging.projection import patient_pose

    pose = getattr(patient, "pose", None)
    return pose() if callable(pose) else patient_pose("HFS")


def describe_patient(patient) -> dict:
    """The patient as provenance (JSON values): the model's fields, or the obstacles' names and shapes."""
    import dataclasses

    if patient is None:
        return {"model": None}
    if dataclasses.is_dataclass(patient):
        fields = {f.name: getattr(patient, f.name) for f in dataclasses.fields(patient) if f.init}
        return {"model": type(patient).__name__, **json.loads(json.dumps(fields, default=str))}
    return {"model": "obstacles", "obstacles": [{"name": o.name, "shape": o.shape, "size": list(o.size),
                                                 "pose": np.asarray(o.pose).ravel().tolist()} for o in patient]}


@dataclass(frozen=True)
class Rejections:
    """What a prior proposed and kept: ``proposed``, ``accepted`` counts, ``reasons`` {binding: count} of
    the rejected (a joint group, ``"contact"``, ``"sweep failed"``), ``groups`` {group: (proposed, accepted)}
    (per standard view, per sweep ...), ``notes`` (sentences, e.g. the views no configuration reaches) and
    ``statistics`` {group: ...}: how the feasibility cut changes the drawn angles (standard views)."""

    proposed: int
    accepted: int
    reasons: dict = field(default_factory=dict)
    groups: dict = field(default_factory=dict)
    notes: tuple = ()
    statistics: dict = field(default_factory=dict)

    @property
    def fraction(self) -> float:
        """Share of the proposals accepted."""
        return self.accepted / self.proposed if self.proposed else 0.0

    def as_dict(self) -> dict:
        return {"proposed": self.proposed, "accepted": self.accepted, "fraction": self.fraction,
                "reasons": dict(self.reasons), "groups": {k: list(v) for k, v in self.groups.items()},
                "notes": list(self.notes), "statistics": self.statistics}


@dataclass(frozen=True)
class PoseSamples:
    """n feasible poses of a prior (see the module docstring for frames and units). ``labels`` (n,) the
    group each sample came from (a standard view's name, a sweep's index, "" for none); ``nominal`` (n, 2)
    the proposed (primary, secondary) (deg; NaN where the prior proposes joints); ``provenance`` (JSON
    values); ``rejections`` the prior's :class:`Rejections`; ``size`` (columns, rows) of the detector P is
    for."""

    q: np.ndarray
    source_pose: np.ndarray
    P: np.ndarray
    primary_deg: np.ndarray
    secondary_deg: np.ndarray
    clearance_m: np.ndarray
    labels: np.ndarray
    nominal: np.ndarray
    provenance: dict
    rejections: Rejections
    size: tuple

    def __len__(self) -> int:
        return len(self.q)


def build(system, patient, Q, labels, nominal, provenance: dict, rejections: Rejections,
          margin: float) -> PoseSamples:
    """The samples of configurations ``Q`` (n, nq) with their geometry, checked (:func:`check`)."""
    from carmkin.imaging.projection import intrinsics, view_intrinsics

    Q = np.asarray(Q, dtype=float).reshape(-1, system.nq)
    _, size = intrinsics(system)
    T = system.fk(Q) if len(Q) else np.zeros((0, 4, 4))
    primary, secondary = xa_angles(T, patient_frame(patient))
    samples = PoseSamples(Q, T, projection_matrices(view_intrinsics(system, Q), T), primary, secondary, clearance(system, patient, Q),
                          np.asarray(labels, dtype=object), np.asarray(nominal, dtype=float).reshape(-1, 2),
                          provenance, rejections, size)
    check(system, samples, margin)
    return samples


def check(system, samples: PoseSamples, margin: float) -> None:
    """Every sample in its joint ranges (± :data:`JOINT_RANGE_TOLERANCE`), its P equal to K [R | t] of its
    source pose by the scalar route (:data:`P_RELATIVE_TOLERANCE`), with ``clearance_m`` ≥ ``margin`` and
    finite, or :class:`DatasetError` naming the first that is not (never expected: priors sample feasible
    poses by construction; this is the check after it)."""
    Q = samples.q
    outside = (Q < system.lower - JOINT_RANGE_TOLERANCE) | (Q > system.upper + JOINT_RANGE_TOLERANCE) | ~np.isfinite(Q)
    if outside.any():
        i, k = map(int, np.argwhere(outside)[0])
        raise DatasetError(f"sample {i}: {system.joint_names[k]} = {Q[i, k]:g} outside its range "
                           f"[{system.lower[k]:g}, {system.upper[k]:g}] (m or rad)")
    from carmkin.imaging.projection import view_intrinsics

    # P = K [Rᵀ | −Rᵀ p] exactly when P's left block times R is K (H K for a calibrated system) and the source
    # position is P's null vector.
    K = view_intrinsics(system, Q)
    R, p, P = samples.source_pose[:, :3, :3], samples.source_pose[:, :3, 3], samples.P
    scale = np.linalg.norm(P, axis=(1, 2))
    residual = np.maximum(np.linalg.norm(P[:, :, :3] @ R - K, axis=(1, 2)),
                          np.linalg.norm(np.einsum("nij,nj->ni", P[:, :, :3], p) + P[:, :, 3], axis=1))
    off = ~(residual <= P_RELATIVE_TOLERANCE * scale)
    if off.any():
        i = int(np.flatnonzero(off)[0])
        raise DatasetError(f"sample {i}: P differs from K [R | t] of its source pose by {residual[i] / scale[i]:.1e} "
                           f"(relative; at most {P_RELATIVE_TOLERANCE:g})")
    low = ~(samples.clearance_m >= margin)
    if low.any():
        i = int(np.flatnonzero(low)[0])
        raise DatasetError(f"sample {i}: clearance {samples.clearance_m[i] * 1e3:.2f} mm below the margin "
                           f"{margin * 1e3:.1f} mm")


__all__ = ["DEFAULT_MARGIN", "P_RELATIVE_TOLERANCE", "PoseSamples", "Rejections", "build", "check", "clearance",
           "describe_patient", "patient_frame", "projection_matrices", "xa_angles"]
