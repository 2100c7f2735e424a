"""The repositioning tests need OpenCV (the ``reposition`` extra, part of ``test``); without it they are not
collected, so a core-only install still runs the rest of the suite."""

import importlib.util

if importlib.util.find_spec("cv2") is None:  # pragma: no cover - CI installs the extra
    collect_ignore_glob = ["test_*.py"]
