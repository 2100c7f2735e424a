"""Viewer (carmkin.viz, `carmkin view`): scene contents, offline page, headless-browser rendering,
loopback-only server."""

from __future__ import annotations

import base64
import ipaddress
import os
import queue
import re
import signal
import socket
import subprocess
import sys
import threading
import time
import urllib.request

import carmkin
import numpy as np
import pinocchio as pin
import pytest
import umsgpack
from carmkin.viz import (
    BrowserNotFoundError,
    CArmViewer,
    DistanceChecker,
    LoopbackServer,
    ServerError,
    VisualizationError,
    find_chromium,
    interpolate,
    offline_visualizer,
    screenshot,
)
from carmkin.viz.distances import distance_color
from carmkin.viz.shapes import cone_vertices
from hypothesis import given, settings
from hypothesis import strategies as st
from strategies import PRESET, configurations, systems

from carmkin.cli import main
from carmkin.commands._common import parse_joints
from carmkin.robot.collision import CARM_EXCLUDED_PAIRS, link_of
from carmkin.world import World
from carmkin.errors import InvalidConfigurationError, InvalidPoseError
from hang import HANG_GUARD_S

# RGB of the xacro materials (urdf/carm_table.urdf.xacro), typed here from the file, not from carmkin.viz.
XACRO_COLORS = {
    "table_grey": (0.55, 0.6, 0.68),
    "carm_white": (0.86, 0.88, 0.92),
    "carm_blue": (0.25, 0.45, 0.8),
    "source_orange": (0.95, 0.55, 0.15),
    "detector_dark": (0.2, 0.22, 0.26),
}
CONE_YELLOW = (1.0, 0.85, 0.2)
Q_MID = (PRESET.lower + PRESET.upper) / 2
Q_TABLE_HIT = np.array([0.0, 0.4, 0.0, 0.1, 0.0, 0.0])  # column up: the lower C passes through the table


# --- helpers ------------------------------------------------------------------------------------------
def page_commands(html: str) -> list[dict]:
    """The meshcat commands embedded in a static page, decoded, in page order."""
    blobs = re.findall(r'data:application/octet-binary;base64,([A-Za-z0-9+/=]+)"', html)
    return [umsgpack.unpackb(base64.b64decode(b)) for b in blobs]


def node_transform(viewer: CArmViewer, path: str) -> np.ndarray:
    """World transform recorded for a meshcat node path below /meshcat (column-major in meshcat)."""
    node = viewer.vis.window.tree
    for part in ["meshcat", *path.split("/")]:
        node = node[part]
    return np.array(umsgpack.unpackb(node.transform)["matrix"]).reshape(4, 4).T


def node_object(viewer: CArmViewer, path: str) -> dict | None:
    node = viewer.vis.window.tree
    for part in ["meshcat", *path.split("/")]:
        if part not in node:
            return None
        node = node[part]
    return None if node.object is None else umsgpack.unpackb(node.object)


def chroma_pixels(png, rgb, tolerance: float = 0.005) -> int:
    """Pixels whose chromaticity r:g:b matches ``rgb`` (shading scales brightness, not chromaticity)."""
    from PIL import Image

    image = np.asarray(Image.open(png).convert("RGB"), dtype=float) / 255.0
    chroma = image / np.maximum(image.sum(axis=-1, keepdims=True), 1e-9)
    target = np.asarray(rgb) / np.sum(rgb)
    return int((np.abs(chroma - target).max(axis=-1) < tolerance).sum())


def require_chromium() -> str:
    try:
        return find_chromium()
    except BrowserNotFoundError as exc:
        pytest.skip(f"headless browser test skipped: {exc}")


def listening_sockets(pid: int) -> list[tuple[str, int]]:
    """(address, port) of the TCP sockets in LISTEN state owned by process ``pid`` (/proc/net/tcp{,6})."""
    inodes = set()
    for fd in os.listdir(f"/proc/{pid}/fd"):
        try:
            target = os.readlink(f"/proc/{pid}/fd/{fd}")
        except OSError:
            continue
        if target.startswith("socket:["):
            inodes.add(target[8:-1])
    out = []
    for table in ("/proc/net/tcp", "/proc/net/tcp6"):
        if not os.path.exists(table):
            continue
        with open(table) as stream:
            lines = stream.readlines()[1:]
        out += [parse_proc_net_line(line) for line in lines
                if line.split()[3] == "0A" and line.split()[9] in inodes]
    return out


def parse_proc_net_line(line: str) -> tuple[str, int]:
    """Local (address, port) of one /proc/net/tcp or tcp6 line (addresses are little-endian words)."""
    address, port = line.split()[1].split(":")
    raw = b"".join(bytes.fromhex(address[i:i + 8])[::-1] for i in range(0, len(address), 8))
    family = socket.AF_INET if len(raw) == 4 else socket.AF_INET6
    return socket.inet_ntop(family, raw), int(port, 16)


def is_loopback(address: str) -> bool:
    ip = ipaddress.ip_address(address)
    if isinstance(ip, ipaddress.IPv6Address) and ip.ipv4_mapped is not None:
        ip = ip.ipv4_mapped
    return ip.is_loopback


# --- parsing and inputs -------------------------------------------------------------------------------
def test_parse_configuration_converts_mm_and_degrees():
    q = parse_joints("100, 250, -5, 150, 90, -45", PRESET, "--q")
    np.testing.assert_allclose(q, [0.1, 0.25, -np.pi / 36, 0.15, np.pi / 2, -np.pi / 4], rtol=0, atol=1e-15)


@pytest.mark.parametrize("text", ["1,2,3", "1,2,3,4,5,6,7", "0,0,x,0,0,0", "0,0,nan,0,0,0"])
def test_parse_configuration_rejects_bad_text(text):
    with pytest.raises(InvalidConfigurationError, match="--q"):
        parse_joints(text, PRESET, "--q")


def test_viewer_rejects_configuration_outside_the_limits():
    q = Q_MID.copy()
    q[1] = PRESET.carm.vertical.upper + 0.01
    with pytest.raises(InvalidConfigurationError, match="vertical"):
        CArmViewer(PRESET, q=q)


def test_cli_reports_bad_input_with_exit_2(tmp_path, capsys):
    assert main(["view", "--q", "0,500,0,0,0,0", "--html", str(tmp_path / "x.html")]) == 2
    assert "vertical" in capsys.readouterr().err
    pose = tmp_path / "pose.txt"
    pose.write_text("1 0 0 0\n0 1 0 0\n0 0 1 0\n")
    assert main(["view", "--to-pose", str(pose), "--html", str(tmp_path / "x.html")]) == 2
    assert not (tmp_path / "x.html").exists()


def test_cli_target_pose_file_is_read_in_mm(tmp_path):
    T = PRESET.fk(Q_MID)
    pose = tmp_path / "pose.txt"
    np.savetxt(pose, np.vstack([np.hstack([T[:3, :3], 1000 * T[:3, 3:]]), [0, 0, 0, 1]]))
    out = tmp_path / "x.html"
    assert main(["view", "--to-pose", str(pose), "--html", str(out)]) == 0
    placed = [c for c in page_commands(out.read_text())
              if c["type"] == "set_transform" and c["path"] == "/meshcat/carmkin/targets/target"]
    np.testing.assert_allclose(np.array(placed[-1]["matrix"]).reshape(4, 4).T, T, atol=1e-9)


def test_bad_margin_and_fps_are_refused():
    viewer = CArmViewer(PRESET)
    with pytest.raises(VisualizationError, match="margin"):
        viewer.show_distances(margin=0.0)
    with pytest.raises(VisualizationError, match="fps"):
        viewer.animate(Q_MID, fps=0.0)


def test_show_target_pose_rejects_non_rigid_matrix():
    with pytest.raises(InvalidPoseError):
        CArmViewer(PRESET).show_target_pose(np.diag([1.0, 1.0, 2.0, 1.0]))


# --- scene contents -----------------------------------------------------------------------------------
@settings(max_examples=20)
@given(system=systems(), data=configurations())
def test_cone_base_is_the_detector_rectangle_around_pinocchios_detector_frame(system, data):
    """The cone's base centre is Pinocchio's `detector` frame; its corners span width x height in its plane."""
    q = data
    corners = cone_vertices(system.carm)
    T = system.fk(q)  # closed form
    world = corners @ T[:3, :3].T + T[:3, 3]
    model, _, _ = system.pinocchio()
    pdata = model.createData()
    pin.framesForwardKinematics(model, pdata, q)
    detector = pdata.oMf[model.getFrameId("detector")]
    np.testing.assert_allclose(world[0], T[:3, 3], atol=1e-12)
    np.testing.assert_allclose(world[1:].mean(axis=0), detector.translation, atol=1e-9)
    local = (world[1:] - detector.translation) @ detector.rotation  # corners in the detector frame
    np.testing.assert_allclose(local[:, 2], 0.0, atol=1e-9)
    np.testing.assert_allclose(np.ptp(local[:, 0]), system.carm.detector_width, atol=1e-9)
    np.testing.assert_allclose(np.ptp(local[:, 1]), system.carm.detector_height, atol=1e-9)


@settings(max_examples=10)
@given(q=configurations())
def test_display_puts_cone_and_source_triad_at_the_closed_form_source_pose(q):
    viewer = CArmViewer(PRESET, q=Q_MID)
    viewer.display(q)
    np.testing.assert_allclose(node_transform(viewer, "carmkin/cone"), PRESET.fk(q), atol=1e-9)
    np.testing.assert_allclose(node_transform(viewer, "carmkin/frames/xray_source"), PRESET.fk(q), atol=1e-9)


MOTORIZED = carmkin.load_preset("siremobile-iso-c3d-motorized-table")


@settings(max_examples=10)
@given(data=st.data())
def test_viewer_is_general_in_the_number_of_joints(data):
    """On the 11-joint motorized preset: cone at the closed-form source pose, ghost, move of (frames, 11)."""
    q, q_to = (np.array([data.draw(st.floats(r.lower, r.upper)) for r in MOTORIZED.joint_ranges]) for _ in range(2))
    viewer = CArmViewer(MOTORIZED, q=q)
    np.testing.assert_allclose(node_transform(viewer, "carmkin/cone"), MOTORIZED.fk(q), atol=1e-9)
    viewer.show_ghost(q_to)
    np.testing.assert_allclose(node_transform(viewer, "carmkin/ghost/cone"), MOTORIZED.fk(q_to), atol=1e-9)
    assert viewer.animate(q_to, frames=3).shape == (3, 11)
    np.testing.assert_allclose(node_transform(viewer, "carmkin/cone"), MOTORIZED.fk(q_to), atol=1e-9)
    pairs = viewer.show_distances(q)
    assert [(d.part, d.obstacle) for d in pairs] == list(World(MOTORIZED).pairs)


def test_scene_frame_is_upright_table_frame():
    """Root node: a pure rotation taking the vertical axis (cart Z) to meshcat's Z (up)."""
    viewer = CArmViewer(PRESET)
    R = node_transform(viewer, "carmkin")
    np.testing.assert_allclose(R[:3, 3], 0.0)
    model, _, _ = PRESET.pinocchio()
    data = model.createData()
    pin.framesForwardKinematics(model, data, np.zeros(6))
    cart_z = data.oMf[model.getFrameId("carm_cart")].rotation[:, 2]
    np.testing.assert_allclose(R[:3, :3] @ cart_z, [0, 0, 1], atol=1e-12)
    # at the middle configuration the detector is above the table origin, the source below it
    assert (R @ PRESET.fk(Q_MID) @ PRESET.detector_in_xray)[2, 3] > 0 > (R @ PRESET.fk(Q_MID))[2, 3]


def test_ghost_target_pose_and_shots_are_placed_where_asked():
    viewer = CArmViewer(PRESET)
    q_target = np.array([0.1, 0.3, 0.05, 0.15, 0.5, -0.7])
    viewer.show_ghost(q_target)
    np.testing.assert_allclose(node_transform(viewer, "carmkin/ghost/cone"), PRESET.fk(q_target), atol=1e-9)
    assert node_object(viewer, "carmkin/ghost/robot/visuals/table_0") is None  # environment not ghosted
    assert node_object(viewer, "carmkin/ghost/robot/visuals/detector_0") is not None
    pose = PRESET.fk(Q_MID) @ np.array([[1, 0, 0, 0.05], [0, 0, -1, 0], [0, 1, 0, 0], [0, 0, 0, 1.0]])
    viewer.show_target_pose(pose, "view")
    np.testing.assert_allclose(node_transform(viewer, "carmkin/targets/view"), pose, atol=1e-12)
    shots = PRESET.fk(np.array([Q_MID + [0, 0, 0, 0, 0, a] for a in (-0.4, 0.0, 0.4)]))
    viewer.draw_shots(shots)
    for i, shot in enumerate(shots):
        np.testing.assert_allclose(node_transform(viewer, f"carmkin/shots/planned/{i}"), shot, atol=1e-12)
        assert node_object(viewer, f"carmkin/shots/planned/{i}/surface") is not None


def test_interpolate_is_linear_in_joint_space():
    a, b = np.zeros(6), np.arange(1.0, 7.0)
    path = interpolate(a, b, 5)
    assert path.shape == (5, 6)
    np.testing.assert_array_equal(path[0], a)
    np.testing.assert_array_equal(path[-1], b)
    np.testing.assert_allclose(np.diff(path, axis=0), np.tile((b - a) / 4, (4, 1)))
    with pytest.raises(InvalidConfigurationError):
        interpolate(a, b, 1)


def test_animation_tracks_run_from_start_to_target_and_come_after_the_objects():
    viewer = CArmViewer(PRESET, q=Q_MID)
    q_to = np.array([0.2, 0.1, -0.1, 0.05, 1.2, 0.6])
    viewer.animate(q_to, frames=12, fps=10)
    commands = page_commands(viewer.static_html())
    kinds = [c["type"] for c in commands]
    assert kinds[-1] == "set_animation" and kinds.count("set_animation") == 1
    animation = commands[-1]
    assert animation["options"]["play"] is True
    clip = next(a["clip"] for a in animation["animations"] if a["path"] == "/meshcat/carmkin/cone")
    track = next(t for t in clip["tracks"] if t["name"] == ".position")
    assert len(track["keys"]) == 12 and clip["fps"] == 10
    np.testing.assert_allclose(track["keys"][0]["value"], PRESET.fk(Q_MID)[:3, 3], atol=1e-9)
    np.testing.assert_allclose(track["keys"][-1]["value"], PRESET.fk(q_to)[:3, 3], atol=1e-9)
    np.testing.assert_allclose(node_transform(viewer, "carmkin/cone"), PRESET.fk(q_to), atol=1e-9)
    animated = {a["path"] for a in animation["animations"]}
    assert "/meshcat/carmkin/robot/visuals/dh_frame_6_3" in animated


# --- distances ----------------------------------------------------------------------------------------
def test_distance_pairs_are_the_collision_policy():
    """One policy: the viewer colours exactly the pairs the planner and the validity report check."""
    checker = DistanceChecker(PRESET)
    pairs = [(d.part, d.obstacle) for d in checker.distances(Q_MID)]
    assert pairs == list(World(PRESET).pairs)
    # and that policy, written out: moving C-arm parts against the table top and the floor
    moving = {"dh_frame_2", "dh_frame_3", "dh_frame_4", "dh_frame_5", "dh_frame_6", "xray_source", "detector"}
    parts = {g.name for g in checker.collision_model.geometryObjects if link_of(g.name) in moving}
    expected = {(p, o) for p in parts for o in ("table_0", "floor_0")}
    expected -= {(p, o) for p, o in expected if (link_of(p), link_of(o)) in set(CARM_EXCLUDED_PAIRS)}
    assert set(pairs) == expected and ("dh_frame_2_0", "floor_0") not in expected


@settings(max_examples=25)
@given(q=configurations())
def test_floor_distance_is_the_lowest_box_corner_above_the_floor(q):
    """Independent of coal: box corners from the placements, floor top at floor_height in the cart frame."""
    checker = DistanceChecker(PRESET)
    model, gmodel = checker.model, checker.collision_model
    data, gdata = model.createData(), pin.GeometryData(gmodel)
    pin.framesForwardKinematics(model, data, q)
    pin.updateGeometryPlacements(model, data, gmodel, gdata)
    cart = data.oMf[model.getFrameId("carm_cart")]
    floor_top = PRESET.body.floor_height - 0.001  # floor box: 20 mm thick, centre 11 mm below floor_height
    signs = np.array(np.meshgrid([-1, 1], [-1, 1], [-1, 1])).reshape(3, -1).T
    for d in checker.distances(q):
        if d.obstacle != "floor_0":
            continue
        gid = gmodel.getGeometryId(d.part)
        corners = (signs * gmodel.geometryObjects[gid].geometry.halfSide) @ gdata.oMg[gid].rotation.T
        heights = (corners + gdata.oMg[gid].translation - cart.translation) @ cart.rotation[:, 2]
        assert d.distance == pytest.approx(heights.min() - floor_top, abs=1e-5)  # coal's GJK tolerance: 1e-6


def test_part_through_the_table_is_in_collision_and_drawn_red():
    checker = DistanceChecker(PRESET)
    model, gmodel = checker.model, checker.collision_model
    data, gdata = model.createData(), pin.GeometryData(gmodel)
    pin.updateGeometryPlacements(model, data, gmodel, gdata, Q_TABLE_HIT)
    table = gdata.oMg[gmodel.getGeometryId("table_0")]
    half = np.asarray(PRESET.table.top_size) / 2
    inside = set()  # parts with a box corner strictly inside the table top, without coal
    signs = np.array(np.meshgrid([-1, 1], [-1, 1], [-1, 1])).reshape(3, -1).T
    for gid, geometry in enumerate(gmodel.geometryObjects):
        if geometry.name in ("table_0", "floor_0"):
            continue
        world = (signs * geometry.geometry.halfSide) @ gdata.oMg[gid].rotation.T + gdata.oMg[gid].translation
        local = (world - table.translation) @ table.rotation
        if np.any(np.all(np.abs(local) < half, axis=1)):
            inside.add(geometry.name)
    assert inside, "test configuration should put a C-arm part into the table"
    viewer = CArmViewer(PRESET, q=Q_TABLE_HIT)
    distances = viewer.show_distances(margin=0.1)
    hit = {d.part for d in distances if d.obstacle == "table_0" and d.in_collision}
    assert inside <= hit
    for part in inside:
        obj = node_object(viewer, f"carmkin/distances/{part}")
        assert obj["object"]["materials"][0]["color"] == 0xFF0000


def test_distance_color_goes_from_red_to_yellow():
    assert distance_color(-0.01, 0.1) == (1.0, 0.0, 0.0)
    assert distance_color(0.0, 0.1) == (1.0, 0.0, 0.0)
    assert distance_color(0.1, 0.1) == (1.0, 0.85, 0.0)
    assert 0.0 < distance_color(0.05, 0.1)[1] < 0.85


# --- the static page ----------------------------------------------------------------------------------
def test_static_page_is_self_contained(tmp_path):
    out = tmp_path / "view.html"
    assert main(["view", "--html", str(out)]) == 0
    html = out.read_text()
    assert "new MeshCat.Viewer" in html
    assert not re.search(r"<script[^>]+src=", html), "the page must not load scripts from elsewhere"
    kinds = [c["type"] for c in page_commands(html)]
    assert kinds.count("set_object") > 20


def test_offline_window_refuses_browser_only_calls():
    vis = offline_visualizer()
    with pytest.raises(Exception, match="browser"):
        vis.get_image()
    with pytest.raises(Exception, match="browser"):
        vis.wait()


def test_headless_chromium_screenshot_shows_carm_table_and_cone(tmp_path):
    """`carmkin view --html` page rendered by Chromium: not blank, the xacro colours and the cone appear."""
    require_chromium()
    page, png = tmp_path / "view.html", tmp_path / "view.png"
    assert main(["view", "--html", str(page), "--png", str(png)]) == 0
    from PIL import Image

    image = np.asarray(Image.open(png).convert("RGB"))
    assert image.shape == (768, 1024, 3)
    assert image.std() > 10 and len(np.unique(image.reshape(-1, 3), axis=0)) > 200, "blank screenshot"
    for name, rgb in XACRO_COLORS.items():
        assert chroma_pixels(png, rgb) > 300, f"{name} not visible"
    assert chroma_pixels(png, CONE_YELLOW) > 50, "X-ray cone not visible"

    # negative control: the same scene with the robot hidden has none of the model's colours
    viewer = CArmViewer(PRESET)
    viewer.root["robot"].set_property("visible", False)
    empty, empty_png = tmp_path / "empty.html", tmp_path / "empty.png"
    viewer.save_html(empty)
    screenshot(empty, empty_png)
    for name in XACRO_COLORS:
        assert chroma_pixels(empty_png, XACRO_COLORS[name]) < 50, name


def test_static_page_plays_the_animation_in_chromium(tmp_path):
    """1 s into the 2 s move the robot is half-way, after 5 s at its end: the page plays the animation."""
    require_chromium()
    from PIL import Image

    viewer = CArmViewer(PRESET, q=np.zeros(6))
    viewer.animate(np.array([0.0, 0.0, 0.0, 0.0, np.pi / 2, 0.0]), frames=20, fps=10)
    page = tmp_path / "move.html"
    viewer.save_html(page)
    early = np.asarray(Image.open(screenshot(page, tmp_path / "early.png", (600, 450), budget_ms=1000)), float)
    late = np.asarray(Image.open(screenshot(page, tmp_path / "late.png", (600, 450), budget_ms=5000)), float)
    changed = (np.abs(early - late).max(axis=-1) > 30).mean()
    assert changed > 0.01, f"only {changed:.2%} of the pixels differ: the animation did not play"


# --- loopback-only server -----------------------------------------------------------------------------
def test_proc_net_parser_reads_addresses():
    v4 = "  0: 0100007F:1B58 00000000:0000 0A 00000000:00000000 00:00000000 00000000 0 0 12345 1"
    any4 = "  1: 00000000:1770 00000000:0000 0A 00000000:00000000 00:00000000 00000000 0 0 12346 1"
    v6 = "  0: 00000000000000000000000001000000:1B59 00000000000000000000000000000000:0000 0A 0 0 0 0 0 999 1"
    assert parse_proc_net_line(v4) == ("127.0.0.1", 7000) and is_loopback("127.0.0.1")
    assert parse_proc_net_line(any4) == ("0.0.0.0", 6000) and not is_loopback("0.0.0.0")
    assert parse_proc_net_line(v6) == ("::1", 7001) and is_loopback("::1")


def test_loopback_server_listens_on_127_0_0_1_only_and_stops_cleanly():
    server = LoopbackServer()
    before = set(listening_sockets(os.getpid()))
    try:
        server.start()
        vis = server.visualizer()
        CArmViewer(PRESET, vis)
        ours = set(listening_sockets(os.getpid())) - before
        http_port = int(server.web_url.rsplit(":", 1)[1].split("/")[0])
        zmq_port = int(server.zmq_url.rsplit(":", 1)[1])
        assert {port for _, port in ours} == {http_port, zmq_port}
        assert all(is_loopback(address) for address, _ in ours), ours
        assert server.bound_addresses() == [("127.0.0.1", http_port)]
        with urllib.request.urlopen(server.web_url, timeout=HANG_GUARD_S) as response:
            assert response.status == 200 and b"meshcat" in response.read().lower()
    finally:
        server.stop()
    assert not server.running
    # libzmq releases a closed socket in its own I/O thread: wait (bounded) until nothing of ours listens
    deadline = time.monotonic() + HANG_GUARD_S
    while set(listening_sockets(os.getpid())) - before and time.monotonic() < deadline:
        time.sleep(0.05)
    assert set(listening_sockets(os.getpid())) - before == set()


def test_loopback_server_refuses_other_hosts():
    with pytest.raises(ServerError, match="loopback"):
        LoopbackServer(host="0.0.0.0")


def test_live_page_in_headless_chromium_shows_the_model(tmp_path):
    """A real browser connects to the live server over the websocket and draws the scene."""
    require_chromium()
    with LoopbackServer() as server:
        CArmViewer(PRESET, server.visualizer())
        png = screenshot(server.web_url, tmp_path / "live.png")
    assert chroma_pixels(png, XACRO_COLORS["carm_blue"]) > 300
    assert chroma_pixels(png, XACRO_COLORS["source_orange"]) > 300


def _read_line(lines: queue.Queue, pattern: str, timeout: float) -> str:
    """The first line from ``lines`` matching ``pattern``, waiting at most ``timeout`` seconds."""
    deadline, seen = time.monotonic() + timeout, []
    while (left := deadline - time.monotonic()) > 0:
        try:
            line = lines.get(timeout=left)
        except queue.Empty:
            break
        if line is None:  # end of output
            break
        seen.append(line)
        if re.search(pattern, line):
            return line
    raise AssertionError(f"no line matching {pattern!r} within {timeout} s; output: {''.join(seen)!r}")


def _pump(stream, lines: queue.Queue) -> None:
    for line in stream:
        lines.put(line)
    lines.put(None)


def test_carmkin_view_serves_on_loopback_only_and_exits_on_sigterm():
    process = subprocess.Popen([sys.executable, "-u", "-m", "carmkin.cli", "view", "--serve-seconds", str(int(HANG_GUARD_S))],
                               stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    lines: queue.Queue = queue.Queue()
    threading.Thread(target=_pump, args=(process.stdout, lines), daemon=True).start()
    try:
        line = _read_line(lines, r"http://127\.0\.0\.1:\d+/static/", timeout=HANG_GUARD_S)
        port = int(re.search(r"127\.0\.0\.1:(\d+)", line).group(1))
        sockets = listening_sockets(process.pid)
        assert port in {p for _, p in sockets}
        assert sockets and all(is_loopback(address) for address, _ in sockets), sockets
        process.send_signal(signal.SIGTERM)
        assert process.wait(timeout=HANG_GUARD_S) == 0
        _read_line(lines, "viewer stopped", timeout=HANG_GUARD_S)
    finally:
        if process.poll() is None:
            process.kill()
            process.wait(timeout=HANG_GUARD_S)
        process.stdout.close()
        process.stderr.close()
