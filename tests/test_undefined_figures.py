"""A figure that is not defined is written ``null``, not ``.nan``: a session of one capture per point has no
fold to hold out, and the model file ``solve`` wrote must still load (validate and predict read it)."""

from __future__ import annotations

import math

import yaml

from lasercal.collector.cli.main import main
from lasercal.solver.formats.robots import load_model


def test_a_model_whose_cross_validation_failed_loads(tmp_path):
    sheet, s, m = tmp_path / "sheet", tmp_path / "s", tmp_path / "m.yaml"
    assert main(["sheet", "-o", str(sheet), "--robot", "panda", "--place", "450", "0", "0"]) == 0
    layout = str(sheet / "layout.yaml")
    assert (
        main(["simulate", "panda_thesis_identified", "--layout", layout, "--per-point", "1", "-o", str(s)])
        == 0
    )
    assert main(["solve", str(s), "-o", str(m)]) == 0
    cv = yaml.safe_load(m.read_text())["identification"]["cross_validation"]
    assert cv["captures_counted"] == 0 and cv["holdout_rms_mm"] is None  # every fold failed: not defined
    model = load_model(str(m))  # refused as torn before (".nan" at identification.cross_validation)
    assert all(math.isfinite(v) for v in model.screws.ravel())
