"""A per-system cache that writes nothing into the (frozen) :class:`~carmkin.model.system.CArmSystem`.

Solvers built from a system (the closed-form IK's constants, the damped-least-squares solver's Pinocchio
data) are built on first use and kept as long as the system object lives. Keyed by the object's identity
through a weak reference, not by its hash: hashing a system walks all its nested dataclasses (~3 µs, a fifth
of a closed-form IK call), and a built value belongs to one object anyway. The cached value must not hold
the system strongly (keep a ``weakref.ref`` to it instead), or the entry would never be freed.
"""

from __future__ import annotations

import functools
import weakref
from collections.abc import Callable
from typing import TypeVar

T = TypeVar("T")


def per_system(build: Callable[[object], T]) -> Callable[[object], T]:
    """Decorate ``build(system) -> value`` so that it runs once per live system object."""
    cache: dict[int, tuple[weakref.ref, T]] = {}

    @functools.wraps(build)
    def get(system) -> T:
        key = id(system)
        entry = cache.get(key)
        if entry is not None and entry[0]() is system:
            return entry[1]
        value = build(system)

        def forget(ref, key=key):  # the system is gone: drop its entry (unless a new object took the id)
            if cache.get(key, (None,))[0] is ref:
                del cache[key]

        cache[key] = (weakref.ref(system, forget), value)
        return value

    get.cache = cache  # for tests
    return get
