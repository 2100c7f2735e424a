"""Show the C-arm and table in the browser (meshcat): the model from the URDF, the X-ray cone from the source
to the detector, the table and source frames, the C-arm parts near the table/floor coloured by distance
(red = collision), and optionally a target configuration as a ghost with the move to it animated.

Configurations are comma-separated values, one per joint of the preset in its joint order, mm for prismatic
and degrees for revolute joints: on siremobile-iso-c3d table_translation (mm), vertical (mm), wigwag (deg),
horizontal (mm), angular (deg), orbital (deg); on siremobile-iso-c3d-motorized-table the five table joints
(table_tilt, table_trendelenburg, table_lateral, table_height, table_rotation) follow table_translation.
The default is the middle of every range. A value outside its range is refused (exit 2), never clipped.

With --html/--png the scene is written to a self-contained page (and a PNG rendered by headless Chromium)
and the command exits. Without them, a meshcat server listening on 127.0.0.1 only serves the scene: the
command prints the URL and serves until Ctrl-C (or --serve-seconds). Nothing waits for a browser.

The scene is drawn in the table frame, turned so that the C-arm cart stands upright (Z up); see
docs/viewer.md.
"""

from __future__ import annotations

import argparse
import signal
import sys
import threading
from pathlib import Path

from ._common import (
    JOINTS_FLAG,
    JOINTS_METAVAR,
    MM_PER_M,
    add_alias,
    add_joints_argument,
    add_preset_argument,
    integer,
    number,
    output_path,
    parse_joints,
    read_pose,
    system_from_args,
)
from ._scene import add_patient_arguments, describe_patient, patient_from_args, table_top_y

HELP = "show the C-arm + table in the browser (meshcat on 127.0.0.1, or --html FILE)"


def register(parser: argparse.ArgumentParser) -> None:
    add_preset_argument(parser)
    add_joints_argument(parser, "configuration to show", "middle of the ranges", old_names=("--q",))
    parser.add_argument("--to-q-mm-deg", dest="to_q_mm_deg", metavar=JOINTS_METAVAR,
                        help="configuration to move to (mm/deg, as --q-mm-deg): drawn as a ghost, move animated")
    add_alias(parser, "--target", "--to-q-mm-deg", "to_q_mm_deg", metavar=JOINTS_METAVAR)
    add_alias(parser, "--target-pose", "--to-pose", "to_pose", metavar="FILE")
    parser.add_argument("--to-pose", metavar="FILE",
                        help="pose of xray_source in the table frame, translation in mm (4x4 text matrix, or JSON "
                        "as for carmkin ik --pose-file; a nearly rigid one is projected, with a note): ghost cone")
    parser.add_argument("--no-animate", action="store_true", help="with --to-q-mm-deg: only the ghost, no animation")
    parser.add_argument("--frames", type=integer(2), default=40, help="frames of the animated move (default 40)")
    parser.add_argument("--fps", type=number(0.0, open_minimum=True), default=20.0, help="frames per second of the move (default 20)")
    parser.add_argument("--margin-mm", type=number(0.0, open_minimum=True, unit="mm"), default=100.0,
                        help="colour C-arm parts closer than this to the table/floor (default 100 mm)")
    parser.add_argument("--html", metavar="FILE", help="write a self-contained static page and exit")
    parser.add_argument("--png", metavar="FILE", help="also render the page to PNG with headless Chromium")
    add_patient_arguments(parser, default="none")
    parser.add_argument("--port", type=integer(1, 65535), default=None,
                        help="HTTP port of the live viewer (default: 7000 or the next free one)")
    parser.add_argument("--serve-seconds", type=number(0.0, unit="s"), default=None,
                        help="stop serving after this many seconds (default: until Ctrl-C)")


def _draw(viewer, args, q_target, T_target, patient=None) -> None:
    """Distances at the current configuration, the patient, target pose, ghost and move, as the flags ask."""
    if patient is not None:
        from carmkin.viz.views import draw_patient

        draw_patient(viewer, patient)
    from carmkin.world.obstacles import link_of

    distances = viewer.show_distances(margin=args.margin_mm / MM_PER_M, patient=patient)
    groups = [link_of(d.obstacle) if link_of(d.obstacle) in ("table", "floor") else "patient" for d in distances]
    for group in sorted(set(groups)):
        mine = [d for d, g in zip(distances, groups) if g == group]
        closest = min(mine, key=lambda d: d.distance)
        hit = sorted({link_of(d.obstacle) for d in mine if d.in_collision})
        which = f" ({link_of(closest.obstacle)})" if group == "patient" else ""
        state = f"COLLISION with {', '.join(hit)}: drawn red" if hit else "clear"
        print(f"closest to {group}{which}: {link_of(closest.part)} at {closest.distance * MM_PER_M:.1f} mm ({state})")
    if T_target is not None:
        viewer.show_target_pose(T_target)
    if q_target is not None:
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
    import tempfile

    with tempfile.TemporaryDirectory(prefix="carmkin-view-") as folder:  # --png alone
        page = Path(folder) / "view.html"
        viewer.save_html(page)
        print(f"wrote {screenshot(page, args.png)}")


def _serve(system, args, q, q_target, T_target) -> None:
    from carmkin.viz import CArmViewer, LoopbackServer

    stop = threading.Event()
    previous = signal.signal(signal.SIGTERM, lambda *_: stop.set())
    try:
        with LoopbackServer(port=args.port) as server:
            viewer = CArmViewer(system, server.visualizer(), q)
            _draw(viewer, args, q_target, T_target, patient_from_args(system, args))
            print(f"meshcat viewer: {server.web_url}  (listening on 127.0.0.1 only; Ctrl-C to stop)", flush=True)
            try:
                stop.wait(args.serve_seconds)
            except KeyboardInterrupt:
                pass
        print("viewer stopped")
    finally:
        signal.signal(signal.SIGTERM, previous)


def run(args: argparse.Namespace) -> int:
    system = system_from_args(args)
    q = parse_joints(args.q_mm_deg, system, JOINTS_FLAG) if args.q_mm_deg else None  # every input checked before any work
    q_target = parse_joints(args.to_q_mm_deg, system, "--to-q-mm-deg") if args.to_q_mm_deg else None
    T_target = read_pose(args.to_pose, "--to-pose") if args.to_pose else None
    if args.html:
        args.html = output_path(args.html, "--html", ("html", "htm"))
    if args.png:
        args.png = output_path(args.png, "--png", ("png",))
        from carmkin.viz.screenshot import find_chromium

        find_chromium()  # a PNG needs a Chromium: said before the scene is built
    patient = patient_from_args(system, args)
    if patient is not None:
        print(f"table top: upper surface at Y0 = {table_top_y(system) * MM_PER_M:+.1f} mm (Y0 points down); patient: "
              f"{describe_patient(patient, args.patient_position)}")
    if args.html or args.png:
        from carmkin.viz import CArmViewer  # meshcat and the viewer (a second) only once every input is checked

        viewer = CArmViewer(system, q=q)
        _draw(viewer, args, q_target, T_target, patient)
        _write_static(viewer, args)
    else:
        _serve(system, args, q, q_target, T_target)
    sys.stdout.flush()
    return 0
