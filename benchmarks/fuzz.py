"""The long fuzz run of issue 19: generated calls over the public entry points, each answer checked by an
oracle (a round trip or an independent formula), sorted into ok / typed error / untyped / silent wrong /
warnings / hangs (see docs/fuzz.md; the engine and the entry points live in tests/fuzz_*.py).

    python benchmarks/fuzz.py --cases 100000           # the acceptance run (prints the table)
    python benchmarks/fuzz.py --cases 2000 --seed 3    # a quick one

Exit status 1 when any entry point outside ``KNOWN`` (findings in other owners' files) has a finding.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

import fuzz_engine  # noqa: E402
import fuzz_entries  # noqa: E402
import fuzz_entries_junk  # noqa: E402
import fuzz_entries_more  # noqa: E402
import fuzz_entries_systems  # noqa: E402


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--cases", type=int, default=100_000, help="total cases over all entry points (default 100000)")
    parser.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    parser.add_argument("--examples", type=int, default=2, help="findings printed per entry point (default 2)")
    args = parser.parse_args(argv)
    entries = {**fuzz_entries.ENTRIES, **fuzz_entries_systems.ENTRIES, **fuzz_entries_more.ENTRIES,
               **fuzz_entries_junk.ENTRIES}
    start = time.perf_counter()
    tallies = fuzz_engine.run(entries, args.cases, args.seed, args.examples)
    print(fuzz_engine.table(tallies))
    print(f"\n{sum(t.cases for t in tallies.values())} cases over {len(tallies)} entry points, seed {args.seed}, "
          f"{time.perf_counter() - start:.0f} s")
    status = 0
    for name, tally in tallies.items():
        if fuzz_engine.findings(tally):
            known = fuzz_entries_systems.KNOWN.get(name)
            print(f"\n{name}: {'KNOWN (' + known + ')' if known else 'FINDING'}")
            for line in tally.examples:
                print(f"  {line[:300]}")
            status = status or (0 if known else 1)
    return status


if __name__ == "__main__":
    sys.exit(main())
