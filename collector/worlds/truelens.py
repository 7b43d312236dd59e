"""The fake world's camera: a pinhole behind a real lens, the views ``vision.render`` paints through, and
the lens's calibration estimated from rendered pattern photos (issue 45).

The lens (the world's own code, not OpenCV's projection): a ray's normalised image point (x, y) = (X/Z,
Y/Z) is distorted radially, tangentially (decentring) and by a thin prism (a sensor a little tilted),

    r^2 = x^2 + y^2,   k(r) = 1 + k1 r^2 + k2 r^4 + k3 r^6
    x_d = x k(r) + 2 p1 x y + p2 (r^2 + 2 x^2) + s1 r^2 + s2 r^4                        (eq. L1)
    y_d = y k(r) + p1 (r^2 + 2 y^2) + 2 p2 x y + s3 r^2 + s4 r^4,

then (u, v) = (f_x x_d + c_x, f_y y_d + c_y) px. Its inverse (a pixel's ray) is found by fixed-point
iteration (the distortion is a small change of a ray). ``lasercal camera-calibrate``'s model (k1, k2, p1,
p2; k3 held at 0, no thin prism) cannot hold it all: the correction a session uses is estimated from
photos of a chessboard rendered through this lens (:func:`calibrated`), as a user would calibrate a real
camera -- not the parameters that made the photos.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

# The fake camera's lens: a phone-like wide lens (barrel), slightly decentred, its sensor a little tilted.
RADIAL = (-0.08, 0.03, -0.006)
TANGENTIAL = (2e-4, -1.5e-4)
PRISM = (3e-4, 0.0, -2e-4, 0.0)
# Calibration: a 9 x 6 chessboard of 30 mm squares held before the camera in CALIBRATION_PHOTOS poses
CHESSBOARD = (9, 6, 20.0)
CALIBRATION_PHOTOS = 10


@dataclass(frozen=True)
class Lens:
    """A camera's intrinsics: size (w, h) px, K (3, 3) px, and the distortion of eq. L1."""

    size: tuple
    K: np.ndarray
    radial: tuple = (0.0, 0.0, 0.0)
    tangential: tuple = (0.0, 0.0)
    prism: tuple = (0.0, 0.0, 0.0, 0.0)

    def distort(self, xy: np.ndarray) -> np.ndarray:
        """Normalised image points (k, 2) to the distorted ones (k, 2) (eq. L1)."""
        x, y = xy[:, 0], xy[:, 1]
        r2 = x * x + y * y
        k1, k2, k3 = self.radial
        p1, p2 = self.tangential
        s1, s2, s3, s4 = self.prism
        k = 1 + r2 * (k1 + r2 * (k2 + r2 * k3))
        xd = x * k + 2 * p1 * x * y + p2 * (r2 + 2 * x * x) + r2 * (s1 + s2 * r2)
        yd = y * k + p1 * (r2 + 2 * y * y) + 2 * p2 * x * y + r2 * (s3 + s4 * r2)
        return np.column_stack([xd, yd])

    def pixels(self, xy: np.ndarray) -> np.ndarray:
        """Normalised image points (k, 2) of rays to the pixels (k, 2) they are recorded at, px."""
        d = self.distort(np.atleast_2d(xy))
        return d * np.diag(self.K)[:2] + self.K[:2, 2]

    def rays(self, uv: np.ndarray, iterations: int = 50) -> np.ndarray:
        """Recorded pixels (k, 2) px to the normalised image points (k, 2) of their rays (eq. L1 inverted by
        fixed-point iteration: x = x_d - (distort(x) - x))."""
        xd = (np.atleast_2d(np.asarray(uv, dtype=float)) - self.K[:2, 2]) / np.diag(self.K)[:2]
        x = xd.copy()
        for _ in range(iterations):
            step = xd - self.distort(x)
            x = x + step
            if np.abs(step).max(initial=0.0) < 1e-14:
                break
        return x


@dataclass(frozen=True)
class SpaceCamera:
    """A camera in the world: its lens and its pose, ``x_cam = R x + t`` (R base -> camera, t mm)."""

    lens: Lens
    R: np.ndarray
    t: np.ndarray

    @property
    def eye(self) -> np.ndarray:
        """The centre of projection (3,) in the base frame, mm."""
        return -self.R.T @ self.t

    def project(self, p: np.ndarray) -> np.ndarray:
        """Points (k, 3) mm, base frame, to recorded pixels (k, 2)."""
        c = np.atleast_2d(p) @ self.R.T + self.t
        return self.lens.pixels(c[:, :2] / c[:, 2:])

    def rays(self, uv: np.ndarray) -> np.ndarray:
        """Recorded pixels (k, 2) to the unit directions (k, 3) of their rays, base frame."""
        x = self.lens.rays(uv)
        d = np.column_stack([x, np.ones(len(x))]) @ self.R  # R^T applied to each camera-frame ray
        return d / np.linalg.norm(d, axis=1, keepdims=True)


@dataclass(frozen=True)
class SheetView:
    """The paper as a camera sees it, for ``vision.render`` (its ``size``, ``project``, ``unproject``): the
    plane's coordinates are the layout's printed (u, v) mm, wherever the paper truly lies.

    Attributes
    ----------
    camera : SpaceCamera
    paper : object with ``surface(uv) -> (k, 3)`` and ``hit(o, d) -> (uv, p, s)``
        (:class:`~collector.worlds.truesheet.PaperSheet`, or :class:`Board`)
    """

    camera: SpaceCamera
    paper: object

    @property
    def size(self) -> tuple:
        return self.camera.lens.size

    def project(self, uv: np.ndarray) -> np.ndarray:
        """Printed points (k, 2) mm to recorded pixels (k, 2)."""
        return self.camera.project(self.paper.surface(np.asarray(uv, dtype=float).reshape(-1, 2)))

    def unproject(self, px: np.ndarray) -> np.ndarray:
        """Recorded pixels (k, 2) to the printed points (k, 2) mm their rays meet."""
        px = np.asarray(px, dtype=float).reshape(-1, 2)
        return self.paper.hit(self.camera.eye, self.camera.rays(px))[0]


@dataclass(frozen=True)
class Board:
    """A flat calibration board: its points (u, v) mm at ``origin + u x + v y`` (x, y unit, orthogonal)."""

    origin: np.ndarray
    x: np.ndarray
    y: np.ndarray

    def surface(self, uv: np.ndarray) -> np.ndarray:
        uv = np.atleast_2d(uv)
        return self.origin + uv[:, :1] * self.x + uv[:, 1:2] * self.y

    def hit(self, origin: np.ndarray, direction: np.ndarray):
        n = np.cross(self.x, self.y)
        d = np.atleast_2d(direction)
        s = ((self.origin - origin) @ n) / (d @ n)
        p = origin + s[:, None] * d
        rel = p - self.origin
        return np.column_stack([rel @ self.x, rel @ self.y]), p, s


def look_at(eye: np.ndarray, target: np.ndarray, up=(0.0, 0.0, 1.0)) -> tuple[np.ndarray, np.ndarray]:
    """R (base -> camera) and t of a camera at ``eye`` looking at ``target`` (mm), the image's right
    horizontal (normal to ``up``), ``x_cam = R x + t``."""
    fwd = np.asarray(target, dtype=float) - eye
    fwd /= np.linalg.norm(fwd)
    right = np.cross(fwd, up)
    right /= np.linalg.norm(right)
    R = np.vstack([right, np.cross(fwd, right), fwd])
    return R, -R @ eye


def board_poses(rng: np.random.Generator, n: int, distance: float, lens: Lens, margin: float = 25.0):
    """n poses of the chessboard before a camera at the origin looking along +z (its own frame): at
    0.8-1.2 x ``distance``, tilted up to 35 deg about both axes, turned up to 15 deg, shifted anywhere the
    whole board stays ``margin`` px inside the photo (drawn again until it does) -- the corners of the view
    covered, as a calibration needs."""
    cols, rows, square = CHESSBOARD
    w, h = (cols + 1) * square, (rows + 1) * square
    corners = np.array([[0, 0], [w, 0], [w, h], [0, h]], dtype=float)
    camera = SpaceCamera(lens, np.eye(3), np.zeros(3))
    size = np.array(lens.size, dtype=float)
    out = []
    while len(out) < n:
        ax, ay = np.radians(rng.uniform(-35, 35, 2))
        spin = np.radians(rng.uniform(-15, 15))
        R = (
            np.array([[1, 0, 0], [0, np.cos(ax), -np.sin(ax)], [0, np.sin(ax), np.cos(ax)]])
            @ np.array([[np.cos(ay), 0, np.sin(ay)], [0, 1, 0], [-np.sin(ay), 0, np.cos(ay)]])
            @ np.array([[np.cos(spin), -np.sin(spin), 0], [np.sin(spin), np.cos(spin), 0], [0, 0, 1]])
        )
        z = distance * rng.uniform(0.8, 1.2)
        centre = np.r_[rng.uniform(-0.3, 0.3) * z, rng.uniform(-0.22, 0.22) * z, z]
        board = Board(centre - (w / 2) * R[:, 0] - (h / 2) * R[:, 1], R[:, 0], R[:, 1])
        px = camera.project(board.surface(corners))
        if np.all(px > margin) and np.all(px < size - 1 - margin):
            out.append(board)
    return out


def chessboard_photo(lens: Lens, board: Board, seed: int, psf: float = 0.8) -> np.ndarray:
    """A photo (h, w) uint8 grey of ``board`` (a :data:`CHESSBOARD` on white paper reaching 30 mm beyond
    it, a grey table around) by a camera with ``lens`` at the origin looking along +z, painted pixel by
    pixel: each pixel's ray meets the board at (u, v) mm; a chessboard is the product of two square waves,
    S(u) S(v), so blurred by the lens's PSF and the pixel (sigma ``psf`` and 1/sqrt(12) px, in mm at the
    board's mean scale) it is the product of two blurred square waves (erf across the nearest edge); then
    shot and read noise, gamma 2.2, 8 bits."""
    from scipy.special import erf

    cols, rows, square = CHESSBOARD
    w, h = lens.size
    camera = SpaceCamera(lens, np.eye(3), np.zeros(3))
    size = np.array([(cols + 1) * square, (rows + 1) * square])
    edge = np.linspace(0, 1, 9)[:, None]
    unit = np.vstack(
        [np.c_[edge, 0 * edge], np.c_[edge, 0 * edge + 1], np.c_[0 * edge, edge], np.c_[0 * edge + 1, edge]]
    )
    corner = camera.project(board.surface(unit * (size + 60) - 30))  # the paper's outline
    x0, y0 = np.clip(np.floor(corner.min(0)).astype(int) - 4, 0, [w, h])
    x1, y1 = np.clip(np.ceil(corner.max(0)).astype(int) + 5, 0, [w, h])
    step = 4  # (u, v) at every 4th pixel, bilinear between: they bend by ~1e-3 px over 4 px
    gx = np.arange(x0, x1 + step, step, dtype=float)
    gy = np.arange(y0, y1 + step, step, dtype=float)
    grid = board.hit(np.zeros(3), camera.rays(np.stack(np.meshgrid(gx, gy), -1).reshape(-1, 2)))[0]
    grid = grid.reshape(len(gy), len(gx), 2)
    mm_per_px = np.median(np.hypot(*np.gradient(grid[..., 0], step)))
    i, fy = np.divmod(np.arange(y1 - y0), step)
    j, fx = np.divmod(np.arange(x1 - x0), step)
    fy, fx = (fy / step)[:, None, None], (fx / step)[None, :, None]
    uv = (grid[i][:, j] * (1 - fx) + grid[i][:, j + 1] * fx) * (1 - fy)
    uv += (grid[i + 1][:, j] * (1 - fx) + grid[i + 1][:, j + 1] * fx) * fy
    sig = np.sqrt(2) * np.hypot(psf, np.sqrt(1 / 12)) * mm_per_px  # sqrt(2) sigma, mm
    value = ink = paper = 1.0
    for k, n in ((0, cols + 1), (1, rows + 1)):
        c = uv[..., k]
        cell = np.floor(c / square)
        frac = c / square - cell
        # the nearest edge between two squares (the pattern's outline is the ink's, below)
        near = np.minimum(np.where(cell > 0, frac, 1.0), np.where(cell < n - 1, 1 - frac, 1.0))
        value = value * np.where(cell % 2 == 0, 1.0, -1.0) * erf(square * near / sig)
        ink = ink * 0.5 * (erf(c / sig) - erf((c - n * square) / sig))  # where squares are printed
        paper = paper * 0.5 * (erf((c + 30.0) / sig) - erf((c - n * square - 30.0) / sig))
    reflect = np.full((h, w), 0.3)  # the table
    black = 0.5 * (1 + value) * ink  # (i + j) even: black
    reflect[y0:y1, x0:x1] = 0.3 + (0.7 - 0.95 * black) * paper  # white paper 1, ink 0.05
    rng = np.random.default_rng([seed, 0xB0A])
    dn = 255.0 * 0.7 * reflect
    dn += np.sqrt(1.0 + 0.02 * dn) * rng.standard_normal(dn.shape)
    return np.round(255.0 * (np.clip(dn, 0, 255) / 255.0) ** (1 / 2.2)).astype(np.uint8)


def calibrated(lens: Lens, distance: float, seed: int):
    """The lens's calibration as ``lasercal camera-calibrate`` makes it (:func:`vision.camera.calibrate`)
    from :data:`CALIBRATION_PHOTOS` chessboard photos rendered through ``lens``, the board ~``distance`` mm
    away: a ``vision.camera.Camera`` (K, dist = k1, k2, p1, p2, k3) whose correction is estimated."""
    import cv2

    from lasercal.vision.camera import calibrate

    rng = np.random.default_rng([seed, 0xCA1])
    boards = board_poses(rng, CALIBRATION_PHOTOS, distance, lens)
    photos = [(f"board-{k}", chessboard_photo(lens, b, seed * 1000 + k)) for k, b in enumerate(boards)]
    cols, rows, square = CHESSBOARD
    pattern = {"type": "chessboard", "cols": cols, "rows": rows, "square": square}
    threads = cv2.getNumThreads()
    cv2.setNumThreads(1)  # OpenCV's parallel sums differ in their last bits from run to run
    try:
        cam, _ = calibrate(photos, pattern, lambda m: None)
    finally:
        cv2.setNumThreads(threads)
    # round-off (a BLAS kernel, a thread count) must not change a session: 10 significant digits kept
    return replace(cam, K=np.round(cam.K, 6), dist=np.round(cam.dist, 10))
