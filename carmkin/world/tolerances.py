"""The world's tolerances and default margins, stated once (lengths in m).

Every planner of the toolkit (validity, the closed form's report, ``qp_ik``, views, sweeps, repositioning)
reads its default clearance from here, so "valid" means one thing: joints in range, every collision pair
at least :data:`DEFAULT_MARGIN` apart, and (for §4.4.3 validity) the table in the X-ray cone.
"""

from __future__ import annotations

import numpy as np

#: The one default clearance margin (m) that every moving C-arm part keeps from table, floor and patient: the
#: default of ``validity.check``, the closed form's report, ``qp_ik`` (``QPIKOptions.safety_margin``),
#: ``views.plan_view`` / ``reach_map`` and ``sweeps.plan_sweep``. 10 mm: the margin the QP and the sweeps used
#: before it was written once (views used 20 mm, validity 0: both now read this).
DEFAULT_MARGIN = 0.01
#: Default clearance (m) kept along joint-by-joint moves (:meth:`World.moves`): half the margin, so that a move
#: that ends at a configuration clear of the margin can approach it.
DEFAULT_PATH_CLEARANCE = 0.005
#: Coal's GJK/EPA stop within their tolerances (``gjk_tolerance`` = ``epa_tolerance`` = 1e-6 by default): near
#: contact a box pair 4e-7 m apart is reported at 0 (found by the tests). Every lower bound of the branch and
#: bound is lowered by twice that tolerance (m), so that a pruned pair is farther than the margin in coal's
#: own numbers too.
BOUND_SLACK = 2e-6
#: Accuracy assumed of a coal distance, relative to max(1 m, the distance): twice GJK/EPA's 1e-6 tolerance (two
#: calls on one pair differ by up to that; 4e-6 m measured on a pair 3.3 m apart); subtracted from every
#: sampled distance before it certifies anything (:func:`accuracy`).
DISTANCE_ACCURACY = 2e-6
#: Default tightness (m) of a swept minimum: the certified bound lies at most this (plus the coal accuracy)
#: below the true minimum of the segment.
DEFAULT_TOLERANCE = 1e-3
#: A swept sample closer than margin + this (m) is a contact: a sweep that stops at contacts stops there.
CONTACT_RESOLUTION = 1e-5
#: Samples per swept segment before giving up (the segment is then reported as not certified).
MAX_SAMPLES = 20000


def accuracy(d) -> np.ndarray:
    """Accuracy (m) of coal distances ``d`` (m): :data:`DISTANCE_ACCURACY` · max(1, |d|)."""
    return DISTANCE_ACCURACY * np.maximum(1.0, np.abs(d))
