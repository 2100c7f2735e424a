"""Calibrate a C-arm from phantom images: the kinematic and imaging parameters of the preset fitted to the
views' joint readings and the beads detected in each image (carmkin.calibration; docs/calibration.md).

VIEWS (.csv or .json): per view its name, the joint readings (columns <joint>_mm / <joint>_deg, the preset's
joints) and the detected beads' pixels (bead, u_px, v_px; one CSV row per bead). --phantom (.csv or .json): the
beads' positions in the table frame (bead, x_mm, y_mm, z_mm). Each view's projection is estimated from its
beads (at least 6), then the model is fitted with the phantom's beads as the residual's points. Prints each
fitted parameter with its 1σ, the parameters the views cannot determine (held at nominal, with the reason), the
residual per view, and the views left out as outliers, by name. --save-preset writes the calibrated preset.
Exit 1 when the fit did not converge; 2 for a file it cannot use (naming the file, line or view).
"""

from __future__ import annotations

import argparse

import numpy as np

from . import _common as common

HELP = "calibrate the preset from phantom images: joint readings and detected beads per view"


def register(parser: argparse.ArgumentParser) -> None:
    common.add_preset_argument(parser)
    parser.add_argument("views", metavar="VIEWS", help="the views: .csv (view,<joint>_mm|_deg...,bead,u_px,v_px) "
                                                       "or .json (docs/calibration.md)")
    parser.add_argument("--phantom", metavar="FILE", required=True,
                        help="the phantom's beads in the table frame: .csv (bead,x_mm,y_mm,z_mm) or .json")
    parser.add_argument("--no-outlier-test", action="store_true",
                        help="fit every view (default: views that disagree with the others are left out and named)")
    parser.add_argument("--save-preset", metavar="FILE",
                        help="write the calibrated preset (.toml; load it with --preset FILE)")
    common.add_json_argument(parser, "the estimates with their 1σ, the held parameters, residuals and outlier views")


def run(args: argparse.Namespace) -> int:
    from carmkin.calibration import files
    from carmkin.calibration.fit import identify
    from carmkin.calibration.report import held_reason
    from carmkin.errors import CalibrationError

    if args.save_preset is not None:
        common.output_path(args.save_preset, "--save-preset", ("toml",))  # before any work
    system = common.system_from_args(args)
    phantom = files.read_phantom(args.phantom)
    common.check_unit_slip("--phantom", args.phantom, phantom.points.ravel() * common.MM_PER_M, error=CalibrationError)
    views = files.read_views(args.views, system, phantom)
    readings = views.q * common.to_cli_units(system)
    prismatic = np.asarray(system.prismatic, dtype=bool)
    common.check_unit_slip(f"views {args.views}:", "readings", readings[:, prismatic], readings[:, ~prismatic],
                           error=CalibrationError)
    result = identify(system, views.q, files.projections(phantom, views), points=phantom.points,
                      reject_outliers=not args.no_outlier_test)
    outliers = [views.names[i] for i in result.outliers]
    print(f"preset {system.name}: {len(views.names)} views from {args.views}, phantom {args.phantom}")
    print(result.report(views.names))
    print("residual per view (px RMS at the phantom's beads, after the fit):")
    for name, r in zip(views.names, result.residual_px):
        print(f"  {name:20s} {r:10.4f}" + ("  OUTLIER: left out of the fit" if name in outliers else ""))
    print("outlier views: " + (", ".join(outliers) + " (left out of the fit)" if outliers else "none"))
    if args.save_preset is not None:
        print(f"wrote {result.save_preset(args.save_preset)}")
    common.write_json(args, {
        "preset": system.name, "views": list(views.names), "converged": bool(result.success),
        "fitted": {n: {"unit": u, "value": float(v), "nominal": float(s), "sigma": float(d)}
                   for n, u, v, s, d in zip(result.names, result.units, result.values, result.nominal_values,
                                            result.std)},
        "held": {h.name: held_reason(h) for h in result.identifiability.held},
        "residual_px": {n: float(r) for n, r in zip(views.names, result.residual_px)},
        "residual_before_px": {n: float(r) for n, r in zip(views.names, result.residual_before_px)},
        "outlier_views": outliers, "noise_px": result.noise_px, "dof": result.dof,
        "cautions": [{"kind": w.kind.value, "message": w.message} for w in result.warnings
                     if w.kind.name != "OUTLIER_VIEWS"],
        "covariance_in_parameter_units": np.asarray(result.covariance)})  # rows and columns in the order of "fitted"
    return 0 if result.success else 1
