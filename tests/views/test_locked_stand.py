"""The exact wigwag values of a stand with locked vertical and horizontal joints (closed_form.locked_theta2)
against the FK: a configuration's own beam through a point on it is found again, its wigwag among the values."""

import dataclasses
import math

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from strategies import geometries, setups

import carmkin
from carmkin.model.params import JointRange
from carmkin.views import closed_form

ANGIO = carmkin.load_preset("angio-floor")
#: The wigwag value found and the configuration's agree to this (rad): a circle met by a line, in closed form.
ROOT_TOLERANCE = 1e-9


@st.composite
def locked_systems(draw):
    """Isocentric C-arms with random geometry, table setup and locked vertical / horizontal values (m)."""
    carm = draw(geometries(isocentric=True))
    d1, d3 = draw(st.floats(-0.3, 0.3)), draw(st.floats(0.0, 0.3))
    carm = dataclasses.replace(carm, vertical=JointRange(d1, d1, "vertical"), horizontal=JointRange(d3, d3, "horizontal"),
                               wigwag=JointRange(-math.pi, math.pi, "wigwag"))
    return ANGIO.replace(carm=carm, setup=draw(setups()))


@settings(max_examples=60, deadline=None)
@given(locked_systems(), st.data())
def test_a_configurations_own_wigwag_is_among_the_exact_values(system, data):
    q = np.array([data.draw(st.floats(r.lower, r.upper)) for r in system.joint_ranges])
    q[1:system.nq - 5] = 0.0  # table joints at rest: the frame below
    T = system.fk(q)
    s = data.draw(st.floats(0.1, 1.5))
    target, direction = T[:3, 3] + s * T[:3, 2], T[:3, 2]
    frame = closed_form.base_frame(system, q)
    values = closed_form.locked_theta2(system, target[None], direction[None], frame)[0]
    finite = values[np.isfinite(values)]
    if not len(finite):  # the degenerate families (beam and table axis level in the base frame): the samples' job
        B = frame[:3, :3]
        assert abs((direction @ B)[2]) < 1e-6 and abs(B[2, 2]) < 1e-6
        return
    wigwag = q[system.nq - 4]
    assert np.min(np.abs(np.angle(np.exp(1j * (finite - wigwag))))) <= ROOT_TOLERANCE


def test_only_a_locked_isocentric_stand_has_exact_values():
    target, direction = np.zeros((1, 3)), np.array([[0.0, -1.0, 0.0]])
    frame = closed_form.base_frame(ANGIO, np.zeros(ANGIO.nq))
    assert closed_form.locked_theta2(ANGIO, target, direction, frame) is not None
    mobile = carmkin.load_preset("siremobile-iso-c3d")
    assert closed_form.locked_theta2(mobile, target, direction, closed_form.base_frame(mobile, np.zeros(6))) is None
    offset = ANGIO.replace(carm=dataclasses.replace(ANGIO.carm, a1=0.02))
    assert closed_form.locked_theta2(offset, target, direction, frame) is None
