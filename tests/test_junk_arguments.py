"""Issue 31: each class of junk argument the fuzz (tests/fuzz_entries_junk.py) found escaping untyped or
accepted, now a typed error naming the argument. One parametrized case per class, with the value that escaped."""

from __future__ import annotations

import numpy as np
import pytest

import carmkin
import carmkin.model.mount_joints
import carmkin.world.between
from carmkin.errors import PatientModelError, QPIKError, SimulationError, SingularityError, SweepError
from carmkin.patient import ParametricPatient
from carmkin.qp_ik import QPIKOptions
from carmkin.reproduce import chapter3, fit, repositioning, stitching, verdict
from carmkin.reproduce.error_model import ErrorModel
from carmkin.sweeps import export, plan_sweep

PRESET = carmkin.load_preset("siremobile-iso-c3d")
MOTORIZED = carmkin.load_preset("siremobile-iso-c3d-motorized-table")


def _room():
    return repositioning.make_room(PRESET, ErrorModel(), np.random.default_rng(0))


def _sweep(arc):
    return plan_sweep(PRESET, np.zeros(3), arc, 6)


CASES = [
    # reproduce: counts given as bools, strings, floats (truncated before), 0-d string arrays, huge
    ("tasks", SimulationError, lambda: repositioning.run(PRESET, tasks=True)),
    ("tasks", SimulationError, lambda: repositioning.run(PRESET, tasks=2.5)),
    ("tasks", SimulationError, lambda: repositioning.run(PRESET, tasks=np.array("2"))),
    ("tasks", SimulationError, lambda: repositioning.run(PRESET, tasks=10 ** 30)),
    ("procedures", SimulationError, lambda: stitching.run(PRESET, procedures="1")),
    ("procedures", SimulationError, lambda: chapter3.table_3_1(PRESET, procedures=float("nan"))),
    ("seed", SimulationError, lambda: repositioning.run(PRESET, tasks=1, seed=np.array(["1"]))),
    ("seed", SimulationError, lambda: chapter3.table_3_2(PRESET, seed=2.0)),
    ("system", SimulationError, lambda: repositioning.run(None, tasks=1)),
    ("model", SimulationError, lambda: stitching.run(PRESET, model="default")),
    ("guidance", SimulationError, lambda: chapter3.table_3_2(PRESET, guidance=True)),
    ("resamples", SimulationError, lambda: fit.fit(PRESET, [0.0], [0.0], tasks=3, resamples=-1)),
    ("base", SimulationError, lambda: fit.fit(PRESET, [0.0], [0.0], tasks=3, base=None)),
    ("progress", SimulationError, lambda: fit.fit(PRESET, [0.0], [0.0], tasks=3, progress=lambda: None)),
    ("corner_noise", SimulationError, lambda: fit.fit(PRESET, [1e300], [0.0], tasks=3)),
    ("repeats", SimulationError, lambda: verdict.verdict(PRESET, ErrorModel(), repeats="2")),
    ("repeats", SimulationError, lambda: verdict.verdict(PRESET, ErrorModel(), repeats=1)),
    ("experiments", SimulationError, lambda: verdict.verdict(PRESET, ErrorModel(), 2, experiments=["nope"])),
    ("seed", SimulationError, lambda: verdict.judge("x", "y", float("inf"), [1.0, 2.0])),
    ("kind", SimulationError, lambda: verdict.judge("x", "y", 1.0, [1.0, 2.0], kind="guessed")),
    ("values", SimulationError, lambda: verdict.judge("x", "y", 1.0, np.array("1.0"))),
    ("values", SimulationError, lambda: verdict.judge("x", "y", 1.0, {"a": 1.0})),
    ("ErrorModel.corner_noise_px", SimulationError, lambda: ErrorModel(corner_noise_px=1e300)),
    ("ErrorModel.frames", SimulationError, lambda: ErrorModel(frames=2.0)),
    # sweeps and their exports
    ("system", SweepError, lambda: plan_sweep(None, np.zeros(3))),
    ("compensate", SweepError, lambda: plan_sweep(
        PRESET, np.zeros(3), 30.0, 4, compensate="False")),
    ("weight of joint", SweepError, lambda: plan_sweep(
        PRESET, np.zeros(3), 30.0, 4, joint={"orbital": "1"})),
    ("weight of joint", SweepError, lambda: plan_sweep(
        PRESET, np.zeros(3), 30.0, 4, joint={"orbital": 1j})),
    ("geometry_only", SweepError, lambda: export.rtk_frames(
        _sweep(190.0), geometry_only="no")),
    ("volume_centre", SweepError, lambda: export.tigre_geometry(
        _sweep(190.0), volume_centre=b"1")),
    ("layout", SweepError, lambda: export.rtk_frames(_sweep(190.0), layout=np.array(["image", 1], dtype=object))),
    # the patient
    ("mass", PatientModelError, lambda: ParametricPatient(height=0.4, mass=650.0)),
    ("system", PatientModelError, lambda: ParametricPatient.on_table(None)),
    ("chest_z", PatientModelError, lambda: ParametricPatient.on_table(PRESET, chest_z=5.0)),
    ("lateral_x", PatientModelError, lambda: ParametricPatient.on_table(PRESET, lateral_x=-3.0)),
    ("patient", PatientModelError, lambda: carmkin.world.World(PRESET, ParametricPatient())),  # floating
    ("patient", PatientModelError, lambda: plan_sweep(PRESET, np.zeros(3), 30.0, 3, ParametricPatient())),
    # the QP
    ("QPIKOptions.progress_window", QPIKError, lambda: QPIKOptions(progress_window=2.5)),
    ("QPIKOptions.max_iterations", QPIKError, lambda: QPIKOptions(max_iterations=float("inf"))),
    ("QPIKOptions.damping", QPIKError, lambda: QPIKOptions(damping=1e300)),
    ("weights", QPIKError, lambda: carmkin.qp_ik.solve(MOTORIZED, MOTORIZED.fk(0.5 * (MOTORIZED.lower + MOTORIZED.upper)),
                                                       weights=np.full(MOTORIZED.nq, "1"))),
    ("prefer", QPIKError, lambda: carmkin.qp_ik.solve(PRESET, PRESET.fk(np.zeros(6)),
                                                      prefer=np.array(["x", 1], dtype=object))),
    # one experiment's public steps
    ("rng", SimulationError, lambda: repositioning.make_room(PRESET, ErrorModel(), 3)),
    ("calibrate", SimulationError, lambda: repositioning.make_room(PRESET, ErrorModel(), np.random.default_rng(0),
                                                                   calibrate="no")),
    ("room", SimulationError, lambda: stitching.run_procedure({}, np.random.default_rng(0))),
    ("end", SimulationError, lambda: repositioning.run_task(_room(), np.random.default_rng(0), end=True)),
    ("overlap", SimulationError, lambda: stitching.run_procedure(_room(), np.random.default_rng(0), overlap=[])),
    ("overlap", SimulationError, lambda: chapter3.metric_measurements(_room(), np.random.default_rng(0), overlap=1.5)),
    ("arms", PatientModelError, lambda: ParametricPatient(arms=np.array(["side", 1], dtype=object))),
    ("prefix", PatientModelError, lambda: ParametricPatient.on_table(PRESET).obstacles(prefix=None)),
    # presets: every error of a text names its source
    ("mine.toml", carmkin.errors.PresetError, lambda: carmkin.presets.parse_preset("", "mine.toml")),
    # singularity
    ("reference_frame", SingularityError, lambda: carmkin.singularity.jacobian(PRESET, np.zeros(6), "world")),
    ("length", SingularityError, lambda: carmkin.singularity.measure_map(PRESET, np.zeros(6), (0, 5), 3,
                                                                         length=np.array("1"))),
    ("pair", SingularityError, lambda: carmkin.singularity.measure_map(PRESET, np.zeros(6), np.array("ab"), 3)),
    ("pair", SingularityError, lambda: carmkin.singularity.singular_curves(PRESET, [None, 1], np.zeros(6))),
]


@pytest.mark.parametrize("name, error, call", CASES, ids=[f"{i}-{c[0]}" for i, c in enumerate(CASES)])
def test_junk_is_a_typed_error_naming_the_argument(name, error, call):
    with pytest.raises(error) as info:
        call()
    assert name in str(info.value)


def test_the_placements_that_rest_on_the_table_are_accepted():
    for system in (PRESET, MOTORIZED):
        patient = ParametricPatient.on_table(system, chest_z=0.3)
        assert len(carmkin.world.World(system, patient).obstacles) == len(patient.obstacles())


def test_failed_sweep_exports_are_refused_and_write_no_file(tmp_path):
    sweep = _sweep(360.0)
    assert not sweep.success
    path = tmp_path / "g.xml"
    for fn in (export.astra_vectors, export.tigre_geometry, export.positioner_angles, export.rtk_frames):
        with pytest.raises(SweepError, match="failed sweep"):
            fn(sweep)
    with pytest.raises(SweepError, match="failed sweep"):
        export.write_rtk_xml(sweep, path)
    assert not path.exists()
    assert export.rtk_frames(sweep, geometry_only=True)[0].shape == (sweep.n_views, 3)


# --- issue 41: the fuzz's LOW and UNTYPED classes (world queries, Between, motion, the mount) ----------------
def _world():
    from carmkin.world import World

    return World(PRESET)


def _q():
    return (PRESET.lower + PRESET.upper) / 2


def _between():
    from carmkin.world.between import Between

    world = _world()
    return Between(world, world)


def _motion():
    from carmkin.model import motion

    return motion


CASES_41 = [
    ("q", carmkin.errors.InvalidConfigurationError, lambda: _world().grouped("abc")),
    ("q", carmkin.errors.InvalidConfigurationError, lambda: _world().grouped(np.ones(PRESET.nq, bool))),
    ("q", carmkin.errors.InvalidConfigurationError, lambda: _world().distances(q=np.ones(PRESET.nq, complex))),
    ("data", carmkin.errors.CollisionSceneError, lambda: _world().distances(data="x")),
    ("qs", carmkin.errors.InvalidConfigurationError, lambda: _world().clearance([[1.0], [1.0, 2.0]])),
    ("qs", carmkin.errors.InvalidConfigurationError, lambda: _world().nearest(np.array("a"))),
    ("exact_below", carmkin.errors.CollisionSceneError, lambda: _world().clearance(_q(), exact_below="1")),
    ("exact_below", carmkin.errors.CollisionSceneError, lambda: _world().nearest(_q(), exact_below=float("nan"))),
    ("exact_below", carmkin.errors.CollisionSceneError, lambda: _world().nearest(_q(), exact_below=True)),
    ("exact_below", carmkin.errors.CollisionSceneError, lambda: _world().nearest(_q(), exact_below=1j)),
    ("stop_below", carmkin.errors.CollisionSceneError, lambda: _world().nearest(_q(), stop_below=np.array("a"))),
    ("order", carmkin.errors.CollisionSceneError, lambda: _world().moves(_q(), _q(), order=5)),
    ("stop_at_contact", carmkin.errors.CollisionSceneError, lambda: _world().swept(_q(), _q(), stop_at_contact="False")),
    ("path_min", carmkin.errors.CollisionSceneError, lambda: _world().swept(_q(), _q(), path_min=float("nan"))),
    ("path_min", carmkin.errors.CollisionSceneError, lambda: _world().swept(_q(), _q(), path_min=True)),
    ("world_a", carmkin.errors.CollisionSceneError, lambda: carmkin.world.between.Between(None, _world())),
    ("links", carmkin.errors.CollisionSceneError, lambda: carmkin.world.between.Between(_world(), _world(),
                                                                                         links=None)),
    ("q of world a", carmkin.errors.CollisionSceneError, lambda: _between().distances(np.ones(PRESET.nq, bool), _q())),
    ("q of world a", carmkin.errors.CollisionSceneError, lambda: _between().nearest(["a"] * PRESET.nq, _q())),
    ("names", carmkin.errors.MotionError, lambda: _motion().Motion.of({"a": 1}, [1.0])),
    ("speeds", carmkin.errors.MotionError, lambda: _motion().Motion.of(["a"], b"x")),
    ("accelerations", carmkin.errors.MotionError, lambda: _motion().Motion.of(["a"], [1.0], 5)),
    ("prismatic", carmkin.errors.MotionError, lambda: _motion().follow(PRESET.motion, np.zeros((3, PRESET.nq)), 1.0,
                                                                       prismatic="yes")),
    ("system", carmkin.errors.MotionError, lambda: _motion().system_move(None, _q(), _q())),
    ("timing", carmkin.errors.MotionError, lambda: _motion().move_duration(PRESET.motion, _q(), _q(),
                                                                           np.ones(PRESET.nq, bool))),
    ("base_origin", carmkin.errors.InvalidParameterError, lambda: carmkin.model.mount_joints.MountGeometry(
        base_origin=np.ones(3, complex))),
    ("base_origin", carmkin.errors.InvalidParameterError, lambda: carmkin.model.mount_joints.MountGeometry(
        base_origin=np.ones(3, bool))),
    ("base_x_axis", carmkin.errors.InvalidParameterError, lambda: carmkin.model.mount_joints.MountGeometry(
        base_x_axis=np.array([1j, 0, 0]))),
    ("carm_base", carmkin.errors.InvalidParameterError, lambda: carmkin.model.mount_joints.MountGeometry(
        carm_base=((0, 0, 0), (1j, 0, 0), (0, 0, 1)))),
]


@pytest.mark.parametrize("name, error, call", CASES_41, ids=[f"{i}-{c[0]}" for i, c in enumerate(CASES_41)])
def test_issue_41_junk_is_a_typed_error_naming_the_argument(name, error, call):
    """Issue 41 (fuzz, LOW and UNTYPED): junk to World.grouped/distances/clearance/nearest/moves and Between, a
    truthy string as swept(stop_at_contact=), NaN/bool/complex thresholds, junk to Motion.of, follow,
    system_move, move_duration, complex or bool arrays to MountGeometry: each a typed error naming the argument
    (before: ValueError, TypeError, AttributeError, pinocchio's ArgumentError, a ComplexWarning, or accepted)."""
    with pytest.raises(error) as info:
        call()
    assert name in str(info.value)


# --- issue 41, the rest of the fuzz's classes: "Still from before" and UNTYPED leftovers --------------------
def _tree():
    from carmkin.views.anatomy import synthetic_tree

    return synthetic_tree(np.array([0.02, 0.05, -0.02]), 0)


def _experiment_config(**changes):
    from carmkin.reposition.experiment import ExperimentConfig

    return ExperimentConfig(**changes)


def _anatomy_map(others):
    from carmkin.views import optimal_view_map

    return optimal_view_map(PRESET, _tree()[0], [0.0], [0.0], None, others, plan=False)


CASES_41_MORE = [
    ("roll", carmkin.errors.ViewError, lambda: carmkin.views.View.from_pose(PRESET.fk(_q()), 0.6, roll="False")),
    ("seed", carmkin.errors.CentrelineError, lambda: carmkin.views.anatomy.synthetic_tree(np.zeros(3), None)),
    ("seed", carmkin.errors.CentrelineError, lambda: carmkin.views.anatomy.synthetic_tree(np.zeros(3), 1.5)),
    ("vessels", carmkin.errors.CentrelineError, lambda: carmkin.views.anatomy.synthetic_tree(np.zeros(3), 0, 10 ** 30)),
    ("points", carmkin.errors.CentrelineError, lambda: carmkin.views.anatomy.synthetic_tree(np.zeros(3), 0, 4, "40")),
    ("spacing", SimulationError, lambda: stitching.phantom_points(spacing=0.0)),
    ("length", SimulationError, lambda: stitching.phantom_points(length=0.0)),
    ("length", SimulationError, lambda: stitching.phantom_points(length=-1.0)),
    ("rows", SimulationError, lambda: stitching.phantom_points(rows=0)),
    ("width", SimulationError, lambda: stitching.phantom_points(width=-0.08)),
    ("markers", SimulationError, lambda: stitching.phantom_points(length=10.0, spacing=1e-9)),
    ("corner_noise_px", SimulationError, lambda: _experiment_config(corner_noise_px="junk")),
    ("operator", SimulationError, lambda: _experiment_config(operator="junk")),
    ("guidance", SimulationError, lambda: _experiment_config(guidance="junk")),
    ("mount_error", SimulationError, lambda: _experiment_config(mount_error="junk")),
    ("calibration_positions", SimulationError, lambda: _experiment_config(calibration_positions="junk")),
    ("table_shift", SimulationError, lambda: _experiment_config(table_shift="junk")),
    ("max_steps", SimulationError, lambda: _experiment_config(max_steps="junk")),
    ("reference_ranges", SimulationError, lambda: _experiment_config(reference_ranges="junk")),
    ("reference_ranges['vertical']", SimulationError, lambda: _experiment_config(reference_ranges={"vertical": (1, 0)})),
    ("others", carmkin.errors.AnatomyError, lambda: _anatomy_map(5)),
]


@pytest.mark.parametrize("name, error, call", CASES_41_MORE, ids=[f"{i}-{c[0]}" for i, c in enumerate(CASES_41_MORE)])
def test_issue_41_remaining_junk_is_a_typed_error_naming_the_argument(name, error, call):
    """Issue 41 (fuzz, "Still from before", LOW, UNTYPED, HANG): a truthy string as View.from_pose(roll=),
    synthetic_tree's seed None (not deterministic) or 10**30 vessels (hung), phantom_points' zero or negative
    sizes and spacing=0 (ZeroDivisionError), junk ExperimentConfig fields (accepted, or TypeError/ValueError),
    an int as optimal_view_map(others=) (TypeError): each a typed error naming the argument."""
    with pytest.raises(error) as info:
        call()
    assert name in str(info.value)


def test_other_vessels_with_per_point_radii_of_different_lengths_are_mapped():
    """Issue 41 (fuzz, MED): optimal_view_map crashed (numpy's ValueError) when the other vessels carried
    per-point radii of different lengths. Each vessel's radii now stay its own: the overlap equals the one of a
    map given each vessel's one radius where its radii are all equal."""
    from carmkin.views import optimal_view_map
    from carmkin.views.anatomy import Centreline

    tree = _tree()
    a, b = tree[1].points, tree[2].points[:10]
    ragged = [Centreline(a, np.full(len(a), 1e-3), "a"), Centreline(b, np.full(len(b), 2e-3), "b")]
    primary, secondary = np.arange(-90.0, 91.0, 30.0), np.array([-30.0, 0.0, 30.0])
    m = optimal_view_map(PRESET, tree[0], primary, secondary, None, ragged, plan=False)
    from carmkin.imaging import intrinsics
    from carmkin.views import metrics

    P, S = np.meshgrid(primary, secondary, indexing="ij")
    poses = metrics.xa_poses(P.ravel(), S.ravel(), m.target, m.distance)
    K = intrinsics(PRESET)[0]
    expected = np.maximum(*(metrics.overlap(tree[0].points, [v], poses, K, r) for v, r in ((a, 1e-3), (b, 2e-3))))
    union = metrics.overlap(tree[0].points, [a, b], poses, K, [1e-3, 2e-3]).reshape(m.overlap.shape)
    assert np.array_equal(m.overlap, union)
    assert np.all(union.ravel() >= expected - 1e-12) and np.any(union > 0)


def _preset_file(tmp_path, data: bytes):
    path = tmp_path / "user.toml"
    path.write_bytes(data)
    return path


def _builtin_text():
    from pathlib import Path

    return (Path(carmkin.__file__).parent / "presets" / "siremobile-iso-c3d.toml").read_text()


def _dict_with_key(section, key):
    import tomllib

    data = tomllib.loads(_builtin_text())
    (data if section is None else data[section])[key] = 1
    return data


@pytest.mark.parametrize("name, make", [
    ("not a UTF-8 text file", lambda tmp: carmkin.load_preset(_preset_file(tmp, b"\xff\xfe" + _builtin_text().encode()))),
    ("cannot hold as a number", lambda tmp: carmkin.load_preset(_preset_file(tmp, _builtin_text().replace(
        "detector_columns = 800", "detector_columns = " + "9" * 5000).encode()))),
    ("every key in the top level must be a string, got 5",
     lambda tmp: carmkin.presets.system_from_dict(_dict_with_key(None, 5))),
    ("every key in [carm] must be a string, got 7",
     lambda tmp: carmkin.presets.system_from_dict(_dict_with_key("carm", 7))),
])
def test_issue_41_junk_preset_files_are_a_preset_error(name, make, tmp_path):
    """Issue 41 (fuzz, "Still from before"): a non-UTF-8 preset file (UnicodeDecodeError), a 5000-digit
    integer (Python's ValueError) and a non-string key in a preset dict (difflib's TypeError)."""
    assert "detector_columns = 800" in _builtin_text()
    with pytest.raises(carmkin.errors.PresetError) as info:
        make(tmp_path)
    assert name in str(info.value)


@pytest.mark.parametrize("name, call", [
    ("BodyGeometry.cart_size", lambda junk: carmkin.BodyGeometry(cart_size=junk)),
    ("BodyGeometry.source_housing", lambda junk: carmkin.BodyGeometry(source_housing=junk)),
    ("TableGeometry.top_size", lambda junk: carmkin.TableGeometry(top_size=junk)),
    ("TableGeometry.top_center", lambda junk: carmkin.TableGeometry(top_center=junk)),
    ("TableGeometry.joints", lambda junk: carmkin.TableGeometry(joints=junk)),
    ("principal_point", lambda junk: PRESET.carm.replace(principal_point=junk) if hasattr(PRESET.carm, "replace")
     else __import__("dataclasses").replace(PRESET.carm, principal_point=junk)),
    ("size", lambda junk: __import__("carmkin.interop.simulators").interop.simulators.diffdrr_detector(
        PRESET.carm.intrinsics(), junk, 980.0)),
])
@pytest.mark.parametrize("junk", [np.array("1"), 1j, {"a": 1, "b": 2}], ids=["0-d string array", "complex", "dict"])
def test_issue_41_sizes_that_are_not_sequences_are_typed(name, call, junk):
    """Issue 41 (fuzz, "Still from before"): 0-d string arrays, complex numbers or a dict as body, table or
    detector sizes (and the DRR detector size) escaped as TypeError/KeyError from len() or indexing."""
    with pytest.raises(carmkin.CarmkinError) as info:
        call(junk)
    assert name in str(info.value)


@pytest.mark.parametrize("call", [
    lambda: carmkin.views.plane_views(PRESET, [[0.01, 0, 0], [0, 0.01, 0], [-0.01, 0, 0.001]], count=4, plan="False"),
    lambda: carmkin.views.optimal_view_map(PRESET, _tree()[0], [0.0], [0.0], plan="False"),
], ids=["plane_views", "optimal_view_map"])
def test_issue_41_a_truthy_string_as_plan_is_refused(call):
    """Issue 41 (fuzz, LOW): plane_views(plan="False") planned (a non-empty string reads as True)."""
    with pytest.raises(carmkin.errors.ViewError, match="plan must be True or False"):
        call()
