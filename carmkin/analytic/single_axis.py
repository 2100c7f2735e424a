"""Closed-form IK of a C-arm beside a multi-DOF table, one table translation active (issue 9, §4.7).

With the other table joints held, the source pose in the table-top frame 0 is
``T = Trans(q·w) · C · K · Tz(d1) · 2T_xray(θ2, d3, θ4, θ5)`` for the active translation q along a unit
direction w (in frame 0) and a constant C: the held joints' inverse motions. Rotating frame 0 into a frame 0'
whose Z axis is w turns this into the paper's 6-DOF chain with d0 = q, whose table setup comes from the
common-normal construction of eq. 4.3 (:meth:`TableSetup.from_pose`). The closed form of
:mod:`carmkin.analytic_ik` solves it; the result maps back to the table's joints.

Case (a) of §4.3.2 (table axis ∥ vertical axis) is what a height-adjustable table gives when the floor is
level: ``table_height`` moves along the C-arm's vertical axis, so it can never be the sixth DOF — the
closed form reports the pose as singular and falls back on damped least squares.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from carmkin.analytic.results import IKResult
from carmkin.analytic.solve import solve_pose
from carmkin.errors import (
    InvalidConfigurationError,
    TableIKError,  # noqa: F401 (defined there, raised here)
)
from carmkin.model.kinematics import check_configuration
from carmkin.model.mount_joints import MountGeometry
from carmkin.model.params import TableSetup
from carmkin.model.system import CArmSystem
from carmkin.transforms import check_rigid_transform, inverse, rotation_between

#: Joints that can play the paper's d0: the table's translations.
TRANSLATIONS = ("table_translation", "table_lateral", "table_height")


@dataclass(frozen=True)
class SingleAxisResult:
    """Solutions of :func:`solve_single_axis` in the full joint order of the system.

    ``solutions`` (2, nq): both closed-form branches with the held table joints filled in; ``chosen``;
    ``ik``: the :class:`carmkin.analytic_ik.IKResult` of the equivalent 6-DOF chain; ``equivalent``: that
    chain (a 6-DOF :class:`CArmSystem`) and ``T_equivalent_table`` (4, 4), the pose of frame 0 in it.
    """

    solutions: np.ndarray
    chosen: int
    ik: IKResult
    equivalent: CArmSystem
    T_equivalent_table: np.ndarray

    @property
    def q(self) -> np.ndarray:
        """The chosen solution (nq,)."""
        return self.solutions[self.chosen]

    @property
    def valid(self) -> bool:
        """Chosen branch within every range: the 6-DOF joints and the active table joint's own range."""
        return bool(self.ik.valid)


def equivalent_chain(system: CArmSystem, active: str, q_held) -> tuple[CArmSystem, np.ndarray, int]:
    """The paper's 6-DOF chain equivalent to ``system`` with only ``active`` moving among the table joints
    (a mount's joints, if any, held as well).

    ``q_held`` (nq,) gives the held joints (its value of ``active`` and of the C-arm joints is ignored).
    Returns ``(system6, T_equivalent_table, index)``: a 6-DOF system whose d0 is the active joint, the pose
    of frame 0 in its table frame 0' (a pure rotation), and the index of ``active`` in the full q.
    """
    if active not in system.joint_names:
        raise TableIKError(f"{active!r} is not a joint of this system; table joints: {system.joint_names[:-5]}")
    if active not in TRANSLATIONS:
        raise TableIKError(f"{active!r} is not a table translation; the closed form needs one of {TRANSLATIONS}")
    q_held = check_configuration(q_held, system.nq, "q_held")
    if q_held.ndim != 1:
        raise InvalidConfigurationError(f"q_held must have shape ({system.nq},), got {q_held.shape}")
    index = system.joint_names.index(active)
    q6, q_table = system.split(q_held)
    joints = system.table.joints
    # T_table_cart = Tz(d0) · E_before · e^{-ξ q} · E_after · K, with the active joint's value 0 in C.
    values = np.where(np.arange(len(joints)) + 1 == index, 0.0, q_table)
    d0 = 0.0 if active == "table_translation" else float(q6[0])
    before = np.eye(4)
    before[2, 3] = d0
    for k, joint in enumerate(joints):
        if k + 1 == index:
            break
        before = before @ joint.inverse_motion(float(values[k]))
    if active == "table_translation":
        w = np.array([0.0, 0.0, 1.0])
    else:  # e^{-ξ q} = Trans(-q u); moved to the left of E_before it becomes Trans(-q R_before u)
        w = -before[:3, :3] @ np.asarray(joints[index - 1].axis)
    C = system.table_motion(values)
    if system.mount.joints:  # held too: G(q_mount) follows the table's motion (carmkin.model.mount_joints)
        C = C @ system.mount_motion(system.mount_part(q_held))
    C[2, 3] += d0
    T_table_cart = C @ system.carm_base_pose
    R = rotation_between((0.0, 0.0, 1.0), w)
    T_equivalent_table = np.eye(4)
    T_equivalent_table[:3, :3] = R.T
    T_equivalent_cart = T_equivalent_table @ T_table_cart
    setup = TableSetup.from_pose(inverse(T_equivalent_cart))
    active_range = system.joint_ranges[index]
    table = replace(system.table, joints=(), translation=replace(active_range, name="table_translation"))
    return system.replace(setup=setup, table=table, mount=MountGeometry()), T_equivalent_table, index


def solve_single_axis(system: CArmSystem, T, active: str, q_held, q_current=None) -> SingleAxisResult:
    """Closed-form IK with only the table translation ``active`` moving among the table joints.

    ``T`` (4, 4): desired source pose in the table-top frame 0. ``q_held`` (nq,): the held table joints'
    values (the rest of it is ignored). ``q_current`` (nq,), optional: reference of the selection rules of
    §4.4.2 (defaults to ``q_held``).
    """
    T = check_rigid_transform(T, "T")
    system6, T_eq_table, index = equivalent_chain(system, active, q_held)
    q_held = np.asarray(q_held, dtype=float)
    reference = q_held if q_current is None else check_configuration(q_current, system.nq, "q_current")
    ref6 = np.concatenate(([reference[index]], reference[-5:]))
    ik = solve_pose(system6, T_eq_table @ T, q_current=ref6)
    solutions = np.tile(q_held, (2, 1))
    solutions[:, index] = ik.solutions[:, 0]
    solutions[:, -5:] = ik.solutions[:, 1:]
    return SingleAxisResult(solutions, ik.chosen, ik, system6, T_eq_table)
