"""Issue 19: each defect of the outside boundary in the imaging, transforms and presets modules, pinned.

Every test reproduces one reported input and fails on the code before the fix (the comment says what came
back then).
"""

import numpy as np
import pytest

import carmkin
from carmkin import transforms
from carmkin.errors import CarmkinError, InvalidPoseError, PanoramaError, PresetError
from carmkin.panorama import PanoramaPlanner
from carmkin.presets import preset_provenance, system_from_dict

PRESET = carmkin.load_preset("siremobile-iso-c3d")
JUNK = [None, {"a": 1}, "1.5", b"1.5", 1 + 0j, True]


@pytest.fixture(scope="module")
def planner():
    return PanoramaPlanner(PRESET)


@pytest.mark.parametrize("du, dv", [(1e300, 1e300), (1e-320, 0.0), (5e-324, 5e-324)])
def test_direction_from_pixels_never_a_zero_unit_vector(planner, du, dv):
    # before: (1e300, 1e300) overflowed the norm and returned (0, 0, 0) as a "unit" vector
    try:
        d = planner.direction_from_pixels(du, dv)
    except PanoramaError:
        return
    assert abs(np.linalg.norm(d) - 1.0) < 1e-12
    expected = np.array([du / planner.K[0, 0], dv / planner.K[1, 1]])
    assert np.allclose(d[:2] * np.abs(expected).max(), expected / np.linalg.norm(expected / np.abs(expected).max()),
                       rtol=1e-12)


def test_direction_from_pixels_tiny_but_exact(planner):
    d = planner.direction_from_pixels(1e-300, 0.0)  # before: refused as zero (norm underflow)
    assert np.allclose(d, (1.0, 0.0, 0.0))


@pytest.mark.parametrize("junk", JUNK)
@pytest.mark.parametrize("call", [
    lambda p, j: p.direction_from_pixels(j, 1.0),
    lambda p, j: p.rotation_for(j),
    lambda p, j: p.shot((400.0, 300.0), q_current=j),
    lambda p, j: p.line_shots(0.3, direction=j),
    lambda p, j: p.extent(j, (1.0, 0.0, 0.0), 0.5),
    lambda p, j: PanoramaPlanner(PRESET, q_reference=j),
    lambda p, j: PanoramaPlanner(PRESET, margin=j),
    lambda p, j: p.validity_map(j, [300.0]),
])
def test_panorama_junk_is_typed(planner, junk, call):
    try:
        call(planner, None)
        none_is_default = True
    except CarmkinError:
        none_is_default = False
    if junk is None and none_is_default:
        return  # None is the documented default there
    with pytest.raises(CarmkinError):
        call(planner, junk)


@pytest.mark.parametrize("junk", JUNK)
@pytest.mark.parametrize("call", [
    transforms.inverse, transforms.skew, transforms.rot_x, transforms.translation, transforms.wrap_angle,
    lambda j: transforms.rotation_between(j, (0, 0, 1)),
    lambda j: transforms.dh_matrix(j, 0.0, 0.0, 0.0),
    lambda j: transforms.pose_error(j, np.eye(4)),
    lambda j: transforms.segment_hits_box(j, (1, 1, 1), (0, 0, 0), (1, 1, 1)),
])
def test_transforms_junk_is_typed(junk, call):
    with pytest.raises(CarmkinError):
        call(junk)


def test_inverse_refuses_a_non_rigid_matrix():
    T = np.eye(4)
    T[:3, :3] *= 2.0  # before: returned a matrix that is not T's inverse
    with pytest.raises(InvalidPoseError):
        transforms.inverse(T)


def test_wrap_angle_refuses_infinity_and_bool():
    for value in (np.inf, float("-inf"), np.array([0.0, np.inf]), True):
        with pytest.raises(CarmkinError):
            transforms.wrap_angle(value)
    assert np.isnan(transforms.wrap_angle(float("nan")))


def test_rotation_between_tiny_vectors():
    # before: the norm of (1e-200, 0, 0) underflowed to 0 and the rotation came back NaN
    R = transforms.rotation_between((1e-200, 0.0, 0.0), (0.0, 1e-200, 0.0))
    assert np.allclose(R @ (1.0, 0.0, 0.0), (0.0, 1.0, 0.0))


@pytest.mark.parametrize("data", [[], None, "carm", 3, ("carm",)])
def test_system_from_dict_refuses_non_dicts(data):
    with pytest.raises(PresetError, match="dict"):  # before: AttributeError
        system_from_dict(data)


@pytest.mark.parametrize("name", [3, None, b"siremobile-iso-c3d", ["siremobile-iso-c3d"]])
def test_preset_provenance_refuses_non_paths(name):
    with pytest.raises(PresetError):  # before: TypeError / AttributeError
        preset_provenance(name)


def test_homography_between_refuses_a_distance_without_a_normal():
    from carmkin import imaging

    K = PRESET.carm.intrinsics()
    with pytest.raises(CarmkinError, match="without the plane normal"):  # before: d silently ignored
        imaging.homography_between(K, np.eye(4), np.eye(4), None, 0.5)


@pytest.mark.parametrize("junk", JUNK)
def test_junk_system_is_typed(junk):
    from carmkin import imaging, singularity
    from carmkin.interop import simulators

    q = np.zeros(6)
    for call in (lambda: imaging.projection_matrix(junk, q), lambda: simulators.deepdrr_mobile_carm(junk, q),
                 lambda: singularity.measures(junk, q), lambda: singularity.singular_curves(junk, (2, 4)),
                 lambda: singularity.grid_axis(junk, 2, 5)):
        with pytest.raises(CarmkinError, match="system"):  # before: AttributeError
            call()
