"""The calibration's value object and where the toolkit reads it: the nominal system unchanged, the detector's
rotation and sag against an explicit ray–detector-plane construction, the batch projections against the one
view's, the [calibration] preset section both ways."""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import carmkin
from carmkin.errors import InvalidParameterError, PresetError
from carmkin.imaging import projection_from_pose, projection_matrices, projection_matrix
from carmkin.model.calibration import Calibration
from carmkin.presets import parse_preset, to_toml

SYSTEM = carmkin.load_preset("siremobile-iso-c3d")
MOTORIZED = carmkin.load_preset("siremobile-iso-c3d-motorized-table")
#: Agreement of two computations of the same pixel or projection matrix entry (relative, float64 round-off).
SAME = 1e-12


def _configurations(system, n, seed=0):
    rng = np.random.default_rng(seed)
    return system.lower + (system.upper - system.lower) * rng.uniform(size=(n, system.nq))


def test_a_nominal_system_projects_exactly_as_before():
    assert SYSTEM.calibration == Calibration() and SYSTEM.calibration.is_nominal
    for q in _configurations(SYSTEM, 5):
        expected = projection_from_pose(SYSTEM.carm.intrinsics(), SYSTEM.fk(q))
        assert np.array_equal(projection_matrix(SYSTEM, q), expected)
    assert "[calibration]" not in to_toml(SYSTEM)


def _detector_pixel(system, calibration, T, X, orbital):
    """The pixel of world point X by construction: the ray from the source meets the detector plane z = f (source
    frame); the detector, turned by ρ about the principal axis and shifted by s(θ5) along Y_xray, reads the hit
    point in its own axes, in pixels of size (sx, sy) from the principal point."""
    carm = system.carm
    Xc = T[:3, :3].T @ (X - T[:3, 3])
    hit = carm.source_to_detector * Xc[:2] / Xc[2]
    shift = calibration.sag_cos * math.cos(orbital) + calibration.sag_sin * math.sin(orbital)
    rho = calibration.detector_rotation
    axes = np.array([[math.cos(rho), -math.sin(rho)], [math.sin(rho), math.cos(rho)]])  # columns: detector u, v
    local = axes.T @ (hit - np.array([0.0, shift]))
    sx, sy = carm.pixel_spacing
    return carm.intrinsics()[:2, 2] + local / np.array([sx, sy])


@settings(max_examples=40)
@given(st.floats(-3, 3), st.floats(-0.01, 0.01), st.floats(-0.01, 0.01), st.integers(0, 2**31))
def test_detector_rotation_and_sag_equal_the_ray_and_plane_construction(rho_deg, sag_cos, sag_sin, seed):
    calibration = Calibration(detector_rotation=math.radians(rho_deg), sag_cos=sag_cos, sag_sin=sag_sin)
    system = SYSTEM.replace(calibration=calibration)
    q = _configurations(system, 1, seed)[0]
    T = system.fk(q)
    X = T[:3, 3] + 0.6 * T[:3, 2] + np.random.default_rng(seed).uniform(-0.1, 0.1, 3)
    m = projection_matrix(system, q) @ np.append(X, 1.0)
    assert np.allclose(m[:2] / m[2], _detector_pixel(system, calibration, T, X, q[-1]), rtol=0, atol=1e-9)


@pytest.mark.parametrize("system", [SYSTEM, MOTORIZED], ids=["6 joints", "motorized"])
@pytest.mark.parametrize("calibrated", [False, True])
def test_batch_projections_equal_each_view(system, calibrated):
    if calibrated:
        system = system.replace(calibration=Calibration(tuple(0.001 * np.arange(system.nq)), 0.01, 0.002, -0.003))
    Q = _configurations(system, 6)
    batch = projection_matrices(system, Q)
    for q, P in zip(Q, batch):
        single = projection_matrix(system, q)
        assert np.abs(P - single).max() <= SAME * np.abs(single).max()


def test_readings_and_model_joints_are_inverse():
    calibration = Calibration((0.001, -0.002, 0.01, 0.003, -0.02, 0.005))
    q = _configurations(SYSTEM, 4)
    assert np.allclose(calibration.model_joints(q) - q, calibration.joint_offsets)
    assert np.allclose(calibration.readings(calibration.model_joints(q)), q, rtol=0, atol=1e-15)
    assert np.array_equal(Calibration().model_joints(q), q)


def test_a_calibration_must_have_one_offset_per_joint():
    with pytest.raises(InvalidParameterError, match="joint_offsets has 3 values, the system has 6 joints"):
        SYSTEM.replace(calibration=Calibration((0.0, 0.0, 0.0)))
    with pytest.raises(InvalidParameterError, match=r"Calibration.detector_rotation"):
        Calibration(detector_rotation=float("nan"))
    with pytest.raises(InvalidParameterError, match=r"joint_offsets must be a tuple"):
        Calibration(joint_offsets="0.1")


@pytest.mark.parametrize("system", [SYSTEM, MOTORIZED], ids=["6 joints", "motorized"])
def test_the_calibration_section_round_trips(system):
    calibrated = system.replace(calibration=Calibration(tuple(0.001 * (1 + np.arange(system.nq))), 0.01, 2e-3, -1e-3))
    back = parse_preset(to_toml(calibrated))
    assert np.allclose(back.calibration.offsets(back.nq), calibrated.calibration.offsets(system.nq), rtol=1e-12)
    assert math.isclose(back.calibration.detector_rotation, 0.01, rel_tol=1e-12)
    assert (back.calibration.sag_cos, back.calibration.sag_sin) == pytest.approx((2e-3, -1e-3), rel=1e-12)


def test_the_calibration_section_is_checked():
    text = to_toml(SYSTEM)
    with pytest.raises(PresetError, match="table_tilt_zero_offset_deg: the system has no such joint"):
        parse_preset(text + "\n[calibration]\ntable_tilt_zero_offset_deg = 0.1\n")
    with pytest.raises(PresetError, match="unknown key 'orbital_zero_ofset_deg'.*orbital_zero_offset_deg"):
        parse_preset(text + "\n[calibration]\norbital_zero_ofset_deg = 0.1\n")
    system = parse_preset(text + "\n[calibration]\norbital_zero_offset_deg = 0.5\n")
    assert system.calibration.offsets(6) == pytest.approx([0, 0, 0, 0, 0, math.radians(0.5)])


def test_a_calibrated_sweep_has_the_calibrated_projection_matrices():
    """Sweep.P of a calibrated system is the calibrated detector's (H K [Rᵀ|−Rᵀp] per view), not the nominal."""
    from carmkin.sweeps import plan_sweep

    nominal = carmkin.load_preset("siremobile-iso-c3d")
    calibrated = nominal.replace(calibration=Calibration(joint_offsets=(0.0,) * 6, detector_rotation=0.01,
                                                         sag_cos=0.001, sag_sin=-0.002))
    sweep = plan_sweep(calibrated, (0.0, 0.0, 0.0), 190.0, 12)
    P = projection_matrices(calibrated, sweep.q)
    assert np.abs(sweep.P - P).max() <= 1e-12 * np.abs(P).max()
    assert np.abs(plan_sweep(nominal, (0.0, 0.0, 0.0), 190.0, 12).P - P).max() > 1e-3 * np.abs(P).max()
