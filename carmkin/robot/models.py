"""Pinocchio models (kinematic, collision, visual) built from the generated URDF."""

from __future__ import annotations

import pinocchio as pin


def build_models(urdf: str) -> tuple[pin.Model, pin.GeometryModel, pin.GeometryModel]:
    """``(model, collision_model, visual_model)`` from URDF text; the root link is the table frame 0."""
    model = pin.buildModelFromXML(urdf)
    collision = pin.buildGeomFromUrdfString(model, urdf, pin.GeometryType.COLLISION)
    visual = pin.buildGeomFromUrdfString(model, urdf, pin.GeometryType.VISUAL)
    return model, collision, visual


def frame_placement(model: pin.Model, data: pin.Data, frame: str):
    """Placement (pin.SE3) of ``frame`` in the root (table) frame after a forward-kinematics pass."""
    return data.oMf[model.getFrameId(frame)]
