"""Reproduce the 5- vs 6-DOF workspace study of §4.6.1 (Table 4.5 of the dissertation).

Desired X-ray source poses come from the 6-DOF forward kinematics over the joint grid of §4.6.1 (12285 C-arm
configurations) at each table translation (default 0..400 mm, step 50); the 5-DOF C-arm IK (table fixed,
roll free) is solved for each, and for every C-arm joint the command counts the poses out of range (K) and
the mean, std, max and min of the excess over the closest limit (mm or degrees). It prints Table 4.5 next to
the dissertation's numbers, the fractions of poses reachable within all ranges by the 5-DOF IK and by the
6-DOF model (generating configuration or analytic 6-DOF IK), and optionally writes JSON and a plot.

With ``--table-dofs none|paper|translations|all|compare`` it runs instead the study generalised to multi-DOF
tables (:mod:`carmkin.studies.table_workspace`; preset default ``siremobile-iso-c3d-motorized-table``): the fraction
of ``--poses`` random desired poses reachable with the C-arm alone, + d0, + the three table translations, +
all table joints; JSON ``{"<model>": {"fraction": x, "reached": int, "poses": int}}``.

JSON: {"translations_mm": {"<d0 in mm>": {"<joint>_<unit>": {"K": int, "mean": x, "std": x, "max": x,
"min": x}}}} with joints vertical_mm, wigwag_deg, horizontal_mm, angular_deg, orbital_deg (the statistics in
that unit; K a count).
"""

from __future__ import annotations

import argparse
import sys

from ._common import (
    DEFAULT_PRESET,
    MM_PER_M,
    UsageError,
    add_json_argument,
    add_png_argument,
    add_preset_argument,
    check_unit_slip,
    integer,
    number,
    plot_path,
    system_from_args,
    write_json,
)

#: Preset used by ``--table-dofs`` when ``--preset`` is left at its default.
TABLE_PRESET = "siremobile-iso-c3d-motorized-table"

#: The rows of --table-dofs, as named by carmkin.studies.table_workspace.MODELS (a test keeps them equal).
TABLE_MODELS = ("none", "paper", "translations", "all")

HELP = "5- vs 6-DOF workspace study of §4.6.1 (Table 4.5): joint-range excess of the 5-DOF IK"


def register(parser: argparse.ArgumentParser) -> None:
    add_preset_argument(parser)
    parser.add_argument("--translations-mm", type=number(unit="mm"), nargs="+", default=None,
                        metavar="D0", help="table translations d0 in mm (default: the paper's 0 50 ... 400)")
    add_json_argument(parser, "the per-joint statistics")
    add_png_argument(parser, "excess and K against translation", old_names=("--plot",))
    parser.add_argument("--tolerance", type=number(0.0), default=1e-9,
                        help="excess (m or rad) still counted as inside a range (default 1e-9)")
    parser.add_argument("--table-dofs", choices=(*TABLE_MODELS, "compare"),
                        help="instead of Table 4.5: generalised study over random poses of the full motorized "
                        "table + C-arm, reachable with only the C-arm (none), + d0 (paper), + lateral and height "
                        f"(translations), + tilts and rotation (all), or all four rows (compare); preset "
                        f"defaults to {TABLE_PRESET}")
    parser.add_argument("--poses", type=integer(1), default=300, help="--table-dofs: number of desired poses (default 300)")
    parser.add_argument("--seed", type=integer(0), default=0, help="--table-dofs: random seed of the poses (default 0)")
    parser.add_argument("--random-seeds", type=integer(0), default=6,
                        help="--table-dofs: random QP seeds per pose after the deterministic ones (default 6)")


def _print_table(result) -> None:
    from carmkin.studies import workspace

    print(f"{'quantity':<22}{'d0 (mm)':>8}{'ours':>11}{'dissertation':>14}")
    for quantity, d0, ours, paper in workspace.comparison_rows(result):
        flag = "" if paper in ("—", ours) else "  *"
        joint, stat = quantity.split()
        label = quantity if stat == "K" else f"{quantity} ({workspace.UNITS[joint][0]})"  # K is a count
        print(f"{label:<22}{d0:>8}{ours:>11}{paper:>14}{flag}")
    print("(* differs from the printed value; see docs/errata/workspace.md)")
    keys = "".join(f"{workspace.translation_key(r.translation):>8}" for r in result.results)
    print(f"{'joint':<12}{keys}   (K per d0)")
    for joint in workspace.JOINTS:
        print(f"{joint:<12}" + "".join(f"{r.joints[joint].K:>8d}" for r in result.results))


def run_table_study(args: argparse.Namespace) -> int:
    """The generalised study of :mod:`carmkin.studies.table_workspace`."""
    from tqdm import tqdm

    from carmkin.studies import table_workspace

    if args.preset == DEFAULT_PRESET:
        args.preset = TABLE_PRESET
    system = system_from_args(args)
    models = tuple(table_workspace.MODELS) if args.table_dofs == "compare" else (args.table_dofs,)
    with tqdm(total=args.poses * len(models), unit="solve", desc="workspace", leave=False, file=sys.stderr) as bar:
        _, results = table_workspace.run_study(system, models, n=args.poses, seed=args.seed,
                                               random_seeds=args.random_seeds, progress=bar.update)
    print(f"preset {system.name}: {args.poses} desired poses (position + principal axis, roll free) from "
          f"random in-range collision-free configurations of all {system.nq} joints, seed {args.seed}")
    print("\n".join(table_workspace.table_rows(results)))
    write_json(args, {r.model: {"fraction": r.fraction, "reached": int(r.reached.sum()), "poses": len(r.reached)}
                      for r in results})
    if args.png:
        table_workspace.plot(results, args.png)
        print(f"wrote {args.png}")
    return 0


def run(args: argparse.Namespace) -> int:
    if args.png:
        args.png = plot_path(args.png, "--png")
    if getattr(args, "table_dofs", None):
        return run_table_study(args)
    from tqdm import tqdm

    from carmkin.studies import workspace

    system = system_from_args(args)
    translations = workspace.PAPER_GRID.translations_mm if args.translations_mm is None else args.translations_mm
    d0 = system.joint_ranges[0]
    check_unit_slip("--translations-mm", " ".join(f"{t:g}" for t in translations), translations,
                    ranges_mm=[[d0.lower * MM_PER_M, d0.upper * MM_PER_M]] * len(translations))
    for value in translations:
        if d0.excess(value / MM_PER_M) != 0.0:
            raise UsageError(f"--translations-mm {value:g} is outside the table translation range "
                             f"[{d0.lower * MM_PER_M:g}, {d0.upper * MM_PER_M:g}] mm of preset {system.name!r}")
    grid = workspace.StudyGrid(translations_mm=tuple(translations))
    n = len(grid.configurations()) * len(grid.translations_mm)
    with tqdm(total=n, unit="pose", desc="workspace", leave=False, file=sys.stderr) as bar:
        result = workspace.run_study(system, grid, tolerance=args.tolerance, progress=bar.update)
    print(f"preset {system.name}: {n} poses ({n // len(grid.translations_mm)} per translation), "
          f"{'isocentric closed form' if system.carm.is_isocentric else 'general polynomial'} 5-DOF IK")
    held = system.joint_names[1:system.nq - 5]  # the joints between d0 and the C-arm's five: table (and mount)
    if held:
        print(f"note: preset {system.name} has {system.nq} joints; Table 4.5's study moves only the table translation "
              f"and the C-arm's five and holds {', '.join(held)} at 0, so these are the numbers of its 6-joint chain "
              "(--table-dofs studies the other joints)")
    _print_table(result)
    worst = max(r.max_residual for r in result.results)
    unsolved = sum(r.unsolved for r in result.results)
    print(f"reachable within all ranges: 5-DOF IK {result.fraction_5dof:.2%}, "
          f"6-DOF model {result.fraction_6dof:.2%}")
    print(f"worst FK residual of the chosen 5-DOF solutions {worst:.2e}; poses without a 5-DOF solution: {unsolved}")
    write_json(args, result.as_json())
    if args.png:
        from carmkin.studies import figures

        figures.workspace_excess(result, args.png)
        print(f"wrote {args.png}")
    return 0
