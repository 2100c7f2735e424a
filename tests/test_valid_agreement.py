"""One meaning of "valid" (issue 27): for 500 random configurations whose clearance lies between 0 and 40 mm (and
whose beam meets the table, so that §4.4.3's cone condition holds), the closed form's report of its chosen
solution, validity.check and qp_ik.solve give the same verdict on the same configuration at the one default
margin. The clearance used to pick the configurations is the world's (a route independent of the verdicts:
coal on every pair)."""

import numpy as np

import carmkin
from carmkin import analytic_ik, qp_ik
from carmkin.robot import validity
from carmkin.world import World

PRESET = carmkin.load_preset("siremobile-iso-c3d")
CONFIGURATIONS = 500


def test_closed_form_validity_and_qp_agree_at_the_default_margin():
    margin = carmkin.DEFAULT_MARGIN
    assert margin == validity.check.__defaults__[1] == qp_ik.QPIKOptions().safety_margin
    world = World(PRESET)
    rng = np.random.default_rng(2027)
    verdicts, checked = {True: 0, False: 0}, 0
    while checked < CONFIGURATIONS:
        Q = PRESET.lower + rng.uniform(size=(400, 6)) * (PRESET.upper - PRESET.lower)
        clearance = np.array([world.distances(q=q).min() for q in Q])
        for q in Q[(clearance >= 0.0) & (clearance <= 0.04)]:
            T = PRESET.fk(q)
            if not validity.pose_in_cone(PRESET, T) or checked >= CONFIGURATIONS:
                continue
            ik = analytic_ik.solve(PRESET, T, q_current=q)
            np.testing.assert_allclose(ik.q, q, atol=1e-9)  # the configuration itself is chosen (no motion)
            closed = ik.validity.valid
            checked_verdict = validity.check(PRESET, ik.q).valid
            result = qp_ik.solve(PRESET, T, q_current=q)
            report = next(b for b in result.branch_reports if np.allclose(b.q, ik.q, atol=1e-12))
            assert closed == checked_verdict == report.accepted == report.validity.valid, (q, ik.validity, report)
            if closed:  # the closed form's choice is the QP's answer
                assert result.success and np.allclose(result.q, ik.q, atol=1e-12)
            assert ik.validity.margin == report.validity.margin == margin
            verdicts[closed] += 1
            checked += 1
    print(f"\n{checked} configurations with 0-40 mm clearance: {verdicts[True]} valid, {verdicts[False]} not, "
          f"at margin {margin * 1e3:g} mm; closed form, validity.check and qp_ik agree on all")
    assert verdicts[True] > 50 and verdicts[False] > 50  # both verdicts exercised around the margin
