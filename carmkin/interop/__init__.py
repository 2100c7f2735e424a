"""Interoperability: X-ray simulators' camera conventions (:mod:`.simulators`), DICOM XA geometry
(:mod:`.dicom`) and optional DRR rendering on torch (:mod:`.drr`).

Nothing here imports a simulator, torch or pydicom on import; :mod:`.dicom` needs the ``dicom`` extra and
:mod:`.drr` the ``drr`` extra when their readers/renderers are called.
"""
