"""Parallax-free panorama planning (§4.4, Table 4.3): from a principal point in the panorama to joint moves.

The panorama frame is the image of the reference X-ray pose ``P_ref`` (pose of ``xray_source`` in the
table frame 0). A shot is given by its principal point ``p`` (pixels) in that frame:

1. ``V_p = K⁻¹ p`` (normalized): the new principal axis in the reference source frame (eq. 4.18);
2. ``R`` = the minimal rotation taking the principal axis ``e_z`` to ``V_p`` (roll choice: no rotation about
   the axis beyond the tilt, see :func:`carmkin.imaging.rotation_between`); it is the orientation of the new
   view in the reference view (see ``docs/errata/panorama.md`` for the printed "from V_p to [0;0;1]");
3. ``H = K R K⁻¹`` maps the new image onto the panorama (Table 4.3 step 4 prints ``K⁻¹ R K``: erratum);
4. target pose ``P_ref · [R 0; 0 1]`` (eq. 4.19): same source position relative to the table;
5. closed-form IK (:mod:`carmkin.analytic_ik`, rules of §4.4.2), validity (§4.4.3,
   :mod:`carmkin.robot.validity`: joint ranges, collisions, principal axis meets the table top); the other
   branch is tried when the chosen one is invalid, and the QP IK (:mod:`carmkin.qp_ik`) when none is;
6. joint moves from the current configuration and the outline of the predicted image in the panorama.

Units: m and rad; pixels for image coordinates.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np
from scipy.optimize import brentq

from carmkin import imaging
from carmkin.errors import (
    PanoramaError,  # noqa: F401 (defined there, raised here)
)
from carmkin.model.bounds import MAX_LENGTH
from carmkin.model.kinematics import check_configuration
from carmkin.world import Obstacle, World
from carmkin.transforms import check_rigid_transform, pose_residual, segment_box_interval
from carmkin.validation import MAGNITUDE_LIMIT, real_array, real_scalar, rotation

#: Map categories, in the order of the colours of :func:`carmkin.panorama.figure.plot_validity_map`.
CATEGORIES = ("valid", "joint out of range", "collision", "table not in cone", "no IK solution")


#: Most shots one plan may hold: bounds the cost of a call (a femur needs three to five, a 2 m table a dozen).
MAX_SHOTS = 100
#: Largest number of principal points of one validity map (a 300 x 300 grid): bounds the cost of a call.
MAX_MAP_POINTS = 90_000
#: Tolerance on ``|‖direction‖ − 1|`` and on its component along the reference principal axis.
DIRECTION_TOLERANCE = 1e-9


def _configuration(system, q, name: str) -> np.ndarray:
    q = check_configuration(q, system.nq, name)
    if q.ndim != 1:
        raise PanoramaError(f"{name} must be one configuration ({system.nq},), got shape {q.shape}")
    return q


def _flag(value, name: str) -> bool:
    if not isinstance(value, (bool, np.bool_)):
        raise PanoramaError(f"{name} must be True or False, got {value!r}")
    return bool(value)


def _pixel(value, name: str = "principal point") -> np.ndarray:
    return real_array(value, f"{name} (u, v)", (2,), error=PanoramaError, unit="px")


def _direction(value) -> np.ndarray:
    d = real_array(value, "direction", (3,), error=PanoramaError)
    if abs(d[2]) > DIRECTION_TOLERANCE or abs(np.linalg.norm(d) - 1) > DIRECTION_TOLERANCE:
        raise PanoramaError(f"direction must be a unit (3,) vector ⟂ to the reference principal axis (to "
                            f"{DIRECTION_TOLERANCE:g}), got {d}")
    return d


def reference_configuration(system) -> np.ndarray:
    """Default reference configuration (nq,): every joint at the middle of its range.

    For the Siremobile preset that is wigwag, angular and orbital at 0°, the table translation at 0,
    vertical 200 mm and horizontal 100 mm.
    """
    return 0.5 * (system.lower + system.upper)


@dataclass
class Shot:
    """One planned X-ray shot.

    ``principal_point`` (2,) px in the panorama; ``axis`` (3,) unit V_p in the reference source frame;
    ``R`` (3, 3) orientation of the shot in the reference source frame; ``H`` (3, 3) shot image → panorama;
    ``target`` (4, 4) source pose in the table frame; ``q`` (nq,) planned joints (the chosen closed-form
    branch when invalid; NaN when there is no solution); ``path``: ``"closed_form"``, ``"single_axis"``
    (motorized table), ``"qp"`` or ``"none"``; ``valid``; ``reasons``: why not valid (empty when valid); ``category``: one of
    :data:`CATEGORIES`; ``moves`` (nq,): ``q − q_current`` (m, rad); ``outline`` (M, 2): border of the
    predicted image in the panorama (px); ``residual``: max(position m, angle rad) of FK(q) vs target.
    """

    principal_point: np.ndarray
    axis: np.ndarray
    R: np.ndarray
    H: np.ndarray
    target: np.ndarray
    q: np.ndarray
    path: str
    valid: bool
    reasons: tuple[str, ...]
    category: str
    moves: np.ndarray
    outline: np.ndarray
    residual: float
    validity: object = None
    ik: object = None

    @property
    def table_translation(self) -> float:
        """Move of d0 (m): the C-arm relative to the table along Z0 (the table moves by −Δd0)."""
        return float(self.moves[0])


def _category(report) -> str:
    if report is None:
        return "no IK solution"
    if report.joints:
        return "joint out of range"
    if report.collisions:
        return "collision"
    if not report.table_in_cone:
        return "table not in cone"
    return "valid"


class PanoramaPlanner:
    """Plans shots of a parallax-free panorama for ``system`` around the reference pose.

    ``q_reference`` (nq,): configuration of the reference (first) X-ray image, default
    :func:`reference_configuration`; ``P_ref`` = FK of it unless ``P_ref`` (4, 4) is given (then
    ``q_reference`` is only the starting configuration of the moves). ``obstacles``: extra bodies (table
    frame). ``fallback``: try the QP IK when no closed-form branch is valid. ``margin`` (m): collision
    margin of the validity check.
    """

    def __init__(self, system, q_reference=None, P_ref=None, obstacles: Sequence[Obstacle] = (),
                 fallback: bool = True, margin: float = 0.0) -> None:
        self.system = system
        q = reference_configuration(system) if q_reference is None else _configuration(system, q_reference,
                                                                                        "q_reference")
        self.q_reference = q
        self.P_ref = system.fk(q) if P_ref is None else check_rigid_transform(P_ref, "P_ref")
        self.K = system.carm.intrinsics()
        self.K_inv = np.linalg.inv(self.K)
        self.size = (system.carm.detector_columns, system.carm.detector_rows)
        if isinstance(obstacles, (str, bytes)) or not hasattr(obstacles, "__iter__") or not all(
                isinstance(o, Obstacle) for o in obstacles):
            raise PanoramaError(f"obstacles must be a sequence of carmkin.robot.collision.Obstacle, got {obstacles!r}")
        self.obstacles = tuple(obstacles)
        self.scene = World(system, self.obstacles)
        self.fallback = _flag(fallback, "fallback")
        self.margin = real_scalar(margin, "margin", error=PanoramaError, low=0.0, high=MAX_LENGTH, unit="m")

    # --- one shot (Table 4.3) ---------------------------------------------------------------------------
    def rotation_for(self, principal_point) -> tuple[np.ndarray, np.ndarray]:
        """``(V_p, R)``: unit principal axis K⁻¹p (reference source frame) and the minimal rotation e_z → V_p."""
        p = _pixel(principal_point)
        V = self.K_inv @ np.array([p[0], p[1], 1.0])
        V /= np.linalg.norm(V)
        return V, imaging.rotation_between((0.0, 0.0, 1.0), V)

    def target_pose(self, R) -> np.ndarray:
        """Eq. 4.19: ``P_ref · [R 0; 0 1]`` (4, 4), the source pose in the table frame."""
        M = np.eye(4)
        M[:3, :3] = rotation(R, "R", error=PanoramaError)
        return self.P_ref @ M

    def _solve(self, T, q_current, fallback: bool):
        """(q, path, report, ik, reasons) from the one solve of :func:`carmkin.qp_ik.solve` with this
        planner's rule (valid: joints, collisions at ``margin``, table in the cone) and scene: the first valid
        closed-form branch, else the QP, else the chosen branch that reaches the pose (invalid), else NaN."""
        from carmkin import qp_ik
        from carmkin.robot.validity import pose_in_cone

        # The QP cannot change whether the beam meets the table (that depends on the pose alone): skip it
        # when the pose misses the table.
        result = qp_ik.solve(self.system, T, q_current=q_current, world=self.scene,
                             options=qp_ik.QPIKOptions(safety_margin=self.margin),
                             accept=lambda report: report.valid, qp=fallback and pose_in_cone(self.system, T))
        if result.success:
            return result.q, result.path.value, result.validity, result.closed_form, ()
        reached = [b for b in result.branch_reports if b.reached]
        if not reached:
            return np.full(self.system.nq, np.nan), "none", None, result.closed_form, result.reasons
        return reached[0].q, "closed_form", reached[0].validity, result.closed_form, result.reasons

    def shot(self, principal_point, q_current=None, fallback: bool | None = None) -> Shot:
        """Plan the shot whose principal point is ``principal_point`` (u, v) px in the panorama.

        ``q_current`` (nq,): configuration the moves start from (default: the reference configuration);
        ``fallback``: try the QP IK when no closed-form branch is valid (default: the planner's setting).
        """
        q_current = self.q_reference if q_current is None else _configuration(self.system, q_current, "q_current")
        V, R = self.rotation_for(principal_point)
        H = imaging.rotation_homography(self.K, R)
        T = self.target_pose(R)
        fallback = self.fallback if fallback is None else _flag(fallback, "fallback")
        q, path, report, ik, reasons = self._solve(T, q_current, fallback)
        category = _category(report)
        valid = category == "valid"
        residual = pose_residual(self.system.fk(q, check_units=False), T) if np.all(np.isfinite(q)) else float("inf")
        outline = self.outline(H)
        return Shot(_pixel(principal_point), V, R, H, T, q, path, valid,
                    () if valid else reasons, category, q - q_current, outline, residual, report, ik)

    def outline(self, H, per_edge: int = 16) -> np.ndarray:
        """Border of an image mapped into the panorama by ``H`` (px); NaN where it leaves the half-space."""
        H = real_array(H, "H", (3, 3), error=PanoramaError)
        border = imaging.homogeneous(imaging.image_border(*self.size, per_edge))
        m = border @ H.T
        out = np.full((len(m), 2), np.nan)
        ahead = m[:, 2] > 1e-12
        out[ahead] = m[ahead, :2] / m[ahead, 2:]
        return out

    # --- a panorama along a line ----------------------------------------------------------------------
    def default_direction(self) -> np.ndarray:
        """Unit direction (3,) in the reference image plane along the table axis Z0 (the long axis)."""
        d = self.P_ref[:3, :3].T @ np.array([0.0, 0.0, 1.0])
        d[2] = 0.0
        if np.linalg.norm(d) < 1e-9:
            raise PanoramaError("the table axis is parallel to the principal axis: give a direction")
        return d / np.linalg.norm(d)

    def direction_from_pixels(self, du: float, dv: float) -> np.ndarray:
        """Unit direction (3,) on a plane ⟂ to the reference axis from a panorama direction (du, dv) px."""
        du = real_scalar(du, "du", error=PanoramaError, limit=MAGNITUDE_LIMIT, unit="px")
        dv = real_scalar(dv, "dv", error=PanoramaError, limit=MAGNITUDE_LIMIT, unit="px")
        d = np.array([du / self.K[0, 0], dv / self.K[1, 1], 0.0])
        big = np.abs(d).max()
        if big == 0.0:  # scaled by the largest component first: no underflow to a zero "unit" vector
            raise PanoramaError(f"direction must be a non-zero (du, dv), got {(du, dv)}")
        d = d / big
        return d / np.linalg.norm(d)

    def default_object_distance(self) -> float:
        """Distance (m) along the reference axis to where it leaves the table-top box (the patient side).

        Falls back to half the source-to-detector distance when the axis misses the table top.
        """
        table = self.system.table
        hit = segment_box_interval(self.P_ref[:3, 3], self.P_ref[:3, 2], table.top_center, table.top_size,
                                   -np.inf, np.inf)
        if hit is None or hit[1] <= 0:
            return 0.5 * self.system.carm.source_to_detector
        return hit[1]

    def extent(self, s: float, direction, distance: float) -> tuple[float, float]:
        """Interval of the line ``X(σ) = distance·e_z + σ·direction`` (reference frame, m) that the shot
        aimed at ``X(s)`` sees on its detector: ``(σ_lo, σ_hi)`` (m)."""
        s = real_scalar(s, "s", error=PanoramaError, high=MAX_LENGTH, low=-MAX_LENGTH, unit="m")
        direction = _direction(direction)
        distance = real_scalar(distance, "distance", error=PanoramaError, low=0.0, high=MAX_LENGTH, unit="m")
        if distance == 0.0:
            raise PanoramaError("object distance must be > 0 (m), got 0")
        c = np.array([0.0, 0.0, distance])
        _, R = self.rotation_for((self.K @ (c + s * direction))[:2] / (c + s * direction)[2])
        a, b = self.K @ R.T @ c, self.K @ R.T @ direction
        (w, h), lo, hi = self.size, -np.inf, np.inf
        constraints = [(a[2], b[2])]  # depth > 0
        for k, limit in ((0, -0.5), (1, -0.5)):
            constraints.append((a[k] - limit * a[2], b[k] - limit * b[2]))  # m_k/m_2 ≥ limit
        for k, limit in ((0, w - 0.5), (1, h - 0.5)):
            constraints.append((limit * a[2] - a[k], limit * b[2] - b[k]))  # m_k/m_2 ≤ limit
        for alpha, beta in constraints:  # alpha + σ beta ≥ 0
            if abs(beta) < 1e-15:
                if alpha < 0:
                    return (np.nan, np.nan)
                continue
            if beta > 0:
                lo = max(lo, -alpha / beta)
            else:
                hi = min(hi, -alpha / beta)
        return float(lo), float(hi)

    def line_shots(self, length: float, overlap: float = 0.0, direction=None,
                   distance: float | None = None) -> tuple[np.ndarray, np.ndarray, float, np.ndarray]:
        """Aim points along the line covering ``length`` (m) centred on the reference axis.

        Returns ``(s, extents, distance, direction)``: aim parameters (n,) (m along ``direction`` on the
        plane ⟂ to the reference axis at ``distance``), their seen intervals (n, 2), the distance and the
        unit direction. Shots are placed greedily from ``−length/2``: each starts ``overlap`` (fraction of
        the previous shot's interval, 0 ≤ overlap < 1) before the previous one ends; the last one reaches
        ``+length/2``.
        """
        length = real_scalar(length, "length", error=PanoramaError, low=0.0, high=MAX_LENGTH, unit="m")
        overlap = real_scalar(overlap, "overlap", error=PanoramaError, low=0.0, high=1.0)
        if length == 0.0 or overlap == 1.0:
            raise PanoramaError(f"length must be > 0 m and overlap < 1, got {length:g} m and {overlap:g}")
        direction = self.default_direction() if direction is None else _direction(direction)
        distance = self.default_object_distance() if distance is None else real_scalar(
            distance, "distance", error=PanoramaError, low=0.0, high=MAX_LENGTH, unit="m")
        if distance == 0.0:
            raise PanoramaError("object distance must be > 0 (m), got 0")
        start, end = -0.5 * length, 0.5 * length
        aims, extents = [], []
        target = start
        for _ in range(MAX_SHOTS):
            def gap(s):
                return self.extent(s, direction, distance)[0] - target
            step = max(distance, 1e-3)
            hi = target + step
            while gap(hi) < 0:
                hi += step
                if hi - target > 100 * step:
                    raise PanoramaError("cannot place a shot along the line (too oblique)")
            s = brentq(gap, target - step, hi, xtol=1e-13)
            lo_s, hi_s = self.extent(s, direction, distance)
            aims.append(s)
            extents.append((lo_s, hi_s))
            if hi_s >= end:
                break
            target = hi_s - overlap * (hi_s - lo_s)
        else:
            raise PanoramaError(f"more than {MAX_SHOTS} shots needed: a shorter length or a smaller overlap")
        return np.array(aims), np.array(extents), distance, direction

    def principal_point_of(self, s: float, direction, distance: float) -> np.ndarray:
        """Panorama pixel (2,) of the aim point ``distance·e_z + s·direction`` (reference frame)."""
        s = real_scalar(s, "s", error=PanoramaError, high=MAX_LENGTH, low=-MAX_LENGTH, unit="m")
        distance = real_scalar(distance, "distance", error=PanoramaError, low=0.0, high=MAX_LENGTH, unit="m")
        if distance == 0.0:
            raise PanoramaError("object distance must be > 0 (m), got 0")
        X = np.array([0.0, 0.0, distance]) + s * _direction(direction)
        m = self.K @ X
        return m[:2] / m[2]

    def plan(self, length: float, overlap: float = 0.0, direction=None, distance: float | None = None) -> "Plan":
        """Shots covering ``length`` (m) on the object plane (see :meth:`line_shots`), each planned from the
        previous valid shot's joints (the first from the reference configuration)."""
        aims, extents, distance, direction = self.line_shots(length, overlap, direction, distance)
        shots, q = [], self.q_reference
        for s in aims:
            shot = self.shot(self.principal_point_of(s, direction, distance), q_current=q)
            shots.append(shot)
            if shot.valid:  # an invalid shot cannot be taken: the next moves start where the C-arm is
                q = shot.q
        return Plan(shots, aims, extents, distance, direction, length, overlap)

    # --- validity map -----------------------------------------------------------------------------------
    def validity_map(self, us, vs, fallback: bool = False) -> np.ndarray:
        """Category index (len(vs), len(us)) into :data:`CATEGORIES` for each principal point (u, v) px.

        Starts every shot from the reference configuration; by default without the QP fallback (which
        cannot change a 6-DOF pose's two branches and costs ~30 ms per invalid point).
        """
        us = real_array(us, "us", (None,), error=PanoramaError, unit="px")
        vs = real_array(vs, "vs", (None,), error=PanoramaError, unit="px")
        if len(us) * len(vs) > MAX_MAP_POINTS:
            raise PanoramaError(f"a validity map holds at most {MAX_MAP_POINTS} points, got {len(us)} x {len(vs)}")
        fallback = _flag(fallback, "fallback")
        out = np.empty((len(vs), len(us)), dtype=int)
        for i, v in enumerate(vs):
            for j, u in enumerate(us):
                out[i, j] = CATEGORIES.index(self.shot((u, v), fallback=fallback).category)
        return out


@dataclass
class Plan:
    """A panorama plan: ``shots``, aim parameters ``aims`` (m), seen intervals ``extents`` (n, 2) (m) on
    the object plane at ``distance`` (m) along ``direction`` (unit, reference source frame)."""

    shots: list
    aims: np.ndarray
    extents: np.ndarray
    distance: float
    direction: np.ndarray
    length: float
    overlap: float

    @property
    def valid(self) -> bool:
        return all(s.valid for s in self.shots)

    @property
    def table_translations(self) -> np.ndarray:
        """Δd0 (m) of each shot from the previous valid one (the first from the reference configuration)."""
        return np.array([s.table_translation for s in self.shots])
