"""The Python API is the command line: ``lasercal.calibrate(lasercal.load_session(S), ...).save(P)`` writes
the file ``lasercal solve S -o P ...`` writes, byte for byte, and ``.summary()`` / ``.report(dir)`` are what
``solve`` prints and ``report`` writes -- on a laser session with a hidden effect and on a position session.
"""

from __future__ import annotations

import csv
import json
import re
import shutil

import numpy as np
import pytest
import yaml

import lasercal
from lasercal.collector.cli.main import main
from lasercal.solver.formats.data import builtin_dir

LAYOUT = str(builtin_dir("layouts") / "thesis.yaml")


@pytest.fixture(scope="module")
def sessions(tmp_path_factory):
    """A laser session whose robot bends at joint 2 (a compliance for ``--extend``), the same without its
    logged torques ('bare': the gravity model's, with a payload) and a position session."""
    root = tmp_path_factory.mktemp("api")
    laser = ["simulate", "panda_thesis_identified", "--layout", LAYOUT, "--per-point", "12", "--seed", "4"]
    laser += ["--effect", "joint_compliance", "--effect-size", "1.2e-4", "-o", str(root / "laser")]
    position = ["simulate", "panda_thesis_identified", "--measurement", "position", "--configs", "25"]
    assert main(laser) == 0 and main(position + ["-o", str(root / "position")]) == 0
    shutil.copytree(root / "laser", root / "bare")  # the same captures without their torques (as MUKCa's)
    rows = list(csv.reader((root / "laser" / "captures.csv").open()))
    keep = [i for i, c in enumerate(rows[0]) if not c.startswith("tau")]
    with (root / "bare" / "captures.csv").open("w", newline="") as f:
        csv.writer(f).writerows([r[i] for i in keep] for r in rows)
    return root


def untimed(rep):
    """A statistics mapping without its wall times (the one thing two runs of a fit do not share)."""
    if isinstance(rep, dict):
        return {k: untimed(v) for k, v in rep.items() if k != "seconds"}
    return [untimed(v) for v in rep] if isinstance(rep, list) else rep


CASES = [
    ("laser", [], {}),
    ("laser", ["--extend", "auto", "--folds", "3"], {"extend": "auto", "folds": 3}),
    ("laser", ["--method", "thesis", "--folds", "0"], {"method": "thesis", "folds": 0}),
    ("laser", ["--extend", "joint_compliance", "--folds", "0"], {"extend": "joint_compliance", "folds": 0}),
    (
        "laser",
        ["--prior", "none", "--no-robust", "--folds", "0"],
        {"prior": "none", "robust": False, "folds": 0},
    ),
    (
        "bare",
        ["--extend", "auto", "--folds", "0", "--payload", "2,0,0,900"],
        {"extend": "auto", "folds": 0, "payload": (2.0, np.array([0.0, 0.0, 900.0]))},
    ),
    ("position", ["--folds", "0"], {"folds": 0}),
    ("position", ["--extend", "auto", "--folds", "0"], {"extend": "auto", "folds": 0}),
]


@pytest.mark.parametrize("kind, flags, kw", CASES)
def test_calibrate_writes_the_model_file_solve_writes(sessions, tmp_path, capsys, kind, flags, kw):
    S = sessions / kind
    capsys.readouterr()
    assert main(["solve", str(S), "-o", str(tmp_path / "cli.yaml"), *flags]) == 0
    printed = capsys.readouterr().out
    cal = lasercal.calibrate(lasercal.load_session(S), **kw)
    cal.save(tmp_path / "api.yaml")
    cli, api = (tmp_path / "cli.yaml").read_bytes(), (tmp_path / "api.yaml").read_bytes()
    assert cli == api
    model = yaml.safe_load(api)
    assert model["identification"]["session"] == str(S.resolve()) and model["nominal"] == "panda"
    assert ("diagnosis" in model["identification"]) == ("extend" in kw)
    # the printed text: the summary and the file it wrote (the fit's wall time aside: each run takes its own)
    untimed_text = lambda text: re.sub(r"iterations, [0-9.]+ s", "iterations, T s", text)  # noqa: E731
    assert untimed_text(printed) == untimed_text(cal.summary() + f"\nwrote {tmp_path / 'cli.yaml'}\n")
    capsys.readouterr()
    assert main(["solve", str(S), "-o", str(tmp_path / "j.yaml"), "--json", *flags]) == 0
    assert untimed(json.loads(capsys.readouterr().out)) == untimed(json.loads(cal.to_json()))


def test_calibrate_takes_the_prior_and_the_robot_the_command_takes(sessions, tmp_path):
    """``--prior none`` and ``--robot`` given to load_session or to calibrate write the same file; the robot
    override is the nominal the model names."""
    S = sessions / "laser"
    cli = ["solve", str(S), "-o", str(tmp_path / "cli.yaml"), "--robot", "panda", "--prior", "none"]
    assert main(cli) == 0
    a = lasercal.calibrate(lasercal.load_session(S, robot="panda", prior="none"))
    b = lasercal.calibrate(lasercal.load_session(S, robot="panda"), prior="none")
    a.save(tmp_path / "a.yaml")
    b.save(tmp_path / "b.yaml")
    assert (tmp_path / "cli.yaml").read_bytes() == (tmp_path / "a.yaml").read_bytes()
    assert (tmp_path / "a.yaml").read_bytes() == (tmp_path / "b.yaml").read_bytes()
    assert a.statistics["prior"] == "none (plain least squares)"


def test_calibrate_fits_the_hidden_compliance(sessions):
    """The simulated truth is known: the compliance fitted at joint 2 (``extend="joint_compliance"``) lies
    within four of its standard errors of the hidden 1.2e-4 rad/Nm, and the model file carries it."""
    cal = lasercal.calibrate(lasercal.load_session(sessions / "laser"), extend="joint_compliance", folds=0)
    ext = cal.identification.extension
    assert ext.effect == "joint_compliance" and 2 in ext.joints
    k = list(ext.joints).index(2)
    assert abs(ext.params[k] - 1.2e-4) < 4 * ext.std_errors[k]
    assert "joint_compliance" in cal.model.extensions and not cal.partial


def test_calibrate_refuses_what_solve_refuses(sessions):
    from lasercal.solver.errors import IdentificationError

    s = lasercal.load_session(sessions / "laser")
    with pytest.raises(IdentificationError, match="more folds than"):
        lasercal.calibrate(s, folds=s.m + 1)
    with pytest.raises(IdentificationError, match="needs --method lm"):
        lasercal.calibrate(s, method="thesis", extend="auto")
    with pytest.raises(IdentificationError, match="method 'ls'"):
        lasercal.calibrate(s, method="ls")


def test_calibrate_takes_the_folds_seed_the_diagnosis_threshold_and_the_payload(sessions):
    """What the demo and the MUKCa study ask of it: the folds of ``seed``; ``alpha`` decides (a level below
    the best candidate's corrected p keeps nothing, one above keeps it); ``payload`` loads the flange of a
    session without logged torques (the diagnosed session's torques are the gravity model's with it)."""
    from dataclasses import replace

    from lasercal.solver.analysis.stats import grouped_folds
    from lasercal.solver.kinematics.gravity import gravity_torques

    s = lasercal.load_session(sessions / "laser")
    by_seed = {k: lasercal.calibrate(s, folds=3, seed=k).cross_validation.fold for k in (0, 1)}
    for k, fold in by_seed.items():
        np.testing.assert_array_equal(fold, grouped_folds(s, 3, k))
    assert (by_seed[0] != by_seed[1]).any()
    p = lasercal.calibrate(s, extend="auto", folds=0).diagnosis.p_value  # the best candidate's, corrected
    assert 0 < p < 0.5  # a compliance is hidden in the robot
    for alpha, kept in ((p / 2, False), (min(1.0, 2 * p), True)):  # without folds the F test decides alone
        cal = lasercal.calibrate(s, extend="auto", folds=0, alpha=alpha)
        assert (cal.diagnosis.effect != "none") == kept == (cal.identification.extension is not None)
    payload = (2.0, np.array([0.0, 0.0, 900.0]))  # kg, mm at q = 0
    bare = replace(s, tau=None)
    loaded = lasercal.calibrate(bare, extend="auto", folds=0, payload=payload)
    np.testing.assert_allclose(loaded.session.tau, gravity_torques(s.robot, s.q, payload))
    unloaded = lasercal.calibrate(bare, extend="auto", folds=0).session.tau
    assert np.abs(loaded.session.tau - unloaded).max() > 1.0  # Nm: 2 kg a few hundred mm out


def test_report_is_the_report_command(sessions, tmp_path, capsys):
    S = sessions / "laser"
    opts = ["--bootstrap", "40", "--refits", "1", "--seed", "3"]
    assert main(["report", str(S), "-o", str(tmp_path / "cli"), *opts]) == 0
    cal = lasercal.calibrate(lasercal.load_session(S), folds=0)
    index = cal.report(tmp_path / "api", n_boot=40, n_refit=1, seed=3)
    assert index == tmp_path / "api" / "index.html"
    html = {k: (tmp_path / k / "index.html").read_text() for k in ("cli", "api")}
    assert html["cli"] == html["api"]
    assert sorted(p.name for p in (tmp_path / "cli").iterdir()) == sorted(
        p.name for p in (tmp_path / "api").iterdir()
    )


def test_position_session_model_predicts_its_truth(sessions):
    """Noise 0.02 mm: the calibrated model's position predictions sit within a few noise sigmas."""
    cal = lasercal.calibrate(lasercal.load_session(sessions / "position"), folds=0)
    after = [t["after_rms_mm"] for t in cal.statistics["targets"].values()]
    assert np.max(after) < 5 * 0.02 * np.sqrt(3)


def test_every_public_name_loads_with_a_scipy_style_docstring():
    """``lasercal.__all__`` is what ``dir`` shows; each name loads, and each workflow function documents
    its parameters and what it returns."""
    import inspect

    assert set(lasercal.__all__) <= set(dir(lasercal))
    for name in lasercal.__all__:
        obj = getattr(lasercal, name)
        assert inspect.getdoc(obj), name
    for name in ("calibrate", "simulate", "plan", "spots", "load_session"):
        doc = inspect.getdoc(getattr(lasercal, name))
        assert "Parameters\n----------" in doc and "Returns\n-------" in doc, name


def test_spots_of_an_array_a_file_and_a_lost_photo(tmp_path):
    """A rendered spot at a known sub-pixel centre is found there, from an array and from its file, as
    ``lasercal spots`` finds it; a file that is no photo is an entry saying why, not an exception."""
    import cv2

    from lasercal.vision.render import LaserSpot, Photo, look_down, render

    u, v = 160.3, 118.6
    img = render(Photo(look_down((320, 240), 0.3, centre=(450.0, 0.0)), spots=(LaserSpot(u, v, sigma=2.0,
                 peak=0.4),), paper=0.5), 0)  # fmt: skip
    cv2.imwrite(str(tmp_path / "p.png"), img)
    (tmp_path / "bad.jpg").write_text("not a photo")
    found, file, lost = lasercal.spots([img, tmp_path / "p.png", tmp_path / "bad.jpg"])
    for r in (found, file):
        assert r.error is None and len(r.spots) == 1
        assert np.hypot(r.spots[0].u - u, r.spots[0].v - v) < 0.1  # the detector's 0.05 px, with margin
    assert lost.error and not lost.spots


def test_calibrate_fullpose_writes_the_model_file_fullpose_writes(tmp_path, capsys):
    """Noise-free circle points of a known truth: the API's file is the command's, byte for byte, and the
    calibrated poses match the measured ones to round-off (the paper's method recovers the truth)."""
    m = tmp_path / "m.csv"
    sim = ["simulate-fullpose", "--robot", "panda_thesis_identified", "--configs", "12", "--noise", "0"]
    assert main([*sim, "--seed", "2", "-o", str(m)]) == 0
    for flags, kw in (([], {}), (["--method", "circle", "--folds", "3"], {"method": "circle", "folds": 3})):
        capsys.readouterr()
        assert (
            main(
                ["fullpose", str(m), "--robot", "panda", "-o", str(tmp_path / "cli.yaml"), "--force", *flags]
            )
            == 0
        )
        printed = capsys.readouterr().out
        res = lasercal.calibrate_fullpose("panda", m, **kw)
        res.save(tmp_path / "api.yaml")
        assert (tmp_path / "cli.yaml").read_bytes() == (tmp_path / "api.yaml").read_bytes()
        untimed_text = lambda text: re.sub(r"iterations, [0-9.]+ s", "iterations, T s", text)  # noqa: E731
        assert untimed_text(printed) == untimed_text(res.summary() + f"\nwrote {tmp_path / 'cli.yaml'}\n")
        after = res.statistics["accuracy"]["after"]
        assert after["position_mm"]["max"] < 1e-3, after
