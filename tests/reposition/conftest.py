"""The repositioning tests need OpenCV (the ``reposition`` extra); skip them cleanly without it."""

import pytest

pytest.importorskip("cv2", reason="OpenCV (pip install 'carmkin[reposition]') is needed by carmkin.reposition")
