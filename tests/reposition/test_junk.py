"""Junk input at every public function of carmkin.reposition: a CarmkinError naming the argument, never a
numpy/OpenCV/scipy exception or a leaked warning (issue 19)."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

import carmkin
from carmkin.reposition import calibration, camera, guidance, model, pattern, pose, render, reprojection, world

SYSTEM = carmkin.load_preset("siremobile-iso-c3d")
BOARD = pattern.MarkerBoard()
MOUNT = world.system_mount(SYSTEM, BOARD)
K = SYSTEM.carm.intrinsics()
SIZE = (800, 600)
Q = np.array([0.0, 0.05, 0.0, 0.1, 0.1, -0.1])
T_CAM = camera.camera_in_marker(MOUNT, SYSTEM.fk(Q))
VIEW = camera.visible_corners(BOARD, K, SIZE, T_CAM)
OBJ, IMG = VIEW.object_points, VIEW.image_points
ESTIMATE = pose.pose_from_view(VIEW, K, sigma_px=0.2)
MOVES = calibration.calibration_moves(6, 0.2)
WORLD = world.World(SYSTEM, BOARD, MOUNT, MOUNT[:3, :3])
GUIDE = guidance.Guide(SYSTEM, SYSTEM.fk(Q), Q)
JUNK = [None, {"a": 1}, "1.5", b"1.5", 1 + 0j, True, float("nan"), np.zeros((2, 2, 2)), [[1.0, 2.0], [3.0]]]
rng = np.random.default_rng

#: (name, function, valid arguments): each argument in turn is replaced by each junk value.
CALLS = [
    ("camera.check_intrinsics", camera.check_intrinsics, (K,)),
    ("camera.project_points", camera.project_points, (K, T_CAM, OBJ)),
    ("camera.visible_corners", camera.visible_corners, (BOARD, K, SIZE, T_CAM)),
    ("camera.with_noise", camera.with_noise, (VIEW, 0.2, rng(0))),
    ("camera.camera_in_marker", camera.camera_in_marker, (MOUNT, SYSTEM.fk(Q))),
    ("camera.check_image_size", camera.check_image_size, (SIZE,)),
    ("pattern.MarkerBoard", pattern.MarkerBoard, (4, 3, 0.01, 0.002, "DICT_4X4_50")),
    ("pattern.nominal_mount", pattern.nominal_mount, (BOARD, 0.21)),
    ("pattern.mounted", pattern.mounted, (MOUNT, np.eye(3))),
    ("render.board_homography", render.board_homography, (K, T_CAM)),
    ("render.render", render.render, (BOARD, K, SIZE, T_CAM, 0.8, 2.0, rng(0))),
    ("reprojection.reprojection_jacobian", reprojection.reprojection_jacobian, (K, T_CAM, OBJ)),
    ("reprojection.refine", reprojection.refine, (K, T_CAM, OBJ, IMG, "minpack")),
    ("pose.solve_pose", pose.solve_pose, (OBJ, IMG, K, 0.2, "minpack", T_CAM)),
    ("pose.estimate_pose", pose.estimate_pose, (OBJ, IMG, K)),
    ("pose.detect_corners", pose.detect_corners, (np.zeros((60, 80), np.uint8), BOARD)),
    ("pose.pose_from_view", pose.pose_from_view, (VIEW, K, 0.2, "minpack", T_CAM)),
    ("PoseEstimate.expressed_in", ESTIMATE.expressed_in, (MOUNT,)),
    ("calibration.calibrate", calibration.calibrate, (MOVES + 0.3, MOVES, "svd", 0.005)),
    ("calibration.calibrate_table", calibration.calibrate_table, (MOVES + 0.3, MOVES, "svd", 0.005)),
    ("calibration.residual_rms", calibration.residual_rms, (np.eye(3), MOVES, MOVES)),
    ("calibration.rotation_angle", calibration.rotation_angle, (np.eye(3), np.eye(3))),
    ("calibration.calibration_moves", calibration.calibration_moves, (6, 0.2, (2, 1))),
    ("calibration.error_curve", calibration.error_curve, ([0.0002], [3], 2, 0.4, (2, 1, 0), "svd", 0)),
    ("model.carm_kinematics", model.carm_kinematics, (SYSTEM, Q)),
    ("model.base_pose", model.base_pose, (SYSTEM, 0.0, np.zeros(0))),
    ("model.setup_from_pose", model.setup_from_pose, (SYSTEM, SYSTEM.fk(Q), Q)),
    ("model.model_from_pose", model.model_from_pose, (SYSTEM, SYSTEM.fk(Q), Q)),
    ("model.frozen_table_system", model.frozen_table_system, (SYSTEM, np.zeros(0))),
    ("model.setup_jacobian", model.setup_jacobian, (SYSTEM, SYSTEM.fk(Q), Q)),
    ("model.setup_covariance", model.setup_covariance, (SYSTEM, SYSTEM.fk(Q), Q, np.eye(6) * 1e-8)),
    ("model.to_table_frame", model.to_table_frame, (np.eye(6), np.eye(3))),
    ("guidance.GuidanceOptions", guidance.GuidanceOptions, (0.002, 0.01, 0.01, 0.005)),
    ("guidance.read_joints", guidance.read_joints, (SYSTEM, SYSTEM.fk(Q), Q)),
    ("guidance.reading_covariance", guidance.reading_covariance, (SYSTEM, Q, np.eye(6) * 1e-8)),
    ("guidance.stop_rule_bound", guidance.stop_rule_bound, (SYSTEM, Q)),
    ("guidance.Guide", guidance.Guide, (SYSTEM, SYSTEM.fk(Q), Q)),
    ("Guide.step", GUIDE.step, (SYSTEM.fk(Q),)),
    ("world.random_rotation", world.random_rotation, (rng(0), 0.1)),
    ("world.system_mount", world.system_mount, (SYSTEM, BOARD)),
    ("world.OperatorModel", world.OperatorModel, (0.1, 0.001, 0.003)),
    ("OperatorModel.execute", world.OperatorModel().execute, (SYSTEM, Q, 1, 0.01, rng(0))),
    ("world.World.create", world.World.create, (SYSTEM, rng(0), 0.03, 0.2, BOARD)),
    ("World.view", WORLD.view, (SYSTEM.fk(Q),)),
    ("World.measure_marker", WORLD.measure_marker, (SYSTEM.fk(Q), rng(0))),
    ("World.measure_estimate", WORLD.measure_estimate, (Q, rng(0))),
    ("World.measure", WORLD.measure, (Q, rng(0))),
    ("World.calibrated", WORLD.calibrated, (np.zeros(6), rng(0), 6, 0.2, "svd")),
]
CASES = [(name, f, args, i) for name, f, args in CALLS for i in range(len(args))]


@pytest.mark.parametrize("name, f, args", CALLS, ids=[c[0] for c in CALLS])
def test_the_valid_call_works(name, f, args):
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        f(*args)


@pytest.mark.parametrize("name, f, args, i", CASES, ids=[f"{c[0]}-arg{c[3]}" for c in CASES])
def test_junk_gives_a_typed_error_and_no_warning(name, f, args, i):
    import inspect

    try:
        parameter = list(inspect.signature(f).parameters)[i]
    except (TypeError, ValueError):  # pragma: no cover - every callable here has a signature
        parameter = None
    for junk in JUNK:
        call = list(args)
        call[i] = junk
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            try:
                f(*call)
            except carmkin.CarmkinError as exc:
                if parameter is not None and junk is not True:  # a bool may be refused by the type's name
                    assert parameter in str(exc) or parameter.replace("_", " ") in str(exc), (junk, str(exc))
                continue
            except Exception as exc:  # noqa: BLE001 - the point of the test
                pytest.fail(f"{name}({parameter}={junk!r}) raised {type(exc).__name__}: {exc}")
        # accepted: only where the junk is a legitimate value of that argument
        assert (junk is None and parameter in ("sigma_px", "T_previous", "q_table", "board", "rng")) or \
            (isinstance(junk, str) and parameter in ("dictionary",)), f"{name}({parameter}={junk!r}) was accepted"
