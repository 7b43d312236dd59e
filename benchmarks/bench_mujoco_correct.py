"""Issue 46: ``lasercal correct`` on a MuJoCo world's truth -- commands from the calibrated model, the error
by MuJoCo's forward kinematics.

    python benchmarks/bench_mujoco_correct.py DIR [N]

DIR is a folder ``bench_mujoco.py`` filled (scene/, model.yaml). Goals: the nominal fr3's flange at N
configurations aiming at the sheet (``x,y,z`` mm, base frame). Before: the nominal's own configurations
commanded; after: ``lasercal correct model.yaml goals.csv``'s. Each command is settled in the world (its
servos, gravity, passive joints) and the flange (107 mm along joint 7's axis from link 7's frame, as
franka_description puts it; the hand and laser mounted on it are tools) read from MuJoCo, in the robot's
own base frame (eq. S2: joint 1 as the nominal's, joint 2's direction at q = 0 as the nominal's: the frame
every sheet calibration is in), built from MuJoCo's own joint axes at q = 0.
"""

from __future__ import annotations

import csv
import os
import subprocess
import sys
from pathlib import Path

import numpy as np

os.environ.setdefault("MUJOCO_GL", "egl")

from lasercal.collector.worlds.mujoco import MujocoWorld  # noqa: E402
from lasercal.solver.formats.robots import load_model  # noqa: E402
from lasercal.solver.formats.session import load_layout  # noqa: E402
from lasercal.solver.kinematics.aim import aim  # noqa: E402
from lasercal.solver.kinematics.frames import own_frame  # noqa: E402
from lasercal.solver.kinematics.poe import poe_chain  # noqa: E402


def true_screws(world: MujocoWorld) -> np.ndarray:
    """The world's joint screws at q = 0 (n, 6): MuJoCo's axes and anchors, mm."""
    import mujoco

    d = world.d
    keep = d.qpos.copy()
    d.qpos[:] = 0
    mujoco.mj_kinematics(world.m, d)
    S = []
    for name in world.c.joints:
        j = world.m.joint(name).id
        w, p = d.xaxis[j].copy(), d.xanchor[j] * 1e3
        S.append(np.r_[w, -np.cross(w, p)])
    d.qpos[:] = keep
    mujoco.mj_kinematics(world.m, d)
    return np.array(S)


def flange_in_own_frame(world: MujocoWorld, q: np.ndarray, G: np.ndarray) -> np.ndarray:
    world.command(q)
    world.step(world._path[1] + 1.5)
    b = world.m.body("fr3_link7").id  # the flange: 107 mm along joint 7's axis from link 7's frame
    p = (world.d.xpos[b] + world.d.xmat[b].reshape(3, 3) @ [0, 0, 0.107]) * 1e3
    return G[:3, :3] @ p + G[:3, 3]


def main() -> None:
    d = Path(sys.argv[1])
    n = int(sys.argv[2]) if len(sys.argv) > 2 else 30
    nominal = load_model("fr3")
    world = MujocoWorld(d / "scene" / "scene.xml")
    G = own_frame(nominal.replace(screws=true_screws(world)), nominal)
    layout = load_layout(d / "sheet" / "layout.yaml")
    rng = np.random.default_rng(46)
    xy = rng.uniform([-60, -100], [60, 100], (n, 2))
    q = np.vstack([aim(nominal, layout.sheet.to_base(p[None], layout.plane_z)[0], 1, rng)[0] for p in xy])
    goals = (poe_chain(nominal.screws, q)[:, -1] @ nominal.ee_pose)[:, :3, 3]
    with open(d / "goals.csv", "w") as f:
        f.write("x,y,z\n" + "".join(f"{float(a)!r},{float(b)!r},{float(c)!r}\n" for a, b, c in goals))
    p = subprocess.run(
        [sys.executable, "-m", "lasercal.collector.cli.main", "correct", d / "model.yaml", d / "goals.csv",
         "-o", d / "commands.csv", "--force"], capture_output=True, text=True,
    )  # fmt: skip
    if p.returncode not in (0, 1):
        raise SystemExit(p.stderr)
    with open(d / "commands.csv") as f:
        rows = list(csv.DictReader(line for line in f if not line.startswith("#")))
    cmd = np.array([[float(r[f"cmd_q{j}"]) for j in range(1, 8)] for r in rows])
    before = [np.linalg.norm(flange_in_own_frame(world, qi, G) - g) for qi, g in zip(q, goals)]
    after = [np.linalg.norm(flange_in_own_frame(world, qi, G) - g) for qi, g in zip(cmd, goals)]
    print(
        f"flange at {n} goals, MuJoCo's FK in the robot's own frame: nominal commands "
        f"{np.mean(before):.3f} mm mean ({np.max(before):.3f} max); lasercal correct {np.mean(after):.3f} mm "
        f"({np.max(after):.3f} max)"
    )


if __name__ == "__main__":
    main()
