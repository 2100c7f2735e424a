"""Skin dose of a procedure: the entrance skin dose map from a dose report (RDSR).

`carmkin dose map --rdsr FILE --preset angio-floor` reads the report's irradiation events (pydicom, the dose
extra), places each through the preset's joints (docs/dose.md: the vendor's table-position convention, the
XA primary and secondary angles), and prints the peak skin dose (PSD, mGy), where it is (table frame, mm),
the largest overlap of entrance fields and the cells hit, on --phantom plane (PySkinDose's 40 x 120 cm sheet on
a 4 cm pad, the default), cylinder (its 20 x 10 cm elliptic cylinder) or patient (the parametric body of
--patient-height-mm, --patient-mass-kg, --patient-chest-z-mm, head first supine as the report's angles are read)
at --spacing-mm. An event the report does not give the geometry or
technique of is refused by name (exit 2); --skip-incomplete maps the others and lists the refused.
--secondary pyskindose reads the secondary angle as PySkinDose does per vendor (its Siemens reading is the
opposite of the standard's text). --json writes the numbers, --png the map.
"""

from __future__ import annotations

import argparse

from . import _common as common
from . import _scene

HELP = "skin dose of a procedure: the dose map of a dose report (RDSR) on a phantom or the parametric patient"
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
    dmap.add_argument("--phantom", choices=("plane", "cylinder", "patient"), default="plane",
                      help="the skin: PySkinDose's plane (default) or cylinder, or the parametric patient")
    dmap.add_argument("--spacing-mm", type=common.number(1.0, 100.0, unit="mm"), default=10.0,
                      help="skin cell spacing (mm, default 10)")
    _scene.add_patient_arguments(dmap, default="parametric")  # used with --phantom patient
    dmap.add_argument("--secondary", choices=("dicom", "pyskindose"), default="dicom",
                      help="reading of the secondary angle: the standard's (default) or PySkinDose's per vendor")
    dmap.add_argument("--skip-incomplete", action="store_true",
                      help="map the events that have their geometry and list the refused ones (else exit 2)")
    common.add_json_argument(dmap, "the PSD, its place, the overlap and each event's part")
    common.add_png_argument(dmap, "the dose map")
    dmap.set_defaults(action_run=_map)


def run(args: argparse.Namespace) -> int:
    return args.action_run(args)


def _skin(system, args):
    from carmkin import dose

    spacing = args.spacing_mm / MM
    if args.phantom == "plane":
        return dose.plane(system, spacing=spacing)
    if args.phantom == "cylinder":
        return dose.cylinder(system, spacing=spacing)
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
    return 0
