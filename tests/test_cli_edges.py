"""Edges a new user cut on (issue 47, items 7-10, 15): what each command says and writes where a first run
went wrong. Truth: the files the commands wrote, read back by an independent reader (csv.DictReader, the
URDF's own text), and what a user types."""

from __future__ import annotations

import csv
import io
import re

import numpy as np
import pytest

from lasercal.collector.cli.main import main
from lasercal.solver.formats.data import builtin_dir
from lasercal.solver.formats.poses import pose_meta, write_pose_session
from lasercal.solver.formats.robots import load_model
from lasercal.solver.formats.session import load_session
from lasercal.solver.kinematics.poe import exp6, fk


def test_predict_of_a_pose_model_names_its_measured_and_predicted_columns_apart(tmp_path, capsys):
    """A pose session's captures predicted by the model solved on them: the measured x ... rz carried from
    the input are measured_x ... measured_rz, the predicted keep x ... rz (the outside check reads them),
    so a csv.DictReader reads each once; and ``-o`` says what it wrote."""
    ur = load_model("ur10")
    q = np.random.default_rng(3).uniform(-2.5, 2.5, (30, 6))
    X = exp6(np.r_[0.1, -0.2, 0.5, 2500.0, -1500.0, -1200.0])  # the tracker 3 m away
    T = X @ fk(ur.screws, ur.ee_pose @ exp6(np.r_[0, 0, 0.3, 1.0, 2.0, 90.0]), q)  # exact poses
    write_pose_session(tmp_path / "s", pose_meta("ur10"), q, T)
    model, out = tmp_path / "m.yaml", tmp_path / "out.csv"
    assert main(["solve", str(tmp_path / "s"), "-o", str(model), "--folds", "0"]) == 0
    capsys.readouterr()
    assert main(["predict", str(model), str(tmp_path / "s" / "captures.csv"), "-o", str(out)]) == 0
    said = capsys.readouterr().out.splitlines()
    assert said == [f"wrote {out}: 30 rows, the input's columns and x, y, z, rx, ry, rz"]
    header = out.read_text().splitlines()[0].split(",")
    assert len(header) == len(set(header))
    assert header[-12:] == [f"measured_{k}" for k in ("x", "y", "z", "rx", "ry", "rz")] + list(header[-6:])
    measured = list(csv.DictReader((tmp_path / "s" / "captures.csv").open()))
    rows = list(csv.DictReader(out.open()))
    for k in ("x", "y", "z"):  # the predicted beside the measured (exact data: the fit reproduces them)
        m = np.array([float(r[k]) for r in measured])
        assert np.array_equal([float(r[f"measured_{k}"]) for r in rows], m)
        assert np.abs(np.array([float(r[k]) for r in rows]) - m).max() < 1e-3


def test_export_urdf_says_on_stderr_what_a_urdf_cannot_carry(tmp_path, capsys):
    """A compliance is no joint origin: ``--format urdf`` names it on stderr with its size, as ``--format
    franka`` does (before: an XML comment only); a model without effects exports without a word."""
    ext = {"joint_compliance": {"units": "rad/Nm", "joints": [2, 4], "c": [-2e-4, -1e-4]}}
    load_model("panda").replace(extensions=ext).save(tmp_path / "m.yaml")
    out = tmp_path / "m.urdf"
    assert main(["export", str(tmp_path / "m.yaml"), "--format", "urdf", "-o", str(out)]) == 0
    err = capsys.readouterr().err.splitlines()
    said = [s for s in err if s.startswith("lasercal: warning: not in the URDF: the joint_compliance")]
    assert len(said) == 1 and "of joint(s) 2, 4" in said[0] and "mm at the flange" in said[0], err
    assert "joint_compliance" in out.read_text()  # still listed in the file, for whoever reads it
    load_model("panda").save(tmp_path / "n.yaml")
    assert main(["export", str(tmp_path / "n.yaml"), "--format", "urdf", "-o", str(tmp_path / "n.urdf")]) == 0
    assert "warning" not in capsys.readouterr().err


@pytest.fixture(scope="module")
def folders(tmp_path_factory):
    """A simulated session (session.yaml not written by capture), its model, and a finished validation."""
    d = tmp_path_factory.mktemp("edges")
    layout = str(builtin_dir("layouts") / "thesis.yaml")
    sim = ["simulate", "panda_thesis_identified", "--layout", layout, "--per-point", "4", "-o", str(d / "s")]
    assert main(sim) == 0
    assert main(["solve", str(d / "s"), "-o", str(d / "m.yaml"), "--folds", "0"]) == 0
    assert main(["validate", str(d / "m.yaml"), "--backend", "fake", "-n", "2", "-o", str(d / "v")]) == 0
    return d


def _hint(err: str) -> str:
    """The advice of an 'exists and is kept (...)' line."""
    return re.search(r"exists and is kept \((.*)\)$", err.strip()).group(1)


@pytest.mark.parametrize(
    "argv, folder, says",
    [
        (
            ["validate", "{d}/m.yaml", "--backend", "fake", "-n", "2"],
            "s",
            "a capture session, not a validation",
        ),
        (
            ["capture", "--backend", "fake", "--auto", "--per-point", "2"],
            "v",
            "a validation run, not a capture",
        ),
        (
            ["capture", "--backend", "fake", "--auto", "--per-point", "2"],
            "s",
            "not written by lasercal capture",
        ),
        (["validate", "{d}/m.yaml", "--backend", "fake", "-n", "2"], "empty", "not a validation run"),
    ],
)
def test_an_existing_output_is_resumed_only_where_the_resume_would_run(folders, argv, folder, says, capsys):
    """``-o`` naming a folder the command cannot resume says to choose another -o; the --resume the old hint
    gave fails there (the user's walkthrough), the one given for a validation run works."""
    (folders / "empty" / "notes").mkdir(parents=True, exist_ok=True)
    capsys.readouterr()
    args = [a.replace("{d}", str(folders)) for a in argv]
    assert main(args + ["-o", str(folders / folder)]) == 2
    hint = _hint(capsys.readouterr().err)
    assert says in hint and "choose another -o" in hint and "--resume" not in hint
    assert main([argv[0], "--resume", str(folders / folder)]) == 2  # what the old hint said: it fails
    assert "nothing to resume" in capsys.readouterr().err


def test_a_validation_run_s_hint_resumes_it(folders, capsys):
    capsys.readouterr()
    validate = ["validate", str(folders / "m.yaml"), "--backend", "fake", "-n", "2", "-o", str(folders / "v")]
    assert main(validate) == 2
    hint = _hint(capsys.readouterr().err)
    assert hint == f"resume it with --resume {folders / 'v'}"
    assert main(["validate", *hint.split(" with ")[1].split()]) == 0
    assert "2 of 2 configurations" in capsys.readouterr().out


CAPTURE = ["capture", "--backend", "fake", "--layout", "thesis", "--per-point", "2", "--no-coach"]


def test_capture_whose_standard_input_ends_stops_keeps_its_captures_and_says_so(
    tmp_path, capsys, monkeypatch
):
    """``capture`` without ``--auto`` reads Enter from standard input. Its end is no operator's quit: before
    any capture, exit 2 and the new session is not kept (was exit 0, an empty session); after some, exit 1,
    each capture on disk, and the resume the message gives finishes the session."""
    s = tmp_path / "s"
    monkeypatch.setattr("sys.stdin", open("/dev/null"))
    assert main(CAPTURE + ["-o", str(s)]) == 2
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 1 and err[0].startswith("lasercal: error: standard input ended"), err
    assert "nothing captured" in err[0] and not s.exists()
    monkeypatch.setattr("sys.stdin", io.StringIO("\n\n\n"))  # three Enters, then the end
    assert main(CAPTURE + ["-o", str(s)]) == 1
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 1 and "standard input ended" in err[0] and "3 captures in" in err[0], err
    assert load_session(s).m == 3
    resume = err[0].split("resume with: ")[1].split()
    assert resume == ["lasercal", "capture", "--resume", str(s)]
    monkeypatch.setattr("sys.stdin", io.StringIO(""))  # resumed, and nothing more: exit 2, the 3 kept
    assert main(resume[1:] + ["--no-coach"]) == 2
    assert "nothing captured this run" in capsys.readouterr().err and load_session(s).m == 3
    monkeypatch.setattr("sys.stdin", io.StringIO("\n\n\n"))
    assert main(resume[1:] + ["--no-coach"]) == 0
    assert load_session(s).m == 6 and "session complete: 6 captures" in capsys.readouterr().out


def test_solve_on_too_few_captures_at_a_point_names_the_captures_file(tmp_path, capsys):
    """A base-frame session cut to one capture at P3: one line naming the captures file, exit 2, no model."""
    s = tmp_path / "s"
    args = ["simulate", "panda_thesis_identified", "--layout", "thesis", "--per-point", "4", "-o", str(s)]
    assert main(args) == 0
    lines = (s / "captures.csv").read_text().splitlines(keepends=True)
    p3 = [i for i, ln in enumerate(lines) if ln.startswith("P3,")]
    (s / "captures.csv").write_text("".join(ln for i, ln in enumerate(lines) if i not in p3[1:]))
    capsys.readouterr()
    assert main(["solve", str(s), "-o", str(tmp_path / "m.yaml")]) == 2
    err = capsys.readouterr().err.splitlines()
    head = f"lasercal: error: {s / 'captures.csv'}: too few captures at P3 (1): "
    assert len(err) == 1 and err[0].startswith(head), err
    assert not (tmp_path / "m.yaml").exists()
