"""How thin the command line is (issue 32): lines of ``collector/cli/`` and its longest handlers, and the
time ``import lasercal`` takes on its own.

Run: python benchmarks/bench_cli_size.py [REPO]   (REPO: another checkout's lines, without the import time;
default this one; prints numbers, no assertions). A handler is a ``cmd_*`` or ``*_command`` function of
``collector/cli/``; its length is its lines from ``def`` to its last statement.
"""

from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path


def handlers(cli: Path) -> tuple[int, list[tuple[int, str]]]:
    """Lines of every module in ``cli`` and (length, file:name) of each handler, longest first."""
    total, found = 0, []
    for f in sorted(cli.glob("*.py")):
        text = f.read_text()
        total += len(text.splitlines())
        for node in ast.walk(ast.parse(text)):
            if isinstance(node, ast.FunctionDef) and (
                node.name.startswith("cmd_") or node.name.endswith("_command")
            ):
                found.append((node.end_lineno - node.lineno + 1, f"{f.name}:{node.name}"))
    return total, sorted(found, reverse=True)


def import_seconds(repeat: int = 5) -> float:
    """Median self time (s) of ``import lasercal`` from ``python -X importtime`` in new processes."""
    times = []
    for _ in range(repeat):
        err = subprocess.run(
            [sys.executable, "-X", "importtime", "-c", "import lasercal"], capture_output=True, text=True
        ).stderr
        line = next(ln for ln in err.splitlines() if ln.rstrip().endswith("| lasercal"))
        times.append(int(line.split("|")[1]) * 1e-6)  # cumulative microseconds of the package
    return sorted(times)[len(times) // 2]


def main() -> None:
    repo = Path(sys.argv[1]) if len(sys.argv) > 1 else Path(__file__).resolve().parents[1]
    total, found = handlers(repo / "collector" / "cli")
    print(f"collector/cli/: {total} lines, {len(found)} handlers")
    for n, name in found[:5]:
        print(f"  {n:4d} lines  {name}")
    if len(sys.argv) == 1:  # (the installed lasercal: this checkout's)
        print(f"import lasercal: {import_seconds():.4f} s (python -X importtime, cumulative, median of 5)")


if __name__ == "__main__":
    main()
