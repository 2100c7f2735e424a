"""Interoperability: X-ray simulators' camera conventions (:mod:`.simulators`), DICOM XA geometry
(:mod:`.dicom`; datasets and moves to a DICOM view in :mod:`.dicom_io`), DRR rendering on torch
(:mod:`.drr`; rendered panoramas are the panorama planner's, :mod:`carmkin.panorama.drr`) and the round-trip check of issue 15
(:mod:`.check`).

Nothing here imports a simulator, torch or pydicom on import: :mod:`.dicom_io` needs the ``dicom`` extra and
:mod:`.drr` the ``drr`` extra when their readers/renderers are called.
"""
