"""What several subcommands share: the preset option, joint vectors and poses in mm/degrees, checked option
values, output paths, and the errors a command line can raise.

Only numpy and the light public face of carmkin are imported here (``carmkin --help`` must stay fast):
Pinocchio, coal, scipy, matplotlib and meshcat load inside the commands' ``run`` when they are needed.

Units on the command line: mm for prismatic joints and lengths, degrees for revolute joints and angles; the
unit is in the option name (``--q-mm-deg``, ``--margin-mm``). The library works in m and rad.
"""

from __future__ import annotations

import argparse
import json
import math
import shlex
import sys
from pathlib import Path

import numpy as np

from carmkin.errors import (  # noqa: F401 (defined there, raised here)
    CarmkinError,
    InvalidConfigurationError,
    InvalidPoseError,
    NotApplicableError,
    PresetError,
    UsageError,
)
from carmkin.model.system import CArmSystem
from carmkin.presets import biplane_planes, list_presets, load_preset
from carmkin.transforms import check_rigid_transform, nearest_rigid
from carmkin.validation import unit_slip

DEFAULT_PRESET = "siremobile-iso-c3d"
#: Factors from SI to the command line's units: m -> mm, rad -> degrees.
MM_PER_M = 1000.0
#: Smallest distance (mm) accepted by a distance option (source to target, source to object plane): 10 mm, less
#: than any source housing allows. A value below it is a distance in m (``0.6`` for 600 mm), refused naming it.
MIN_DISTANCE_MM = 10.0
DEG_PER_RAD = 180.0 / math.pi
#: Metavar of a joint-vector option: one value per joint of the preset, mm or degrees.
JOINTS_METAVAR = "V1,...,VN"


def _default_margin_mm() -> float:
    """:data:`carmkin.DEFAULT_MARGIN` in mm, read from ``carmkin/world/tolerances.py`` itself (the one place it is
    stated): importing the package ``carmkin.world`` loads coal, which ``carmkin --help`` must not."""
    import importlib.util

    path = Path(__file__).resolve().parents[1] / "world" / "tolerances.py"
    spec = importlib.util.spec_from_file_location("_carmkin_cli_tolerances", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return float(module.DEFAULT_MARGIN) * MM_PER_M


#: The one default clearance margin (:data:`carmkin.DEFAULT_MARGIN`) in mm: the default of every planner's
#: ``--margin-mm`` (views, sweeps, the biplane), as of the library's planners.
DEFAULT_MARGIN_MM = _default_margin_mm()


def add_margin_argument(parser: argparse.ArgumentParser,
                        what: str = "clearance every moving part keeps from table, floor and patient") -> None:
    """Add ``--margin-mm`` (``args.margin_mm``, mm), defaulting to :data:`DEFAULT_MARGIN_MM`."""
    parser.add_argument("--margin-mm", type=number(0.0, 1000.0, unit="mm"), default=DEFAULT_MARGIN_MM,
                        help=f"{what} (mm, default {DEFAULT_MARGIN_MM:g}: carmkin.DEFAULT_MARGIN, the one default "
                        "of every planner)")


# --- the preset -----------------------------------------------------------------------------------------
def add_preset_argument(parser: argparse.ArgumentParser) -> None:
    """``--preset NAME|FILE.toml`` (default: the Siremobile Iso-C 3D)."""
    parser.add_argument("--preset", default=DEFAULT_PRESET,
                        help=f"built-in preset ({', '.join(list_presets())}) or a preset .toml file "
                        f"(default: {DEFAULT_PRESET})")


def system_from_args(args: argparse.Namespace) -> CArmSystem:
    """The system named by ``--preset``; :class:`UsageError` for a missing or unreadable preset file, and for a
    biplane preset: the commands that read one system model one plane and would silently drop the lateral one
    (``carmkin biplane`` reads both; the frontal plane's own preset names the frontal plane alone)."""
    if str(args.preset).endswith(".toml") and not Path(args.preset).is_file():
        raise UsageError(f"--preset {args.preset}: no such preset file")
    try:
        planes = biplane_planes(args.preset)
        if planes is not None:
            command = getattr(args, "prog", "this command")
            raise UsageError(f"--preset {args.preset} is a biplane preset (frontal {planes['frontal']}, lateral "
                             f"{planes['lateral']}); {command} models one plane and would drop the lateral one: use "
                             f"`carmkin biplane check|plan --preset {args.preset}` for both planes, or --preset "
                             f"{planes['frontal']} for the frontal plane alone")
        return load_preset(args.preset)
    except PresetError as exc:
        raise UsageError(f"--preset: {exc}") from None


def require_six_joints(system: CArmSystem, command: str, alternative: str) -> None:
    """:class:`NotApplicableError` unless ``system`` is the paper's 6-joint chain (the closed forms' domain)."""
    if system.nq != 6:
        extra = system.joint_names[1:1 + system.nq - 6]  # the table's and a mount's joints between d0 and the C-arm
        what = "extra table joints" if not system.mount.joints else "extra table and mount joints"
        raise NotApplicableError(
            f"{command} uses the closed form of the paper's 6-joint chain; preset {system.name!r} has "
            f"{system.nq} joints ({what} {', '.join(extra)}): {alternative}")


# --- joint vectors --------------------------------------------------------------------------------------
#: The one option name for a joint vector (the configuration a command works at) on every command.
JOINTS_FLAG = "--q-mm-deg"


class _RenamedOption(argparse.Action):
    """An option's former name, hidden from ``--help`` and kept for one release: stores its value where the
    new name does and says so in one line on stderr (``new_name``: the option's name now)."""

    def __init__(self, *args, new_name: str = JOINTS_FLAG, **kwargs):
        super().__init__(*args, **kwargs)
        self.new_name = new_name

    def __call__(self, parser, namespace, values, option_string=None):
        print(f"note: {option_string} is now called {self.new_name}; the old name will be removed in the next release",
              file=sys.stderr)
        setattr(namespace, self.dest, values)


def add_alias(parser: argparse.ArgumentParser, old: str, new: str, dest: str, **kwargs) -> None:
    """``old``: a hidden former name of option ``new`` (same ``dest``; a note on stderr when used). ``kwargs``:
    what ``new`` was declared with that parsing needs (``type``, ``nargs``, ``metavar``...)."""
    parser.add_argument(old, dest=dest, action=_RenamedOption, new_name=new, help=argparse.SUPPRESS, **kwargs)


# --- the flag grammar (docs/cli.md): figures and JSON ---------------------------------------------------------
#: argparse dests whose value is a file a command writes: checked (folder there, not a folder) before the work
#: starts, by :func:`check_output_paths` (``carmkin.cli.main`` calls it). An output *folder* (``--out DIR``) is
#: the command's to check, with :func:`output_folder`.
OUTPUT_DESTS = ("json", "png", "html", "output", "rtk_xml", "astra", "tigre", "write_xa", "write_enhanced")
#: ``--json -``: the JSON goes to stdout instead of the text report (notes and errors stay on stderr).
STDOUT = "-"


def add_json_argument(parser: argparse.ArgumentParser, what: str = "the results") -> None:
    """``--json [FILE]``: write ``what`` as JSON to FILE; ``-`` (or the flag alone) prints it on stdout instead of
    the text report."""
    parser.add_argument("--json", metavar="FILE", nargs="?", const=STDOUT,
                        help=f"write {what} as JSON to FILE (- or no FILE: on stdout, instead of the text report)")


def add_png_argument(parser: argparse.ArgumentParser, what: str, old_names: tuple[str, ...] = ()) -> None:
    """``--png FILE``: a matplotlib figure of ``what`` (any format matplotlib writes, by the extension);
    ``old_names``: hidden former names (``--plot``, ``--out``)."""
    parser.add_argument("--png", metavar="FILE", help=f"write {what} as a figure (.png; .pdf, .svg... also work)")
    for old in old_names:
        add_alias(parser, old, "--png", "png", metavar="FILE")


def check_output_paths(args: argparse.Namespace) -> None:
    """Every output path of ``args`` (:data:`OUTPUT_DESTS`) ready to be written before any work: its folder
    there, or :class:`UsageError` naming the option (:func:`output_path`). ``--json -`` is stdout."""
    for dest in OUTPUT_DESTS:
        value = getattr(args, dest, None)
        if isinstance(value, (str, Path)) and str(value) != STDOUT:
            suffixes = {"json": ("json",), "html": ("html", "htm")}.get(dest)
            if dest == "png":
                suffixes = plot_formats()
            output_path(str(value), "--" + dest.replace("_", "-"), suffixes)


def _jsonable(value):
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, Path):
        return str(value)
    return float(value)  # a number-like value (a TypeError names what cannot be written)


def write_json(args: argparse.Namespace, data: dict) -> None:
    """``data`` (numbers in mm/degrees, keys with their unit) to ``--json``'s file, or stdout for ``-``
    (``carmkin.cli.main`` silences the text report then). Nothing without ``--json``."""
    target = getattr(args, "json", None)
    if target is None:
        return
    text = json.dumps(data, indent=2, default=_jsonable, allow_nan=True)
    if str(target) == STDOUT:
        stream = getattr(args, "json_stream", None) or sys.stdout
        stream.write(text + "\n")
        stream.flush()
        return
    path = output_path(str(target), "--json", ("json",))
    path.write_text(text + "\n", encoding="utf-8")
    print(f"wrote {path}")


def add_joints_argument(parser: argparse.ArgumentParser, what: str = "configuration",
                        default: str = "prismatic joints mid-range, revolute 0°",
                        old_names: tuple[str, ...] = ()) -> None:
    """Add :data:`JOINTS_FLAG` (``args.q_mm_deg``, text; read it with :func:`parse_joints`): one value per joint
    of the preset, mm for prismatic and degrees for revolute joints. ``old_names``: hidden aliases the command
    used before (a note on stderr when used)."""
    parser.add_argument(JOINTS_FLAG, dest="q_mm_deg", metavar=JOINTS_METAVAR,
                        help=f"{what}: one value per joint of the preset, mm for prismatic and degrees for revolute "
                        f"joints, comma-separated (default: "
                        f"{default})")
    for old in old_names:
        add_alias(parser, old, JOINTS_FLAG, "q_mm_deg", metavar=JOINTS_METAVAR)


def joint_units(system: CArmSystem) -> tuple[str, ...]:
    """``"mm"`` for each prismatic joint, ``"deg"`` for each revolute one, in the order of q."""
    return tuple("mm" if p else "deg" for p in system.prismatic)


def to_cli_units(system: CArmSystem) -> np.ndarray:
    """(nq,) factors from q in m/rad to the command line's mm/degrees."""
    return np.array([MM_PER_M if p else DEG_PER_RAD for p in system.prismatic])


def parse_joints(text: str, system: CArmSystem, option: str, check_range: bool = True) -> np.ndarray:
    """``"v0,v1,..."`` in mm (prismatic) / degrees (revolute), one value per joint of ``system`` -> q (nq,) in m/rad.

    Raises :class:`InvalidConfigurationError` naming ``option``, the expected count and the joint names for a
    wrong count, a value that is not a finite number, or (``check_range``) a value outside its joint range
    (a value on a limit is in range); values are never clipped.
    """
    names, units = system.joint_names, joint_units(system)
    expected = ", ".join(f"{n} ({u})" for n, u in zip(names, units))
    parts = [p.strip() for p in str(text).split(",")]
    if len(parts) != system.nq:
        raise InvalidConfigurationError(f"{option} needs {system.nq} comma-separated values for preset "
                                        f"{system.name!r}: {expected}; got {len(parts)} in {text!r}")
    values = np.empty(system.nq)
    for i, part in enumerate(parts):
        try:
            values[i] = float(part)
        except ValueError:
            raise InvalidConfigurationError(f"{option}: {names[i]} ({units[i]}) is not a number: {part!r} "
                                            f"(expected {expected})") from None
        if not math.isfinite(values[i]):
            raise InvalidConfigurationError(f"{option}: {names[i]} must be finite, got {part!r}")
    prismatic = np.asarray(system.prismatic, dtype=bool)
    ranges = np.array([[r.lower, r.upper] for r in system.joint_ranges])[prismatic] * MM_PER_M
    check_unit_slip(option, text, values[prismatic], values[~prismatic], ranges, error=InvalidConfigurationError)
    q = values / to_cli_units(system)
    if check_range:
        check_joint_ranges(system, q, option)
    return q


def check_joint_ranges(system: CArmSystem, q: np.ndarray, option: str) -> None:
    """:class:`InvalidConfigurationError` naming the first joint of q (m/rad) outside its range, in mm/degrees."""
    scale = to_cli_units(system)
    for i, (joint_range, unit) in enumerate(zip(system.joint_ranges, joint_units(system))):
        excess = float(joint_range.excess(q[i]))
        if excess != 0.0:
            raise InvalidConfigurationError(
                f"{option}: {system.joint_names[i]} = {q[i] * scale[i]:.6g} {unit} is outside its range "
                f"[{joint_range.lower * scale[i]:.6g}, {joint_range.upper * scale[i]:.6g}] {unit} "
                f"by {excess * scale[i]:+.4g} {unit}")


def format_joints(system: CArmSystem, q, digits: int = 3, sign: bool = True, between: str = "=") -> str:
    """``"name=+1.000 mm, name=-2.500°, ..."`` for q (nq,) in m/rad (a value that rounds to zero prints as
    +0.000, never -0.000); ``between`` goes between a name and its value (``" "`` for moves)."""
    spec = f"{'+' if sign else ''}.{digits}f"
    return ", ".join(f"{n}{between}{round(float(v), digits) + 0.0:{spec}}{' mm' if u == 'mm' else '°'}"
                     for n, u, v in zip(system.joint_names, joint_units(system), np.asarray(q) * to_cli_units(system)))


def joints_json(system: CArmSystem, q) -> dict[str, float]:
    """``{"<name>_<unit>": value}`` for q (nq,) in m/rad, values in mm/degrees."""
    return {f"{n}_{u}": float(v)
            for n, u, v in zip(system.joint_names, joint_units(system), np.asarray(q) * to_cli_units(system))}


# --- unit slips: metres where mm are read, radians where degrees are --------------------------------------
#: The command line's one unit-slip rule. A vector of lengths read in mm (a point, a joint vector's prismatic
#: joints, a list of table translations) whose values are all below this magnitude (mm), not all zero, is a
#: vector in metres: the C-arm's scene spans metres, and no command needs every coordinate of a point within
#: 3 mm of the table origin. Where the values have ranges (joints), the slip needs also their reading in metres
#: to lie in range. Refused (exit 2) naming metres (and radians, when the angles beside them read as radians),
#: never converted. A lone scalar option is checked by its bounds instead (:func:`number`, ``unit_slip``).
METRES_SLIP_BELOW_MM = 3.0
#: Angles (deg) that read as radians beside lengths in metres: every |value| within a turn in radians (2π).
RADIANS_AT_MOST = 2.0 * math.pi


def metres_slip(values_mm, ranges_mm=None) -> bool:
    """True when lengths ``values_mm`` (mm) look like metres by :data:`METRES_SLIP_BELOW_MM` (and, with
    ``ranges_mm`` ((n, 2) lower/upper, mm), their reading in metres lies in range)."""
    v = np.asarray(values_mm, dtype=float).ravel()
    if v.size == 0 or not np.any(v != 0.0) or np.any(np.abs(v) >= METRES_SLIP_BELOW_MM):
        return False
    if ranges_mm is not None:
        low, high = np.asarray(ranges_mm, dtype=float).reshape(-1, 2).T
        return bool(np.all((low <= v * MM_PER_M) & (v * MM_PER_M <= high)))
    return True


def check_unit_slip(option: str, text, lengths_mm, angles_deg=(), ranges_mm=None, error=UsageError) -> None:
    """``error`` naming ``option``, metres and (when every angle reads as radians) radians, when
    ``lengths_mm`` look like metres (:func:`metres_slip`); nothing otherwise."""
    if not metres_slip(lengths_mm, ranges_mm):
        return
    lengths = np.asarray(lengths_mm, dtype=float).ravel()
    angles = np.asarray(angles_deg, dtype=float).ravel()
    first = lengths[np.flatnonzero(lengths)[0]]
    hint = f"given in m? ({first:g} m = {first * MM_PER_M:g} mm)"
    turning = angles[angles != 0.0]
    if turning.size and np.all(np.abs(turning) <= RADIANS_AT_MOST):
        hint += f" and the angles in radians? ({turning[0]:g} rad = {math.degrees(turning[0]):.4g}°)"
    raise error(f"{option} {text}: every length is below {METRES_SLIP_BELOW_MM:g} mm: {hint}; the command line "
                "reads mm and degrees")


# --- numbers and poses ----------------------------------------------------------------------------------
def parse_numbers(text: str, count: int | None, option: str, error=UsageError, unit: str = "") -> np.ndarray:
    """Comma-separated finite numbers (``count`` of them unless ``None``); ``error`` names the option.
    ``unit="mm"``: lengths (a point, sizes), refused when they look like metres (:func:`check_unit_slip`)."""
    try:
        values = np.array([float(v) for v in str(text).split(",")])
    except ValueError:
        raise error(f"{option} must be numbers separated by commas, got {text!r}") from None
    if count is not None and values.shape != (count,):
        raise error(f"{option} needs {count} comma-separated numbers, got {len(values)} in {text!r}")
    if not np.all(np.isfinite(values)):
        raise error(f"{option} values must be finite, got {text!r}")
    if unit == "mm":
        check_unit_slip(option, text, values, error=error)
    return values


def parse_pose(text: str, option: str) -> np.ndarray:
    """``"x,y,z,rx,ry,rz"`` (position mm, rotation vector deg) -> 4x4 pose (m); a pose in m and rad is refused
    (:func:`check_unit_slip`)."""
    values = parse_numbers(text, 6, option)
    check_unit_slip(option, text, values[:3], values[3:])
    return pose_from_mm_deg(values[:3], values[3:])


def pose_from_mm_deg(position_mm, rotation_vector_deg) -> np.ndarray:
    """4x4 pose (m) from a position in mm and a rotation vector (axis × angle, R = exp([r]×)) in degrees."""
    from scipy.spatial.transform import Rotation

    T = np.eye(4)
    T[:3, :3] = Rotation.from_rotvec(np.radians(np.asarray(rotation_vector_deg, dtype=float))).as_matrix()
    T[:3, 3] = np.asarray(position_mm, dtype=float) / MM_PER_M
    return T


def read_pose(path: str, option: str) -> np.ndarray:
    """The rigid 4x4 pose (m) in a file, translation in mm; :class:`InvalidPoseError` naming ``option`` otherwise.

    ``*.json``: ``{"position_mm": [x, y, z], "rotation_vector_deg": [rx, ry, rz]}`` or ``{"matrix_mm": 4x4}``;
    any other file: a 4x4 matrix as text (``numpy.loadtxt``). A nearly rigid matrix (typed with 4 decimals,
    written in float32) is projected onto the nearest rigid transform, with a note on stderr
    (:func:`rigid_pose`).
    """
    if not Path(path).is_file():
        raise InvalidPoseError(f"{option} {path}: no such file")
    if Path(path).suffix.lower() == ".json":
        T = _read_json_pose(path, option)
    else:
        try:
            T = np.loadtxt(path, dtype=float, ndmin=2)
        except (OSError, ValueError) as exc:
            raise InvalidPoseError(f"{option} {path}: cannot read a 4x4 matrix ({exc})") from None
        if T.shape != (4, 4) or not np.all(np.isfinite(T)):
            raise InvalidPoseError(f"{option} {path}: expected a 4x4 matrix of finite numbers, got shape {T.shape}")
        T[:3, 3] /= MM_PER_M
    return rigid_pose(T, f"{option} {path}")


def rigid_pose(T: np.ndarray, name: str) -> np.ndarray:
    """``T`` (4x4, m) unchanged when it is rigid to :data:`carmkin.transforms.RIGID_TOLERANCE`; otherwise its
    nearest rigid transform (:func:`carmkin.transforms.nearest_rigid`), with one line on stderr saying how far
    that moved it (degrees, mm). :class:`InvalidPoseError` naming ``name`` and the threshold beyond
    :data:`carmkin.transforms.NEARLY_RIGID_TOLERANCE` (or for a reflection).
    """
    try:
        return check_rigid_transform(T, name)
    except InvalidPoseError:
        pass
    T_rigid, _ = nearest_rigid(T, name)
    print(f"note: {name}: projected the pose onto the nearest rigid transform: rotation moved by "
          f"{axis_change_deg(T, T_rigid):.2g}°, translation by "
          f"{np.linalg.norm(T_rigid[:3, 3] - T[:3, 3]) * MM_PER_M:.2g} mm", file=sys.stderr)
    return T_rigid


def axis_change_deg(T: np.ndarray, T_rigid: np.ndarray) -> float:
    """Largest angle (degrees) between a column of ``T``'s rotation block and the same column of ``T_rigid``'s:
    how far the projection turned the frame's axes (the blocks are not both rotations, so the angle of
    ``Rᵀ R_rigid`` would not measure it)."""
    a, b = T[:3, :3], T_rigid[:3, :3]
    sines = np.linalg.norm(np.cross(a, b, axis=0), axis=0)
    cosines = np.einsum("ij,ij->j", a, b)
    return float(np.degrees(np.arctan2(sines, cosines)).max())


def _read_json_pose(path: str, option: str) -> np.ndarray:
    try:
        with open(path) as stream:
            content = json.load(stream)
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise InvalidPoseError(f"{option} {path}: {exc}") from None
    if not isinstance(content, dict):
        raise InvalidPoseError(f"{option} {path}: expected a JSON object")
    if "matrix_mm" in content:
        try:
            T = np.array(content["matrix_mm"], dtype=float)
        except (TypeError, ValueError):
            raise InvalidPoseError(f"{option} {path}: matrix_mm must be a 4x4 array of numbers") from None
        if T.shape != (4, 4) or not np.all(np.isfinite(T)):
            raise InvalidPoseError(f"{option} {path}: matrix_mm must be 4x4 finite numbers, got shape {T.shape}")
        T[:3, 3] /= MM_PER_M
        return T
    try:
        position = np.array(content["position_mm"], dtype=float)
        rotation = np.array(content["rotation_vector_deg"], dtype=float)
    except KeyError as exc:
        raise InvalidPoseError(f"{option} {path}: missing key {exc}; expected position_mm and "
                               "rotation_vector_deg, or matrix_mm") from None
    except (TypeError, ValueError):
        raise InvalidPoseError(f"{option} {path}: position_mm/rotation_vector_deg must be numbers") from None
    if position.shape != (3,) or rotation.shape != (3,) or not np.all(np.isfinite(np.r_[position, rotation])):
        raise InvalidPoseError(f"{option} {path}: position_mm and rotation_vector_deg need 3 finite values each")
    check_unit_slip(f"{option} {path}:", f"position_mm {position.tolist()}", position, rotation, error=InvalidPoseError)
    return pose_from_mm_deg(position, rotation)


# --- option values (argparse types: a bad value is a one-line usage error naming the option) ---------------
def integer(minimum: int | None = None, maximum: int | None = None):
    """argparse type: an integer in ``[minimum, maximum]``."""
    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected an integer, got {text!r}") from None
        if (minimum is not None and value < minimum) or (maximum is not None and value > maximum):
            raise argparse.ArgumentTypeError(f"expected an integer {_bounds(minimum, maximum)}, got {value}")
        return value
    parse.__name__ = "integer"
    return parse


def number(minimum: float | None = None, maximum: float | None = None, open_minimum: bool = False,
           open_maximum: bool = False, unit: str = "", slips: tuple[tuple[str, float], ...] = ()):
    """argparse type: a finite number in ``[minimum, maximum]``; ``open_minimum``/``open_maximum`` exclude the
    bound itself. A value out of bounds is refused naming the likely unit when, read in another unit, it lies
    within them: the units of :data:`carmkin.validation.UNIT_SLIPS` for ``unit``, then this option's own
    ``slips`` (``(unit given, factor to unit)`` pairs, e.g. ``("arcmin", 1 / 60)`` for a threshold in deg)."""
    def parse(text: str) -> float:
        try:
            value = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected a number{_unit(unit)}, got {text!r}") from None
        too_low = minimum is not None and (value <= minimum if open_minimum else value < minimum)
        too_high = maximum is not None and (value >= maximum if open_maximum else value > maximum)
        if not math.isfinite(value) or too_low or too_high:
            raise argparse.ArgumentTypeError(f"expected a finite number "
                                             f"{_bounds(minimum, maximum, open_minimum, open_maximum)}{_unit(unit)}, "
                                             f"got {text}{_slip(value, minimum, maximum, unit, slips)}")
        return value
    parse.__name__ = "number"
    return parse


def _slip(value: float, minimum, maximum, unit: str, slips) -> str:
    """The hint of :func:`number` for an out-of-bounds value: ``carmkin.validation.unit_slip``, then ``slips``."""
    hint = unit_slip(value, minimum, maximum, unit)
    if hint or minimum is None or maximum is None:
        return hint
    for other, factor in slips:
        if minimum <= value * factor <= maximum:
            return f": given in {other}? {value:g} {other} = {value * factor:.4g} {unit}"
    return ""


def patient_position(text: str) -> str:
    """argparse type: a DICOM Patient Position code (``hfs`` reads as HFS), or the option's error naming the codes."""
    from carmkin.imaging.projection import PATIENT_POSITIONS

    code = str(text).strip().upper()
    if code not in PATIENT_POSITIONS:
        raise argparse.ArgumentTypeError(f"expected a DICOM patient position ({', '.join(PATIENT_POSITIONS)}), "
                                         f"got {text!r}")
    return code


def _bounds(minimum, maximum, open_minimum: bool = False, open_maximum: bool = False) -> str:
    low = None if minimum is None else f"{'>' if open_minimum else '>='} {minimum:g}"
    high = None if maximum is None else f"{'<' if open_maximum else '<='} {maximum:g}"
    return " and ".join(b for b in (low, high) if b) or "(any)"


def _unit(unit: str) -> str:
    return f" ({unit})" if unit else ""


# --- output files ---------------------------------------------------------------------------------------
def output_path(path: str, option: str, suffixes: tuple[str, ...] | None = None) -> Path:
    """``path`` ready to be written, or :class:`UsageError` naming ``option``: the suffix one of ``suffixes``,
    not a folder, and its folder there. A missing folder is refused, never created (a typo in a path must not
    leave folders behind, e.g. ``/nonexistent`` as root): the message names it and the ``mkdir -p`` to run."""
    target = Path(path)
    if suffixes is not None and target.suffix.lower().lstrip(".") not in suffixes:
        raise UsageError(f"{option} {path}: the file extension must be one of {', '.join('.' + s for s in suffixes)}")
    if target.is_dir():
        raise UsageError(f"{option} {path}: is a folder, expected a file name")
    if not target.parent.is_dir():
        raise UsageError(f"{option} {path}: {_missing_folder(target.parent)}")
    return target


def output_folder(path: str, option: str) -> Path:
    """``path`` as an output *folder* (``--out DIR``), or :class:`UsageError` naming ``option``: a folder, or
    a name not yet taken whose parent folder is there (the command creates that one folder, as ``mkdir``
    would); a missing parent is refused, as :func:`output_path` refuses a missing folder."""
    target = Path(path)
    if target.exists() and not target.is_dir():
        raise UsageError(f"{option} {path}: is a file, expected a folder")
    parent = target.absolute().parent
    if not target.exists() and not parent.is_dir():
        raise UsageError(f"{option} {path}: {_missing_folder(parent)}")
    return target


def _missing_folder(folder: Path) -> str:
    """Why ``folder`` cannot hold an output: the first part of it that is a file, or that it does not exist."""
    blocker = next((p for p in (folder, *folder.parents) if p.exists()), None)
    if blocker == folder and not folder.is_dir():
        return f"{str(folder)!r} is a file, not a folder"
    if blocker is not None and not blocker.is_dir():
        return f"the folder {str(folder)!r} cannot exist ({str(blocker)!r} is a file)"
    return f"the folder {str(folder)!r} does not exist (create it first: mkdir -p {shlex.quote(str(folder))})"


def plot_formats() -> tuple[str, ...]:
    """File extensions matplotlib can write (imports matplotlib: call it inside ``run``)."""
    from matplotlib.backend_bases import FigureCanvasBase

    return tuple(sorted(FigureCanvasBase.get_supported_filetypes()))


def plot_path(path: str, option: str) -> Path:
    """:func:`output_path` for a matplotlib figure: the extension must be a format matplotlib writes."""
    return output_path(path, option, plot_formats())
