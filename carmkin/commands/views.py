"""Clinical views with the patient on the table: plan one view, or map which views are reachable and clear.

`carmkin views plan --primary-deg 30 --secondary-deg 20` plans the XA view (primary LAO +, RAO −;
secondary CRA +, CAU −; degrees) of --target-mm (table frame, mm) for a patient lying on the table
(--patient parametric, the default, sized by --patient-height-mm / --patient-mass-kg and placed by
--patient-position, the DICOM Patient Position code; or --patient none). `--standard NAME` names a standard
view instead (`carmkin views plan --standard list` lists them). It prints the joints (mm, deg), the clearance
to patient, table and floor (mm), from --q-mm-deg the joint-by-joint moves and how long they take (s, at the
preset's joint speeds), and when the view is unreachable the reason and the nearest reachable view.
`carmkin views map` prints how many (primary, secondary) cells are reachable (default −90…90 × −45…45 at
--step-deg 5); --png writes the map as a figure, --html a static page with the sphere of view directions
coloured by clearance, --json the cells. Exit 1 when a planned view is unreachable.
`carmkin views optimal --centreline FILE.csv [--others FILE.csv ...]` maps the foreshortening and overlap of a
vessel over the (primary, secondary) grid with the reachability of each view, and prints the optimal view, the
best reachable one, its loss and its plan; --png writes the map figure, --json the answer (`-`: stdout). CSV
files: one point a row, x,y,z in mm (an optional fourth column: the radius, mm; a header line is skipped) in the
table frame (--frame table, default) or the patient's LPS frame (--frame patient, placed by the patient's
position); --target-mm defaults to the centreline's midpoint. Exit 1 when no view of the map is reachable.
"""

from __future__ import annotations

import argparse

import numpy as np

from . import _common as common
from . import _scene

HELP = "plan clinical views (LAO/RAO, CRA/CAU) around a patient, map reachable views"
MM = 1000.0


def _common(parser: argparse.ArgumentParser, target_default: str | None = "0,0,0") -> None:
    common.add_preset_argument(parser)
    parser.add_argument("--target-mm", metavar="X,Y,Z", default=target_default,
                        help="the point the beam passes through, table frame (mm, default "
                        + (target_default or "the centreline's midpoint") + ")")
    _scene.add_patient_arguments(parser, default="parametric")
    common.add_margin_argument(parser)


def register(parser: argparse.ArgumentParser) -> None:
    sub = parser.add_subparsers(dest="action", required=True, metavar="ACTION", parser_class=type(parser))
    plan = sub.add_parser("plan", help="plan one view", description=__doc__,
                          formatter_class=argparse.RawDescriptionHelpFormatter)
    _common(plan)
    plan.add_argument("--primary-deg", type=common.number(-180.0, 180.0, unit="deg"), help="primary angle (LAO +, deg)")
    plan.add_argument("--secondary-deg", type=common.number(-90.0, 90.0, unit="deg"), help="secondary angle (CRA +, deg)")
    plan.add_argument("--standard", metavar="NAME", help="a standard view's name ('list' lists them)")
    plan.add_argument("--segment-mm", metavar="X1,Y1,Z1,X2,Y2,Z2",
                      help="a segment (vessel, screw; table frame, mm): plan its foreshortening-free view with the "
                           "most clearance, or the one nearest --primary-deg/--secondary-deg when given")
    plan.add_argument("--distance-mm", type=common.number(common.MIN_DISTANCE_MM, 10000.0, unit="mm"),
                      help="source-to-target distance (mm; default: free)")
    plan.add_argument("--rotation-deg", type=common.number(-180.0, 180.0, unit="deg"),
                      help="detector rotation about the beam (deg, as the plan prints it; default: free)")
    common.add_joints_argument(plan, "the current configuration: the plan moves least from it", "none")
    common.add_json_argument(plan, "the plan")
    common.add_png_argument(plan, "the plan: table, patient, C-arm, beam and target (two orthographic views)")
    plan.add_argument("--html", metavar="FILE", help="write the plan in the viewer: C-arm, table, patient, beam, target")
    plan.set_defaults(action_run=_plan)
    cmap = sub.add_parser("map", help="map reachable views", description=__doc__,
                          formatter_class=argparse.RawDescriptionHelpFormatter)
    _common(cmap)
    cmap.add_argument("--primary-range-deg", metavar="LO,HI", default="-90,90", help="primary angles (deg)")
    cmap.add_argument("--secondary-range-deg", metavar="LO,HI", default="-45,45", help="secondary angles (deg)")
    cmap.add_argument("--step-deg", type=common.number(0.1, 90.0, unit="deg"), default=5.0, help="grid step (deg, default 5)")
    cmap.add_argument("--workers", type=common.integer(1, 256), default=None,
                      help="processes for a map of 2048 cells or more (default: the usable cores)")
    cmap.add_argument("--compare", action="store_true",
                      help="side by side: the C-arm alone, with the table translation, and with the motorized "
                           "preset's table joints (each at its limits, one at a time)")
    common.add_png_argument(cmap, "the map", old_names=("--plot",))
    cmap.add_argument("--html", metavar="FILE", help="write a static page: the sphere of views coloured by clearance")
    common.add_json_argument(cmap, "the cells")
    cmap.set_defaults(action_run=_map)
    best = sub.add_parser("optimal", help="the best reachable view of a vessel (foreshortening, overlap)",
                          description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    _common(best, target_default=None)
    best.add_argument("--centreline", metavar="FILE.csv", required=True,
                      help="the vessel of interest: x,y,z (mm) a row, optional radius (mm)")
    best.add_argument("--others", metavar="FILE.csv", nargs="+", action="extend", default=[],
                      help="the other vessels, drawn as tubes (same format)")
    best.add_argument("--frame", choices=("table", "patient"), default="table",
                      help="frame of the CSV points: the table frame (default) or the patient's LPS frame")
    best.add_argument("--radius-mm", type=common.number(0.0, 30.0, unit="mm"), default=1.5,
                      help="tube radius of the other vessels without a radius column (mm, default 1.5)")
    best.add_argument("--weights", metavar="F,O", default="0.5,0.5",
                      help="weights of foreshortening and overlap in the score (default 0.5,0.5)")
    best.add_argument("--primary-range-deg", metavar="LO,HI", default="-90,90", help="primary angles (deg)")
    best.add_argument("--secondary-range-deg", metavar="LO,HI", default="-45,45", help="secondary angles (deg)")
    best.add_argument("--step-deg", type=common.number(0.1, 90.0, unit="deg"), default=2.0,
                      help="grid step (deg, default 2)")
    best.add_argument("--workers", type=common.integer(1, 256), default=None,
                      help="processes for the reachability of 2048 cells or more (default: the usable cores)")
    best.add_argument("--png", metavar="FILE", help="write the map figure (png, pdf, svg, ...)")
    common.add_json_argument(best, "the answer")
    best.set_defaults(action_run=_optimal)


def run(args: argparse.Namespace) -> int:
    return args.action_run(args)


def _patient(system, args):
    return _scene.patient_from_args(system, args)


def _plan(args: argparse.Namespace) -> int:
    from carmkin.views import View, plan_perpendicular, plan_view
    from carmkin.views.standard import STANDARD_VIEWS, standard_view

    if args.standard == "list":
        for v in STANDARD_VIEWS.values():
            print(f"{v.name:20s} primary {v.primary_deg:+6.1f}°, secondary {v.secondary_deg:+6.1f}°  {v.description}"
                  f"  [{v.source}]")
        return 0
    system = common.system_from_args(args)
    target = common.parse_numbers(args.target_mm, 3, "--target-mm", unit="mm") / MM
    patient = _patient(system, args)
    position = patient if patient is not None else args.patient_position
    distance = None if args.distance_mm is None else args.distance_mm / MM
    q_current = None if args.q_mm_deg is None else common.parse_joints(args.q_mm_deg, system, "--q-mm-deg")
    if args.segment_mm is not None:
        if args.standard is not None or (args.primary_deg is None) != (args.secondary_deg is None):
            raise common.UsageError("--segment-mm: give no --standard, and --primary-deg with --secondary-deg or neither")
        if args.distance_mm is not None or args.rotation_deg is not None:
            raise common.UsageError("--segment-mm searches the distance and the roll: give no --distance-mm or "
                                    "--rotation-deg")
        ends = common.parse_numbers(args.segment_mm, 6, "--segment-mm", unit="mm") / MM
        prefer = None
        if args.primary_deg is not None:
            prefer = View.from_angles(args.primary_deg, args.secondary_deg, ends[:3], position)
        plan = plan_perpendicular(system, ends[:3], ends[3:], patient, q_current, prefer=prefer,
                                  margin=args.margin_mm / MM)
        return _report(args, system, plan, position)
    if args.standard is not None:
        if args.primary_deg is not None or args.secondary_deg is not None:
            raise common.UsageError("--standard: give either a standard view or --primary-deg/--secondary-deg, not both")
        standard = standard_view(args.standard, target, position)
        angles = STANDARD_VIEWS[standard.name]
        view = View.from_angles(angles.primary_deg, angles.secondary_deg, target, position, distance, standard.name,
                                args.rotation_deg)
    elif args.primary_deg is None or args.secondary_deg is None:
        raise common.UsageError("--primary-deg and --secondary-deg (or --standard NAME) are required")
    else:
        view = View.from_angles(args.primary_deg, args.secondary_deg, target, position, distance,
                                rotation_deg=args.rotation_deg)
    plan = plan_view(system, view, patient, q_current, margin=args.margin_mm / MM)
    return _report(args, system, plan, position)


def _report(args, system, plan, position) -> int:
    patient = None if isinstance(position, str) else position
    print(_scene.describe_scene(system, plan.view.target, patient, getattr(patient, "position", position)))
    _print_plan(system, plan, position)
    common.write_json(args, {"preset": system.name, "target_mm": list(np.asarray(plan.view.target) * MM),
                             "patient": _scene.patient_json(patient, getattr(patient, "position", position)),
                             "margin_mm": args.margin_mm, **_plan_json(system, plan, position)})
    # the picture shows what the text reports: the plan; for a view unreachable by contact the configuration in
    # contact (the pair that fails drawn red); for one beyond the joint limits, the nearest reachable view
    title = f"view {_describe_view(plan.view, position)}"
    if plan.success:
        shown = plan.q
    elif plan.q_contact is not None:
        shown, title = plan.q_contact, f"{title} UNREACHABLE: the configuration in contact"
    elif plan.nearest is not None:
        shown = plan.nearest.q
        title = f"{title} unreachable ({plan.binding}): the nearest reachable view {_describe_view(plan.nearest.view, position)}"
    else:
        shown = None
    if shown is not None:
        _scene.write_figures(args, system, shown, patient, plan.view.target, title)
    return 0 if plan.success else 1


def _rotation(system, q, position) -> float:
    """The detector's rotation about the beam (deg) at q, as :func:`carmkin.interop.dicom.xa_angles` reads it."""
    from carmkin.interop.dicom import xa_angles
    from carmkin.views.view import _patient_frame

    return float(xa_angles(system.fk(q), _patient_frame(position))[2])


def _describe_view(view, position) -> str:
    p, s = view.angles(position)
    return f"{abs(p):.1f}° {'LAO' if p >= 0 else 'RAO'}, {abs(s):.1f}° {'CRA' if s >= 0 else 'CAU'}"


def _print_plan(system, plan, position) -> None:
    print(f"view {plan.view.name or ''} {_describe_view(plan.view, position)}".replace("  ", " "))
    if plan.success:
        print(f"reachable: q = {common.format_joints(system, plan.q)}")
        print(f"clearance {plan.clearance * MM:.1f} mm, source-to-target {plan.distance * MM:.1f} mm, "
              f"rotation about the beam {_rotation(system, plan.q, position):.1f}°")
        if plan.clearance_to:
            print("  clearance to " + ", ".join(f"{k} {v * MM:.1f} mm" for k, v in plan.clearance_to.items()))
        if plan.solver == "qp":
            print("  found by the QP with every joint free (the closed forms left the view unreachable)")
        for m in plan.moves:
            print(f"  move {m.joint}: {'clear' if m.clear else 'blocked'}" + (f" ({m.reason})" if m.reason else ""))
        if plan.moves and plan.duration is not None:
            print(f"  moves take {plan.duration}")
        if plan.motion is not None:
            print(f"  certified motion (every joint at once): {plan.motion}")
        return
    print(f"unreachable: {plan.reason}")
    if plan.q_contact is not None:
        print(f"in contact at q = {common.format_joints(system, plan.q_contact)} (joints in range; drawn by --png/--html)")
    if plan.nearest is not None:
        n = plan.nearest
        print(f"nearest reachable view: {_describe_view(n.view, position)}, {np.degrees(plan.angle):.2f}° away, "
              f"rotation about the beam {_rotation(system, n.q, position):.1f}°, "
              f"q = {common.format_joints(system, n.q)}, clearance {n.clearance * MM:.1f} mm")


def _plan_json(system, plan, position) -> dict:
    out = {"success": plan.success, "angles_deg": list(plan.view.angles(position)),
           "reason": plan.reason, "binding": plan.binding, "solver": plan.solver}
    if plan.success:
        out.update(q=common.joints_json(system, plan.q), clearance_mm=plan.clearance * MM, distance_mm=plan.distance * MM,
                   rotation_deg=_rotation(system, plan.q, position),
                   clearance_to_mm={k: v * MM for k, v in (plan.clearance_to or {}).items()},
                   duration_s=plan.duration.seconds if plan.duration is not None else None)
        if plan.motion is not None:
            out["motion"] = {"success": plan.motion.success, "reason": plan.motion.reason,
                             "method": plan.motion.method, "duration_s": plan.motion.duration,
                             "min_clearance_mm": plan.motion.min_clearance * MM,
                             "waypoints": [common.joints_json(system, q) for q in plan.motion.waypoints]}
    if plan.q_contact is not None:
        out["contact_q"] = common.joints_json(system, plan.q_contact)
    if plan.nearest is not None:
        out["nearest"] = {"angles_deg": list(plan.nearest.view.angles(position)), "angle_deg": float(np.degrees(plan.angle)),
                          "q": common.joints_json(system, plan.nearest.q), "clearance_mm": plan.nearest.clearance * MM}
    return out


def _range(text, option, step):
    lo, hi = common.parse_numbers(text, 2, option)

    if lo > hi:
        raise common.UsageError(f"{option} {text}: expected LO <= HI (deg)")
    return np.arange(lo, hi + 1e-9, step)


def _map(args: argparse.Namespace) -> int:
    from carmkin.views import reach_map

    system = common.system_from_args(args)
    target = common.parse_numbers(args.target_mm, 3, "--target-mm", unit="mm") / MM
    primary = _range(args.primary_range_deg, "--primary-range-deg", args.step_deg)
    secondary = _range(args.secondary_range_deg, "--secondary-range-deg", args.step_deg)
    paths = {k: v for k, v in (("plot", args.png and common.plot_path(args.png, "--png")),
                               ("html", args.html and common.output_path(args.html, "--html", ("html",))),
                               ("json", args.json)) if v}
    patient = _patient(system, args)
    if args.compare:
        return _compare(args, system, target, primary, secondary, patient, paths)
    m = reach_map(system, target, primary, secondary, patient, position=patient or args.patient_position,
                  margin=args.margin_mm / MM, workers=args.workers)
    print(f"preset {system.name}: {int(m.reachable.sum())} of {m.reachable.size} views reachable "
          f"({100 * m.fraction:.1f} %), primary {primary[0]:g}..{primary[-1]:g}°, secondary "
          f"{secondary[0]:g}..{secondary[-1]:g}° at {args.step_deg:g}°, margin {args.margin_mm:g} mm")
    for binding in ("angular/orbital", "translations", "wigwag", "contact"):
        count = int(np.sum(m.binding == binding))
        if count:
            print(f"  unreachable by {binding}: {count}")
    if m.reachable.any():
        print(f"  clearance of the reachable views: {np.nanmin(m.clearance) * MM:.1f} .. {np.nanmax(m.clearance) * MM:.1f} mm")
    if "plot" in paths:
        from carmkin.views.figure import reach_map_figure

        reach_map_figure(m).savefig(paths["plot"])
        print(f"wrote {paths['plot']}")
    if "html" in paths:
        from carmkin.viz.views import reach_map_page

        paths["html"].write_text(reach_map_page(system, m, patient), encoding="utf-8")
        print(f"wrote {paths['html']}")
    if "json" in paths:
        cells = [{"primary_deg": float(p), "secondary_deg": float(s), "reachable": bool(m.reachable[i, j]),
                  "clearance_mm": None if not m.reachable[i, j] else float(m.clearance[i, j] * MM),
                  "binding": str(m.binding[i, j]),
                  "q": common.joints_json(system, m.q[i, j]) if m.reachable[i, j] else None}
                 for i, p in enumerate(m.primary_deg) for j, s in enumerate(m.secondary_deg)]
        common.write_json(args, {"preset": system.name, "target_mm": list(target * MM), "margin_mm": args.margin_mm,
                                 "patient": _scene.patient_json(patient, args.patient_position), "cells": cells})
    return 0


def _compare(args, system, target, primary, secondary, patient, paths) -> int:
    import carmkin
    from carmkin.views.compare import compare_figure, compare_maps

    if system.table.joints:
        raise common.UsageError("--compare: give a 6-joint system (the third map adds the motorized preset's table "
                                "joints to it)")
    if "html" in paths or "json" in paths:
        raise common.UsageError("--compare writes --png only")
    import dataclasses

    # This C-arm on the motorized preset's table joints.
    joints = carmkin.load_preset("siremobile-iso-c3d-motorized-table").table.joints
    motorized = system.replace(table=dataclasses.replace(system.table, joints=joints))
    maps = compare_maps(system, target, primary, secondary, patient, motorized=motorized,
                        position=patient or args.patient_position, margin=args.margin_mm / MM, workers=args.workers)
    print(f"preset {system.name}, margin {args.margin_mm:g} mm:")
    for label, m in maps.items():
        print(f"{label}: {int(m.reachable.sum())} of {m.reachable.size} views reachable ({100 * m.fraction:.1f} %)")
    if "plot" in paths:
        compare_figure(maps).savefig(paths["plot"])
        print(f"wrote {paths['plot']}")
    return 0


def _read_centreline(path, option, frame, patient, position):
    """A CSV of points (mm; optional radius column) as a :class:`carmkin.views.Centreline` (table frame, m)."""
    from carmkin.views import Centreline, centreline_from_patient

    try:
        with open(path, encoding="utf-8") as handle:
            rows = [line for line in handle.read().splitlines() if line.strip()]
    except OSError as exc:
        raise common.UsageError(f"{option} {path}: cannot read ({exc.strerror})") from None
    if rows and not any(c.isdigit() for c in rows[0].split(",")[0]):
        rows = rows[1:]  # a header
    try:
        data = np.array([[float(v) for v in row.split(",")] for row in rows], dtype=float)
    except ValueError as exc:
        raise common.UsageError(f"{option} {path}: expected numbers x,y,z[,radius] in mm a row ({exc})") from None
    if data.ndim != 2 or data.shape[1] not in (3, 4):
        raise common.UsageError(f"{option} {path}: expected 3 or 4 columns (x,y,z[,radius] in mm), got "
                                f"{data.shape[1] if data.ndim == 2 and len(data) else 0}")
    radii = data[:, 3] if data.shape[1] == 4 else None
    label = f"{option} {path}"
    if frame == "patient":
        return centreline_from_patient(data[:, :3], patient if patient is not None else position, radii, label)
    return Centreline(data[:, :3] / MM, None if radii is None else radii / MM, label)


def _optimal(args: argparse.Namespace) -> int:
    from carmkin.views import optimal_view_map

    system = common.system_from_args(args)
    primary = _range(args.primary_range_deg, "--primary-range-deg", args.step_deg)
    secondary = _range(args.secondary_range_deg, "--secondary-range-deg", args.step_deg)
    weights = common.parse_numbers(args.weights, 2, "--weights")
    png = args.png and common.plot_path(args.png, "--png")
    patient = _patient(system, args)
    position = patient or args.patient_position
    line = _read_centreline(args.centreline, "--centreline", args.frame, patient, args.patient_position)
    others = [_read_centreline(f, "--others", args.frame, patient, args.patient_position)
              for f in args.others]
    target = None if args.target_mm is None else common.parse_numbers(args.target_mm, 3, "--target-mm", unit="mm") / MM
    m = optimal_view_map(system, line, primary, secondary, patient, [o.points for o in others], target,
                         radius=args.radius_mm / MM, weights=weights, margin=args.margin_mm / MM, position=position,
                         workers=args.workers)
    if args.json != common.STDOUT:
        _print_optimal(system, m, primary, secondary, args.step_deg, args.margin_mm)
    if png:
        from carmkin.views.optimal_figure import optimal_map_figure

        optimal_map_figure(m).savefig(png)
        print(f"wrote {png}")
    common.write_json(args, {**_optimal_json(system, m), "margin_mm": args.margin_mm,
                             "patient": _scene.patient_json(patient, args.patient_position)})
    return 0 if m.best_reachable is not None else 1


def _print_optimal(system, m, primary, secondary, step, margin_mm) -> None:
    print(f"preset {system.name}: {int(m.reachable.sum())} of {m.reachable.size} views reachable, primary "
          f"{primary[0]:g}..{primary[-1]:g}°, secondary {secondary[0]:g}..{secondary[-1]:g}° at {step:g}°, margin "
          f"{margin_mm:g} mm; target "
          f"{np.round(m.target * MM, 1).tolist()} mm; score = {m.weights[0]:g} foreshortening + {m.weights[1]:g} overlap")
    print(f"{'view':20s} {'primary':>8s} {'secondary':>9s} {'foreshort.':>10s} {'worst':>7s} {'overlap':>8s} "
          f"{'score':>7s} {'clearance':>10s}")
    for label, angles in (("optimal", m.optimal), ("best reachable", m.best_reachable)):
        if angles is None:
            print(f"{label:20s} none reachable")
            continue
        i, j = m.cell(angles)
        clear = f"{m.clearance[i, j] * MM:8.1f} mm" if m.reachable[i, j] else "unreachable"
        print(f"{label:20s} {angles[0]:+8.1f} {angles[1]:+9.1f} {100 * m.foreshortening[i, j]:9.2f}% "
              f"{100 * m.worst_foreshortening[i, j]:6.2f}% {100 * m.overlap[i, j]:7.2f}% {m.score[i, j]:7.4f} {clear:>10s}")
    for line in m.summary()[2:]:
        print(line)
    if m.plan is not None and m.plan.success:
        print(f"plan of the best reachable view: q = {common.format_joints(system, m.plan.q)}, clearance "
              f"{m.plan.clearance * MM:.1f} mm")


def _optimal_json(system, m) -> dict:
    def cell(angles):
        if angles is None:
            return None
        i, j = m.cell(angles)
        return {"primary_deg": angles[0], "secondary_deg": angles[1], "reachable": bool(m.reachable[i, j]),
                "foreshortening": float(m.foreshortening[i, j]), "worst_foreshortening": float(m.worst_foreshortening[i, j]),
                "overlap": float(m.overlap[i, j]), "score": float(m.score[i, j]),
                "clearance_mm": float(m.clearance[i, j] * MM) if m.reachable[i, j] else None}

    plan = None
    if m.plan is not None and m.plan.success:
        plan = {"q": common.joints_json(system, m.plan.q), "clearance_mm": m.plan.clearance * MM,
                "distance_mm": m.plan.distance * MM}
        if m.plan_metrics is not None:  # the plan's own metrics, where it stands (the cells are nominal views)
            plan.update({k: m.plan_metrics[k] for k in ("foreshortening", "worst_foreshortening", "overlap")})
    return {"target_mm": list(m.target * MM), "weights": list(m.weights), "optimal": cell(m.optimal),
            "best_reachable": cell(m.best_reachable), "optimum_reachable": m.optimum_reachable,
            "loss": m.loss, "plan": plan, "reachable_cells": int(m.reachable.sum()), "cells": int(m.reachable.size)}
