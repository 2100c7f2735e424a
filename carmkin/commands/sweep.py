"""Plan a cone-beam CT sweep (``plan``) and simulate + reconstruct it with RTK (``reconstruct``).

``carmkin sweep plan`` turns the C-arm by --arc-deg about --joint around --target-mm (table frame, mm),
compensating the other joints so that the target stays on the principal axis at --distance-mm (the virtual
isocentre; --plain for the joint rotation alone), and checks the whole arc — between frames too — against
the table, the floor and a box patient (--patient-box-mm) with a --margin-mm clearance. It prints the swept
clearance, the plain rotation's isocentre drift, the joint that limits the arc and the short-scan check
(arc vs 180° + fan angle); exit 1 when the arc does not fit (the obstruction, its angle and the largest
feasible arc are printed), how long the sweep takes at the preset's joint speeds, and with
--acquisition-time-s whether the joints can follow that time (exit 1 when one cannot: which, and by how
much). Exports: --rtk-xml (RTK geometry, mm), --astra (.npy cone_vec rows, mm), --tigre
(.npz TIGRE arrays, mm), --html (the arc in the viewer), --png (clearance and drift along the arc), --json (the plan).

``carmkin sweep reconstruct`` forward-projects RTK's Shepp–Logan along the planned sweep (Joseph, CPU),
reconstructs it by FDK with Parker weights and prints the RMSE; --study adds the perturbations (joint encoder
noise, the §4.6.2 table setup error, the plain rotation of a non-isocentric C-arm). Needs the cbct extra.
"""

from __future__ import annotations

import argparse
import math

import numpy as np

from carmkin.errors import UsageError
from carmkin.model.motion import ACQUISITION_TIME_RANGE

from ._common import JOINTS_FLAG, MIN_DISTANCE_MM, MM_PER_M, add_joints_argument, add_json_argument, \
    add_margin_argument, add_png_argument, add_preset_argument, integer, joints_json, number, output_path, \
    parse_joints, parse_numbers, plot_path, system_from_args, unit_slip, write_json

#: Sizes of a box patient along each axis (mm): a newborn's limb to the longest body; outside, a unit slip
#: (0.5,0.3,1.6 given in m) refused, naming it.
PATIENT_BOX_MM = (20.0, 3000.0)

HELP = "plan a collision-free cone-beam CT sweep, export its geometry (RTK, ASTRA, TIGRE), reconstruct it"


def _plan_arguments(parser: argparse.ArgumentParser) -> None:
    add_preset_argument(parser)
    parser.add_argument("--target-mm", metavar="X,Y,Z", default="0,0,0",
                        help="point kept at the isocentre, table frame (mm, default 0,0,0)")
    parser.add_argument("--arc-deg", type=number(0.0, 360.0, open_minimum=True, unit="deg"), default=190.0,
                        help="sweep arc (deg, default 190)")
    parser.add_argument("--views", type=integer(2, 2000), default=100, help="number of frames (default 100)")
    parser.add_argument("--joint", default="orbital", metavar="NAME[:W],...",
                        help="revolute joint(s) that turn: orbital (default), angular, or weights such as "
                        "orbital:1,angular:0.3 (rad per rad)")
    add_joints_argument(parser, "the configuration whose orientation starts the arc",
                        "the arc centred on the joint's mid-range", old_names=("--q-start",))
    parser.add_argument("--distance-mm", type=number(MIN_DISTANCE_MM, 10000.0, unit="mm"), default=None,
                        help="source-to-target distance (mm, default the source-to-orbital-axis distance)")
    parser.add_argument("--plain", action="store_true", help="plan the plain joint rotation (no compensation)")
    add_margin_argument(parser, "clearance kept along the whole arc")
    parser.add_argument("--patient-box-mm", metavar="W,H,L[,X,Y,Z]",
                        help="box patient: full size (mm) along table X, Y, Z and its centre (mm, default 0,0,0)")
    parser.add_argument("--acquisition-time-s", type=number(*ACQUISITION_TIME_RANGE, unit="s"), default=None,
                        help="acquire the views over this time (s): check that the joints can follow it (their "
                        "speeds and accelerations from the preset; exit 1 if one cannot)")


def register(parser: argparse.ArgumentParser) -> None:
    sub = parser.add_subparsers(dest="action", required=True, metavar="ACTION")
    plan = sub.add_parser("plan", help="plan and check a sweep, export its geometry")
    _plan_arguments(plan)
    plan.add_argument("--rtk-xml", metavar="FILE",
                      help="write RTK's geometry XML (mm; RTK's file format, written without itk-rtk)")
    plan.add_argument("--astra", metavar="FILE.npy", help="write ASTRA cone_vec rows (n, 12), mm")
    plan.add_argument("--tigre", metavar="FILE.npz", help="write TIGRE arbitrary-geometry arrays, mm")
    plan.add_argument("--html", metavar="FILE", help="write the arc in the viewer as a static page")
    add_png_argument(plan, "clearance and drift along the arc", old_names=("--plot",))
    add_json_argument(plan, "the plan (clearance mm, joints mm/deg per frame, exit status)")
    reco = sub.add_parser("reconstruct", help="simulate and reconstruct the sweep with RTK (cbct extra)")
    _plan_arguments(reco)
    reco.add_argument("--size", type=integer(8, 512), default=64, help="voxels per side (default 64)")
    reco.add_argument("--pixels", type=integer(8, 2048), default=128,
                      help="detector pixels per side, same physical size (default 128)")
    reco.add_argument("--study", action="store_true", help="also reconstruct with the perturbed geometries")
    add_png_argument(reco, "slices and a line profile", old_names=("--plot",))
    add_json_argument(reco, "the reconstructions' RMSE")


def _joint(text: str):
    spec = {}
    for part in text.split(","):
        name, _, weight = part.strip().partition(":")
        try:
            spec[name] = float(weight) if weight else 1.0
        except ValueError:
            raise UsageError(f"--joint: weight of {name!r} is not a number: {weight!r}") from None
    return spec


def _patient(text: str | None):
    from carmkin.world import Obstacle

    if text is None:
        return []
    values = parse_numbers(text, None, "--patient-box-mm")
    if len(values) not in (3, 6) or np.any(values[:3] <= 0):
        raise UsageError(f"--patient-box-mm needs W,H,L (> 0) and optionally X,Y,Z (mm), got {text!r}")
    low, high = PATIENT_BOX_MM
    for axis, size in zip("WHL", values[:3]):
        if not low <= size <= high:
            raise UsageError(f"--patient-box-mm {text}: {axis} = {size:g} mm is not a body size (expected {low:g} to "
                             f"{high:g} mm){unit_slip(size, low, high, 'mm')}")
    centre = values[3:] if len(values) == 6 else np.zeros(3)
    return [Obstacle.box("patient", values[:3] / MM_PER_M, center=centre / MM_PER_M)]


def _plan(args, system):
    from carmkin.sweeps import plan_sweep

    q_start = parse_joints(args.q_mm_deg, system, JOINTS_FLAG) if args.q_mm_deg else None
    return plan_sweep(system, parse_numbers(args.target_mm, 3, "--target-mm", unit="mm") / MM_PER_M, args.arc_deg, args.views,
                      patient=_patient(args.patient_box_mm), q_start=q_start, joint=_joint(args.joint),
                      distance=None if args.distance_mm is None else args.distance_mm / MM_PER_M,
                      compensate=not args.plain, margin=args.margin_mm / MM_PER_M,
                      acquisition_time_s=args.acquisition_time_s)


def _followed(sweep) -> bool:
    """False when the joints cannot follow the asked acquisition time."""
    from carmkin.model.motion import Follow

    return sweep.timing is None or sweep.timing.status is not Follow.TOO_FAST


def run(args: argparse.Namespace) -> int:
    system = system_from_args(args)
    if args.action == "reconstruct":
        return _reconstruct(args, system)
    paths = {name: getattr(args, name) and output_path(getattr(args, name), f"--{name.replace('_', '-')}", suffixes)
             for name, suffixes in (("rtk_xml", ("xml",)), ("astra", ("npy",)), ("tigre", ("npz",)),
                                    ("html", ("html", "htm")))}
    plot = plot_path(args.png, "--png") if args.png else None
    sweep = _plan(args, system)
    print(sweep.summary())
    _export(sweep, paths, plot)
    write_json(args, _sweep_json(sweep))
    return 0 if sweep.success and _followed(sweep) else 1


def _sweep_json(sweep) -> dict:
    """The plan in the command line's units (mm, degrees)."""
    q = np.where(np.isfinite(sweep.q), sweep.q, np.nan)
    return {"preset": sweep.system.name, "success": bool(sweep.success), "compensated": bool(sweep.compensated),
            "views": int(sweep.n_views), "arc_deg": math.degrees(sweep.arc), "target_mm": sweep.target * MM_PER_M,
            "distance_mm": sweep.distance * MM_PER_M, "min_clearance_mm": sweep.min_clearance * MM_PER_M,
            "margin_mm": sweep.margin * MM_PER_M, "limiting_joint": sweep.limiting_joint,
            "failure": None if sweep.failure is None else str(sweep.failure),
            "q": [joints_json(sweep.system, row) for row in q], **_timing_json(sweep)}


def _timing_json(sweep) -> dict:
    """The approach and the sweep's timing (s; None where unknown)."""
    timing = sweep.timing
    return {"approach_s": sweep.approach.seconds if sweep.approach is not None else None,
            "acquisition_time_s": None if timing is None else timing.acquisition_time,
            "minimum_acquisition_s": None if timing is None else timing.minimum_time,
            "follows": None if timing is None else timing.status.value,
            "binding_joint": None if timing is None else timing.joint,
            "duration_s": None if timing is None else timing.duration}


def _export(sweep, paths, plot) -> None:
    from carmkin.sweeps import export

    if not sweep.success:  # a failed sweep's frames include poses the machine cannot take: no geometry files
        skipped = [p for name, p in paths.items() if p and name != "html"]
        if skipped:
            print(f"not written (the sweep failed; plan its feasible arc instead): {', '.join(map(str, skipped))}")
        paths = {name: (p if name == "html" else None) for name, p in paths.items()}
    if paths["astra"]:
        np.save(paths["astra"], export.astra_vectors(sweep))
        print(f"wrote {paths['astra']} (ASTRA cone_vec, mm)")
    if paths["tigre"]:
        np.savez(paths["tigre"], **export.tigre_geometry(sweep))
        print(f"wrote {paths['tigre']} (TIGRE arrays, mm; TIGRE rows = ours flipped)")
    if paths["rtk_xml"]:
        export.write_rtk_xml(sweep, paths["rtk_xml"])
        print(f"wrote {paths['rtk_xml']} (RTK geometry, mm)")
    if plot:
        from carmkin.sweeps.figures import clearance_and_drift

        clearance_and_drift(sweep, plot)
        print(f"wrote {plot}")
    if paths["html"]:
        _html(sweep, paths["html"])
        print(f"wrote {paths['html']}")


def _html(sweep, path) -> None:
    from carmkin.viz import CArmViewer  # first: it imports meshcat without its deprecation warning

    import meshcat.geometry as g  # noqa: I001

    q = np.where(np.isfinite(sweep.q), sweep.q, sweep.q_plain)
    viewer = CArmViewer(sweep.system, q=q[0])
    viewer.draw_shots(sweep.poses[:: max(1, sweep.n_views // 12)], name="sweep")
    for obstacle in sweep.obstacles:
        if obstacle.shape == "box":
            viewer.vis[f"obstacles/{obstacle.name}"].set_object(
                g.Box(list(obstacle.size)), g.MeshLambertMaterial(color=0xD9B38C, opacity=0.6, transparent=True))
            viewer.vis[f"obstacles/{obstacle.name}"].set_transform(obstacle.pose)
    viewer.animate(q[-1], q_from=q[0], frames=min(sweep.n_views, 60))
    viewer.save_html(path)


def _reconstruct(args, system) -> int:
    from carmkin.extras import check_installed

    check_installed("itk", "cbct")  # before the plan: without RTK the reconstruction is refused at once
    from carmkin.sweeps import reconstruct as rc

    plot = plot_path(args.png, "--png") if args.png else None
    sweep = _plan(args, rc.with_detector(system, args.pixels, args.pixels))
    print(sweep.summary())
    if not sweep.success:
        write_json(args, {"plan": _sweep_json(sweep), "reconstructions": []})
        return 1
    volume = rc.Volume(args.size)
    results = rc.perturbation_study(sweep, volume) if args.study else [rc.simulate_and_reconstruct(sweep, volume)]
    print(f"FDK (Parker) of {args.size}³ from {sweep.n_views} frames of {args.pixels}² px over "
          f"{math.degrees(sweep.arc):.0f}°, Shepp–Logan 0…{results[0].phantom.max():g}:")
    for r in results:
        print(f"  {r.label}: RMSE {r.rmse:.4f}")
    if plot:
        from carmkin.sweeps.figures import study

        study(results, plot)
        print(f"wrote {plot}")
    write_json(args, {"plan": _sweep_json(sweep), "size_voxels": args.size, "pixels": args.pixels,
                      "reconstructions": [{"label": r.label, "rmse": float(r.rmse)} for r in results]})
    return 0
