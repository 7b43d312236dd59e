"""Issue 23, solver side: a sheet laid anywhere, its pose identified with the robot in the robot's own frame.

Oracles: the simulated true pose (``simulate --sheet-pose``, the truth in its own frame written beside the
session), the gauge (eq. S2) checked on the identified screws, and the invariance of every prediction under
the rigid motion :func:`own_frame` applies.
"""

from __future__ import annotations

import numpy as np
import pytest
import yaml

from lasercal.collector.cli.main import main
from lasercal.solver.formats.robots import load_model
from lasercal.solver.formats.session import load_session
from lasercal.solver.identify.measurement import fit
from lasercal.solver.identify.spot import predict_spots
from lasercal.solver.kinematics.aim import aim
from lasercal.solver.kinematics.frames import moved, own_frame
from lasercal.solver.kinematics.laser import beam
from lasercal.solver.kinematics.sheet import SheetPose

NOMINAL = load_model("panda")


@pytest.fixture(scope="module")
def displaced(tmp_path_factory):
    """Issue 23's case: the thesis layout's sheet 5 mm / -3 mm / 1.5 deg away from where it says."""
    out = tmp_path_factory.mktemp("sheet") / "s"
    args = ["simulate", "panda_thesis_identified", "--layout", "thesis", "--sheet-pose", "5", "-3", "1.5"]
    assert main(args + ["--aim-noise", "0.5", "--seed", "3", "-o", str(out)]) == 0
    return out


def test_own_frame_puts_joint_1_and_2_where_the_nominal_has_them_and_changes_no_prediction():
    truth = load_model("panda_thesis_identified")
    G = own_frame(truth, NOMINAL)
    own = moved(truth, G)
    assert np.allclose(own.screws[0], NOMINAL.screws[0], atol=1e-12)  # joint 1's axis: direction, position
    assert abs(own.screws[1, 0]) < 1e-12  # joint 2's axis at q = 0 has no x component (the Panda's)
    assert np.degrees(abs(np.arctan2(G[1, 0], G[0, 0]))) > 0.3  # the thesis Panda's base was turned 0.44 deg
    q = np.random.default_rng(0).uniform(-1, 1, (20, 7)) + NOMINAL.home
    a, b = (
        beam(truth.screws, truth.laser_dir, truth.aperture, q),
        beam(own.screws, own.laser_dir, own.aperture, q),
    )
    assert np.allclose(b.aperture, a.aperture @ G[:3, :3].T + G[:3, 3], atol=1e-9)  # the same beams, moved
    assert np.allclose(b.direction, a.direction @ G[:3, :3].T, atol=1e-12)


def test_simulate_writes_a_sheet_session_and_solve_finds_the_sheet(displaced, tmp_path, capsys):
    meta = yaml.safe_load((displaced / "session.yaml").read_text())
    assert meta["frame"] == "sheet" and meta["sheet"] == {"x_mm": 0.0, "y_mm": 0.0, "yaw_deg": 0.0}
    assert meta["points"]["P1"] == [521.0, 200.0, 0.0]  # sheet coordinates: the layout's x, y
    assert meta["simulated"]["sheet"]["pose"] == {"x_mm": 5.0, "y_mm": -3.0, "yaw_deg": 1.5}
    capsys.readouterr()
    out = tmp_path / "m.yaml"
    assert main(["solve", str(displaced), "-o", str(out), "--folds", "0"]) == 0
    assert "the sheet lies at x" in capsys.readouterr().out
    model = load_model(out)
    # within 3 of its reported sigmas (0.3 mm and 0.05 deg with 45 captures at 0.5 mm: the issue's 0.5 mm and
    # 0.1 deg are 1.6-2 sigma, benchmarks/bench_sheet_pose.py; z-scores over 12 seeds: RMS 0.82-1.03)
    sd = model.sheet_std
    assert set(sd) == {"x_mm", "y_mm", "yaw_deg", "scale_x", "scale_y", "tilt_x_rad", "tilt_y_rad"}
    # this layout's points lie ~500 mm from the sheet's origin, where the print's scale moves them as a shift
    # would: x's sigma grows from 0.3 mm (pose alone) to ~1 mm; a printed sheet's origin is its centre cross
    assert 0 < sd["x_mm"] < 1.5 and 0 < sd["yaw_deg"] < 0.1
    err = (model.sheet.x_mm - 5, model.sheet.y_mm + 3, model.sheet.yaw_deg - 1.5)
    assert all(abs(e) < 3 * sd[k] for e, k in zip(err, ("x_mm", "y_mm", "yaw_deg")))
    # the robot's own frame: joint 1 exactly the nominal's, joint 2 in the nominal's direction
    assert np.allclose(model.screws[0], NOMINAL.screws[0], atol=1e-12) and abs(model.screws[1, 0]) < 1e-12
    # against the truth in its own frame (written beside the session): spots off the table
    truth = load_model(displaced / meta["simulated"]["sheet"]["truth_in_own_frame"])
    rng = np.random.default_rng(1)
    for z in (-8.0, 100.0, 250.0):
        points = ((380, -200), (600, 0), (450, 250))
        q = np.concatenate([aim(truth, np.r_[x, y, z], 4, rng) for x, y in points])
        e = np.linalg.norm((predict_spots(model, q, z)[0] - predict_spots(truth, q, z)[0])[:, :2], axis=1)
        e0 = np.linalg.norm((predict_spots(NOMINAL, q, z)[0] - predict_spots(truth, q, z)[0])[:, :2], axis=1)
        assert np.sqrt(np.mean(e**2)) < 1.5 < 5 < np.sqrt(np.mean(e0**2))  # the noise floor ~0.5 mm


def test_without_a_placement_the_pose_starts_from_the_data(displaced, tmp_path):
    """No ``sheet:`` placement: no prior on the pose, the fit starts from the nominal spots (closed form)."""
    meta = yaml.safe_load((displaced / "session.yaml").read_text())
    meta.pop("sheet")
    folder = tmp_path / "s"
    folder.mkdir()
    (folder / "session.yaml").write_text(yaml.safe_dump(meta))
    (folder / "captures.csv").write_text((displaced / "captures.csv").read_text())
    session = load_session(folder)
    assert session.frame == "sheet" and session.sheet is None
    model = fit(session).model
    pose, sd = model.sheet, model.sheet_std
    # within 4 of its sigmas
    for k, true in zip(("x_mm", "y_mm", "yaw_deg"), (5.0, -3.0, 1.5)):
        assert abs(getattr(pose, k) - true) < 4 * sd[k], (k, getattr(pose, k), sd[k])
    assert sd["x_mm"] < 1.5 and sd["y_mm"] < 1.5 and sd["yaw_deg"] < 0.1  # as above: a far origin


def test_the_layout_read_as_base_frame_points_is_the_issue_s_silent_error(displaced):
    """Before: the same captures with the layout's points taken as base-frame points fit as well (the
    error is invisible in the residuals) but the model is the robot moved by the sheet's error."""
    session = load_session(displaced)
    right = fit(session)
    wrong = fit(session.__class__(**{**session.__dict__, "frame": "base", "sheet": None}))
    assert abs(wrong.rms_mm - right.rms_mm) < 0.05  # as good a fit...
    offset = np.linalg.norm(np.cross(wrong.model.screws[0, :3], wrong.model.screws[0, 3:])[:2])
    assert offset > 3  # ...of a robot whose joint 1 stands mm away from where it is


def test_sheet_sessions_refuse_the_thesis_method_and_validation_needs_a_sheet_pose(
    displaced, tmp_path, capsys
):
    assert main(["solve", str(displaced), "-o", str(tmp_path / "t.yaml"), "--method", "thesis"]) == 2
    assert "the thesis method needs the reference points in the base frame" in capsys.readouterr().err
    layout = tmp_path / "sheet.yaml"
    meta = yaml.safe_load((displaced / "session.yaml").read_text())
    layout.write_text(yaml.safe_dump({k: meta[k] for k in ("plane", "points", "frame", "sheet", "validation")}
                                     | {"format": "lasercal-layout/1"}))  # fmt: skip
    args = [
        "validate",
        "panda",
        "--layout",
        str(layout),
        "--backend",
        "fake",
        "-n",
        "3",
        "-o",
        str(tmp_path / "v"),
    ]
    assert main(args) == 2
    assert "the model has no sheet pose" in capsys.readouterr().err


def test_a_sheet_pose_round_trips_through_the_model_file(tmp_path):
    m = NOMINAL.replace(
        sheet=SheetPose(1.5, -2.25, 3.0), sheet_std={"x_mm": 0.1, "y_mm": 0.2, "yaw_deg": 0.01}
    )
    m.save(tmp_path / "m.yaml")
    back = load_model(tmp_path / "m.yaml")
    assert back.sheet == m.sheet and back.sheet_std == m.sheet_std
    (tmp_path / "b.yaml").write_text(
        (tmp_path / "m.yaml").read_text().replace("yaw_deg: 3.0", "yaw_deg: .nan")
    )
    with pytest.raises(Exception, match=r"sheet\.yaw_deg"):
        load_model(tmp_path / "b.yaml")


def test_print_capture_solve_validate_on_the_simulated_robot(tmp_path, capsys):
    """The whole path a lab takes, on the fake backend: a printed sheet laid at its placement, a coached
    capture (the on-screen check in the base frame through the placement), solve, validate at P6."""
    sheet, session, model, val = (tmp_path / k for k in ("sheet", "session", "model.yaml", "val"))
    assert main(["sheet", "-o", str(sheet), "--robot", "panda", "--place", "450", "0", "0"]) == 0
    layout = str(sheet / "layout.yaml")
    cap = ["capture", "--layout", layout, "--robot", "panda", "--backend", "fake", "--auto"]
    assert main(cap + ["--per-point", "4", "-o", str(session)]) == 0
    assert "discarded" not in capsys.readouterr().out  # every capture within reach of its cross
    assert main(["solve", str(session), "-o", str(model), "--folds", "0"]) == 0
    said = capsys.readouterr().out
    # The pose is in the robot's own base frame (joint 1 the nominal's, joint 2 pointing as the nominal's);
    # the fake truth (the thesis's Panda) is turned 0.44 deg from the nominal's base, so the sheet laid at
    # (450, 0, 0) in the truth's file frame lies at y -4 mm in its own: the truth, moved here (eq. S2).
    found = load_model(model)
    G = own_frame(load_model("panda_thesis_identified"), NOMINAL)
    origin = G[:3, :3] @ [450.0, 0.0, found.plane_z] + G[:3, 3]
    yaw = np.degrees(np.arctan2(G[1, 0], G[0, 0]))
    assert -4.3 < origin[1] < -3.7 and abs(yaw + 0.44) < 0.01  # the truth's own frame: y -4 mm, -0.44 deg
    # the table, level in the truth's file frame, rises in its own along -n_xy / n_z (eq. S3), a level print
    rise = -G[:2, 2] / G[2, 2]
    c, s = np.cos(np.radians(yaw)), np.sin(np.radians(yaw))
    true = {"x_mm": origin[0], "y_mm": origin[1], "yaw_deg": yaw, "scale_x": 1.0, "scale_y": 1.0}
    true |= {"tilt_x_rad": rise @ [c, s], "tilt_y_rad": rise @ [-s, c]}
    for k, v in found.sheet.as_dict().items():
        assert abs(v - true[k]) < 4 * found.sheet_std[k], (k, v, true[k])  # 4 sigma: 1 in 16,000 per axis
    line = next(s for s in said.splitlines() if s.startswith("simulated: the sheet truly lies at"))
    assert f"y {origin[1]:.2f} mm, yaw {yaw:.3f} deg in that frame" in line
    assert "it was laid at x 450.00, y 0.00 mm" in line
    assert "the sheet lies at x" in said and "robot's own base frame: joint 1's axis is the nominal's" in said
    capsys.readouterr()
    assert main(["validate", str(model), "--layout", layout, "--point", "P6", "-n", "4", "--backend", "fake",
                 "-o", str(val)]) == 0  # fmt: skip
    last = capsys.readouterr().out.strip().splitlines()[-1]
    assert last.startswith("P6: 4 spots measured") and float(last.split("error mean ")[1].split()[0]) < 2.0
