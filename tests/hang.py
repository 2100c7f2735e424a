"""The tests' one hang guard: how long a test waits for a subprocess, an output line, a file or a socket before
it calls the thing hung.

It is a guard against a hang, never a performance bound: the README's test command must pass on a shared,
loaded machine (2 cores at load 13 made a 96 s CPU command take several minutes of wall time), so a test never
fails for being slow. A test waits *until* what it waits for happens (a loop that ends at once when it does),
bounded by this guard. How fast things are is measured in ``benchmarks/`` (ratios against a baseline).
"""

#: Seconds a test waits for anything before it calls it hung (30 min: far over the slowest command the tests run,
#: ``carmkin reproduce all``, 96 s of CPU, even at load 13 on 2 cores).
HANG_GUARD_S = 1800.0
