"""Cross-check of the closed-form DH kinematics against Pinocchio's model built from the generated URDF.

Both routes are independent: the closed form multiplies the DH matrices of :mod:`carmkin.model.kinematics`;
Pinocchio parses the URDF that xacro expanded from the same system and composes its own joint placements.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pinocchio as pin

from carmkin.model.sampling import random_configurations, random_system
from carmkin.model.system import CArmSystem
from carmkin.transforms import rotation_angle

#: Frames compared: the DH frames 1..6 and the imaging frames.
FRAMES = tuple(f"dh_frame_{i}" for i in range(1, 7)) + ("xray_source", "detector")


@dataclass
class VerifyReport:
    """Worst errors between closed form and Pinocchio, per frame: position (m) and rotation (rad)."""

    samples: int = 0
    systems: int = 0
    position_error: dict[str, float] = field(default_factory=lambda: dict.fromkeys(FRAMES, 0.0))
    rotation_error: dict[str, float] = field(default_factory=lambda: dict.fromkeys(FRAMES, 0.0))

    @property
    def worst(self) -> float:
        """Largest error over all frames and quantities (m or rad)."""
        return max(max(self.position_error.values()), max(self.rotation_error.values()))

    def update(self, frame: str, position: float, rotation: float) -> None:
        self.position_error[frame] = max(self.position_error[frame], position)
        self.rotation_error[frame] = max(self.rotation_error[frame], rotation)


def closed_form_frames(system: CArmSystem, q: np.ndarray) -> np.ndarray:
    """Closed-form poses of :data:`FRAMES` in the table frame, shape (N, 8, 4, 4) for q of (N, 6)."""
    dh = system.dh_frames(q)
    source = dh[:, -1] @ system.xray_in_flange
    detector = source @ system.detector_in_xray
    return np.concatenate((dh, source[:, None], detector[:, None]), axis=1)


def pinocchio_frames(system: CArmSystem, q: np.ndarray) -> np.ndarray:
    """Pinocchio's placements of :data:`FRAMES` in the table frame, shape (N, 8, 4, 4)."""
    model = system.pinocchio()[0]
    data = model.createData()
    ids = [model.getFrameId(name) for name in FRAMES]
    out = np.empty((len(q), len(FRAMES), 4, 4))
    for k, qk in enumerate(q):
        pin.framesForwardKinematics(model, data, qk)
        for j, frame_id in enumerate(ids):
            out[k, j] = data.oMf[frame_id].homogeneous
    return out


def compare(system: CArmSystem, q: np.ndarray, report: VerifyReport) -> None:
    """Add the errors of ``system`` over configurations ``q`` (N, 6) to ``report``."""
    a, b = closed_form_frames(system, q), pinocchio_frames(system, q)
    position = np.linalg.norm(a[..., :3, 3] - b[..., :3, 3], axis=-1).max(axis=0)
    rotation = rotation_angle(a[..., :3, :3], b[..., :3, :3]).max(axis=0)
    for j, frame in enumerate(FRAMES):
        report.update(frame, float(position[j]), float(rotation[j]))
    report.samples += len(q)
    report.systems += 1


def verify(system: CArmSystem, samples: int, random_setups: int = 0, seed: int = 0, progress=None) -> VerifyReport:
    """Compare closed form and Pinocchio over ``samples`` random configurations, in and beyond the limits.

    With ``random_setups > 0`` the samples are spread over that many random systems (random table pose and
    non-isocentric a1, a2 ≠ 0) in addition to ``system`` itself. ``progress(n)`` is called after each batch.
    """
    rng = np.random.default_rng(seed)
    systems = [system] + [random_system(rng, system) for _ in range(random_setups)]
    counts = np.full(len(systems), samples // len(systems))
    counts[: samples % len(systems)] += 1
    report = VerifyReport()
    for sys_k, n in zip(systems, counts):
        if n:
            compare(sys_k, random_configurations(rng, sys_k, int(n)), report)
        if progress is not None:
            progress(int(n))
    return report
