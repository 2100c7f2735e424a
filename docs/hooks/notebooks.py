"""MkDocs hook: execute the notebooks at build time and put them, with their outputs, into the site.

Each ``notebooks/NN_name.ipynb`` (committed without outputs) is executed with nbclient (kernels in parallel,
one per CPU), in a scratch folder so that files it writes do not land in the repository. A cell error fails
the build (``mkdocs build --strict`` then exits non-zero). The executed copy is written to
``docs/notebooks/`` (git-ignored), which mkdocs-jupyter renders as it is (``execute: false`` in mkdocs.yml:
the execution happened here). Executed copies are cached in ``build/notebooks/`` under a hash of the
notebook, of carmkin's sources (the CLI's modules aside) and of the installed distributions, so an unchanged notebook is not run twice
(``tests/test_notebooks.py`` reads the same cache). A notebook that needs an extra the build's environment
lacks (its metadata ``carmkin.needs``: ``[module, extra]`` pairs, see :func:`missing_extra`) is not executed:
the site shows its code under a note naming the extra, and the build says so (``python -m pip install -e
".[docs]" && python -m mkdocs build --strict``, the README's docs command, needs no other extra). Every notebook and every docs page missing from ``nav``
is appended to it, so a new page or notebook is in the site without an edit of mkdocs.yml (add a nav line to
place it elsewhere), and a new package of carmkin that no page of docs/api/ documents gets a generated API
page.
"""

from __future__ import annotations

import hashlib
import logging
import os
import shutil
import tempfile
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
NOTEBOOKS = ROOT / "notebooks"
CACHE = ROOT / "build" / "notebooks"
SITE_COPY = ROOT / "docs" / "notebooks"
#: Longest a single cell may run (s); the notebooks are meant to take well under a minute each.
CELL_TIMEOUT_S = 600
log = logging.getLogger("mkdocs.hooks.notebooks")


def notebook_paths() -> list[Path]:
    return sorted(NOTEBOOKS.glob("[0-9][0-9]_*.ipynb"))


def needs(path: Path) -> list[tuple[str, str]]:
    """The ``(module, extra)`` pairs notebook ``path`` cannot run without: its metadata ``carmkin.needs``
    (stated once, in the notebook; the site build and ``pytest --nbmake`` (tests/conftest.py) both read it)."""
    import json

    metadata = json.loads(path.read_text()).get("metadata", {})
    return [(module, extra) for module, extra in metadata.get("carmkin", {}).get("needs", ())]


def missing_extra(path: Path) -> str | None:
    """Why notebook ``path`` cannot run here (``"needs pyarrow (extra datasets)"``: the first of its
    :func:`needs` whose module is absent), or None when it can."""
    from importlib.util import find_spec

    for module, extra in needs(path):
        if find_spec(module) is None:
            return f"needs {module} (extra {extra})"
    return None


def unexecuted_copy(path: Path, reason: str) -> str:
    """Notebook ``path`` as committed (no outputs) under a first cell saying why this build did not run it."""
    import nbformat

    notebook = nbformat.read(path, as_version=4)
    extras = sorted({extra.split(":")[0] for _, extra in needs(path)})
    install = "python -m pip install -e \".[" + ",".join(extras) + "]\""
    note = (f"> **Not executed in this build of the site.** This notebook {reason}, which the environment that "
            f"built the site lacks: its code is shown without outputs. Run it after `{install}`.")
    notebook.cells.insert(0, nbformat.v4.new_markdown_cell(note))
    return nbformat.writes(notebook)


def _environment_digest() -> str:
    """A hash of carmkin's sources and of the environment's installed distributions (name and version): a
    notebook that prints "rendering skipped" without an extra must not be served from the cache to an environment
    that has the extra (CI builds the site first with the docs extra alone, then with every extra)."""
    from importlib.metadata import distributions

    digest = hashlib.sha256()
    # a set: ``python -m pytest`` puts the checkout on sys.path, where carmkin.egg-info lists carmkin a second time
    installed = sorted({f"{d.metadata['Name']}=={d.version}" for d in distributions() if d.metadata["Name"]})
    digest.update("\n".join(installed).encode())
    for folder in ("carmkin", "viz", "urdf"):
        for path in sorted((ROOT / folder).rglob("*")):
            if path.is_file() and path.suffix in (".py", ".toml", ".xacro") and "commands" not in path.parts:
                digest.update(path.relative_to(ROOT).as_posix().encode() + path.read_bytes())
    return digest.hexdigest()


def cached_path(path: Path, environment: str | None = None) -> Path:
    """Where the executed copy of ``path`` is cached (whether or not it exists yet)."""
    key = hashlib.sha256(path.read_bytes() + (environment or _environment_digest()).encode()).hexdigest()[:16]
    return CACHE / f"{path.stem}-{key}.ipynb"


def execute(path: Path, environment: str | None = None) -> tuple[Path, float]:
    """The executed copy of notebook ``path`` (cached) and the seconds its execution took (0 from the cache).
    Raises ``nbclient.exceptions.CellExecutionError`` when a cell fails."""
    import nbformat
    from nbclient import NotebookClient

    target = cached_path(path, environment)
    if target.exists():
        return target, 0.0
    notebook = nbformat.read(path, as_version=4)
    start = time.perf_counter()
    with tempfile.TemporaryDirectory(prefix=f"{path.stem}-") as scratch:
        NotebookClient(notebook, timeout=CELL_TIMEOUT_S, kernel_name="python3",
                       resources={"metadata": {"path": scratch}}).execute(env={**os.environ, "TQDM_DISABLE": "1"})
    seconds = time.perf_counter() - start
    target.parent.mkdir(parents=True, exist_ok=True)
    for stale in CACHE.glob(f"{path.stem}-*.ipynb"):
        stale.unlink()
    nbformat.write(notebook, target)
    return target, seconds


def execute_all(paths: list[Path], workers: int | None = None) -> dict[Path, tuple[Path, float]]:
    """Execute ``paths`` in parallel; ``{notebook: (executed copy, seconds)}``; the first failure is raised."""
    environment = _environment_digest()
    workers = workers or max(1, min(len(paths), os.cpu_count() or 1))
    with ThreadPoolExecutor(workers) as pool:
        futures = {p: pool.submit(execute, p, environment) for p in paths}
        return {p: f.result() for p, f in futures.items()}


# --- MkDocs events ---------------------------------------------------------------------------------------------
def _listed(nav) -> set[str]:
    found: set[str] = set()
    for item in nav or []:
        value = next(iter(item.values())) if isinstance(item, dict) else item
        if isinstance(value, list):
            found |= _listed(value)
        elif isinstance(value, str):
            found.add(value)
    return found


#: Parts of the package that are not library API (the command line has its own --help).
NOT_API = {"cli", "commands"}
#: Folder (in the site) of the API pages written by this hook for packages no page of docs/api/ documents yet.
GENERATED_API = "api/more"


def undocumented_packages(docs: Path) -> list[str]:
    """``carmkin.X`` (a subpackage or a module of carmkin) that no ``::: carmkin.X...`` of docs/api/ renders."""
    documented = "\n".join(p.read_text() for p in (docs / "api").glob("*.md"))
    names = sorted({p.stem if p.is_file() else p.name for p in (ROOT / "carmkin").iterdir()
                    if (p.suffix == ".py" or (p / "__init__.py").exists()) and not p.name.startswith("_")})
    return [f"carmkin.{n}" for n in names
            if n not in NOT_API and f"::: carmkin.{n}\n" not in documented and f"::: carmkin.{n}." not in documented]


def on_config(config):
    """Append to ``nav`` every notebook and docs page it does not list yet (under "Notebooks" / "More"), and an
    API page for each package of carmkin that docs/api/ does not document yet (under "API reference")."""
    nav = config.get("nav")
    if nav is None:
        return config
    listed = _listed(nav)
    docs = Path(config["docs_dir"])
    pages = [p.relative_to(docs).as_posix() for p in sorted(docs.rglob("*.md"))
             if not p.relative_to(docs).as_posix().startswith(("hooks/", "notebooks/"))]
    missing_pages = [p for p in pages if p not in listed]
    missing_notebooks = [f"notebooks/{p.name}" for p in notebook_paths() if f"notebooks/{p.name}" not in listed]
    missing_api = [f"{GENERATED_API}/{name}.md" for name in undocumented_packages(docs)]
    for title, entries in (("More", missing_pages), ("Notebooks", missing_notebooks), ("API reference", missing_api)):
        if not entries:
            continue
        section = next((item for item in nav if isinstance(item, dict) and title in item), None)
        if section is None:
            section = {title: []}
            nav.append(section)
        section[title].extend(entries)
    return config


def on_pre_build(config):
    from mkdocs.exceptions import PluginError

    paths = notebook_paths()
    start = time.perf_counter()
    absent = {p: reason for p in paths if (reason := missing_extra(p))}
    try:
        done = execute_all([p for p in paths if p not in absent])
    except Exception as exc:  # a failing cell: the build fails, naming the notebook and the cell
        raise PluginError(f"a notebook failed to execute: {exc}") from exc
    SITE_COPY.mkdir(exist_ok=True)
    for notebook, reason in absent.items():
        text = unexecuted_copy(notebook, reason)
        copy = SITE_COPY / notebook.name
        if not copy.exists() or copy.read_text() != text:
            copy.write_text(text)
        log.info(f"{notebook.name}: not executed, shown without outputs: it {reason}")
    for notebook, (executed, seconds) in done.items():
        copy = SITE_COPY / notebook.name
        if not copy.exists() or copy.read_bytes() != executed.read_bytes():
            shutil.copyfile(executed, copy)
        log.info(f"{notebook.name}: {'cached' if not seconds else f'executed in {seconds:.1f} s'}")
    for stray in SITE_COPY.glob("*.ipynb"):
        if not (NOTEBOOKS / stray.name).exists():
            stray.unlink()
    log.info(f"{len(paths)} notebooks ready ({len(absent)} not executed for a missing extra) in {time.perf_counter() - start:.1f} s")


def on_files(files, config):
    """The API pages announced by :func:`on_config`: one ``::: carmkin.X`` each."""
    from mkdocs.structure.files import File

    for name in undocumented_packages(Path(config["docs_dir"])):
        files.append(File.generated(config, f"{GENERATED_API}/{name}.md", content=f"# {name}\n\n::: {name}\n"))
    return files
