"""End to end: the real ``franky`` adapter against the franky-sim simulator, which speaks libfranka's
protocol.

Only loopback is used. The simulator and the adapter run in a child process inside a
private network namespace (``unshare --net``: nothing but a loopback interface) where the
machine allows it; in any case the simulator's UDP state socket, which binds 0.0.0.0 by
default, is pinned to the run's own 127.0.0.x address (libfranka always dials port 1337,
so parallel simulators need distinct addresses). The operator is emulated by writing the
simulator's joint positions in a step callback.

Run as a script, this file is that harness: ``serve HOST`` runs a simulator,
``scenario DIR HOST [--netns]`` drives it and prints a JSON report.
"""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]

# The fake camera in a clean world (``capture --camera fake`` off the fake backend), from
# benchmarks/bench_camera_sigma.py both 200 7 3 (1,000 photos beside the five crosses): sessions of the
# tests' sizes resampled 200,000 times (``--bounds 40 10``), the 0.1 % and 99.9 % quantiles of the z-score
# RMS (error / stated sigma, both axes) and the bound on the larger axis's mean error, mm, above the 99.99 %
# quantile of 10-photo sessions' (0.0377; 15 photos' 0.0306, for which it was set). The largest error, mm,
# from the photos' tail (``largest_bound``: a generalised Pareto fit to the top 10 %, its 99.9 % session
# quantile 0.1184 / 0.1127 mm, here its bootstrap 95 % upper limit). Until issue 51's second pass this was the
# resampled 99.9 % quantile, 0.1180 for both: the single largest of the 1,000 photos, which a fresh session
# passes in about 1 of 25 (40 photos) or 100 (10 photos); franky-sim's session did once, at 0.1243 mm.
PHOTOS_PER_POINT = 8
CLEAN_Z_RMS_40 = (0.816, 1.483)
CLEAN_LARGEST_ERROR_40 = 0.1368
CLEAN_Z_RMS_10 = (0.562, 1.844)
CLEAN_LARGEST_ERROR_10 = 0.1273
CLEAN_MEAN_ERROR_10 = 0.04


# ----------------------------------------------------------------------------- simulator side
def serve(host: str) -> None:
    """Run one franky-sim robot on ``host`` until stdin closes.

    stdin lines: a JSON list of 7 joint positions holds the arm there (the emulated
    operator's hand); ``free`` lets the simulator's own control move it again.
    """
    import socket
    import threading

    import franky_sim
    from franky_sim import franka_server
    from franky_sim.mujoco_simulator import MujocoSimulator

    class PinnedSocket(socket.socket):
        def bind(self, address):  # franky-sim binds its UDP state socket to 0.0.0.0: keep it on loopback
            if isinstance(address, tuple) and address[0] in ("0.0.0.0", ""):
                address = (host, address[1])
            super().bind(address)

    class SocketModule:
        socket = PinnedSocket

        def __getattr__(self, name):
            return getattr(socket, name)

    franka_server.socket = SocketModule()
    hold: list = [None]
    done = threading.Event()

    def read_commands():
        for line in sys.stdin:
            hold[0] = None if line.strip() == "free" else np.array(json.loads(line))
        done.set()

    with MujocoSimulator() as sim:
        robot = sim.add_robot()

        def operator(_sim):
            if hold[0] is not None:
                for a, v in zip(robot._qpos_addrs, hold[0]):
                    robot.data.qpos[a] = v
                for a in robot._dof_addrs:
                    robot.data.qvel[a] = 0.0

        sim.register_post_step_callback(operator)
        with franky_sim.SimulationServer(sim, hostname_candidates=[host]) as server:
            threading.Thread(target=read_commands, daemon=True).start()
            print("READY", flush=True)
            server.run_async()
            done.wait()


# ----------------------------------------------------------------------------- adapter side
def _loopback_up() -> None:
    """Bring up ``lo`` in a fresh network namespace (SIOCGIFFLAGS / SIOCSIFFLAGS)."""
    import fcntl
    import socket
    import struct

    s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    flags = struct.unpack("16sH", fcntl.ioctl(s, 0x8913, struct.pack("16sH", b"lo", 0))[:18])[1]
    fcntl.ioctl(s, 0x8914, struct.pack("16sH", b"lo", flags | 0x1))
    s.close()


def scenario(workdir: str, host: str) -> dict:
    """Read joint positions, run a capture session, move, and lose the robot; report what happened."""
    sys.path.insert(0, str(ROOT))
    from lasercal.collector.errors import RobotConnectionError
    from lasercal.collector.hardware.franky import FrankyRobot
    from lasercal.collector.hardware.triggers import Trigger
    from lasercal.collector.sessions.capture import CaptureOptions, run_capture
    from lasercal.collector.sessions.store import CaptureStore
    from lasercal.solver.formats.data import builtin_dir
    from lasercal.solver.formats.robots import load_model
    from lasercal.solver.formats.session import load_layout, load_session, session_meta
    from lasercal.solver.kinematics.aim import aim

    report: dict = {}
    t0 = time.monotonic()
    server = subprocess.Popen(
        [sys.executable, __file__, "serve", host], stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True
    )
    try:
        assert server.stdout.readline().strip() == "READY"
        report["start_s"] = time.monotonic() - t0

        def hold(q) -> None:
            server.stdin.write((json.dumps([float(v) for v in q]) if q is not None else "free") + "\n")
            server.stdin.flush()

        nominal = load_model("panda")
        layout = load_layout(builtin_dir("layouts") / "thesis.yaml")
        rng = np.random.default_rng(4)
        poses = {nm: aim(nominal, layout.points[nm], 2, rng, **layout.aim_kwargs()) for nm in ("P1", "P2")}

        robot = FrankyRobot(host, dynamics=0.5)
        t = time.monotonic()
        robot.connect()
        report["connect_s"] = time.monotonic() - t
        start = robot.read().q
        target = start + np.array([0.3, 0.2, -0.2, -0.3, 0.2, 0.3, -0.2])  # a short move clear of the floor
        t = time.monotonic()
        robot.move_to(target)
        report["move_s"] = time.monotonic() - t
        time.sleep(
            1.0
            # the simulator's position control settles (its dq then chatters at ~0.08 rad/s: no standstill
            # wait
            # here)
        )
        report["move_error"] = float(np.abs(robot.read().q - target).max())

        q_set = poses["P1"][0]
        hold(q_set)
        time.sleep(0.1)
        s = robot.read()
        report["read_error"] = float(np.abs(s.q - q_set).max())
        report["read_dq"] = float(np.abs(s.dq).max())
        report["robot_mode"] = s.extra["robot_mode"]

        class Operator(Trigger):
            """Puts the arm on the next pose, then triggers (what a person at the pilot would do)."""

            hint = "emulated operator"

            def __init__(self):
                self.queue = [q for nm in ("P1", "P2") for q in poses[nm]]

            def wait(self) -> str:
                hold(self.queue.pop(0))
                time.sleep(0.05)
                return "capture"

        meta = session_meta("panda", layout, None)
        meta["requested"] = ["P1", "P2"]
        store = CaptureStore.create(Path(workdir) / "session", meta, 7, robot.extra_columns)
        t = time.monotonic()
        res = run_capture(
            store, robot, Operator(), nominal, CaptureOptions(2, hold=0.2), out=open(os.devnull, "w")
        )
        report["session_s"] = time.monotonic() - t
        report["complete"] = res.complete
        session = load_session(store.folder)
        report["session_error"] = float(np.abs(session.q - np.concatenate([poses["P1"], poses["P2"]])).max())
        report["session_points"] = list(session.point)
        report["session_modes"] = sorted(set(session.extra["robot_mode"]))

        robot.connect()  # run_capture closed it
        server.kill()
        server.wait()
        t = time.monotonic()
        try:
            robot.read()
            report["disconnect"] = "not noticed"
        except RobotConnectionError as e:
            report["disconnect"] = str(e)
        report["disconnect_s"] = time.monotonic() - t
        robot.close()
    finally:
        if server.poll() is None:
            server.kill()
            server.wait()
    report["total_s"] = time.monotonic() - t0
    return report


def validate_scenario(workdir: str, host: str) -> dict:
    """``lasercal validate`` on franky-sim: refused without confirmation, then --yes, in bounded steps."""
    sys.path.insert(0, str(ROOT))
    import cv2

    from lasercal.collector.cli.main import main
    from lasercal.collector.hardware.franky import FrankyRobot

    report: dict = {}
    frames = Path(workdir) / "frames"
    frames.mkdir()
    for k in range(64):  # an image sequence stands in for the camera
        cv2.imwrite(str(frames / f"{k:04d}.png"), np.zeros((48, 64, 3), np.uint8))
    server = subprocess.Popen(
        [sys.executable, __file__, "serve", host], stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True
    )
    moves: list = []
    real_move = FrankyRobot.move_to

    def recording_move(self, q):
        moves.append([float(v) for v in q])
        real_move(self, q)

    FrankyRobot.move_to = recording_move
    try:
        assert server.stdout.readline().strip() == "READY"
        probe = FrankyRobot(host)
        probe.connect()
        start = probe.read().q
        probe.close()
        common = ["validate", "panda", "--backend", "franky", "--host", host, "--layout", "thesis",
                  "--camera", str(frames / "%04d.png"), "-n", "2", "--dynamics", "0.3",
                  "--speed-threshold", "0.5", "--hold", "0.1"]  # fmt: skip
        sys.stdin = open(os.devnull)  # no terminal
        report["refused_rc"] = main(common + ["-o", str(Path(workdir) / "refused")])
        report["refused_moves"] = len(moves)
        report["refused_csv"] = (Path(workdir) / "refused" / "validation.csv").exists()
        probe.connect()
        report["moved_while_refused"] = float(np.abs(probe.read().q - start).max())
        probe.close()
        report["rc"] = main(common + ["-o", str(Path(workdir) / "val"), "--yes", "--max-step", "0.4"])
        path = np.vstack([start, np.array(moves)])
        report["moves"] = len(moves)
        report["largest_step"] = float(np.abs(np.diff(path, axis=0)).max())
        text = (Path(workdir) / "val" / "validation.csv").read_text().splitlines()
        report["rows"] = len([ln for ln in text if ln and not ln.startswith("#")]) - 1
    finally:
        FrankyRobot.move_to = real_move
        if server.poll() is None:
            server.kill()
            server.wait()
    return report


def _steps(text: str, moves: list) -> tuple[list, float]:
    """Moves per previewed plan (the screen's "in N moves") and the largest joint step of ``moves``
    ((where the arm was, where it was sent) pairs), rad: each plan's first step starts where the arm was
    read, the others where the step before sent it."""
    per_plan = [int(k) for k in re.findall(r"the arm will move to 1 configurations in (\d+) moves", text)]
    first = np.cumsum([0] + per_plan[:-1])
    steps = [
        np.abs(np.subtract(b, a if k in first else moves[k - 1][1])).max() for k, (a, b) in enumerate(moves)
    ]
    return per_plan, float(max(steps))


def capture_scenario(workdir: str, host: str) -> dict:
    """``lasercal capture --guide move`` on franky-sim: refused without confirmation, then --yes: the arm
    goes to each suggested pose in bounded steps and the captures are taken there."""
    sys.path.insert(0, str(ROOT))
    import contextlib
    import io

    from lasercal.collector.cli.main import main
    from lasercal.collector.hardware.franky import FrankyRobot
    from lasercal.solver.formats.session import load_session

    report: dict = {}
    server = subprocess.Popen(
        [sys.executable, __file__, "serve", host], stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True
    )
    moves: list = []  # (where the arm was, where it was sent)
    real_move = FrankyRobot.move_to

    def recording_move(self, q):
        moves.append((self.read().q.tolist(), [float(v) for v in q]))
        real_move(self, q)

    FrankyRobot.move_to = recording_move
    try:
        assert server.stdout.readline().strip() == "READY"
        probe = FrankyRobot(host)
        probe.connect()
        start = probe.read().q
        probe.close()
        # --hold 1: the simulator's position control settles within a second of a move
        # the simulator is an FR3: the coach must keep its suggestions inside the FR3's joint limits
        common = ["capture", "--backend", "franky", "--host", host, "--layout", "thesis", "--per-point", "1",
                  "--robot", "fr3",
                  "--guide", "move", "--max-step", "0.4", "--dynamics", "0.3",
                  "--speed-threshold", "0.5", "--hold", "1.0"]  # fmt: skip
        sys.stdin = open(os.devnull)  # no terminal
        report["refused_rc"] = main(common + ["-o", str(Path(workdir) / "refused")])
        report["refused_moves"] = len(moves)
        report["refused_folder"] = (Path(workdir) / "refused").exists()
        probe.connect()
        report["moved_while_refused"] = float(np.abs(probe.read().q - start).max())
        probe.close()
        sys.stdin = io.StringIO("\n" * 10)  # the operator presses Enter at each suggested pose
        screen = io.StringIO()
        with contextlib.redirect_stdout(screen):
            report["rc"] = main(common + ["--yes", "-o", str(Path(workdir) / "s")])
        per_plan, report["largest_step"] = _steps(screen.getvalue(), moves)
        report["plans"] = per_plan
        report["moves"] = len(moves)
        arrivals = np.array([moves[k - 1][1] for k in np.cumsum(per_plan)])
        session = load_session(Path(workdir) / "s")
        report["captures"] = int(session.m)
        report["points"] = list(session.point)
        report["capture_from_arrival"] = [float(np.abs(q - a).max()) for q, a in zip(session.q, arrivals)]
    finally:
        FrankyRobot.move_to = real_move
        if server.poll() is None:
            server.kill()
            server.wait()
    return report


def camera_scenario(workdir: str, host: str, per_point: int = 2) -> dict:
    """A hands-free camera session on franky-sim: ``lasercal sheet --place``, then ``capture --guide move
    --camera fake --yes`` with nobody at the keyboard (stdin at EOF), then ``solve --json`` on it.

    The fake camera photographs where the nominal FR3's beam meets the sheet at the joint angles franky
    reports; the joint angles of every photo are recorded here (around ``StatedTruth.true_q``).
    """
    sys.path.insert(0, str(ROOT))
    import contextlib
    import csv
    import io

    from lasercal.collector.cli.main import main
    from lasercal.collector.hardware.franky import FrankyRobot
    from lasercal.collector.sessions.store import CaptureStore
    from lasercal.collector.worlds.cameras import StatedTruth

    report: dict = {}
    work = Path(workdir)
    server = subprocess.Popen(
        [sys.executable, __file__, "serve", host], stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True
    )
    moves: list = []  # (where the arm was, where it was sent)
    photo_q: list = []  # the joint angles each photo was taken at
    logged: list = []  # photos taken when each row was logged (a photo of a creeping arm is retaken)
    real_move, real_true_q = FrankyRobot.move_to, StatedTruth.true_q
    real_append = CaptureStore.append

    def recording_append(self, row):
        logged.append(len(photo_q))
        return real_append(self, row)

    def recording_move(self, q):
        moves.append((self.read().q.tolist(), [float(v) for v in q]))
        real_move(self, q)

    def recording_true_q(self):
        q = real_true_q(self)
        photo_q.append(q.tolist())
        return q

    FrankyRobot.move_to, StatedTruth.true_q = recording_move, recording_true_q
    CaptureStore.append = recording_append
    try:
        assert server.stdout.readline().strip() == "READY"
        screen, err, solved = io.StringIO(), io.StringIO(), io.StringIO()
        sys.stdin = open(os.devnull)  # hands-free: nobody at the keyboard (a prompt would read EOF: quit)
        with contextlib.redirect_stdout(screen), contextlib.redirect_stderr(err):
            report["sheet_rc"] = main(
                ["sheet", "-o", str(work / "sheet"), "--robot", "fr3", "--place", "450", "0", "0"]
            )
            t = time.monotonic()
            report["rc"] = main(
                ["capture", "--backend", "franky", "--host", host, "--robot", "fr3",
                 "--layout", str(work / "sheet" / "layout.yaml"), "--guide", "move", "--camera", "fake",
                 "--yes", "--per-point", str(per_point), "--max-step", "0.4", "--dynamics", "0.3",
                 "--speed-threshold", "0.5", "--hold", "1.0", "-o", str(work / "s")]
            )  # fmt: skip
            report["session_s"] = time.monotonic() - t
        with contextlib.redirect_stdout(solved), contextlib.redirect_stderr(err):
            report["solve_rc"] = main(["solve", str(work / "s"), "-o", str(work / "model.yaml"), "--json"])
        report["stderr"] = err.getvalue().splitlines()
        text = screen.getvalue()
        report["hands_free"] = text.count("hands-free  [Ctrl-C stops]")
        report["by_hand"] = text.count("guided by hand once")
        report["plans"], report["largest_step"] = _steps(text, moves)
        report["moves"] = len(moves)
        if report["solve_rc"] == 0:
            fit = json.loads(solved.getvalue())
            keep = ("fit_rms_mm", "noise_by_kind", "sheet", "cross_validation")
            report["solve"] = {k: fit[k] for k in keep}
        with open(work / "s" / "captures.csv", newline="") as f:
            rows = list(csv.DictReader(ln for ln in f if not ln.startswith("#")))
        report["rows"] = rows
        report["photos_exist"] = [bool(r["photo"]) and (work / "s" / r["photo"]).is_file() for r in rows]
        report["photo_q"] = [photo_q[k - 1] for k in logged]  # each row's photo: the last before it
        report["retaken"] = text.count("photographing again once it is still")
    finally:
        FrankyRobot.move_to, StatedTruth.true_q = real_move, real_true_q
        CaptureStore.append = real_append
        if server.poll() is None:
            server.kill()
            server.wait()
    return report


def _netns_available() -> bool:
    try:
        return subprocess.run(["unshare", "--net", "true"], capture_output=True, timeout=10).returncode == 0
    except (OSError, subprocess.TimeoutExpired):
        return False


def _run_on_franky_sim(kind: str, tmp_path, offset: int, timeout: int) -> tuple[dict, bool, str]:
    """Run scenario ``kind`` of this file in a child process against franky-sim on a loopback address of
    its own (inside a network namespace when one can be made); its last stdout line is the JSON result."""
    pytest.importorskip(
        "franky", reason="the [sim] extra is not installed (pip install -e '.[sim]'): franky-control missing"
    )
    pytest.importorskip(
        "franky_sim", reason="the [sim] extra is not installed (pip install -e '.[sim]'): franky-sim missing"
    )
    host = f"127.0.0.{2 + (os.getpid() + offset) % 250}"
    cmd = [sys.executable, __file__, kind, str(tmp_path), host]
    netns = _netns_available()
    if netns:
        cmd = ["unshare", "--net", "--"] + cmd + ["--netns"]
    run = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout, cwd=ROOT)
    assert run.returncode == 0, run.stderr[-3000:]
    return json.loads(run.stdout.strip().splitlines()[-1]), netns, host


def test_franky_adapter_reads_moves_and_notices_loss_against_franky_sim(tmp_path):
    r, netns, host = _run_on_franky_sim("scenario", tmp_path, 0, 180)
    print(
        "franky-sim end to end:",
        {k: round(v, 3) if isinstance(v, float) else v for k, v in r.items()},
        "netns",
        netns,
    )
    # franky reads the positions the simulator holds (the wire carries them exactly; MuJoCo rounds nothing)
    assert r["read_error"] < 1e-6
    assert r["read_dq"] < 1e-6
    assert r["robot_mode"] == "Idle"
    # a whole capture session through the adapter logs exactly the emulated operator's poses
    assert r["complete"]
    assert r["session_points"] == ["P1", "P1", "P2", "P2"]
    assert r["session_error"] < 1e-6
    # a commanded move (0.3 rad on the largest joint) gets there, to the simulator's position-control accuracy
    assert r["move_error"] < 5e-3
    # a robot that goes away is noticed within a few seconds, with the adapter's message
    assert r["disconnect"].startswith(f"franky: the robot at {host} stopped answering")
    assert r["disconnect_s"] < 5


def test_validate_on_franky_sim_refuses_without_confirmation_and_moves_in_bounded_steps(tmp_path):
    r, netns, _ = _run_on_franky_sim("validate", tmp_path, 101, 300)
    print("franky-sim validate:", r, "netns", netns)
    # no terminal and no --yes: exit 2 before any move or any file
    assert r["refused_rc"] == 2 and r["refused_moves"] == 0 and not r["refused_csv"]
    assert r["moved_while_refused"] < 1e-3
    # with --yes: no commanded move changes a joint by more than --max-step; both configurations photographed
    assert r["rc"] == 0 and r["rows"] == 2
    assert r["largest_step"] <= 0.4 + 1e-9
    assert r["moves"] > 2  # the aiming configurations are further apart than 0.4 rad: moves were split


def test_capture_guide_move_on_franky_sim_refuses_without_confirmation_and_moves_to_suggestions(tmp_path):
    r, netns, _ = _run_on_franky_sim("capture", tmp_path, 202, 300)
    print("franky-sim capture --guide move:", r, "netns", netns)
    # no terminal and no --yes: exit 2 before any move and before the session folder exists
    assert r["refused_rc"] == 2 and r["refused_moves"] == 0 and not r["refused_folder"]
    assert r["moved_while_refused"] < 1e-3
    # with --yes: one suggestion per capture (the first from the prior), each reached in bounded steps
    assert r["rc"] == 0 and r["captures"] == 3 and sorted(r["points"]) == ["P1", "P2", "P3"]
    assert len(r["plans"]) == 3 and r["moves"] == sum(r["plans"]) > 3  # split: poses differ by > 0.4 rad
    assert r["largest_step"] <= 0.4 + 1e-3  # first steps start from a read of the (still) arm
    # each capture is taken where the arm was sent (the simulator's position-control accuracy)
    assert max(r["capture_from_arrival"]) < 5e-3


def test_a_fake_camera_off_the_fake_backend_photographs_the_stated_nominal_beam(tmp_path, capsys):
    """No simulator needed: ``--camera fake`` on another backend photographs where the nominal model
    (``--robot``) puts the beam at the joint angles the robot reports, says so once on stderr, and still
    refuses a sheet without a placement."""
    from lasercal.collector.errors import SessionError
    from lasercal.collector.hardware.base import JointState
    from lasercal.collector.sessions.spotcam import BESIDE_MM, capture_camera
    from lasercal.collector.worlds.cameras import StatedTruth
    from lasercal.collector.worlds.fakeworld import World
    from lasercal.solver.formats.robots import load_model
    from lasercal.solver.formats.session import load_layout
    from lasercal.solver.identify.spot import predict_spots
    from lasercal.solver.kinematics.aim import aim
    from lasercal.vision.sheet import design_sheet, write_layout

    class Reporting:
        """A robot adapter as far as the camera uses it: it reports ``q``."""

        q = np.zeros(7)

        def read(self) -> JointState:
            return JointState(self.q.copy(), np.zeros(7), np.zeros(7), 0.0)

    fr3, robot = load_model("fr3"), Reporting()
    cfg = {"backend": "franky", "robot": "fr3", "seed": 5}
    bare = tmp_path / "bare.yaml"
    write_layout(bare, design_sheet("A4"), -8.0)
    with pytest.raises(SessionError, match="with a placement"):
        capture_camera("fake", cfg, robot, load_layout(bare), bare, World())
    path = tmp_path / "layout.yaml"
    write_layout(path, design_sheet("A4"), -8.0, {"x_mm": 450.0, "y_mm": 30.0, "yaw_deg": 10.0})
    layout = load_layout(path)
    camera, measure = capture_camera("fake", cfg, robot, layout, path, World())
    assert isinstance(camera.robot, StatedTruth) and camera.robot.truth.name == "fr3"
    said = capsys.readouterr().err.splitlines()
    assert len(said) == 1 and said[0].startswith("--camera fake on --backend franky") and "none" in said[0]
    rng = np.random.default_rng(7)
    err, sigma = [], []
    for name in layout.calibration:  # beside each cross, PHOTOS_PER_POINT configurations
        beside = layout.sheet.to_base(layout.points[name][None, :2] + BESIDE_MM, layout.plane_z)[0]
        for q in aim(fr3, beside, PHOTOS_PER_POINT, rng, **layout.aim_kwargs()):
            robot.q = q
            m = measure(camera.photo(), name)
            true = layout.sheet.from_base(predict_spots(fr3, q[None], layout.plane_z)[0])[0]
            np.testing.assert_allclose(true, layout.points[name][:2] + BESIDE_MM, atol=1e-3)  # aimed there
            err.append(m.xy - true)
            sigma.append(m.sigma)
    # The stated sigma says what the error is. Bounds from the clean world's 1,000 photos
    # (benchmarks/bench_camera_sigma.py both 200 7 3, --bounds 40): 40-photo sessions resampled 200,000 times,
    # their 0.1 % and 99.9 % quantiles; a sigma 1.5x too large or too small leaves the band (checked by
    # scaling it). The wrong arm or joint angles put the spot millimetres off.
    err, sigma = np.array(err), np.array(sigma)
    z_rms = float(np.sqrt(np.mean((err / sigma) ** 2)))
    assert len(err) == 40 and CLEAN_Z_RMS_40[0] < z_rms < CLEAN_Z_RMS_40[1], (z_rms, err / sigma)
    assert np.abs(err).max() < CLEAN_LARGEST_ERROR_40, err


def test_hands_free_camera_session_on_franky_sim_measures_the_nominal_fr3s_beam(tmp_path):
    """capture --guide move --camera fake on franky-sim: 10 captures (2 per point) with nobody at the
    keyboard, each measured by the fake camera where the nominal FR3's beam (franky-sim's arm) meets the
    sheet at the logged joint angles; then solve. (15 until issue 51: the franky-sim session moves the arm in
    real time, ~8 s a capture; the bounds below are those of 10-photo sessions.)"""
    from lasercal.solver.formats.robots import load_model
    from lasercal.solver.formats.session import load_layout
    from lasercal.solver.identify.spot import predict_spots

    r, netns, _ = _run_on_franky_sim("camera", tmp_path, 303, 290)
    rows = r.pop("rows")
    photo_q = np.array(r.pop("photo_q"))
    print("franky-sim hands-free camera session:", r, "netns", netns)
    assert r["sheet_rc"] == 0 and r["rc"] == 0
    # said once, on stderr: what the fake camera photographs off the fake backend
    notice = [ln for ln in r["stderr"] if ln.startswith("--camera fake on --backend franky")]
    assert len(notice) == 1 and "nominal fr3's laser beam" in notice[0]
    # hands-free: every capture taken at the coach's pose without a trigger, none handed to the operator
    assert len(rows) == 10 and r["hands_free"] == 10 and r["by_hand"] == 0
    assert sorted(row["point"] for row in rows) == sorted(["P1", "P2", "P3", "P4", "P5"] * 2)
    assert all(r["photos_exist"]) and all(row["camera_x"] and row["camera_y"] for row in rows)
    # every commanded move within --max-step (first steps start from a read of the still arm)
    assert len(r["plans"]) == 10 and r["moves"] == sum(r["plans"]) > 10
    assert r["largest_step"] <= 0.4 + 1e-3
    # the truth, independently: where the nominal FR3's beam at the logged q meets the sheet, in its frame
    layout = load_layout(tmp_path / "sheet" / "layout.yaml")
    fr3 = load_model("fr3")
    q = np.array([[float(row[f"q{j}"]) for j in range(1, 8)] for row in rows])
    true = layout.sheet.from_base(predict_spots(fr3, q, layout.plane_z)[0])
    # the photo is taken at a later read than the logged one: franky-sim's flange joint chatters (|dq| ~0.08
    # rad/s at standstill, 8e-5 rad seen), which moves the spot by ~3e-4 mm, and a loaded machine's arm still
    # creeps (0.04 mm seen): capture reads the arm after each photo and retakes one whose spot moved more
    # than PHOTO_MOVED_MM (5e-3 mm), the bound here
    assert photo_q.shape == q.shape
    seen = layout.sheet.from_base(predict_spots(fr3, photo_q, layout.plane_z)[0])
    assert np.abs(seen - true).max() < 5e-3
    measured = np.array([[float(row["camera_x"]), float(row["camera_y"])] for row in rows])
    sigma = np.array([[float(row["camera_sx"]), float(row["camera_sy"])] for row in rows])
    assert sigma.min() > 0 and sigma.max() < 0.1  # the fake camera's 0.02-0.05 mm per axis
    # each spot where the beam met the sheet, as well as the fake camera measures in this clean world and
    # as well as its stated sigma says: within the bands 10-photo sessions resampled from the benchmark's
    # 1,000 photos stay inside at their 0.1 % and 99.9 % quantiles (CLEAN_Z_RMS_10, CLEAN_LARGEST_ERROR_10;
    # the mean's CLEAN_MEAN_ERROR_10 above their 99.99 %; benchmarks/bench_camera_sigma.py --bounds,
    # 200,000 draws). A spot misplaced (the wrong pose photographed, a frame off) moves the mean or the
    # largest error; a sigma 1.5x too small moves the z-score RMS out of the band in 28 % of such sessions
    # (44 % at 15 photos): the stated sigma is judged by the 40 photos of
    # test_a_fake_camera_off_the_fake_backend_photographs_the_stated_nominal_beam (90 %, 82 % at 1/1.5, 1.5),
    # this session's photos by where franky-sim's arm put the beam.
    err = measured - true
    assert np.abs(err.mean(axis=0)).max() < CLEAN_MEAN_ERROR_10, err.mean(axis=0)
    assert np.abs(err).max() < CLEAN_LARGEST_ERROR_10, err
    z_rms = float(np.sqrt(np.mean((err / sigma) ** 2)))
    assert CLEAN_Z_RMS_10[0] < z_rms < CLEAN_Z_RMS_10[1], (z_rms, err / sigma)
    # solve on it: every capture fitted as measured, the sheet found where it was placed (the arm is the
    # nominal FR3, so the robot's own base frame is the nominal's)
    assert r["solve_rc"] == 0
    kinds = r["solve"]["noise_by_kind"]
    assert kinds["measured"] == 10 and kinds["aimed"] == 0
    pose, std = r["solve"]["sheet"]["pose"], r["solve"]["sheet"]["std"]
    assert abs(pose["x_mm"] - 450) < 4 * std["x_mm"] and abs(pose["y_mm"]) < 4 * std["y_mm"]
    assert abs(pose["yaw_deg"]) < 4 * std["yaw_deg"]


if __name__ == "__main__":
    if sys.argv[1] == "serve":
        serve(sys.argv[2])
    else:
        if "--netns" in sys.argv:
            _loopback_up()
        if sys.argv[1] == "camera":  # --per-point N: the benchmark's longer session
            k = sys.argv.index("--per-point") + 1 if "--per-point" in sys.argv else None
            result = camera_scenario(sys.argv[2], sys.argv[3], int(sys.argv[k]) if k else 2)
        else:
            fn = {"validate": validate_scenario, "capture": capture_scenario}.get(sys.argv[1], scenario)
            result = fn(sys.argv[2], sys.argv[3])
        print(json.dumps(result))
