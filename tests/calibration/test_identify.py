"""carmkin.calibration.identify: a device perturbed by known amounts is recovered (exactly without noise, within
its reported covariance with noise), the residual is the size the degrees of freedom predict, the views that
cannot separate parameters are named, the calibrated preset reproduces the fitted projections, bad input is
refused naming the field."""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import carmkin
from carmkin import calibration as cal
from carmkin.calibration.fit import JACOBIAN_STEP, _jacobian
from carmkin.errors import CalibrationError
from carmkin.imaging import projection_matrix

SYSTEM = carmkin.load_preset("siremobile-iso-c3d")
#: The parameters no set of views separates from a joint zero offset (DH rows 0, 1, 3 and the wigwag row).
STRUCTURAL = {"length_offset", "gamma3", "D2", "D3"}
#: The simulated measurement noise of the acceptance check (px per pixel coordinate).
NOISE_PX = 0.1
#: Recovery bound of the acceptance check at its fixed seed, in reported standard deviations.
ACCEPTANCE_SIGMAS = 3.0
#: The property test's bound (standard deviations): 5σ, so that it fails only on a real error (a chance of
#: ~1e-5 per example for 18 parameters when the covariance is right).
PROPERTY_SIGMAS = 5.0
#: Noise-free recovery tolerance (mm, deg, px): the fit's round-off, far below any real calibration.
EXACT = 1e-6


def _truth_values(truth, result):
    return cal.values(truth, [p for p in cal.parameters(truth) if p.name in result.names])


def _fit(truth, Q, noise_px=NOISE_PX, seed=0, **kwargs):
    P = cal.measured_projections(truth, Q, noise_px, seed=seed, points=cal.reference_points(SYSTEM, Q))
    return cal.identify(SYSTEM, Q, P, **kwargs)


def test_noise_free_views_recover_the_perturbation_exactly():
    truth = cal.adjust(SYSTEM, cal.EXAMPLE_PERTURBATION)
    result = _fit(truth, cal.spread_readings(SYSTEM, 12, seed=3), noise_px=0.0)
    assert set(result.unidentifiable) == STRUCTURAL
    assert np.abs(result.values - _truth_values(truth, result)).max() < EXACT
    assert result.residual_px.max() < EXACT


def test_acceptance_30_views_with_noise():
    """Issue 30: 30 views, 0.1 px noise: every identifiable parameter within 3σ, residual ≈ the noise."""
    truth = cal.adjust(SYSTEM, cal.EXAMPLE_PERTURBATION)
    Q = cal.spread_readings(SYSTEM, 30, seed=1)
    result = _fit(truth, Q, seed=1)
    z = (result.values - _truth_values(truth, result)) / result.std
    n_points = cal.reference_points(SYSTEM, Q).shape[1]
    rms = math.sqrt(np.mean(result.residual_px**2) / 2)  # per pixel coordinate
    expected = math.sqrt(result.dof / (2 * n_points * len(Q)))
    print(f"\n30 views, {NOISE_PX} px noise: {len(result.names)} parameters fitted, held {result.unidentifiable}; "
          f"max |error| / sigma = {np.abs(z).max():.2f}; residual RMS {rms:.4f} px = {rms / NOISE_PX:.3f} x noise "
          f"(expected sqrt(dof / 2MN) = {expected:.3f}); implied noise s = {result.noise_px:.4f} px = "
          f"{result.noise_px / NOISE_PX:.3f} x noise")
    assert set(result.unidentifiable) == STRUCTURAL
    assert np.abs(z).max() <= ACCEPTANCE_SIGMAS
    assert 0.8 < (rms / NOISE_PX) / expected < 1.25  # the RMS of 30 x 11 - 18 = 312 squares: ±8 % is 2σ
    assert 0.8 < result.noise_px / NOISE_PX < 1.25
    assert np.median(result.residual_before_px) > 10 * np.median(result.residual_px)


def test_three_views_name_the_parameters_they_cannot_separate():
    truth = cal.adjust(SYSTEM, cal.EXAMPLE_PERTURBATION)
    spread = _fit(truth, cal.spread_readings(SYSTEM, 3, seed=2))
    assert set(spread.unidentifiable) >= STRUCTURAL
    # three views that move the angular and orbital joints only
    few = _fit(truth, cal.spread_readings(SYSTEM, 3, seed=2, joints=("angular", "orbital")))
    print(f"\n3 views (all joints): held {spread.unidentifiable}\n3 views (angular, orbital): held {few.unidentifiable}")
    # with the first four joints fixed, the table setup and their offsets only place the angular axis' frame:
    # three translations (table, vertical, horizontal offsets; D1 along X1 is a combination of them) and three
    # rotations (wigwag about Z1, angular offset about the arm; gamma1 turns about X1, which is the arm at
    # wigwag zero); gamma2, about the table axis Z0, is the third rotation and stays
    assert set(few.unidentifiable) == STRUCTURAL | {"gamma1", "D1"}
    for held in few.identifiability.held:
        assert held.separation < cal.MIN_SINGULAR_VALUE
        with pytest.raises(CalibrationError, match="not identifiable"):
            few.estimate(held.name)


def test_an_orbital_sweep_names_what_it_cannot_separate():
    truth = cal.adjust(SYSTEM, cal.EXAMPLE_PERTURBATION)
    result = _fit(truth, cal.spread_readings(SYSTEM, 30, seed=4, joints=("orbital",)))
    print(f"\norbital sweep: held {result.unidentifiable}")
    # the fixed joints' offsets and the table setup all place one fixed orbital axis: 6 numbers for 12 parameters
    assert set(result.unidentifiable) >= STRUCTURAL | {"a1", "gamma1", "gamma2", "D1"}
    assert "orbital_zero_offset" in result.names and "sag_sin" in result.names


def test_a_length_offset_error_is_reported_as_the_horizontal_zero_offset():
    truth = cal.adjust(SYSTEM, {"length_offset": 2.0})
    result = _fit(truth, cal.spread_readings(SYSTEM, 12, seed=5), noise_px=0.0)
    held = {h.name: h for h in result.identifiability.held}["length_offset"]
    assert held.reason is cal.Reason.CONFOUNDED
    assert held.equivalent[0][0] == "horizontal_zero_offset" and held.equivalent[0][1] == pytest.approx(1.0, abs=1e-6)
    assert result.estimate("horizontal_zero_offset")[0] == pytest.approx(2.0, abs=EXACT)
    assert result.residual_px.max() < EXACT


def test_the_calibrated_preset_reproduces_the_fitted_projections(tmp_path):
    truth = cal.adjust(SYSTEM, cal.EXAMPLE_PERTURBATION)
    Q = cal.spread_readings(SYSTEM, 12, seed=6)
    result = _fit(truth, Q)
    loaded = carmkin.load_preset(result.save_preset(tmp_path / "calibrated.toml"))
    fitted = cal.model_projections(result.system, Q)
    for q, P in zip(Q, fitted):  # the one-view path: readings -> model joints -> FK -> calibrated detector
        P_loaded = projection_matrix(loaded, loaded.calibration.model_joints(q))
        assert np.abs(P_loaded - P).max() <= 1e-12 * np.abs(P).max()
    provenance = carmkin.presets.preset_provenance(tmp_path / "calibrated.toml")
    assert provenance["calibration.orbital_zero_offset_deg"].kind == "source"
    assert provenance["carm.length_offset_mm"].kind == "assumption"


def test_a_motorized_table_is_calibrated_with_its_joints():
    system = carmkin.load_preset("siremobile-iso-c3d-motorized-table")
    truth = cal.adjust(system, {"table_height_zero_offset": 1.0, "orbital_zero_offset": 0.2, "a1": 1.0})
    Q = cal.spread_readings(system, 15, seed=7)
    result = cal.identify(system, Q, cal.measured_projections(truth, Q, 0.0))
    assert len(result.identifiability.names) == system.nq + 16
    assert result.residual_px.max() < EXACT
    assert result.estimate("orbital_zero_offset")[0] == pytest.approx(0.2, abs=EXACT)


def test_the_jacobian_is_converged_in_its_step():
    """Central differences at the step and at a tenth of it agree: the step is in the flat part of the error."""
    Q = cal.spread_readings(SYSTEM, 4, seed=8)
    X = cal.reference_points(SYSTEM, Q)
    chosen = cal.parameters(SYSTEM)
    x0 = cal.values(SYSTEM, chosen)

    def residual(x):
        return cal.reprojection.pixels(cal.model_projections(cal.quantities.with_values(SYSTEM, chosen, x), Q), X).ravel()

    J = _jacobian(residual, x0)
    J_small = (np.column_stack([residual(x0 + e) - residual(x0 - e) for e in np.eye(len(x0)) * JACOBIAN_STEP / 10])
               / (2 * JACOBIAN_STEP / 10))
    assert np.abs(J - J_small).max() <= 1e-5 * np.abs(J).max()


perturbation = st.fixed_dictionaries({
    name: st.floats(-3.0, 3.0) if unit in ("mm", "px") else st.floats(-0.5, 0.5)
    for name, unit in ((p.name, p.unit) for p in cal.parameters(SYSTEM) if p.name not in STRUCTURAL)})


@pytest.mark.slow  # ~10 s: 8 simulated calibrations
@settings(max_examples=8)
@given(perturbation, st.integers(0, 1000))
def test_random_perturbations_are_recovered_within_their_covariance(changes, seed):
    truth = cal.adjust(SYSTEM, changes)
    result = _fit(truth, cal.spread_readings(SYSTEM, 15, seed=seed), seed=seed)
    error = result.values - _truth_values(truth, result)
    assert np.abs(error / result.std).max() <= PROPERTY_SIGMAS
    chi2 = error @ np.linalg.solve(result.covariance, error)
    assert chi2 < 52.0  # the 0.99999 quantile of chi-square with 18 degrees of freedom is 51.2


def _bad(Q=None, P=None, **kwargs):
    Q = cal.spread_readings(SYSTEM, 3, seed=9) if Q is None else Q
    P = cal.model_projections(SYSTEM, Q[:3]) if P is None else P
    return cal.identify(SYSTEM, Q, P, **kwargs)


def test_bad_input_is_refused_naming_the_field():
    Q = cal.spread_readings(SYSTEM, 3, seed=9)
    P = cal.model_projections(SYSTEM, Q)
    with pytest.raises(CalibrationError, match=r"2 views give 22 numbers .* the 22 parameters to fit: need at least 3 views"):
        cal.identify(SYSTEM, Q[:2], P[:2])
    with pytest.raises(CalibrationError, match="q has 3 views .* P has 2"):
        cal.identify(SYSTEM, Q, P[:2])
    bad = P.copy()
    bad[1, 0, 0] = np.nan
    with pytest.raises(CalibrationError, match="P"):
        cal.identify(SYSTEM, Q, bad)
    flat = P.copy()
    flat[2, :, 2] = flat[2, :, 0]  # rank 2 left block
    with pytest.raises(CalibrationError, match=r"P\[2\] must have a left 3x3 block of rank 3"):
        cal.identify(SYSTEM, Q, flat)
    out = Q.copy()
    out[1, 5] = math.radians(120)
    with pytest.raises(CalibrationError, match=r"q\[1, 5\] \(orbital reading\) = 120 deg is outside .*\[-95, 95\] deg"):
        cal.identify(SYSTEM, out, P)
    with pytest.raises(CalibrationError, match=r"q \(joint readings\) must have shape \(N, 6\)"):
        cal.identify(SYSTEM, Q[:, :5], P)
    with pytest.raises(CalibrationError, match="unknown parameter 'orbital_zero_ofset'.*'orbital_zero_offset'"):
        cal.identify(SYSTEM, Q, P, parameters=["orbital_zero_ofset"])
    with pytest.raises(CalibrationError, match="at least 6 reference points"):
        cal.identify(SYSTEM, Q, P, points=np.zeros((5, 3)))
    with pytest.raises(CalibrationError, match="behind the centre of projection"):
        cal.identify(SYSTEM, Q, P, points=cal.reference_points(SYSTEM, Q) - 2.0 * SYSTEM.fk(Q)[:, None, :3, 2])
    with pytest.raises(CalibrationError, match="system must be a carmkin.CArmSystem"):
        cal.identify("siremobile", Q, P)


@pytest.mark.parametrize("call, match", [
    (lambda: cal.spread_readings(SYSTEM, 3.0), "n must be an integer"),
    (lambda: cal.spread_readings(SYSTEM, 3, seed=-1), "seed must be an integer"),
    (lambda: cal.spread_readings(SYSTEM, 3, joints="orbital"), "joints must be a list of joint names"),
    (lambda: cal.spread_readings(SYSTEM, 3, joints=["orbit"]), r"unknown joint\(s\) \['orbit'\]"),
    (lambda: cal.measured_projections(SYSTEM, np.zeros((2, 6)), noise_px=-0.1), "noise_px"),
    (lambda: cal.measured_projections(SYSTEM, np.zeros((2, 6)), seed="0"), "seed must be an integer"),
    (lambda: cal.adjust(SYSTEM, {"a1": "2 mm"}), "changes"),
    (lambda: cal.adjust(SYSTEM, [("a1", 2.0)]), "changes must be a dict"),
    (lambda: cal.identify(SYSTEM, np.zeros((3, 6)), np.zeros((3, 3, 4)) + 1, parameters="a1"),
     "parameters must be a list"),
    (lambda: cal.identify(SYSTEM, np.zeros((3, 6)), np.zeros((3, 3, 4)) + 1, points="cube"), "points"),
])
def test_junk_arguments_are_refused_naming_them(call, match):
    with pytest.raises(CalibrationError, match=match):
        call()


def test_views_of_a_far_other_device_fit_without_a_warning(recwarn):
    """P of a device 200 mm and 5 degrees off the nominal: the fit's trial steps leak no numpy warning."""
    other = cal.adjust(SYSTEM, {"source_to_detector": 200.0, "orbital_offset": -150.0, "angular_zero_offset": 5.0,
                                "principal_point_u": 80.0})
    Q = cal.spread_readings(SYSTEM, 10, seed=11)
    result = _fit(other, Q, noise_px=0.0)
    assert not [w for w in recwarn if issubclass(w.category, RuntimeWarning)]
    assert result.success and result.residual_px.max() < EXACT
