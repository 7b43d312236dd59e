"""Annotated PNGs so a person can check a measurement.

Drawn on the photo: the mm grid of the plane (blue, labelled in mm), the detected
markers (green outlines with ids; fiducials that disagree with the layout as red
crosses), each spot (magenta circle and cross, numbered) and, along the top and
clear of the corners, a zoomed inset of every spot with its sub-pixel centre.
Pixels in OpenCV's convention; lengths in mm.
"""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np

from lasercal.vision.detect import Spot
from lasercal.vision.images import upright, upright_points
from lasercal.vision.plane import PlaneMap

GRID, MARKER, OUTLIER, SPOT, TEXT = (255, 160, 0), (0, 200, 0), (0, 0, 255), (255, 0, 255), (20, 20, 20)


def _nice_step(span: float) -> float:
    """A round grid step giving ~10 lines over ``span`` mm."""
    raw = span / 10
    base = 10 ** np.floor(np.log10(raw))
    return float(min((s * base for s in (1, 2, 5, 10)), key=lambda s: abs(s - raw)))


def _label(img, text, org, scale, colour=TEXT):
    th = max(1, int(round(scale * 2)))
    cv2.putText(img, text, org, cv2.FONT_HERSHEY_SIMPLEX, scale, (255, 255, 255), th + 2, cv2.LINE_AA)
    cv2.putText(img, text, org, cv2.FONT_HERSHEY_SIMPLEX, scale, colour, th, cv2.LINE_AA)


def draw(
    img: np.ndarray,
    spots: list[Spot],
    plane: PlaneMap | None = None,
    title: str = "",
    convention: str = "opencv",
    orientation: int = 1,
) -> np.ndarray:
    """Return an annotated BGR uint8 copy of ``img``, turned upright as a viewer shows it.

    Parameters
    ----------
    img : (h, w, 3) BGR or (h, w) grey array, uint8 or uint16, in the stored pixel grid
    spots : list of Spot
    plane : PlaneMap or None, for the mm grid and the markers
    title : str, first line of the header
    convention : "opencv" or "imagej", for the pixel coordinates printed
    orientation : int, the photo's EXIF orientation (1-8, see ``images.exif_orientation``): the
        overlay is turned upright, while the printed coordinates stay in the stored grid
    """
    out = img if img.dtype == np.uint8 else (img >> 8).astype(np.uint8)
    out = cv2.cvtColor(out, cv2.COLOR_GRAY2BGR) if out.ndim == 2 else out.copy()
    out = np.ascontiguousarray(upright(out, orientation))

    def shown(uv) -> np.ndarray:
        """Stored-grid px -> px in the upright overlay."""
        return upright_points(np.reshape(uv, (-1, 2)), img.shape, orientation)

    sh, sw = img.shape[:2]
    h, w = out.shape[:2]
    k = max(w, h) / 1000  # line widths and text grow with the photo
    t = max(1, int(round(k)))
    fs = 0.45 * k
    if plane is not None:
        edge = np.array([[0, 0], [sw - 1, 0], [sw - 1, sh - 1], [0, sh - 1]], float)
        xy = plane.to_plane(edge)
        lo, hi = xy.min(0), xy.max(0)
        step = _nice_step(max(hi - lo))
        for axis in (0, 1):
            for val in np.arange(np.ceil(lo[axis] / step) * step, hi[axis] + 1e-9, step):
                s = np.linspace(lo[1 - axis], hi[1 - axis], 100)
                line = np.column_stack([np.full_like(s, val), s] if axis == 0 else [s, np.full_like(s, val)])
                px = shown(plane.to_image(line))
                cv2.polylines(out, [np.round(px).astype(np.int32)], False, GRID, max(1, t // 2), cv2.LINE_AA)
                ok = (px[:, 0] >= 0) & (px[:, 0] < w) & (px[:, 1] >= 0) & (px[:, 1] < h)
                if ok.any():
                    # Label x lines at the bottom edge, y lines at the left edge, inside the photo.
                    u, v = px[ok][np.argmax(px[ok, 1])] if axis == 0 else px[ok][np.argmin(px[ok, 0])]
                    org = (int(np.clip(u + 3 * t, 0, w - 90 * k)), int(np.clip(v - 4 * t, 20 * k, h - 6 * k)))
                    _label(out, f"{'x' if axis == 0 else 'y'}={val:g}", org, fs, GRID)
        fid = plane.fiducials
        for mid, c in zip(fid.marker_ids, fid.marker_corners):
            c = shown(c)
            cv2.polylines(out, [np.round(c).astype(np.int32)], True, MARKER, 2 * t, cv2.LINE_AA)
            cv2.circle(out, tuple(np.round(c[0]).astype(int)), 4 * t, MARKER, -1)  # corner 0
            _label(out, f"id {mid}", tuple(np.round(c.mean(0)).astype(int)), 1.2 * fs, MARKER)
        for u, v in shown(fid.image[~plane.inliers]):
            cv2.drawMarker(
                out, (int(round(u)), int(round(v))), OUTLIER, cv2.MARKER_TILTED_CROSS, 12 * t, 2 * t
            )
    shift = 0.5 if convention == "imagej" else 0.0
    for n, s in enumerate(spots, 1):
        c = tuple(int(round(x)) for x in shown([s.u, s.v])[0])
        r = int(round(3 * np.sqrt(s.area / np.pi) + 6 * t))
        cv2.circle(out, c, r, SPOT, t, cv2.LINE_AA)
        cv2.drawMarker(out, c, SPOT, cv2.MARKER_CROSS, r // 2, t)
        txt = f"#{n} ({s.u + shift:.2f}, {s.v + shift:.2f}) px"
        if s.x_mm is not None:
            txt += f"  ({s.x_mm:.2f}, {s.y_mm:.2f}) mm"
        _label(out, txt, (c[0] + r + 3 * t, c[1] - r), fs, SPOT)
    _insets(out, upright(img, orientation), [shown([s.u, s.v])[0] for s in spots], spots, k)
    lines = [title]
    if plane is not None:
        fid = plane.fiducials
        lines.append(
            f"{len(fid.marker_ids)} markers, {fid.charuco} ChArUco corners, fit RMS {plane.rms_mm:.3f} mm, "
            f"{plane.mm_per_px:.3f} mm/px, {int((~plane.inliers).sum())} outliers"
        )
    y0 = int(round((220 if spots else 30) * k))
    for i, line in enumerate(ln for ln in lines if ln):
        _label(out, line, (int(10 * k), y0 + int(i * 24 * k)), 1.2 * fs)
    return out


def _insets(out: np.ndarray, img: np.ndarray, centres: list, spots: list[Spot], k: float) -> None:
    """Zoomed crops of the spots along the top edge, centre marked at sub-pixel accuracy.

    ``img`` and ``centres`` (px) are in the overlay's (upright) frame."""
    side = int(round(180 * k)) | 1  # odd: the centre pixel is the middle one
    x = int(round(0.15 * out.shape[1]))  # clear of a marker in the top-left corner
    src = img if img.dtype == np.uint8 else (img >> 8).astype(np.uint8)
    src = cv2.cvtColor(src, cv2.COLOR_GRAY2BGR) if src.ndim == 2 else src
    for n, (s, (cu, cv)) in enumerate(zip(spots[:8], centres), 1):
        half = max(8, int(round(2.5 * np.sqrt(s.area / np.pi) + 4)))
        zoom = side / (2 * half + 1)
        # Affine crop keeps the sub-pixel centre exactly in the middle of the inset.
        c = side // 2
        M = np.float32([[zoom, 0, c - zoom * cu], [0, zoom, c - zoom * cv]])
        crop = cv2.warpAffine(src, M, (side, side), flags=cv2.INTER_NEAREST, borderMode=cv2.BORDER_CONSTANT)
        cv2.line(crop, (c, 0), (c, side), SPOT, 1)
        cv2.line(crop, (0, c), (side, c), SPOT, 1)
        cv2.rectangle(crop, (0, 0), (side - 1, side - 1), SPOT, 2)
        _label(crop, f"#{n}", (6, int(22 * k)), 0.6 * k, SPOT)
        if x + side > out.shape[1] or int(10 * k) + side > out.shape[0]:
            break
        out[int(10 * k) : int(10 * k) + side, x : x + side] = crop
        x += side + int(round(10 * k))


def write(path, img: np.ndarray) -> Path:
    """Write a PNG, creating the folder."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    if not cv2.imwrite(str(path), img):
        from lasercal.vision.errors import VisionError

        raise VisionError(f"{path}: cannot write the overlay PNG")
    return path
