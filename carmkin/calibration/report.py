"""The calibration result as text for people: values and standard deviations in mm, deg and px, the
residual per view, and each held parameter with the reason (sentences rendered from the data, never parsed)."""

from __future__ import annotations

import numpy as np

from .identifiability import Reason


def render(result, view_names=None) -> str:
    """Lines: one per fitted parameter (estimate, change from nominal, 1σ), one per held parameter, then the
    residual (RMS per view before and after, the noise it implies), then one per caution (outlier views left
    out, by ``view_names`` when given, else by index; joints the views do not move)."""
    lines = [f"fitted {len(result.names)} parameters from {len(result.residual_px)} views "
             f"({'converged' if result.success else 'NOT converged: ' + result.message})"]
    for name, unit, value, start, std in zip(result.names, result.units, result.values, result.nominal_values,
                                             result.std):
        lines.append(f"  {name:32s} {value:+14.4f} {unit:3s}  (nominal {start:+.4f}, change {value - start:+.4f}, "
                     f"1σ {std:.2g} {unit})")
    for held in result.identifiability.held:
        lines.append(f"  {held.name:32s} held at nominal: {held_reason(held)}")
    lines.append(f"residual per view (RMS over its reference points): nominal {np.median(result.residual_before_px):.3g} px"
                 f" median, fitted {np.median(result.residual_px):.3g} px median, {result.residual_px.max():.3g} px max;"
                 f" noise implied s = {result.noise_px:.3g} px ({result.dof} degrees of freedom)")
    for warning in result.warnings:
        message = warning.message
        if view_names is not None and warning.kind.name == "OUTLIER_VIEWS":
            message = ("views " + ", ".join(f"{view_names[i]} ({result.residual_px[i]:.3g} px RMS against the fit)"
                                            for i in result.outliers)
                       + " disagree with the others and were left out of the fit")
        lines.append(f"caution ({warning.kind.value}): {message}")
    return "\n".join(lines)


def held_reason(held) -> str:
    """Why a parameter is held, in words."""
    if held.reason is Reason.NO_EFFECT:
        return "these views do not see it (its change moves no reference point)"
    same = " + ".join(f"{amount:.3g} × {name}" for name, amount in held.equivalent)
    return f"not separable from {same} (one unit of it moves the projections as that does; separation {held.separation:.1g})"
