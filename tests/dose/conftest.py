"""Make tests/dose/pyskindose_oracle.py importable (the PySkinDose cross-check, also run as a script)."""

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).parent))
