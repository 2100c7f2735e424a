"""The layout follows the data flow (docs/architecture.md, "The house"): a module imports only from its own
layer or the layers before it (no exception), the planners stand side by side without importing each other,
no two rooms (top-level packages) import each other in a circle, and the house is at most
:data:`MAX_FLOORS` floors high. ``import carmkin`` stays light.

Imports are read from the source with ``ast`` (module-level and function-level alike, ``TYPE_CHECKING``
blocks too), so a lazy import that runs back up a layer is caught as well.
"""

import ast
import subprocess
import sys
from functools import cache
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]

#: The planners: they stand side by side on the core and never import each other.
PLANNERS = ("carmkin.views", "carmkin.sweeps", "carmkin.reposition", "carmkin.panorama")

#: Layers in data-flow order; a module may import from its layer and the ones before it. ``carmkin.world``
#: (the one collision world: obstacles, batch, swept and joint-by-joint clearance) stands on the model and
#: under the robot, whose validity is computed on it; ``carmkin.datasets`` is a study.
LAYERS = (
    # the typed errors; the dissertation's quoted numbers (plain data); submodules as attributes on first use
    ("carmkin.errors", "carmkin.seed", "carmkin._lazy"),
    ("carmkin.validation", "carmkin.extras"),
    ("carmkin.transforms",),
    ("carmkin.model", "carmkin.presets"),  # what the machine is, its URDF and Pinocchio models; preset files
    ("carmkin.world", "carmkin.analytic", "carmkin.imaging", "carmkin.singularity"),
    ("carmkin.robot", "carmkin.patient"),
    ("carmkin.analytic_ik", "carmkin.plots"),
    ("carmkin.qp",),
    ("carmkin.qp_ik",),
    ("carmkin.interop",),
    # certified motion between configurations: on the world, under every planner (plan_view, plan_sweep use it)
    ("carmkin.motion",),
    PLANNERS,
    # carmkin.biplane runs the view planner for each of its two planes: a study of the planner, not a planner
    ("carmkin.studies", "carmkin.reproduce", "carmkin.datasets", "carmkin.calibration", "carmkin.viz",
     "carmkin.biplane", "carmkin.dose"),
    ("carmkin.commands", "carmkin.cli"),
)

#: The house's height limit (issue 27): the longest chain of imports between rooms, counted in rooms.
MAX_FLOORS = 13

#: What ``import carmkin`` must not load (they load on first use).
HEAVY = ("pinocchio", "coal", "qpsolvers", "scipy", "matplotlib", "meshcat", "cv2", "torch", "pydicom")


def module_files():
    """(module name, path) of every source module of the installed package."""
    for path in sorted((ROOT / "carmkin").rglob("*.py")):
        parts = list(path.relative_to(ROOT).with_suffix("").parts)
        yield ".".join(parts[:-1] if parts[-1] == "__init__" else parts), path
    for path in sorted((ROOT / "viz").rglob("*.py")):
        parts = ["carmkin", "viz", *path.relative_to(ROOT / "viz").with_suffix("").parts]
        yield ".".join(parts[:-1] if parts[-1] == "__init__" else parts), path


KNOWN = {m for m, _ in module_files()}


def imported_modules(name: str, path: Path) -> set[str]:
    """carmkin modules imported anywhere in the file (relative imports resolved)."""
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    found = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            found |= {a.name for a in node.names if a.name.startswith("carmkin")}
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")
                base = base[: len(base) - (node.level - 1)] if node.level > 1 else base
                module = ".".join(base + ([node.module] if node.module else []))
            else:
                module = node.module or ""
            if module.startswith("carmkin"):  # `from pkg import submodule` imports the submodule, else pkg
                found |= {f"{module}.{a.name}" if f"{module}.{a.name}" in KNOWN else module for a in node.names}
    return {m for m in found if m in KNOWN and m != name}


def layer_of(module: str) -> int | None:
    for index, layer in enumerate(LAYERS):
        if any(module == prefix or module.startswith(prefix + ".") for prefix in layer):
            return index
    return None


GRAPH = {name: imported_modules(name, path) for name, path in module_files()}


def test_every_module_has_a_layer():
    assert [m for m in GRAPH if m != "carmkin" and layer_of(m) is None] == []


@pytest.mark.parametrize("module", sorted(m for m in GRAPH if m != "carmkin"))
def test_imports_only_from_its_layer_or_before(module):
    upward = {target for target in GRAPH[module] if layer_of(target) is not None and layer_of(target) > layer_of(module)}
    assert upward == set(), f"{module} imports from a later layer"


def test_no_import_cycle():
    """Depth-first search over the module graph."""
    graph = GRAPH
    state: dict[str, int] = {}
    cycle: list[str] = []

    def visit(node, stack):
        state[node] = 1
        for nxt in graph.get(node, ()):
            # a package's __init__ importing its own submodules is not a cycle of ideas
            if nxt.startswith(node + "."):
                continue
            if state.get(nxt) == 1:
                cycle.extend(stack[stack.index(nxt):] + [nxt] if nxt in stack else [node, nxt])
                return True
            if state.get(nxt) is None and visit(nxt, stack + [nxt]):
                return True
        state[node] = 2
        return False

    assert not any(visit(m, [m]) for m in sorted(graph) if state.get(m) is None), f"cycle: {' -> '.join(cycle)}"


def room_of(module: str) -> str:
    """The room of a module: its top-level package or single module under ``carmkin/`` (the package's
    ``__init__`` is a room of its own), ``viz`` or ``benchmarks``."""
    parts = module.split(".")
    if parts[0] == "benchmarks":
        return "benchmarks"
    return "carmkin/__init__" if module == "carmkin" else ".".join(parts[:2])


def benchmark_files():
    for path in sorted((ROOT / "benchmarks").glob("*.py")):
        yield f"benchmarks.{path.stem}", path


#: Room -> rooms it imports (carmkin/, viz/ and benchmarks/; an import inside one room is not an arrow).
ROOMS: dict[str, set[str]] = {}
for _name, _path in [*module_files(), *benchmark_files()]:
    _targets = GRAPH[_name] if _name in GRAPH else imported_modules(_name, _path)
    ROOMS.setdefault(room_of(_name), set()).update(room_of(t) for t in _targets if room_of(t) != room_of(_name))


def room_cycle() -> list[str]:
    """A circle of rooms (the first found, as a path that ends where it starts), or []."""
    state: dict[str, int] = {}

    def visit(node, stack):
        state[node] = 1
        for nxt in sorted(ROOMS.get(node, ())):
            if state.get(nxt) == 1:
                return stack[stack.index(nxt):] + [nxt]
            if state.get(nxt) is None and (found := visit(nxt, stack + [nxt])):
                return found
        state[node] = 2
        return []

    for room in sorted(ROOMS):
        if state.get(room) is None and (found := visit(room, [room])):
            return found
    return []


@cache
def floors(room: str) -> int:
    """The floor of a room: 1 + the highest floor it imports from (1 when it imports no other room)."""
    return 1 + max((floors(t) for t in ROOMS.get(room, ())), default=0)


def longest_chain() -> list[str]:
    """The longest chain of imports between rooms, from the top floor down."""
    room, chain = max(sorted(ROOMS), key=floors), []
    while room is not None:
        chain.append(room)
        room = max(sorted(ROOMS.get(room, ())), key=floors, default=None)
    return chain


def planner_imports() -> dict[str, set[str]]:
    """Planner -> the other planners it imports (module by module)."""
    return {p: {room_of(t) for m, ts in GRAPH.items() if room_of(m) == p for t in ts
                if room_of(t) in PLANNERS and room_of(t) != p} for p in PLANNERS}


def test_no_planner_imports_another_planner():
    """views, sweeps, reposition and panorama stand side by side on the core (the one world serves them all)."""
    assert {p: ts for p, ts in planner_imports().items() if ts} == {}


def test_no_circle_between_rooms():
    assert room_cycle() == []


def test_the_house_is_at_most_max_floors_high():
    assert room_cycle() == []  # floors are defined on a house without circles
    chain = longest_chain()
    print(f"the house: {len(chain)} floors ({' > '.join(chain)})")
    assert len(chain) <= MAX_FLOORS, f"{len(chain)} floors: {' > '.join(chain)}"


def test_the_floor_count_sees_every_room_and_arrow():
    """The measure can fail: cli sits on the commands, which sit on the planners, which sit on the core."""
    assert floors("carmkin.cli") > floors("carmkin.commands") > floors("carmkin.reposition") > floors("carmkin.qp_ik")
    assert floors("carmkin.errors") == 1 and "carmkin.errors" in longest_chain()
    assert {"carmkin.viz", "benchmarks", "carmkin/__init__", "carmkin.panorama", "carmkin.seed"} <= set(ROOMS)


def test_import_carmkin_is_light():
    code = f"import sys, carmkin; print([m for m in {HEAVY!r} if m in sys.modules])"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "[]"


def test_test_modules_have_unique_names():
    """The tests folders are not packages: two test files of one name in two folders break the collection of
    the whole suite (pytest's rootdir imports), though each folder runs alone."""
    from collections import Counter
    from pathlib import Path

    names = Counter(p.name for p in Path(__file__).parent.rglob("test_*.py"))
    assert not [name for name, count in names.items() if count > 1]
