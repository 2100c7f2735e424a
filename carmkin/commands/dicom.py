"""DICOM XA geometry of a configuration, synthetic datasets, and the moves that give a DICOM image's view.

Without --read: prints, for --q-mm-deg, the patient-based XA Positioner Primary/Secondary Angle (LAO+/RAO−,
CRA+/CAU−) for --patient-position, the Enhanced XA Isocenter Reference System (positioner and table angles in deg,
table position to isocentre in mm) and the Table Top Vertical/Longitudinal/Lateral Position (mm; in DICOM's
terms "longitudinal" is across the table and "lateral" along it, seen by an operator beside the table).
--write-xa / --write-enhanced FILE write synthetic datasets (geometry only). --read FILE reads a dataset's
geometry and prints the joint (and table) moves from --q-mm-deg that reproduce its view, through the QP IK;
XA datasets need --isocenter-mm, the point the beam passed through (table frame), and a Patient Position:
the dataset's, or --patient-position where the dataset has none (never assumed). --positioner-convention names the
reading of the signs of the Enhanced XA positioner angles Ap2/Ap3 (beam: the detector tilts to +Z for
Ap2 > 0, the default; literal: the source does; see docs/interop.md). A file that cannot be read, or whose
geometry is missing or outside the standard's ranges, exits 2 with one line naming the attribute and its
tag. Needs pydicom (the dicom extra) for reading and writing.
"""

from __future__ import annotations

import argparse

import numpy as np

from ._common import add_alias, add_json_argument, add_preset_argument, format_joints, joints_json, patient_position, \
    system_from_args, write_json
from ._interop import add_configuration_argument, configuration, describe, millimetres

HELP = "XA / Enhanced XA geometry of a configuration, synthetic datasets, moves to a DICOM image's view"


def register(parser: argparse.ArgumentParser) -> None:
    add_preset_argument(parser)
    add_configuration_argument(parser, what="configuration (the current one with --read)")
    parser.add_argument("--patient-position", metavar="CODE", type=patient_position,
                        help="DICOM patient position (default HFS; with --read only used where the dataset has none)")
    add_alias(parser, "--patient", "--patient-position", "patient_position", metavar="CODE", type=patient_position)
    add_json_argument(parser, "the angles, the isocenter geometry and the table position (or, with --read, the moves)")
    parser.add_argument("--positioner-convention", choices=("beam", "literal", "literal-ap2", "literal-ap3",
                                                             "pyskindose"), default="beam",
                        help="reading of the Enhanced XA Ap2/Ap3 signs: beam (default), literal (both), or literal "
                             "for one angle only (literal-ap2 = pyskindose, literal-ap3)")
    parser.add_argument("--patient-origin-mm", metavar="X,Y,Z", default="0,0,0",
                        help="patient frame origin in the table frame (mm, default 0,0,0)")
    parser.add_argument("--write-xa", metavar="FILE", help="write a synthetic XA dataset of the configuration")
    parser.add_argument("--write-enhanced", metavar="FILE", help="write a synthetic Enhanced XA dataset")
    parser.add_argument("--read", metavar="FILE", help="read a dataset and print the moves to its view")
    parser.add_argument("--isocenter-mm", metavar="X,Y,Z",
                        help="for an XA dataset: the isocentre in the table frame (mm; default the patient origin)")


def run(args: argparse.Namespace) -> int:
    from carmkin.interop import dicom

    system = system_from_args(args)
    q = configuration(system, args.q_mm_deg)
    origin = millimetres(args.patient_origin_mm, "--patient-origin-mm")
    if args.read:
        from carmkin.interop import dicom_io

        return _read(system, q, args, origin, dicom_io.read_file(args.read))
    print(f"preset {system.name}: q = {describe(system, q)}")
    code = args.patient_position or "HFS"
    patient = dicom.patient_pose(code, origin)
    primary, secondary, rotation = dicom.xa_angles(system.fk(q), patient, convention=args.positioner_convention)
    # as printed (4 decimals): an angle that rounds to 0 is 0°, neither RAO nor CAU (a -1e-15 must not name a side)
    primary, secondary, rotation = (round(float(a), 4) + 0.0 for a in (primary, secondary, rotation))
    print(f"XA ({code.upper()}): Positioner Primary Angle {primary:.4f}° ({'LAO' if primary >= 0 else 'RAO'}), "
          f"Secondary Angle {secondary:.4f}° ({'CRA' if secondary >= 0 else 'CAU'}), detector rotation {rotation:.4f}°")
    g = dicom.isocenter_geometry(system, q, convention=args.positioner_convention)
    print(f"Isocenter Reference System: positioner {round(g.positioner_primary_deg, 4) + 0.0:.4f}°, "
          f"{round(g.positioner_secondary_deg, 4) + 0.0:.4f}°, "
          f"detector rotation {round(g.detector_rotation_deg, 4) + 0.0:.4f}°; table X/Y/Z to isocentre "
          + ", ".join(f"{round(v, 3) + 0.0:.3f}" for v in g.table_position_mm)
          + f" mm; table rotation {round(g.table_rotation_deg, 4) + 0.0:.4f}°, "
          f"head tilt {round(g.table_head_tilt_deg, 4) + 0.0:.4f}°, "
          f"cradle tilt {round(g.table_cradle_tilt_deg, 4) + 0.0:.4f}°; source to isocentre {g.source_to_isocenter_mm:.3f} mm")
    table = dicom.table_position(system, q)
    for name, value in table.items():
        print(f"{name}: {round(value, 3) + 0.0:.3f} mm")
    if args.write_xa or args.write_enhanced:
        from carmkin.interop import dicom_io

        if args.write_xa:
            dicom_io.write_xa(system, q, code, origin).save_as(args.write_xa, enforce_file_format=True)
            T = system.fk(q)
            iso = (T[:3, 3] + T[:3, 2] * system.carm.orbital_offset) * 1e3  # on the beam, source-isocentre away
            print(f"wrote {args.write_xa} (an XA dataset holds the view's angles, not where its isocentre is: read it "
                  f"back with --isocenter-mm={','.join(f'{round(v, 3) + 0.0:g}' for v in iso)}, this "
                  "configuration's isocentre in the table frame)")
        if args.write_enhanced:
            ds = dicom_io.write_enhanced_xa(system, q, patient_position=code, convention=args.positioner_convention)
            ds.save_as(args.write_enhanced, enforce_file_format=True)
            print(f"wrote {args.write_enhanced}")
    write_json(args, {"preset": system.name, "q": joints_json(system, q), "patient_position": code.upper(),
                      "primary_deg": primary, "secondary_deg": secondary, "detector_rotation_deg": rotation,
                      "isocenter_reference_system": {k: v for k, v in vars(g).items() if not k.startswith("_")},
                      "table_position_mm": {k: float(v) for k, v in table.items()}})
    return 0


def _read(system, q, args, origin, ds) -> int:
    from carmkin.reposition.dicom import moves_for_dataset

    view, result = moves_for_dataset(system, ds, q_current=q,
                                     isocenter=millimetres(args.isocenter_mm, "--isocenter-mm"),
                                     patient_origin=origin, patient_position=args.patient_position,
                                     convention=args.positioner_convention)
    # Nothing is printed before the file and its geometry are read: a bad file is one line on stderr, exit 2.
    print(f"preset {system.name}: q = {describe(system, q)}")
    if not view.full_pose and args.isocenter_mm is None:
        print(f"note: an XA dataset does not say where its isocentre is: assumed at the patient origin "
              f"{args.patient_origin_mm} mm (table frame); give --isocenter-mm, the point the beam passed through")
    print(f"view from the {view.source}: source at {np.round(view.pose[:3, 3] * 1e3, 3)} mm (table frame), "
          f"beam direction {np.round(view.pose[:3, 2], 6)}")
    out = {"preset": system.name, "q_current": joints_json(system, q), "view_source": str(view.source),
           "source_mm": view.pose[:3, 3] * 1e3, "beam_direction": view.pose[:3, 2], "success": bool(result.success)}
    if not result.success:
        print(f"no valid configuration reaches this view: {result.reason}")
        write_json(args, {**out, "reason": str(result.reason)})
        return 1
    from carmkin.model.motion import system_move

    duration = system_move(system, q, result.q)  # every joint at once
    write_json(args, {**out, "path": getattr(result.path, "value", str(result.path)), "q": joints_json(system, result.q),
                      "moves": joints_json(system, result.q - q), "duration_s": duration.seconds})
    print(f"configuration ({getattr(result.path, 'value', result.path)}): {describe(system, result.q)}")
    print("moves: " + format_joints(system, result.q - q, between=" "))
    print(f"the moves take {duration}")
    return 0
