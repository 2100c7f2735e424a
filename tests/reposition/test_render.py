"""Synthetic images: the detector finds every visible marker where the geometry puts its corners."""

from __future__ import annotations

import math

import numpy as np
import pytest

import carmkin
from carmkin.reposition import camera, pattern, pose, render
from carmkin.reposition.world import system_mount

SYSTEM = carmkin.load_preset("siremobile-iso-c3d")
BOARD = pattern.MarkerBoard()
MOUNT = system_mount(SYSTEM, BOARD)
K = SYSTEM.carm.intrinsics()
SIZE = (SYSTEM.carm.detector_columns, SYSTEM.carm.detector_rows)
#: Sub-pixel ArUco corners on the rendered images stay within this RMS of the projected truth (px).
CORNER_RMS = 0.3


@pytest.mark.parametrize("q", [np.zeros(6), np.array([0.05, 0.1, 0.05, 0.1, math.radians(12), math.radians(-8)])])
def test_rendered_markers_are_detected_at_their_projected_corners(q):
    T = camera.camera_in_marker(MOUNT, SYSTEM.fk(q))
    truth = camera.visible_corners(BOARD, K, SIZE, T)
    image = render.render(BOARD, K, SIZE, T, rng=np.random.default_rng(0))
    assert image.shape == (SIZE[1], SIZE[0]) and image.dtype == np.uint8
    found = pose.detect_corners(image, BOARD)
    assert np.array_equal(found.ids, truth.ids)
    rms = np.sqrt(np.mean((found.image_points - truth.image_points) ** 2))
    assert rms < CORNER_RMS
    estimate = pose.pose_from_view(found, K)
    assert np.linalg.norm(estimate.T[:3, 3] - T[:3, 3]) < 0.002


def test_texture_pixels_map_to_board_metres():
    texture, S = render.board_texture(BOARD)
    found = pose.detect_corners(texture[:600, :900].copy(), BOARD)
    assert len(found) >= 4  # the markers at the board's edge lack the white quiet zone a detector needs
    expected = (found.object_points[:, :2] @ S[:2, :2].T) + S[:2, 2]
    assert np.abs(found.image_points - expected).max() < 0.5


def test_bad_render_settings_raise():
    T = camera.camera_in_marker(MOUNT, SYSTEM.fk(np.zeros(6)))
    with pytest.raises(camera.CameraError, match="blur_px"):
        render.render(BOARD, K, SIZE, T, blur_px=-1.0, noise_gray=0.0)
    with pytest.raises(camera.CameraError, match="rng"):
        render.render(BOARD, K, SIZE, T, noise_gray=1.0)
    for size in ((0, 10), (640.5, 480), (640.0, 480), ("640", 480), (640,), 640, "640x480", (True, 480)):
        with pytest.raises(camera.CameraError, match="image_size"):
            render.render(BOARD, K, size, T, noise_gray=0.0)
    assert camera.check_image_size((np.int64(640), np.int32(480))) == (640, 480)
    with pytest.raises(pose.PoseError, match="uint8"):
        pose.detect_corners(np.zeros((10, 10)), BOARD)
