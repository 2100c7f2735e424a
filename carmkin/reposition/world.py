"""The simulated operating room: the true system, the mounted pattern, the camera and the operator.

Everything the guidance does not know lives here: the true C-arm + table (:class:`CArmSystem`), the true
marker→table mount (a rotation error about the nominal mount), the camera's corner noise, and how the
operator executes a move. The guidance sees only what :meth:`World.measure` returns: the source pose in the
table frame estimated from noisy corners and mapped with the *calibrated* rotation. Lengths in m, angles
in rad, pixels in px.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from carmkin.errors import (
    SimulationError,  # noqa: F401 (defined there, raised here)
)
from carmkin.transforms import check_rigid_transform

from carmkin.validation import joint_index, real_scalar, rigid_transform

from . import _checks, camera, pose
from .calibration import calibrate_table, calibration_moves
from .pattern import MarkerBoard, mounted, nominal_mount

#: Default mount error of the pattern: a rotation of this angle (rad) about a random axis ("edges roughly
#: parallel to the edges of the table", §3.3.1).
MOUNT_ERROR = math.radians(2.0)


def random_rotation(rng: np.random.Generator, angle: float) -> np.ndarray:
    """A rotation (3, 3) by ``angle`` (rad) about a uniformly random axis."""
    from scipy.spatial.transform import Rotation

    _checks.generator(rng, "rng", SimulationError)
    angle = real_scalar(angle, "angle", error=SimulationError, unit="rad")
    axis = rng.normal(size=3)
    return Rotation.from_rotvec(angle * axis / np.linalg.norm(axis)).as_matrix()


def system_mount(system, board: MarkerBoard) -> np.ndarray:
    """The nominal mount (4, 4) of ``board`` centred under the table top of ``system`` (Y0 points down)."""
    _checks.system(system, "system", SimulationError)
    _checks.instance(board, MarkerBoard, "board", SimulationError)
    top = system.table
    return nominal_mount(board, float(top.top_center[1] + top.top_size[1] / 2))


@dataclass(frozen=True)
class OperatorModel:
    """How a person executes "move joint j by Δ": ``Δ (1 + relative·N₁) + absolute·N₂`` with standard
    normal N₁, N₂; ``translation`` (m) and ``rotation`` (rad) are the absolute terms of prismatic and
    revolute joints. The joint then stops at its mechanical limit if the move overshoots it."""

    relative: float = 0.1
    translation: float = 0.001
    rotation: float = math.radians(0.2)

    def __post_init__(self) -> None:
        for f in dataclasses.fields(self):
            real_scalar(getattr(self, f.name), f"OperatorModel.{f.name}", error=SimulationError, low=0.0)

    def execute(self, system, q, joint: int, move: float, rng: np.random.Generator) -> np.ndarray:
        """The joints (nq,) after the operator moved ``joint`` by about ``move`` from ``q``."""
        _checks.system(system, "system", SimulationError)
        out = _checks.joints(system, q, "q", SimulationError).copy()
        joint = joint_index(joint, "joint", system.nq, names=system.joint_names, error=SimulationError)
        move = real_scalar(move, "move", error=SimulationError, unit="m or rad")
        _checks.generator(rng, "rng", SimulationError)
        absolute = self.translation if system.prismatic[joint] else self.rotation
        actual = move * (1.0 + self.relative * rng.normal()) + absolute * rng.normal()
        # the physical stops: a joint cannot pass its mechanical limit
        out[joint] = min(max(out[joint] + actual, system.lower[joint]), system.upper[joint])
        return out


@dataclass(frozen=True)
class World:
    """The truth of one simulated room.

    ``system``: the true C-arm + table; ``board``; ``T_table_marker``: the true mount (4, 4);
    ``tRm``: the calibrated marker→table rotation the guidance uses (the truth until :meth:`calibrated`);
    ``corner_noise_px``: σ of the corner noise of each camera measurement.
    """

    system: object
    board: MarkerBoard
    T_table_marker: np.ndarray
    tRm: np.ndarray
    corner_noise_px: float = 0.2

    @classmethod
    def create(cls, system, rng: np.random.Generator, mount_error: float = MOUNT_ERROR,
               corner_noise_px: float = 0.2, board: MarkerBoard | None = None) -> "World":
        """A room with the pattern under the table top of ``system``, mounted with a rotation error of
        ``mount_error`` (rad) about a random axis; ``tRm`` starts as the truth (see :meth:`calibrated`)."""
        _checks.system(system, "system", SimulationError)
        _checks.generator(rng, "rng", SimulationError)
        mount_error = real_scalar(mount_error, "mount_error", error=SimulationError, low=0.0, unit="rad")
        corner_noise_px = real_scalar(corner_noise_px, "corner_noise_px (corner noise)", error=SimulationError, low=0.0, unit="px")
        board = MarkerBoard() if board is None else _checks.instance(board, MarkerBoard, "board", SimulationError)
        T = mounted(system_mount(system, board), random_rotation(rng, mount_error))
        return cls(system, board, T, T[:3, :3].copy(), float(corner_noise_px))

    @property
    def K(self) -> np.ndarray:
        return self.system.carm.intrinsics()

    @property
    def image_size(self) -> tuple[int, int]:
        return self.system.carm.detector_columns, self.system.carm.detector_rows

    @property
    def measured_mount(self) -> np.ndarray:
        """The mount the guidance believes: calibrated rotation, known origin (4, 4)."""
        T = self.T_table_marker.copy()
        T[:3, :3] = self.tRm
        return T

    def view(self, T_table_source) -> camera.CornerView:
        """Ideal corners seen by the camera at the source pose ``T_table_source`` (true, table frame)."""
        T = rigid_transform(T_table_source, "T_table_source", error=SimulationError)
        return camera.visible_corners(self.board, self.K, self.image_size,
                                      camera.camera_in_marker(self.T_table_marker, T))

    def measure_marker(self, T_table_source, rng: np.random.Generator) -> pose.PoseEstimate:
        """The camera's estimate, in the marker frame, at the true source pose ``T_table_source``."""
        _checks.generator(rng, "rng", SimulationError)
        noisy = camera.with_noise(self.view(T_table_source), self.corner_noise_px, rng)
        return pose.pose_from_view(noisy, self.K, sigma_px=self.corner_noise_px or None)

    def measure_estimate(self, q, rng: np.random.Generator) -> pose.PoseEstimate:
        """The camera's estimate at the true joints ``q``, expressed in the table frame as the guidance sees
        it (through the calibrated mount): pose, residuals, covariance."""
        q = _checks.joints(self.system, q, "q", SimulationError)
        return self.measure_marker(self.system.fk(q), rng).expressed_in(self.measured_mount)

    def measure(self, q, rng: np.random.Generator) -> np.ndarray:
        """The source pose (4, 4) in the table frame as the guidance sees it at the true joints ``q``."""
        return self.measure_estimate(q, rng).T

    def calibrated(self, q, rng: np.random.Generator, positions: int = 6, span: float = 0.2,
                   method: str = "svd") -> "World":
        """This room after the §3.3.3 calibration at the C-arm joints ``q``: the table moves along Z0 and
        Y0 (``positions`` stops, up to ``span`` m each), the camera measures each time, and ``tRm`` is
        estimated by :func:`calibrate_table`."""
        q = _checks.joints(self.system, q, "q", SimulationError)
        _checks.generator(rng, "rng", SimulationError)
        moves = calibration_moves(positions, span)
        T0 = check_rigid_transform(self.system.fk(q), "source pose")
        measured, covariances = [], []
        for d in moves:
            T = T0.copy()
            T[:3, 3] += d  # the table moving by −d moves the camera by d relative to it
            estimate = self.measure_marker(T, rng)
            measured.append(estimate.T[:3, 3])
            covariances.append(estimate.covariance[3:, 3:])
        # the estimator's covariances: a position is refused only when its corner noise cannot explain it
        return dataclasses.replace(self, tRm=calibrate_table(np.array(measured), moves, method=method,
                                                             covariances=np.array(covariances)))
