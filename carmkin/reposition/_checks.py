"""Argument checks shared by the repositioning modules: objects of the right type, joint vectors, random
generators; each a typed error naming the argument (numbers go through :mod:`carmkin.validation`)."""

from __future__ import annotations

import numpy as np

from carmkin.errors import CarmkinError
from carmkin import validation
from carmkin.validation import real_array


def instance(value, cls, name: str, error: type[CarmkinError]):
    """``value`` if it is a ``cls``, else ``error`` naming ``name`` (:func:`carmkin.validation.instance`)."""
    return validation.instance(value, cls, name, error=error)


def system(value, name: str, error: type[CarmkinError]):
    """``value`` as a :class:`~carmkin.model.system.CArmSystem`, else ``error``."""
    from carmkin.model.system import CArmSystem

    return instance(value, CArmSystem, name, error)


def joints(system, value, name: str, error: type[CarmkinError]) -> np.ndarray:
    """``value`` as a joint vector (nq,) of ``system`` (m, rad), else ``error``."""
    return real_array(value, name, (system.nq,), error=error, unit="m, rad")


def generator(value, name: str, error: type[CarmkinError]) -> np.random.Generator:
    """``value`` as a :class:`numpy.random.Generator`, else ``error``."""
    return instance(value, np.random.Generator, name, error)
