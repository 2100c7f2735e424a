"""Projection matrices (carmkin.imaging.projection): P against the pinhole projection, P ↔ pose ↔ joints
round trips over random non-isocentric systems, the patient frames of DICOM PS3.17 FFF.1.2.2.2, errors."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import assume, given
from hypothesis import strategies as st
from strategies import PRESET, configurations, systems

from carmkin import analytic_ik, imaging
from carmkin.imaging.projection import PATIENT_POSITIONS

#: Round-trip tolerance of issue 15 (m, rad, and relative for matrices).
ROUND_TRIP = 1e-9

finite = dict(allow_nan=False, allow_infinity=False)


def rotation_angle(R1, R2) -> float:
    """Angle (rad) of R1ᵀ R2, well conditioned near 0 (atan2 of the skew and symmetric parts)."""
    E = R1.T @ R2
    sin = 0.5 * np.linalg.norm([E[2, 1] - E[1, 2], E[0, 2] - E[2, 0], E[1, 0] - E[0, 1]])
    return float(np.arctan2(sin, 0.5 * (np.trace(E) - 1.0)))


def points(data, n=8):
    """World points (n, 3) in a 2 m cube (m)."""
    return np.array(data.draw(st.lists(st.tuples(*[st.floats(-1, 1, **finite)] * 3), min_size=n, max_size=n)))


@given(st.data())
def test_projection_matrix_agrees_with_the_pinhole_projection(data):
    system = data.draw(systems())
    q = data.draw(configurations(system))
    P = imaging.projection_matrix(system, q)
    K, size = imaging.intrinsics(system)
    assert size == (system.carm.detector_columns, system.carm.detector_rows)
    T = system.fk(q)
    X = points(data)
    depth = (X - T[:3, 3]) @ T[:3, 2]
    X = X[depth > 0.05]
    assume(len(X))
    expected = imaging.project(K, T, X)
    m = np.column_stack((X, np.ones(len(X)))) @ P.T
    got = m[:, :2] / m[:, 2:]
    assert np.abs(got - expected).max() <= ROUND_TRIP * max(1.0, np.abs(expected).max())


@given(st.data())
def test_projection_to_pose_to_joints_round_trip(data):
    system = data.draw(systems())
    q = data.draw(configurations(system))
    assume(abs(math.cos(q[4])) > 1e-3 and abs(math.sin(q[2] + system.setup.gamma3)) > 1e-3)
    scale = data.draw(st.sampled_from([1.0, -1.0, 1e-3, -250.0]))
    P = scale * imaging.projection_matrix(system, q)
    K, T = imaging.pose_from_projection(P)
    assert np.abs(K - system.carm.intrinsics()).max() <= ROUND_TRIP * np.abs(K).max()
    T_true = system.fk(q)
    assert np.linalg.norm(T[:3, 3] - T_true[:3, 3]) <= ROUND_TRIP
    assert rotation_angle(T[:3, :3], T_true[:3, :3]) <= ROUND_TRIP
    # ... and back to P, up to the scale.
    P_again = imaging.projection_from_pose(K, T) * scale
    assert np.abs(P_again - P).max() <= ROUND_TRIP * np.abs(P).max()
    # ... and to joints through the closed-form IK: a branch lands on the pose.
    result = analytic_ik.solve(system, T)
    # (a far branch may put the table tens of metres out: fk's unit-slip guard is not this test's subject)
    poses = [system.fk(s, check_units=False) for s, b in zip(result.solutions, result.branches) if b.reached]
    errors = [max(np.linalg.norm(T_s[:3, 3] - T_true[:3, 3]), rotation_angle(T_s[:3, :3], T_true[:3, :3]))
              for T_s in poses]
    assert errors and min(errors) <= ROUND_TRIP


def test_patient_positions_are_right_handed_lps_frames():
    """Each row of the PS3.17 table gives Left × Posterior = Head (a proper rotation)."""
    for code, (left, posterior, head) in PATIENT_POSITIONS.items():
        assert np.array_equal(np.cross(left, posterior), head), code
        R = imaging.patient_pose(code)[:3, :3]
        assert np.isclose(np.linalg.det(R), 1.0)


@pytest.mark.parametrize("code", ["HFS", "HFP", "HFDR", "HFDL"])
def test_patient_positions_follow_from_their_names(code):
    """Head first: head towards the table head (+Z0); feet first is the same patient turned by 180° about
    the vertical (Y0); supine: posterior down (+Y0); prone: anterior down; decubitus left/right: that side
    down."""
    down, head_end = np.array([0, 1, 0]), np.array([0, 0, 1])
    R = imaging.patient_pose(code)[:3, :3]
    left, posterior, head = R.T
    assert np.array_equal(head, head_end)
    expected_down = {"HFS": posterior, "HFP": -posterior, "HFDR": -left, "HFDL": left}[code]
    assert np.array_equal(expected_down, down)
    turned = np.diag([-1.0, 1.0, -1.0])  # half turn about Y0
    feet_first = imaging.patient_pose("FF" + code[2:])[:3, :3]
    assert np.allclose(feet_first, turned @ R)


@given(st.data())
def test_projection_in_the_patient_frame_sees_the_same_pixels(data):
    system = data.draw(systems())
    q = data.draw(configurations(system))
    code = data.draw(st.sampled_from(sorted(PATIENT_POSITIONS)))
    origin = np.array(data.draw(st.tuples(*[st.floats(-0.5, 0.5, **finite)] * 3)))
    T_patient = imaging.patient_pose(code, origin)
    X_patient = points(data)
    X_table = X_patient @ T_patient[:3, :3].T + origin
    P_table = imaging.projection_matrix(system, q)
    P_patient = imaging.projection_matrix(system, q, patient=T_patient)
    a = np.column_stack((X_table, np.ones(len(X_table)))) @ P_table.T
    b = np.column_stack((X_patient, np.ones(len(X_patient)))) @ P_patient.T
    assert np.abs(a - b).max() <= ROUND_TRIP * max(1.0, np.abs(a).max())


def test_patient_code_uses_the_table_origin():
    q = 0.5 * (PRESET.lower + PRESET.upper)
    assert np.allclose(imaging.projection_matrix(PRESET, q, "HFS"), imaging.projection_matrix(PRESET, q))


@pytest.mark.parametrize("bad, match", [
    (np.zeros((3, 4)), "non-zero third row"),
    (np.hstack((np.ones((3, 3)), np.ones((3, 1)))), "rank 3"),
    (np.ones((3, 3)), "shape"),
    (np.full((3, 4), np.nan), "finite"),
])
def test_bad_projection_matrices_raise(bad, match):
    with pytest.raises(imaging.ImagingError, match=match):
        imaging.pose_from_projection(bad)


def test_bad_patient_position_raises():
    with pytest.raises(imaging.ImagingError, match="HFS"):
        imaging.patient_pose("supine")
    with pytest.raises(imaging.ImagingError, match="origin"):
        imaging.patient_pose("HFS", origin=(0, 0))


# --- issue 19: the projection boundary ------------------------------------------------------------------
def test_projection_from_pose_refuses_a_zero_K():
    # before: P = 0 came back
    with pytest.raises(imaging.ImagingError, match="shape"):
        imaging.projection_from_pose(0, np.eye(4))
    with pytest.raises(imaging.ImagingError, match="K\\[2, 2\\] = 1"):
        imaging.projection_from_pose(np.zeros((3, 3)), np.eye(4))
    with pytest.raises(imaging.ImagingError, match="focal"):
        imaging.projection_from_pose(np.diag([0.0, 0.0, 1.0]), np.eye(4))
    with pytest.raises(imaging.ImagingError, match="K\\[2, 2\\] = 1"):
        imaging.projection_from_pose(5.0 * PRESET.carm.intrinsics(), np.eye(4))


def test_pose_from_projection_refuses_strings_and_complex():
    P = imaging.projection_matrix(PRESET, 0.5 * (PRESET.lower + PRESET.upper))
    with pytest.raises(imaging.ImagingError):
        imaging.pose_from_projection(P.astype(str))  # before: parsed
    with pytest.raises(imaging.ImagingError, match="complex"):
        imaging.pose_from_projection(P + 1e-3j)  # before: the imaginary part was dropped


@pytest.mark.parametrize("entry", [(0, 0), (0, 3), (1, 2), (2, 3), (2, 0)])
@pytest.mark.parametrize("huge", [1e150, -1e200, 1e300])
def test_pose_from_projection_huge_entry_is_refused_or_right(entry, huge):
    # before: NaN intrinsics for a finite P with one huge entry
    P = imaging.projection_matrix(PRESET, 0.5 * (PRESET.lower + PRESET.upper))
    P[entry] = huge
    try:
        K, T = imaging.pose_from_projection(P)
    except imaging.ImagingError:
        return
    assert np.all(np.isfinite(K)) and np.all(np.isfinite(T))
    again = imaging.projection_from_pose(K, T)
    scale = P[2, :3] @ again[2, :3] / (again[2, :3] @ again[2, :3])
    assert np.allclose(scale * again, P, rtol=1e-9, atol=1e-9 * np.abs(P).max())
