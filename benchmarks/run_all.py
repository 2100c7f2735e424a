"""Run every benchmark in this folder one after the other: python benchmarks/run_all.py [--quick].

Every ``bench_*.py`` is run, then ``presets_acceptance.py`` (issue 30: every preset's acceptance row) and
``acceptance_biplane.py`` (the biplane's two-plane rows), e.g. bench_fk, bench_ik, bench_qp_ik, bench_table_ik, bench_workspace and
bench_import (start-up time of ``import carmkin`` and ``carmkin --help`` against ``import numpy``).
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path


def main() -> int:
    here = Path(__file__).parent
    status = 0
    for script in [*sorted(here.glob("bench_*.py")), here / "presets_acceptance.py",
                   here / "acceptance_biplane.py"]:
        print(f"\n=== {script.name} ===", flush=True)
        status |= subprocess.call([sys.executable, str(script), *sys.argv[1:]])
    return status


if __name__ == "__main__":
    sys.exit(main())
