"""The layout follows the data flow (docs/architecture.md): a module imports only from its own layer or the
layers before it, there is no import cycle, and ``import carmkin`` stays light.

Imports are read from the source with ``ast`` (module-level and function-level alike), so a lazy import that
runs back up a layer is caught too.
"""

import ast
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]

#: Layers in data-flow order; a module may import from its layer and the ones before it.
LAYERS = (
    ("carmkin.errors", "carmkin.validation", "carmkin.extras", "carmkin.transforms"),
    ("carmkin.model", "carmkin.presets"),
    ("carmkin.world",),
    ("carmkin.robot",),
    ("carmkin.analytic", "carmkin.analytic_ik"),
    ("carmkin.qp", "carmkin.qp_ik", "carmkin.singularity"),
    ("carmkin.studies", "carmkin.imaging", "carmkin.reposition", "carmkin.interop", "carmkin.plots",
     "carmkin.sweeps", "carmkin.patient"),
    ("carmkin.views",),
    ("carmkin.reproduce",  # the dissertation's experiments: above the applications they simulate
     "carmkin.datasets"),  # synthetic datasets: poses from the planners (views, sweeps), DRRs from interop
    ("carmkin.viz",),
    ("carmkin.commands", "carmkin.cli"),
)

#: Imports that run back up on purpose, each with its reason.
ALLOWED_UPWARD = {
    # The contract (shared/DESIGN.md) has the system hand out its generated artifacts: system.urdf() and
    # system.pinocchio() import the robot layer lazily, inside those two methods only.
    ("carmkin.model.system", "carmkin.robot.urdf"),
    ("carmkin.model.system", "carmkin.robot.models"),
}

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
            if module.startswith("carmkin"):
                found.add(module)
                found |= {f"{module}.{a.name}" for a in node.names}  # `from pkg import submodule`
    known = {m for m, _ in module_files()}
    return {m for m in found if m in known and m != name}


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
    upward = {
        target for target in GRAPH[module]
        if layer_of(target) is not None and layer_of(target) > layer_of(module)
        and (module, target) not in ALLOWED_UPWARD
    }
    assert upward == set(), f"{module} imports from a later layer"


def test_no_import_cycle():
    """Depth-first search over the module graph (minus the documented upward imports)."""
    graph = {m: {t for t in ts if (m, t) not in ALLOWED_UPWARD} for m, ts in GRAPH.items()}
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


def test_import_carmkin_is_light():
    code = f"import sys, carmkin; print([m for m in {HEAVY!r} if m in sys.modules])"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "[]"
