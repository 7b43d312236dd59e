"""``lasercal plan`` end to end on a simulated session."""

from __future__ import annotations

import csv
import json

import numpy as np

from lasercal.collector.cli.main import main
from lasercal.solver.formats.robots import load_model
from lasercal.solver.formats.session import load_session
from lasercal.solver.kinematics.aim import spot_error


def test_plan_writes_aimed_configurations_and_rejects_bad_input(tmp_path, capsys):
    s = tmp_path / "s"
    args = ["simulate", "panda_thesis_identified", "--layout", "thesis", "--robot", "panda"]
    assert main(args + ["--per-point", "4", "--seed", "1", "-o", str(s)]) == 0
    out = tmp_path / "next.csv"
    assert main(["plan", str(s), "--next", "3", "-o", str(out)]) == 0
    rows = list(csv.DictReader(out.open()))
    assert list(rows[0]) == ["point"] + [f"q{i}" for i in range(1, 8)] + ["expected_mm"]
    assert len(rows) == 3
    session, panda = load_session(s), load_model("panda")
    q = np.array([[float(r[f"q{i}"]) for i in range(1, 8)] for r in rows])
    assert panda.within_limits(q).all()
    expected = [float(r["expected_mm"]) for r in rows]
    assert expected == sorted(expected, reverse=True)
    capsys.readouterr()
    far = tmp_path / "far.yaml"
    far.write_text(
        "format: lasercal-layout/1\nplane: {z: -8}\npoints: {P1: [2521, 200, -8], P4: [441, 160, -8]}\n"
        "calibration: [P1]\nvalidation: [P4]\n"
    )
    for bad, words in (
        (["--next", "0"], "argument --next: 0 is out of range"),
        (["--workspace", "500", "0", "-8", "400", "100", "-8"], "must be <= max"),
        (["--layout", str(far)], "out of reach"),
    ):
        assert main(["plan", str(s)] + bad) == 2
        err = capsys.readouterr().err.strip()
        assert words in err and "\n" not in err
    # the plan aims at its points under the current model: refit it and check
    from lasercal.solver.analysis.design import posterior

    post = posterior(
        panda.replace(aperture=np.r_[panda.aperture[:2], session.aperture_z]),
        session.q,
        session.target,
        session.tolerances,  # the robot's: plan's prior
    )
    pts = [session.points[r["point"]] for r in rows]
    assert all(spot_error(post.model, qi[None], p)[0] < 0.5 for qi, p in zip(q, pts))


def test_plan_counts_the_parameters_solve_counts_on_a_sheet_session(tmp_path, capsys):
    """One count: a sheet session's pose is a parameter and the base frame's gauge is held, in ``plan`` (as
    in the capture coach) as in ``solve``; spots miss two combinations: the aperture along the beam, and the
    scale common to robot and sheet (residuals in the printed sheet's units, eq. S4, cannot tell it)."""
    s = tmp_path / "s"
    args = ["simulate", "panda_thesis_identified", "--layout", "thesis", "--robot", "panda"]
    assert main(args + ["--per-point", "6", "--seed", "2", "--sheet-pose", "3", "-2", "1", "-o", str(s)]) == 0
    capsys.readouterr()
    assert main(["plan", str(s), "--next", "2", "--json"]) == 0
    planned = json.loads(capsys.readouterr().out)["identifiable"]
    assert main(["solve", str(s), "-o", str(tmp_path / "m.yaml"), "--folds", "0", "--json"]) == 0
    solved = json.loads(capsys.readouterr().out)["identifiability"]
    # 7 joints x 4 + beam direction 2 + beam start 3 + sheet pose 3, print scale 2, tilt 2 - 5 held for the
    # base frame
    assert planned["parameters"] == solved["parameters"] == 35
    assert planned["rank"] == solved["rank"] == planned["of"] == solved["possible"] == 33
    # the unseen directions: one holds the print scale with the arm's lengths (a world grown with the sheet)
    assert sum("sheet.e" in d for d in solved["unidentifiable"]) == 1
    assert solved["counted"].startswith("35 = 7 joints x 4")
    assert "sheet pose 3, print scale 2 and tilt 2 - 5 held" in solved["counted"]
