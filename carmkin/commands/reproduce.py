"""Reproduce the dissertation's experiments under one stated error model (docs/fidelity.md).

  carmkin reproduce model     the error model: every parameter, its value and its source or "assumption"
  carmkin reproduce 4.6.2     §4.6.2 repositioning: camera-measured errors (separate single-frame
                              estimates, as the seed) and X-ray corner pixels beside the seed's, the truth
                              below, the per-joint decomposition and the verdict (--end box: an operator
                              who ends within 0.5 mm / 0.1° of every reference joint)
  carmkin reproduce fit       the fit of the free parameters (corner noise, operator precision) to §4.6.2's
                              six numbers, the 95 % region and the verdict
  carmkin reproduce 4.6.3     Table 4.6 (five parallax-free panoramas of the 440 x 80 mm phantom)
  carmkin reproduce 3.1       Table 3.1 (three-plane phantom, with and without VDP)
  carmkin reproduce 3.2       Table 3.2 (240 mm, 120 mm, 90°, 180°: parallax-free A/B, one-plane C)
                              (3.1, 3.2: --protocol chapter3, §3.3.4.2's, default; chapter4 beside)
  carmkin reproduce all       all tables and the verdict of one error model for every number, each row
                              predicted / fitted / not-a-test with its criterion, and the counts

Every experiment prints its verdict rows (over --repeats numpy seeds, each the seed's size;
carmkin.reproduce.verdict: a t-test of the seed's number against the repeats at α = 0.05, or Table
3.2's error against the seed's stated 1 %). Under the fitted model the verdicts are judged **across the
fit's 95 % region** (carmkin.reproduce.fit.FIT_REGION, three points): a row keeps its verdict only where
every point gives it, else "undetermined", and the tally says so (three times the time of one point;
--best-fit-only judges at the best fit alone). A model given by --corner-noise-px / --operator-scale is
not the fit: its verdicts are judged at that one point, and the tally says that too.

Every experiment runs under the fitted model (``--corner-noise-px`` and ``--operator-scale`` override its
two free parameters). Lengths print in mm, angles in degrees, image errors in px. ``--json FILE`` writes
the numbers; ``--png FILE`` writes the per-joint decomposition (4.6.2) or the fit's χ² map (fit).
Exit 0 on success, 2 on bad input. ``carmkin reposition experiment`` is the guidance package's own
run, not this reproduction (it says so).
"""

from __future__ import annotations

import argparse
import sys

from carmkin.errors import UsageError

from ._common import add_json_argument, add_png_argument, add_preset_argument, integer, number, parse_numbers, \
    plot_path, system_from_args, write_json

HELP = "reproduce §4.6.2 (+ error-model fit), §4.6.3 Table 4.6 and ch. 3 Tables 3.1-3.2 beside the seed"
TABLES = ("model", "4.6.2", "fit", "4.6.3", "3.1", "3.2", "all")


def register(parser: argparse.ArgumentParser) -> None:
    add_preset_argument(parser)
    parser.add_argument("table", choices=TABLES, help="what to reproduce")
    parser.add_argument("--tasks", type=integer(1), default=10, help="4.6.2: repositioning tasks (default 10, as the seed)")
    parser.add_argument("--fit-tasks", type=integer(2), default=10,
                        help="fit: tasks per grid point (default 10; the ten-task statistics are resampled)")
    parser.add_argument("--repeats", type=integer(2), default=8,
                        help="verdicts: repeats of each experiment (default 8; at least 2, the test needs their spread)")
    parser.add_argument("--protocol", choices=("chapter3", "chapter4"), default="chapter3",
                        help="3.1, 3.2: the stitching procedure, §3.3.4.2's (chapter3, default) or chapter 4's guidance")
    parser.add_argument("--end", choices=("guided", "box"), default="guided",
                        help="4.6.2: guided manual moves (default) or an operator ending within 0.5 mm / 0.1° per joint")
    parser.add_argument("--corner-noise-grid-px", metavar="PX,...", default=None,
                        help="fit: corner noise grid in px (default 0.25,0.5,1,1.5,2,3)")
    parser.add_argument("--operator-scale-grid", metavar="S,...", default=None,
                        help="fit: operator scale grid (default 0.02,0.05,0.1,0.2,0.4,1)")
    parser.add_argument("--seed", type=integer(0), default=0, help="numpy seed (default 0)")
    parser.add_argument("--corner-noise-px", type=number(0.0, 20.0, unit="px"), default=None,
                        help="video corner noise in px (default: the fitted value)")
    parser.add_argument("--operator-scale", type=number(0.0, 10.0), default=None,
                        help="operator stop errors as a multiple of 10 %% + 1 mm / 0.2 deg (default: the fitted value)")
    parser.add_argument("--rotation", choices=("axes", "angle"), default="axes",
                        help="fit: the seed's rotational error read as the mean |XYZ Euler angle| (axes, default) "
                        "or as the angle of the relative rotation")
    parser.add_argument("--best-fit-only", action="store_true",
                        help="verdicts: judge at the best fit alone, not across the fit's 95 %% region (a third of the "
                        "time; the verdicts then ignore the fit's uncertainty)")
    add_json_argument(parser, "the numbers")
    add_png_argument(parser, "4.6.2: the per-joint sensitivity and image share; fit: the chi2 map", old_names=("--plot",))


def _model(args):
    from carmkin.reproduce.error_model import ErrorModel
    from carmkin.reproduce.fit import BEST_FIT

    noise = BEST_FIT[0] if args.corner_noise_px is None else args.corner_noise_px
    scale = BEST_FIT[1] if args.operator_scale is None else args.operator_scale
    return ErrorModel(corner_noise_px=noise).with_operator_scale(scale)


def _judged_at(args):
    """The models the verdicts are judged under and the words the tally states it in: the fit's 95 % region
    (:func:`carmkin.reproduce.verdict.region_models`) under the fitted model, else the one model given."""
    from carmkin.reproduce import fit, verdict
    from carmkin.reproduce.error_model import ErrorModel

    if args.corner_noise_px is None and args.operator_scale is None and not args.best_fit_only:
        points = ", ".join(f"({c:g} px, {s:g})" for c, s in fit.FIT_REGION)
        return (verdict.region_models(ErrorModel()), fit.FIT_REGION,
                f"judged across the fit's 95 % region ({len(fit.FIT_REGION)} points: {points}; a verdict holds only "
                "where every point gives it, else undetermined)")
    model = _model(args)
    why = "--best-fit-only" if args.best_fit_only and args.corner_noise_px is None and args.operator_scale is None \
        else "a model given by --corner-noise-px / --operator-scale"
    return ([model], ((model.corner_noise_px, model.operator_scale),),
            f"judged at one point ({model.corner_noise_px:g} px, {model.operator_scale:g}: {why}), not across the "
            "fit's 95 % region")


def _grid(text, option: str, default) -> tuple:
    if text is None:
        return default
    values = parse_numbers(text, None, option)
    if values.size == 0 or (values < 0).any():
        raise UsageError(f"{option} must be numbers >= 0 separated by commas, got {text!r}")
    return tuple(float(v) for v in values)


def run(args: argparse.Namespace) -> int:
    if args.png:
        args.png = plot_path(args.png, "--png")
    from tqdm import tqdm

    from carmkin.reproduce import chapter3, error_model, fit, joints, repositioning, stitching, verdict

    system, model, out = system_from_args(args), _model(args), {}
    models, points, judged = _judged_at(args)
    corner_grid = _grid(args.corner_noise_grid_px, "--corner-noise-grid-px", fit.CORNER_NOISE_GRID)
    operator_grid = _grid(args.operator_scale_grid, "--operator-scale-grid", fit.OPERATOR_SCALE_GRID)
    # done/total on a terminal: the tables, then (all) each experiment's verdict rows
    stages = {"all": 5 + len(models) * len(verdict.EXPERIMENTS), "model": 1, "fit": 1}.get(args.table, 1 + len(models))
    bar = tqdm(total=stages, unit="table", desc=f"reproduce {args.table}", leave=False, file=sys.stderr)

    def verdict_of(*names, **options):
        """The verdict rows of ``names`` over --repeats at every model of ``models`` (combined by
        :func:`carmkin.reproduce.verdict.across`), printed with the tally saying where they were judged; kept
        for --json."""
        by_point = []
        for point in models:
            rows = []
            for name in names:
                rows += verdict.EXPERIMENTS[name](system, point, args.repeats, **options)
                bar.update(1)
            by_point.append(rows)
        rows = verdict.across(by_point)
        print(verdict.format_verdict(rows, judged))
        out.setdefault("verdict", []).extend(r.__dict__ for r in rows)
        out["counts"] = verdict.counts([verdict.Row(**r) for r in out["verdict"]])
        out["judged_at"] = {"points": [list(map(float, p)) for p in points], "rule": judged}
        return rows

    if args.table in ("model", "all"):
        print(error_model.format_model(model))
        out["model"] = {name: value for name, value, _ in model.table()}
        bar.update(1)
    if args.table in ("4.6.2", "all"):
        tasks = repositioning.run(system, model, args.tasks, args.seed, end=args.end)
        stats = repositioning.summary(tasks)
        square = error_model.square_pixel_system(system)
        table = joints.decompose(square, tasks)
        print(repositioning.format_summary(stats))
        print(joints.format_decomposition(square, table))
        out["4.6.2"] = {k: v for k, v in stats.items()}
        out["4.6.2 joints"] = {k: (list(map(float, v)) if k != "joints" and hasattr(v, "__len__") else v)
                               for k, v in table.items()}
        bar.update(1)
        if args.png and args.table == "4.6.2":
            joints.plot_decomposition(square, table).savefig(args.png)
            print(f"wrote {args.png}")
        if args.table == "4.6.2":
            verdict_of("4.6.2", end=args.end)
    if args.table == "fit":
        result = fit.fit(system, corner_grid, operator_grid, tasks=args.fit_tasks, seed=args.seed, rotation=args.rotation)
        print(fit.format_fit(result))
        out["fit"] = {"best": [result.best.corner_noise_px, result.best.operator_scale], "chi2": result.best.chi2,
                      "p_value": result.p_value, "reproduced": result.reproduced,
                      "region": [[p.corner_noise_px, p.operator_scale] for p in result.region],
                      "grid": [[p.corner_noise_px, p.operator_scale, p.chi2] for p in result.points]}
        bar.update(1)
        if args.png:
            fit.plot_fit(result).savefig(args.png)
            print(f"wrote {args.png}")
    if args.table in ("4.6.3", "all"):
        rows = stitching.table(stitching.run(system, model, 5, args.seed))
        print(stitching.format_table(rows))
        out["4.6.3"] = rows
        bar.update(1)
        if args.table == "4.6.3":
            verdict_of("4.6.3")
    if args.table in ("3.1", "all"):
        rows = chapter3.table_3_1(system, model, 2, args.seed, protocol=args.protocol)
        print(chapter3.format_table_3_1(rows))
        out["3.1"] = rows
        bar.update(1)
        if args.table == "3.1":
            verdict_of("3.1", protocol=args.protocol)
    if args.table in ("3.2", "all"):
        result = chapter3.table_3_2(system, model, args.seed, protocol=args.protocol)
        print(chapter3.format_table_3_2(result))
        out["3.2"] = result
        bar.update(1)
        if args.table == "3.2":
            verdict_of("3.2", protocol=args.protocol)
    if args.table == "all":
        verdict_of(*verdict.EXPERIMENTS)
    bar.close()
    write_json(args, out)
    return 0
