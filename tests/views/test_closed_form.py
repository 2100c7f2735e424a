"""The closed-form view families against the system's FK (an independent route): any configuration's beam is
found again, on random non-isocentric geometries, table setups and motorized tables."""

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from strategies import configurations, motorized_systems, systems

from carmkin.views import closed_form

#: Beam axis and through-target residuals of a closed form (m, rad).
CLOSED_FORM_TOLERANCE = 1e-9


def _frame(system, q):
    if not system.table.joints:
        return system.carm_base_pose
    return system.table_motion(system.split(q)[1]) @ system.carm_base_pose


def _check_found(system, q, s0):
    T = system.fk(q)
    target, z = T[:3, 3] + s0 * T[:3, 2], T[:3, 2]
    fam = closed_form.families(system, target[None], z[None], np.array([q[system.nq - 4]]), _frame(system, q), q,
                               np.array([[0.0, 3.0]]))
    # The generating configuration is one point of its family's line: its interval is not empty.
    assert fam.feasible.any()
    idx = np.nonzero(fam.feasible)
    lam = 0.5 * (fam.lo[idx] + fam.hi[idx])
    Q = closed_form.joints(system, fam, idx, lam, q)
    for qk in Q:
        Tk = system.fk(qk)
        w = target - Tk[:3, 3]
        assert np.linalg.norm(Tk[:3, 2] - z) < CLOSED_FORM_TOLERANCE
        assert np.linalg.norm(w - (w @ z) * z) < CLOSED_FORM_TOLERANCE
        assert all(r.contains(v) for r, v in zip(system.joint_ranges, qk))


@settings(max_examples=60)
@given(st.data(), st.floats(0.05, 2.5))
def test_every_configuration_is_found_again(data, s0):
    system = data.draw(systems())
    q = data.draw(configurations(system))
    _check_found(system, q, s0)


@settings(max_examples=40)
@given(st.data(), st.floats(0.05, 2.5))
def test_motorized_tables(data, s0):
    system = data.draw(motorized_systems(min_joints=1))
    q = data.draw(configurations(system))
    _check_found(system, q, s0)
