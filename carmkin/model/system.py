"""`CArmSystem`: the one source of truth for a C-arm + table model (geometry, limits, setup, body)."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from functools import cached_property

import numpy as np

from carmkin.errors import InvalidConfigurationError, InvalidParameterError
from carmkin.transforms import translation
from carmkin.validation import JOINT_VALUE_LIMIT, plain_floats, unit_slip

from . import kinematics
from .bounds import MAX_ANGLE, MAX_LENGTH, check_joint_limits
from .calibration import Calibration
from .motion import Motion
from .mount_joints import MountGeometry
from .params import (
    JOINT_NAMES,
    PRISMATIC,
    BodyGeometry,
    CArmGeometry,
    JointRange,
    TableGeometry,
    TableSetup,
)


#: Largest |prismatic joint value| (m) the public :meth:`CArmSystem.fk` accepts: three times the largest joint
#: limit a system may have (:data:`~carmkin.model.bounds.MAX_LENGTH`, 10 m). A larger value is a unit slip
#: (400 mm passed as 400 m), refused naming it. The toolkit's own callers that evaluate solver output (IK
#: branches near a singular pose reach 4e6 m and must still be evaluated to be reported out of range) pass
#: ``check_units=False``.
PLAUSIBLE_PRISMATIC = 3.0 * MAX_LENGTH
#: Largest |revolute joint value| (rad) the public :meth:`CArmSystem.fk` accepts: two turns, twice the widest
#: joint range (:data:`~carmkin.model.bounds.MAX_ANGLE`, ±2π). A larger value is an angle in degrees.
PLAUSIBLE_REVOLUTE = 2.0 * MAX_ANGLE


@dataclass(frozen=True)
class CArmSystem:
    """A mobile C-arm and an operating table modelled as one 6-DOF chain (§4.3).

    The joint vector is ``q = [d0, d1, theta2, d3, theta4, theta5]`` (m, m, rad, m, rad, rad): table
    translation, vertical, wigwag, horizontal, angular, orbital. Poses are expressed in the table frame 0.
    A motorized table's joints (``table``) follow d0, then a mount's joints (``mount``, e.g. the robot that
    holds the C), then the C-arm's five: ``[d0, table joints…, mount joints…, d1, θ2, d3, θ4, θ5]``.
    """

    carm: CArmGeometry
    setup: TableSetup
    table: TableGeometry = field(default_factory=TableGeometry)
    body: BodyGeometry = field(default_factory=BodyGeometry)
    name: str = "custom"
    calibration: Calibration = field(default_factory=Calibration)
    #: Joint speeds and accelerations (:mod:`carmkin.model.motion`), one per joint in the order of q; None
    #: when the preset gives none (plans then report no duration).
    motion: Motion | None = None
    #: What carries the C-arm base: a robot's joints (:mod:`carmkin.model.mount_joints`); none by default.
    mount: MountGeometry = field(default_factory=MountGeometry)

    def __post_init__(self) -> None:
        for name, kind in (("carm", CArmGeometry), ("setup", TableSetup), ("table", TableGeometry),
                           ("body", BodyGeometry), ("name", str), ("calibration", Calibration),
                           ("mount", MountGeometry)):
            if not isinstance(getattr(self, name), kind):
                raise InvalidParameterError(
                    f"CArmSystem.{name} must be a {kind.__name__}, got {type(getattr(self, name)).__name__} "
                    f"{getattr(self, name)!r:.80}")
        for joint_range, prismatic in zip(self.joint_ranges, self.prismatic):
            check_joint_limits(joint_range, prismatic, "CArmSystem")
        self.calibration.offsets(self.nq)  # one zero offset per joint, or none
        if self.body.c_radius is not None and self.body.c_radius < self.carm.source_to_orbital_axis:
            raise InvalidParameterError(
                f"CArmSystem.body.c_radius = {self.body.c_radius * 1e3:g} mm is shorter than the source to orbital "
                f"axis distance {self.carm.source_to_orbital_axis * 1e3:g} mm: the C must reach the source; "
                f"expected at least that, or None")
        if self.motion is not None and (not isinstance(self.motion, Motion) or self.motion.names != self.joint_names):
            raise InvalidParameterError(
                f"CArmSystem.motion must be a Motion naming the joints {', '.join(self.joint_names)} in this "
                f"order, got {getattr(self.motion, 'names', type(self.motion).__name__)}")

    def replace(self, **changes) -> "CArmSystem":
        """A new system with some fields replaced, e.g. ``system.replace(carm=..., setup=...)``. A new
        ``table`` (or ``mount``) whose joints differ keeps the joint speeds (:attr:`motion`) by joint name, or none
        when a joint has none (give ``motion=`` to set them)."""
        names = [f.name for f in dataclasses.fields(self)]
        for key in changes:
            if key not in names:
                import difflib

                hint = difflib.get_close_matches(key, names, n=1)
                raise InvalidParameterError(f"CArmSystem.replace: unknown field {key!r}"
                                            + (f"; did you mean {hint[0]!r}?" if hint else f"; fields: {', '.join(names)}"))
        if "motion" not in changes and self.motion is not None and ("table" in changes or "mount" in changes):
            # the joints may change: keep each remaining joint's speed by name (none if a new joint has none)
            names = dataclasses.replace(self, **changes, motion=None).joint_names
            changes["motion"] = self.motion.for_joints(names)
        return dataclasses.replace(self, **changes)

    # --- joints ---------------------------------------------------------------------------------------
    @property
    def nq(self) -> int:
        """Number of joints: 6, plus the extra joints of a motorized table (:mod:`carmkin.model.table_joints`)
        and the joints of a mount (:mod:`carmkin.model.mount_joints`)."""
        return 6 + len(self.table.joints) + len(self.mount.joints)

    @property
    def joint_names(self) -> tuple[str, ...]:
        """Names of the joints in the order of q: table translation, extra table joints (top down), mount joints
        (floor up), C-arm."""
        return (JOINT_NAMES[:1] + tuple(j.name for j in self.table.joints) + tuple(j.name for j in self.mount.joints)
                + JOINT_NAMES[1:])

    @property
    def joint_ranges(self) -> tuple[JointRange, ...]:
        """Ranges of the joints, in the order of q (m or rad)."""
        return ((self.table.translation,) + tuple(j.range for j in self.table.joints)
                + tuple(j.range for j in self.mount.joints) + self.carm.joint_ranges)

    @property
    def prismatic(self) -> tuple[bool, ...]:
        """True for each prismatic joint (m), False for each revolute one (rad), in the order of q."""
        return (PRISMATIC[:1] + tuple(j.prismatic for j in self.table.joints)
                + tuple(j.prismatic for j in self.mount.joints) + PRISMATIC[1:])

    def split(self, q) -> tuple[np.ndarray, np.ndarray]:
        """``(q6, q_table)``: the paper's six joints and the extra table joints of q (nq,) or (N, nq) (the mount
        joints, between them, are :meth:`mount_part`)."""
        q = kinematics.check_configuration(q, self.nq)
        k = len(self.table.joints)
        return np.concatenate((q[..., :1], q[..., -5:]), axis=-1), q[..., 1:1 + k]

    def mount_part(self, q) -> np.ndarray:
        """The mount joints' values of q (nq,) or (N, nq): (n,) or (N, n), floor up."""
        q = kinematics.check_configuration(q, self.nq)
        k = 1 + len(self.table.joints)
        return q[..., k:k + len(self.mount.joints)]

    def mount_motion(self, q_mount) -> np.ndarray:
        """``G = e^{η1 q1} ··· e^{ηn qn}`` for mount joint values (n,) or (N, n): (4, 4) or (N, 4, 4), the motion
        of the C-arm base in the rest table frame 0 (see :mod:`carmkin.model.mount_joints`)."""
        from .mount_joints import chain

        return chain(self.mount.twists, np.asarray(q_mount, dtype=float))

    def base_motion(self, q) -> np.ndarray:
        """``Tz(d0) · E(q_table) · G(q_mount)`` (4, 4) or (N, 4, 4) for q (nq,) or (N, nq): what carries the
        C-arm base from its rest pose :attr:`carm_base_pose`, so that ``fk(q) = base_motion(q) · P(q6, d0 = 0)``."""
        q6, q_table = self.split(q)
        E = self.table_motion(q_table)
        if self.mount.joints:
            E = E @ self.mount_motion(self.mount_part(q))
        E[..., 2, 3] += q6[..., 0]
        return E

    def mount_frames(self, q) -> np.ndarray:
        """Poses (n, 4, 4) or (N, n, 4, 4) in the table frame of the mount bodies for q (nq,) or (N, nq): body i
        at ``Tz(d0) · E(q_table) · e^{η1 q1} ··· e^{ηi qi}`` (the identity's orientation at rest, as the URDF's
        ``<joint>_frame`` links)."""
        from .mount_joints import partial_chains

        q = kinematics.check_configuration(q, self.nq)
        flat = q.reshape(-1, self.nq)
        reference = self.base_motion(np.concatenate((flat[:, :1 + len(self.table.joints)],
                                                     np.zeros((len(flat), len(self.mount.joints))), flat[:, -5:]), axis=1))
        out = reference[:, None] @ partial_chains(self.mount.twists, self.mount_part(flat))
        return out.reshape(q.shape[:-1] + (len(self.mount.joints), 4, 4))

    def table_motion(self, q_table: np.ndarray) -> np.ndarray:
        """``e^{-ξk qk} ··· e^{-ξ1 q1}`` for extra table joint values (k,) or (N, k): (4, 4) or (N, 4, 4).

        The floor-fixed frame ``table_reference`` seen from the table top (see :mod:`carmkin.model.table_joints`).
        """
        from .table_joints import inverse_chain

        if not self.table.joints and q_table.ndim == 2:  # no table joint: the identity for every configuration
            return np.broadcast_to(np.eye(4), (len(q_table), 4, 4)).copy()
        if q_table.ndim == 1:
            return inverse_chain(self.table.joints, q_table)
        return np.array([inverse_chain(self.table.joints, v) for v in q_table]).reshape(len(q_table), 4, 4)

    def _with_table_joints(self, q, poses_of_q6) -> np.ndarray:
        """Poses ``Tz(d0) · E(q_table) · G(q_mount) · P(q6 with d0 = 0)`` for poses P computed by ``poses_of_q6``."""
        q6, _ = self.split(q)
        q6 = q6.copy()
        q6[..., 0] = 0.0
        E = self.base_motion(q)
        P = poses_of_q6(q6)
        return E[..., None, :, :] @ P if P.ndim == E.ndim + 1 else E @ P

    @property
    def lower(self) -> np.ndarray:
        """Lower joint limits (nq,)."""
        return np.array([r.lower for r in self.joint_ranges])

    @property
    def upper(self) -> np.ndarray:
        """Upper joint limits (nq,)."""
        return np.array([r.upper for r in self.joint_ranges])

    # --- closed-form kinematics ------------------------------------------------------------------------
    @cached_property
    def dh_table(self) -> tuple[kinematics.DHRow, ...]:
        """The six standard-DH rows of the chain (see :mod:`carmkin.model.kinematics`)."""
        return kinematics.dh_table(self.carm, self.setup)

    @cached_property
    def xray_in_flange(self) -> np.ndarray:
        """``6T_xray`` (eq. 4.2), pose of the X-ray source frame in frame 6."""
        return kinematics.xray_in_flange(self.carm)

    @cached_property
    def detector_in_xray(self) -> np.ndarray:
        """Pose of the ``detector`` frame in the source frame: on the principal axis at the SDD."""
        return translation(z=self.carm.source_to_detector)

    @cached_property
    def carm_base_pose(self) -> np.ndarray:
        """``K = A0(0) A1(0)`` (4, 4): the C-arm base frame (``carm_cart``) in the table frame at rest, d0 = 0."""
        T = np.eye(4)
        T[:3, :3], T[:3, 3] = self.closed_form.R, self.closed_form.p
        return T

    @cached_property
    def closed_form(self) -> kinematics.ClosedFormFK:
        """The expanded closed-form FK of the 6-DOF chain (constants precomputed once per system)."""
        return kinematics.ClosedFormFK(self.carm, self.setup)

    def fk(self, q, *, check_units: bool = True) -> np.ndarray:
        """Pose of ``xray_source`` in the table frame: (4, 4) for q of shape (nq,), (N, 4, 4) for (N, nq).

        One configuration of plain floats (a float64 array or a list of floats) takes the scalar path on
        Python floats (:meth:`ClosedFormFK.rows <carmkin.model.kinematics.ClosedFormFK.rows>`, a few µs);
        anything else is checked in full (:func:`~carmkin.model.kinematics.check_configuration`); batches
        are vectorized.

        A prismatic value beyond :data:`PLAUSIBLE_PRISMATIC` (m) or a revolute one beyond
        :data:`PLAUSIBLE_REVOLUTE` (rad) is an :class:`~carmkin.errors.InvalidConfigurationError` naming the
        likely unit slip (``"given in mm? 400 mm = 0.4 m"``, ``"given in degrees?"``). ``check_units=False``
        lifts that bound (to :data:`~carmkin.validation.JOINT_VALUE_LIMIT`, an overflow guard): for joint values
        that are not a user's but a solver's, e.g. an IK branch far out of range near a singular pose."""
        if not check_units:
            return self._fk(q)
        values = plain_floats(q, self.nq, PLAUSIBLE_REVOLUTE)
        if values is not None:  # every value within two turns and 12.6 m: plausible in either unit
            return np.array(self._fk_rows(values)).reshape(4, 4)
        q = kinematics.check_configuration(q, self.nq)
        self._check_plausible(q)
        return self._fk(q)

    def _check_plausible(self, q: np.ndarray) -> None:
        """InvalidConfigurationError naming the first joint value of q (nq,) or (N, nq) that no C-arm takes in
        the unit asked for (see :data:`PLAUSIBLE_PRISMATIC`, :data:`PLAUSIBLE_REVOLUTE`)."""
        limits = np.where(self.prismatic, PLAUSIBLE_PRISMATIC, PLAUSIBLE_REVOLUTE)
        beyond = np.abs(q) > limits
        if not beyond.any():
            return
        index = tuple(int(i) for i in np.argwhere(beyond)[0])
        joint, value = index[-1], float(q[index])
        bound, unit = float(limits[joint]), "m" if self.prismatic[joint] else "rad"
        raise InvalidConfigurationError(
            f"q[{', '.join(map(str, index))}] ({self.joint_names[joint]}) = {value:g} {unit} is not a C-arm joint "
            f"value: |value| must "
            f"be at most {bound:.4g} {unit}{unit_slip(value, -bound, bound, unit)}")

    def _fk(self, q) -> np.ndarray:
        """:meth:`fk` with ``check_units=False``."""
        values = plain_floats(q, self.nq, JOINT_VALUE_LIMIT)
        if values is not None:
            return np.array(self._fk_rows(values)).reshape(4, 4)
        if self.nq > 6:
            return self._with_table_joints(q, self._fk6)
        return self._fk6(kinematics.check_configuration(q))

    def _fk_rows(self, values: list[float]) -> list[float]:
        """The pose row-major (16 floats) for one configuration of Python floats:
        ``Tz(d0) · E(q_table) · G(q_mount) · P(q6 with d0 = 0)`` with a motorized table or a mount, as
        :meth:`_with_table_joints`."""
        steps = self._table_steps
        if not steps:
            return self.closed_form.rows(*values)
        rows = self.closed_form.rows(0.0, *values[-5:])
        for apply, index in steps:
            apply(rows, values[index])
        rows[11] += values[0]
        return rows

    @cached_property
    def _table_steps(self) -> tuple:
        """``(apply, index in q)`` of the mount joints and the extra table joints in the order the scalar FK
        applies them to the C-arm's pose: the last mount joint first (``e^{ηn qn}``, :meth:`MountJoint.apply_motion
        <carmkin.model.mount_joints.MountJoint.apply_motion>`), then the table's from the floor up (the last of
        its chain first, ``e^{-ξ q}``)."""
        k = len(self.table.joints)
        mount = [(joint.apply_motion, 1 + k + i) for i, joint in enumerate(self.mount.twists)]
        table = [(joint.apply_inverse_motion, 1 + i) for i, joint in enumerate(self.table.joints)]
        return tuple(reversed(table + mount))

    def _fk6(self, q6: np.ndarray) -> np.ndarray:
        return self.closed_form.pose(q6) if q6.ndim == 1 else self.closed_form.poses(q6)

    def dh_frames(self, q) -> np.ndarray:
        """Poses of DH frames 1..6 in the table frame: (6, 4, 4) for q (nq,), (N, 6, 4, 4) for (N, nq)."""
        if self.nq > 6:
            return self._with_table_joints(q, lambda q6: kinematics.dh_frames(self.dh_table, q6))
        return kinematics.dh_frames(self.dh_table, q)

    # --- generated descriptions ----------------------------------------------------------------------
    def urdf(self) -> str:
        """URDF text of the chain, generated from ``urdf/carm_table.urdf.xacro`` with this system's numbers."""
        from carmkin.model.urdf import urdf_text

        return urdf_text(self)

    def pinocchio(self):
        """``(model, collision_model, visual_model)`` built by Pinocchio from :meth:`urdf`.

        Built once per system and cached: treat the returned models as read-only (create your own
        ``pin.Data`` / ``pin.GeometryData`` from them).
        """
        return self._pinocchio_models

    @cached_property
    def _pinocchio_models(self):
        from carmkin.model.urdf import build_models

        return build_models(self.urdf())


def require_system(system, error=None) -> None:
    """``error`` (default :class:`~carmkin.errors.InvalidConfigurationError`) naming the argument unless
    ``system`` is a :class:`CArmSystem` (the one check of the solvers' ``system`` argument: a junk value is
    refused before any attribute of it is read)."""
    if not isinstance(system, CArmSystem):
        from carmkin.errors import InvalidConfigurationError

        raise (error or InvalidConfigurationError)(
            f"system must be a carmkin.CArmSystem (carmkin.load_preset(...)), got {type(system).__name__}")
