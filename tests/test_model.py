"""Robot model files: the shipped thesis tables, their typos handled openly, round trip, bad files."""

import numpy as np
import pytest

from lasercal.solver.errors import FormatError
from lasercal.solver.formats.data import builtin_dir
from lasercal.solver.formats.robots import load_model, model_from_dict


@pytest.mark.parametrize("name", sorted(p.stem for p in (builtin_dir("robots")).glob("*.yaml")))
def test_shipped_models_are_valid_screws(name):
    m = load_model(name)
    w, v = m.screws[:, :3], m.screws[:, 3:]
    assert np.allclose(np.linalg.norm(w, axis=1), 1, atol=1e-12)
    assert np.allclose(np.sum(w * v, axis=1), 0, atol=1e-9)
    assert np.isclose(np.linalg.norm(m.laser_dir), 1)


def test_printed_typos_are_corrected_and_rounding_is_reported():
    t43 = load_model("panda_thesis_identified")
    assert len(t43.notes) == 7  # every joint's 4-5 digit rounding is reported, never silent
    assert np.isclose(t43.laser_dir[0], 0.02478, atol=1e-5)  # printed 0.2478: |v_p| would be 1.030
    actual = load_model("puma560_thesis_actual")
    # Table 4.1's printed joint-4/6 omega_z (-0.0998, -0.0995) and joint-3 (-0.01) corrected to -0.998,
    # -0.995, -0.001
    assert np.allclose(actual.screws[[2, 3, 5], 2], [-0.001, -0.998, -0.995], atol=2e-4)
    # and Table 4.2, identified by the thesis, confirms the corrected digits
    assert np.allclose(
        load_model("puma560_thesis_identified").screws[[2, 3, 5], 2], actual.screws[[2, 3, 5], 2], atol=2e-3
    )


def test_save_load_round_trip(tmp_path):
    m = load_model("panda_thesis_identified")
    m.save(tmp_path / "m.yaml")
    m2 = load_model(tmp_path / "m.yaml")
    assert np.allclose(m.screws, m2.screws, atol=1e-12) and np.allclose(m.aperture, m2.aperture)
    assert m2.links and np.isclose(m2.links[3].mass, 3.587895)


@pytest.mark.parametrize(
    "patch, field",
    [
        ({"joints": []}, "joints"),
        ({"joints": [{"omega": [0, 0, "x"], "v": [0, 0, 0], "limits": [-1, 1]}]}, "joints[0].omega"),
        ({"joints": [{"omega": [0, 0, 1], "v": [0, 0, 0], "limits": [1, -1]}]}, "joints[0].limits"),
        ({"laser": {"omega": [0, 0, 1], "v": [0, 0, -1], "M": [0, 0, 0]}}, "laser.omega"),
        ({"units": {"length": "m"}}, "units"),
    ],
)
def test_bad_model_names_the_field(patch, field):
    d = {
        "format": "lasercal-robot/1",
        "joints": [{"omega": [0, 0, 1], "v": [0, 0, 0], "limits": [-1, 1]}],
        "laser": {"v": [0, 0, -1], "M": [0, 0, 100]},
    }
    d.update(patch)
    with pytest.raises(FormatError) as e:
        model_from_dict(d, "bad.yaml")
    assert e.value.field == field and "bad.yaml" in str(e.value)


def test_a_yaml_file_is_read_as_it_is_now_and_its_document_is_the_callers(tmp_path):
    """load_yaml remembers what it parsed, by the file's text: a file rewritten is read as it is now (a
    NaN written into it refused as before), and a document its caller changed leaves the next read alone."""
    from lasercal.solver.formats.checks import load_yaml

    path = tmp_path / "a.yaml"
    path.write_text("a: [1, 2]\n")
    load_yaml(path)["a"].append(3)  # a document parsed
    load_yaml(path)["a"].append(4)  # one remembered
    assert load_yaml(path) == {"a": [1, 2]}
    path.write_text("a: [1, 5]\n")
    assert load_yaml(path) == {"a": [1, 5]}
    path.write_text("a: [1, .nan]\n")
    with pytest.raises(FormatError, match="expected a finite number"):
        load_yaml(path)
