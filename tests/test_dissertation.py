"""The printed equations of §4.3.1 (Table 4.1, eq. 4.2) and the text's definitions, checked against the chain.

Table 4.1 is transcribed term by term from the dissertation (the paper's data, not computed by carmkin).
"""

from __future__ import annotations

import numpy as np
from hypothesis import given
from hypothesis import strategies as st
from strategies import configurations, systems


def table_4_1(system, q, printed: bool = False) -> np.ndarray:
    """0T6(q) of Table 4.1 (eq. 4.6); ``printed=True`` keeps the printed sign of the a1 term of p_z
    (erratum E1 in docs/ERRATA.md), otherwise the corrected sign."""
    s, c = np.sin, np.cos
    g1, g2, g3 = system.setup.gamma1, system.setup.gamma2, system.setup.gamma3
    D1, D2, D3 = system.setup.D1, system.setup.D2, system.setup.D3
    l1, l2, a1, a2 = system.carm.length_offset, system.carm.orbital_offset, system.carm.a1, system.carm.a2
    d0, d1, t2, d3, t4, t5 = q
    sg1, cg1, sg2, cg2, sg3, cg3 = s(g1), c(g1), s(g2), c(g2), s(g3), c(g3)
    s2, c2, s4, c4, s5, c5 = s(t2), c(t2), s(t4), c(t4), s(t5), c(t5)
    A = cg2 * cg3 - cg1 * sg2 * sg3
    B = cg2 * sg3 + cg1 * sg2 * cg3
    C = sg2 * cg3 + cg1 * cg2 * sg3
    D = sg2 * sg3 - cg1 * cg2 * cg3
    L, M = l2 + a1, l1 - a2
    r11 = sg1 * sg2 * c4 * c5 + A * (c2 * s4 * c5 - s2 * s5) - B * (s2 * s4 * c5 + c2 * s5)
    r12 = -sg1 * sg2 * c4 * s5 - A * (c2 * s4 * s5 + s2 * c5) + B * (s2 * s4 * s5 - c2 * c5)
    r13 = sg1 * sg2 * s4 - A * c2 * c4 + B * s2 * c4
    r21 = -sg1 * cg2 * c4 * c5 + C * (c2 * s4 * c5 - s2 * s5) - D * (s2 * s4 * c5 + c2 * s5)
    r22 = sg1 * cg2 * c4 * s5 - C * (c2 * s4 * s5 + s2 * c5) + D * (s2 * s4 * s5 - c2 * c5)
    r23 = -sg1 * cg2 * s4 - C * c2 * c4 + D * s2 * c4
    r31 = cg1 * c4 * c5 + sg1 * sg3 * (c2 * s4 * c5 - s2 * s5) + sg1 * cg3 * (s2 * s4 * c5 + c2 * s5)
    r32 = -cg1 * c4 * s5 - sg1 * sg3 * (c2 * s4 * s5 + s2 * c5) - sg1 * cg3 * (s2 * s4 * s5 - c2 * c5)
    r33 = cg1 * s4 - sg1 * sg3 * c2 * c4 - sg1 * cg3 * s2 * c4
    U = d1 + D3 + a1 * c4 - L * c4 * c5
    V = L * s2 * s5 - M * s2 - s2 * d3 - L * c2 * s4 * c5 + a1 * c2 * s4
    W = L * s2 * s4 * c5 + L * c2 * s5 - M * c2 - c2 * d3 - a1 * s2 * s4
    px = cg2 * D1 + sg1 * sg2 * U + A * V + B * W
    py = sg2 * D1 - sg1 * cg2 * U + C * V + D * W
    a1_sign = -1.0 if printed else 1.0  # printed: "... + c θ2 d3 − a1 s θ2 s θ4"
    pz = D2 + d0 + cg1 * U + sg1 * sg3 * V + sg1 * cg3 * (-L * s2 * s4 * c5 - L * c2 * s5 + M * c2 + c2 * d3
                                                          + a1_sign * a1 * s2 * s4)
    return np.array([[r11, r12, r13, px], [r21, r22, r23, py], [r31, r32, r33, pz], [0, 0, 0, 1.0]])


@given(systems(), st.data())
def test_table_4_1_equals_the_dh_chain(system, data):
    q = data.draw(configurations(system, beyond=1.0))
    assert np.abs(system.dh_frames(q)[-1] - table_4_1(system, q)).max() <= 1e-12


def test_printed_p_z_of_table_4_1_fails_for_non_isocentric_c_arms():
    """Erratum E1: with a1 != 0 the printed sign of a1·sθ2·sθ4 in p_z disagrees with the chain."""
    from dataclasses import replace

    from strategies import PRESET

    import carmkin

    system = PRESET.replace(carm=replace(PRESET.carm, a1=0.1),
                            setup=carmkin.TableSetup(1.0, 0.3, 0.2, 0.5, 0.1, 0.2))
    q = np.array([0.1, 0.2, 0.15, 0.05, 0.7, 0.4])
    chain = system.dh_frames(q)[-1]
    assert np.abs(chain - table_4_1(system, q)).max() <= 1e-12
    printed_error = abs(chain[2, 3] - table_4_1(system, q, printed=True)[2, 3])
    # the printed form is off by 2·a1·sγ1·cγ3·sθ2·sθ4
    expected = 2 * 0.1 * np.sin(1.0) * np.cos(0.2) * np.sin(0.15) * np.sin(0.7)
    assert abs(printed_error - expected) <= 1e-12 and expected > 1e-3


def _line_distance(p1, u1, p2, u2) -> float:
    n = np.cross(u1, u2)
    if np.linalg.norm(n) < 1e-12:
        return float(np.linalg.norm(np.cross(p2 - p1, u1)))
    return float(abs(np.dot(p2 - p1, n)) / np.linalg.norm(n))


@given(systems(), st.data())
def test_offsets_a1_a2_are_the_distances_the_text_defines(system, data):
    """§4.3.1: a1 = Dist(angular axis, orbital axis); a2 = Dist(X-ray beam, orbital axis)."""
    q = data.draw(configurations(system, beyond=1.0))
    F = system.dh_frames(q)
    source = system.fk(q)
    angular, orbital = (F[3, :3, 3], F[3, :3, 2]), (F[4, :3, 3], F[4, :3, 2])
    beam = (source[:3, 3], source[:3, 2])
    assert abs(_line_distance(*angular, *orbital) - abs(system.carm.a1)) <= 1e-12
    assert abs(_line_distance(*beam, *orbital) - abs(system.carm.a2)) <= 1e-12


@given(systems(), st.data())
def test_eq_4_2_principal_axis_is_perpendicular_to_the_orbital_axis(system, data):
    """eq. 4.2: Z_xray = X6, so the beam turns in the C's plane about the orbital axis Z5."""
    q = data.draw(configurations(system, beyond=1.0))
    F = system.dh_frames(q)
    assert abs(np.dot(system.fk(q)[:3, 2], F[4, :3, 2])) <= 1e-12
    assert np.allclose(system.fk(q)[:3, 2], F[5, :3, 0], atol=1e-14)


@given(systems())
def test_length_and_orbital_offsets_are_the_distances_the_text_defines(system):
    """§4.3.1 at zero joints: l1 = Dist(X-ray beam, wigwag axis), l2 = Dist(source centre, angular axis)."""
    F = system.dh_frames(np.zeros(6))
    source = system.fk(np.zeros(6))
    beam, wigwag = (source[:3, 3], source[:3, 2]), (F[1, :3, 3], F[1, :3, 2])
    assert abs(_line_distance(*beam, *wigwag) - system.carm.length_offset) <= 1e-12
    to_source = source[:3, 3] - F[3, :3, 3]
    assert abs(np.linalg.norm(np.cross(to_source, F[3, :3, 2])) - system.carm.orbital_offset) <= 1e-12
