"""What ``patient=`` accepts everywhere (views, sweeps): ``None``, one
:class:`~carmkin.robot.collision.Obstacle`, a list of them, or a patient model with ``obstacles()``
(:class:`~carmkin.patient.ParametricPatient`, :class:`~carmkin.patient.CTPatient`)."""

from __future__ import annotations

from carmkin.errors import CarmkinError, PatientModelError


def as_obstacles(patient, error: type[CarmkinError] = PatientModelError) -> tuple:
    """``patient`` as a tuple of :class:`~carmkin.robot.collision.Obstacle` (empty for ``None``), or ``error``."""
    from carmkin.robot.collision import Obstacle

    if patient is None:
        return ()
    if hasattr(patient, "obstacles") and callable(patient.obstacles):
        patient = patient.obstacles()
    if isinstance(patient, Obstacle):
        patient = [patient]
    expected = "a patient model (ParametricPatient, CTPatient) or a list of carmkin.robot.collision.Obstacle"
    if isinstance(patient, (str, bytes, dict)):
        raise error(f"patient must be {expected}, got {type(patient).__name__}")
    try:
        items = tuple(patient)
    except TypeError:
        raise error(f"patient must be {expected}, got {type(patient).__name__}") from None
    for item in items:
        if not isinstance(item, Obstacle):
            raise error(f"patient must be {expected}, got an item {type(item).__name__}")
    return items
