"""``lasercal correct`` against simulated truth: a perturbed Panda from a URDF seen by a tracker, a
laser-calibrated Panda and a model with a joint compliance. Goals are reached on the TRUE robot, the
Cartesian commands are the nominal model's forward kinematics (pinocchio, Franka's DH table), every command
is inside the limits; and bad input is one line."""

from __future__ import annotations

import csv
import re
from pathlib import Path

import numpy as np
import pytest
import yaml

import lasercal
from lasercal.collector.cli.main import main
from lasercal.solver.analysis.simulate import random_configs, simulate_positions
from lasercal.solver.control.nominal import nominal_model
from lasercal.solver.control.robot import Robot
from lasercal.solver.formats.positions import position_meta, write_position_session
from lasercal.solver.formats.robots import load_model as load_robot_model
from lasercal.solver.formats.urdf import calibrated_urdf, load_urdf
from lasercal.solver.kinematics.effects import Extension
from lasercal.solver.kinematics.gravity import model_torques
from lasercal.solver.kinematics.ik import tool_frames
from tests.conftest import franka_flange, perturbed

DATA = Path(__file__).parent / "data"
ARM7 = DATA / "arm7.urdf"
SIGMA = 0.02  # mm per axis: a laser tracker
MARGIN = 0.01  # rad: lasercal correct's default limit margin
COMPLIANCE = Extension("joint_compliance", (2, 4), None, np.array([-2e-4, -1.5e-4]))  # rad/Nm: a sag


def work_configs(model, m: int, seed: int) -> np.ndarray:
    """m configurations inside the limits, the elbow bent (q4 < -0.8 rad): a program away from the stretched
    arm, where a pose the nominal reaches may lie beyond the true arm's reach."""
    q = random_configs(model, m, np.random.default_rng(seed), margin=0.3)
    q[:, 3] = np.minimum(q[:, 3], -0.8)
    return q


def write_csv(path: Path, header: list, rows) -> Path:
    with open(path, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(header)
        w.writerows(rows)
    return path


def read_out(path: Path) -> tuple[list, list]:
    lines = path.read_text().splitlines()
    assert lines[0].startswith("# lasercal correct") and "angles rad, positions mm" in lines[0]
    rows = list(csv.reader(lines[1:]))
    return rows[0], rows[1:]


def column(header, rows, names) -> np.ndarray:
    return np.array([[float(r[header.index(c)]) for c in names] for r in rows])


def correct(tmp: Path, model: Path, name: str, header: list, rows, *tool) -> tuple[list, list]:
    """``lasercal correct MODEL IN.csv -o OUT.csv [tool]``: exit 0 and OUT.csv's header and rows."""
    out = tmp / f"{name}_out.csv"
    assert (
        main(
            ["correct", str(model), str(write_csv(tmp / f"{name}.csv", header, rows)), "-o", str(out), *tool]
        )
        == 0
    )
    return read_out(out)


# ----------------------------------------------------------------------------- a tracker-calibrated arm
def position_case(tmp: Path, effect: Extension | None, extend: bool):
    """A perturbed Panda from a URDF (screws moved ~1 mrad / 1 mm), 3 targets seen by a tracker 2.5 m away,
    60 poses at 0.02 mm noise (a hidden ``effect`` acting through the truth's gravity torques), solved by
    ``lasercal solve`` (``--extend joint_compliance`` when ``extend``)."""
    nominal = load_urdf(ARM7)
    rng = np.random.default_rng(7)
    truth = perturbed(nominal, rng)
    names = np.tile(np.array(list(truth.targets), dtype=object), 60)
    q = np.repeat(random_configs(nominal, 60, rng), 3, axis=0)
    y = simulate_positions(truth, q, names, SIGMA, rng, effect, model_torques(truth, q)[0])
    write_position_session(tmp / "S", position_meta(str(ARM7), truth.targets), q, y, names)
    model = tmp / "model.yaml"
    assert (
        main(
            ["solve", str(tmp / "S"), "-o", str(model), "--folds", "0"]
            + (["--extend", "joint_compliance"] if extend else [])
        )
        == 0
    )
    return model, truth


def true_target(truth, effect, q_cmd: np.ndarray, name: str = "T1") -> np.ndarray:
    """Where the true robot puts target ``name`` at the commands, in the tracker's frame (m, 3) mm."""
    q = effect.true_q(q_cmd, None, model_torques(truth, q_cmd)[0]) if effect is not None else q_cmd
    E = tool_frames(truth.screws, np.eye(4), q)[0]
    p = E[:, :3, :3] @ truth.targets[name] + E[:, :3, 3]
    X = truth.sensor_pose
    return p @ X[:3, :3].T + X[:3, 3]


def errors_on_truth(tmp: Path, model: Path, truth, effect) -> dict:
    """Mean error (mm) of target T1 on the true robot for x,y,z goals and for a nominal program, commanded
    by the nominal model and by lasercal correct; and the commands themselves."""
    robot = lasercal.load_model(model)
    X = robot.model.sensor_pose  # goals are in the calibrated base frame: compare in the tracker's

    def seen(p):
        return p @ X[:3, :3].T + X[:3, 3]

    T1 = robot.tool("T1")
    out = {}
    q_goal = work_configs(robot.model, 150, 11)
    goal = robot.fk(q_goal, "T1")[:, :3, 3]
    head, rows = correct(tmp, model, "xyz", ["x", "y", "z"], goal, "--tool", "T1")
    q_cmd = column(head, rows, [f"cmd_q{i}" for i in range(1, 8)])
    q_nom = Robot(robot.nominal, robot.nominal).ik(goal, tool=T1).q  # the nominal controller's own IK
    out["xyz"] = (
        np.linalg.norm(true_target(truth, effect, q_nom) - seen(goal), axis=1).mean(),
        np.linalg.norm(true_target(truth, effect, q_cmd) - seen(goal), axis=1).mean(),
        head,
        rows,
    )
    program = work_configs(robot.model, 150, 12)
    goal = robot.fk(program, "T1", nominal=True)[:, :3, 3]
    head, rows = correct(tmp, model, "program", [f"q{i}" for i in range(1, 8)], program, "--tool", "T1")
    q_cmd = column(head, rows, [f"cmd_q{i}" for i in range(1, 8)])
    out["program"] = (
        np.linalg.norm(true_target(truth, effect, program) - seen(goal), axis=1).mean(),
        np.linalg.norm(true_target(truth, effect, q_cmd) - seen(goal), axis=1).mean(),
        head,
        rows,
    )
    return out


@pytest.fixture(scope="module")
def tracker(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("tracker")
    model, truth = position_case(tmp, None, extend=False)
    return tmp, model, truth, errors_on_truth(tmp, model, truth, None)


def _pin_frames(urdf: Path, q: np.ndarray, frames: list) -> list[np.ndarray]:
    """Frames (m, 4, 4) mm of a URDF by pinocchio (an independent URDF implementation)."""
    pin = pytest.importorskip("pinocchio")
    model = pin.buildModelFromUrdf(str(urdf))
    data = model.createData()
    out = {f: [] for f in frames}
    for qi in q:
        pin.framesForwardKinematics(model, data, qi)
        for f in frames:
            T = data.oMf[model.getFrameId(f)].homogeneous.copy()
            T[:3, 3] *= 1000.0
            out[f].append(T)
    return [np.array(out[f]) for f in frames]


@pytest.mark.parametrize("kind", ["xyz", "program"])
def test_tracker_goals_are_reached_on_the_true_robot(tracker, kind):
    """Target T1 of a perturbed URDF Panda: within 0.1 mm on the truth, at most 1/20 of the nominal's miss,
    every goal ok, every command inside the limits less the margin."""
    _, model, truth, errors = tracker
    nominal_mm, corrected_mm, head, rows = errors[kind]
    assert corrected_mm <= 0.2 and corrected_mm <= nominal_mm / 20
    assert nominal_mm > 2.0  # the perturbation is far above the noise
    assert all(r[head.index("ok")] == "true" and r[head.index("reason")] == "" for r in rows)
    q = column(head, rows, [f"cmd_q{i}" for i in range(1, 8)])
    assert load_robot_model(model).within_limits(q, margin=MARGIN - 1e-9).all()
    assert column(head, rows, ["residual_mm"]).max() < 1e-3


def test_tracker_cartesian_commands_are_the_nominal_forward_kinematics(tracker, tmp_path):
    """cmd_x,y,z = the nominal URDF's tip (pinocchio) at cmd_q, carrying T1 where the calibrated URDF puts it
    on the tip (pinocchio reads lasercal_T1 from the exported URDF): what MoveIt would compute."""
    _, model, _, errors = tracker
    cal = tmp_path / "calibrated.urdf"
    cal.write_text(calibrated_urdf(load_robot_model(model)))
    hand, t1 = _pin_frames(cal, np.zeros((1, 7)), ["hand", "lasercal_T1"])
    offset = np.linalg.inv(hand[0]) @ t1[0]  # T1 in the tip frame, from the calibrated URDF
    for kind in ("xyz", "program"):
        _, _, head, rows = errors[kind]
        q = column(head, rows, [f"cmd_q{i}" for i in range(1, 8)])
        (tip,) = _pin_frames(ARM7, q, ["hand"])
        expected = (tip @ offset)[:, :3, 3]
        assert np.abs(column(head, rows, ["cmd_x", "cmd_y", "cmd_z"]) - expected).max() < 1e-3


def test_solve_names_the_nominal_and_the_program_goals_have_an_orientation(tracker):
    _, model, _, errors = tracker
    assert yaml.safe_load(model.read_text())["nominal"] == str(ARM7.resolve())
    head = errors["program"][2]
    assert head[:7] == [f"q{i}" for i in range(1, 8)] and head[7:14] == [f"cmd_q{i}" for i in range(1, 8)]
    assert head[14:] == [
        "cmd_x",
        "cmd_y",
        "cmd_z",
        "cmd_rx",
        "cmd_ry",
        "cmd_rz",
        "residual_mm",
        "ok",
        "reason",
    ]
    assert errors["xyz"][2][3:] == [f"cmd_q{i}" for i in range(1, 8)] + [
        "cmd_x",
        "cmd_y",
        "cmd_z",
        "residual_mm",
        "ok",
        "reason",
    ]


# ----------------------------------------------------------------------------- a model with a compliance
def test_a_compliance_is_corrected_through_the_gravity_torques(tmp_path):
    """A hidden sag of joints 2 and 4 (the truth's gravity torques), fitted by solve --extend: the commands
    reach T1 on the true robot; the geometric model of the same data, blind to the sag, does not."""
    model, truth = position_case(tmp_path / "ext", COMPLIANCE, extend=True)
    assert set(load_robot_model(model).extensions) == {"joint_compliance"}
    errors = errors_on_truth(tmp_path / "ext", model, truth, COMPLIANCE)
    geometric, _ = position_case(tmp_path / "geo", COMPLIANCE, extend=False)
    blind = errors_on_truth(tmp_path / "geo", geometric, truth, COMPLIANCE)
    for kind in ("xyz", "program"):
        nominal_mm, corrected_mm = errors[kind][:2]
        assert corrected_mm <= 0.2 and corrected_mm <= nominal_mm / 20
        assert blind[kind][1] > 5 * corrected_mm


# ----------------------------------------------------------------------------- a laser-calibrated Panda
@pytest.fixture(scope="module")
def laser(tmp_path_factory):
    """The demo's truth (thesis Table 4.3 identified) calibrated from laser spots at P1-P3, 15 a point; aiming
    noise 0.02 mm, the tracker's, so that the check is of lasercal correct and not of the laser's noise."""
    tmp = tmp_path_factory.mktemp("laser")
    sim = [
        "simulate",
        "panda_thesis_identified",
        "--layout",
        "thesis",
        "--aim-noise",
        "0.02",
        "-o",
        str(tmp / "S"),
    ]
    assert main(sim) == 0
    # the noise prior says what this aiming is (docs/formats.md, Priors): the default, 1 mm, would hold it
    # at ~0.25 mm with 45 captures, and the prior would then weigh as if the data were that noisy
    prior = tmp / "prior.yaml"
    prior.write_text("format: lasercal-prior/1\nprior: {noise_mm: {laser: 0.02}}\n")
    solve = ["solve", str(tmp / "S"), "-o", str(tmp / "model.yaml"), "--folds", "0", "--prior", str(prior)]
    assert main(solve) == 0
    return tmp, tmp / "model.yaml"


@pytest.mark.parametrize("kind", ["xyz", "program"])
def test_a_laser_calibrated_panda_reaches_flange_goals_on_the_truth(laser, kind):
    """Tool = the flange (the nominal flange carried by the calibrated joint 7); Cartesian commands are the
    flange of Franka's DH table at the commands."""
    tmp, model = laser
    robot = lasercal.load_model(model)
    assert robot.nominal.name == "panda" and yaml.safe_load(model.read_text())["nominal"] == "panda"
    truth = Robot(load_robot_model("panda_thesis_identified"), robot.nominal)
    qs = work_configs(robot.model, 150, 13)
    if kind == "xyz":
        goal = robot.fk(qs)[:, :3, 3]
        head, rows = correct(
            tmp, model, kind, ["x", "y", "z", "label"], [[*g, f"g{i}"] for i, g in enumerate(goal)]
        )
        assert [r[3] for r in rows] == [f"g{i}" for i in range(150)]  # rows in input order, columns kept
        q_nom = Robot(robot.nominal, robot.nominal).ik(goal).q
    else:
        goal = robot.fk(qs, nominal=True)[:, :3, 3]
        head, rows = correct(tmp, model, kind, [f"q{i}" for i in range(1, 8)], qs)
        q_nom = qs
    q = column(head, rows, [f"cmd_q{i}" for i in range(1, 8)])
    nominal_mm = np.linalg.norm(truth.fk(q_nom)[:, :3, 3] - goal, axis=1).mean()
    corrected_mm = np.linalg.norm(truth.fk(q)[:, :3, 3] - goal, axis=1).mean()
    assert corrected_mm <= 0.2 and corrected_mm <= nominal_mm / 20
    assert all(r[head.index("ok")] == "true" for r in rows)
    assert robot.model.within_limits(q, margin=MARGIN - 1e-9).all()
    assert np.abs(column(head, rows, ["cmd_x", "cmd_y", "cmd_z"]) - franka_flange(q)[:, :3, 3]).max() < 1e-3
    assert all(len(r[head.index("cmd_q1")].split(".")[1]) == 9 for r in rows)  # angles to 1e-9 rad


def test_the_api_gives_the_commands_of_the_command_line(laser):
    tmp, model = laser
    head, rows = read_out(tmp / "program_out.csv")
    program = column(head, rows, [f"q{i}" for i in range(1, 8)])
    c = lasercal.load_model(str(model)).correct(q=program)
    assert np.abs(c.q - column(head, rows, [f"cmd_q{i}" for i in range(1, 8)])).max() < 1e-9
    assert c.nominal_pose.shape == (len(program), 4, 4) and c.ok.all()


# ----------------------------------------------------------------------------- which nominal
def test_the_nominal_is_found_from_the_key_the_urdf_or_the_name(tmp_path):
    panda = load_robot_model("panda")
    (tmp_path / "sub").mkdir()
    panda.save(tmp_path / "sub" / "nom.yaml")
    mine = panda.replace(name="mybot", nominal="sub/nom.yaml")
    mine.save(tmp_path / "mine.yaml")
    assert nominal_model(load_robot_model(tmp_path / "mine.yaml"), tmp_path / "mine.yaml").name == "panda"
    assert nominal_model(load_urdf(ARM7)).urdf["file"] == str(ARM7.resolve())
    assert nominal_model(load_robot_model("fr3")).name == "fr3"
    assert nominal_model(load_robot_model("panda_thesis_identified")).name == "panda"


# ----------------------------------------------------------------------------- bad input, one line
GOALS = "x,y,z\n400,0,500\n"


@pytest.mark.parametrize(
    "text, where, message",
    [
        ("a,b\n1,2\n", "line 1", "expected goal columns x,y,z (mm) or a program q1..q7 (rad)"),
        ("x,y\n400,0\n", "line 1, column 'z'", "missing column(s) z"),
        ("x,y,z\n0.4,0.1,0.5\n", "line 2, column 'x'", "look like metres"),
        ("x,y,z\n400,oops,500\n", "line 2, column 'y'", "not a finite number: 'oops'"),
        ("x,y,z,rx,ry,rz\n400,0,500,180,0,0\n", "line 2, column 'rx'", "degrees? expected rad"),
        ("rx,ry,rz,q1,q2,q3,q4,q5,q6,q7\n0,0,0,0,0,0,-1,0,1,0\n", "line 1, column 'rx'", "need x,y,z"),
        ("q1,q2,q3,q4,q5,q6,q7\n0,0,0,-1,0,1.5,45\n", "line 2", "outside its limits"),
        ("x,y,z\n", "line 1", "no goals"),
    ],
)
def test_bad_goals_are_one_line_naming_file_line_and_column(tmp_path, capsys, text, where, message):
    goals = tmp_path / "in.csv"
    goals.write_text(text)
    assert main(["correct", "panda", str(goals), "-o", str(tmp_path / "out.csv")]) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and f"in.csv, {where}" in err and message in err, err
    assert not (tmp_path / "out.csv").exists()


def test_bad_models_tools_and_outputs_are_one_line(tmp_path, capsys):
    goals = tmp_path / "in.csv"
    goals.write_text(GOALS)
    out = str(tmp_path / "out.csv")
    orphan = load_robot_model("panda").replace(name="mybot")
    orphan.save(tmp_path / "mybot.yaml")
    drift = load_robot_model("panda").replace(
        extensions={"drift": {"joints": [2], "r": [1e-6]}}, nominal="panda"
    )
    drift.save(tmp_path / "drift.yaml")
    cases = [
        (["--tool", "T9"], "panda", "'panda' has no tool 'T9' (it has: flange)"),
        (["--tool", "T1", "--tcp", "0", "0", "1"], "panda", "not allowed with argument"),
        (["--tcp", "0", "0", "inf"], "panda", "argument --tcp"),
        ([], str(tmp_path / "mybot.yaml"), "mybot.yaml, field 'nominal': cannot tell which nominal model"),
        ([], str(tmp_path / "drift.yaml"), "drift needs the time since a session started"),
    ]
    for extra, model, message in cases:
        assert main(["correct", model, str(goals), "-o", out, *extra]) == 2
        err = capsys.readouterr().err
        assert len(err.strip().splitlines()) == 1 and message in err, err
    assert main(["correct", "panda", str(goals), "-o", out]) == 0
    assert main(["correct", "panda", str(goals), "-o", out]) == 2  # kept unless --force
    assert "--force" in capsys.readouterr().err


def test_an_unreachable_goal_is_written_with_its_reason_and_exit_code_1(tmp_path, capsys):
    goals = tmp_path / "in.csv"
    goals.write_text("x,y,z\n400,0,500\n3000,0,0\n")
    assert main(["correct", "panda", str(goals), "-o", str(tmp_path / "out.csv")]) == 1
    head, rows = read_out(tmp_path / "out.csv")
    assert [r[head.index("ok")] for r in rows] == ["true", "false"]
    assert rows[1][head.index("reason")].startswith("unreachable: the best of 9 starts misses by")
    out, err = capsys.readouterr()
    assert "line 3: unreachable" in err
    # the summary's residual is the miss the row reports, not 0 (the reached goals' alone)
    miss, hit = (float(r[head.index("residual_mm")]) for r in (rows[1], rows[0]))
    assert miss > 1000 and hit < 0.01
    said = re.search(r"1 of 2 goals reached; residual (\S+) mm max \((\S+) mm over the 1 reached\)", out)
    assert said and abs(float(said[1]) - miss) < 0.05 and float(said[2]) < 0.01, out
    goals.write_text("x,y,z\n3000,0,0\n")
    assert main(["correct", "panda", str(goals), "-o", str(tmp_path / "out.csv"), "--force"]) == 1
    head, rows = read_out(tmp_path / "out.csv")
    miss = float(rows[0][head.index("residual_mm")])
    assert f"0 of 1 goals reached; residual {miss:.1f} mm max\n" in capsys.readouterr().out
