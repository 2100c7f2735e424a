"""Back to the view of an earlier image stored as DICOM: the joint and table moves that reproduce the
geometry of an XA or Enhanced XA dataset (read by :mod:`carmkin.interop.dicom_io`, the ``dicom`` extra)
from the current configuration, through :func:`carmkin.qp_ik.solve`. Lengths in m, angles in rad.
"""

from __future__ import annotations

from carmkin.interop import dicom, dicom_io


def moves_for_dataset(system, ds, q_current=None, isocenter=None, patient_origin=(0.0, 0.0, 0.0), *,
                      frame: int = 0, patient_position: str | None = None, convention: str = dicom.DEFAULT_CONVENTION,
                      source_to_isocenter: float | None = None, **solve_kwargs):
    """``(view, result)``: the dataset's view (:func:`~carmkin.interop.dicom_io.view_from_dataset`, same
    arguments) and the :func:`carmkin.qp_ik.solve` result reaching it from ``q_current`` (joints and table
    joints; ``result.q − q_current`` are the moves). An Enhanced XA view is a full pose; XA angles fix the source
    position and the beam, the rotation about the beam stays free (:class:`carmkin.qp_ik.AxisTarget`)."""
    from carmkin import qp_ik  # Pinocchio and the QP solvers load here

    dicom._system(system)
    view = dicom_io.view_from_dataset(ds, isocenter, patient_origin, frame=frame, patient_position=patient_position,
                                      convention=convention, source_to_isocenter=source_to_isocenter)
    target = view.pose if view.full_pose else qp_ik.AxisTarget(tuple(view.pose[:3, 3]), tuple(view.pose[:3, 2]))
    return view, qp_ik.solve(system, target, q_current=q_current, **solve_kwargs)
