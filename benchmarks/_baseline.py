"""The code of an earlier commit, runnable beside today's: for benchmarks that compare against "the previous code
in the same run". ``checkout(rev)`` extracts the commit's package into a temporary folder laid out as the wheel
installs it (``urdf/`` → ``carmkin/urdf``, ``viz/`` → ``carmkin/viz``); ``run(code, path)`` runs Python code in
a fresh interpreter with that folder first on ``sys.path`` (``path=None``: today's installed code) and returns
what the code printed last, as JSON."""

from __future__ import annotations

import io
import json
import os
import shutil
import subprocess
import sys
import tarfile
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def checkout(rev: str) -> Path | None:
    """The package of commit ``rev`` in a temporary folder, or None (no git history here: e.g. a source archive)."""
    try:
        archive = subprocess.run(["git", "-C", str(ROOT), "archive", "--format=tar", rev, "carmkin", "urdf", "viz"],
                                 check=True, capture_output=True).stdout
    except (OSError, subprocess.CalledProcessError):
        return None
    folder = Path(tempfile.mkdtemp(prefix=f"carmkin-{rev}-"))
    with tarfile.open(fileobj=io.BytesIO(archive)) as tar:
        tar.extractall(folder, filter="data")
    for name in ("urdf", "viz"):
        shutil.move(str(folder / name), str(folder / "carmkin" / name))
    return folder


def run(code: str, path: Path | None = None) -> object:
    """The JSON value of the last line ``code`` prints, run in a fresh interpreter (``path`` first on sys.path)."""
    env = dict(os.environ)
    if path is not None:
        env["PYTHONPATH"] = os.pathsep.join([str(path), env.get("PYTHONPATH", "")]).rstrip(os.pathsep)
    out = subprocess.run([sys.executable, "-c", code], check=True, capture_output=True, text=True, env=env,
                         cwd=tempfile.gettempdir()).stdout
    return json.loads(out.strip().splitlines()[-1])
