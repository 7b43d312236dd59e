"""Issue 38's figures: an eye-aimed session against a camera session, through the public command line.

As the outside check runs it: ``lasercal sheet --place 450 0 0``, ``capture --backend fake --auto
--per-point 9`` with ``--aim-noise 0.5`` (eye) and with ``--aim-noise 3 --camera fake`` (camera), each
``solve --extend auto``, then ``validate --backend fake -n 30 --point P6``; the figure is validate's
``error mean``. The floor: the true robot itself (the thesis's identified Panda, at the sheet's true pose)
validated in the same simulated world (the sheet where it was laid, as the printer scaled it).

    python benchmarks/bench_camera_capture.py [RUN ...]

RUN: name=capture options (default: the issue's, and each effect alone with the arm's repeatability);
about 2-3 minutes each on the 2-core machine. Prints one line per run.
"""

from __future__ import annotations

import re
import subprocess
import sys
import tempfile
from pathlib import Path

RUNS = {
    "eye (clean world, the default)": "--aim-noise 0.5",
    "eye, every effect": "--aim-noise 0.5 --effects all",
    "camera (every effect, the default)": "--aim-noise 3 --camera fake",
    "camera, hands-free (--guide move)": "--aim-noise 3 --camera fake --guide move",
    **{
        f"camera, repeatability + {e}": f"--aim-noise 3 --camera fake --effects repeatability,{e}"
        for e in ("distortion", "occlusion", "ellipse", "print-scale", "sheet-height")
    },
    "camera, repeatability alone": "--aim-noise 3 --camera fake --effects repeatability",
    "camera, no effect": "--aim-noise 3 --camera fake --effects none",
}


def lasercal(*args, cwd) -> str:
    out = subprocess.run(["lasercal", *args], cwd=cwd, capture_output=True, text=True, check=True)
    return out.stdout


def error_mean(text: str) -> float:
    return float(re.findall(r"error mean ([0-9.]+) mm", text)[-1])


def run(options: str, where: Path) -> tuple[float, float, float]:
    """(error mean, the floor, simulated seconds of the capture) of one session in folder ``where``."""
    from lasercal.solver.formats.robots import load_model
    from lasercal.solver.formats.session import load_session
    from lasercal.solver.kinematics.sheet import SheetPose

    lasercal("sheet", "-o", "sheet", "--place", "450", "0", "0", cwd=where)
    base = ["capture", "--layout", "sheet/layout.yaml", "--robot", "panda", "--backend", "fake", "--auto"]
    lasercal(*base, "--per-point", "9", *options.split(), "-o", "s", cwd=where)
    lasercal("solve", "s", "-o", "m.yaml", "--extend", "auto", cwd=where)
    val = ["--layout", "sheet/layout.yaml", "--backend", "fake", "-n", "30", "--point", "P6"]
    err = error_mean(lasercal("validate", "m.yaml", *val, "-o", "val", cwd=where))
    truth = load_model("panda_thesis_identified")  # at the sheet's placement: capture --backend fake's world
    world = load_session(where / "s").meta["simulated"].get("world", {})
    printed = SheetPose(450.0, 0.0, 0.0, *world.get("print_scale", (1.0, 1.0)))  # as the printer scaled it
    truth.replace(sheet=printed, identification={"session": "s"}, plane_z=-8.0).save(where / "truth.yaml")
    floor = error_mean(lasercal("validate", "truth.yaml", *val, "-o", "valtruth", cwd=where))
    return err, floor, float(load_session(where / "s").t[-1])


def main(argv: list[str]) -> None:
    runs = dict(a.split("=", 1) for a in argv) if argv else RUNS
    for name, options in runs.items():
        with tempfile.TemporaryDirectory() as d:
            err, floor, t = run(options, Path(d))
        print(f"{name:45s} error mean {err:.3f} mm, floor {floor:.3f} mm ({err / floor:.2f} x), {t:.0f} s")


if __name__ == "__main__":
    main(sys.argv[1:])
