"""Synthetic photos of laser spots on a printed sheet, with known truth.

Used by the tests and the benchmark to measure errors against the truth.

Geometry: a point (x, y) in mm on the table plane (robot base frame) maps to an
ideal pixel through a homography ``H`` (3x3), then through OpenCV's lens
distortion ``(K, dist)`` to the recorded pixel. Pixels follow OpenCV's convention
(pixel centres at integer coordinates). A laser spot is placed by its true centre
``(u, v)`` in recorded pixels.

Photometry, in linear digital numbers (DN, full scale 255): paper brightness
times room light (tint, gradient, vignetting) times printed reflectance, blurred by
the lens PSF; plus laser light (a Gaussian, optionally elliptical, with speckle)
and specular glare; plus shot and read noise; excess charge blooms into the
neighbours; clipped at full scale; then gamma-encoded, quantised to 8 bits and
optionally JPEG-compressed (with 4:2:0 chroma subsampling, as cameras do).

With ``Photo.camera`` set to a :class:`PhoneCamera`, the last steps follow a phone's
pipeline instead: auto exposure (a gain that changes from photo to photo), a Bayer
(RGGB) mosaic with shot and read noise, saturation of the sensor with excess charge
blooming into the neighbouring photosites (whatever their colour filter), clipping,
demosaicing, white balance, a colour-correction matrix and a tone curve applied
after the clipping, and a 4:2:0 JPEG. A laser spot then records as phones record
it: a white clipped core in a pink (or pale green) halo.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import cv2
import numpy as np

from lasercal.vision.camera import distort, undistort

FULL = 255.0


@dataclass(frozen=True)
class View:
    """How the table plane appears in the photo.

    Attributes
    ----------
    size : (width, height), px
    H : (3, 3) array, plane (x, y) mm -> ideal pixel
    K : (3, 3) array, camera matrix, px
    dist : (k,) array, OpenCV distortion coefficients
    """

    size: tuple[int, int]
    H: np.ndarray
    K: np.ndarray
    dist: np.ndarray = field(default_factory=lambda: np.zeros(5))

    def project(self, xy: np.ndarray) -> np.ndarray:
        """Plane points (n, 2) mm -> recorded pixels (n, 2) px."""
        xy = np.asarray(xy, float).reshape(-1, 2)
        p = np.column_stack([xy, np.ones(len(xy))]) @ self.H.T
        return distort(p[:, :2] / p[:, 2:], self.K, self.dist)

    def unproject(self, uv: np.ndarray) -> np.ndarray:
        """Recorded pixels (n, 2) px -> plane points (n, 2) mm."""
        uv = undistort(uv, self.K, self.dist)
        p = np.column_stack([uv, np.ones(len(uv))]) @ np.linalg.inv(self.H).T
        return p[:, :2] / p[:, 2:]


def pose_view(size, K, dist, R, t, z: float = 0.0) -> View:
    """View of the plane z = ``z`` (mm) from a camera with pose ``x_cam = R x + t``.

    Parameters
    ----------
    size : (width, height), px
    K : (3, 3) array; dist : (k,) array
    R : (3, 3) rotation, base -> camera; t : (3,) array, mm
    z : float, height of the plane in the base frame, mm
    """
    R, t = np.asarray(R, float), np.asarray(t, float)
    H = np.asarray(K, float) @ np.column_stack([R[:, 0], R[:, 1], R[:, 2] * z + t])
    return View(tuple(size), H / H[2, 2], np.asarray(K, float), np.asarray(dist, float))


def look_down(
    size=(4000, 3000),
    mm_per_px: float = 0.3,
    centre=(450.0, 0.0),
    yaw_deg: float = 0.0,
    tilt_deg=(0.0, 0.0),
    height: float = 1000.0,
    dist=(0, 0, 0, 0, 0),
    z: float = 0.0,
) -> View:
    """A camera ``height`` mm above ``centre`` looking down at the plane z = ``z``.

    With zero yaw the image's right is +x and its down is -y (a top view of a
    right-handed frame with z up). ``tilt_deg`` rotates the camera about its own
    x and y axes (perspective); ``mm_per_px`` is the scale at the image centre.
    """
    w, h = size
    f = height / mm_per_px
    K = np.array([[f, 0, (w - 1) / 2], [0, f, (h - 1) / 2], [0, 0, 1]])
    c, s = np.cos(np.radians(yaw_deg)), np.sin(np.radians(yaw_deg))
    R0 = np.array([[c, s, 0], [s, -c, 0], [0, 0, -1.0]])
    ax, ay = np.radians(tilt_deg)
    Rx = np.array([[1, 0, 0], [0, np.cos(ax), -np.sin(ax)], [0, np.sin(ax), np.cos(ax)]])
    Ry = np.array([[np.cos(ay), 0, np.sin(ay)], [0, 1, 0], [-np.sin(ay), 0, np.cos(ay)]])
    R = Rx @ Ry @ R0
    C = np.array([centre[0], centre[1], z + height])
    return pose_view(size, K, dist, R, -R @ C, z)


@dataclass(frozen=True)
class Print:
    """A printed item on the sheet.

    Attributes
    ----------
    image : (h, w) or (h, w, 3) BGR array, reflectance in [0, 1]
    corners_mm : (4, 2) array, plane positions of the image's outer corners
        (top-left, top-right, bottom-right, bottom-left), mm
    """

    image: np.ndarray
    corners_mm: np.ndarray


def square_corners(centre, side: float, angle_deg: float = 0.0) -> np.ndarray:
    """Corners (4, 2) mm of a square as seen from above: top-left, top-right,
    bottom-right, bottom-left (OpenCV's marker corner order), rotated by
    ``angle_deg`` counter-clockwise about ``centre``."""
    half = side / 2
    local = np.array([[-half, half], [half, half], [half, -half], [-half, -half]])
    c, s = np.cos(np.radians(angle_deg)), np.sin(np.radians(angle_deg))
    return np.asarray(centre, float) + local @ np.array([[c, s], [-s, c]])


def aruco_print(dictionary: str, marker_id: int, corners_mm) -> Print:
    """An ArUco marker of OpenCV's ``dictionary`` (e.g. ``"DICT_4X4_50"``)."""
    d = cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, dictionary))
    cells = d.markerSize + 2
    img = cv2.aruco.generateImageMarker(d, int(marker_id), cells)
    return Print(img.astype(np.float32) / 255, np.asarray(corners_mm, float))


def chessboard_print(cols: int, rows: int, square: float, origin=(0.0, 0.0)) -> Print:
    """A chessboard with ``cols`` x ``rows`` inner corners, squares of ``square`` mm."""
    board = (np.indices((rows + 1, cols + 1)).sum(0) % 2).astype(np.float32)
    w, h = (cols + 1) * square, (rows + 1) * square
    x0, y0 = origin
    return Print(board, np.array([[x0, y0 + h], [x0 + w, y0 + h], [x0 + w, y0], [x0, y0]], float))


def cross_print(centre, size: float = 10.0, width: float = 0.5) -> Print:
    """A printed black cross (a reference-point mark), arms ``size`` mm, lines ``width`` mm."""
    n = max(int(round(size / width)) | 1, 3)
    img = np.ones((n, n), np.float32)
    img[n // 2, :] = img[:, n // 2] = 0.05
    return Print(img, square_corners(centre, n * width))


def ink_dot(centre, diameter: float, bgr=(0.15, 0.15, 0.85)) -> Print:
    """A printed coloured dot (red ink by default) of ``diameter`` mm."""
    n = 32
    yy, xx = np.mgrid[:n, :n] - (n - 1) / 2
    img = np.ones((n, n, 3), np.float32)
    img[xx**2 + yy**2 <= (n / 2) ** 2] = bgr
    return Print(img, square_corners(centre, diameter))


@dataclass(frozen=True)
class LaserSpot:
    """A laser spot with its true centre.

    Attributes
    ----------
    u, v : float, true centre, px (OpenCV convention)
    sigma : float, Gaussian sigma along the major axis, px
    peak : float, peak irradiance in the laser's channel, in units of full scale
        (> 1 saturates)
    speckle : float, speckle contrast in [0, 1] (std / mean of the multiplicative pattern)
    grain : float, speckle grain size (correlation length), px
    aspect : float, minor / major sigma
    angle_deg : float, direction of the major axis, degrees from +u towards +v
    scatter : float, peak of the light the surface scatters under its skin (paper, matte plastic), as a
        fraction of ``peak``: a broad Gaussian wing, ``scatter_width`` times wider than the beam, that
        stays in the laser's channel when the beam itself clips (a phone's red halo)
    scatter_width : float, that wing's sigma over ``sigma``
    """

    u: float
    v: float
    sigma: float = 2.0
    peak: float = 0.7
    speckle: float = 0.0
    grain: float = 1.5
    aspect: float = 1.0
    angle_deg: float = 0.0
    scatter: float = 0.0
    scatter_width: float = 4.0


@dataclass(frozen=True)
class Glare:
    """A specular reflection of room light: white, additive, px and full-scale units."""

    u: float
    v: float
    sigma: float = 6.0
    peak: float = 2.0


LASER_RESPONSE = {  # camera response (B, G, R) to each laser, crosstalk of the Bayer filters
    "red": np.array([0.04, 0.10, 1.0]),
    "green": np.array([0.15, 1.0, 0.08]),
}


def tilted_spot(
    u: float, v: float, sigma: float, peak: float, tilt_deg: float, azimuth_deg: float = 0.0, **kw
) -> LaserSpot:
    """The spot of a round beam of ``sigma`` px meeting the paper ``tilt_deg`` off the normal.

    The footprint stretches by 1/cos(tilt) along the azimuth (degrees from +u towards
    +v) and its irradiance drops by cos(tilt); ``kw`` go to :class:`LaserSpot`.
    """
    c = np.cos(np.radians(tilt_deg))
    return LaserSpot(u, v, sigma / c, peak * c, aspect=c, angle_deg=azimuth_deg, **kw)


# Sensor level (after white balance) from which a phone's processing starts to desaturate highlights.
HIGHLIGHT_KNEE = 0.8


# A phone sensor's colour-correction matrix (camera RGB -> sRGB, rows sum to 1), in BGR order. Its
# negative terms are what turn a clipped red core with bloomed green/blue neighbours pink, not red.
PHONE_CCM = np.array([[1.55, -0.50, -0.05], [-0.30, 1.55, -0.25], [-0.05, -0.60, 1.65]], np.float32)


@dataclass(frozen=True)
class PhoneCamera:
    """A phone camera's processing, applied after the optics (see the module docstring).

    Attributes
    ----------
    bloom : float, fraction of a photosite's excess charge (over full well) spilt into
        its neighbours; 0 for none
    bloom_sigma : float, reach of the spill, px
    ccm : (3, 3) array, colour-correction matrix applied to BGR after white balance
    contrast : float in [0, 1), strength of the tone curve's S shape over the sRGB curve
    jpeg : int or None, JPEG quality with 4:2:0 chroma subsampling; None: lossless
    ae_target : float or None, auto exposure meters the scene: its median (green) is brought to
        this fraction of the clipping level; None: no metering (the light as given)
    ae_stops : float, and misses by 2**U(-ae_stops, ae_stops), a new draw for each photo
    highlight : float in [0, 1], highlight desaturation: a pixel whose brightest sensor channel nears
        clipping (over :data:`HIGHLIGHT_KNEE`) is blended towards white by up to this fraction, as
        phones' processing does where it can no longer know the colour; 0 for none. It widens the
        white core of a clipped spot and thins its coloured ring
    chroma_blur : float, px, sigma of the chroma noise reduction (a blur of Cr and Cb) before the JPEG;
        0 for none. It fades a thin coloured ring further
    """

    bloom: float = 0.4
    bloom_sigma: float = 1.2
    ccm: np.ndarray = field(default_factory=lambda: PHONE_CCM.copy())
    contrast: float = 0.3
    jpeg: int | None = 88
    ae_target: float | None = 0.45
    ae_stops: float = 0.5
    highlight: float = 0.0
    chroma_blur: float = 0.0

    def gain(self, seed: int) -> float:
        """The auto exposure's miss for the photo rendered with ``seed`` (multiplies all light)."""
        return float(2.0 ** np.random.default_rng([seed, 7]).uniform(-self.ae_stops, self.ae_stops))


@dataclass(frozen=True)
class Photo:
    """Everything needed to render one photo (see the module docstring for units)."""

    view: View
    prints: tuple = ()
    spots: tuple = ()
    glares: tuple = ()
    colour: str = "red"
    paper: float = 0.65
    tint: tuple = (0.85, 0.95, 1.0)  # room light (B, G, R): warm
    gradient: float = 0.0  # relative brightness change from the left to the right edge
    vignetting: float = 0.0  # relative brightness loss at the corners
    psf: float = 0.6  # lens blur sigma, px
    read_noise: float = 1.0  # DN
    shot_noise: float = 0.02  # variance per DN of signal, DN
    bloom: float = 0.0  # fraction of excess charge spilt into the neighbours
    bloom_sigma: float = 2.0  # px
    gamma: float = 1.0  # 2.2 for an sRGB-like camera JPEG
    jpeg: int | None = None  # JPEG quality, None for lossless
    camera: PhoneCamera | None = None  # a phone's pipeline; replaces bloom, bloom_sigma, gamma and jpeg
    background: np.ndarray | None = None  # (h, w, 3) reflectance, prints already pasted (:func:`reflectance`)
    response: tuple | None = None  # (B, G, R) response to the laser (cross-talk); None: LASER_RESPONSE
    # the paper's reflectance (B, G, R) relative to white, e.g. (0.25, 0.9, 0.95) yellow
    surface: tuple = (1.0, 1.0, 1.0)
    # The light (B, G, R) a phone camera white-balances for; None: the room light (tint) itself, a perfect
    # balance. A real camera's auto white balance estimates the room light and misses it by a few degrees,
    # which leaves a grey surface a few % off neutral.
    balance: tuple | None = None

    def truth(self) -> np.ndarray:
        """(n, 2) array of the spots' true centres, px."""
        return np.array([[s.u, s.v] for s in self.spots], float).reshape(-1, 2)


def _supersample(x0: int, y0: int, w: int, h: int, s: int) -> np.ndarray:
    """Sample points (h*s, w*s, 2) spread evenly over each pixel of a box, px."""
    offs = (np.arange(s) + 0.5) / s - 0.5
    xs = (x0 + np.arange(w)[:, None] + offs).ravel()
    ys = (y0 + np.arange(h)[:, None] + offs).ravel()
    return np.stack(np.meshgrid(xs, ys), -1)


def _paste(refl: np.ndarray, view: View, item: Print, blur: float) -> None:
    """Multiply the reflectance map by a print seen through a blur of ``blur`` px.

    The print is upsampled, blurred by the lens PSF combined with the pixel's box
    aperture, and sampled at each pixel centre: edges land at exact sub-pixel places.
    """
    h_img, w_img = refl.shape[:2]
    t = np.linspace(0, 1, 9)[:, None]
    c = item.corners_mm
    edges = np.concatenate([c[i] + t * (c[(i + 1) % 4] - c[i]) for i in range(4)])
    px = view.project(edges)
    pad_px = int(np.ceil(4 * blur)) + 2
    x0, y0 = np.maximum(np.floor(px.min(0)).astype(int) - pad_px, 0)
    x1, y1 = np.minimum(np.ceil(px.max(0)).astype(int) + pad_px + 1, [w_img, h_img])
    if x1 <= x0 or y1 <= y0:
        return
    th, tw = item.image.shape[:2]
    px_per_texel = np.linalg.norm(px[9] - px[0]) / tw
    up = max(1, int(np.ceil(8 * px_per_texel)))  # >= 8 samples per pixel
    pad = int(np.ceil(4 * blur * up / px_per_texel)) + 1
    img = item.image if item.image.ndim == 3 else item.image[..., None].repeat(3, -1)
    big = np.ones((th * up + 2 * pad, tw * up + 2 * pad, 3), np.float32)
    big[pad:-pad, pad:-pad] = img.repeat(up, 0).repeat(up, 1)
    big = cv2.GaussianBlur(big, (0, 0), blur * up / px_per_texel)
    grid = np.stack(np.meshgrid(np.arange(x0, x1), np.arange(y0, y1)), -1).reshape(-1, 2)
    T = cv2.getPerspectiveTransform(
        c.astype(np.float32),
        np.float32([[-0.5, -0.5], [tw - 0.5, -0.5], [tw - 0.5, th - 0.5], [-0.5, th - 0.5]]),
    )
    tex = cv2.perspectiveTransform(view.unproject(grid).reshape(-1, 1, 2), T).reshape(y1 - y0, x1 - x0, 2)
    tex = ((tex + 0.5) * up - 0.5 + pad).astype(np.float32)
    vals = cv2.remap(
        big,
        tex[..., 0],
        tex[..., 1],
        cv2.INTER_LINEAR,
        borderMode=cv2.BORDER_CONSTANT,
        borderValue=(1.0, 1.0, 1.0),
    )
    refl[y0:y1, x0:x1] *= vals


def reflectance(view: View, prints: tuple, psf: float = 0.6) -> np.ndarray:
    """The printed sheet's reflectance as seen through ``view``, (h, w, 3) float32: a photo's
    ``background`` when many photos share the prints and the view (the prints are pasted once)."""
    w, h = view.size
    refl = np.ones((h, w, 3), np.float32)
    for item in prints:
        _paste(refl, view, item, np.hypot(psf, np.sqrt(1 / 12)))  # PSF and pixel aperture
    return refl


def _spot_box(u, v, r, w, h):
    x0, y0 = max(int(np.floor(u - r)), 0), max(int(np.floor(v - r)), 0)
    return x0, y0, min(int(np.ceil(u + r)) + 1, w), min(int(np.ceil(v + r)) + 1, h)


def _gaussian(spot: LaserSpot, x0, y0, w, h, s: int = 5) -> np.ndarray:
    """Pixel-integrated elliptical Gaussian with unit peak, (h, w)."""
    p = _supersample(x0, y0, w, h, s) - [spot.u, spot.v]
    a = np.radians(spot.angle_deg)
    major = p @ [np.cos(a), np.sin(a)]
    minor = p @ [-np.sin(a), np.cos(a)]
    g = np.exp(-0.5 * ((major / spot.sigma) ** 2 + (minor / (spot.sigma * spot.aspect)) ** 2))
    return g.reshape(h, s, w, s).mean((1, 3))


def _speckle(shape, grain: float, contrast: float, rng) -> np.ndarray:
    """Multiplicative speckle with mean 1 and std ``contrast``, grain ``grain`` px."""
    field = rng.standard_normal(shape + (2,)).astype(np.float32)
    k = max(grain / 2, 0.3)
    field = cv2.GaussianBlur(field, (0, 0), k, borderType=cv2.BORDER_REFLECT)
    inten = (field**2).sum(-1)
    inten /= inten.mean()
    return 1 + contrast * (inten - 1)  # fully developed speckle (exponential) scaled to the contrast


def scene_light(photo: Photo, rng) -> np.ndarray:
    """The light reaching the sensor before any camera processing: (h, w, 3) float32 BGR, DN.

    Paper, prints, laser spots (their speckle drawn from ``rng``) and glares, before noise,
    auto exposure and clipping: the mean the camera then samples (as :func:`render` does).
    """
    w, h = photo.view.size
    refl = (
        np.ones((h, w, 3), np.float32) * np.float32(photo.surface)
        if photo.background is None
        else photo.background * np.float32(photo.surface)
    )
    for item in photo.prints:
        _paste(refl, photo.view, item, np.hypot(photo.psf, np.sqrt(1 / 12)))  # PSF and pixel aperture
    xs = np.linspace(-0.5, 0.5, w, dtype=np.float32)
    ys = np.linspace(-0.5, 0.5, h, dtype=np.float32) * (h / w)
    light = (1 + photo.gradient * xs)[None, :] * (
        1 - photo.vignetting * 2 * (xs[None, :] ** 2 + ys[:, None] ** 2)
    )
    img = refl * (FULL * photo.paper * light)[..., None] * np.float32(photo.tint)
    response = np.float32(LASER_RESPONSE[photo.colour] if photo.response is None else photo.response)
    for spot in photo.spots:
        # Out to where the tail (the scatter wing's, when there is one) falls below 1e-3 DN.
        reach = spot.sigma * (spot.scatter_width if spot.scatter > 0 else 1.0)
        r = reach * np.sqrt(2 * np.log(max(spot.peak * FULL, 2) / 1e-3)) + 2
        x0, y0, x1, y1 = _spot_box(spot.u, spot.v, r, w, h)
        if x1 <= x0 or y1 <= y0:
            continue
        g = _gaussian(spot, x0, y0, x1 - x0, y1 - y0) * (FULL * spot.peak)
        if spot.speckle > 0:
            g *= _speckle(g.shape, spot.grain, spot.speckle, rng)
        if spot.scatter > 0:  # light scattered under the surface: smooth (speckle averages out)
            wing = LaserSpot(
                spot.u, spot.v, spot.sigma * spot.scatter_width, 1.0, 0, 1.5, spot.aspect, spot.angle_deg
            )
            g += _gaussian(wing, x0, y0, x1 - x0, y1 - y0, 1) * (FULL * spot.peak * spot.scatter)
        # Laser light is reflected by the sheet like room light: ink under the spot absorbs it.
        img[y0:y1, x0:x1] += g[..., None] * response * refl[y0:y1, x0:x1]
    for gl in photo.glares:
        r = gl.sigma * np.sqrt(2 * np.log(max(gl.peak * FULL, 2) / 1e-3)) + 2
        x0, y0, x1, y1 = _spot_box(gl.u, gl.v, r, w, h)
        g = _gaussian(LaserSpot(gl.u, gl.v, gl.sigma), x0, y0, x1 - x0, y1 - y0) * (FULL * gl.peak)
        img[y0:y1, x0:x1] += g[..., None] * np.float32(photo.tint)
    return img


def render(photo: Photo, seed: int = 0) -> np.ndarray:
    """Render a photo.

    Parameters
    ----------
    photo : Photo
    seed : int, seed of the noise and speckle

    Returns
    -------
    (height, width, 3) uint8 BGR image
    """
    rng = np.random.default_rng(seed)
    img = scene_light(photo, rng)
    if photo.camera is not None:
        return _phone(img, photo, photo.camera, rng, seed)
    img += np.sqrt(photo.read_noise**2 + photo.shot_noise * np.maximum(img, 0)) * rng.standard_normal(
        img.shape, dtype=np.float32
    )
    if photo.bloom > 0:
        excess = np.maximum(img - FULL, 0)
        if excess.any():
            img += photo.bloom * cv2.GaussianBlur(excess, (0, 0), photo.bloom_sigma)
    np.clip(img, 0, FULL, out=img)
    if photo.gamma != 1:
        img = FULL * (img / FULL) ** (1 / photo.gamma)
    out = np.round(img).astype(np.uint8)
    if photo.jpeg is not None:
        _, buf = cv2.imencode(".jpg", out, [cv2.IMWRITE_JPEG_QUALITY, int(photo.jpeg)])
        out = cv2.imdecode(buf, cv2.IMREAD_COLOR)
    return out


def _tone(x: np.ndarray, contrast: float) -> np.ndarray:
    """Linear [0, 1] -> encoded [0, 1]: the sRGB curve blended with an S curve (monotonic)."""
    y = np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(np.maximum(x, 0.0031308), 1 / 2.4) - 0.055)
    return (1 - contrast) * y + contrast * y * y * (3 - 2 * y)


def _phone(img: np.ndarray, photo: Photo, cam: PhoneCamera, rng, seed: int) -> np.ndarray:
    """The phone pipeline from linear scene light (h, w, 3) DN to an 8-bit BGR photo."""
    h, w = img.shape[:2]
    gain = cam.gain(seed)
    if cam.ae_target is not None:
        gain *= cam.ae_target * FULL / max(float(np.median(img[::8, ::8, 1])), 1e-3)
    img *= np.float32(gain)
    # RGGB mosaic: R on even rows and columns, B on odd ones, G elsewhere (BGR indices).
    site = np.ones((h, w), np.intp)
    site[0::2, 0::2], site[1::2, 1::2] = 2, 0
    raw = np.take_along_axis(img, site[..., None], 2)[..., 0]
    raw += np.sqrt(photo.read_noise**2 + photo.shot_noise * np.maximum(raw, 0)) * rng.standard_normal(
        raw.shape, dtype=np.float32
    )
    if cam.bloom > 0:
        excess = np.maximum(raw - FULL, 0)
        if excess.any():
            raw += cam.bloom * cv2.GaussianBlur(excess, (0, 0), cam.bloom_sigma)
    raw16 = np.round(np.clip(raw, 0, FULL) * (65535 / FULL)).astype(np.uint16)
    rgb = cv2.cvtColor(raw16, cv2.COLOR_BayerBG2BGR).astype(np.float32) / 65535  # OpenCV's name for RGGB
    # White balance for the room light, scaled so that no gain is below 1: whatever clipped on
    # the sensor stays clipped (white) instead of turning a tint.
    wb = 1 / np.float32(photo.tint if photo.balance is None else photo.balance)
    rgb = np.minimum(rgb * (wb / wb.min()), 1.0)
    top = rgb.max(axis=2, keepdims=True)
    rgb = np.clip(rgb @ np.asarray(cam.ccm, np.float32).T, 0, 1)
    if cam.highlight > 0:
        near = np.clip((top - HIGHLIGHT_KNEE) / (1 - HIGHLIGHT_KNEE), 0, 1) ** 2 * np.float32(cam.highlight)
        rgb += near * (rgb.max(axis=2, keepdims=True) - rgb)
    out = np.round(255 * _tone(rgb, cam.contrast)).astype(np.uint8)
    if cam.chroma_blur > 0:
        ycc = cv2.cvtColor(out, cv2.COLOR_BGR2YCrCb)
        ycc[..., 1:] = cv2.GaussianBlur(ycc[..., 1:], (0, 0), cam.chroma_blur)
        out = cv2.cvtColor(ycc, cv2.COLOR_YCrCb2BGR)
    if cam.jpeg is not None:
        params = [
            cv2.IMWRITE_JPEG_QUALITY,
            int(cam.jpeg),
            cv2.IMWRITE_JPEG_SAMPLING_FACTOR,
            cv2.IMWRITE_JPEG_SAMPLING_FACTOR_420,
        ]
        _, buf = cv2.imencode(".jpg", out, params)
        out = cv2.imdecode(buf, cv2.IMREAD_COLOR)
    return out


def marker_sheet(
    view: View, side: float = 40.0, dictionary: str = "DICT_4X4_50", inset: float = 0.1, ids=(0, 1, 2, 3)
) -> dict:
    """Four markers near the corners of the photo, upright in it.

    Parameters
    ----------
    view : View
    side : float, marker side, mm
    dictionary : str, OpenCV dictionary name
    inset : float, marker centres at this fraction of the width/height from the photo's edges
    ids : 4 marker ids (top-left, top-right, bottom-right, bottom-left of the photo)

    Returns
    -------
    dict id -> (4, 2) corners mm (OpenCV order), for :func:`aruco_print` and the layout
    """
    w, h = view.size
    at = np.array([[inset, inset], [1 - inset, inset], [1 - inset, 1 - inset], [inset, 1 - inset]]) * [
        w - 1,
        h - 1,
    ]
    centres = view.unproject(at)
    right = view.unproject(at + [1, 0]) - centres  # the photo's +u on the plane
    angles = np.degrees(np.arctan2(right[:, 1], right[:, 0]))
    return {int(i): square_corners(c, side, a) for i, c, a in zip(ids, centres, angles)}


def marker_prints(corners: dict, dictionary: str = "DICT_4X4_50") -> tuple:
    """Prints of the markers ``{id: (4, 2) corners mm}``."""
    return tuple(aruco_print(dictionary, i, c) for i, c in corners.items())
