"""Start-up cost: ``python -c "import carmkin"`` and ``carmkin --help`` against ``python -c "import numpy"``.

Each command runs in a fresh interpreter (subprocess), the three round-robin so that a busy machine slows
them alike; the medians and their ratios to the numpy baseline measured in the same run are printed with the
targets of issue 12 (import ≤ 1.5×, --help ≤ 2×), each "met" or "MISSED". Bytecode caching is on for the runs
(:data:`ENVIRONMENT`), as for an installed copy. Speed is reported, never asserted.

Run: python benchmarks/bench_import.py [--quick]
"""

from __future__ import annotations

import argparse
import os
import shutil
import statistics
import subprocess
import sys
import time
from pathlib import Path

#: Targets of issue 12: ratio to ``python -c "import numpy"``.
TARGETS = {"import carmkin": 1.5, "carmkin --help": 2.0}


def carmkin_command() -> list[str]:
    """The installed ``carmkin`` script next to this interpreter, else ``python -m carmkin.cli``."""
    script = Path(sys.executable).with_name("carmkin")
    if script.is_file():
        return [str(script)]
    found = shutil.which("carmkin")
    return [found] if found else [sys.executable, "-m", "carmkin.cli"]


#: The commands run with bytecode caching on (``PYTHONDONTWRITEBYTECODE`` removed): numpy's wheel ships its
#: compiled modules and an installed carmkin has them too, while with the variable set (as on some development
#: machines) carmkin's source would be compiled again at every start-up (about a third of its import time), a
#: cost no installed copy pays.
ENVIRONMENT = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}


def wall_time(command: list[str]) -> float:
    start = time.perf_counter()
    subprocess.run(command, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, check=True, env=ENVIRONMENT)
    return time.perf_counter() - start


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--quick", action="store_true", help="fewer repetitions (CI)")
    parser.add_argument("--repeat", type=int, default=None, help="runs of each command (default 21, quick 7)")
    args = parser.parse_args()
    repeat = args.repeat or (7 if args.quick else 21)
    commands = {
        "import numpy": [sys.executable, "-c", "import numpy"],
        "import carmkin": [sys.executable, "-c", "import carmkin"],
        "carmkin --help": [*carmkin_command(), "--help"],
    }
    for command in commands.values():  # warm the file cache and write the bytecode of what is not compiled yet
        wall_time(command)
    times: dict[str, list[float]] = {name: [] for name in commands}
    for _ in range(repeat):
        for name, command in commands.items():
            times[name].append(wall_time(command))
    baseline = statistics.median(times["import numpy"])
    print(f"median wall time of a fresh interpreter over {repeat} runs each, round-robin ({sys.executable})")
    for name, samples in times.items():
        median = statistics.median(samples)
        target = TARGETS.get(name)
        verdict = "" if target is None else f"  target <= {target:g}x: {'met' if median / baseline <= target else 'MISSED'}"
        print(f"{name:<18}{median * 1e3:9.1f} ms  {median / baseline:6.2f}x import numpy{verdict}")


if __name__ == "__main__":
    main()
