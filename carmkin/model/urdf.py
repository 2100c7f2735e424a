"""URDF generation and the Pinocchio models built from it: ``urdf/carm_table.urdf.xacro`` expanded with the
numbers of a :class:`~carmkin.model.system.CArmSystem`, then parsed by Pinocchio (:func:`build_models`).

The xacro file holds the structure (links, joints, primitives); every number is passed as an xacro argument
computed here from the system, so nothing is typed twice. Expansion uses the ``xacro`` package directly,
which needs no ROS installation.
"""

from __future__ import annotations

from importlib import resources

import numpy as np
import pinocchio as pin

from carmkin.model import mount_joints
from carmkin.model.table_joints import xacro_spec

#: Number of boxes approximating the C's arc.
C_SEGMENTS = 8


def xacro_path():
    """Path of the shipped ``carm_table.urdf.xacro``."""
    return resources.files("carmkin.urdf") / "carm_table.urdf.xacro"


def _fmt(*values: float) -> str:
    return " ".join(repr(float(v)) for v in values)


def xacro_arguments(system) -> dict[str, str]:
    """The xacro arguments (strings, SI units) that describe ``system``, a
    :class:`~carmkin.model.system.CArmSystem` (which calls this module through ``system.urdf()`` and
    ``system.pinocchio()``; it is not imported here, so the two modules form no circle)."""
    carm, body, table = system.carm, system.body, system.table
    args: dict[str, str] = {}
    for i, row in enumerate(system.dh_table):
        args.update({f"r{i}_theta": _fmt(row.theta), f"r{i}_d": _fmt(row.d), f"r{i}_a": _fmt(row.a),
                     f"r{i}_alpha": _fmt(row.alpha)})
    row0 = system.dh_table[0]  # its constant part Rz(θ) Tz(d) Tx(a) Rx(α) as one URDF origin
    args.update(r0_a_cos=_fmt(row0.a * np.cos(row0.theta)), r0_a_sin=_fmt(row0.a * np.sin(row0.theta)),
                table_joints=xacro_spec(table.joints))
    for name, joint_range in zip(system.joint_names, system.joint_ranges):
        args[f"{name}_lower"], args[f"{name}_upper"] = _fmt(joint_range.lower), _fmt(joint_range.upper)
    source = system.xray_in_flange
    args.update(
        gamma3=_fmt(system.setup.gamma3),
        D3=_fmt(system.setup.D3),
        source_xyz=_fmt(*source[:3, 3]),
        source_rpy=_fmt(*pin.rpy.matrixToRpy(source[:3, :3])),
        source_to_detector=_fmt(carm.source_to_detector),
        bracket_y=_fmt(carm.a2),
        detector_width=_fmt(carm.detector_width),
        detector_height=_fmt(carm.detector_height),
        arm_length=_fmt(carm.arm_length),
        c_radius=_fmt(carm.source_to_orbital_axis),
        c_arc=_fmt(carm.source_to_orbital_axis if body.c_radius is None else body.c_radius),
        table_size=_fmt(*table.top_size),
        table_center=_fmt(*table.top_center),
        floor_height=_fmt(body.floor_height),
        cart_size=_fmt(*body.cart_size),
        column_width=_fmt(body.column_width),
        c_thickness=_fmt(body.c_thickness),
        c_depth=_fmt(body.c_depth),
        source_housing=_fmt(*body.source_housing),
        detector_thickness=_fmt(body.detector_thickness),
        ceiling_mount=str(body.mount == "ceiling"),
        ceiling_height=_fmt(body.ceiling_height),
        c_segments=str(C_SEGMENTS),
    )
    if system.mount.joints:  # the floor stays with the table reference while the mount moves the C-arm base
        K = system.carm_base_pose
        floor = K[:3, 3] + body.floor_height * K[:3, 2]
        joints, boxes = mount_joints.xacro_spec(system.mount, K[:3, 3])
        args.update(mount_joints=joints, mount_boxes=boxes, mount_width=_fmt(system.mount.link_width),
                     floor_xyz=_fmt(*floor), floor_rpy=_fmt(*mount_joints.rpy(K[:3, :3])))
    return args


def urdf_text(system) -> str:
    """URDF XML of ``system`` (a :class:`~carmkin.model.system.CArmSystem`)."""
    import xacro

    with resources.as_file(xacro_path()) as path:
        document = xacro.process_file(str(path), mappings=xacro_arguments(system))
        for node in document.childNodes:  # xacro's banner names the file: no machine path in the URDF
            if node.nodeType == node.COMMENT_NODE and str(path) in node.data:
                node.data = node.data.replace(str(path), f"carmkin.urdf/{path.name}")
    return document.toprettyxml(indent="  ")


def build_models(urdf: str) -> tuple[pin.Model, pin.GeometryModel, pin.GeometryModel]:
    """``(model, collision_model, visual_model)`` from URDF text; the root link is the table frame 0."""
    model = pin.buildModelFromXML(urdf)
    collision = pin.buildGeomFromUrdfString(model, urdf, pin.GeometryType.COLLISION)
    visual = pin.buildGeomFromUrdfString(model, urdf, pin.GeometryType.VISUAL)
    return model, collision, visual
