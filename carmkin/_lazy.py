"""A package's submodules as attributes on first use, so that a dotted name the docs give resolves after
``import carmkin`` (``carmkin.robot.verify``, ``carmkin.studies.workspace``, ``carmkin.interop``) without
importing every submodule, and their heavy libraries, up front."""

from __future__ import annotations

import importlib


def submodules(package: str, path, also: tuple[str, ...] = ()) -> "callable":
    """A module ``__getattr__`` for package ``package`` (its ``__name__``, ``__path__``): a public submodule
    (a ``.py`` file or a subpackage whose name does not start with ``_``) is imported when first asked for;
    ``also``: submodules installed from elsewhere (``carmkin.viz``, mapped from ``viz/`` by the build backend,
    is not in an editable install's ``__path__``)."""
    names: set[str] = set()

    def __getattr__(name: str):
        if not names:
            import pkgutil

            names.update(m.name for m in pkgutil.iter_modules(path) if not m.name.startswith("_"))
            names.update(also)
        if name in names:
            return importlib.import_module(f"{package}.{name}")
        raise AttributeError(f"module {package!r} has no attribute {name!r}")

    return __getattr__
