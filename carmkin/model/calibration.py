"""`Calibration`: what a calibrated C-arm differs by from its kinematic model, beyond the geometry's numbers.

A calibration (:mod:`carmkin.calibration` fits one from measured projection matrices) changes the numbers of
:class:`~carmkin.model.params.CArmGeometry` and :class:`~carmkin.model.params.TableSetup` (link offsets,
source–detector distance, principal point, table setup) and adds the three quantities the model has no field
for, held here (SI units):

- ``joint_offsets`` (nq,): joint zero offsets, m or rad in the order of q; **reading + offset = model value**.
  The toolkit's joint values (FK, IK, planners) are model values everywhere; :meth:`Calibration.model_joints`
  turns a device's readings into them and :meth:`Calibration.readings` goes back. ``()`` = all zero.
- ``detector_rotation`` (rad): the detector's in-plane rotation about the principal axis (its pixel axes
  turned by this angle from the source frame's X/Y, right-handed about Z_xray).
- ``sag_cos``, ``sag_sin`` (m): C-arm sag, the detector's in-plane displacement relative to the source along
  Y_xray (the axis of image rows, which lies in the C's plane; X_xray is the orbital axis, eq. 4.2) as a
  function of the model orbital angle θ5: ``s(θ5) = sag_cos · cos θ5 + sag_sin · sin θ5``.

Both detector quantities act in the image plane: a point's nominal pixel ``m`` (from ``K`` of
:meth:`CArmGeometry.intrinsics`) becomes ``H m`` with the affine map of :meth:`Calibration.detector_map`,
``pixel = c + S⁻¹ R(−ρ) (S (m − c) − (0, s(θ5)))`` (``c`` the principal point, ``S = diag(sx, sy)`` the pixel
size). The X-ray source pose (FK) stays the rigid chain's; this is the image-plane correction of the
"virtual detector plane" that §2.2.2 uses against the gantry's sag. A nominal ``Calibration()`` changes
nothing, and the scalar FK never reads it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from carmkin.errors import InvalidParameterError

from .bounds import MAX_ANGLE, MAX_LENGTH, check_real


@dataclass(frozen=True)
class Calibration:
    """Joint zero offsets, detector rotation and sag of a calibrated system (SI; see the module docstring).

    Attributes:
        joint_offsets: per joint, in the order of q (m for prismatic, rad for revolute joints); ``()`` = zeros.
        detector_rotation: in-plane rotation of the detector about the principal axis (rad).
        sag_cos, sag_sin: the detector's displacement along Y_xray, ``sag_cos·cos θ5 + sag_sin·sin θ5`` (m).
    """

    joint_offsets: tuple[float, ...] = ()
    detector_rotation: float = 0.0
    sag_cos: float = 0.0
    sag_sin: float = 0.0

    def __post_init__(self) -> None:
        owner = "Calibration"
        if isinstance(self.joint_offsets, (str, bytes)) or not hasattr(self.joint_offsets, "__iter__"):
            raise InvalidParameterError(f"{owner}.joint_offsets must be a tuple of numbers (m or rad, one per "
                                        f"joint), got {self.joint_offsets!r:.80}")
        offsets = tuple(check_real(f"{owner}.joint_offsets[{i}]", v, -MAX_LENGTH, MAX_LENGTH, "m or rad")
                        for i, v in enumerate(self.joint_offsets))
        object.__setattr__(self, "joint_offsets", offsets)
        object.__setattr__(self, "detector_rotation", check_real(
            f"{owner}.detector_rotation", self.detector_rotation, -MAX_ANGLE, MAX_ANGLE, "rad"))
        for name in ("sag_cos", "sag_sin"):
            object.__setattr__(self, name, check_real(f"{owner}.{name}", getattr(self, name), -MAX_LENGTH,
                                                      MAX_LENGTH, "m"))

    @property
    def is_nominal(self) -> bool:
        """True when the calibration changes nothing (zero offsets, no rotation, no sag)."""
        return not any(self.joint_offsets) and self.detector_rotation == 0.0 and self.sag_cos == self.sag_sin == 0.0

    def offsets(self, nq: int) -> np.ndarray:
        """The joint zero offsets as an array (nq,) (zeros when none are set)."""
        if not self.joint_offsets:
            return np.zeros(nq)
        if len(self.joint_offsets) != nq:
            raise InvalidParameterError(f"Calibration.joint_offsets has {len(self.joint_offsets)} values, the "
                                        f"system has {nq} joints")
        return np.array(self.joint_offsets)

    def model_joints(self, readings) -> np.ndarray:
        """Model joint values ``readings + offsets`` for readings (nq,) or (N, nq) (m, rad)."""
        readings = np.asarray(readings, dtype=float)
        return readings + self.offsets(readings.shape[-1])

    def readings(self, q) -> np.ndarray:
        """The readings a device shows for model joint values q (nq,) or (N, nq): ``q − offsets``."""
        q = np.asarray(q, dtype=float)
        return q - self.offsets(q.shape[-1])

    def detector_map(self, carm, orbital) -> np.ndarray:
        """``H`` (3, 3), or (N, 3, 3) for N orbital angles (rad, model values): nominal pixels to calibrated.

        The calibrated intrinsics of a view are ``H @ carm.intrinsics()`` (see the module docstring); the
        identity for a nominal calibration."""
        orbital = np.asarray(orbital, dtype=float)
        sx, sy = carm.pixel_spacing
        c = carm.intrinsics()[:2, 2]
        rho = self.detector_rotation
        A = np.array([[math.cos(rho), math.sin(rho) * sy / sx],
                      [-math.sin(rho) * sx / sy, math.cos(rho)]])  # S⁻¹ R(−ρ) S
        shift = self.sag_cos * np.cos(orbital) + self.sag_sin * np.sin(orbital)  # m along Y_xray
        H = np.zeros(orbital.shape + (3, 3))
        H[..., :2, :2] = A
        H[..., :2, 2] = c - A @ c
        # − S⁻¹ R(−ρ) (0, s): R(−ρ) (0, 1) = (sin ρ, cos ρ)
        H[..., 0, 2] -= shift * math.sin(rho) / sx
        H[..., 1, 2] -= shift * math.cos(rho) / sy
        H[..., 2, 2] = 1.0
        return H
