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
TRUE_POSE = {"x_mm": 5.0, "y_mm": -3.0, "yaw_deg": 1.5}
# The spread of the identified pose about the truth, RMS over noise draws (seeds 10-49, not the tests' 3:
# ``python tests/test_sheet_pose.py`` measures it): issue 23's sheet, 45 captures at 0.5 mm. x's reported
# sigma is 1.45x its spread: the print's scale, unknown to the fit, moves points ~500 mm from the sheet's
# origin as a shift of x would, but the simulated print is exact, at the prior's mean
SPREAD = {"x_mm": 0.63, "y_mm": 0.31, "yaw_deg": 0.041}


def simulate_displaced(out, seed: int) -> None:
    args = ["simulate", "panda_thesis_identified", "--layout", "thesis", "--sheet-pose", "5", "-3", "1.5"]
    assert main(args + ["--aim-noise", "0.5", "--seed", str(seed), "-o", str(out)]) == 0


def without_placement(folder, into):
    """The session in ``folder`` without its ``sheet:`` placement, written to ``into``."""
    meta = yaml.safe_load((folder / "session.yaml").read_text())
    meta.pop("sheet")
    into.mkdir()
    (into / "session.yaml").write_text(yaml.safe_dump(meta))
    (into / "captures.csv").write_text((folder / "captures.csv").read_text())
    return into


def pose_error(model) -> dict:
    return {k: getattr(model.sheet, k) - v for k, v in TRUE_POSE.items()}


@pytest.fixture(scope="module")
def displaced(tmp_path_factory):
    """Issue 23's case: the thesis layout's sheet 5 mm / -3 mm / 1.5 deg away from where it says."""
    out = tmp_path_factory.mktemp("sheet") / "s"
    simulate_displaced(out, 3)
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
    sd = model.sheet_std
    assert set(sd) == {"x_mm", "y_mm", "yaw_deg", "scale_x", "scale_y", "tilt_x_rad", "tilt_y_rad"}
    # found within 3 times the spread of the pose over noise draws (SPREAD: 1 in 370 per axis)
    err = pose_error(model)
    assert all(abs(err[k]) < 3 * SPREAD[k] for k in SPREAD), err
    # and the sigma it reports is that spread (y, yaw; over the seeds 0.77-1.32x) or, for x, the spread with
    # the print's scale unknown (1.2-1.6x; SPREAD's note): a sigma 1.5x too large fails
    ratio = {k: sd[k] / SPREAD[k] for k in SPREAD}
    assert 0.7 < ratio["y_mm"] < 1.4 and 0.7 < ratio["yaw_deg"] < 1.4 and 1.1 < ratio["x_mm"] < 2.0, ratio
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
    """No ``sheet:`` placement: no prior on the pose, the fit starts from the nominal spots (closed form),
    and ends where the fit with the placement ends: the placement's prior moves the pose by micrometres
    (over seeds 10-49 at most 3 um and 0.001 deg), far below its spread; both within 3 spreads of the
    truth."""
    session = load_session(without_placement(displaced, tmp_path / "s"))
    assert session.frame == "sheet" and session.sheet is None
    placed, free = fit(load_session(displaced)).model, fit(session).model
    err, err_placed = pose_error(free), pose_error(placed)
    assert all(abs(err[k] - err_placed[k]) < 0.05 * SPREAD[k] for k in SPREAD), (err, err_placed)
    assert all(abs(err[k]) < 3 * SPREAD[k] for k in SPREAD), err


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


if __name__ == "__main__":  # SPREAD: the pose's RMS error over seeds 10-49 (python tests/test_sheet_pose.py)
    import tempfile
    from contextlib import redirect_stdout
    from io import StringIO
    from pathlib import Path

    errors = []
    for seed in range(10, 50):
        folder = Path(tempfile.mkdtemp()) / "s"
        with redirect_stdout(StringIO()):
            simulate_displaced(folder, seed)
        model = fit(load_session(folder)).model
        errors.append([pose_error(model)[k] for k in SPREAD])
        print(
            seed,
            " ".join(f"{k} {e:+.4f} (sigma {model.sheet_std[k]:.4f})" for k, e in zip(SPREAD, errors[-1])),
        )
    rms = np.sqrt(np.mean(np.square(errors), axis=0))
    print("RMS error over the seeds:", ", ".join(f"{k} {v:.3f}" for k, v in zip(SPREAD, rms)))
