"""Layout markers, ArUco/ChArUco fiducials and the homography to mm, against the renderer's truth."""

import cv2
import numpy as np
import pytest
import yaml

from lasercal.vision import plane as P
from lasercal.vision.camera import Camera
from lasercal.vision.errors import LayoutError, MarkerError
from lasercal.vision.images import to_gray
from lasercal.vision.measure import Options, measure_photo
from lasercal.vision.render import (
    LaserSpot,
    Photo,
    Print,
    look_down,
    marker_prints,
    marker_sheet,
    render,
    square_corners,
)

PHOTO = dict(paper=0.55, jpeg=92, gamma=2.2, bloom=0.3, gradient=0.2)


def write_layout(tmp_path, markers, **extra):
    doc = {
        "format": "lasercal-layout/1",
        "units": {"length": "mm"},
        "plane": {"z": -8},
        "points": {"P1": [521, 200, -8]},
        "calibration": ["P1"],
        "aiming": {"tilt_deg": [0, 35]},
        "markers": {**P.layout_markers("DICT_4X4_50", markers), **extra},
    }
    path = tmp_path / "layout.yaml"
    path.write_text(yaml.safe_dump(doc, sort_keys=False))
    return path


def scene(seed, size=(1000, 750), dist=(0, 0, 0, 0, 0), n_spots=3):
    """A 0.3 mm/px photo with four markers and spots at known plane positions (mm)."""
    rng = np.random.default_rng(seed)
    view = look_down(
        size,
        0.3,
        centre=(450.0, 0.0),
        tilt_deg=tuple(rng.uniform(-1, 1, 2)),
        yaw_deg=rng.uniform(-20, 20),
        dist=dist,
        z=-8,
    )
    markers = marker_sheet(view, side=40)
    xy = view.unproject(rng.uniform([250, 200], [size[0] - 250, size[1] - 200], (n_spots, 2)))
    spots = tuple(LaserSpot(*view.project(p)[0], 2.0, 3.0, speckle=0.3) for p in xy)
    return view, markers, xy, render(Photo(view, marker_prints(markers), spots, **PHOTO), seed)


def test_layout_markers_are_read_and_unknown_sections_ignored(tmp_path):
    markers = {7: square_corners((300, 100), 40), 3: square_corners((600, -100), 40, 30)}
    lay = P.load_markers(write_layout(tmp_path, markers))
    assert lay.dictionary == "DICT_4X4_50" and set(lay.corners) == {3, 7}
    assert np.allclose(lay.corners[3], markers[3], atol=1e-4)
    assert lay.min_markers == 2 and lay.plane_z == -8 and lay.charuco is None


def test_layout_without_markers_gives_none(tmp_path):
    path = tmp_path / "l.yaml"
    path.write_text("format: lasercal-layout/1\npoints: {P1: [1, 2, 3]}\n")
    assert P.load_markers(path) is None


@pytest.mark.parametrize(
    "markers, field, message",
    [
        ({"dictionary": "DICT_9X9_1"}, "markers.dictionary", "not an OpenCV ArUco dictionary"),
        ({"ids": {0: [[0, 0], [1, 0]]}, "dictionary": "DICT_4X4_50"}, "markers.ids.0", "expected 4 corners"),
        (
            {"ids": {0: [[0, 0], [40, 0], [40, 40], [0, 40]]}, "dictionary": "DICT_4X4_50"},
            "markers.ids.0",
            "clockwise",
        ),
        (
            {"ids": {"a": [[0, 40], [40, 40], [40, 0], [0, 0]]}, "dictionary": "DICT_4X4_50"},
            "markers.ids.a",
            "whole",
        ),
        ({"ids": {}, "dictionary": "DICT_4X4_50"}, "markers.ids", "no markers"),
        ({"ids": {0: [[0, 40], [40, 40], [40, 0], [0, 0]]}}, "markers.dictionary", "missing"),
        (
            {"ids": {0: [[0, 40], [40, 40], [40, 0], [0, 0]]}, "dictionary": "DICT_4X4_50", "min_markers": 4},
            "markers.min_markers",
            "between 1 and",
        ),
        (
            {
                "ids": {0: [[0, 40], [40, 40], [40, 0], [0, 0]]},
                "dictionary": "DICT_4X4_50",
                "charuco": {
                    "squares": [5, 4],
                    "square": 30,
                    "marker": 22,
                    "origin": [0, 0],
                    "x_axis": [1, 0],
                    "y_axis": [0, -1],
                },
            },
            "markers.ids",
            "also markers of the ChArUco board",
        ),
        (
            {
                "dictionary": "DICT_4X4_50",
                "charuco": {
                    "squares": [5, 4],
                    "square": 30,
                    "marker": 40,
                    "origin": [0, 0],
                    "x_axis": [1, 0],
                    "y_axis": [0, -1],
                },
            },
            "markers.charuco.marker",
            "below the square side",
        ),
    ],
)
def test_layout_errors_name_the_file_and_field(tmp_path, markers, field, message):
    path = tmp_path / "bad.yaml"
    path.write_text(yaml.safe_dump({"format": "lasercal-layout/1", "markers": markers}))
    with pytest.raises(LayoutError, match=message) as exc:
        P.load_markers(path)
    assert str(path) in str(exc.value) and f"field '{field}'" in str(exc.value)


def test_layout_file_errors(tmp_path):
    with pytest.raises(LayoutError, match="cannot read layout"):
        P.load_markers(tmp_path / "missing.yaml")
    bad = tmp_path / "bad.yaml"
    bad.write_text("markers: [unclosed\n")
    with pytest.raises(LayoutError, match="not valid YAML"):
        P.load_markers(bad)
    bad.write_text("format: lasercal-layout/9\n")
    with pytest.raises(LayoutError, match="format"):
        P.load_markers(bad)


def test_spot_on_the_plane_within_01_mm_with_four_markers_at_03_mm_per_px(tmp_path):
    errs = []
    for seed in range(4):
        view, markers, xy, img = scene(seed)
        lay = P.load_markers(write_layout(tmp_path, markers))
        res = measure_photo(img, "p", Options(expect=None), lay)
        assert len(res.spots) == len(xy) and res.plane.mm_per_px == pytest.approx(0.3, abs=0.005)
        assert res.plane.rms_mm < 0.1 and not (~res.plane.inliers).any()
        got = np.array([[s.x_mm, s.y_mm] for s in res.spots])
        for p in xy:
            errs.append(np.min(np.hypot(*(got - p).T)))
        assert all(s.sigma_x_mm is not None and 0.005 < s.sigma_x_mm < 0.2 for s in res.spots)
    assert np.sqrt(np.mean(np.square(errs))) < 0.1


def test_lens_distortion_is_fitted_to_the_markers_when_no_camera_is_given(tmp_path, monkeypatch):
    # Issue 47 item 12: `lasercal spots` on a capture's photo gave y -118.874 where capture, which knows
    # the camera's calibration, recorded -118.746 +- 0.031. Without a camera YAML the lens is now fitted
    # to the markers' corners: the same photo gives the same spot, and a warning says why.
    dist = (-0.12, 0.05, 0, 0, 0)
    err = {"calibrated": [], "fitted": [], "plane only": []}
    apart = []
    for seed in range(3):
        view, markers, xy, img = scene(seed + 10, dist=dist)
        lay = P.load_markers(write_layout(tmp_path, markers))
        known = measure_photo(img, "p", Options(expect=None), lay, Camera(view.size, view.K, view.dist))
        fitted = measure_photo(img, "p", Options(expect=None), lay)
        with monkeypatch.context() as m:  # as before: the homography alone
            m.setattr(P, "LENS_MIN_FIDUCIALS", 10**9)
            plain = measure_photo(img, "p", Options(expect=None), lay)
        assert any("lens distortion fitted to them" in w for w in fitted.warnings), fitted.warnings
        assert not any("lens distortion" in w for w in known.warnings + plain.warnings)
        for res, how in ((known, "calibrated"), (fitted, "fitted"), (plain, "plane only")):
            got = np.array([[s.x_mm, s.y_mm] for s in res.spots])
            err[how] += [np.min(np.hypot(*(got - p).T)) for p in xy]
        for a, b in zip(known.spots, fitted.spots):  # the same spot, within the sigma spots states
            apart.append(np.hypot(a.x_mm - b.x_mm, a.y_mm - b.y_mm) / np.hypot(b.sigma_x_mm, b.sigma_y_mm))
    rms = {how: float(np.sqrt(np.mean(np.square(e)))) for how, e in err.items()}
    # Measured: 0.033 mm calibrated, 0.050 mm through the fitted lens, 0.142 mm through the plane alone.
    assert rms["calibrated"] < 0.1 and rms["fitted"] < 0.1, rms
    assert rms["plane only"] > 2 * rms["fitted"], rms
    # Four markers in the photo's corners leave the lens loose in the sheet's middle: up to 2.2 of the
    # stated sigma apart here (docs/vision.md); the capture's sheet, six markers, agrees to 0.2 sigma.
    assert max(apart) < 3.0, apart


def test_no_lens_is_fitted_to_markers_that_lie_on_a_plane(tmp_path):
    for seed in range(2):
        view, markers, xy, img = scene(seed)
        lay = P.load_markers(write_layout(tmp_path, markers))
        res = measure_photo(img, "p", Options(expect=None), lay)
        assert res.plane.camera is None and not any("lens" in w for w in res.warnings)


def test_too_few_markers_is_a_clear_error(tmp_path):
    view = look_down((640, 480), 0.3, centre=(450.0, 0.0))
    markers = marker_sheet(view, side=24)
    shown = {i: c for i, c in markers.items() if i in (0, 2)}
    img = render(Photo(view, marker_prints(shown), (LaserSpot(320.2, 240.7, 2.0, 3.0),), **PHOTO), 0)
    lay = P.load_markers(write_layout(tmp_path, markers))
    with pytest.raises(
        MarkerError,
        match=r"p\.jpg: found 2 of the 4 markers of .*layout\.yaml \(ids 0, 2\); "
        r"at least 3 needed",
    ):
        measure_photo(img, "p.jpg", Options(), lay)


def test_a_marker_listed_with_wrong_corners_is_an_outlier(tmp_path):
    view, markers, xy, img = scene(5)
    wrong = dict(markers)
    wrong[1] = np.roll(markers[1], 1, axis=0)  # corner order shifted by one: 40 mm off
    lay = P.load_markers(write_layout(tmp_path, wrong, min_markers=3))
    res = measure_photo(img, "p", Options(expect=None), lay)
    assert (~res.plane.inliers).sum() == 4
    assert any("marker 1 not where the layout says (a wrong id or corner order" in w for w in res.warnings)
    got = np.array([[s.x_mm, s.y_mm] for s in res.spots])
    assert max(np.min(np.hypot(*(got - p).T)) for p in xy) < 0.15


def test_a_marker_with_one_corner_off_is_named_partly_hidden(tmp_path):
    """Issue 53: a marker whose corners partly disagree (an edge found where the arm's shadow or body cut
    it) is named as partly hidden or shadowed, not as a wrong id; a layout corner 5 mm off stands in for
    it."""
    view, markers, xy, img = scene(5)
    moved = dict(markers)
    moved[2] = markers[2] + np.array([[5.0, 0.0], [0.0, 0.0], [0.0, 0.0], [0.0, 0.0]])
    lay = P.load_markers(write_layout(tmp_path, moved, min_markers=3))
    res = measure_photo(img, "p", Options(expect=None), lay)
    assert (~res.plane.inliers).sum() == 1
    note = next(w for w in res.warnings if "disagree with the layout" in w)
    assert "marker 2 partly hidden or shadowed" in note and "wrong id" not in note, note


def test_charuco_board_maps_pixels_to_mm(tmp_path):
    view = look_down((800, 600), 0.3, centre=(450.0, 0.0), yaw_deg=8)
    cols, rows, square, marker = 7, 5, 20.0, 15.0
    origin = np.array([450 - cols * square / 2, rows * square / 2])
    x_axis, y_axis = np.array([1.0, 0.0]), np.array([0.0, -1.0])
    board = cv2.aruco.CharucoBoard(
        (cols, rows), square, marker, cv2.aruco.getPredefinedDictionary(cv2.aruco.DICT_5X5_100)
    )
    tex = board.generateImage((cols * 100, rows * 100), marginSize=0).astype(np.float32) / 255
    w, h = cols * square, rows * square
    corners = np.array([origin, origin + w * x_axis, origin + w * x_axis + h * y_axis, origin + h * y_axis])
    xy = np.array([[540.3, 71.7], [361.0, -70.4]])  # off the board: black squares would swallow the light
    spots = tuple(LaserSpot(*view.project(p)[0], 2.0, 3.0) for p in xy)
    img = render(Photo(view, (Print(tex, corners),), spots, **PHOTO), 1)
    path = tmp_path / "charuco.yaml"
    path.write_text(
        yaml.safe_dump(
            {
                "format": "lasercal-layout/1",
                "markers": {
                    "dictionary": "DICT_5X5_100",
                    "charuco": {
                        "squares": [cols, rows],
                        "square": square,
                        "marker": marker,
                        "origin": origin.tolist(),
                        "x_axis": [1, 0],
                        "y_axis": [0, -1],
                    },
                },
            }
        )
    )
    lay = P.load_markers(path)
    fid = P.find_fiducials(to_gray(img), lay)
    assert fid.charuco == (cols - 1) * (rows - 1) and fid.marker_ids == ()
    truth = lay.charuco.to_base(board.getChessboardCorners()[:, :2])
    assert np.sqrt(np.mean(np.sum((view.unproject(fid.image) - fid.plane) ** 2, 1))) < 0.02  # mm, ~0.05 px
    assert np.abs(fid.plane[:, None] - truth[None]).sum(-1).min(1).max() < 1e-9
    res = measure_photo(img, "c", Options(expect=None), lay)
    got = np.array([[s.x_mm, s.y_mm] for s in res.spots])
    assert max(np.min(np.hypot(*(got - p).T)) for p in xy) < 0.08 and res.plane.rms_mm < 0.05


def test_opencv_4_and_5_array_shapes_are_both_accepted(tmp_path, monkeypatch):
    view, markers, xy, img = scene(2)
    lay = P.load_markers(write_layout(tmp_path, markers))
    ref = P.find_fiducials(to_gray(img), lay)
    real = P._detector

    class Legacy:  # OpenCV 4.x: ids (N, 1), corners a tuple of (1, 4, 2)
        def __init__(self, d):
            self.det = real(d)

        def detectMarkers(self, gray):
            c, ids, rej = self.det.detectMarkers(gray)
            return tuple(np.asarray(x).reshape(1, 4, 2) for x in c), np.asarray(ids).reshape(-1, 1), rej

    monkeypatch.setattr(P, "_detector", lambda d: Legacy(d))
    got = P.find_fiducials(to_gray(img), lay)
    assert got.marker_ids == ref.marker_ids and np.allclose(got.image, ref.image)


def test_edge_fitted_marker_corners_beat_opencv_subpix(tmp_path):
    view, markers, xy, img = scene(3, dist=(-0.1, 0.03, 0, 0, 0))
    lay = P.load_markers(write_layout(tmp_path, markers))
    cam = Camera(view.size, view.K, view.dist)
    rms = {}
    for refine in (False, True):
        fid = P.find_fiducials(to_gray(img), lay, camera=cam, refine_edges=refine)
        rms[refine] = np.sqrt(np.mean(np.sum((fid.image - view.project(fid.plane)) ** 2, 1)))
    assert rms[True] < 0.05 and rms[False] > 0.1


def test_gamma_linearisation_removes_the_edge_bias(tmp_path):
    view, markers, xy, img = scene(3)
    lay = P.load_markers(write_layout(tmp_path, markers))
    rms = {}
    for g in (1.0, 2.2):
        fid = P.find_fiducials(to_gray(img), lay, gamma=g)
        rms[g] = np.sqrt(np.mean(np.sum((fid.image - view.project(fid.plane)) ** 2, 1)))
    assert rms[2.2] < 0.05 and rms[1.0] > 0.2
