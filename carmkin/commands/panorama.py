"""Parallax-free panorama planning (§4.4, Table 4.3).

The panorama frame is the image of the reference X-ray pose: by default every joint at the middle of its
range (Siremobile preset: wigwag/angular/orbital 0°, table translation 0, vertical 200 mm, horizontal
100 mm); give another with --q-mm-deg. Pixel coordinates (u, v) are in that frame.

  carmkin panorama shot --principal-point 600,300     plan one shot: pose, joints, moves, validity
  carmkin panorama plan --length-mm 400 --overlap 0   shots covering a length on the object plane
  carmkin panorama map --png map.png                  validity of a grid of principal points (PNG)
  carmkin panorama parallax --length-mm 400           stitch a 3-plane marker phantom: parallax (px)

shot and plan take --html FILE: a self-contained viewer page (open it in a browser) with the C-arm at the
reference configuration, a cone at every shot's target pose, and the last valid shot as a ghost.

Joint values (--q-mm-deg: one per joint of the preset) and moves print in mm for prismatic
joints and degrees for revolute joints. Δd0 is the C-arm's motion
relative to the table along Z0: the table itself moves by −Δd0.
"""

from __future__ import annotations

import argparse
import math

import numpy as np

from ._common import (
    JOINTS_FLAG,
    MIN_DISTANCE_MM,
    MM_PER_M,
    UsageError,
    add_joints_argument,
    add_json_argument,
    add_png_argument,
    add_preset_argument,
    format_joints,
    integer,
    joints_json,
    number,
    output_path,
    parse_joints,
    parse_numbers,
    plot_path,
    system_from_args,
    write_json,
)

#: Lengths a panorama can cover (mm): from a fraction of one image to more than any table travel; outside, the
#: value is a unit slip (0.4 given for 400 mm) and is refused, naming it.
PANORAMA_LENGTH_MM = (10.0, 5000.0)

HELP = "plan parallax-free panoramas: one shot, a sequence, the validity map, the parallax check"


def _add_common(parser: argparse.ArgumentParser) -> None:
    add_preset_argument(parser)
    add_joints_argument(parser, "configuration of the reference image", "mid-range joints",
                        old_names=("--reference-q-mm-deg",))
    parser.add_argument("--margin-mm", type=number(0.0, unit="mm"), default=0.0,
                        help="collision margin of the validity check (default 0: only intersections)")
    parser.add_argument("--no-fallback", action="store_true", help="do not try the QP IK when no "
                        "closed-form branch is valid")
    add_json_argument(parser)


def _add_line(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--length-mm", type=number(*PANORAMA_LENGTH_MM, unit="mm"), default=400.0,
                        help=f"length to cover, {PANORAMA_LENGTH_MM[0]:g} to {PANORAMA_LENGTH_MM[1]:g} mm (default 400)")
    parser.add_argument("--overlap", type=number(0.0, 1.0, open_maximum=True), default=0.0,
                        help="overlap of consecutive shots, fraction of a shot in [0, 1) (default 0)")
    parser.add_argument("--direction-px", metavar="DU,DV",
                        help="panorama direction in pixels (default: the table axis Z0 as seen in the image)")
    parser.add_argument("--object-distance-mm", type=number(MIN_DISTANCE_MM, 10000.0, unit="mm"), default=None,
                        help="distance from the source to the object plane ⟂ to the reference axis "
                        "(default: where the reference axis leaves the table top)")


def register(parser: argparse.ArgumentParser) -> None:
    sub = parser.add_subparsers(dest="panorama_command", required=True, metavar="ACTION")
    shot = sub.add_parser("shot", help="plan one shot from its principal point (Table 4.3)")
    _add_common(shot)
    shot.add_argument("--principal-point", required=True, metavar="U,V", help="principal point (px)")
    _add_html(shot)
    plan = sub.add_parser("plan", help="shots covering a length with a given overlap")
    _add_common(plan)
    _add_line(plan)
    _add_html(plan)
    vmap = sub.add_parser("map", help="validity map of principal points, saved as a PNG")
    _add_common(vmap)
    vmap.add_argument("--range-px", metavar="UMIN,UMAX,VMIN,VMAX",
                      help="principal points to scan (default: the reference image extended by 3 widths "
                      "left/right and 2 heights up/down)")
    vmap.add_argument("--grid", type=integer(2, 1001), default=41, help="grid points along u (v in proportion; default 41)")
    add_png_argument(vmap, "the map (default panorama_map.png)", old_names=("--out",))
    vmap.set_defaults(png="panorama_map.png")
    vmap.add_argument("--with-plan", action="store_true", help="overlay the plan of --length-mm/--overlap")
    _add_line(vmap)
    par = sub.add_parser("parallax", help="stitch a synthetic 3-plane marker phantom and report parallax")
    _add_common(par)
    _add_line(par)
    par.add_argument("--noise", default="0.1,0;1,0;0,0.1;0,1;1,1", metavar="MM,DEG;...",
                     help="pose noise levels σ (mm, deg), separated by ';' (default '0.1,0;1,0;0,0.1;0,1;1,1')")
    par.add_argument("--trials", type=integer(1), default=50, help="noise trials per level (default 50)")
    par.add_argument("--seed", type=integer(0), default=0, help="random seed (default 0)")


def _add_html(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--html", metavar="FILE", help="also write the shots into a viewer page (.html) to open in "
                        "a browser: cones at the shots' poses, the last valid shot as a ghost")


def _write_html(system, planner, shots, path) -> None:
    """The viewer page of ``shots``: the C-arm at the reference, cones at the targets, the last valid shot's ghost."""
    from carmkin.viz import CArmViewer

    viewer = CArmViewer(system, q=planner.q_reference)
    viewer.draw_shots(np.array([shot.target for shot in shots]))
    valid = [shot for shot in shots if shot.valid]
    if valid:
        viewer.show_ghost(valid[-1].q)
    viewer.save_html(path)
    print(f"wrote {path}")


def _planner(system, args):
    from carmkin import panorama as pano

    q = None
    if args.q_mm_deg is not None:
        q = parse_joints(args.q_mm_deg, system, JOINTS_FLAG)
    return pano.PanoramaPlanner(system, q_reference=q, fallback=not args.no_fallback,
                                margin=args.margin_mm / MM_PER_M)


def _joints(system, q) -> str:
    return format_joints(system, q)


def _shot_json(system, shot) -> dict:
    """One shot in the command line's units."""
    return {"principal_point_px": list(map(float, shot.principal_point)), "valid": bool(shot.valid),
            "category": shot.category, "path": str(shot.path), "q": joints_json(system, shot.q),
            "moves": joints_json(system, shot.moves), "table_translation_mm": shot.table_translation * MM_PER_M,
            "reasons": list(shot.reasons)}


def _print_shot(system, shot, label: str = "shot") -> None:
    u, v = shot.principal_point
    tilt = math.degrees(math.acos(np.clip(shot.axis[2], -1.0, 1.0)))
    print(f"{label}: principal point ({u:.2f}, {v:.2f}) px, tilt {tilt:.3f}° from the reference axis: "
          f"{'VALID' if shot.valid else 'INVALID (' + shot.category + ')'} [{shot.path}]")
    print(f"  joints: {_joints(system, shot.q)}")
    print(f"  moves:  {_joints(system, shot.moves)}")
    print(f"  table: d0 changes by {shot.table_translation * 1e3:+.3f} mm, i.e. the table top moves "
          f"{-shot.table_translation * 1e3:+.3f} mm along Z0 relative to the C-arm; FK residual {shot.residual:.2e}")
    corners = shot.outline[:: (len(shot.outline) - 1) // 4][:4]
    print("  predicted image corners in the panorama (px): "
          + " ".join(f"({a:.1f}, {b:.1f})" for a, b in corners))
    for reason in shot.reasons:
        print(f"  why: {reason}")


def _line_args(planner, args):
    direction = None
    if args.direction_px is not None:
        du, dv = parse_numbers(args.direction_px, 2, "--direction-px")
        direction = planner.direction_from_pixels(du, dv)
    distance = None
    if args.object_distance_mm is not None:
        sid_mm = planner.system.carm.source_to_detector * MM_PER_M
        if args.object_distance_mm >= sid_mm:
            raise UsageError(f"--object-distance-mm {args.object_distance_mm:g} puts the object plane at or beyond "
                             f"the detector ({sid_mm:g} mm from the source): expected > 0 and < {sid_mm:g} mm")
        distance = args.object_distance_mm / MM_PER_M
    return args.length_mm / MM_PER_M, args.overlap, direction, distance


def _numbers(values, spec: str) -> str:
    """``"(+1.0000, +0.0000, -0.5000)"``: each value in ``spec``; a value that rounds to zero prints as +0, never -0."""
    digits = int(spec.rpartition(".")[2].rstrip("f"))
    return "(" + ", ".join(f"{round(float(v), digits) + 0.0:{spec}}" for v in np.ravel(values)) + ")"


def _print_plan(system, plan) -> None:
    print(f"object plane at {plan.distance * 1e3:.1f} mm from the source, direction "
          f"{_numbers(plan.direction, '+.4f')} (unit vector, reference source frame); "
          f"{len(plan.shots)} shots, overlap {plan.overlap:.0%}")
    for k, (shot, (lo, hi)) in enumerate(zip(plan.shots, plan.extents)):
        _print_shot(system, shot, f"shot {k + 1}")
        print(f"  covers [{lo * 1e3:+.1f}, {hi * 1e3:+.1f}] mm on the object plane")
    print(f"table translations Δd0 (mm, from the previous shot): {_numbers(plan.table_translations * 1e3, '+.2f')}")
    print("plan VALID" if plan.valid else "plan INVALID: " + ", ".join(
        f"shot {k + 1}" for k, s in enumerate(plan.shots) if not s.valid))


def run(args: argparse.Namespace) -> int:
    system = system_from_args(args)
    if args.panorama_command == "map":
        args.png = plot_path(args.png, "--png")
    html = getattr(args, "html", None)
    html = None if html is None else output_path(html, "--html", ("html", "htm"))
    planner = _planner(system, args)
    print(f"preset {system.name}; reference: {_joints(system, planner.q_reference)}")
    if args.panorama_command == "shot":
        u, v = parse_numbers(args.principal_point, 2, "--principal-point")
        shot = planner.shot((u, v))
        _print_shot(system, shot)
        if html is not None:
            _write_html(system, planner, [shot], html)
        write_json(args, {"preset": system.name, "shot": _shot_json(system, shot)})
        return 0 if shot.valid else 1
    if args.panorama_command == "plan":
        plan = planner.plan(*_line_args(planner, args))
        _print_plan(system, plan)
        if html is not None:
            _write_html(system, planner, plan.shots, html)
        write_json(args, {"preset": system.name, "valid": bool(plan.valid), "distance_mm": plan.distance * MM_PER_M,
                          "overlap": plan.overlap, "shots": [_shot_json(system, shot) for shot in plan.shots],
                          "covers_mm": np.asarray(plan.extents) * MM_PER_M,
                          "table_translations_mm": plan.table_translations * MM_PER_M})
        return 0 if plan.valid else 1
    if args.panorama_command == "map":
        return _run_map(system, planner, args)
    return _run_parallax(system, planner, args)


def _run_map(system, planner, args) -> int:
    import matplotlib

    from carmkin import panorama as pano

    matplotlib.use("Agg")
    w, h = planner.size
    if args.range_px is None:
        umin, umax, vmin, vmax = -3.0 * w, 4.0 * w, -2.0 * h, 3.0 * h
    else:
        umin, umax, vmin, vmax = parse_numbers(args.range_px, 4, "--range-px")
    if umax <= umin or vmax <= vmin:
        raise UsageError(f"--range-px needs UMIN < UMAX and VMIN < VMAX, got {args.range_px!r}")
    us = np.linspace(umin, umax, args.grid)
    vs = np.linspace(vmin, vmax, max(2, round(args.grid * (vmax - vmin) / (umax - umin))))
    categories = planner.validity_map(us, vs)
    shots = planner.plan(*_line_args(planner, args)).shots if args.with_plan else ()
    pano.plot_validity_map(planner, us, vs, categories, args.png, shots)
    for k, name in enumerate(pano.CATEGORIES):
        print(f"{name:>20}: {np.mean(categories == k) * 100:5.1f} % of {categories.size} principal points")
    print(f"wrote {args.png}")
    write_json(args, {"preset": system.name, "u_px": us, "v_px": vs, "categories": list(pano.CATEGORIES),
                      "category": categories,
                      "fraction": {name: float(np.mean(categories == k)) for k, name in enumerate(pano.CATEGORIES)}})
    return 0


def _run_parallax(system, planner, args) -> int:
    from carmkin.panorama import phantom as ph

    levels = [parse_numbers(item, 2, "--noise") for item in args.noise.split(";") if item.strip()]
    if not levels or any(np.any(level < 0) for level in levels):
        raise UsageError(f"--noise needs levels 'MM,DEG;...' with σ >= 0 (mm, deg), got {args.noise!r}")
    plan = planner.plan(*_line_args(planner, args))
    print(f"{len(plan.shots)} shots, overlap {plan.overlap:.0%}, object plane at {plan.distance * 1e3:.1f} mm; "
          f"plan {'valid' if plan.valid else 'INVALID'}")
    phantom = ph.marker_phantom(planner, length=args.length_mm / 1e3)
    print(f"phantom: {len(phantom.points)} markers on {len(phantom.offsets)} planes 80 mm apart "
          f"(table Y0 = {_numbers(phantom.offsets * 1e3, '+.1f')} mm)")
    print(ph.parallax_check(planner, plan, phantom).describe())
    print(f"pose noise ({args.trials} trials per level; discrepancy to the exact reference projection):")
    print("σ (mm)  σ (deg)  RMS (px)  max (px)  f·σ_rad (px)  f·σ_m/z (px)")
    rows = ph.noise_propagation(planner, plan, phantom, levels, trials=args.trials, seed=args.seed)
    for row in rows:
        print(f"{row['sigma_mm']:6g}  {row['sigma_deg']:7g}  {row['rms_px']:8.3f}  {row['max_px']:8.3f}  "
              f"{row['rotation_px']:12.3f}  {row['translation_px']:12.3f}")
    write_json(args, {"preset": system.name, "plan_valid": bool(plan.valid), "shots": len(plan.shots),
                      "parallax": str(ph.parallax_check(planner, plan, phantom).describe()), "noise": list(rows)})
    return 0
