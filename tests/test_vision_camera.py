"""Camera YAML and calibration against synthetic pattern photos with known intrinsics (px)."""

import cv2
import numpy as np
import pytest
import yaml

from lasercal.vision.camera import Camera, calibrate, distort, load_camera, save_camera, undistort
from lasercal.vision.errors import CalibrationError, LayoutError
from lasercal.vision.render import Photo, Print, chessboard_print, pose_view, render

SIZE = (640, 480)
K = np.array([[620.0, 0, 322.5], [0, 620.0, 238.0], [0, 0, 1]])
DIST = np.array([-0.18, 0.07, 0.001, -0.0005, 0.0])  # k3 = 0: calibrate() fixes it


def pattern_photos(item: Print, centre, n=8, seed=0, distance=600.0):
    """Photos of a planar pattern (z = 0) from several tilted poses."""
    rng = np.random.default_rng(seed)
    out = []
    for i in range(n):
        rvec = np.r_[rng.uniform(-0.45, 0.45, 2), rng.uniform(-0.3, 0.3)]
        R, _ = cv2.Rodrigues(rvec)
        t = np.array([*rng.uniform(-0.15, 0.15, 2) * distance, distance]) - R @ np.r_[centre, 0]
        view = pose_view(SIZE, K, DIST, R, t)
        img = render(Photo(view, (item,), paper=0.7, read_noise=1.0, gamma=2.2), seed * 100 + i)
        out.append((f"cal{i}.png", cv2.cvtColor(img, cv2.COLOR_BGR2GRAY)))
    return out


def test_distort_and_undistort_are_inverse():
    uv = np.random.default_rng(0).uniform([0, 0], SIZE, (50, 2))
    assert np.allclose(undistort(distort(uv, K, DIST), K, DIST), uv, atol=1e-4)
    assert np.allclose(distort(uv, K, np.zeros(5)), uv)


def test_chessboard_calibration_recovers_the_intrinsics():
    board = chessboard_print(9, 6, 25.0)
    cam, used = calibrate(
        pattern_photos(board, (125.0, 87.5)), {"type": "chessboard", "cols": 9, "rows": 6, "square": 25.0}
    )
    assert used == 8 and cam.size == SIZE
    assert cam.rms_px < 0.15
    assert np.allclose(np.diag(cam.K)[:2], np.diag(K)[:2], rtol=0.02)  # f and k1, k2 trade off a little
    assert np.allclose(cam.K[:2, 2], K[:2, 2], atol=3.0)
    # What the plane mapping needs: undistorted, a plane maps to the image by a homography.
    R, _ = cv2.Rodrigues(np.array([0.2, -0.15, 0.1]))
    view = pose_view(SIZE, K, DIST, R, np.array([0, 0, 500.0]) - R @ np.r_[0, 0, 0])
    plane = np.stack(np.meshgrid(np.linspace(-190, 190, 12), np.linspace(-140, 140, 9)), -1).reshape(-1, 2)
    uv = view.project(plane)
    inside = np.all((uv > 0) & (uv < SIZE), 1)
    assert inside.sum() > 60

    def homography_rms(pts):
        H, _ = cv2.findHomography(plane[inside], pts[inside], 0)
        fit = cv2.perspectiveTransform(plane[inside].reshape(-1, 1, 2), H).reshape(-1, 2)
        return np.sqrt(np.mean(np.sum((fit - pts[inside]) ** 2, 1)))

    assert homography_rms(undistort(uv, cam.K, cam.dist)) < 0.1
    assert homography_rms(uv) > 1.0  # the distortion the camera model removes


def test_charuco_calibration():
    d = cv2.aruco.getPredefinedDictionary(cv2.aruco.DICT_4X4_50)
    board = cv2.aruco.CharucoBoard((7, 5), 30.0, 22.0, d)
    tex = board.generateImage((700, 500), marginSize=0).astype(np.float32) / 255
    item = Print(tex, np.array([[0, 0], [210, 0], [210, 150], [0, 150.0]]))  # board frame: y down the print
    photos = pattern_photos(item, (105.0, 75.0), n=6, seed=1, distance=420.0)
    cam, used = calibrate(
        photos,
        {
            "type": "charuco",
            "cols": 7,
            "rows": 5,
            "square": 30.0,
            "marker": 22.0,
            "dictionary": "DICT_4X4_50",
        },
    )
    assert used == 6 and cam.rms_px < 0.5
    assert np.allclose(np.diag(cam.K)[:2], np.diag(K)[:2], rtol=0.02)


def test_calibration_errors():
    blank = [(f"b{i}.png", np.full((480, 640), 200, np.uint8)) for i in range(4)]
    warned = []
    with pytest.raises(CalibrationError, match="found in 0 of 4 photos; at least 3"):
        calibrate(blank, {"type": "chessboard", "cols": 9, "rows": 6, "square": 25.0}, warned.append)
    assert len(warned) == 4 and "b0.png: calibration pattern not found" in warned[0]
    with pytest.raises(CalibrationError, match="different sizes"):
        calibrate(
            [("a", np.zeros((10, 20), np.uint8)), ("b", np.zeros((20, 10), np.uint8))],
            {"type": "chessboard", "cols": 9, "rows": 6, "square": 25.0},
        )


def test_camera_yaml_round_trip(tmp_path):
    path = tmp_path / "camera.yaml"
    save_camera(
        path, Camera(SIZE, K, DIST, 0.123), {"type": "chessboard", "cols": 9, "rows": 6, "square": 25.0}, 8
    )
    doc = yaml.safe_load(path.read_text())
    assert doc["format"] == "lasercal-camera/1" and doc["units"] == {"image": "px", "pattern": "mm"}
    assert doc["image_size"] == [640, 480] and doc["photos"] == 8 and doc["rms_px"] == 0.123
    cam = load_camera(path)
    assert np.allclose(cam.K, K) and np.allclose(cam.dist, DIST) and cam.size == SIZE


def test_a_camera_yaml_cut_short_is_refused_at_any_line_end(tmp_path):
    """The camera YAML says where it ends, with the line solver/whole.py writes (vision stands alone, so it
    keeps its own copy): cut at any line end -- where the rest still parses -- it is refused naming it."""
    from lasercal.solver.whole import WHOLE
    from lasercal.vision.camera import WHOLE as VISION_WHOLE

    assert VISION_WHOLE == WHOLE
    path = tmp_path / "camera.yaml"
    save_camera(
        path, Camera(SIZE, K, DIST, 0.1), {"type": "chessboard", "cols": 9, "rows": 6, "square": 25.0}, 8
    )
    lines = path.read_text().splitlines(keepends=True)
    assert lines[0] == WHOLE + "\n" and lines[-1] == "...\n"
    for k in range(1, len(lines)):
        path.write_text("".join(lines[:k]))
        with pytest.raises(LayoutError, match="cut short") as e:
            load_camera(path)
        assert str(path) in str(e.value)


@pytest.mark.parametrize(
    "text, field",
    [
        ("format: other/1\n", "format"),
        ("format: lasercal-camera/1\nimage_size: [640]\nK: [[1,0,0],[0,1,0],[0,0,1]]\n", "image_size"),
        ("format: lasercal-camera/1\nimage_size: [640, 480]\nK: [[1,0,0],[0,1,0]]\n", "K"),
        (
            "format: lasercal-camera/1\nimage_size: [640, 480]\nK: [[1,0,0],[0,1,0],[0,0,1]]\ndist: [1, 2, "
            "3]\n",
            "dist",
        ),
    ],
)
def test_camera_yaml_errors_name_the_field(tmp_path, text, field):
    path = tmp_path / "cam.yaml"
    path.write_text(text)
    with pytest.raises(LayoutError, match=f"field '{field}'"):
        load_camera(path)


def test_photo_of_another_size_is_refused():
    with pytest.raises(
        CalibrationError, match="p.jpg: image is 480x640 px but the camera was calibrated at 640x480"
    ):
        Camera(SIZE, K, DIST).check_size((480, 640), "p.jpg")
