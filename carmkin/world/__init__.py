"""The one collision world under every planner (issue 27): :class:`World` — the scene of a system with its
table, floor and patient, built once — with batch, swept and joint-by-joint clearance written once, and the
one default margin :data:`DEFAULT_MARGIN` of every "valid"."""

from .moves import DEFAULT_ORDER, Move
from .obstacles import Obstacle, link_of
from .swept import Swept
from .tolerances import DEFAULT_MARGIN, DEFAULT_PATH_CLEARANCE, DEFAULT_TOLERANCE
from .world import GROUPS, Proximity, World

__all__ = ["DEFAULT_MARGIN", "DEFAULT_ORDER", "DEFAULT_PATH_CLEARANCE", "DEFAULT_TOLERANCE", "GROUPS", "Move",
           "Obstacle", "Proximity", "Swept", "World", "link_of"]
