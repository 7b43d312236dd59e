"""The diagnosis on the user's path (issue 45): effects hidden in sheet and camera sessions, named or not.

Run: python benchmarks/bench_diagnose_sheet.py [SEEDS] [NULLS]   (prints a table; no assertions)

Every session is made and solved by the public commands, in-process, as a user runs them: a sheet printed
for ``--place 450 0 0`` (``lasercal sheet``) and laid 2 mm, 3 mm and 1 deg off it; ``lasercal simulate
panda_thesis_identified --layout sheet/layout.yaml --sheet-pose 452 3 1.0 --per-point 15 --effect E ...``
(75 captures at P1-P5); then ``lasercal solve S -o M.yaml --extend auto --json``. Three kinds of session:

* eye: every capture aimed at its cross by eye, 0.5 mm per axis;
* camera: every spot measured by the camera (0.03 mm per axis), aimed anywhere within 40 mm of its point;
* mixed: half measured, half aimed by eye at 0.5 mm (the spots the camera could not see).

A mis-measured point exists only where a layout's points are measured (here the sheet's five calibration
points measured in the base frame, a ``frame: base`` layout); on a printed sheet it is no candidate, and a
camera's measured spot does not use its point. 'named' = the finding is the hidden effect; 'located' =
exactly its joint (or point); 'gain' = the held-out gain of the extension over the geometry (mean over
the seeds where it was named, %). False alarms: sessions without an effect whose finding is not 'none'.
"""

from __future__ import annotations

import contextlib
import io
import json
import sys
import tempfile
import time
from pathlib import Path

from lasercal.collector.cli.main import main

KINDS = {"eye": ("0", "0.5"), "camera": ("1", "0.5"), "mixed": ("0.5", "0.5")}  # --measured, --aim-noise
EFFECTS = [  # (label, effect, joints or point, size): each moves an eye session's spots by about 1 mm RMS
    ("compliance j2", "joint_compliance", "2", "1.5e-4"),
    ("compliance j4", "joint_compliance", "4", "1.5e-4"),
    ("eccentricity j3", "encoder_eccentricity", "3", "3e-3"),
    ("drift j4", "drift", "4", "1e-6"),
    ("point P2 (measured layout)", "reference_point_offset", "P2", "1.5"),
]


def run(argv: list) -> tuple[int, str]:
    out = io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(io.StringIO()):
        code = main(argv)
    return code, out.getvalue()


MEASURED_LAYOUT = """format: lasercal-layout/1
units: {length: mm}
plane: {z: -8}
points: {P1: [481, 82, -8], P2: [481, -82, -8], P3: [450, 0, -8], P4: [419, 82, -8], P5: [419, -82, -8]}
calibration: [P1, P2, P3, P4, P5]
...
"""


def one(tmp: Path, layout: str, kind: str, seed: int, effect=None, per_point: int = 15) -> dict:
    """Simulate and solve one session (``per_point`` captures at each calibration point); the diagnosis as
    ``solve --json`` reports it."""
    measured, noise = KINDS[kind]
    s = tmp / f"s{seed}"
    argv = ["simulate", "panda_thesis_identified", "--layout", layout, "--per-point", str(per_point)]
    argv += ["--aim-noise", noise, "--measured", measured, "--seed", str(seed), "-o", str(s), "--force"]
    if layout.endswith("sheet/layout.yaml"):
        argv += ["--sheet-pose", "452", "3", "1.0"]
    if effect is not None:
        _, name, where, size = effect
        argv += ["--effect", name, "--effect-size", size]
        argv += ["--effect-point", where] if name == "reference_point_offset" else ["--effect-joints", where]
    code, text = run(argv)
    if code:
        raise RuntimeError(f"simulate failed: {text}")
    code, text = run(["solve", str(s), "-o", str(tmp / "m.yaml"), "--extend", "auto", "--json", "--force"])
    if code:
        raise RuntimeError(f"solve failed: {text}")
    return json.loads(text)["diagnosis"]


def main_(seeds: int, nulls: int) -> None:
    with tempfile.TemporaryDirectory() as d:
        tmp = Path(d)
        run(["sheet", "-o", str(tmp / "sheet"), "--robot", "panda", "--place", "450", "0", "0"])
        sheet = str(tmp / "sheet" / "layout.yaml")
        (tmp / "measured.yaml").write_text(MEASURED_LAYOUT)
        t0 = time.perf_counter()
        print(f"{'effect':28} {'kind':7} {'named':>6} {'located':>8} {'gain %':>7}   (of {seeds} seeds)")
        for effect in EFFECTS:
            point = effect[1] == "reference_point_offset"
            for kind in KINDS:
                if point and kind == "camera":
                    print(
                        f"{effect[0]:28} {kind:7} {'-':>6} {'-':>8} {'-':>7}   a measured spot uses no point"
                    )
                    continue
                named = located = 0
                gains = []
                for seed in range(seeds):
                    g = one(tmp, str(tmp / "measured.yaml") if point else sheet, kind, 100 + seed, effect)
                    if g["effect"] == effect[1]:
                        named += 1
                        gains.append(g["gain_percent"])
                        where = g["point"] if point else ",".join(map(str, g["joints"]))
                        located += where == effect[2]
                gain = f"{sum(gains) / len(gains):7.1f}" if gains else f"{'-':>7}"
                print(f"{effect[0]:28} {kind:7} {named:6d} {located:8d} {gain}", flush=True)
        for kind in KINDS:
            alarms = [g["label"] for g in (one(tmp, sheet, kind, 500 + s) for s in range(nulls))]
            wrong = [a for a in alarms if a != "none"]
            print(
                f"{'none (null sessions)':28} {kind:7} false alarms {len(wrong)} of {nulls} {wrong}",
                flush=True,
            )
        print(f"{time.perf_counter() - t0:.0f} s")


if __name__ == "__main__":
    main_(int(sys.argv[1]) if len(sys.argv) > 1 else 10, int(sys.argv[2]) if len(sys.argv) > 2 else 20)
