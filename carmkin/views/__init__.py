"""Clinical views with the patient in the world (issue 20).

``View`` (a beam axis through a target), :func:`plan_view` (joints, clearance, moves, nearest reachable
view), :func:`reach_map` (which XA views are reachable and clear) and the named standard views.
"""

from .maps import ReachMap, carm_alone, reach_map
from .plan import DEFAULT_MARGIN, Move, ViewPlan, plan_view
from .view import View

__all__ = ["DEFAULT_MARGIN", "Move", "ReachMap", "View", "carm_alone", "ViewPlan", "plan_view", "reach_map"]
