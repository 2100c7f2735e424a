"""Griffe extension (mkdocs.yml, mkdocstrings ``extensions``): the Sphinx roles of carmkin's docstrings
(``:class:`CArmSystem```, ``:func:`~carmkin.qp_ik.solve```, ``:data:`JOINT_RANGE_TOLERANCE```...) become
cross-references of the API pages.

Each role is replaced by an *optional* autorefs reference to the object's full path, shown as code: a link where
the object is rendered on some page, plain code where it is not (nothing is left as ``:class:`` text, and no
unresolved reference fails the strict build). The target is resolved as Python would from the docstring's
place: an absolute ``carmkin.`` path, a member of the documented class, a name of its module (following imports
to where a class or function is defined), or a name below ``carmkin``. ``~`` shows only the last component.
"""

from __future__ import annotations

import importlib
import re

import griffe

#: A Sphinx role: ``:class:`target```, ``:py:func:`~a.b```, ``:meth:`title <target>```.
ROLE = re.compile(r":(?:py:)?(?:class|func|meth|mod|data|attr|exc|obj|const):`(?P<body>[^`]+)`")


def _import(path: str):
    """The Python object at a dotted ``path`` (longest importable module, then attributes), or None."""
    parts = path.split(".")
    for cut in range(len(parts), 0, -1):
        try:
            value = importlib.import_module(".".join(parts[:cut]))
        except Exception:  # noqa: BLE001 - not a module (or one that needs a missing extra): try shorter
            continue
        for name in parts[cut:]:
            value = getattr(value, name, _MISSING)
            if value is _MISSING:
                return None
        return value
    return None


_MISSING = object()


def _canonical(path: str, value) -> str:
    """Where ``value`` is defined (its module and qualified name) for classes and functions; ``path`` otherwise.
    ``carmkin.viz`` is documented from its source folder, as ``viz``."""
    module, qualname = getattr(value, "__module__", None), getattr(value, "__qualname__", None)
    if isinstance(module, str) and isinstance(qualname, str) and "<" not in qualname and module.startswith("carmkin"):
        path = f"{module}.{qualname}"
    return "viz." + path[len("carmkin.viz."):] if path.startswith("carmkin.viz.") else path


def resolve(target: str, obj) -> str:
    """The full path of ``target`` as written in ``obj``'s docstring (``obj``: a griffe object)."""
    target = target.lstrip("~.")
    scopes = []
    if obj.kind is griffe.Kind.CLASS:
        scopes.append(obj.path)
    if obj.parent is not None and obj.parent.kind is griffe.Kind.CLASS:
        scopes.append(obj.parent.path)
    module = obj.module.path if obj.kind is not griffe.Kind.MODULE else obj.path
    scopes += [module, module.rpartition(".")[0], "carmkin"]
    candidates = [target] + [f"{scope}.{target}" for scope in scopes if scope]
    for path in candidates:
        value = _import("carmkin." + path if path.startswith("viz.") else path)
        if value is not None:
            return _canonical(path, value)
    return target


def replace_roles(text: str, obj) -> str:
    def link(match: re.Match) -> str:
        body = match["body"].strip()
        title, _, explicit = body.partition("<")
        if explicit:
            target, shown = explicit.rstrip(">").strip(), title.strip()
        else:
            target = body
            shown = body.lstrip("~.").rpartition(".")[2] if body.startswith("~") else body.lstrip(".")
        return f'<autoref identifier="{resolve(target, obj)}" optional><code>{shown}</code></autoref>'

    return ROLE.sub(link, text)


class SphinxRoles(griffe.Extension):
    """Rewrite every docstring's Sphinx roles into optional autorefs (see the module's docstring)."""

    def on_object(self, *, obj, **kwargs) -> None:
        if obj.docstring is not None and ":" in obj.docstring.value:
            obj.docstring.value = replace_roles(obj.docstring.value, obj)
