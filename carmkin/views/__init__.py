"""Clinical views with the patient in the world (issue 20).

``View`` (a beam axis through a target), :func:`plan_view` (joints, clearance, moves, nearest reachable
view), :func:`plan_perpendicular` (the best foreshortening-free view of a segment), :func:`reach_map` (which XA views are reachable and clear), :func:`compare_maps` (the C-arm alone, with
the table translation, with a motorized table, side by side) and the named standard views.
"""

from .compare import compare_maps
from .maps import ReachMap, carm_alone, reach_map
from .plan import DEFAULT_MARGIN, Move, ViewPlan, plan_view
from .segment import plan_perpendicular
from .view import View

__all__ = ["DEFAULT_MARGIN", "Move", "ReachMap", "View", "carm_alone", "compare_maps", "ViewPlan", "plan_perpendicular",
           "plan_view", "reach_map"]
