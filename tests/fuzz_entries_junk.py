"""Fuzz entry points of issue 31: junk of every Python type for every public argument of the studies
(``reproduce``), the sweeps and their exports, the parametric patient, the QP's options and call arguments,
the singularity maps and the presets; failed sweeps (their exports must be refused); current configurations
past a joint's range on every preset (``qp_ik.solve`` and ``plan_view`` never answer success with a joint
out of range).

Oracles, written here and not taken from the code under test: a junk argument must raise a
:class:`carmkin.CarmkinError` whose message names it (:func:`fuzz_junk.junk_argument`); a valid call's
answer is checked by FK and the joint ranges read off the system (``lower``/``upper`` with
:data:`carmkin.model.params.JOINT_RANGE_TOLERANCE`), the segment volumes of a body computed from their
shapes, the table top's box read from the preset, and the sweep's frames (ASTRA rows rebuilt from the poses).
"""

from __future__ import annotations

import math
import tempfile
from pathlib import Path

import fuzz_geometry as g
import numpy as np
from fuzz_engine import Case
from fuzz_entries_systems import PRESET, _q, _system
from fuzz_junk import junk_argument, maybe_junk_argument

import carmkin
from carmkin.model.params import JOINT_RANGE_TOLERANCE


def _in_range(system, q) -> bool:
    q = np.asarray(q, dtype=float)
    return bool(q.shape == (system.nq,) and np.all(np.isfinite(q)) and np.all(q >= system.lower - JOINT_RANGE_TOLERANCE)
                and np.all(q <= system.upper + JOINT_RANGE_TOLERANCE))


def _pick(rng, values):
    return values[int(rng.integers(0, len(values)))]


# --- reproduce ------------------------------------------------------------------------------------------------
def _model():
    from carmkin.reproduce.error_model import ErrorModel

    return ErrorModel()


def reproduce_run(rng):
    from carmkin.reproduce import repositioning

    tasks = 1
    case = Case(repositioning.run, (), {"system": PRESET, "model": _model(), "tasks": tasks,
                                        "seed": int(rng.integers(0, 100)), "end": _pick(rng, repositioning.ENDS)},
                check=lambda r: len(r) == tasks)
    return maybe_junk_argument(rng, case, {"system": "system", "model": "model", "tasks": "count", "seed": "seed",
                                           "end": "name", "guidance": "model?"}, fraction=0.9)


def reproduce_stitching(rng):
    from carmkin.reproduce import stitching

    case = Case(stitching.run, (), {"system": PRESET, "model": _model(), "procedures": 1,
                                    "seed": int(rng.integers(0, 100))}, check=lambda r: len(r) == 1)
    return maybe_junk_argument(rng, case, {"system": "system", "model": "model", "procedures": "count",
                                           "seed": "seed", "guidance": "model?"}, fraction=0.9)


def reproduce_table_3_1(rng):
    from carmkin.reproduce import chapter3

    k = 1

    def check(rows):  # one row per procedure and the overall row, whose marker counts add up
        return set(rows) == {"#1", "overall"} and all(rows["overall"][i][2] == rows["#1"][i][2] for i in (0, 1))
    case = Case(chapter3.table_3_1, (), {"system": PRESET, "model": _model(), "procedures": k,
                                         "seed": int(rng.integers(0, 100)), "protocol": _pick(rng, chapter3.PROTOCOLS)},
                check=check)
    return maybe_junk_argument(rng, case, {"system": "system", "model": "model", "procedures": "count",
                                           "seed": "seed", "protocol": "name", "guidance": "model?"}, fraction=0.9)


def reproduce_fit(rng):
    from carmkin.reproduce import fit

    case = Case(fit.fit, (), {"system": PRESET, "corner_noise": [0.0], "operator_scale": [0.0], "tasks": 3,
                              "seed": 0, "resamples": 2, "rotation": _pick(rng, fit.ROTATIONS)},
                check=lambda r: len(r.points) <= 1)
    spec = {"system": "system", "corner_noise": "grid", "operator_scale": "grid", "tasks": "count",
            "seed": "seed", "resamples": "count", "rotation": "name", "base": "model", "progress": "model?"}
    return maybe_junk_argument(rng, case, spec, fraction=0.9)


def reproduce_verdict(rng):
    from carmkin.reproduce import verdict

    def check(rows):  # Table 3.2: twelve numbers (four values by three methods), each judged
        return len(rows) == 12 and all(r.verdict in ("reproduced", "not reproduced", "undetermined") for r in rows)
    case = Case(verdict.verdict, (), {"system": PRESET, "model": _model(), "repeats": 2, "experiments": ("3.2",)},
                check=check)
    spec = {"system": "system", "model": "model", "repeats": "count", "experiments": "name"}
    return maybe_junk_argument(rng, case, spec, {"repeats": (("1", lambda: 1), ("0", lambda: 0))}, fraction=0.9)


def reproduce_judge(rng):
    from carmkin.reproduce import verdict

    seed = float(rng.uniform(0.1, 10))
    values = rng.normal(seed, 1.0, int(rng.integers(2, 9)))
    case = Case(verdict.judge, (), {"experiment": "x", "quantity": "y", "seed": seed, "values": values,
                                    "kind": _pick(rng, verdict.KINDS)}, check=lambda row: row.seed == seed)
    return maybe_junk_argument(rng, case, {"seed": "real", "values": "repeats", "kind": "name"})


def error_model(rng):
    from dataclasses import fields

    from carmkin.reproduce.error_model import ErrorModel

    names = [f.name for f in fields(ErrorModel)]
    value = {n: float(rng.uniform(0, 0.01)) for n in names if n not in ("frames", "calibration_positions")}
    value.update(frames=int(rng.integers(1, 10)), calibration_positions=int(rng.integers(3, 10)))
    case = Case(ErrorModel, (), value, check=lambda m: all(getattr(m, n) == value[n] for n in names))
    spec = {n: ("count" if n in ("frames", "calibration_positions") else "real") for n in names}
    return maybe_junk_argument(rng, case, spec, {n: (("-1", lambda: -1.0),) for n in names})


# --- sweeps ---------------------------------------------------------------------------------------------------
def _astra_rows(sweep, scale):
    """ASTRA cone_vec rows rebuilt from the frames' poses and the detector read off the preset."""
    carm = sweep.system.carm
    K = carm.intrinsics()
    sx, sy = carm.pixel_spacing
    rows = []
    for T in sweep.poses:
        s, x, y, z = T[:3, 3], T[:3, 0], T[:3, 1], T[:3, 2]
        centre = (s + carm.source_to_detector * z + ((carm.detector_columns - 1) / 2 - K[0, 2]) * sx * x
                  + ((carm.detector_rows - 1) / 2 - K[1, 2]) * sy * y)
        rows.append(np.r_[s, centre, sx * x, sy * y] * scale)
    return np.array(rows)


def _sweep_is_right(system, sweep, target, margin) -> bool:
    """A successful sweep: every frame in range, the target on the principal axis at the distance, clear of
    the table by the margin (the world's exact distance); a failed one: a failure and refused exports."""
    from carmkin.world import World

    if not sweep.success:
        return sweep.failure is not None and _exports_refused(sweep)
    world = World(system)
    for q, T in zip(sweep.q, sweep.poses):
        w = np.asarray(target) - T[:3, 3]
        if not _in_range(system, q) or not g.close(system.fk(q), T, atol=1e-9):
            return False
        if sweep.compensated and (np.linalg.norm(w - (w @ T[:3, 2]) * T[:3, 2]) > 1e-6
                                 or abs(w @ T[:3, 2] - sweep.distance) > 1e-6):
            return False
        if world.clearance(q)[0] < margin - 1e-9:
            return False
    return True


EXPORTS = ("astra_vectors", "tigre_geometry", "positioner_angles", "rtk_frames", "pixel_from_detector",
           "rtk_projection_grid", "rtk_detector_axes", "write_rtk_xml")


def _exports_refused(sweep) -> bool:
    """Every export of a failed sweep raises SweepError, and write_rtk_xml writes no file."""
    from carmkin.errors import SweepError
    from carmkin.sweeps import export

    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "g.xml"
        for name in EXPORTS:
            try:
                getattr(export, name)(sweep, *((path,) if name == "write_rtk_xml" else ()))
            except SweepError:
                continue
            return False
        return not path.exists()


def plan_a_sweep(rng):
    from carmkin.sweeps import plan_sweep

    system = _system(rng)
    target = rng.normal(size=3) * float(rng.choice([0.0, 0.02, 0.1]))
    arc = float(rng.choice([30.0, 120.0, 190.0, 240.0, 360.0]))  # 240 and 360: past the orbital range (fail)
    n = int(rng.integers(2, 12))
    margin = float(rng.choice([0.0, 0.01, 0.05]))
    kwargs = {"system": system, "target": target, "arc_deg": arc, "n_views": n, "margin": margin,
              "joint": _pick(rng, ["orbital", "angular", {"orbital": 1.0, "angular": 0.3}]),
              "compensate": bool(rng.random() < 0.7)}
    case = Case(plan_sweep, (), kwargs, check=lambda s: _sweep_is_right(system, s, target, margin))
    spec = {"system": "system", "target": "vector:3", "arc_deg": "real", "n_views": "count", "margin": "real",
            "tolerance": "real", "distance": "real?", "compensate": "flag", "joint": "name",
            "q_start": f"vector:{system.nq}?", "patient": "name?"}
    extra = {"arc_deg": (("0", lambda: 0.0), ("-10", lambda: -10.0)), "n_views": (("1", lambda: 1),),
             "margin": (("-0.01", lambda: -0.01),), "joint": (("prismatic", lambda: "vertical"),
                                                               ("bool weight", lambda: {"orbital": True}),
                                                               ("str weight", lambda: {"orbital": "1"}),
                                                               ("complex weight", lambda: {"orbital": 1j}),
                                                               ("nan weight", lambda: {"orbital": math.nan}))}
    return maybe_junk_argument(rng, case, spec, extra, fraction=0.4)


_SWEEPS: dict = {}


def _planned(system, arc):
    from carmkin.sweeps import plan_sweep

    key = (system.name, arc)
    if key not in _SWEEPS:
        _SWEEPS[key] = plan_sweep(system, np.zeros(3), arc, 8)
    return _SWEEPS[key]


def sweep_export(rng):
    from carmkin.sweeps import export

    system = _system(rng)
    sweep = _planned(system, float(rng.choice([190.0, 360.0])))
    scale = float(rng.choice([1.0, 1e3, 0.5]))
    if not sweep.success:  # a failed sweep: every export refused, no file written
        return Case(_exports_refused, (sweep,), check=lambda r: r is True)
    which = _pick(rng, ("astra", "tigre", "positioner", "rtk_frames", "grid", "xml"))
    if which == "astra":
        case = Case(export.astra_vectors, (), {"sweep": sweep, "scale": scale}, check=lambda r: g.close(
            r, _astra_rows(sweep, scale), rtol=1e-9, atol=1e-9 * scale))
        spec = {"sweep": "model", "scale": "real"}
    elif which == "tigre":
        case = Case(export.tigre_geometry, (), {"sweep": sweep, "scale": scale, "volume_centre": np.zeros(3)},
                    check=lambda r: g.close(r["DSD"], np.full(sweep.n_views, system.carm.source_to_detector * scale)))
        spec = {"sweep": "model", "scale": "real", "volume_centre": "vector:3?"}
    elif which == "positioner":
        case = Case(export.positioner_angles, (), {"sweep": sweep, "patient": "HFS"},
                    check=lambda r: r.shape == (sweep.n_views, 3) and bool(np.all(np.isfinite(r))))
        spec = {"sweep": "model", "patient": "name"}
    elif which == "rtk_frames":
        case = Case(export.rtk_frames, (), {"sweep": sweep, "scale": scale, "layout": "image"},
                    check=lambda r: g.close(r[0], sweep.poses[:, :3, 3] * scale))
        spec = {"sweep": "model", "scale": "real", "layout": "name", "geometry_only": "flag"}
    elif which == "grid":
        case = Case(export.rtk_projection_grid, (), {"sweep": sweep, "scale": scale, "layout": "image"},
                    check=lambda r: r[2] == (system.carm.detector_columns, system.carm.detector_rows, sweep.n_views))
        spec = {"sweep": "model", "scale": "real", "layout": "name", "geometry_only": "flag"}
    else:
        folder = tempfile.mkdtemp()
        path = Path(folder) / "g.xml"
        case = Case(export.write_rtk_xml, (), {"sweep": sweep, "path": path, "scale": scale},
                    check=lambda r: path.exists() and path.stat().st_size > 0)
        spec = {"sweep": "model", "scale": "real", "layout": "name"}
    extra = {"scale": (("0", lambda: 0.0), ("-1000", lambda: -1e3))}
    return maybe_junk_argument(rng, case, spec, extra)


# --- patient ----------------------------------------------------------------------------------------------------
def _volumes(patient) -> tuple[float, float]:
    """(volume of the segments from their shapes, volume their masses need at Winter's densities), m³."""
    from carmkin.patient import body

    have = 0.0
    for s in patient.segments:
        if s.shape == "box":
            have += float(np.prod(s.extents))
        else:  # a capsule of total length L = |b − a| (caps included): cylinder of L − 2r and a ball
            L, r = float(np.linalg.norm(np.subtract(s.b, s.a))), s.radius
            have += math.pi * r * r * (L - 2 * r) + 4 / 3 * math.pi * r ** 3
    need = sum(body.MASS_FRACTIONS[s.name.rsplit("_", 1)[0] if s.name not in body.MASS_FRACTIONS else s.name]
               * patient.mass / body.DENSITIES[s.name.rsplit("_", 1)[0] if s.name not in body.DENSITIES else s.name]
               for s in patient.segments)
    return have, need


def parametric_patient(rng):
    from carmkin.patient import ParametricPatient

    height, mass = float(rng.uniform(0.4, 2.8)), float(10 ** rng.uniform(0, math.log10(650)))

    def check(p):  # accepted: the segments hold (at least VOLUME_SHARE of) the volume the mass needs
        from carmkin.patient.body import VOLUME_SHARE

        have, need = _volumes(p)
        return have >= VOLUME_SHARE * need and p.height == height and p.mass == mass
    case = Case(ParametricPatient, (), {"height": height, "mass": mass, "position": _pick(rng, ["HFS", "FFP", "HFDL"]),
                                        "origin": tuple(rng.normal(size=3)), "arms": _pick(rng, ["side", "up"])},
                check=check)
    spec = {"height": "real", "mass": "real", "position": "name", "origin": "vector:3", "arms": "name"}
    extra = {"height": (("mm", lambda: 1750.0),), "mass": (("0", lambda: 0.0),)}
    case = maybe_junk_argument(rng, case, spec, extra, fraction=0.5)
    if case.junk is None and rng.random() < 0.3:  # far too heavy for its height: must be refused
        kwargs = {**case.kwargs, "height": float(rng.uniform(0.4, 0.6)), "mass": float(rng.uniform(300, 650))}
        return Case(ParametricPatient, (), kwargs, junk="mass (its volume far below its mass)", named="mass")
    return case


def patient_on_table(rng):
    from carmkin.patient import ParametricPatient

    system = _system(rng)
    top_y = system.table.top_center[1] - system.table.top_size[1] / 2  # Y0 down: the top surface
    half_length = system.table.top_size[2] / 2
    chest_z = float(rng.uniform(-0.3, 0.3))

    def check(p):  # resting on the top: its lowest point on the surface, its trunk over the top
        points = p.surface_points()
        return abs(points[:, 1].max() - top_y) < 1e-9 and abs(p.origin[2] - system.table.top_center[2] - chest_z) < 1e-9
    case = Case(ParametricPatient.on_table, (), {"system": system, "chest_z": chest_z, "lateral_x": 0.0}, check=check)
    spec = {"system": "system", "chest_z": "real", "lateral_x": "real", "height": "real", "mass": "real",
            "position": "name", "arms": "name"}
    off = half_length + 2.9  # farther than any body is long: the whole body beyond the table's end
    extra = {"chest_z": (("off the end", lambda: off), ("off the other end", lambda: -off)),
             "lateral_x": (("off the side", lambda: 3.0),)}
    return maybe_junk_argument(rng, case, spec, extra, fraction=0.5)


def _lifted(rng, system):
    """A patient placed by origin: resting on the top (lift 0) or floating 5 cm to 2 m above it (Y0 is down)."""
    from carmkin.patient import ParametricPatient

    resting = ParametricPatient.on_table(system)
    lift = float(rng.choice([0.0, 0.05, 0.5, 2.0]))
    return lift, ParametricPatient(origin=(resting.origin[0], resting.origin[1] - lift, resting.origin[2]))


def floating_patient(rng):
    """A world or a sweep with a patient: resting on the top is accepted; floating above it is refused."""
    from carmkin.sweeps import plan_sweep
    from carmkin.world import World

    system = _system(rng)
    lift, patient = _lifted(rng, system)
    if rng.random() < 0.5:
        case = Case(World, (system, patient), check=lambda w: len(w.obstacles) == len(patient.obstacles()))
    else:
        case = Case(plan_sweep, (system, np.zeros(3), 30.0, 3, patient), check=lambda s: [o.name for o in s.obstacles] == [
            o.name for o in patient.obstacles()])
    if lift == 0.0:
        return case
    return Case(case.fn, case.args, junk=f"patient (floating {lift} m above the table)", named="patient")


def plan_view_floating_patient(rng):
    """plan_view with a patient floating above the table: refused (as by the world and the sweeps)."""
    from carmkin.views import View, plan_view

    system = _system(rng)
    lift, patient = _lifted(rng, system)
    view = View.from_angles(float(rng.uniform(-60, 60)), float(rng.uniform(-30, 30)), np.zeros(3))
    case = Case(plan_view, (system, view, patient), {"nearest": False},
                check=lambda plan: not plan.success or _in_range(system, plan.q))
    if lift == 0.0:
        return case
    return Case(case.fn, case.args, case.kwargs, junk=f"patient (floating {lift} m above the table)", named="patient")


# --- qp ---------------------------------------------------------------------------------------------------------
def qp_options(rng):
    from dataclasses import fields

    from carmkin.qp_ik import QPIKOptions

    names = [f.name for f in fields(QPIKOptions)]
    counts = ("max_iterations", "progress_window")
    case = Case(QPIKOptions, (), {"max_iterations": int(rng.integers(1, 200)), "max_step": float(rng.uniform(0.01, 1))},
                check=lambda o: isinstance(o, QPIKOptions))
    spec = {n: ("count" if n in counts else "real") for n in names}
    extra = {n: (("-1", lambda: -1.0),) for n in names if n != "safety_margin"}
    return maybe_junk_argument(rng, case, spec, extra, fraction=0.7)


def _past_range(rng, system, q):
    """``q`` with one joint past its range by 1e-6 m/rad to 0.5 (beyond the range tolerance)."""
    q = q.copy()
    j = int(rng.integers(0, system.nq))
    step = float(rng.choice([1e-6, 1e-4, 0.01, 0.5])) + 2 * JOINT_RANGE_TOLERANCE
    q[j] = system.upper[j] + step if rng.random() < 0.5 else system.lower[j] - step
    return q


def qp_solve_args(rng):
    from carmkin import qp_ik

    system = _system(rng)
    T = system.fk(_q(rng, system))
    q_current = _q(rng, system)
    out_of_range = rng.random() < 0.3
    if out_of_range:
        q_current = _past_range(rng, system, q_current)

    def check(result):  # never success with a joint out of range; success reaches the target
        return not result.success or (_in_range(system, result.q) and g.close(system.fk(result.q), T, atol=1e-5))
    kwargs = {"system": system, "target": T, "q_current": q_current, "random_seeds": 0}
    case = Case(qp_ik.solve, (), kwargs, check=check)
    if out_of_range:
        return case
    spec = {"q_current": f"vector:{system.nq}?", "options": "model", "random_seeds": "count?", "rng_seed": "seed",
            "closed_form": "flag", "qp": "flag", "record": "flag", "prefer": "name?", "weights": f"vector:{system.nq}?",
            "seeds": "model?", "obstacles": "model?", "backend": "name?"}
    return maybe_junk_argument(rng, case, spec, fraction=0.5)


def plan_view_out_of_range(rng):
    from carmkin.views import View, plan_view

    system = _system(rng)
    view = View.from_angles(float(rng.uniform(-90, 90)), float(rng.uniform(-45, 45)), rng.normal(size=3) * 0.05)
    q_current = _q(rng, system)
    if rng.random() < 0.5:  # past a joint's range: refused, or never a success with a joint out of range
        q_current = _past_range(rng, system, q_current)

    def check(plan):
        return not plan.success or _in_range(system, plan.q)
    return Case(plan_view, (system, view), {"q_current": q_current, "nearest": False}, check=check)


# --- singularity ------------------------------------------------------------------------------------------------
def singularity_args(rng):
    from carmkin import singularity as sing

    system = _system(rng)
    q = _q(rng, system)
    which = _pick(rng, ("map", "classify", "check", "scaled", "curves"))
    if which == "map":
        n = int(rng.integers(2, 5))
        case = Case(sing.measure_map, (), {"system": system, "q": q, "pair": (0, system.nq - 1), "n": n,
                                           "measure": "det"}, check=lambda r: r[2].shape == (n, n))
        spec = {"q": f"vector:{system.nq}", "n": "count", "measure": "name", "length": "real?", "pair": "name"}
    elif which == "classify":
        case = Case(sing.classify, (), {"system": PRESET, "q": q[:6] if system is PRESET else _q(rng, PRESET)},
                    check=lambda r: r.rank <= 6)
        spec = {"near": "real", "tol": "real", "length": "real?", "rtol": "real"}
    elif which == "check":
        case = Case(sing.check_determinant, (), {"system": PRESET, "samples": 3, "seed": 0},
                    check=lambda r: 0 <= r < 1e-9)
        spec = {"samples": "count", "random_setups": "count", "seed": "seed"}
    elif which == "scaled":
        length = float(rng.choice([0.01, 0.625, 10.0]))
        case = Case(sing.scaled_jacobian, (), {"system": system, "q": q, "length": length},
                    check=lambda J: J.shape == (6, system.nq))
        spec = {"length": "real?", "q": f"vector:{system.nq}"}
    else:
        case = Case(sing.singular_curves, (), {"system": system, "pair": (system.nq - 2, system.nq - 1), "q": q},
                    check=lambda r: isinstance(r, list))
        spec = {"pair": "name", "q": f"vector:{system.nq}?"}
    return maybe_junk_argument(rng, case, spec, {"n": (("1", lambda: 1),)})


# --- presets ----------------------------------------------------------------------------------------------------
def _shipped(name):
    import tomllib
    from importlib import resources

    return tomllib.loads((resources.files("carmkin.presets") / f"{name}.toml").read_text())


def _leaves(data, prefix=()):
    for key, value in data.items():
        if isinstance(value, dict):
            yield from _leaves(value, prefix + (key,))
        else:
            yield prefix + (key,), value


def preset_fields(rng):
    """The shipped preset with one field replaced by junk of every type: refused naming the field."""
    import copy

    from carmkin.presets import system_from_dict

    name = _pick(rng, ["siremobile-iso-c3d", "siremobile-iso-c3d-motorized-table"])
    data = _shipped(name)
    leaves = [(path, v) for path, v in _leaves(data) if path[-1] not in ("name", "description", "base", "source")
              and not isinstance(v, str)]
    if rng.random() < 0.2:
        expected = carmkin.load_preset(name)
        return Case(system_from_dict, (data,), check=lambda s: s.carm == expected.carm and s.nq == expected.nq)
    path, value = leaves[int(rng.integers(0, len(leaves)))]
    kind = "vector:%d" % len(value) if isinstance(value, list) else "real"
    from fuzz_junk import wrong_for

    table = wrong_for(kind)
    label, make = table[int(rng.integers(0, len(table)))]
    data = copy.deepcopy(data)
    node = data
    for key in path[:-1]:
        node = node[key]
    node[path[-1]] = make()
    return Case(system_from_dict, (data,), junk=f"{'.'.join(path)} ({label})", named=path[-1])


def load_junk_preset(rng):
    from carmkin.presets import load_preset

    case = Case(load_preset, (), {"name_or_path": "siremobile-iso-c3d"}, check=lambda s: s.nq == 6)
    return maybe_junk_argument(rng, case, {"name_or_path": "name"}, fraction=0.8,
                               named={"name_or_path": "preset"})


ENTRIES = {
    "reproduce.repositioning.run": (reproduce_run, 0.05), "reproduce.stitching.run": (reproduce_stitching, 0.05),
    "reproduce.chapter3.table_3_1": (reproduce_table_3_1, 0.05), "reproduce.fit.fit": (reproduce_fit, 0.1),
    "reproduce.verdict.verdict": (reproduce_verdict, 0.1), "reproduce.verdict.judge": (reproduce_judge, 0.5),
    "reproduce.ErrorModel": (error_model, 0.5), "sweeps.plan_sweep": (plan_a_sweep, 1),
    "sweeps.export": (sweep_export, 1), "patient.ParametricPatient": (parametric_patient, 0.5),
    "patient.ParametricPatient.on_table": (patient_on_table, 0.5), "patient.floating": (floating_patient, 0.5),
    "qp.QPIKOptions": (qp_options, 0.5), "qp_ik.solve (arguments, q_current past a range)": (qp_solve_args, 1),
    "views.plan_view (q_current past a range)": (plan_view_out_of_range, 0.5),
    "views.plan_view (patient floating above the table)": (plan_view_floating_patient, 0.2),
    "singularity (arguments)": (singularity_args, 0.5), "presets.system_from_dict (fields)": (preset_fields, 0.5),
    "presets.load_preset (junk)": (load_junk_preset, 0.3),
}


# --- the rest of the public arguments of these modules ----------------------------------------------------------
_ROOM = None


def reproduce_room_steps(rng):
    """One room (made once), its public steps with junk: make_room's rng and calibrate, a task's end, a
    procedure's overlap, the metric measurements' overlap."""
    global _ROOM
    from carmkin.reproduce import chapter3, repositioning, stitching

    _ROOM = _ROOM or repositioning.make_room(PRESET, _model(), np.random.default_rng(0))
    which = _pick(rng, ("room", "task", "procedure", "metric"))
    if which == "room":
        case = Case(repositioning.make_room, (), {"system": PRESET, "model": _model(), "rng": np.random.default_rng(1),
                                                  "calibrate": bool(rng.random() < 0.5)},
                    check=lambda room: room.system.nq == PRESET.nq)
        return junk_argument(rng, case, {"rng": "rng", "calibrate": "flag"}) if rng.random() < 0.8 else case
    if which == "task":
        case = Case(repositioning.run_task, (), {"room": _ROOM, "rng": np.random.default_rng(2), "end": "box"},
                    check=lambda task: task.image_errors.ndim == 1)
        return maybe_junk_argument(rng, case, {"room": "model", "rng": "rng", "end": "name"}, fraction=0.8)
    if which == "procedure":
        case = Case(stitching.run_procedure, (), {"room": _ROOM, "rng": np.random.default_rng(3), "overlap": 0.1},
                    check=lambda p: p.success in (True, False) and (p.success or bool(p.reason)))
        return maybe_junk_argument(rng, case, {"room": "model", "rng": "rng", "overlap": "real"},
                                   {"overlap": (("1.5", lambda: 1.5), ("-0.1", lambda: -0.1))}, fraction=0.8)
    case = Case(chapter3.metric_measurements, (), {"room": _ROOM, "rng": np.random.default_rng(4), "overlap": 0.1},
                check=lambda r: set(r) == {"A", "B", "C"} and all(len(v) == 4 for v in r.values()))
    return maybe_junk_argument(rng, case, {"room": "model", "rng": "rng", "overlap": "real", "protocol": "name"},
                               {"overlap": (("1.5", lambda: 1.5), ("-0.1", lambda: -0.1))}, fraction=0.8)


def singularity_more(rng):
    from carmkin import singularity as sing

    system = _system(rng)
    q = _q(rng, system)
    which = _pick(rng, ("jacobian", "jacobians", "length", "scaling", "axes", "distances", "grid"))
    if which == "jacobian":
        case = Case(sing.jacobian, (), {"system": system, "q": q}, check=lambda J: g.close(
            J, __import__("fuzz_entries_systems")._pin_jacobian(system, q), atol=1e-9))
        spec = {"system": "system", "q": f"vector:{system.nq}", "reference_frame": "name"}
    elif which == "jacobians":
        Q = np.stack([q, _q(rng, system)])
        case = Case(sing.jacobians, (), {"system": system, "q": Q}, check=lambda J: J.shape == (2, 6, system.nq))
        spec = {"system": "system", "reference_frame": "name"}
    elif which == "length":
        case = Case(sing.characteristic_length, (), {"system": system}, check=lambda L: L > 0)
        spec = {"system": "system"}
    elif which == "scaling":
        length = float(rng.choice([0.01, 1.0]))
        case = Case(sing.scaling, (), {"system": system, "length": length}, check=lambda r: g.close(
            r[0], [1 / length] * 3 + [1.0] * 3))
        spec = {"system": "system", "length": "real?"}
    elif which == "axes":
        case = Case(sing.joint_axes, (), {"system": PRESET, "q": _q(rng, PRESET)}, check=lambda a: a.shape[-1] == 3)
        spec = {"system": "system", "q": "vector:6"}
    elif which == "distances":
        case = Case(sing.singularity_distances, (), {"system": PRESET, "q": _q(rng, PRESET)},
                    check=lambda d: len(d) == 3)
        spec = {"system": "system", "q": "vector:6"}
    else:
        n = int(rng.integers(2, 40))
        case = Case(sing.grid_axis, (), {"system": system, "joint": "orbital", "n": n}, check=lambda x: len(x) == n)
        spec = {"system": "system", "joint": "joint", "n": "count"}
    return maybe_junk_argument(rng, case, spec)


def presets_more(rng):
    from carmkin.presets import parse_preset, preset_provenance, system_from_dict
    from carmkin.presets.writer import save_preset, to_toml

    which = _pick(rng, ("parse", "provenance", "save", "dict"))
    if which == "parse":
        text = to_toml(PRESET)
        case = Case(parse_preset, (), {"text": text, "source": "fuzz"}, check=lambda s: s.carm == PRESET.carm)
        # a text that is no preset is refused naming its source (the label the user gave it)
        return maybe_junk_argument(rng, case, {"text": "name", "source": "label"}, named={"text": "fuzz"})
    if which == "provenance":
        case = Case(preset_provenance, (), {"name_or_path": "siremobile-iso-c3d"}, check=lambda p: len(p) > 0)
        return maybe_junk_argument(rng, case, {"name_or_path": "name"}, named={"name_or_path": "preset"})
    if which == "save":
        path = Path(tempfile.mkdtemp()) / "p.toml"
        case = Case(save_preset, (), {"system": PRESET, "path": path},
                    check=lambda p: carmkin.load_preset(p).carm == PRESET.carm)
        return maybe_junk_argument(rng, case, {"system": "system"})
    case = Case(system_from_dict, (), {"data": _shipped("siremobile-iso-c3d"), "default_name": "x", "source": "y"},
                check=lambda s: s.nq == 6)
    return maybe_junk_argument(rng, case, {"default_name": "label", "source": "label"})


def qp_targets(rng):
    from carmkin.qp_ik import AimTarget, AxisTarget

    if rng.random() < 0.5:
        p, d = rng.normal(size=3), g.unit(rng)
        case = Case(AxisTarget, (), {"position": p, "direction": d}, check=lambda t: g.close(t.position, p))
        return maybe_junk_argument(rng, case, {"position": "vector:3", "direction": "vector:3"},
                                   {"direction": (("zero", lambda: np.zeros(3)),)})
    p, lo = rng.normal(size=3), float(rng.uniform(0.1, 1))
    case = Case(AimTarget, (), {"point": p, "distance_range": (lo, lo + 0.2)}, check=lambda t: g.close(t.point, p))
    return maybe_junk_argument(rng, case, {"point": "vector:3", "distance_range": "vector:2"},
                               {"distance_range": (("reversed", lambda: (1.0, 0.5)), ("negative", lambda: (-1.0, 0.5)))})


def patient_more(rng):
    system = _system(rng)
    patient = ParametricPatientOnTable(system)
    which = _pick(rng, ("obstacles", "pose", "centre"))
    if which == "obstacles":
        prefix = _pick(rng, ["patient", "p"])
        case = Case(patient.obstacles, (), {"prefix": prefix}, check=lambda obs: all(
            o.name.startswith(prefix + "_") for o in obs) and len(obs) == len(patient.segments))
        return _prefix_junk(rng, case)
    if which == "pose":
        return Case(patient.pose, check=lambda T: g.is_rotation(T[:3, :3]) and g.close(T[:3, 3], patient.origin))
    return Case(patient.centre_of_mass, check=lambda c: abs(c[2] - patient.origin[2]) < 0.5)


def ParametricPatientOnTable(system):
    from carmkin.patient import ParametricPatient

    return ParametricPatient.on_table(system)


def _prefix_junk(rng, case):
    """A prefix of obstacle names: a string; junk of other types is refused."""
    from fuzz_junk import ANY, OBJECT

    if rng.random() < 0.5:
        return case
    label, make = _pick(rng, tuple(item for item in ANY + OBJECT if item[0] != "str"))
    return Case(case.fn, case.args, {"prefix": make()}, None, f"prefix ({label})", named="prefix")


ENTRIES.update({
    "reproduce (room, task, procedure, metric)": (reproduce_room_steps, 0.1),
    "singularity (jacobians, scaling, axes, grid)": (singularity_more, 0.5),
    "presets (parse, provenance, save)": (presets_more, 0.3), "qp targets": (qp_targets, 0.5),
    "patient (obstacles, pose, centre of mass)": (patient_more, 0.3),
})


def cli_failed_sweep(rng):
    """``carmkin sweep plan`` of an arc that does not fit (past the orbital range) with every export asked for:
    exit status 1 and no geometry file written; an arc that fits: exit 0 and every file written."""
    import contextlib
    import io

    from carmkin.cli import main

    arc = float(rng.choice([60.0, 300.0, 360.0]))
    folder = Path(tempfile.mkdtemp())
    files = {"--astra": folder / "a.npy", "--tigre": folder / "t.npz", "--rtk-xml": folder / "r.xml"}
    argv = ["sweep", "plan", "--arc-deg", str(arc), "--views", str(int(rng.integers(2, 8)))]
    for flag_name, path in files.items():
        argv += [flag_name, str(path)]

    def run():
        with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
            return main(argv)

    def check(status):
        written = [p.exists() for p in files.values()]
        return (status == 0 and all(written)) if arc == 60.0 else (status == 1 and not any(written))
    return Case(run, check=check)


ENTRIES["cli: sweep plan exports (failed arcs write nothing)"] = (cli_failed_sweep, 0.2)
