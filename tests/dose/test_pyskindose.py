"""carmkin.dose against PySkinDose 25.1.1 on its four example reports (extra ``dose-check``; skipped without it).

Same skin cells (PySkinDose's plane phantom), same corrections (its tables), same secondary-angle reading
(``secondary="pyskindose"``): the acceptance of issue 38 asks the PSD within ±5 % per report and each event's
field centre within 5 mm. ``python tests/dose/pyskindose_oracle.py`` prints the numbers.
"""

import pytest

pytest.importorskip("pyskindose", reason="PySkinDose is the oracle (extra dose-check: pip install pyskindose==25.1.1)")
pytest.importorskip("pydicom", reason="read_rdsr needs pydicom (extra dose)")
import pyskindose_oracle  # noqa: E402

#: The acceptance's bounds (issue 38).
PSD_AGREEMENT = 0.05
FIELD_CENTRE_MM = 5.0


@pytest.mark.parametrize("name", list(pyskindose_oracle.REPORTS))
def test_psd_and_field_centres_agree_with_pyskindose(name):
    row = pyskindose_oracle.compare(name)
    print(row)
    assert row["max_field_centre_offset_mm"] <= FIELD_CENTRE_MM
    if row["psd_pyskindose_gy"] == 0.0:
        # philips_allura_clarity_u104: PySkinDose's Philips table offset puts the isocentre 21 cm beyond the
        # table's head end, where its plane phantom (which starts there) is not: no field reaches it, in both
        assert row["psd_carmkin_gy"] == 0.0 and row["events_compared"] == 0
    else:
        assert abs(row["psd_ratio"] - 1.0) <= PSD_AGREEMENT and row["events_compared"] >= 10
