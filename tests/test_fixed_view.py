"""Issue 53: a hands-free camera session's photo in which the arm hides a marker. The camera stands still,
so the session's earlier view of every marker still maps its spot (collector.sessions.spotcam.SpotMeter);
a camera that has moved is caught by its markers' corners and the spot is refused as before."""

from __future__ import annotations

import numpy as np
import pytest
import yaml

from lasercal.collector.sessions.spotcam import UNMOVED_PX, SpotMeter, measure_spot
from lasercal.vision.errors import VisionError
from lasercal.vision.plane import load_markers
from lasercal.vision.render import LaserSpot, Photo, look_down, marker_prints, marker_sheet, render

VIEW = look_down(size=(1200, 900), mm_per_px=0.25, centre=(0.0, 0.0), height=600.0)
CORNERS = marker_sheet(VIEW, side=30.0, inset=0.12, ids=(0, 1, 2, 3))
HIDDEN = 2  # the bottom-right marker of the photo


@pytest.fixture(scope="module")
def markers(tmp_path_factory):
    path = tmp_path_factory.mktemp("fixed") / "layout.yaml"
    ids = {i: np.round(c, 6).tolist() for i, c in CORNERS.items()}
    doc = {"format": "lasercal-layout/1", "units": {"length": "mm"}, "plane": {"z": 0.0}}
    doc |= {"points": {"P1": [0.0, 0.0, 0.0]}, "calibration": ["P1"]}
    doc |= {"markers": {"dictionary": "DICT_4X4_50", "ids": ids}}
    path.write_text(yaml.safe_dump(doc))
    return load_markers(path)


def photo(uv, hide: bool, shift_px: float = 0.0, seed: int = 0) -> np.ndarray:
    """A photo of the markers with a spot at ``uv`` px; ``hide``: the arm (a grey block) over marker HIDDEN;
    ``shift_px``: the camera bumped along the image's u."""
    img = render(Photo(VIEW, marker_prints(CORNERS), (LaserSpot(*uv, sigma=2.5, peak=0.8),)), seed)
    if hide:
        box = VIEW.project(CORNERS[HIDDEN])
        (u0, v0), (u1, v1) = np.floor(box.min(0)).astype(int) - 15, np.ceil(box.max(0)).astype(int) + 15
        img[v0:v1, u0:u1] = 60
    if shift_px:
        img = np.ascontiguousarray(np.roll(img, int(shift_px), axis=1))
    return img


def test_a_spot_past_a_hidden_marker_is_measured_through_the_session_view(markers):
    """The spot beyond the three markers the photo shows: alone, refused (extrapolated); after a photo of
    every marker, mapped through that view within its stated 3 sigma of the truth, its note naming the
    hidden marker; a camera bumped by 2 px (8 x the limit's median corner move) is refused."""
    w, h = VIEW.size
    uv = np.array([0.8 * (w - 1), 0.8 * (h - 1)])  # in the hidden marker's corner of the photo
    truth = VIEW.unproject(uv[None])[0]
    with pytest.raises(VisionError, match="outside the area the markers span"):
        measure_spot(photo(uv, hide=True), "alone", markers)
    meter = SpotMeter(markers)
    first = meter(photo(0.5 * np.array([w - 1, h - 1]), hide=False, seed=1), "first")
    assert set(first.in_view) == set(CORNERS) and meter.view is not None
    got = meter(photo(uv, hide=True, seed=2), "hidden")
    assert HIDDEN not in got.in_view and f"markers {HIDDEN} hidden" in got.note
    assert np.all(np.abs(got.xy - truth) <= 3 * got.sigma), (got.xy - truth, got.sigma)
    assert 2.0 >= 8 * UNMOVED_PX
    with pytest.raises(VisionError, match="outside the area the markers span"):
        meter(photo(uv, hide=True, shift_px=2.0, seed=3), "bumped")
