"""The diagnosis on the user's path (issue 45): a printed sheet laid off its placement, eye, camera and mixed
sessions made and solved by the public commands; each hidden effect is named at its joint, null sessions
give none, and the sheet's print scale is found without bias.

Every test before this file used the thesis's base-frame layout; on a sheet session every candidate scored
F = 0: a fit in base-frame mm could shrink robot and sheet together (a common scale) until its residual
lay in the fit's own span. The residuals are now in the printed sheet's units (eq. S4 of
solver/kinematics/sheet.py), where a common scale does not pay.
"""

from __future__ import annotations

import contextlib
import io
import json
import re
from dataclasses import replace

import numpy as np
import pytest

from lasercal.collector.cli.main import main
from lasercal.simulation import simulate
from lasercal.solver.analysis import diagnose
from lasercal.solver.formats.robots import load_model
from lasercal.solver.formats.session import load_session
from lasercal.solver.identify.measurement import fit
from lasercal.solver.kinematics.effects import candidates
from lasercal.solver.kinematics.sheet import SheetPose, sheet_residual

# --measured, --aim-noise: eye (every capture aimed at its cross), camera (every spot measured at 0.03 mm,
# aimed anywhere within 40 mm of its point), mixed (half measured, half aimed by eye)
KINDS = {"eye": ("0", "0.5"), "camera": ("1", "0.5"), "mixed": ("0.5", "0.5")}


def run(argv: list) -> str:
    out = io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(io.StringIO()):
        code = main(argv)
    assert code == 0, out.getvalue()
    return out.getvalue()


def simulated(tmp_path, sheet, kind: str, seed: int, effect: tuple = ()) -> str:
    """`lasercal simulate` on the sheet laid at 452, 3 mm, 1 deg (75 captures at P1-P5); the folder."""
    measured, noise = KINDS[kind]
    s = str(tmp_path / f"{kind}{seed}")
    run(
        ["simulate", "panda_thesis_identified", "--layout", str(sheet), "--sheet-pose", "452", "3", "1.0"]
        + ["--per-point", "15", "--aim-noise", noise, "--measured", measured, "--seed", str(seed), "-o", s]
        + list(effect)
    )
    return s


def diagnosis(tmp_path, session: str) -> dict:
    """`lasercal solve S --extend auto --json`'s diagnosis."""
    out = ["-o", str(tmp_path / "m.yaml"), "--force"]
    return json.loads(run(["solve", session, *out, "--extend", "auto", "--json"]))["diagnosis"]


def test_the_issues_session_names_the_compliance_where_every_candidate_scored_zero(tmp_path, sheet):
    # issue 45's first command: `simulate ... --sheet-pose 452 3 1.0 --per-point 15 --aim-noise 0.5 --effect
    # joint_compliance --effect-joints 2 --effect-size 1.5e-4`, `solve --extend auto` said 'finding: none'
    s = simulated(tmp_path, sheet, "eye", 0, ["--effect", "joint_compliance", "--effect-size", "1.5e-4"])
    text = run(["solve", s, "-o", str(tmp_path / "m.yaml"), "--extend", "auto"])
    assert "finding: joint_compliance at joint 2 (corrected p = " in text, text
    d = diagnosis(tmp_path, s)
    assert d["parameters"]["c2"]["value"] == pytest.approx(1.5e-4, abs=4 * d["parameters"]["c2"]["std_error"])
    assert d["acceptance"]["accepted"] and d["gain_percent"] > 5  # held out: 1.071 -> 0.808 mm
    assert max(c["F"] for c in d["details"]["candidates"]) > 30  # F = 0.000 for every candidate before


def test_a_sheet_sessions_residual_is_outside_the_fits_span():
    # the root cause: in base-frame mm a common scale of robot and sheet moves every residual along itself
    # (d r / d scale = r), so the fit's span held the residual and no candidate could explain any of it.
    # In sheet units the residual is invariant to that scale: it is the fit's null direction, not its span.
    r = np.random.default_rng(1).normal(0, 0.5, (40, 2))
    v = SheetPose(452.0, 3.0, 1.0, 1.001, 0.999).vector
    grown = v.copy()
    grown[:2] *= 1.01  # the sheet's position grows with the world ...
    grown[3:5] = (1 + v[3:5]) * 1.01 - 1  # ... and so does its print
    rs, _, _ = sheet_residual(v, r)
    assert np.allclose(sheet_residual(grown, 1.01 * r)[0], rs, atol=1e-12)  # the spots' offsets grew too


def test_an_eye_sheet_sessions_residual_leaves_room_for_a_candidate(tmp_path, sheet):
    s = load_session(
        simulated(tmp_path, sheet, "eye", 3, ["--effect", "joint_compliance", "--effect-size", "1.5e-4"])
    )
    tau, _ = diagnose.session_torques(s)
    geo = fit(s)
    t = diagnose.Tester(s, geo, candidates(7, [], True, False), tau)
    assert np.linalg.norm(t.res - t.U @ (t.U.T @ t.res)) > 0.5 * np.linalg.norm(t.res)  # was 5e-13 of it


CASES = [  # (kind, seed, --effect NAME, joints, size): every effect family on every kind of session
    ("eye", 13, "encoder_eccentricity", "3", "3e-3"),  # a phase the joint's zero cannot absorb (the seed's)
    ("camera", 13, "joint_compliance", "2", "5e-5"),
    ("camera", 14, "drift", "4", "3e-7"),
    ("camera", 15, "encoder_eccentricity", "1", "5e-4"),
    ("mixed", 16, "drift", "2", "1e-6"),
    ("mixed", 17, "joint_compliance", "4", "1e-4"),
]


@pytest.mark.parametrize("kind, seed, effect, joints, size", CASES)
def test_an_effect_hidden_in_a_sheet_session_is_named_at_its_joint(
    tmp_path, sheet, kind, seed, effect, joints, size
):
    s = simulated(
        tmp_path, sheet, kind, seed, ["--effect", effect, "--effect-joints", joints, "--effect-size", size]
    )
    d = diagnosis(tmp_path, s)
    assert d["effect"] == effect and d["joints"] == [int(joints)], (
        d["label"],
        d["details"]["candidates"][:3],
    )
    assert d["acceptance"]["accepted"] and d["gain_percent"] > 0


def test_an_eye_sessions_marginal_compliance_is_proposed_and_refused_by_its_folds(tmp_path, sheet):
    # was a case of the test above (named, gain > 0, with the choice made on the whole session). The whole
    # session's F test still proposes it (corrected p = 0.0015); on 80 % of the rows 1 fold of 5 chooses
    # it (p 0.002 - 0.10 in the folds), and there it loses held out: 0.860 mm without, 0.870 mm with
    s = simulated(
        tmp_path,
        sheet,
        "eye",
        11,
        ["--effect", "joint_compliance", "--effect-joints", "4"] + ["--effect-size", "1.5e-4"],
    )
    d = diagnosis(tmp_path, s)
    acc = d["acceptance"]
    assert d["effect"] == "none" and d["proposed"]["joints"] == [4], d["label"]
    assert acc["folds_agree"] == 1 and acc["holdout_rms_mm"]["extended"] > acc["holdout_rms_mm"]["geometric"]


@pytest.mark.parametrize("kind, seed", [("eye", 21), ("camera", 22), ("mixed", 23)])
def test_a_sheet_session_without_an_effect_finds_none(tmp_path, sheet, kind, seed):
    s = simulated(tmp_path, sheet, kind, seed)
    d = diagnosis(tmp_path, s)
    assert d["effect"] == "none", d["label"]
    assert "reference_point_offset" in d["untested"]  # a printed point is where the printer put it
    if kind == "camera":  # what remains beyond the camera is said plainly (here: nothing but its noise)
        text = run(["solve", s, "-o", str(tmp_path / "m.yaml"), "--force", "--extend", "auto"])
        remains = re.search(r"^remains: ([\d.]+) mm per axis beyond what the camera sees", text, re.M)
        # sqrt of the variance's excess over 0.03^2 from ~110 residual degrees of freedom: 0.011 at one sigma
        assert remains and float(remains.group(1)) < 0.025, text


def test_a_measured_layouts_point_offset_is_judged_by_the_captures_aimed_at_it(tmp_path):
    # half the spots measured by a camera (they use no point), half aimed at the points of a layout measured
    # in the base frame: the offset shows in the aimed ones alone, and the decision weighs each capture at
    # its own noise (judged by the measured ones only, the held-out error could not see it)
    layout = tmp_path / "measured.yaml"
    layout.write_text(
        "format: lasercal-layout/1\nunits: {length: mm}\nplane: {z: -8}\npoints: {P1: [481, 82, -8], "
        "P2: [481, -82, -8], P3: [450, 0, -8], P4: [419, 82, -8], P5: [419, -82, -8]}\n"
        "calibration: [P1, P2, P3, P4, P5]\n...\n"
    )
    s = str(tmp_path / "s")
    run(
        ["simulate", "panda_thesis_identified", "--layout", str(layout), "--per-point", "15", "--aim-noise"]
        + ["0.5", "--measured", "0.5", "--seed", "100", "--effect", "reference_point_offset"]
        + ["--effect-point", "P2", "--effect-size", "1.5", "-o", s]
    )
    d = diagnosis(tmp_path, s)
    assert d["effect"] == "reference_point_offset" and d["point"] == "P2"
    kinds = d["acceptance"]["holdout_by_kind"]
    assert kinds["aimed"]["extended"] < 0.8 * kinds["aimed"]["geometric"]


def test_the_print_scale_does_not_drift_as_the_same_captures_come_again(tmp_path, sheet):
    # before: a fit in base-frame mm shrank robot and print together by about m x 0.002^2 (m captures), so
    # the same 75 captures ten times over moved the print scale from -0.05, -0.03 % to -0.23, -0.34 % off
    # the truth (1.7 and 2.4 sigma); in the sheet's units the common scale earns nothing: 0.03, -0.07 %
    true = SheetPose(452.0, 3.0, 1.0, 1.0015, 0.9990, 0.002, -0.001)
    simulate(
        "panda_thesis_identified",
        tmp_path / "s",
        layout=str(sheet),
        per_point=15,
        aim_noise=0.5,
        seed=5,
        sheet_pose=true,
    )
    once = load_session(tmp_path / "s")
    for k in (1, 10):
        again = replace(
            once,
            point=np.tile(once.point, k),
            target=np.tile(once.target, (k, 1)),
            t=np.tile(once.t, k),
            q=np.tile(once.q, (k, 1)),
            tau=np.tile(once.tau, (k, 1)),
            lines=np.arange(k * once.m) + 2,
        )
        model = fit(again).model
        for axis in ("scale_x", "scale_y"):
            assert abs(getattr(model.sheet, axis) - getattr(true, axis)) < 1.5 * model.sheet_std[axis], (
                k,
                axis,
            )


def test_the_print_scale_and_tilt_are_recovered_within_their_sigma_from_many_captures(tmp_path, sheet):
    true = SheetPose(452.0, 3.0, 1.0, 1.0015, 0.9990, 0.002, -0.001)
    simulate(
        "panda_thesis_identified",
        tmp_path / "s",
        layout=str(sheet),
        per_point=150,
        aim_noise=0.5,
        seed=6,
        sheet_pose=true,
    )
    model = fit(load_session(tmp_path / "s")).model
    for k in ("scale_x", "scale_y", "tilt_x_rad", "tilt_y_rad"):
        assert abs(getattr(model.sheet, k) - getattr(true, k)) < 3 * model.sheet_std[k], k


def test_a_camera_session_of_the_fake_robot_proposes_the_compliance_its_truth_holds(tmp_path, sheet):
    # issue 45's second command: `capture --backend fake --camera fake --guide move --auto --truth T`, T a
    # model whose extensions hold a joint-2 compliance; the fake arm ignored T's extensions and solve found
    # nothing (every F = 0)
    truth = tmp_path / "T.yaml"
    load_model("panda_thesis_identified").replace(
        name="compliant", extensions={"joint_compliance": {"units": "rad/Nm", "joints": [2], "c": [1.5e-4]}}
    ).save(truth)
    s = str(tmp_path / "s")
    run(
        ["capture", "--layout", str(sheet), "--robot", "panda", "--backend", "fake", "--camera", "fake"]
        + ["--guide", "move", "--auto", "--per-point", "6", "--truth", str(truth), "-o", s]
    )
    d = diagnosis(tmp_path, s)
    # the fake arm holds T's compliance: the whole session's F test proposes it (corrected p = 9.7e-6; every
    # F = 0 before issue 45). Named before issue 52 (c2 within 4 sigma of the truth); with the selection
    # inside the folds, 2 of 5 folds choose it on their ~21 measured captures (corrected p 1e-6, 1e-5; the
    # other three 0.03-0.16), short of the 4 the agreement rule needs: 'none', its gain still measured (the
    # measured captures held out 1.843 -> 1.745 mm).
    assert d["effect"] == "none" and d["proposed"]["joints"] == [2] and d["p_value"] < 1e-4, d["label"]
    acc = d["acceptance"]
    assert acc["folds_agree"] == 2 and "folds chose different causes" in acc["rejected"]
    held = acc["holdout_by_kind"]["measured"]
    assert held["extended"] < held["geometric"]
