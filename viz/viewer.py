"""`CArmViewer`: the C-arm + table in meshcat, with the X-ray cone, frames, ghosts, distances and moves.

Scene frame: everything is expressed in the table frame 0 (the root of the Pinocchio model), under one
meshcat node ``/meshcat/carmkin`` whose constant transform only rotates the table frame so that the C-arm
cart stands upright: the rotation of the cart frame ``carm_cart`` at q = 0, inverted. The origin stays the
table origin (the isocentre for the presets), which is where the browser camera looks. In the browser, Z
points up along the column, the floor is horizontal and the table stays still; the table translation d0
moves the whole C-arm (cart included) along the table, as the chain says (d0 is the C-arm's displacement
relative to the table).

Node layout under ``/meshcat/carmkin``: ``robot`` (Pinocchio's visuals; collisions hidden), ``cone`` (the
X-ray pyramid at ``xray_source``), ``frames/table`` and ``frames/xray_source`` (triads), ``ghost`` (the
robot and cone at a target configuration), ``targets/<name>`` (source housing + cone at a 4x4 pose),
``shots/<name>/<i>`` (cones of planned shots), ``distances`` (C-arm parts near the table/floor/patient, and
``distances/collided/<body>``: the bodies they collide with, red).
"""

from __future__ import annotations

import meshcat
import meshcat.geometry as mg
import numpy as np
import pinocchio as pin
from meshcat.animation import Animation
from pinocchio.visualize import MeshcatVisualizer

from carmkin.errors import InvalidConfigurationError, VisualizationError
from carmkin.model import kinematics
from carmkin.model.system import CArmSystem
from carmkin.transforms import check_rigid_transform
from carmkin.world.obstacles import link_of

from . import shapes
from .distances import DistanceChecker, PairDistance, distance_color
from .static import RecordingWindow, offline_visualizer

ROOT = "carmkin"
#: Camera position in the scene frame (m), looking at the table origin: front-right, above.
CAMERA_OFFSET = (1.4, 1.7, 0.9)
#: Colour (RGB in [0, 1]) of a body the C-arm is in collision with (table top, patient body), over its own.
COLLIDED_RGB = (0.9, 0.0, 0.0)
#: Links left out of the ghost copy: the environment, which does not move with the C-arm joints.
NOT_IN_GHOST = ("table", "floor")


def check_configuration(system: CArmSystem, q, name: str = "q") -> np.ndarray:
    """``q`` as a (nq,) float array; :class:`InvalidConfigurationError` naming the joint if out of its range.

    A value on a limit is in range; nothing is clipped. Messages in m (prismatic) or rad and degrees.
    """
    q = kinematics.check_configuration(q, system.nq, name)
    if q.ndim != 1:
        raise InvalidConfigurationError(f"{name} must be one configuration of shape ({system.nq},), got {q.shape}")
    for value, joint_name, joint_range, prismatic in zip(q, system.joint_names, system.joint_ranges,
                                                         system.prismatic):
        excess = float(joint_range.excess(value))
        if excess != 0.0:
            unit = "m" if prismatic else "rad"
            degrees = "" if prismatic else f" ({np.degrees(value):.4g}°)"
            raise InvalidConfigurationError(
                f"{name}: {joint_name} = {value:.6g} {unit}{degrees} is outside [{joint_range.lower:.6g}, "
                f"{joint_range.upper:.6g}] {unit} by {excess:+.3g} {unit}")
    return q


def interpolate(q_from, q_to, frames: int) -> np.ndarray:
    """(frames, nq) configurations from ``q_from`` to ``q_to``, linear in joint space, both ends included."""
    if frames < 2:
        raise InvalidConfigurationError(f"a move needs at least 2 frames, got {frames}")
    s = np.linspace(0.0, 1.0, frames)[:, None]
    return (1.0 - s) * np.asarray(q_from, dtype=float) + s * np.asarray(q_to, dtype=float)


class CArmViewer:
    """Draws a :class:`CArmSystem` into a meshcat visualizer.

    Args:
        system: the C-arm + table.
        vis: a ``meshcat.Visualizer``; ``None`` records offline (see :func:`carmkin.viz.offline_visualizer`,
            then :meth:`static_html`). For a live page use ``LoopbackServer().start().visualizer()``.
        q: initial configuration (m, rad); ``None`` is the middle of the joint ranges.
        root: the meshcat node everything is drawn under (two viewers share one visualizer under two roots, as
            the two planes of a biplane do: ``carmkin.viz.biplane``).
        scene_in_world: the root's constant rotation (4, 4); ``None``: this system's cart upright (see above).
    """

    def __init__(self, system: CArmSystem, vis: meshcat.Visualizer | None = None, q=None, root: str = ROOT,
                 scene_in_world=None) -> None:
        self.system = system
        self.vis = offline_visualizer(f"carmkin: {system.name}") if vis is None else vis
        self.root_path = root
        self.root = self.vis[root]
        model, collision_model, visual_model = system.pinocchio()
        self.model = model
        self.robot = self._load_robot(f"{root}/robot", collision_model, visual_model, color=None)
        self.data = self.robot.data  # the one kinematic state of the displayed q: robot, cone, triad, distances
        self._scratch = model.createData()  # for configurations that are not displayed (ghost cone, distances)
        self._ghost: MeshcatVisualizer | None = None
        self._distances: DistanceChecker | None = None
        self._distances_patient: int | None = None  # id() of the patient the checker was built with
        self.q = check_configuration(system, (system.lower + system.upper) / 2 if q is None else q)
        self.scene_in_world = np.eye(4)  # constant rotation, see the module docstring
        self.scene_in_world[:3, :3] = self._frame_pose(pin.neutral(model), "carm_cart", self._scratch)[:3, :3].T
        if scene_in_world is not None:
            self.scene_in_world = check_rigid_transform(scene_in_world, "scene_in_world")
        self.root.set_transform(self.scene_in_world)
        self._draw_cone(self.root["cone"], shapes.CONE_RGB, 0.3)
        self._draw_triad(self.root["frames/table"], np.eye(4), 0.3)
        self._draw_triad(self.root["frames/xray_source"], np.eye(4), 0.2)
        self._set_camera()
        self.display(self.q)

    # --- current configuration ------------------------------------------------------------------------
    def display(self, q) -> None:
        """Move the robot, the cone and the source triad to ``q`` (nq,) (m, rad): one forward kinematics pass."""
        self.q = check_configuration(self.system, q)
        source = self._frame_pose(self.q, "xray_source", self.data)
        self.robot.display()  # places the visuals from self.data, no second FK
        self.root["cone"].set_transform(source)
        self.root["frames/xray_source"].set_transform(source)

    # --- targets, ghosts and shots -------------------------------------------------------------------
    def show_ghost(self, q_target, show_robot: bool = True) -> None:
        """A translucent copy of the robot (and its cone) at configuration ``q_target`` (m, rad)."""
        q_target = check_configuration(self.system, q_target, "q_target")
        if show_robot:
            if self._ghost is None:
                self._ghost = self._load_robot(f"{self.root_path}/ghost/robot", None, self._ghost_model(),
                                               color=[*shapes.GHOST_RGB, 0.3])
        data = self._ghost.data if show_robot else self._scratch
        source = self._frame_pose(q_target, "xray_source", data)
        if show_robot:
            self._ghost.display()
        self._draw_cone(self.root["ghost/cone"], shapes.GHOST_RGB, 0.2)
        self.root["ghost/cone"].set_transform(source)

    def show_target_pose(self, T_source, name: str = "target") -> None:
        """A translucent source housing and cone at ``T_source`` (4x4 pose of ``xray_source``, table frame, m)."""
        T_source = check_rigid_transform(T_source, "T_source")
        node = self.root[f"targets/{name}"]
        node.delete()
        fid = self.model.getFrameId("xray_source")
        frame_in_joint = self.model.frames[fid].placement
        _, _, visual_model = self.system.pinocchio()
        for geometry in visual_model.geometryObjects:
            if geometry.parentFrame == fid:  # the housing, placed relative to the source frame
                obj = self.robot.loadPrimitive(geometry)
                node[geometry.name].set_object(obj, mg.MeshLambertMaterial(
                    color=shapes.hex_color(shapes.GHOST_RGB), opacity=0.35, transparent=True))
                node[geometry.name].set_transform((frame_in_joint.inverse() * geometry.placement).homogeneous)
        self._draw_cone(node["cone"], shapes.GHOST_RGB, 0.2)
        node.set_transform(T_source)

    def draw_shots(self, poses, name: str = "planned", rgb=(0.95, 0.35, 0.85)) -> None:
        """Cones at a list of source poses (N, 4, 4) in the table frame (m), e.g. a panorama's shots."""
        poses = check_rigid_transform(np.asarray(poses, dtype=float).reshape(-1, 4, 4), "poses", batch=True)
        node = self.root[f"shots/{name}"]
        node.delete()
        for i, pose in enumerate(poses):
            self._draw_cone(node[str(i)], rgb, 0.12)
            node[str(i)].set_transform(pose)

    # --- distances ------------------------------------------------------------------------------------
    def show_distances(self, q=None, margin: float = 0.1, patient=None) -> list[PairDistance]:
        """Colour the C-arm parts within ``margin`` (m) of the table top, the floor or the ``patient`` (as
        :class:`carmkin.world.World` takes it; draw it with :func:`carmkin.viz.views.draw_patient`), at ``q``
        (default: current).

        Each close part gets a translucent overlay, red when in collision (distance <= 0) through orange to
        yellow at ``margin``, and a line between the nearest points. A body the C-arm collides with (a patient
        body, the table top) is painted red too (:data:`COLLIDED_RGB`), so that a picture shows every collision
        the distances report. Returns all pair distances.
        """
        if not margin > 0:
            raise VisualizationError(f"margin must be > 0 m, got {margin}")
        key = id(patient) if patient is not None else None
        if self._distances is None or self._distances_patient != key:
            self._distances, self._distances_patient = DistanceChecker(self.system, patient), key
        checker = self._distances
        if q is None:  # the displayed configuration: its kinematics is in self.data already
            pairs = checker.distances(data=self.data)
        else:
            pin.forwardKinematics(self.model, self._scratch, check_configuration(self.system, q))
            pairs = checker.distances(data=self._scratch)
        node = self.root["distances"]
        node.delete()
        closest: dict[str, PairDistance] = {}
        for pair in pairs:
            if pair.distance < margin and (pair.part not in closest or pair.distance < closest[pair.part].distance):
                closest[pair.part] = pair
        for part, pair in closest.items():  # checker.collision_data is placed at this configuration
            color = shapes.hex_color(distance_color(pair.distance, margin))
            self._overlay(node[part], checker, part, color)
            segment = np.array([pair.point_part, pair.point_obstacle], dtype=np.float32).T
            node[f"{part}_to_{pair.obstacle}"].set_object(
                mg.LineSegments(mg.PointsGeometry(segment), mg.LineBasicMaterial(color=color)))
        for obstacle in sorted({p.obstacle for p in pairs if p.in_collision and link_of(p.obstacle) != "floor"}):
            self._overlay(node[f"collided/{obstacle}"], checker, obstacle, shapes.hex_color(COLLIDED_RGB))
        return pairs

    def _overlay(self, node, checker: DistanceChecker, name: str, color: int) -> None:
        """A translucent copy of collision geometry ``name``, 3 % larger, where ``checker`` last placed it."""
        gid = checker.collision_model.getGeometryId(name)
        obj = self.robot.loadPrimitive(checker.collision_model.geometryObjects[gid])
        node.set_object(obj, mg.MeshLambertMaterial(color=color, opacity=0.6, transparent=True))
        node.set_transform(checker.collision_data.oMg[gid].homogeneous @ np.diag([1.03, 1.03, 1.03, 1.0]))

    # --- moves ----------------------------------------------------------------------------------------
    def animate(self, q_to, q_from=None, frames: int = 40, fps: float = 20.0, repetitions: int = 1,
                play: bool = True) -> np.ndarray:
        """Animate a move from ``q_from`` (default: current) to ``q_to``, linear in joint space (m, rad).

        Sends one meshcat animation (robot, cone, source triad) that the browser plays by itself, with
        play/pause/scrub controls in its "Animations" panel: nothing waits for a browser. The robot ends at
        ``q_to``. The distance overlay belongs to one configuration and is removed. Returns the
        (frames, nq) configurations.
        """
        q_from = self.q if q_from is None else check_configuration(self.system, q_from, "q_from")
        q_to = check_configuration(self.system, q_to, "q_to")
        return self.animate_path(interpolate(q_from, q_to, frames), fps, repetitions, play)

    def animate_path(self, path, fps: float = 20.0, repetitions: int = 1, play: bool = True) -> np.ndarray:
        """Animate the configurations ``path`` (frames, nq) (m, rad), one per frame at ``fps``: a planned
        trajectory sampled at ``fps`` plays at its own speed (:meth:`animate` for a straight move). The robot
        ends at the last configuration. Returns ``path``."""
        path = np.asarray(path, dtype=float)
        if path.ndim != 2 or path.shape[1] != self.system.nq or not len(path):
            raise VisualizationError(f"path must have shape (frames, {self.system.nq}) (m, rad), got {path.shape}")
        for q in path[[0, -1]]:
            check_configuration(self.system, q, "path")
        if not fps > 0:
            raise VisualizationError(f"fps must be > 0, got {fps}")
        self.root["distances"].delete()
        animation = Animation(default_framerate=fps)
        geometry_data = self.robot.visual_data
        for i, q in enumerate(path):  # one FK per frame, in the one Data of the displayed robot
            frame = animation.at_frame(self.vis, i)
            source = self._frame_pose(q, "xray_source", self.data)
            pin.updateGeometryPlacements(self.model, self.data, self.robot.visual_model, geometry_data)
            for gid, geometry in enumerate(self.robot.visual_model.geometryObjects):
                name = self.robot.getViewerNodeName(geometry, pin.GeometryType.VISUAL)
                frame[name].set_transform(geometry_data.oMg[gid].homogeneous)
            frame[f"{self.root_path}/cone"].set_transform(source)
            frame[f"{self.root_path}/frames/xray_source"].set_transform(source)
        self.display(path[-1])
        self.vis.set_animation(animation, play=play, repetitions=repetitions)
        return path

    # --- output ---------------------------------------------------------------------------------------
    def static_html(self) -> str:
        """The scene as one self-contained HTML page (three.js viewer inlined, ~0.9 MB)."""
        return self.vis.static_html()

    def save_html(self, path) -> None:
        """Write :meth:`static_html` to ``path``."""
        with open(path, "w", encoding="utf-8") as stream:
            stream.write(self.static_html())

    def _repr_html_(self) -> str:
        """Inline display in Jupyter: the recorded page in an iframe, or the live page when served."""
        if isinstance(self.vis.window, RecordingWindow):
            return self.vis.render_static(height=480).data
        return self.vis.jupyter_cell(height=480).data

    # --- internals ------------------------------------------------------------------------------------
    def _load_robot(self, root: str, collision_model, visual_model, color) -> MeshcatVisualizer:
        robot = MeshcatVisualizer(self.model, collision_model, visual_model)
        robot.initViewer(viewer=self.vis)
        robot.loadViewerModel(rootNodeName=root, visual_color=color)
        return robot

    def _ghost_model(self) -> pin.GeometryModel:
        """The visual model without the table and the floor."""
        _, _, visual_model = self.system.pinocchio()
        ghost = pin.GeometryModel()
        for geometry in visual_model.geometryObjects:
            if self.model.frames[geometry.parentFrame].name not in NOT_IN_GHOST:
                ghost.addGeometryObject(geometry)
        return ghost

    def _frame_pose(self, q, frame: str, data: pin.Data) -> np.ndarray:
        """Forward kinematics of ``q`` into ``data`` (joints and frames); the pose (4x4) of ``frame``."""
        pin.framesForwardKinematics(self.model, data, np.asarray(q, dtype=float))
        return data.oMf[self.model.getFrameId(frame)].homogeneous

    def _draw_cone(self, node, rgb, opacity: float) -> None:
        surface, outline = shapes.xray_cone(self.system.carm, rgb, opacity)
        node["surface"].set_object(surface)
        node["outline"].set_object(outline)

    def _draw_triad(self, node, pose: np.ndarray, length: float) -> None:
        for axis, (geometry, material, placement) in zip("xyz", shapes.triad(length)):
            node[axis].set_object(geometry, material)
            node[axis].set_transform(placement)
        node.set_transform(pose)

    def _set_camera(self) -> None:
        x, y, z = CAMERA_OFFSET  # the camera looks at the world origin, the table origin
        self.vis["/Cameras/default/rotated/<object>"].set_property("position", [x, z, -y])  # three.js is Y-up
        self.vis["/Grid"].set_property("visible", False)  # the model has its own floor
