"""Certified motion between configurations (issue 37): collision-free joint paths found with OMPL, certified
by the world's distances and chain speed bounds, timed optimally within every joint's speed and acceleration.

* :func:`plan_motion` / :class:`MotionPlanner` (:mod:`carmkin.motion.plan`): one query, or many with one world;
* :class:`Trajectory` (:mod:`carmkin.motion.trajectory`): waypoints, time law ``sample(t)``, duration,
  certified minimum clearance;
* :mod:`carmkin.motion.certificate`: the sound segment check and the path's certified minimum;
* :mod:`carmkin.motion.search`: OMPL's planners over those checks;
* :mod:`carmkin.motion.time_law`: time-optimal straight segments from rest to rest.

See ``docs/motion.md``.
"""

from .certificate import END_TOLERANCE, SEARCH_RESOLUTION, Certifier, SegmentCheck
from .plan import DEFAULT_TIME_LIMIT_S, MAX_TIME_LIMIT_S, MotionPlanner, plan_motion
from .search import PLANNERS
from .time_law import SegmentLaw, TimeLaw, segment_law
from .trajectory import Trajectory

__all__ = ["DEFAULT_TIME_LIMIT_S", "END_TOLERANCE", "MAX_TIME_LIMIT_S", "PLANNERS",
           "SEARCH_RESOLUTION", "Certifier", "MotionPlanner", "SegmentCheck", "SegmentLaw", "TimeLaw", "Trajectory",
           "plan_motion", "segment_law"]
