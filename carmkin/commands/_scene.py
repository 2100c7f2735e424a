"""The scene of a plan on the command line: where the target, the patient and the table top are in the table
frame (printed), and the plan drawn (``--png``: :func:`carmkin.plots.scene_figure`; ``--html``: the viewer with
the patient and the target). Table frame, m in the library and mm on the command line; Y0 points down, so a
point "above the table top" has a smaller Y0 than the top's surface.
"""

from __future__ import annotations

import numpy as np

MM = 1000.0
#: Radius (m) of the sphere that marks the target in the viewer page.
TARGET_MARK_M = 0.012
#: Distance (m) within which the viewer page colours a C-arm part by its distance to the table, patient or floor
#: (as ``carmkin view --margin-mm``'s default).
COLOUR_MARGIN_M = 0.1


def add_patient_arguments(parser, default: str = "parametric") -> None:
    """``--patient parametric|none`` (a body model lying on the table), ``--patient-position CODE`` (DICOM),
    ``--patient-height-mm``, ``--patient-mass-kg``, ``--patient-chest-z-mm``: the flags of ``views`` (docs/cli.md)."""
    from . import _common as common

    parser.add_argument("--patient", choices=("parametric", "none"), default=default,
                        help=f"a parametric patient lying on the table, or none (default {default})")
    parser.add_argument("--patient-position", default="HFS", metavar="CODE", type=common.patient_position,
                        help="DICOM Patient Position (HFS, HFP, HFDR, HFDL, FFS, FFP, FFDR, FFDL; default HFS)")
    parser.add_argument("--patient-height-mm", type=common.number(400.0, 2800.0, unit="mm"), default=1750.0,
                        help="body height (mm, default 1750)")
    parser.add_argument("--patient-mass-kg", type=common.number(1.0, 650.0, unit="kg"), default=75.0,
                        help="body mass (kg, default 75)")
    parser.add_argument("--patient-chest-z-mm", type=common.number(-3000.0, 3000.0, unit="mm"), default=0.0,
                        help="the chest (nipple line) along the table, Z0 (mm, default 0)")


def patient_from_args(system, args):
    """The patient model of :func:`add_patient_arguments`' flags, or ``None``."""
    from carmkin.patient import ParametricPatient

    if args.patient == "none":
        return None
    return ParametricPatient.on_table(system, args.patient_height_mm / MM, args.patient_mass_kg,
                                      args.patient_position, args.patient_chest_z_mm / MM)


def table_top_y(system) -> float:
    """Y0 (m) of the table top's upper surface (Y0 points down: the surface is the top box's smallest Y0)."""
    return float(system.table.top_center[1] - system.table.top_size[1] / 2)


def describe_patient(patient, position: str) -> str:
    """One phrase for the patient model (``None``: no patient)."""
    if patient is None:
        return f"none (angles read for {position})"
    height, mass = getattr(patient, "height", None), getattr(patient, "mass", None)
    if height is not None and mass is not None:
        return (f"parametric, {height * MM:.0f} mm, {mass:g} kg, {getattr(patient, 'position', position)}, lying on "
                "the table top")
    return f"{type(patient).__name__}"


def patient_json(patient, position: str) -> dict:
    """The patient of :func:`describe_patient` for a ``--json`` file: model, position and (parametric) size."""
    if patient is None:
        return {"model": "none", "position": position}
    height, mass = getattr(patient, "height", None), getattr(patient, "mass", None)
    if height is not None and mass is not None:
        return {"model": "parametric", "position": getattr(patient, "position", position), "height_mm": height * MM,
                "mass_kg": float(mass)}
    return {"model": type(patient).__name__, "position": getattr(patient, "position", position)}


def describe_scene(system, target, patient, position: str) -> str:
    """Lines: the target in the table frame and its height over the table top, the table top's Y0, the patient."""
    target = np.asarray(target, dtype=float)
    top = table_top_y(system)
    above = (top - target[1]) * MM
    return "\n".join((
        f"target (table frame): X0 {target[0] * MM:+.1f}, Y0 {target[1] * MM:+.1f}, Z0 {target[2] * MM:+.1f} mm; "
        f"{abs(above):.1f} mm {'above' if above >= 0 else 'below'} the table top",
        f"table top: upper surface at Y0 = {top * MM:+.1f} mm (Y0 points down), {system.table.top_size[0] * MM:.0f} x "
        f"{system.table.top_size[2] * MM:.0f} mm",
        f"patient: {describe_patient(patient, position)}",
    ))


def write_figures(args, system, q, patient, target, title: str = "") -> None:
    """``--png`` (the two orthographic views) and ``--html`` (the viewer page) of the configuration ``q`` (m, rad)
    with the patient, the beam and the target; each path was checked before the work (``carmkin.cli.main``)."""
    from . import _common as common

    if getattr(args, "png", None):
        from carmkin import plots

        path = common.plot_path(args.png, "--png")
        plots.scene_figure(system, q, patient, target, path, title)
        print(f"wrote {path}")
    if getattr(args, "html", None):
        path = common.output_path(args.html, "--html", ("html", "htm"))
        path.write_text(scene_page(system, q, patient, target), encoding="utf-8")
        print(f"wrote {path}")


def scene_page(system, q, patient=None, target=None) -> str:
    """A static viewer page: the C-arm at q with its X-ray cone, the table, the patient and the target; the C-arm
    parts within :data:`COLOUR_MARGIN_M` of the table, patient or floor coloured by distance, and every body the
    C-arm collides with painted red (:meth:`carmkin.viz.CArmViewer.show_distances`)."""
    from carmkin.viz import CArmViewer
    from carmkin.viz.views import draw_patient

    import meshcat.geometry as mg  # noqa: I001 (after carmkin.viz, which imports meshcat quietly)

    viewer = CArmViewer(system, q=q)
    if patient is not None:
        draw_patient(viewer, patient)
    viewer.show_distances(margin=COLOUR_MARGIN_M, patient=patient)  # collisions red, as the text reports them
    if target is not None:
        mark = np.eye(4)
        mark[:3, 3] = target
        viewer.root["target"].set_object(mg.Sphere(TARGET_MARK_M), mg.MeshLambertMaterial(color=0xD62728))
        viewer.root["target"].set_transform(mark)
    return viewer.static_html()
