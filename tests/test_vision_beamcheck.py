"""Circle fit and the laser alignment check (beam tilt from the joint-7 axis)."""

import json

import cv2
import numpy as np
import pytest
import yaml

from lasercal.collector.cli.main import main
from lasercal.vision.beamcheck import fit_circle, tilt
from lasercal.vision.errors import CalibrationError
from lasercal.vision.plane import layout_markers
from lasercal.vision.render import LaserSpot, Photo, look_down, marker_prints, marker_sheet, render


def test_circle_through_exact_points():
    a = np.linspace(0, 2 * np.pi, 7, endpoint=False)
    c = fit_circle(np.c_[3 + 2.5 * np.cos(a), -4 + 2.5 * np.sin(a)])
    assert np.allclose(c.centre, [3, -4]) and c.radius == pytest.approx(2.5)
    assert c.rms < 1e-9 and c.arc_deg == pytest.approx(360 - 360 / 7)


def test_circle_on_a_partial_arc_with_noise_and_far_from_the_origin():
    rng = np.random.default_rng(0)
    a = rng.uniform(0, np.pi, 30)  # half a turn
    pts = np.c_[5000 + 10 * np.cos(a), 7000 + 10 * np.sin(a)] + rng.normal(0, 0.02, (30, 2))
    c = fit_circle(pts)
    assert np.hypot(*(c.centre - [5000, 7000])) < 0.05 and abs(c.radius - 10) < 0.05
    assert c.rms == pytest.approx(0.02, rel=0.4) and abs(c.radius - 10) < 4 * c.radius_sigma
    assert 150 < c.arc_deg < 181


def test_circle_errors():
    with pytest.raises(CalibrationError, match="at least 3 spots"):
        fit_circle(np.zeros((2, 2)))
    with pytest.raises(CalibrationError, match="on a line"):
        fit_circle(np.c_[np.arange(5.0), 2 * np.arange(5.0)])
    with pytest.raises(CalibrationError, match="same place"):
        fit_circle(np.ones((4, 2)))


def test_tilt_from_radius_and_laser_length():
    assert tilt(4.0, 400.0) == pytest.approx(np.arctan(0.01))
    with pytest.raises(CalibrationError, match="positive"):
        tilt(1.0, 0.0)


def test_beam_check_command_on_rendered_photos(tmp_path, capsys):
    view = look_down((1000, 750), 0.3, centre=(450.0, 0.0), yaw_deg=5, z=-8)
    markers = marker_sheet(view, side=40)
    centre, radius, length = np.array([452.4, -3.1]), 3.0, 400.0  # tilt = atan(3 / 400) = 7.5 mrad
    paths = []
    for i, a in enumerate(np.radians([0, 50, 100, 160, 220, 290])):
        p = centre + radius * np.array([np.cos(a), np.sin(a)])
        img = render(
            Photo(
                view,
                marker_prints(markers),
                (LaserSpot(*view.project(p)[0], 2.0, 3.0, speckle=0.3),),
                paper=0.55,
                jpeg=92,
                gamma=2.2,
            ),
            i,
        )
        paths.append(str(tmp_path / f"j7_{i}.jpg"))
        cv2.imwrite(paths[-1], img)
    layout = tmp_path / "layout.yaml"
    layout.write_text(
        yaml.safe_dump(
            {
                "format": "lasercal-layout/1",
                "plane": {"z": -8},
                "markers": layout_markers("DICT_4X4_50", markers),
            }
        )
    )
    assert main(["beam-check", *paths, "--layout", str(layout), "--laser-length", str(length), "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert np.hypot(*(np.array(out["centre_mm"]) - centre)) < 0.05
    assert out["radius_mm"] == pytest.approx(radius, abs=0.05)
    assert out["tilt_mrad"] == pytest.approx(1e3 * np.arctan(radius / length), abs=0.15)
    assert out["tilt_deg"] == pytest.approx(np.degrees(out["tilt_mrad"] / 1e3), abs=1e-3)
    assert out["radius_px"] == pytest.approx(radius / 0.3, rel=0.02) and out["rms_mm"] < 0.05
    assert len(out["spots"]) == 6 and out["arc_deg"] > 250

    # Without markers: px only, and the tilt needs mm.
    assert main(["beam-check", *paths, "--laser-length", "400"]) == 0
    captured = capsys.readouterr()
    assert "radius" in captured.out and "tilt needs the radius in mm" in captured.err

    assert main(["beam-check", *paths[:2]]) == 2
    assert "beam-check needs at least 3 photos with a spot, 2 of 2" in capsys.readouterr().err
