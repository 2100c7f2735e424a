"""One kinematic state per configuration: forward kinematics once, shared by every consumer.

:class:`KinematicState` holds ``q`` and a ``pin.Data`` after one :func:`pinocchio.forwardKinematics` (or
:func:`pinocchio.computeJointJacobians`, which includes it, when Jacobians are asked for) and
:func:`pinocchio.updateFramePlacements`. The collision distances and the source pose are computed on first
use and kept. Tasks, the collision rows, the validity report and the QP's stop test all read the same
state, so one configuration costs one forward-kinematics pass. Lengths in metres, poses in the root (table)
frame 0.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from carmkin.errors import InvalidConfigurationError

#: Frame of the X-ray source (Z along the principal axis towards the detector).
SOURCE_FRAME = "xray_source"


class KinematicState:
    """Kinematics of ``model`` at ``q`` (nq,).

    ``world``: an optional :class:`carmkin.world.World` of the same model, used for
    :attr:`distances`. ``jacobians``: also compute the joint Jacobians (``data.J``, world frame), as the QP
    step needs. ``data``: reuse this ``pin.Data`` (it is overwritten) instead of allocating one.
    """

    def __init__(self, model: pin.Model, q, world=None, jacobians: bool = False, data: pin.Data | None = None):
        q = np.asarray(q, dtype=float)
        if q.shape != (model.nq,) or not np.all(np.isfinite(q)):
            raise InvalidConfigurationError(f"q must be a finite vector of shape ({model.nq},), got {q.shape}")
        self.model, self.q, self.world = model, q, world
        self.data = data if data is not None else model.createData()
        if jacobians:
            pin.computeJointJacobians(model, self.data, q)
        else:
            pin.forwardKinematics(model, self.data, q)
        pin.updateFramePlacements(model, self.data)
        self.has_jacobians = jacobians
        self._distances: np.ndarray | None = None

    @property
    def distances(self) -> np.ndarray:
        """Signed distance (m) of every pair of ``world`` (empty without a world), computed once.

        The world's ``geometry_data`` then holds this state's witness points (for
        :meth:`carmkin.world.World.proximity`) until another state computes its distances.
        """
        if self._distances is None:
            self._distances = np.zeros(0) if self.world is None or not len(self.world) else self.world.distances(self.data)
        return self._distances

    @property
    def min_distance(self) -> float:
        """Smallest pair distance (m), ``inf`` without pairs."""
        d = self.distances
        return float(d.min()) if d.size else float("inf")

    def frame_pose(self, frame: str = SOURCE_FRAME) -> np.ndarray:
        """Pose (4, 4) of ``frame`` in the root frame."""
        return self.data.oMf[self.model.getFrameId(frame)].homogeneous

    @property
    def source_pose(self) -> np.ndarray:
        """Pose (4, 4) of ``xray_source`` in the table frame 0."""
        if not hasattr(self, "_source"):
            self._source = self.frame_pose(SOURCE_FRAME)
        return self._source
