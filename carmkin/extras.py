"""Optional dependencies (the extras of ``pyproject.toml``): one way to import them.

``require(module, extra)`` imports ``module`` or raises :class:`~carmkin.errors.MissingExtraError` naming the
module and the command that installs the extra, ``python -m pip install "carmkin[EXTRA]"``. Every optional
import of the library goes through it (OpenCV for repositioning, pydicom for DICOM files, torch / nanodrr /
nibabel for DRRs), so a missing extra is a typed error in Python and a one-line usage error (exit 2) on the
command line, never an ``ImportError`` or an "internal error".
"""

from __future__ import annotations

import importlib

from carmkin.errors import InvalidParameterError, MissingExtraError

#: The extras and what each brings (the keys are the names in ``carmkin[...]``, see pyproject.toml).
EXTRAS = {
    "reposition": "OpenCV (cv2)",
    "dicom": "pydicom",
    "dose": "pydicom (skin dose from a dose report, RDSR)",
    "drr": "torch, nanodrr and nibabel",
    "cbct": "itk-rtk (itk with RTK's CPU filters)",
    "ct": "nibabel and scikit-image (a patient body or a vessel centreline from a CT)",
    "datasets": "pyarrow (Parquet shards) and Ray (scale-out); rendering also needs the drr extra",
}


def install_command(extra: str) -> str:
    """The pip command that installs ``extra``: ``python -m pip install "carmkin[EXTRA]"``."""
    return f'python -m pip install "carmkin[{extra}]"'


def require(module: str, extra: str):
    """The imported ``module`` (e.g. ``"cv2"``), or :class:`MissingExtraError` naming ``extra``'s install command.

    Only a missing module (``ModuleNotFoundError`` for ``module`` or a package it needs) is translated; an
    error raised while the module itself initialises is not hidden.
    """
    if not isinstance(extra, str) or extra not in EXTRAS:
        raise InvalidParameterError(f"extra must be one of {', '.join(EXTRAS)}, got {extra!r}")
    if not isinstance(module, str) or not module.isidentifier() and not all(
            part.isidentifier() for part in module.split(".")):
        raise InvalidParameterError(f"module must be an importable module name, got {module!r}")
    try:
        return importlib.import_module(module)
    except ModuleNotFoundError as exc:
        raise _missing(module, exc.name or module, extra) from None


def check_installed(module: str, extra: str) -> None:
    """:class:`~carmkin.errors.MissingExtraError`, as :func:`require` says it, when ``module`` is not installed,
    without importing it: a command checks this before any work when the module loads only later (RTK takes tens
    of seconds)."""
    from importlib.util import find_spec

    if extra not in EXTRAS:
        raise InvalidParameterError(f"extra must be one of {', '.join(EXTRAS)}, got {extra!r}")
    try:
        found = find_spec(module) is not None
    except (ImportError, ValueError):  # a parent package missing, or a module without a spec
        found = False
    if not found:
        raise _missing(module, module, extra)


def _missing(module: str, missing: str, extra: str) -> MissingExtraError:
    return MissingExtraError(f"{module} is not installed (missing module {missing!r}; the {extra!r} extra brings "
                             f"{EXTRAS[extra]}): install it with {install_command(extra)}", module, extra)
