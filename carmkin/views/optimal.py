"""Optimal-view maps of real anatomy that know the C-arm: the best view of a curved vessel, the best
*reachable* one, what it costs, and how to take it; the reachable views edge-on to a valve plane.

:func:`optimal_view_map` fills every (primary, secondary) cell — reachable or not — with the foreshortening
and overlap of a centreline (:mod:`carmkin.views.metrics`) at the cell's **nominal view**: the XA angles of the
patient at rotation 0 (:func:`carmkin.interop.dicom.pose_from_xa_angles`), the target at the isocentre, the
source the system's source–isocentre distance (``system.carm.orbital_offset``) from it and the detector at its
SID with its pixel size (:func:`carmkin.imaging.intrinsics`) — the geometry of the literature's optimal-view
maps, the same for every cell so that cells compare. Reachability and clearance come from
:func:`~carmkin.views.reach_map` on the same grid with the same patient. The combined score is
``weights[0] · foreshortening + weights[1] · overlap`` (lower is better; :data:`DEFAULT_WEIGHTS`).

:func:`plane_views` searches the views whose beam lies in a plane (beam · normal = 0: the annulus seen
edge-on, TAVI's "line of perpendicularity") for the reachable ones and the one that best separates the
plane's points (cusps). Lengths in m, angles in degrees where named ``_deg``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from carmkin.errors import AnatomyError, ViewError
from carmkin.validation import real_array, real_scalar

from . import metrics, search
from .anatomy import MAX_RADIUS, Centreline, Plane, as_centreline, check_inside_patient, plane_from_points
from .maps import ReachMap, reach_map
from .plan import DEFAULT_MARGIN, ViewPlan, _table_samples, plan_view, reference, world_for
from .segment import FAMILY_SIZE
from .view import View, _patient_frame, _point

#: Weights (foreshortening, overlap) of the combined score: equal, as Chen & Carroll's optimal-view map
#: combines the two maps (both fractions, 0 best).
DEFAULT_WEIGHTS = (0.5, 0.5)


@dataclass(frozen=True)
class OptimalViewMap:
    """Per cell (P, S): ``foreshortening``, ``worst_foreshortening``, ``overlap`` (fractions), ``score``
    (``weights`` · (foreshortening, overlap)), ``reachable``, ``clearance`` (m, NaN where unreachable); the
    ``reach`` map itself; ``optimal`` (primary_deg, secondary_deg) the best-scoring cell, ``best_reachable``
    the best reachable cell or ``None``; ``loss`` the best reachable cell's score, foreshortening and overlap
    minus the optimum's (``None`` when nothing is reachable); ``plan`` the :class:`ViewPlan` of the best
    reachable view; ``distance`` the source–target distance (m) of the nominal views; ``target`` (3,) m;
    ``plan_metrics`` the plan's own ``foreshortening``, ``worst_foreshortening``, ``overlap`` (fractions) and
    ``distance`` (m, source–target along its beam), at the source pose where the plan stands
    (``system.fk(plan.q)``: its distance and roll, not the cell's nominal view; ``None`` without a successful
    plan)."""

    primary_deg: np.ndarray
    secondary_deg: np.ndarray
    target: np.ndarray
    foreshortening: np.ndarray
    worst_foreshortening: np.ndarray
    overlap: np.ndarray
    score: np.ndarray
    weights: tuple
    reachable: np.ndarray
    clearance: np.ndarray
    reach: ReachMap
    optimal: tuple
    best_reachable: tuple | None
    loss: dict | None
    plan: ViewPlan | None
    distance: float
    plan_metrics: dict | None = None

    @property
    def optimum_reachable(self) -> bool:
        """Whether the optimal cell itself is reachable."""
        return self.best_reachable is not None and self.best_reachable == self.optimal

    def cell(self, angles) -> tuple[int, int]:
        """Grid indices of ``(primary_deg, secondary_deg)`` (a cell of this map)."""
        return int(np.argmin(np.abs(self.primary_deg - angles[0]))), int(np.argmin(np.abs(self.secondary_deg - angles[1])))

    def summary(self) -> list[str]:
        """The answer in a clinician's words, one line each (angles in deg, fractions in %, clearance in mm)."""
        lines = []
        for label, angles in (("optimal view", self.optimal), ("best reachable view", self.best_reachable)):
            if angles is None:
                lines.append(f"{label}: none (no cell of the map is reachable)")
                continue
            i, j = self.cell(angles)
            clear = f", clearance {self.clearance[i, j] * 1e3:.1f} mm" if self.reachable[i, j] else ", unreachable"
            lines.append(f"{label}: {_describe(angles)}: foreshortening {100 * self.foreshortening[i, j]:.2f} % (worst "
                         f"segment {100 * self.worst_foreshortening[i, j]:.2f} %), overlap {100 * self.overlap[i, j]:.2f} %, "
                         f"score {self.score[i, j]:.4f}{clear}")
        if self.best_reachable is not None:
            if self.optimum_reachable:
                lines.append("the optimal view is reachable")
            else:
                lines.append(f"the optimal view is unreachable; the best reachable view loses {self.loss['score']:.4f} of "
                             f"score ({100 * self.loss['foreshortening']:+.2f} % foreshortening, "
                             f"{100 * self.loss['overlap']:+.2f} % overlap)")
        if self.plan_metrics is not None:
            m = self.plan_metrics
            lines.append(f"the plan stands {1e3 * m['distance']:.0f} mm from the target: foreshortening "
                         f"{100 * m['foreshortening']:.2f} % (worst segment {100 * m['worst_foreshortening']:.2f} %), "
                         f"overlap {100 * m['overlap']:.2f} % there")
        return lines


def _describe(angles) -> str:
    p, s = angles
    return f"{abs(p):.1f}° {'LAO' if p >= 0 else 'RAO'}, {abs(s):.1f}° {'CRA' if s >= 0 else 'CAU'}"


def _weights(value) -> tuple[float, float]:
    w = real_array(value, "weights", (2,), error=ViewError)
    if np.any(w < 0) or not np.any(w > 0):
        raise ViewError(f"weights (foreshortening, overlap) must be non-negative and not both 0, got {w.tolist()}")
    return float(w[0]), float(w[1])


def _radius(value, name="radius") -> float:
    from carmkin.errors import CentrelineError

    return real_scalar(value, name, error=CentrelineError, low=0.0, high=MAX_RADIUS, unit="m")


def _others(others, radius) -> tuple[list[Centreline], list]:
    if isinstance(others, np.ndarray) and others.ndim == 3:  # (K, M, 3): K vessels of M points each
        others = list(others)
    if isinstance(others, (np.ndarray, str, bytes)) or isinstance(others, Centreline) or not hasattr(others, "__iter__"):
        raise AnatomyError("others must be a sequence of centrelines ((M, 3) arrays in m or Centreline), got "
                           f"{type(others).__name__} {getattr(others, 'shape', '')}".rstrip())
    lines = [as_centreline(o, f"others[{k}]") for k, o in enumerate(others)]
    return lines, [c.radii if c.radii is not None else radius for c in lines]


def _position(patient, position):
    if position is None:
        return patient if patient is not None and hasattr(patient, "pose") else "HFS"
    return position


def optimal_view_map(system, centreline, primary_deg=np.arange(-90, 91), secondary_deg=np.arange(-45, 46),
                     patient=None, others=(), target=None, *, radius: float = metrics.DEFAULT_RADIUS,
                     weights=DEFAULT_WEIGHTS, margin: float = DEFAULT_MARGIN, position=None,
                     workers: int | None = None, table_samples=None, plan: bool = True) -> OptimalViewMap:
    """The optimal-view map of ``centreline`` ((N, 3) m, table frame, or a :class:`Centreline`) over
    ``primary_deg`` × ``secondary_deg`` (XA angles, deg) for ``system`` with ``patient`` (as
    :func:`~carmkin.views.reach_map`; a patient model must contain the anatomy). ``others``: the other
    vessels, (M, 3) m each, drawn as tubes of their radii or ``radius`` (m, default
    :data:`carmkin.views.metrics.DEFAULT_RADIUS`). ``target`` (3,) m: default the centreline's arc midpoint.
    ``plan``: plan the best reachable view (:func:`plan_view`, no ``q_current``)."""
    from carmkin.validation import flag

    line = as_centreline(centreline, "centreline")
    radius = _radius(radius)
    plan = flag(plan, "plan", error=ViewError)
    lines, radii = _others(others, radius)
    weights = _weights(weights)
    target = line.midpoint if target is None else _point(target, "target")
    if patient is not None and callable(getattr(patient, "obstacles", None)):
        for c in [line, *lines]:
            check_inside_patient(c.points, patient, c.name)
    position = _position(patient, position)
    reach = reach_map(system, target, primary_deg, secondary_deg, patient, position=position, margin=margin,
                      workers=workers, table_samples=table_samples)
    p, s = reach.primary_deg, reach.secondary_deg
    P, S = np.meshgrid(p, s, indexing="ij")
    distance = float(system.carm.orbital_offset)
    poses = metrics.xa_poses(P.ravel(), S.ravel(), target, distance, _patient_frame(position)[:3, :3])
    F, W = metrics.foreshortening(line.points, poses, distance)
    if lines:
        from carmkin.imaging import intrinsics

        O = metrics.overlap(line.points, [c.points for c in lines], poses, intrinsics(system)[0], radii)
    else:
        O = np.zeros(len(poses))
    shape = P.shape
    score = (weights[0] * F + weights[1] * O).reshape(shape)
    F, W, O = F.reshape(shape), W.reshape(shape), O.reshape(shape)
    o = np.unravel_index(int(np.argmin(score)), shape)
    optimal = (float(p[o[0]]), float(s[o[1]]))
    best, loss, the_plan = None, None, None
    if reach.reachable.any():
        b = np.unravel_index(int(np.argmin(np.where(reach.reachable, score, np.inf))), shape)
        best = (float(p[b[0]]), float(s[b[1]]))
        loss = {"score": float(score[b] - score[o]), "foreshortening": float(F[b] - F[o]),
                "overlap": float(O[b] - O[o])}
        if plan:
            view = View.from_angles(best[0], best[1], target, position, name="best reachable")
            the_plan = plan_view(system, view, patient, margin=margin, nearest=False, table_samples=table_samples,
                                 qp=False)
    clearance = np.where(reach.reachable, reach.clearance, np.nan)
    plan_metrics = None
    if the_plan is not None and the_plan.success:
        plan_metrics = _metrics_at(system, system.fk(the_plan.q), line, lines, radii, target)
    return OptimalViewMap(p, s, target, F, W, O, score, weights, reach.reachable, clearance, reach, optimal, best,
                          loss, the_plan, distance, plan_metrics)


def _metrics_at(system, pose, line, lines, radii, target) -> dict:
    """Foreshortening, worst foreshortening, overlap and the source–target distance along the beam of the view
    at ``pose`` (4, 4), the source pose a plan stands at (issue 41: the map's cells are nominal views)."""
    pose = np.asarray(pose, dtype=float)[None]
    distance = float(pose[0, :3, 2] @ (np.asarray(target, dtype=float) - pose[0, :3, 3]))
    F, W = metrics.foreshortening(line.points, pose, distance)
    O = np.zeros(1)
    if lines:
        from carmkin.imaging import intrinsics

        O = metrics.overlap(line.points, [c.points for c in lines], pose, intrinsics(system)[0], radii)
    return {"foreshortening": float(F[0]), "worst_foreshortening": float(W[0]), "overlap": float(O[0]),
            "distance": distance}


@dataclass(frozen=True)
class PlaneViews:
    """The views edge-on to ``plane`` through ``target`` (3,) m: ``directions`` (F, 3) unit beams (beam ·
    normal = 0), their XA ``primary_deg``, ``secondary_deg`` (F,), ``angle`` (F,) rad between beam and plane,
    ``reachable`` (F,), ``q`` (F, nq), ``clearance`` (F,) m, ``separation`` (F,) m: the smallest distance
    between two of the plane's points as projected (at the target's depth); ``best`` the index of the
    reachable view with the largest separation (``None``: none reachable) and its ``plan``."""

    plane: Plane
    target: np.ndarray
    directions: np.ndarray
    primary_deg: np.ndarray
    secondary_deg: np.ndarray
    angle: np.ndarray
    reachable: np.ndarray
    q: np.ndarray
    clearance: np.ndarray
    separation: np.ndarray
    best: int | None
    plan: ViewPlan | None


def plane_views(system, plane, patient=None, *, count: int = FAMILY_SIZE, target=None, margin: float = DEFAULT_MARGIN,
                position=None, table_samples=None, plan: bool = True) -> PlaneViews:
    """The ``count`` beams in ``plane`` (a :class:`Plane` or ≥ 3 points (K, 3) m, table frame), evenly spaced
    over the full turn, through ``target`` (default the plane's centre): which are reachable with ``patient``
    (the search of :func:`reach_map`), and the reachable one that best separates the plane's points."""
    from carmkin.validation import flag, integer

    plane = plane if isinstance(plane, Plane) else plane_from_points(plane)
    count = integer(count, "count", low=3, high=36000, error=ViewError)
    plan = flag(plan, "plan", error=ViewError)  # a string "False" would read as True (issue 41)
    margin = real_scalar(margin, "margin", error=ViewError, low=0.0, high=1.0, unit="m")
    target = plane.centre if target is None else _point(target, "target")
    position = _position(patient, position)
    family = View.perpendicular_to(target, target + plane.normal, count, target)
    directions = np.array([v.direction for v in family])
    angles = np.array([v.angles(position) for v in family])
    world = world_for(system, patient)
    ctx = search.make_context(system, world, margin, reference(system, None), _table_samples(system, table_samples))
    ranges = np.tile([0.0, system.carm.source_to_detector], (count, 1))
    out = search.solve_cells(ctx, np.tile(target, (count, 1)), directions, ranges)
    distance = float(system.carm.orbital_offset)
    poses = metrics.xa_poses(angles[:, 0], angles[:, 1], target, distance, _patient_frame(position)[:3, :3])
    gap = metrics.separation(plane.points, poses, distance)
    best, the_plan = None, None
    if out.reachable.any():
        best = int(np.argmax(np.where(out.reachable, gap, -np.inf)))
        if plan:
            the_plan = plan_view(system, family[best], patient, margin=margin, nearest=False,
                                 table_samples=table_samples, qp=False)
    return PlaneViews(plane, target, directions, angles[:, 0], angles[:, 1], metrics.plane_angle(plane.normal, directions),
                      out.reachable, out.q, np.where(out.reachable, out.clearance, np.nan), gap, best, the_plan)
