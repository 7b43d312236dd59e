"""CI's time: the README's test command (what .ci/run runs), its wall and CPU seconds, and the files that
take longest (issue 37: under 10 minutes on a two-core machine).

    python benchmarks/bench_ci.py            # the whole suite, as .ci/run runs it
    python benchmarks/bench_ci.py -n 2 tests/test_identify.py   # other pytest arguments

Prints the wall time, the CPU time of pytest and its workers (user + system: on a busy machine the wall
time grows, the CPU time does not), and each file's summed test time (setup, call and teardown) from
pytest's JUnit XML, longest first: the files to list in tests/conftest.py's RUN_FIRST.
"""

from __future__ import annotations

import collections
import resource
import subprocess
import sys
import tempfile
import time
import xml.etree.ElementTree as ET
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
COMMAND = ["-n", "auto"]  # the README's `python -m pytest -n auto` (pyproject adds --dist loadfile)


def main(args: list[str]) -> None:
    with tempfile.TemporaryDirectory() as tmp:
        junit = Path(tmp) / "junit.xml"
        t0 = time.perf_counter()
        run = subprocess.run(
            [
                sys.executable,
                "-m",
                "pytest",
                *(args or COMMAND),
                f"--junitxml={junit}",
                "-p",
                "no:cacheprovider",
            ],
            cwd=ROOT,
        )
        wall = time.perf_counter() - t0
        use = resource.getrusage(resource.RUSAGE_CHILDREN)
        per_file = collections.Counter()
        for case in ET.parse(junit).getroot().iter("testcase"):
            per_file[case.get("classname")] += float(case.get("time"))
    print(
        f"exit {run.returncode}: wall {wall:.0f} s, CPU {use.ru_utime + use.ru_stime:.0f} s (user + system)"
    )
    for name, seconds in per_file.most_common(20):
        print(f"{seconds:8.1f} s  {name}")


if __name__ == "__main__":
    main(sys.argv[1:])
