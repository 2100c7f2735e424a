"""Show the C-arm and table in the browser (meshcat): the model from the URDF, the X-ray cone from the source
to the detector, the table and source frames, the C-arm parts near the table/floor coloured by distance
(red = collision), and optionally a target configuration as a ghost with the move to it animated.

Configurations are 6 comma-separated values in the joint order table_translation (mm), vertical (mm),
wigwag (deg), horizontal (mm), angular (deg), orbital (deg); the default is the middle of every range.

With --html/--png the scene is written to a self-contained page (and a PNG rendered by headless Chromium)
and the command exits. Without them, a meshcat server listening on 127.0.0.1 only serves the scene: the
command prints the URL and serves until Ctrl-C (or --serve-seconds). Nothing waits for a browser.

The scene is drawn in the table frame, turned so that the C-arm cart stands upright (Z up); see
docs/viewer.md.
"""

from __future__ import annotations

import argparse
import math
import signal
import sys
import tempfile
import threading
from pathlib import Path

import numpy as np

from carmkin.errors import InvalidConfigurationError, InvalidPoseError
from carmkin.model.params import JOINT_NAMES, PRISMATIC

from ._common import add_preset_argument, system_from_args

HELP = "show the C-arm + table in the browser (meshcat on 127.0.0.1, or --html FILE)"
UNITS = ",".join("mm" if p else "deg" for p in PRISMATIC)


def parse_configuration(text: str, flag: str) -> np.ndarray:
    """``"d0,d1,θ2,d3,θ4,θ5"`` in mm/deg -> q (6,) in m/rad; :class:`InvalidConfigurationError` naming the flag."""
    parts = [p.strip() for p in text.split(",")]
    if len(parts) != 6:
        raise InvalidConfigurationError(f"{flag} needs 6 comma-separated values ({', '.join(JOINT_NAMES)}), "
                                        f"got {len(parts)}: {text!r}")
    q = np.empty(6)
    for i, (part, prismatic) in enumerate(zip(parts, PRISMATIC)):
        try:
            value = float(part)
        except ValueError:
            raise InvalidConfigurationError(f"{flag}: {JOINT_NAMES[i]} is not a number: {part!r}") from None
        if not math.isfinite(value):
            raise InvalidConfigurationError(f"{flag}: {JOINT_NAMES[i]} must be finite, got {part!r}")
        q[i] = value / 1000.0 if prismatic else math.radians(value)
    return q


def load_pose(path: str) -> np.ndarray:
    """A 4x4 pose from a text file (``numpy.loadtxt``), translation in mm -> m."""
    try:
        T = np.loadtxt(path, dtype=float, ndmin=2)
    except (OSError, ValueError) as exc:
        raise InvalidPoseError(f"--target-pose {path}: cannot read a 4x4 matrix ({exc})") from exc
    if T.shape != (4, 4):
        raise InvalidPoseError(f"--target-pose {path}: expected a 4x4 matrix, got shape {T.shape}")
    T[:3, 3] /= 1000.0
    return T


def register(parser: argparse.ArgumentParser) -> None:
    add_preset_argument(parser)
    parser.add_argument("--q", metavar=UNITS, help="configuration to show (default: middle of the ranges)")
    parser.add_argument("--target", metavar=UNITS, help="target configuration: drawn as a ghost, move animated")
    parser.add_argument("--target-pose", metavar="FILE",
                        help="4x4 pose of xray_source in the table frame (text, translation in mm): ghost cone")
    parser.add_argument("--no-animate", action="store_true", help="with --target: only the ghost, no animation")
    parser.add_argument("--frames", type=int, default=40, help="frames of the animated move (default 40)")
    parser.add_argument("--fps", type=float, default=20.0, help="frames per second of the move (default 20)")
    parser.add_argument("--margin-mm", type=float, default=100.0,
                        help="colour C-arm parts closer than this to the table/floor (default 100 mm)")
    parser.add_argument("--html", metavar="FILE", help="write a self-contained static page and exit")
    parser.add_argument("--png", metavar="FILE", help="also render the page to PNG with headless Chromium")
    parser.add_argument("--port", type=int, default=None,
                        help="HTTP port of the live viewer (default: 7000 or the next free one)")
    parser.add_argument("--serve-seconds", type=float, default=None,
                        help="stop serving after this many seconds (default: until Ctrl-C)")


def _draw(viewer, args) -> None:
    """Distances at the current configuration, target pose, ghost and move, as the flags ask."""
    distances = viewer.show_distances(margin=args.margin_mm / 1000.0)
    for obstacle in sorted({d.obstacle for d in distances}):
        closest = min((d for d in distances if d.obstacle == obstacle), key=lambda d: d.distance)
        state = "COLLISION" if closest.in_collision else "clear"
        print(f"closest to {obstacle}: {closest.part} at {closest.distance * 1000:.1f} mm ({state})")
    if args.target_pose:
        viewer.show_target_pose(load_pose(args.target_pose))
    if args.target:
        q_target = parse_configuration(args.target, "--target")
        viewer.show_ghost(q_target)
        if not args.no_animate:
            viewer.animate(q_target, frames=args.frames, fps=args.fps)
            print(f"animated move: {args.frames} frames at {args.fps:g} fps (Animations panel: play/reset)")


def _write_static(viewer, args) -> None:
    from carmkin.viz import screenshot

    if args.html:
        viewer.save_html(args.html)
        print(f"wrote {args.html}")
        if args.png:
            print(f"wrote {screenshot(args.html, args.png)}")
        return
    with tempfile.TemporaryDirectory(prefix="carmkin-view-") as folder:  # --png alone
        page = Path(folder) / "view.html"
        viewer.save_html(page)
        print(f"wrote {screenshot(page, args.png)}")


def _serve(system, args, q) -> None:
    from carmkin.viz import CArmViewer, LoopbackServer

    stop = threading.Event()
    previous = signal.signal(signal.SIGTERM, lambda *_: stop.set())
    try:
        with LoopbackServer(port=args.port) as server:
            viewer = CArmViewer(system, server.visualizer(), q)
            _draw(viewer, args)
            print(f"meshcat viewer: {server.web_url}  (listening on 127.0.0.1 only; Ctrl-C to stop)", flush=True)
            try:
                stop.wait(args.serve_seconds)
            except KeyboardInterrupt:
                pass
        print("viewer stopped")
    finally:
        signal.signal(signal.SIGTERM, previous)


def run(args: argparse.Namespace) -> int:
    from carmkin.viz import CArmViewer

    system = system_from_args(args)
    q = parse_configuration(args.q, "--q") if args.q else None
    if args.html or args.png:
        viewer = CArmViewer(system, q=q)
        _draw(viewer, args)
        _write_static(viewer, args)
    else:
        _serve(system, args, q)
    sys.stdout.flush()
    return 0
