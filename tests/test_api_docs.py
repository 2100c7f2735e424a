"""The API reference renders: every public module of carmkin is on an API page, and a build of those pages
(mkdocstrings, strict, the same handler options as mkdocs.yml) leaves no Sphinx role (``:class:`...```)
unrendered and no machine path in any page. Needs the docs extra (skips without it)."""

from __future__ import annotations

import pkgutil
import re
import shutil
from pathlib import Path

import pytest

import carmkin
from hang import HANG_GUARD_S

ROOT = Path(__file__).resolve().parents[1]
API = ROOT / "docs" / "api"
#: Not in the API reference: the command line (docs/cli.md and --help) and the xacro data package.
NOT_API = ("carmkin.commands", "carmkin.cli", "carmkin.urdf")
#: What an unrendered Sphinx role looks like in a built page.
ROLE = re.compile(r":(?:py:)?(?:class|func|meth|mod|data|attr|exc|obj|const):`")


def directives() -> dict[str, bool]:
    """``{module: shows its submodules}`` of every ``::: module`` directive of the API pages."""
    found = {}
    for page in API.glob("*.md"):
        text = page.read_text()
        for match in re.finditer(r"^::: (\S+)\n((?:    .*\n)*)", text + "\n", re.M):
            found[match[1].replace("viz", "carmkin.viz", 1) if match[1] == "viz" else match[1]] = \
                "show_submodules: true" in match[2]
    return found


def public_modules() -> list[str]:
    names = [m.name for m in pkgutil.walk_packages(carmkin.__path__, "carmkin.", onerror=lambda name: None)]
    return sorted(n for n in names if not any(p.startswith("_") for p in n.split(".")) and not n.startswith(NOT_API))


def test_every_public_module_is_on_an_api_page():
    shown = directives()
    missing = [m for m in public_modules()
               if m not in shown and not any(m.startswith(p + ".") and sub for p, sub in shown.items())]
    assert not missing, f"modules on no API page (docs/api/*.md): {missing}"


def api_config(site: Path) -> Path:
    """mkdocs.yml reduced to the API pages (no notebook hook), in a folder of its own."""
    pytest.importorskip("mkdocstrings_handlers.python", reason="the API build needs the docs extra")
    yaml = pytest.importorskip("yaml", reason="the API build needs the docs extra (PyYAML)")
    config = yaml.safe_load((ROOT / "mkdocs.yml").read_text())
    docs = site / "docs"
    shutil.copytree(API, docs / "api")
    (docs / "index.md").write_text("# API\n")
    handler = config["plugins"][-1]["mkdocstrings"]["handlers"]["python"]
    handler["paths"] = [str(ROOT)]
    handler["options"]["extensions"] = [str(ROOT / "docs" / "hooks" / "crossrefs.py") + ":SphinxRoles"]
    config.update(docs_dir=str(docs), site_dir=str(site / "site"), nav=None, hooks=[],
                  plugins=["search", {"mkdocstrings": config["plugins"][-1]["mkdocstrings"]}])
    config.pop("nav")
    config.pop("exclude_docs", None)
    path = site / "mkdocs.yml"
    path.write_text(yaml.safe_dump(config))
    return path


@pytest.mark.slow
def test_the_built_api_pages_render_every_role(tmp_path):
    pytest.importorskip("mkdocs", reason="the API build needs the docs extra (mkdocs)")
    import subprocess
    import sys

    config = api_config(tmp_path)
    done = subprocess.run([sys.executable, "-m", "mkdocs", "build", "--strict", "-q", "-f", str(config)],
                          capture_output=True, text=True, timeout=HANG_GUARD_S, cwd=tmp_path)
    assert done.returncode == 0, done.stderr[-3000:]
    pages = sorted((tmp_path / "site" / "api").glob("*.html"))
    assert len(pages) == len(list(API.glob("*.md")))
    unrendered = {p.name: ROLE.findall(p.read_text()) for p in pages}
    assert not any(unrendered.values()), {k: len(v) for k, v in unrendered.items() if v}
    machine = [p.name for p in pages if str(ROOT) in p.read_text() or "/site-packages/" in p.read_text()]
    assert not machine, f"pages with a machine path: {machine}"
