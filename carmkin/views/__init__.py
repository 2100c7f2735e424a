"""Clinical views with the patient in the world (issue 20).

``View`` (a beam axis through a target), :func:`plan_view` (joints, clearance, moves, nearest reachable
view), :func:`plan_perpendicular` (the best foreshortening-free view of a segment), :func:`reach_map` (which XA views are reachable and clear), :func:`compare_maps` (the C-arm alone, with
the table translation, with a motorized table, side by side) and the named standard views. Anatomy (issue 29): :func:`optimal_view_map` (the best reachable
view of a curved vessel: foreshortening, overlap, reachability), :func:`plane_views` (the reachable views
edge-on to a valve plane), with the inputs of :mod:`.anatomy` and the metrics of :mod:`.metrics`.
"""

from .anatomy import (
    Centreline,
    Plane,
    centreline_from_ct,
    centreline_from_patient,
    plane_from_points,
    skeleton_centreline,
)
from .compare import compare_maps
from .maps import ReachMap, carm_alone, reach_map
from .optimal import OptimalViewMap, PlaneViews, optimal_view_map, plane_views
from .plan import DEFAULT_MARGIN, Move, ViewPlan, plan_view
from .segment import plan_perpendicular
from .view import View

__all__ = ["DEFAULT_MARGIN", "Move", "ReachMap", "View", "carm_alone", "compare_maps", "ViewPlan", "plan_perpendicular",
           "plan_view", "reach_map",
           # anatomy (issue 29)
           "Centreline", "OptimalViewMap", "Plane", "PlaneViews", "centreline_from_ct", "centreline_from_patient",
           "optimal_view_map", "plane_from_points", "plane_views", "skeleton_centreline"]
