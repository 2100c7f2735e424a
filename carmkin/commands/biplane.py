"""Biplane C-arms: check a biplane preset, plan a frontal and a lateral view at once.

`carmkin biplane check --preset angio-biplane` loads both planes (the planes must share one table and one
isocentre and be clear of each other at rest) and prints the joints, the rest configuration and the clearances
at rest: between the planes (the nearest pair named) and of each plane to table and floor.
`carmkin biplane plan --standard ap --lateral-deg 90` plans the frontal plane's view (--standard NAME, or
--primary-deg/--secondary-deg; XA angles, LAO +, CRA +) and the lateral plane's (--lateral-deg: the frontal beam
turned about the patient's long axis, default 90; or --lateral-standard NAME) of --target-mm for the patient
(--patient parametric, the default, or none), the planes clear of each other, of the table and of the patient by
--margin-mm. It prints each plane's joints, the clearance between the planes and, when no plan exists, the
reason. --json writes it, --html writes both planes in the viewer. Exit 1 when the pair cannot be planned.
"""

from __future__ import annotations

import argparse

import numpy as np

from . import _common as common
from . import _scene

HELP = "biplane C-arms: check a biplane preset, plan a frontal and a lateral view at once"
MM = 1000.0
#: The preset the biplane commands read by default.
DEFAULT_BIPLANE = "angio-biplane"


def _preset(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--preset", default=DEFAULT_BIPLANE,
                        help=f"a biplane preset: built-in name or .toml file (default {DEFAULT_BIPLANE})")
    common.add_json_argument(parser)


def register(parser: argparse.ArgumentParser) -> None:
    sub = parser.add_subparsers(dest="action", required=True, metavar="ACTION", parser_class=type(parser))
    check = sub.add_parser("check", help="both planes, the rest configuration and the clearances at rest",
                           description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    _preset(check)
    check.set_defaults(action_run=_check)
    plan = sub.add_parser("plan", help="plan a frontal and a lateral view at once", description=__doc__,
                          formatter_class=argparse.RawDescriptionHelpFormatter)
    _preset(plan)
    plan.add_argument("--standard", metavar="NAME", help="the frontal view: a standard view's name")
    plan.add_argument("--primary-deg", type=common.number(-180.0, 180.0, unit="deg"),
                      help="the frontal view's primary angle (LAO +, deg)")
    plan.add_argument("--secondary-deg", type=common.number(-90.0, 90.0, unit="deg"),
                      help="the frontal view's secondary angle (CRA +, deg)")
    plan.add_argument("--lateral-deg", type=common.number(-180.0, 180.0, unit="deg"), default=None,
                      help="the angle between the beams: the frontal beam turned about the patient's long axis "
                           "(deg, default 90)")
    plan.add_argument("--lateral-standard", metavar="NAME", help="the lateral view: a standard view's name")
    plan.add_argument("--target-mm", metavar="X,Y,Z", default="0,0,0",
                      help="the point both beams pass through, table frame (mm, default 0,0,0)")
    _scene.add_patient_arguments(plan, default="parametric")
    common.add_margin_argument(plan, "clearance kept between the planes and from table, floor and patient")
    plan.add_argument("--html", metavar="FILE", help="write both planes and the patient in the viewer")
    plan.set_defaults(action_run=_plan)


def run(args: argparse.Namespace) -> int:
    return args.action_run(args)


def _load(args):
    from carmkin.biplane import load_biplane
    from carmkin.errors import BiplaneError, PresetError

    if str(args.preset).endswith(".toml") and not __import__("pathlib").Path(args.preset).is_file():
        raise common.UsageError(f"--preset {args.preset}: no such preset file")
    try:
        return load_biplane(args.preset)
    except (PresetError, BiplaneError) as exc:
        raise common.UsageError(f"--preset: {exc}") from None


def _check(args: argparse.Namespace) -> int:
    from carmkin.biplane import BiplaneWorld

    biplane = _load(args)
    rest = np.array(biplane.rest)
    clearance = BiplaneWorld(biplane).clearance(rest)
    iso = biplane.isocentres(rest)
    print(f"biplane {biplane.name}: frontal {biplane.frontal.name}, lateral {biplane.lateral.name}, {biplane.nq} joints")
    print(f"rest: {common.format_joints(biplane, rest)}")
    print(f"isocentre {np.round(iso[0] * MM, 1).tolist()} mm (table frame), planes "
          f"{np.linalg.norm(iso[0] - iso[1]) * MM:.3f} mm apart")
    print(f"clearance at rest: between the planes {clearance.planes * MM:.1f} mm ({clearance.pair[0]} - "
          f"{clearance.pair[1]}), frontal to table and floor {clearance.frontal * MM:.1f} mm, lateral "
          f"{clearance.lateral * MM:.1f} mm")
    common.write_json(args, {"preset": biplane.name, "frontal": biplane.frontal.name, "lateral": biplane.lateral.name,
                             "rest": common.joints_json(biplane, rest),
                             "clearance_mm": {"planes": clearance.planes * MM, "frontal": clearance.frontal * MM,
                                              "lateral": clearance.lateral * MM},
                             "nearest_pair": list(clearance.pair)})
    return 0


def _views(args, target, position):
    from carmkin.views import View
    from carmkin.views.standard import standard_view

    if args.standard is not None:
        if args.primary_deg is not None or args.secondary_deg is not None:
            raise common.UsageError("--standard: give either a standard view or --primary-deg/--secondary-deg, not both")
        frontal = standard_view(args.standard, target, position)
    elif args.primary_deg is None or args.secondary_deg is None:
        raise common.UsageError("--primary-deg and --secondary-deg (or --standard NAME) are required")
    else:
        frontal = View.from_angles(args.primary_deg, args.secondary_deg, target, position, name="frontal")
    if args.lateral_standard is not None:
        if args.lateral_deg is not None:
            raise common.UsageError("--lateral-standard: give either a lateral view or --lateral-deg, not both")
        return frontal, standard_view(args.lateral_standard, target, position)
    return frontal, 90.0 if args.lateral_deg is None else args.lateral_deg


def _plan(args: argparse.Namespace) -> int:
    from carmkin.biplane import plan_biplane

    biplane = _load(args)
    target = common.parse_numbers(args.target_mm, 3, "--target-mm", unit="mm") / MM
    patient = _scene.patient_from_args(biplane.frontal, args)
    position = patient if patient is not None else args.patient_position
    frontal, lateral = _views(args, target, position)
    plan = plan_biplane(biplane, frontal, lateral, patient, margin=args.margin_mm / MM)
    print(_scene.describe_scene(biplane.frontal, frontal.target, patient, args.patient_position))
    out = {"preset": biplane.name, "success": plan.success, "failure": plan.failure.name if plan.failure else None,
           "reason": plan.reason}
    for name, view_plan in (("frontal", plan.frontal), ("lateral", plan.lateral)):
        if view_plan is not None:
            p, s = view_plan.view.angles(position)
            print(f"{name} view: primary {p:+.1f}°, secondary {s:+.1f}°")
            out[name] = {"angles_deg": [p, s]}
    if plan.success:
        print(f"both planned: q = {common.format_joints(biplane, plan.q)}")
        print(f"clearance between the planes {plan.clearance * MM:.1f} mm ({plan.pair[0]} - {plan.pair[1]}), "
              f"beams {np.degrees(plan.angle):.2f}° apart")
        out.update(q=common.joints_json(biplane, plan.q), clearance_mm=plan.clearance * MM, nearest_pair=list(plan.pair),
                   angle_deg=float(np.degrees(plan.angle)))
        if args.html:
            from carmkin.viz.biplane import biplane_page

            with open(args.html, "w", encoding="utf-8") as stream:
                stream.write(biplane_page(biplane, plan.q, patient))
            print(f"wrote {args.html}")
    else:
        print(f"not planned: {plan.reason}")
        if args.html:
            print(f"not written (no plan to show): {args.html}")
    common.write_json(args, out)
    return 0 if plan.success else 1
