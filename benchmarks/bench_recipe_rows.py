"""Issue 51: the spread of tests/test_poses.py::test_the_real_data_recipe_runs_as_written's figure.

    python benchmarks/bench_recipe_rows.py [DATA] [--step 8] [--offsets 0 1 ... 7]

docs/real-data.md's UR10 block, command by command, on every STEP-th row of the three series starting at
row OFFSET (the test takes offset 0, step 8): fit A+B (``solve --extend auto``), register on C1, predict C2.
Prints, per offset, the mean position error of the prediction and of the nominal UR10 registered on C1 (the
test's two numbers) and their ratio; then the spread over the offsets.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import shlex
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]


def recipe(data: Path, tmp: Path, step: int, offset: int) -> tuple[float, float]:
    from lasercal.collector.cli.main import main
    from lasercal.solver.analysis.pose_cv import predict_session, register
    from lasercal.solver.formats.poses import frames_from_pose, load_pose_session
    from lasercal.solver.formats.robots import load_model
    from lasercal.solver.identify.poses import errors

    block = (ROOT / "docs" / "real-data.md").read_text().split("## A UR10 and a laser tracker", 1)[1]
    block = block.split("```bash\n", 1)[1]
    lines = [ln.split("  #")[0].strip() for ln in block.split("```", 1)[0].splitlines()]
    lines = [ln for ln in lines if ln.startswith(("lasercal ", "cut "))]
    sub = tmp / "ur10-tracker"
    for name in ("Series_A", "Series_B", "Series_C"):
        (src,) = (data / name).glob("measurements_*.csv")
        rows = src.read_text().splitlines()
        (sub / name).mkdir(parents=True)
        (sub / name / src.name).write_text("\n".join(rows[:1] + rows[1 + offset :: step]) + "\n")
    for line in lines:
        line = line.replace("../shared/data/ur10-tracker", str(sub))
        if line.startswith("cut "):
            subprocess.run(line, shell=True, check=True, cwd=tmp)
        else:
            with contextlib.redirect_stdout(io.StringIO()), contextlib.chdir(tmp):
                assert main(shlex.split(line)[1:]) == 0, line
    c1, c2 = load_pose_session(tmp / "C1"), load_pose_session(tmp / "C2")
    got = np.genfromtxt(tmp / "poses.csv", delimiter=",", names=True)
    pred = frames_from_pose(np.stack([got[k] for k in ("x", "y", "z", "rx", "ry", "rz")], axis=1))
    model_err = errors(pred, c2.T)[0].mean()
    nominal = register(load_model("ur10"), c1)
    return model_err, errors(predict_session(nominal, c2), c2.T)[0].mean()


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("data", nargs="?", default=str(ROOT.parent / "shared" / "data" / "ur10-tracker"))
    ap.add_argument("--step", type=int, default=8)
    ap.add_argument("--offsets", type=int, nargs="+", default=list(range(8)))
    a = ap.parse_args()
    out = []
    for k in a.offsets:
        with tempfile.TemporaryDirectory() as t:
            m, n = recipe(Path(a.data), Path(t), a.step, k)
        out.append((m, n))
        print(f"offset {k}: predicted C2 {m:.4f} mm mean, nominal registered on C1 {n:.4f} mm, "
              f"ratio {m / n:.3f}", flush=True)  # fmt: skip
    m, n = np.array(out).T
    print(f"{len(out)} offsets: model {m.min():.4f}-{m.max():.4f} mm (mean {m.mean():.4f}, "
          f"sd {m.std(ddof=1):.4f}); ratio {(m / n).min():.3f}-{(m / n).max():.3f}")  # fmt: skip
    sys.stdout.flush()


if __name__ == "__main__":
    main()
