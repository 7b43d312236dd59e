"""Degenerate fits fail loudly: a still joint is named; --allow-partial writes a model marked partial."""

from __future__ import annotations

import csv
import dataclasses
import shutil

import pytest
import yaml

from lasercal.collector.cli.main import main
from lasercal.solver.formats.data import builtin_dir
from lasercal.solver.identify.measurement import fit, unidentifiable

LAYOUT = str(builtin_dir("layouts") / "thesis.yaml")


@pytest.fixture(scope="module")
def session_dir(tmp_path_factory):
    out = tmp_path_factory.mktemp("degenerate") / "s"
    assert main(["simulate", "panda_thesis_identified", "--layout", LAYOUT, "--per-point", "12",
                 "--aim-noise", "0.3", "--seed", "5", "-o", str(out)]) == 0  # fmt: skip
    return out


def _freeze_joint(src, dst, joint: int) -> None:
    """A copy of the session in which joint ``joint`` (1-based) stays at its first capture's value."""
    shutil.copytree(src, dst)
    path = dst / "captures.csv"
    rows = list(csv.reader(path.open()))
    col = rows[0].index(f"q{joint}")
    for r in rows[2:]:
        r[col] = rows[1][col]
    with path.open("w", newline="") as f:
        csv.writer(f, lineterminator="\n").writerows(rows)


def test_full_session_has_no_deficiency(panda_noisy):
    session = dataclasses.replace(panda_noisy[0], tolerances=None)  # least squares: nothing held by a prior
    ident = fit(session)
    assert ident.identifiability.rank == ident.identifiability.n_params - 1  # only the aperture gauge
    assert unidentifiable(session, ident) == []


@pytest.mark.parametrize("joint", [1, 4, 7])
def test_still_joint_is_named_first(panda_noisy, joint):
    session = panda_noisy[0]
    q = session.q.copy()
    q[:, joint - 1] = q[0, joint - 1]
    still = dataclasses.replace(session, q=q, tolerances=None)  # least squares (a prior holds it: test_prior)
    ident = fit(still)
    missing = unidentifiable(still, ident)
    deficit = ident.identifiability.n_params - 1 - ident.identifiability.rank
    assert deficit >= 4 and sum(d.directions for d in missing) == deficit  # every direction accounted for
    assert [d.combination for d in missing[:2]] == [
        f"joint {joint}'s axis direction",
        f"joint {joint}'s axis position",
    ]
    assert all(d.fix == f"vary joint {joint}: it never moves in this session" for d in missing[:2])


def test_solve_refuses_a_still_joint(session_dir, tmp_path, capsys):
    """Without a prior (--prior none) nothing holds joint 4's axis: refused, the cause named."""
    _freeze_joint(session_dir, tmp_path / "s", 4)
    capsys.readouterr()
    args = ["solve", str(tmp_path / "s"), "-o", str(tmp_path / "m.yaml"), "--folds", "0", "--prior", "none"]
    assert main(args) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("lasercal: error: the data cannot identify 4 parameter")
    assert "joint 4's axis direction (vary joint 4: it never moves in this session)" in err[0]
    assert "--allow-partial" in err[0] and "Traceback" not in err[0]
    assert not (tmp_path / "m.yaml").exists()


def test_allow_partial_writes_a_model_marked_partial(session_dir, tmp_path, capsys):
    _freeze_joint(session_dir, tmp_path / "s", 4)
    out = tmp_path / "m.yaml"
    args = ["solve", str(tmp_path / "s"), "-o", str(out), "--folds", "0", "--allow-partial"]
    assert main(args + ["--prior", "none"]) == 0
    assert "PARTIAL: not identified: joint 4's axis direction" in capsys.readouterr().out
    idn = yaml.safe_load(out.read_text())["identification"]
    assert idn["partial"] is True
    assert [c["combination"] for c in idn["unidentifiable_combinations"]] == [
        "joint 4's axis direction",
        "joint 4's axis position",
    ]
    assert sum(c["directions"] for c in idn["unidentifiable_combinations"]) == 4


def test_the_prior_holds_a_still_joint_and_solve_says_so(session_dir, tmp_path, capsys):
    """Under the robot's prior (the default) joint 4's axis is the prior's: no --allow-partial needed, and
    solve names it with what it leaves uncalibrated."""
    _freeze_joint(session_dir, tmp_path / "s", 4)
    out = tmp_path / "m.yaml"
    capsys.readouterr()
    assert main(["solve", str(tmp_path / "s"), "-o", str(out), "--folds", "0"]) == 0
    text = capsys.readouterr().out
    idn = yaml.safe_load(out.read_text())["identification"]
    assert idn["partial"] is False
    named = [c["combination"] for c in idn["determined_by"]["from_prior"]]
    # frozen angles no longer fit the spots: the prior holds joint 4 and more; the greedy naming's order
    # varies with the realisation, so every named group is checked to be printed with what it leaves
    assert named and all(f"from the prior: {n}" in text for n in named) and "uncalibrated" in text


def test_full_rank_model_is_marked_complete(session_dir, tmp_path):
    out = tmp_path / "m.yaml"
    assert main(["solve", str(session_dir), "-o", str(out), "--folds", "0"]) == 0
    idn = yaml.safe_load(out.read_text())["identification"]
    assert idn["partial"] is False and "unidentifiable_combinations" not in idn


def test_captures_at_one_point_warn_and_name_what_the_prior_holds(session_dir, tmp_path, capsys):
    """Beams through one point cannot tell the robot from itself turned about that point (3 directions):
    the fit exits 0 under the prior, with a warning naming the prior-held combinations."""
    one = tmp_path / "one"
    shutil.copytree(session_dir, one)
    path = one / "captures.csv"
    rows = list(csv.reader(path.open()))
    with path.open("w", newline="") as f:
        csv.writer(f, lineterminator="\n").writerows([rows[0]] + [r for r in rows[1:] if r[0] == "P1"])
    assert main(["solve", str(one), "-o", str(tmp_path / "m.yaml"), "--folds", "0"]) == 0
    out = capsys.readouterr().out
    warning = next(line for line in out.splitlines() if line.startswith("WARNING"))
    assert "every capture is at one point, P1" in warning and "the prior alone determines" in warning
    held = yaml.safe_load((tmp_path / "m.yaml").read_text())["identification"]["determined_by"]["from_prior"]
    assert held and all(d["combination"] in warning for d in held)
    # and a session at three points has no such warning
    assert main(["solve", str(session_dir), "-o", str(tmp_path / "m3.yaml"), "--folds", "0"]) == 0
    assert "one point" not in capsys.readouterr().out


def test_joints_are_named_by_number_or_by_name_on_trees():
    """A chain's joints by their number; a tree's (lateral axes among its joints) by their names."""
    from lasercal.solver.formats.robots import load_model
    from lasercal.solver.kinematics.joint_names import joint_label

    panda = [f"panda_joint{j + 1}" for j in range(7)]
    assert [joint_label(j, panda) for j in (0, 6)] == ["joint 1", "joint 7"]
    assert joint_label(3, [f"joint{j + 1}" for j in range(6)]) == "joint 4"
    justin = load_model("justin").joint_names
    assert joint_label(51, justin) == "joint left_7" and joint_label(1, justin) == "joint torso_1.x"
    assert joint_label(0, justin) == "joint torso_1"  # its name says 1, but a tree's joints go by name
