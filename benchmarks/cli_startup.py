"""How long a user waits for the CLI before anything happens: ``econmotor --help`` and a bad-input error.

Every command's module is imported to build the Typer app, so whatever they import at module level is
paid by ``--help`` and by every one-line error. scipy.stats / scipy.optimize (the error-rate bounds) and
matplotlib (the report plots) are imported where they are used; this script times, side by side and
alternating, each in a fresh interpreter:

- ``econmotor --help``;
- ``econmotor report --task-id no_such_task`` (a one-line error, exit 2);
- ``econmotor --help`` with those three imported first, as the CLI did before (``-c``, the same app).

Run: ``.venv/bin/python benchmarks/cli_startup.py [--repeats 7]``. It prints the median wall seconds of
each and the ratio lazy / eager for ``--help``.
Measured on the project's 2 idle cores, 7 runs each: median ``--help`` 1.32 s lazy against 2.73 s
with the eager imports (ratio 0.48); the bad task id in 1.62 s (before this change, with torch also
imported before the flags were checked, about 7 s on a loaded machine).
"""

from __future__ import annotations

import argparse
import statistics
import subprocess
import sys
import time

SMOKE_ARGS: list[str] = ["--repeats", "1"]

EAGER = ("import scipy.stats, scipy.optimize, matplotlib.figure, matplotlib.backends.backend_agg; "
         "from econmotor.cli import entrypoint; import sys; sys.argv = ['econmotor', '--help']; entrypoint()")
CASES = {
    "--help": ([sys.executable, "-m", "econmotor", "--help"], 0),
    "bad task id": ([sys.executable, "-m", "econmotor", "report", "--task-id", "no_such_task"], 2),
    "--help, eager imports": ([sys.executable, "-c", EAGER], 0),
}


def wall_s(cmd: list[str], expected_rc: int) -> float:
    started = time.perf_counter()
    done = subprocess.run(cmd, capture_output=True, text=True, check=False)
    elapsed = time.perf_counter() - started
    if done.returncode != expected_rc:
        raise SystemExit(f"{' '.join(cmd)} exited {done.returncode}, expected {expected_rc}:\n{done.stderr[-2000:]}")
    return elapsed


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=7, help="runs of each case, alternating")
    args = parser.parse_args()
    times: dict[str, list[float]] = {name: [] for name in CASES}
    for _ in range(args.repeats):
        for name, (cmd, rc) in CASES.items():
            times[name].append(wall_s(cmd, rc))
    median = {name: statistics.median(ts) for name, ts in times.items()}
    print(f"CLI start-up, median of {args.repeats} fresh interpreters each (wall seconds):")
    for name, value in median.items():
        print(f"  {name:<24}{value:6.2f} s")
    print(f"ratio --help lazy / eager imports: {median['--help'] / median['--help, eager imports']:.2f}")


if __name__ == "__main__":
    main()
