"""The 6-DOF model from one measured pose and the joint readings (eq. 4.3), and how pose noise propagates.

Eq. 4.3: ``1T0 = 1T6 · 6T_xray · xrayT0``: the C-arm base frame (on the cart, Z along the vertical axis)
relative to the table follows from the measured source pose in the table frame ``0T_xray`` and the C-arm's
own kinematics ``1T_xray(q5)`` at the read joint values. With the chain written as
``0T_xray(q) = Tz(d0) · E(q_table) · K · B(q5)`` (``K`` = :attr:`CArmSystem.carm_base_pose`, ``E`` the
extra joints of a motorized table, identity for the plain table, ``B`` the C-arm's five joints, which
depend on the C-arm geometry only), the base pose at rest is
``K = E⁻¹ · Tz(−d0) · 0T_xray · B(q5)⁻¹`` and :meth:`TableSetup.from_pose` turns it into γ1..3, D1..3.
Lengths in m, angles in rad.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from carmkin.errors import (
    RepositionModelError,  # noqa: F401 (defined there, raised here)
)
from carmkin.model.params import TableSetup
from carmkin.transforms import inverse, translation
from carmkin.validation import real_array, real_scalar, rigid_transform, rotation

from . import _checks

#: Central-difference step of the linear noise propagation (rad for rotations, m for translations).
PROPAGATION_STEP = 1e-6


def carm_kinematics(system, q) -> np.ndarray:
    """``B(q5)`` (4, 4): the source pose in the C-arm base frame at rest for the joints ``q`` (nq,).

    Independent of the table setup: computed from the system's FK with the table contribution removed.
    """
    system = _checks.system(system, "system", RepositionModelError)
    q = _checks.joints(system, q, "q", RepositionModelError)
    _, q_table = system.split(q)
    return inverse(_base_pose(system, q[0], q_table)) @ system.fk(q)


def base_pose(system, d0: float, q_table) -> np.ndarray:
    """``Tz(d0) · E(q_table) · K`` (4, 4): the C-arm base frame in the table frame for the table joints."""
    system = _checks.system(system, "system", RepositionModelError)
    d0 = real_scalar(d0, "d0", error=RepositionModelError, unit="m")
    q_table = real_array(q_table, "q_table", (len(system.table.joints),), error=RepositionModelError, unit="m, rad")
    return _base_pose(system, d0, q_table)


def _base_pose(system, d0: float, q_table: np.ndarray) -> np.ndarray:
    E = system.table_motion(q_table) if q_table.size else np.eye(4)
    return translation(z=d0) @ E @ system.carm_base_pose


def setup_from_pose(system, T_table_source, q_readings) -> TableSetup:
    """Eq. 4.3: the table setup from the measured source pose ``T_table_source`` (4, 4, table frame) and the
    joint readings ``q_readings`` (nq,) at the moment of the measurement (m, rad)."""
    system = _checks.system(system, "system", RepositionModelError)
    T = rigid_transform(T_table_source, "T_table_source", error=RepositionModelError)
    q = _checks.joints(system, q_readings, "q_readings", RepositionModelError)
    _, q_table = system.split(q)
    E = system.table_motion(q_table) if q_table.size else np.eye(4)
    K = inverse(E) @ translation(z=-q[0]) @ T @ inverse(carm_kinematics(system, q))
    return TableSetup.from_pose(inverse(K))


def model_from_pose(system, T_table_source, q_readings):
    """``system`` with the setup of :func:`setup_from_pose`: the model the guidance plans with."""
    setup = setup_from_pose(system, T_table_source, q_readings)  # checks the arguments first
    return system.replace(setup=setup)


def frozen_table_system(system, q_table):
    """A plain 6-DOF system (d0 + the C-arm's joints) with a motorized table's extra joints held at
    ``q_table``: ``Tz(d0) · (E K) · B(q5)`` is the plain chain with base pose ``E K``. The system itself
    when it has no extra joints. Used to read the C-arm's joints off a measured pose by closed-form IK."""
    system = _checks.system(system, "system", RepositionModelError)
    q_table = real_array(q_table, "q_table", (len(system.table.joints),), error=RepositionModelError, unit="m, rad")
    if not system.table.joints:
        return system
    K = system.table_motion(q_table) @ system.carm_base_pose
    return system.replace(setup=TableSetup.from_pose(inverse(K)),
                          table=dataclasses.replace(system.table, joints=()))


def _setup_vector(setup: TableSetup) -> np.ndarray:
    return np.array([setup.gamma1, setup.gamma2, setup.gamma3, setup.D1, setup.D2, setup.D3])


def setup_jacobian(system, T_table_source, q_readings) -> np.ndarray:
    """d(γ1, γ2, γ3, D1, D2, D3)/d(ω, δp) (6, 6) by central differences, for the pose perturbation
    ``R = exp([ω]) R̂``, ``p = p̂ + δp`` in the table frame (the convention of :mod:`.pose`)."""
    from scipy.spatial.transform import Rotation

    system = _checks.system(system, "system", RepositionModelError)
    T = rigid_transform(T_table_source, "T_table_source", error=RepositionModelError)
    q_readings = _checks.joints(system, q_readings, "q_readings", RepositionModelError)
    J = np.zeros((6, 6))
    for k in range(6):
        columns = []
        for sign in (1.0, -1.0):
            T_k = T.copy()
            if k < 3:
                T_k[:3, :3] = Rotation.from_rotvec(sign * PROPAGATION_STEP * np.eye(3)[k]).as_matrix() @ T[:3, :3]
            else:
                T_k[k - 3, 3] += sign * PROPAGATION_STEP
            columns.append(_setup_vector(setup_from_pose(system, T_k, q_readings)))
        delta = columns[0] - columns[1]
        delta[:3] = (delta[:3] + np.pi) % (2 * np.pi) - np.pi  # angles may wrap at ±π
        J[:, k] = delta / (2 * PROPAGATION_STEP)
    return J


def setup_covariance(system, T_table_source, q_readings, pose_covariance) -> np.ndarray:
    """Covariance (6, 6) of (γ1, γ2, γ3 in rad, D1, D2, D3 in m) from the pose covariance (6, 6) over
    (ω rad, δp m) in the table frame, by linear propagation ``J Σ Jᵀ`` (:func:`setup_jacobian`)."""
    covariance = real_array(pose_covariance, "pose_covariance", (6, 6), error=RepositionModelError)
    J = setup_jacobian(system, T_table_source, q_readings)
    return J @ covariance @ J.T


def to_table_frame(covariance_marker, tRm) -> np.ndarray:
    """A pose covariance over (ω, δp) in the marker frame expressed in the table frame (both blocks rotated)."""
    covariance = real_array(covariance_marker, "covariance_marker", (6, 6), error=RepositionModelError)
    R6 = np.zeros((6, 6))
    R6[:3, :3] = R6[3:, 3:] = rotation(tRm, "tRm", error=RepositionModelError)
    return R6 @ covariance @ R6.T
