"""Reproduce the dissertation's experiments under one stated error model (docs/fidelity.md).

  carmkin reproduce model     the error model: every parameter, its value and its source or "assumption"
  carmkin reproduce 4.6.2     §4.6.2 repositioning: camera-measured errors and X-ray corner pixels beside
                              the seed's, the truth below, and the per-joint decomposition
  carmkin reproduce fit       the fit of the free parameters (corner noise, operator precision) to §4.6.2's
                              six numbers, the 95 % region and the verdict
  carmkin reproduce 4.6.3     Table 4.6 (five parallax-free panoramas of the 440 x 80 mm phantom)
  carmkin reproduce 3.1       Table 3.1 (three-plane phantom, with and without VDP)
  carmkin reproduce 3.2       Table 3.2 (240 mm, 120 mm, 90°, 180°: parallax-free A/B, one-plane C)
  carmkin reproduce all       all tables and the verdict of one error model for every number

Every experiment runs under the fitted model (``--corner-noise-px`` and ``--operator-scale`` override its
two free parameters). Lengths print in mm, angles in degrees, image errors in px. ``--json FILE`` writes
the numbers; ``--png FILE`` writes the per-joint decomposition (4.6.2) or the fit's χ² map (fit).
Exit 0 on success, 2 on bad input.
"""

from __future__ import annotations

import argparse

from ._common import add_json_argument, add_png_argument, add_preset_argument, integer, number, plot_path, \
    system_from_args, write_json

HELP = "reproduce §4.6.2 (+ error-model fit), §4.6.3 Table 4.6 and ch. 3 Tables 3.1-3.2 beside the seed"
TABLES = ("model", "4.6.2", "fit", "4.6.3", "3.1", "3.2", "all")


def register(parser: argparse.ArgumentParser) -> None:
    add_preset_argument(parser)
    parser.add_argument("table", choices=TABLES, help="what to reproduce")
    parser.add_argument("--tasks", type=integer(1), default=10, help="4.6.2: repositioning tasks (default 10, as the seed)")
    parser.add_argument("--fit-tasks", type=integer(2), default=10,
                        help="fit: tasks per grid point (default 10; the ten-task statistics are resampled)")
    parser.add_argument("--repeats", type=integer(2), default=4, help="all: repeats of each experiment (default 4)")
    parser.add_argument("--seed", type=integer(0), default=0, help="numpy seed (default 0)")
    parser.add_argument("--corner-noise-px", type=number(0.0, 20.0, unit="px"), default=None,
                        help="video corner noise in px (default: the fitted value)")
    parser.add_argument("--operator-scale", type=number(0.0, 10.0), default=None,
                        help="operator stop errors as a multiple of 10 %% + 1 mm / 0.2 deg (default: the fitted value)")
    parser.add_argument("--rotation", choices=("axes", "angle"), default="axes",
                        help="fit: the seed's rotational error read as the mean |XYZ Euler angle| (axes, default) "
                        "or as the angle of the relative rotation")
    add_json_argument(parser, "the numbers")
    add_png_argument(parser, "4.6.2: the per-joint sensitivity and image share; fit: the chi2 map", old_names=("--plot",))


def _model(args):
    from carmkin.reproduce.error_model import ErrorModel
    from carmkin.reproduce.fit import BEST_FIT

    noise = BEST_FIT[0] if args.corner_noise_px is None else args.corner_noise_px
    scale = BEST_FIT[1] if args.operator_scale is None else args.operator_scale
    return ErrorModel(corner_noise_px=noise).with_operator_scale(scale)


def run(args: argparse.Namespace) -> int:
    if args.png:
        args.png = plot_path(args.png, "--png")
    from carmkin.reproduce import chapter3, error_model, fit, joints, repositioning, stitching, verdict

    system, model, out = system_from_args(args), _model(args), {}
    if args.table in ("model", "all"):
        print(error_model.format_model(model))
        out["model"] = {name: value for name, value, _ in model.table()}
    if args.table in ("4.6.2", "all"):
        tasks = repositioning.run(system, model, args.tasks, args.seed)
        stats = repositioning.summary(tasks)
        square = error_model.square_pixel_system(system)
        table = joints.decompose(square, tasks)
        print(repositioning.format_summary(stats))
        print(joints.format_decomposition(square, table))
        out["4.6.2"] = {k: v for k, v in stats.items()}
        out["4.6.2 joints"] = {k: (list(map(float, v)) if k != "joints" and hasattr(v, "__len__") else v)
                               for k, v in table.items()}
        if args.png and args.table == "4.6.2":
            joints.plot_decomposition(square, table).savefig(args.png)
            print(f"wrote {args.png}")
    if args.table == "fit":
        result = fit.fit(system, tasks=args.fit_tasks, seed=args.seed, rotation=args.rotation)
        print(fit.format_fit(result))
        out["fit"] = {"best": [result.best.corner_noise_px, result.best.operator_scale], "chi2": result.best.chi2,
                      "p_value": result.p_value, "reproduced": result.reproduced,
                      "region": [[p.corner_noise_px, p.operator_scale] for p in result.region]}
        if args.png:
            fit.plot_fit(result).savefig(args.png)
            print(f"wrote {args.png}")
    if args.table in ("4.6.3", "all"):
        rows = stitching.table(stitching.run(system, model, 5, args.seed))
        print(stitching.format_table(rows))
        out["4.6.3"] = rows
    if args.table in ("3.1", "all"):
        rows = chapter3.table_3_1(system, model, 2, args.seed)
        print(chapter3.format_table_3_1(rows))
        out["3.1"] = rows
    if args.table in ("3.2", "all"):
        result = chapter3.table_3_2(system, model, args.seed)
        print(chapter3.format_table_3_2(result))
        out["3.2"] = result
    if args.table == "all":
        rows = verdict.verdict(system, model, args.repeats)
        print(verdict.format_verdict(rows))
        out["verdict"] = [r.__dict__ for r in rows]
    write_json(args, out)
    return 0
