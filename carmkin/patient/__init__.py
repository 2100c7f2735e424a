"""The patient in the world: a parametric body from height and mass, or a body from a CT.

Either becomes obstacles of the collision scene (:meth:`obstacles`), placed by DICOM Patient Position.
"""

from .body import ParametricPatient
from .ct import CTPatient

__all__ = ["CTPatient", "ParametricPatient"]
