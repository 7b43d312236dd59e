"""lasercal report: the page's numbers are the library's, and a real browser renders it with its images."""

from __future__ import annotations

import csv
import dataclasses
import html
import re
import shutil
import subprocess
from html.parser import HTMLParser

import cv2
import numpy as np
import pytest
import yaml
from scipy.spatial.transform import Rotation

from lasercal.collector.cli.main import main
from lasercal.collector.demo import TRUTH, DemoOptions, capture_session, thesis_layout, validate_model
from lasercal.collector.report.html import load_validation, parameter_table, write_report
from lasercal.collector.report.text import format_diagnosis
from lasercal.solver.analysis.diagnose import diagnose
from lasercal.solver.analysis.stats import solve_report
from lasercal.solver.formats.robots import load_model
from lasercal.solver.formats.session import load_session
from lasercal.solver.identify.spot import identify
from lasercal.solver.kinematics.laser import LaserParams

OPTS = DemoOptions(per_point=15, n_validation=8, n_boot=200, n_refit=2, seed=4)
CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")


class Tables(HTMLParser):
    """Cell texts of every <table id=...>, row by row; and the <pre id=...> texts."""

    def __init__(self, text: str):
        super().__init__()
        self.tables, self.pre, self._table, self._row, self._cell, self._pre = {}, {}, None, None, None, None
        self.feed(text)

    def handle_starttag(self, tag, attrs):
        a = dict(attrs)
        if tag == "table":
            self._table = self.tables.setdefault(a["id"], [])
        elif tag == "tr" and self._table is not None:
            self._row = []
            self._table.append(self._row)
        elif tag in ("td", "th") and self._row is not None:
            self._cell = ""
        elif tag == "pre":
            self._pre = a["id"]
            self.pre[self._pre] = ""

    def handle_endtag(self, tag):
        if tag in ("td", "th") and self._cell is not None:
            self._row.append(self._cell)
            self._cell = None
        elif tag == "table":
            self._table = None
        elif tag == "pre":
            self._pre = None

    def handle_data(self, data):
        if self._cell is not None:
            self._cell += data
        if self._pre is not None:
            self.pre[self._pre] += data


@pytest.fixture(scope="module")
def experiment(tmp_path_factory):
    """A capture session, its calibration and diagnosis, and validations of the nominal and calibrated models
    at P4."""
    root = tmp_path_factory.mktemp("report")
    truth, layout = load_model(TRUTH), thesis_layout()
    session = load_session(capture_session(root / "session", truth, layout, OPTS))
    ident = identify(session, "lm")
    ident.model.save(root / "model.yaml")
    d = diagnose(session, n_boot=OPTS.n_boot, n_refit=OPTS.n_refit)
    validate_model(root / "nominal", session.robot, "panda", truth, layout, OPTS)
    validate_model(root / "calibrated", ident.model, str(root / "model.yaml"), truth, layout, OPTS)
    validations = [load_validation(root / "nominal"), load_validation(root / "calibrated")]
    reference = {"published": {"scatter_mean": 1.0, "scatter_std": 2.0, "error_mean": 3.0, "error_max": 4.0}}
    index = write_report(root / "out", session, ident, d, validations, reference)
    return root, session, ident, d, validations, index


def test_validation_table_is_the_photos(experiment):
    root, *_, index = experiment
    rows = Tables(index.read_text()).tables["validation-stats"]
    assert rows[0] == [
        "run",
        "model",
        "spots measured",
        "scatter mean",
        "scatter std",
        "error mean",
        "error max",
    ]
    assert [r[0] for r in rows[1:]] == ["nominal", "calibrated", "published"]
    for row, name in zip(rows[1:], ("nominal", "calibrated")):
        with open(root / name / "validation.csv") as f:  # straight from the file, not through load_validation
            data = [r for r in csv.DictReader(line for line in f if not line.startswith("#"))]
        xy = np.array([[float(r["x_mm"]), float(r["y_mm"])] for r in data])
        err = np.hypot(xy[:, 0] - 441, xy[:, 1] - 160)
        radius = np.linalg.norm(xy - xy.mean(axis=0), axis=1)
        assert row[2] == f"{len(xy)} of {OPTS.n_validation}"
        assert row[3:] == [f"{v:.3f}" for v in (radius.mean(), radius.std(ddof=1), err.mean(), err.max())]
    assert rows[3][3:] == ["1.000", "2.000", "3.000", "4.000"]
    assert float(rows[1][5]) > 5 and float(rows[2][5]) < 2  # before: mm off; after: about the aiming noise


def test_parameter_table_is_the_model_with_propagated_standard_errors(experiment):
    _, _, ident, *_, index = experiment
    rows = Tables(index.read_text()).tables["parameters"][1:]
    n = ident.model.n
    assert len(rows) == 2 * n + 2
    values = np.array([[float(x) for x in r[2].split(", ")] for r in rows])
    assert np.allclose(values[: 2 * n].reshape(n, 6), ident.model.screws, rtol=1e-5, atol=1e-8)
    assert np.allclose(values[-2], ident.model.laser_dir, rtol=1e-5) and np.allclose(
        values[-1], ident.model.aperture, rtol=1e-5
    )
    # Standard errors: the fit's covariance through a finite-difference Jacobian of the parametrisation.
    P = LaserParams(ident.nominal)
    x = ident.estimate[: P.size]

    def flat(v):
        m = P.to_model(v)
        return np.r_[m.screws.ravel(), m.laser_dir, m.aperture]

    D = np.empty((6 * n + 6, P.size))
    for k in range(P.size):
        h = np.zeros(P.size)
        h[k] = 1e-7
        D[:, k] = (flat(x + h) - flat(x - h)) / 2e-7
    se = np.sqrt(np.diag(D @ ident.extra["cov"][: P.size, : P.size] @ D.T))
    got = np.concatenate([r.std_error for r in parameter_table(ident)])
    assert np.allclose(got, se, rtol=1e-4, atol=1e-9)
    assert np.allclose(
        [[float(x) for x in r[3].split(", ")] for r in rows], got.reshape(-1, 3), rtol=0.06, atol=1e-12
    )  # printed to 2 digits
    assert got[-1] == 0.0  # the aperture height is the measured p_Mz: fixed, not estimated


def test_points_identifiability_and_diagnosis_are_the_librarys(experiment):
    _, session, ident, d, _, index = experiment
    t = Tables(index.read_text())
    rep = solve_report(session, ident)
    expect = [
        [nm, when, str(s[when]["n"])]
        + [f"{s[when][k]:.3f}" for k in ("scatter_mean", "scatter_std", "error_mean", "error_max")]
        for nm, s in rep["points"].items()
        for when in ("before", "after")
    ]
    assert t.tables["points"][1:] == expect
    idf = {r[0]: r[1] for r in t.tables["identifiability"][1:]}
    assert idf["rank"] == str(ident.identifiability.rank) and idf["parameters"] == str(
        ident.identifiability.n_params
    )
    # the count is the one solve, plan and the coach print: the robot's parameters (and a sheet's), named
    assert idf["what the parameters are"].startswith(f"{ident.identifiability.n_params} = 7 joints x 4")
    assert idf["possible from spots"] == str(ident.identifiability.n_params - 1)
    det = rep["determined_by"]
    counts = idf["determined by the data / data and prior / the prior"]
    assert counts == f"{det['data']} / {det['data_and_prior']} / {det['prior']}"
    assert [k.removeprefix("from the prior: ") for k in idf if k.startswith("from the prior")] == [
        d["combination"] for d in det["from_prior"]
    ]
    assert t.pre["diagnosis"] == format_diagnosis(d)


def test_report_folder_is_self_contained(experiment):
    *_, index = experiment
    text = index.read_text()
    srcs = re.findall(r'<img src="([^"]+)"', text)
    assert len(srcs) == 6 and all("/" not in s and (index.parent / s).is_file() for s in srcs)
    assert "http" not in text and "<script" not in text


@pytest.mark.skipif(
    CHROMIUM is None, reason="needs Chromium to render the report headless (Debian: apt-get install chromium)"
)
def test_report_renders_with_its_images_in_chromium(experiment, tmp_path):
    *_, index = experiment
    # The page under test plus a probe that records, once loaded, every image's decoded size.
    probe = (
        '<script>window.addEventListener("load", function () { var s = [];'
        " for (var i = 0; i < document.images.length; i++) { var im = document.images[i];"
        ' s.push(im.complete ? im.naturalWidth + "x" + im.naturalHeight : "0x0"); }'
        ' document.body.setAttribute("data-images", s.join(" ")); });</script>'
    )
    page = index.with_name("probe.html")
    page.write_text(index.read_text().replace("</body>", probe + "</body>"))
    flags = [
        "--headless",
        "--no-sandbox",
        "--disable-gpu",
        "--disable-quic",
        "--no-first-run",
        "--disable-background-networking",
        "--disable-component-update",
        "--disable-sync",
        f"--user-data-dir={tmp_path / 'profile'}",
    ]
    try:
        dom = subprocess.run(
            [CHROMIUM, *flags, "--virtual-time-budget=5000", "--dump-dom", page.as_uri()],
            capture_output=True,
            text=True,
            timeout=120,
            check=False,
        ).stdout
        shot = tmp_path / "shot.png"
        subprocess.run(
            [
                CHROMIUM,
                *flags,
                f"--screenshot={shot}",
                "--window-size=1200,2400",
                "--hide-scrollbars",
                index.as_uri(),
            ],
            capture_output=True,
            timeout=120,
            check=False,
        )
    finally:
        page.unlink()
    sizes = re.search(r'data-images="([^"]*)"', dom).group(1).split()
    files = [
        cv2.imread(str(index.parent / s)).shape for s in re.findall(r'<img src="([^"]+)"', index.read_text())
    ]
    assert sizes == [f"{w}x{h}" for h, w, _ in files]  # every image decoded, at its file's size
    assert "Validation at P4" in dom and "Diagnosis" in dom
    assert "Simulated data" in dom and "calibrated: " in dom and "Corrections per joint" in dom
    img = cv2.imread(str(shot))
    assert img.shape[:2] == (2400, 1200) and img.std() > 20  # a page was painted, not a blank window


def test_report_cli(experiment, tmp_path, capsys):
    root = experiment[0]
    out = tmp_path / "rep"
    args = [
        str(root / "nominal"),
        str(root / "session"),
        str(root / "calibrated"),
        "-o",
        str(out),
        "--bootstrap",
        "50",
        "--refits",
        "1",
    ]
    assert main(["report", *args]) == 0
    assert capsys.readouterr().out.strip() == f"wrote {out / 'index.html'}"
    t = Tables((out / "index.html").read_text())
    assert [r[0] for r in t.tables["validation-stats"][1:]] == ["nominal", "calibrated"]  # in the order given
    first = Tables(experiment[-1].read_text())
    assert t.tables["parameters"] == first.tables["parameters"]  # the same calibration as the library's
    assert main(["report", str(root / "nominal"), "-o", str(out)]) == 2
    assert "exists and is kept (pass --force to replace it)" in capsys.readouterr().err
    assert main(["report", str(root / "nominal"), "-o", str(out), "--force"]) == 2
    assert (
        "exactly one capture session folder (with session.yaml) among its folders, got 0"
        in capsys.readouterr().err
    )


def test_report_input_errors_name_the_file_and_line(experiment, tmp_path, capsys):
    root = experiment[0]
    bad = tmp_path / "bad"
    shutil.copytree(root / "calibrated", bad, ignore=shutil.ignore_patterns("photos"))
    lines = (bad / "validation.csv").read_text().splitlines()
    header = lines[1].split(",")
    cells = lines[3].split(",")
    cells[header.index("y_mm")] = "abc"
    lines[3] = ",".join(cells)
    (bad / "validation.csv").write_text("\n".join(lines) + "\n")
    assert main(["report", str(root / "session"), str(bad), "-o", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [
        f"lasercal: error: {bad / 'validation.csv'}, line 4, column 'y_mm': not a finite number: 'abc'"
    ]
    assert main(["report", str(root / "session"), str(tmp_path), "-o", str(tmp_path / "o")]) == 2
    assert "neither a capture session" in capsys.readouterr().err
    # Photos not measured yet: empty x_mm, y_mm are skipped, and none at all is an error.
    for i in range(2, len(lines)):
        cells = lines[i].split(",")
        cells[header.index("x_mm")] = cells[header.index("y_mm")] = ""
        lines[i] = ",".join(cells)
    (bad / "validation.csv").write_text("\n".join(lines) + "\n")
    with pytest.raises(Exception, match="no measured spot"):
        load_validation(bad)


def _paragraph(text: str, pid: str) -> str:
    return html.unescape(re.sub(r"<[^>]+>", "", re.search(rf'<p id="{pid}">(.*?)</p>', text).group(1)))


def test_report_says_what_it_is(experiment):
    root, session, ident, _, validations, index = experiment
    text = index.read_text()
    sim = yaml.safe_load((root / "session" / "session.yaml").read_text())["simulated"]  # the demo's capture
    assert _paragraph(text, "data-kind").startswith(
        f"Simulated data: the session was simulated (truth {sim['truth']}"
    )
    assert all(
        yaml.safe_load((root / r / "validation.yaml").read_text())["simulated"]
        for r in ("nominal", "calibrated")
    )
    # the verdict from the validation CSVs directly: nominal's mean error -> calibrated's, configurations
    err = {}
    for name in ("nominal", "calibrated"):
        with open(root / name / "validation.csv") as f:
            data = [r for r in csv.DictReader(line for line in f if not line.startswith("#"))]
        err[name] = np.mean([np.hypot(float(r["x_mm"]) - 441, float(r["y_mm"]) - 160) for r in data])
    n = OPTS.n_validation
    assert err["nominal"] >= 1 > err["calibrated"]  # two decimals from 1 mm up, three below
    held = [d["combination"] for d in solve_report(session, ident)["determined_by"]["from_prior"]]
    assert _paragraph(text, "verdict") == (
        f"calibrated: {err['nominal']:.2f} → {err['calibrated']:.3f} mm at P4, {n} of {n} configurations"
        + (f"; from the prior, not calibrated by the data: {', '.join(held)}" if held else "")
    )
    # corrections per joint: angle between axis directions (deg) and distance of the identified axis from the
    # nominal axis's foot point (mm), recomputed here with scipy's rotation between the two directions
    rows = Tables(text).tables["corrections"]
    assert rows[0] == ["joint", "axis direction change (deg)", "axis position change (mm)"]
    for row, Sn, Si in zip(rows[1:], ident.nominal.screws, ident.model.screws):
        rot, _ = Rotation.align_vectors(Si[None, :3], Sn[None, :3])
        foot = np.cross(Sn[:3], Sn[3:])
        off = foot - np.cross(Si[:3], Si[3:])
        assert float(row[1]) == pytest.approx(np.degrees(rot.magnitude()), abs=1.5e-3)
        assert float(row[2]) == pytest.approx(np.linalg.norm(off - (off @ Si[:3]) * Si[:3]), abs=1.5e-3)
    assert len(rows) == 1 + ident.model.n + 1 and rows[-1][0].startswith("laser")
    assert max(float(r[2]) for r in rows[1:-1]) > 0.1  # the truth differs from the nominal by mm


def test_report_partial_validation_and_partial_fit(experiment, tmp_path):
    root, session, ident, _, validations, _ = experiment
    short = tmp_path / "short"
    shutil.copytree(root / "calibrated", short)
    lines = (short / "validation.csv").read_text().splitlines(keepends=True)
    head = next(i for i, ln in enumerate(lines) if not ln.startswith("#")) + 1
    (short / "validation.csv").write_text("".join(lines[: head + 3]))  # 3 of the 8 photos: a stopped run
    part = load_validation(short)
    text = write_report(tmp_path / "o", session, ident, None, [validations[0], part]).read_text()
    n = OPTS.n_validation
    assert Tables(text).tables["validation-stats"][2][2] == f"partial: 3 of {n}"
    assert f"mm at P4, partial: 3 of {n} configurations" in _paragraph(text, "verdict")
    # a joint that never moves: without a prior the fit is partial, the report says so and names the joint
    q = session.q.copy()
    q[:, 3] = q[0, 3]
    still = dataclasses.replace(session, q=q, tolerances=None)
    text = write_report(tmp_path / "p", still, identify(still, "lm")).read_text()
    assert _paragraph(text, "verdict").startswith("partial calibration")  # (inconsistent data: not converged)
    # which groups the greedy naming lists depends on where the (unconverged) fit stopped: named, any
    assert "not identified: joint " in _paragraph(text, "verdict")
    idf = {r[0]: r[1] for r in Tables(text).tables["identifiability"][1:]}
    assert idf["partial: not identified"].startswith("joint ")
    # under the robot's prior nothing is left undefined: the verdict names what the prior determined
    still = dataclasses.replace(still, tolerances=session.tolerances)
    text = write_report(tmp_path / "q", still, identify(still, "lm")).read_text()
    v = _paragraph(text, "verdict")
    assert "from the prior, not calibrated by the data: joint " in v
    # (these data, a joint frozen in the file but not on the arm, fit no robot: the verdict says so)
    assert v.startswith("NOT calibrated") and "these data do not fit this robot" in v
    idf = {r[0]: r[1] for r in Tables(text).tables["identifiability"][1:]}
    assert "partial: not identified" not in idf and any(k.startswith("from the prior: joint ") for k in idf)
