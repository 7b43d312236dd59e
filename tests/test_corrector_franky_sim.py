"""docs/examples/franky_corrector.py on franky-sim: the corrector in a franky JointImpedanceTracker loop
follows a circle of goals tick by tick; the commands it streams are ``correct``'s, and the simulated arm
tracks them.

The harness is tests/test_collector_franky_sim.py's (a simulator on its own loopback address, in a network
namespace where the machine allows it); run as a script, this file is the scenario's side of it.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]
SIM = Path(__file__).resolve().parent / "test_collector_franky_sim.py"
SECONDS, PERIOD = 3.0, 0.001


def scenario(workdir: str, host: str) -> dict:
    """Follow a 3 s circle (50 mm) from the simulator's start on a calibrated FR3 model; report."""
    sys.path.insert(0, str(ROOT / "docs" / "examples"))
    import franky
    from franky_corrector import circle, follow

    from lasercal.collector.worlds.fake import perturbed_model
    from lasercal.solver.control.corrector import Corrector
    from lasercal.solver.control.robot import Robot
    from lasercal.solver.formats.robots import load_model

    nominal = load_model("fr3")
    model = perturbed_model(nominal, seed=5).replace(
        extensions={"joint_compliance": {"joints": [2], "c": [1e-4]}}, ee_pose=None
    )
    robot = Robot(model, nominal)
    server = subprocess.Popen(
        [sys.executable, str(SIM), "serve", host], stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True
    )
    report: dict = {}
    try:
        assert server.stdout.readline().strip() == "READY"
        arm = franky.Robot(host, realtime_config=franky.RealtimeConfig.Ignore)
        q0 = np.array(arm.state.q)
        goals = circle(robot.fk(q0)[0], SECONDS, PERIOD)
        t = time.monotonic()
        out = follow(arm, Corrector(robot, q0=q0), goals, PERIOD)
        report["follow_s"] = time.monotonic() - t
        q = out["commands"]
        report["goals"], report["commands"] = len(goals), len(q)
        ref = robot.correct(goals[: len(q)], seed=np.vstack([q0, q[:-1]]))
        report["vs_correct_rad"] = float(np.abs(q - ref.q).max())
        report["miss_mm"] = float(
            np.linalg.norm(robot.fk(q)[:, :3, 3] - goals[: len(q), :3, 3], axis=1).max()
        )
        lag = out["measured"][:-1] - q
        report["tracking_rad"] = float(np.abs(lag).max())
        report["settled_rad"] = float(np.abs(out["measured"][-1] - q[-1]).max())
        report["settled_per_joint"] = [float(v) for v in out["measured"][-1] - q[-1]]
        report["path_rad"] = float(np.abs(q - q0).max())
        ms = out["compute_ms"]
        report["compute_median_ms"], report["compute_p99_ms"] = (
            float(np.median(ms)),
            float(np.percentile(ms, 99)),
        )
    finally:
        server.kill()
        server.wait()
    return report


def test_the_corrector_streams_corrects_commands_in_a_franky_motion(tmp_path):
    pytest.importorskip("franky", reason="the [sim] extra is not installed: franky-control missing")
    pytest.importorskip("franky_sim", reason="the [sim] extra is not installed: franky-sim missing")
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    from test_collector_franky_sim import _netns_available

    host = f"127.0.0.{2 + (os.getpid() + 303) % 250}"  # an address of its own, as the harness's tests
    cmd = [sys.executable, __file__, "scenario", str(tmp_path), host]
    netns = _netns_available()
    if netns:
        cmd = ["unshare", "--net", "--"] + cmd + ["--netns"]
    run = subprocess.run(cmd, capture_output=True, text=True, timeout=300, cwd=ROOT)
    assert run.returncode == 0, run.stderr[-3000:]
    r = json.loads(run.stdout.strip().splitlines()[-1])
    print("franky-sim corrector:", r, "netns", netns)
    assert r["commands"] == r["goals"]  # every goal of the path was streamed
    assert r["vs_correct_rad"] < 1e-8 and r["miss_mm"] < 1e-6  # correct's commands, on the calibrated model
    assert r["path_rad"] > 0.02  # the arm really went round the circle ...
    assert (
        r["settled_rad"] < 2e-2
    )  # ... and settles on the last command (seen: 2.6e-3 to 7.2e-3 rad, joint 7)


if __name__ == "__main__":
    if "--netns" in sys.argv:
        from test_collector_franky_sim import _loopback_up

        _loopback_up()
    print(json.dumps(scenario(sys.argv[2], sys.argv[3])))
