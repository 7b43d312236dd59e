"""The ``lasercal`` command end to end, and every malformed-file case: one line, exit code 2."""

import csv
import io
import json
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml

from lasercal.collector.cli.main import main
from lasercal.solver.formats.data import builtin_dir
from lasercal.solver.formats.robots import load_model

LAYOUT = str(builtin_dir("layouts") / "thesis.yaml")


@pytest.fixture(scope="module")
def session_dir(tmp_path_factory):
    out = tmp_path_factory.mktemp("cli") / "s"
    assert (
        main(
            [
                "simulate",
                "panda_thesis_identified",
                "--layout",
                LAYOUT,
                "--per-point",
                "15",
                "--aim-noise",
                "0.5",
                "--seed",
                "4",
                "-o",
                str(out),
            ]
        )
        == 0
    )
    return out


def test_simulate_solve_predict_round_trip(session_dir, tmp_path, capsys):
    meta = yaml.safe_load((session_dir / "session.yaml").read_text())
    assert (
        meta["format"] == "lasercal-session/1"
        and meta["robot"] == "panda"
        and meta["laser"]["aperture_z"] == 825
    )
    assert meta["units"] == {"length": "mm", "angle": "rad", "torque": "Nm", "time": "s"}
    capsys.readouterr()
    assert main(["solve", str(session_dir), "-o", str(tmp_path / "m.yaml"), "--json"]) == 0
    rep = json.loads(capsys.readouterr().out)
    assert rep["converged"] and rep["iterations"] < 40  # LM steps over the noise passes (eq. P3)
    assert (
        rep["points"]["P1"]["before"]["error_mean"] > 5 and rep["points"]["P1"]["after"]["error_mean"] < 1.0
    )
    assert rep["cross_validation"]["holdout_rms_mm"] < 1.5
    model = load_model(tmp_path / "m.yaml")
    assert model.identification["method"] == "lm" and "joint7.qx" in model.identification["std_errors"]
    # predict: input columns pass through, spots of the captured configurations land near their points
    rows = list(csv.DictReader(open(session_dir / "captures.csv")))
    cfg = tmp_path / "configs.csv"
    with open(cfg, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["label"] + [f"q{i}" for i in range(1, 8)])
        for r in rows:
            w.writerow([r["point"]] + [r[f"q{i}"] for i in range(1, 8)])
    assert main(["predict", str(tmp_path / "m.yaml"), str(cfg)]) == 0
    out = list(csv.DictReader(io.StringIO(capsys.readouterr().out)))
    assert list(out[0])[-4:] == ["spot_x", "spot_y", "laser_length", "valid"] and out[0]["label"] == "P1"
    pts = {"P1": (521, 200), "P2": (436, 0), "P3": (521, -200)}
    err = [
        np.hypot(float(o["spot_x"]) - pts[o["label"]][0], float(o["spot_y"]) - pts[o["label"]][1])
        for o in out
    ]
    assert np.sqrt(np.mean(np.square(err))) < 1.0
    assert all(400 < float(o["laser_length"]) + 833 < 1500 for o in out)


def test_solve_thesis_method_text_output(session_dir, tmp_path, capsys):
    assert (
        main(
            ["solve", str(session_dir), "-o", str(tmp_path / "t.yaml"), "--method", "thesis", "--folds", "0"]
        )
        == 0
    )
    out = capsys.readouterr().out
    assert "method thesis" in out and "P2" in out and "not seen by the data" in out


def _corrupt(session_dir, tmp_path, edit_csv=None, edit_yaml=None):
    bad = tmp_path / "bad"
    shutil.copytree(session_dir, bad)
    if edit_csv:
        lines = (bad / "captures.csv").read_text().splitlines()
        (bad / "captures.csv").write_text("\n".join(edit_csv(lines)) + "\n")
    if edit_yaml:
        meta = yaml.safe_load((bad / "session.yaml").read_text())
        edit_yaml(meta)
        (bad / "session.yaml").write_text(yaml.safe_dump(meta))
    return bad


def _set_cell(lines, row, col, value):
    """Set one cell; ``row`` indexes the list of lines, so the file line is row + 1."""
    header = lines[0].split(",")
    cells = lines[row].split(",")
    cells[header.index(col)] = value
    lines[row] = ",".join(cells)
    return lines


@pytest.mark.parametrize(
    "edit_csv, edit_yaml, expect",
    [
        (
            lambda L: _set_cell(L, 3, "point", "P9"),
            None,
            ["captures.csv, line 4, column 'point'", "unknown point 'P9'"],
        ),
        (lambda L: _set_cell(L, 5, "q4", ""), None, ["captures.csv, line 6, column 'q4'", "missing value"]),
        (
            lambda L: _set_cell(L, 6, "t", "abc"),
            None,
            ["captures.csv, line 7, column 't'", "not a finite number"],
        ),
        (
            lambda L: _set_cell(L, 7, "q4", "0.5"),
            None,
            ["captures.csv, line 8, column 'q4'", "outside its limits"],
        ),
        (
            lambda L: [L[0].replace("q7", "qq")] + L[1:],
            None,
            ["captures.csv, line 1, column 'q7'", "missing column"],
        ),
        (lambda L: L[:4] + [L[4] + ",1"] + L[5:], None, ["captures.csv, line 5", "expected 16 values"]),
        (None, lambda m: m.update(format="other/2"), ["session.yaml, field 'format'"]),
        (None, lambda m: m["points"].update(P1=[1, 2]), ["session.yaml, field 'points.P1'"]),
        (None, lambda m: m.update(robot="nonexistent_robot"), ["nonexistent_robot", "no such robot"]),
        (None, lambda m: m["units"].update(length="m"), ["session.yaml, field 'units.length'"]),
    ],
)
def test_malformed_session_one_line_exit_2(session_dir, tmp_path, capsys, edit_csv, edit_yaml, expect):
    bad = _corrupt(session_dir, tmp_path, edit_csv, edit_yaml)
    assert main(["solve", str(bad), "-o", str(tmp_path / "m.yaml")]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and err.startswith("lasercal: error: ")
    for e in expect:
        assert e in err, err
    assert not (tmp_path / "m.yaml").exists()


def test_unparseable_yaml_and_missing_folder(tmp_path, capsys, session_dir):
    bad = _corrupt(session_dir, tmp_path)
    (bad / "session.yaml").write_text("format: [unclosed\n")
    assert main(["solve", str(bad), "-o", str(tmp_path / "m.yaml")]) == 2
    assert "session.yaml" in capsys.readouterr().err and True
    assert main(["solve", str(tmp_path / "nope"), "-o", str(tmp_path / "m.yaml")]) == 2
    assert "nope: no such folder" in capsys.readouterr().err


def test_demo_prints_p4_beside_the_thesis(full_demo):
    code, out, _, folder = full_demo  # the README's demo (tests/test_readme.py), run once
    assert code == 0
    assert "thesis paper, after" in out and "lm (ours)" in out
    s = json.loads((folder / "summary.json").read_text())
    assert s["p4"]["nominal"]["error_mean"] > 5 and s["p4"]["lm"]["error_mean"] < 1.5


def test_third_party_warnings_never_reach_the_terminal(capsys):
    """Inside a command, a library's warning (numpy's, scipy's, matplotlib's) shows nothing; lasercal's own
    warning is one line ``lasercal: warning: ...``; a library's logging goes nowhere."""
    import logging
    import warnings

    from lasercal.collector.cli.main import quiet_libraries, warnings_as_lines
    from lasercal.solver.errors import warn

    quiet_libraries()
    with warnings_as_lines():
        warnings.warn("Covariance of the parameters could not be estimated", UserWarning, stacklevel=1)
        warnings.warn("np.float is deprecated", DeprecationWarning, stacklevel=1)
        logging.getLogger("matplotlib.font_manager").warning("Matplotlib is building the font cache")
        warn("a capture saved twice")
    assert capsys.readouterr().err.splitlines() == ["lasercal: warning: a capture saved twice"]


def test_stdout_closed_early_ends_quietly_with_141(session_dir, tmp_path):
    """``lasercal predict ... | head -1``: the reader goes after one line; lasercal stops with 141 (128 +
    SIGPIPE, as a shell reports) and prints nothing, where it printed ``lasercal: error: Broken pipe``."""
    rows = list(csv.DictReader(open(session_dir / "captures.csv")))
    cfg = tmp_path / "configs.csv"
    with open(cfg, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow([f"q{i}" for i in range(1, 8)])
        for _ in range(300):  # 300 x 45 rows of ~100 bytes: far more than a pipe holds (64 KiB)
            w.writerows([r[f"q{i}"] for i in range(1, 8)] for r in rows)
    child = subprocess.Popen(
        [sys.executable, "-m", "lasercal.collector.cli.main", "predict", "panda_thesis_identified", str(cfg)],
        cwd=Path(__file__).resolve().parents[1],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
    )
    assert child.stdout.readline().startswith(b"q1,q2,")
    child.stdout.close()
    err = child.stderr.read().decode()
    assert (child.wait(timeout=120), err) == (141, "")
