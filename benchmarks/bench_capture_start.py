"""Issue 54 item 3: how long a camera capture takes to start, and the share of it that finds the sheet's
blank cells (where the coach may plan a spot, ``--aim anywhere``).

Run: python benchmarks/bench_capture_start.py [REPEATS]   (default 3; prints seconds)

Each repeat is a fresh Python process (imports count: a capture starts from the command line): an A4
sheet's layout.yaml (``lasercal sheet``), then ``start_capture`` of a fake camera session with the coach
(``--backend fake --camera fake``, aim anywhere by default) up to its first capture, timed; then the blank
cells alone (:func:`lasercal.collector.sessions.anywhere.cells`) in a second fresh process. Each twice: with
the cells found on the drawing (``vision.sheet.drawn_blank_spots``, what a capture used before issue 54)
and with the cells from the sheet's geometry (``vision.sheet.blank_spots``, what it uses now).
"""

from __future__ import annotations

import subprocess
import sys
import tempfile

# the drawn cells in the geometric ones' place (sessions.anywhere.cells imports blank_spots when called)
DRAWN = "import lasercal.vision.sheet as S; S.blank_spots = S.drawn_blank_spots\n"

START = """
import sys, time
from pathlib import Path
from lasercal.vision.sheet import design_sheet, write_layout
folder = Path(sys.argv[1])
layout = folder / "layout.yaml"
write_layout(layout, design_sheet("A4"), -8.0, {"x_mm": 450.0, "y_mm": 0.0, "yaw_deg": 0.0})
t0 = time.perf_counter()
from lasercal.collector.sessions.settings import capture_settings
from lasercal.collector.sessions.start import CaptureGuide, start_capture
given = {"backend": "fake", "per_point": 2, "camera": "fake", "seed": 5}
started = start_capture(capture_settings(given, str(layout), str(folder / "s")), CaptureGuide(auto=True))
assert started.spots is not None
print(time.perf_counter() - t0)
"""

CELLS = """
import sys, time
from pathlib import Path
from lasercal.vision.sheet import design_sheet, write_layout
from lasercal.solver.formats.session import load_layout
layout = Path(sys.argv[1]) / "layout.yaml"
write_layout(layout, design_sheet("A4"), -8.0, {"x_mm": 450.0, "y_mm": 0.0, "yaw_deg": 0.0})
loaded = load_layout(layout)
t0 = time.perf_counter()
from lasercal.collector.sessions.anywhere import cells
cells(loaded, layout)
print(time.perf_counter() - t0)
"""


def seconds(code: str) -> float:
    """The seconds a fresh process prints for ``code`` (run in a new temporary folder)."""
    with tempfile.TemporaryDirectory() as folder:
        out = subprocess.run([sys.executable, "-c", code, folder], capture_output=True, text=True, check=True)
    return float(out.stdout.split()[-1])


def main() -> None:
    repeats = int(sys.argv[1]) if len(sys.argv) > 1 else 3
    for how, head in (("drawn", DRAWN), ("geometric", "")):
        start = sorted(seconds(head + START) for _ in range(repeats))
        blank = sorted(seconds(head + CELLS) for _ in range(repeats))
        print(f"{how} cells: camera capture start-up {median(start):.2f} s, ", end="")
        print("of which the blank cells ", end="")
        print(f"{median(blank):.2f} s (medians of {repeats})")


def median(xs: list) -> float:
    """The middle of a sorted list."""
    return xs[len(xs) // 2]


if __name__ == "__main__":
    main()
