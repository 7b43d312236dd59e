"""Issues 38 and 45's figures: an eye-aimed session against a camera session, through the public command line,
and what no model can beat in the same simulated world.

As the outside check runs it: ``lasercal sheet --place 450 0 0``, ``capture --backend fake --auto
--per-point 9`` with ``--aim-noise 0.5`` (eye) and with ``--aim-noise 3 --camera fake`` (camera), each
``solve --extend auto``, then ``validate --backend fake -n 30 --point P6``; the figure is validate's
``error mean``. The floors (:func:`collector.studies.floors.floors`), in the session's own world (the
world's own code: the paper as printed, skewed, bulged, on a sloping table, the lens corrected by
camera-calibrate's estimate, the spot's subsurface glow):

* honest: the true robot itself, aimed at P6 where it truly lies on the paper and commanded through its
  own effects, photographed and measured as validate does -- the arm's repeatability and the camera's
  measurement are all that is left;
* repeatability: the same poses, where the true beam truly meets the paper (no camera).

Each line also gives what ``solve`` found of the sheet against the world's own paper
(:func:`collector.worlds.record.true_sheet_pose`): found - true print scale x, y and tilt x, y, in the
sigmas ``solve`` reports (eq. S4: residuals in the printed sheet's mm, so the common scale has no bias to
pay).

    python benchmarks/bench_camera_capture.py [RUN ...]

RUN: name=capture options (default: the issue's, and each effect alone with the arm's repeatability);
about 3-4 minutes each on the 2-core machine. Prints one line per run.
"""

from __future__ import annotations

import re
import subprocess
import sys
import tempfile
from pathlib import Path

from lasercal.collector.worlds.fakeworld import EFFECTS

RUNS = {
    "eye (clean world, the default)": "--aim-noise 0.5",
    "eye, every effect": "--aim-noise 0.5 --effects all",
    "camera (every effect, the default)": "--aim-noise 3 --camera fake",
    "camera, hands-free (--guide move)": "--aim-noise 3 --camera fake --guide move",
    **{
        f"camera, repeatability + {e}": f"--aim-noise 3 --camera fake --effects repeatability,{e}"
        for e in EFFECTS[1:]
    },
    "camera, repeatability alone": "--aim-noise 3 --camera fake --effects repeatability",
    "camera, no effect": "--aim-noise 3 --camera fake --effects none",
}


def lasercal(*args, cwd) -> str:
    out = subprocess.run(["lasercal", *args], cwd=cwd, capture_output=True, text=True, check=True)
    return out.stdout


def error_mean(text: str) -> float:
    return float(re.findall(r"error mean ([0-9.]+) mm", text)[-1])


def sheet_sigmas(where: Path) -> list[float]:
    """Found - true print scale x, y and tilt x, y of the solved sheet (m.yaml), in its reported sigmas."""
    import yaml

    from lasercal.collector.worlds.record import session_world, true_sheet_pose
    from lasercal.solver.formats.robots import load_model
    from lasercal.solver.formats.session import load_layout

    model = yaml.safe_load((where / "m.yaml").read_text())
    z = load_layout(where / "sheet" / "layout.yaml").plane_z
    true, _ = true_sheet_pose(session_world(where / "s"), load_model("panda"), z)
    keys = ("scale_x", "scale_y", "tilt_x_rad", "tilt_y_rad")
    return [(model["sheet"][k] - getattr(true, k)) / model["sheet_std"][k] for k in keys]


def run(options: str, where: Path) -> tuple[float, float, float, float, list[float]]:
    """(error mean, honest floor, repeatability floor, simulated seconds of the capture, the sheet's
    found - true scale and tilt in sigmas) of one session."""
    from lasercal.collector.studies.floors import floors
    from lasercal.solver.formats.session import load_session

    lasercal("sheet", "-o", "sheet", "--place", "450", "0", "0", cwd=where)
    base = ["capture", "--layout", "sheet/layout.yaml", "--robot", "panda", "--backend", "fake", "--auto"]
    lasercal(*base, "--per-point", "9", *options.split(), "-o", "s", cwd=where)
    lasercal("solve", "s", "-o", "m.yaml", "--extend", "auto", cwd=where)
    val = ["--layout", "sheet/layout.yaml", "--backend", "fake", "-n", "30", "--point", "P6"]
    opts = options.split()
    if "--truth" in opts:  # validated on the same true arm the session captured
        val += ["--truth", opts[opts.index("--truth") + 1]]
    err = error_mean(lasercal("validate", "m.yaml", *val, "-o", "val", cwd=where))
    honest, repeat = floors(where / "s", where / "sheet" / "layout.yaml", "P6", 30, 0)
    return err, honest, repeat, float(load_session(where / "s").t[-1]), sheet_sigmas(where)


def main(argv: list[str]) -> None:
    runs = dict(a.split("=", 1) for a in argv) if argv else RUNS
    for name, options in runs.items():
        with tempfile.TemporaryDirectory() as d:
            err, honest, repeat, t, z = run(options, Path(d))
        print(
            f"{name:45s} error mean {err:.3f} mm; floors: honest {honest:.3f} mm ({err / honest:.2f} x), "
            f"repeatability {repeat:.3f} mm ({err / repeat:.2f} x); {t:.0f} s; sheet found - true in "
            f"sigmas: scale {z[0]:+.2f} {z[1]:+.2f}, tilt {z[2]:+.2f} {z[3]:+.2f}",
            flush=True,
        )


if __name__ == "__main__":
    main(sys.argv[1:])
