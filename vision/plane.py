"""From pixels to millimetres on the table plane, with printed ArUco/ChArUco fiducials.

Units: image points in pixels (OpenCV convention, recorded, i.e. with lens
distortion unless a camera is given); plane points in mm in the layout's frame: the
robot base frame (x, y on the plane whose height is the layout's ``plane.z``), or with
``frame: sheet`` a printed sheet's own frame (``lasercal sheet``; see vision/sheet.py).

The layout's ``markers`` section (``format: lasercal-layout/1``; other sections
are ignored here)::

    markers:
      dictionary: DICT_4X4_50        # an OpenCV predefined dictionary
      min_markers: 3                 # optional: markers needed (default min(3, listed))
      ids:                           # per marker id: its 4 outer corners, mm, layout frame,
        0: [[x, y], [x, y], [x, y], [x, y]]  # in OpenCV's order: top-left, top-right,
        1: ...                                # bottom-right, bottom-left of the printed marker
      charuco:                       # optional ChArUco board (corners ~3x more precise)
        dictionary: DICT_5X5_100     # optional, default the markers' dictionary
        squares: [7, 5]              # squares along the board's x and y
        square: 30.0                 # square side, mm
        marker: 22.0                 # marker side, mm
        origin: [300, 150]           # board's outer top-left corner, mm, base frame
        x_axis: [1, 0]               # board's +x (to the right on the print), base frame
        y_axis: [0, -1]              # board's +y (down on the print), base frame
        first_id: 0                  # optional: id of the board's first marker
        legacy: false                # optional: OpenCV < 4.6 board pattern

Seen from above, OpenCV's corner order runs clockwise; the corners are checked for it.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from lasercal.vision.camera import Camera, aruco_dictionary, distort, read_yaml
from lasercal.vision.errors import LayoutError, MarkerError

# marker corners all closer than this to the sheet's origin are in metres, not mm (as in solver's checks)
METRES_BELOW_MM = 5.0

_trapezoid = getattr(np, "trapezoid", None) or np.trapz  # renamed in numpy 2.0
LAYOUT_FORMAT = "lasercal-layout/1"
FRAMES = ("base", "sheet")  # a layout's frame: the robot's base, or a printed sheet's own
RANSAC_MM = 2.0  # a corner further than this from its layout position is an outlier, mm


def distort_px(uv: np.ndarray, camera) -> np.ndarray:
    """Ideal pixels back to recorded pixels (identity without a camera)."""
    return uv if camera is None else distort(uv, camera.K, camera.dist)


@dataclass(frozen=True)
class CharucoLayout:
    """A ChArUco board on the sheet (see the module docstring; lengths in mm)."""

    dictionary: str
    squares: tuple[int, int]
    square: float
    marker: float
    origin: np.ndarray
    x_axis: np.ndarray
    y_axis: np.ndarray
    first_id: int = 0
    legacy: bool = False

    def board(self):
        """The OpenCV ``CharucoBoard``."""
        n = (self.squares[0] * self.squares[1]) // 2
        b = cv2.aruco.CharucoBoard(
            self.squares,
            self.square,
            self.marker,
            aruco_dictionary(self.dictionary),
            np.arange(self.first_id, self.first_id + n, dtype=np.int32),
        )
        b.setLegacyPattern(self.legacy)
        return b

    def marker_ids(self) -> range:
        return range(self.first_id, self.first_id + (self.squares[0] * self.squares[1]) // 2)

    def to_base(self, board_xy: np.ndarray) -> np.ndarray:
        """Board coordinates (n, 2) mm -> base frame (n, 2) mm."""
        return self.origin + board_xy[:, :1] * self.x_axis + board_xy[:, 1:2] * self.y_axis


@dataclass(frozen=True)
class MarkerLayout:
    """The ``markers`` section of a layout.

    Attributes
    ----------
    path : str, the layout file
    dictionary : str, OpenCV dictionary name
    corners : dict int -> (4, 2) array, mm, base frame, OpenCV corner order
    min_markers : int, markers needed in a photo (a ChArUco board counts as enough)
    charuco : CharucoLayout or None
    plane_z : float or None, the layout's ``plane.z``, mm
    frame : str, the frame of the corners (and so of the mm measured): 'base' or 'sheet'
    """

    path: str
    dictionary: str
    corners: dict
    min_markers: int
    charuco: CharucoLayout | None = None
    plane_z: float | None = None
    frame: str = "base"


def _vec(value, n, path, field):
    try:
        a = np.array(value, float)
    except (TypeError, ValueError):
        a = None
    if a is None or a.shape != (n,) or not np.all(np.isfinite(a)):
        raise LayoutError(path, f"expected {n} numbers", field)
    return a


def _parse_charuco(c, default_dict, path) -> CharucoLayout:
    f = "markers.charuco"
    if not isinstance(c, dict):
        raise LayoutError(path, "expected a mapping", f)
    for key in ("squares", "square", "marker", "origin", "x_axis", "y_axis"):
        if key not in c:
            raise LayoutError(path, "missing", f"{f}.{key}")
    squares = _vec(c["squares"], 2, path, f"{f}.squares")
    if np.any(squares < 2) or np.any(squares != np.round(squares)):
        raise LayoutError(path, "expected two whole numbers >= 2", f"{f}.squares")
    square = float(_vec([c["square"]], 1, path, f"{f}.square")[0])
    marker = float(_vec([c["marker"]], 1, path, f"{f}.marker")[0])
    if not 0 < marker < square:
        raise LayoutError(
            path,
            f"marker side {marker} mm must be positive and below the square side {square} mm",
            f"{f}.marker",
        )
    x_axis, y_axis = _vec(c["x_axis"], 2, path, f"{f}.x_axis"), _vec(c["y_axis"], 2, path, f"{f}.y_axis")
    if (
        abs(np.linalg.norm(x_axis) - 1) > 1e-3
        or abs(np.linalg.norm(y_axis) - 1) > 1e-3
        or abs(x_axis @ y_axis) > 1e-3
    ):
        raise LayoutError(path, "x_axis and y_axis must be orthogonal unit vectors", f"{f}.x_axis")
    name = c.get("dictionary", default_dict)
    aruco_dictionary(name, path, f"{f}.dictionary")
    return CharucoLayout(
        name,
        (int(squares[0]), int(squares[1])),
        square,
        marker,
        _vec(c["origin"], 2, path, f"{f}.origin"),
        x_axis,
        y_axis,
        int(c.get("first_id", 0)),
        bool(c.get("legacy", False)),
    )


def load_markers(path) -> MarkerLayout | None:
    """Read the ``markers`` section of a layout YAML; None when it has none.

    Raises
    ------
    LayoutError
        Missing file, bad YAML or a malformed ``markers`` section (names the field).
    """
    path = Path(path)
    doc = read_yaml(path, "layout")
    if not isinstance(doc, dict):
        raise LayoutError(path, "expected a mapping at the top level")
    if doc.get("format", LAYOUT_FORMAT) != LAYOUT_FORMAT:
        raise LayoutError(path, f"expected '{LAYOUT_FORMAT}'", "format")
    units = doc.get("units") or {}
    if isinstance(units, dict) and units.get("length", "mm") != "mm":
        raise LayoutError(path, "only mm is supported", "units.length")
    frame = doc.get("frame") or "base"
    if frame not in FRAMES:
        raise LayoutError(path, f"{frame!r} (expected 'base' or 'sheet')", "frame")
    m = doc.get("markers")
    if m is None:
        return None
    if not isinstance(m, dict):
        raise LayoutError(path, "expected a mapping", "markers")
    if "dictionary" not in m:
        raise LayoutError(path, "missing", "markers.dictionary")
    aruco_dictionary(m["dictionary"], path)
    ids = m.get("ids") or {}
    if not isinstance(ids, dict):
        raise LayoutError(path, "expected a mapping of marker id -> 4 corners", "markers.ids")
    corners = {}
    for key, value in ids.items():
        field = f"markers.ids.{key}"
        try:
            mid = int(key)
        except (TypeError, ValueError):
            raise LayoutError(path, "marker ids are whole numbers", field) from None
        try:
            c = np.array(value, float)
        except (TypeError, ValueError):
            c = None
        if c is None or c.shape != (4, 2) or not np.all(np.isfinite(c)):
            raise LayoutError(path, "expected 4 corners [[x, y], ...] in mm", field)
        x, y = c.T
        area = 0.5 * (x @ np.roll(y, -1) - y @ np.roll(x, -1))  # > 0 counter-clockwise (y up)
        if area >= 0:
            raise LayoutError(
                path,
                "corners must run clockwise seen from above (OpenCV's order: top-left, "
                "top-right, bottom-right, bottom-left)",
                field,
            )
        corners[mid] = c
    if corners and np.abs(np.concatenate(list(corners.values()))).max() < METRES_BELOW_MM:
        raise LayoutError(
            path,
            f"every corner is within {METRES_BELOW_MM:g} mm: these look like metres (expected mm)",
            "markers.ids",
        )
    charuco = _parse_charuco(m["charuco"], m["dictionary"], path) if m.get("charuco") is not None else None
    if charuco is None and not corners:
        raise LayoutError(path, "no markers listed", "markers.ids")
    if charuco is not None and charuco.dictionary == m["dictionary"]:
        shared = sorted(set(corners) & set(charuco.marker_ids()))
        if shared:
            raise LayoutError(path, f"ids {shared} are also markers of the ChArUco board", "markers.ids")
    default_min = max(1, min(3, len(corners)))
    try:
        min_markers = int(m.get("min_markers", default_min))
    except (TypeError, ValueError):
        raise LayoutError(path, "expected a whole number", "markers.min_markers") from None
    if not 1 <= min_markers <= max(len(corners), 1):
        raise LayoutError(
            path, f"must be between 1 and the {len(corners)} markers listed", "markers.min_markers"
        )
    plane = doc.get("plane") or {}
    try:
        plane_z = float(plane["z"]) if isinstance(plane, dict) and "z" in plane else None
    except (TypeError, ValueError):
        raise LayoutError(path, "expected a number, mm", "plane.z") from None
    return MarkerLayout(str(path), m["dictionary"], corners, min_markers, charuco, plane_z, frame)


def _detector(dictionary: str):
    params = cv2.aruco.DetectorParameters()
    params.cornerRefinementMethod = cv2.aruco.CORNER_REFINE_SUBPIX
    return cv2.aruco.ArucoDetector(aruco_dictionary(dictionary), params)


def _edge_line(gray: np.ndarray, a: np.ndarray, b: np.ndarray, outward: np.ndarray, reach: float, camera):
    """Sub-pixel points of a dark-to-light edge from ``a`` to ``b``, as an ideal-pixel line.

    Each profile across the edge locates it by area: for a blurred step from the
    dark level ``lo`` to the light level ``hi`` over ``[-r, r]``, the integral of
    ``(I - lo) / (hi - lo)`` is ``r - x_edge``. Symmetric blur does not move it.

    Returns
    -------
    (point (2,), direction (2,)) of the fitted line in ideal px, or None
    """
    length = np.linalg.norm(b - a)
    t = np.arange(0.15 * length, 0.85 * length, 1.0) / length
    if len(t) < 5:
        return None
    s = np.arange(-reach, reach + 1e-9, 0.25)
    base = a + t[:, None] * (b - a)
    pts = base[:, None, :] + s[None, :, None] * outward
    prof = cv2.remap(
        gray,
        pts[..., 0].astype(np.float32),
        pts[..., 1].astype(np.float32),
        cv2.INTER_LINEAR,
        borderMode=cv2.BORDER_REPLICATE,
    ).astype(float)
    k = max(2, len(s) // 6)
    lo, hi = prof[:, :k].mean(1), prof[:, -k:].mean(1)
    ok = hi - lo > 20
    if ok.sum() < 5:
        return None
    frac = np.clip((prof[ok] - lo[ok, None]) / (hi - lo)[ok, None], 0, 1)
    x_edge = reach - _trapezoid(frac, s, axis=1)
    edge = base[ok] + x_edge[:, None] * outward
    if camera is not None:
        edge = camera.undistort(edge)
    for _ in range(2):  # total least squares, then once more without outliers
        c = edge.mean(0)
        _, _, vt = np.linalg.svd(edge - c)
        dist = (edge - c) @ vt[1]
        keep = np.abs(dist) <= max(3 * 1.4826 * np.median(np.abs(dist)), 0.05)
        if keep.all() or keep.sum() < 5:
            break
        edge = edge[keep]
    return c, vt[0]


def _refine_marker_corners(gray: np.ndarray, corners: np.ndarray, cells: int, camera) -> np.ndarray:
    """Corners of ArUco markers as intersections of lines fitted to their outer edges.

    OpenCV's sub-pixel refinement pulls a convex corner ~0.15 px into the marker;
    edges fitted over their whole length and intersected do not. A corner that would
    move by more than 1.5 px keeps OpenCV's value.

    Parameters
    ----------
    gray : (h, w) linear grey image
    corners : (k, 4, 2) array, recorded px, OpenCV order
    cells : int, marker cells per side including the black border
    camera : Camera or None, to fit straight lines in ideal pixels
    """
    out = corners.copy()
    for m, c in enumerate(corners):
        centre = c.mean(0)
        side = np.mean(np.linalg.norm(np.roll(c, -1, 0) - c, axis=1))
        reach = min(4.0, 0.3 * side / cells)  # stay within the black border cell
        if reach < 1.5:
            continue
        lines = []
        for i in range(4):
            a, b = c[i], c[(i + 1) % 4]
            d = (b - a) / np.linalg.norm(b - a)
            n = np.array([d[1], -d[0]])
            n = n if n @ ((a + b) / 2 - centre) > 0 else -n
            lines.append(_edge_line(gray, a, b, n, reach, camera))
        if any(line is None for line in lines):
            continue
        ideal = []
        for i in range(4):  # corner i joins the edges (i-1 -> i) and (i -> i+1)
            (p1, d1), (p2, d2) = lines[i - 1], lines[i]
            A = np.column_stack([d1, -d2])
            if abs(np.linalg.det(A)) < 1e-6:
                break
            t = np.linalg.solve(A, p2 - p1)
            ideal.append(p1 + t[0] * d1)
        if len(ideal) < 4:
            continue
        ideal = np.array(ideal)
        new = distort_px(ideal, camera)
        if np.all(np.linalg.norm(new - c, axis=1) < 1.5):
            out[m] = new
    return out


def _refine_saddles(gray: np.ndarray, img: np.ndarray, obj: np.ndarray, ch: CharucoLayout) -> np.ndarray:
    """Re-refine ChArUco corners with a window that fills the gap to the markers.

    The detector's own refinement leaves ~0.2 px; a window as large as the white
    gap between a corner and the nearest marker reaches ~0.03 px on saddle points.
    """
    if len(img) < 3:
        return img
    hull_px = cv2.contourArea(cv2.convexHull(img.astype(np.float32)))
    hull_mm = cv2.contourArea(cv2.convexHull(obj.astype(np.float32)))
    if hull_mm <= 0 or hull_px <= 0:
        return img
    gap_px = (ch.square - ch.marker) / 2 * np.sqrt(hull_px / hull_mm)
    win = int(np.clip(0.6 * gap_px, 2, 10))
    crit = (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_COUNT, 100, 1e-4)
    out = cv2.cornerSubPix(gray, img.astype(np.float32).reshape(-1, 1, 2), (win, win), (-1, -1), crit)
    return out.reshape(-1, 2).astype(float)


@dataclass(frozen=True)
class Fiducials:
    """Fiducial points found in one photo.

    Attributes
    ----------
    image : (n, 2) array, recorded px
    plane : (n, 2) array, mm, base frame
    marker_ids : tuple of int, layout markers found
    marker_corners : (k, 4, 2) array, px, their corners
    charuco : int, ChArUco corners found
    unknown_ids : tuple of int, markers seen that the layout does not list
    """

    image: np.ndarray
    plane: np.ndarray
    marker_ids: tuple
    marker_corners: np.ndarray
    charuco: int
    unknown_ids: tuple


def linearise(gray: np.ndarray, gamma: float) -> np.ndarray:
    """Undo a camera's gamma encoding (uint8 in, uint8 out).

    Corner refinement finds edges by their gradients; on gamma-encoded photos the
    blurred edges are skewed and the corners land ~0.5 px inside a black marker.
    """
    if gamma == 1:
        return gray
    lut = np.round(255 * (np.arange(256) / 255) ** gamma).astype(np.uint8)
    return cv2.LUT(gray, lut)


def find_fiducials(
    gray: np.ndarray,
    layout: MarkerLayout,
    gamma: float = 2.2,
    camera: Camera | None = None,
    refine_edges: bool = True,
) -> Fiducials:
    """Detect the layout's markers (and ChArUco corners) in a grey photo.

    Parameters
    ----------
    gray : (h, w) uint8 array
    layout : MarkerLayout
    gamma : float, the photo's encoding gamma (2.2 for camera JPEGs, 1 for linear data)
    camera : Camera or None, lens model (marker edges are straight in ideal pixels)
    refine_edges : bool, refine ArUco corners by fitting their edges (else OpenCV's sub-pixel corners)
    """
    gray = linearise(gray, gamma)
    dictionary = aruco_dictionary(layout.dictionary)
    corners, ids, _ = _detector(layout.dictionary).detectMarkers(gray)
    ids = np.asarray(ids if ids is not None else [], int).reshape(-1)  # (N, 1) in 4.x, (N,) in 5.x
    corners = np.asarray(corners, float).reshape(-1, 4, 2)
    if refine_edges and len(corners):
        corners = _refine_marker_corners(gray, corners, dictionary.markerSize + 2, camera)
    board_ids = (
        set(layout.charuco.marker_ids())
        if layout.charuco and layout.charuco.dictionary == layout.dictionary
        else set()
    )
    counts = {i: int((ids == i).sum()) for i in set(ids.tolist())}
    # A duplicated id cannot be told apart: drop it rather than guess.
    keep = sorted(
        (k for k, i in enumerate(ids) if i in layout.corners and counts[i] == 1), key=lambda k: ids[k]
    )
    unknown = tuple(sorted({int(i) for i in ids if i not in layout.corners and i not in board_ids}))
    img_pts = [corners[keep].reshape(-1, 2)]
    plane_pts = [np.concatenate([layout.corners[int(ids[k])] for k in keep]) if keep else np.zeros((0, 2))]
    n_charuco = 0
    if layout.charuco is not None:
        board = layout.charuco.board()
        cc, cids, _, _ = cv2.aruco.CharucoDetector(board).detectBoard(gray)
        if cids is not None and len(cids):
            cids = np.asarray(cids, int).reshape(-1)  # (N, 1) in 4.x, (N,) in 5.x
            obj = board.getChessboardCorners()[cids, :2]
            img_pts.append(_refine_saddles(gray, np.asarray(cc, float).reshape(-1, 2), obj, layout.charuco))
            plane_pts.append(layout.charuco.to_base(obj))
            n_charuco = len(cids)
    return Fiducials(
        np.concatenate(img_pts),
        np.concatenate(plane_pts),
        tuple(int(ids[k]) for k in keep),
        corners[keep],
        n_charuco,
        unknown,
    )


@dataclass(frozen=True)
class PlaneMap:
    """Homography from a photo to the table plane.

    Attributes
    ----------
    H : (3, 3) array, ideal (undistorted) px -> mm
    camera : Camera or None, lens model applied before H
    rms_mm : float, RMS reprojection error of the inlier fiducials on the plane, mm
    max_mm : float, largest inlier reprojection error, mm
    inliers : (n,) bool array, fiducials that agree with the layout
    fiducials : Fiducials
    mm_per_px : float, scale at the image centre, mm / px
    """

    H: np.ndarray
    camera: Camera | None
    rms_mm: float
    max_mm: float
    inliers: np.ndarray
    fiducials: Fiducials
    mm_per_px: float

    def _ideal(self, uv):
        uv = np.asarray(uv, float).reshape(-1, 2)
        return self.camera.undistort(uv) if self.camera is not None else uv

    def to_plane(self, uv: np.ndarray) -> np.ndarray:
        """Recorded pixels (n, 2) px -> plane (n, 2) mm."""
        return cv2.perspectiveTransform(self._ideal(uv).reshape(-1, 1, 2), self.H).reshape(-1, 2)

    def to_image(self, xy: np.ndarray) -> np.ndarray:
        """Plane points (n, 2) mm -> recorded pixels (n, 2) px."""
        uv = cv2.perspectiveTransform(np.asarray(xy, float).reshape(-1, 1, 2), np.linalg.inv(self.H)).reshape(
            -1, 2
        )
        return distort_px(uv, self.camera)

    def jacobian(self, uv: np.ndarray, h: float = 0.5) -> np.ndarray:
        """d(mm)/d(px) at recorded pixels: (n, 2, 2), by central differences."""
        uv = np.asarray(uv, float).reshape(-1, 2)
        cols = [(self.to_plane(uv + d) - self.to_plane(uv - d)) / (2 * h) for d in ([h, 0], [0, h])]
        return np.stack(cols, -1)

    def sigma_mm(self, uv: np.ndarray, sigma_uv: np.ndarray) -> np.ndarray:
        """1-sigma plane errors (n, 2) mm of points with pixel errors (n, 2) px.

        The centroid's error is mapped through the local scale. The homography's own error adds in
        quadrature, per axis, as its mean over the k inlier fiducials it was fitted to (eq. P1)

            var_H = s^2 p / (2 k),   s^2 = k rms^2 / (2 k - p),   p = 8,

        s^2 the misfit's variance per coordinate (rms is the RMS of the misfit's length, over 2 k
        coordinates less the fit's p parameters) and p / (2 k) the mean leverage of a coordinate (the
        hat matrix's trace over its size). It replaced rms^2 8 / k, which took a length's square for one
        axis's: 1.8x too large with 24 fiducials (the fake camera's stated sigma 1.6x too large with
        its paper bent and its lens corrected by an estimate, where the misfit is 0.09 mm).
        """
        J = self.jacobian(uv)
        cov = np.einsum("nij,nj,nkj->nik", J, np.asarray(sigma_uv, float) ** 2, J)
        k = int(self.inliers.sum())
        fit = self.rms_mm**2 * (2 / (k - 4) if k > 4 else 1.0)  # eq. P1: k rms^2 / (2 k - 8) * 8 / (2 k)
        return np.sqrt(np.diagonal(cov, axis1=1, axis2=2) + fit)

    def inside(self, uv: np.ndarray) -> np.ndarray:
        """(n,) bool: recorded pixels inside the hull of the inlier fiducials."""
        hull = cv2.convexHull(self.fiducials.image[self.inliers].astype(np.float32))
        return np.array(
            [
                cv2.pointPolygonTest(hull, (float(u), float(v)), False) >= 0
                for u, v in np.asarray(uv, float).reshape(-1, 2)
            ]
        )


def fit_plane(
    fid: Fiducials, layout: MarkerLayout, camera: Camera | None, size: tuple[int, int], name: str = "image"
) -> PlaneMap:
    """Homography from the fiducials (RANSAC over all corners, refined on the inliers).

    Parameters
    ----------
    fid : Fiducials
    layout : MarkerLayout
    camera : Camera or None
    size : (width, height) of the photo, px
    name : the photo's name for messages

    Raises
    ------
    MarkerError
        Fewer markers than the layout's ``min_markers`` (and no ChArUco board), or
        too few fiducials agreeing with the layout.
    """
    enough_charuco = fid.charuco >= 6
    if len(fid.marker_ids) < layout.min_markers and not enough_charuco:
        seen = f" (ids {', '.join(map(str, fid.marker_ids))})" if fid.marker_ids else ""
        extra = f"; unknown ids seen: {', '.join(map(str, fid.unknown_ids))}" if fid.unknown_ids else ""
        board = f" and {fid.charuco} ChArUco corners" if layout.charuco is not None else ""
        raise MarkerError(
            f"{name}: found {len(fid.marker_ids)} of the {len(layout.corners)} markers of "
            f"{layout.path}{seen}{board}; at least {layout.min_markers} needed{extra}"
        )
    ideal = camera.undistort(fid.image) if camera is not None else fid.image
    H, mask = cv2.findHomography(ideal, fid.plane, cv2.RANSAC, RANSAC_MM, maxIters=5000, confidence=0.999)
    if H is None or mask is None or mask.sum() < 4:
        raise MarkerError(
            f"{name}: the markers' corners do not agree with {layout.path} (no consistent homography)"
        )
    inl = mask.ravel().astype(bool)
    # Refine on the inliers by least squares: RANSAC's model leans on a minimal sample.
    H, _ = cv2.findHomography(ideal[inl], fid.plane[inl], 0)
    res = np.linalg.norm(
        cv2.perspectiveTransform(ideal.reshape(-1, 1, 2), H).reshape(-1, 2) - fid.plane, axis=1
    )
    pm = PlaneMap(H, camera, float(np.sqrt(np.mean(res[inl] ** 2))), float(res[inl].max()), inl, fid, 0.0)
    c = np.array([[(size[0] - 1) / 2, (size[1] - 1) / 2]])
    scale = float(np.sqrt(abs(np.linalg.det(pm.jacobian(c)[0]))))
    return PlaneMap(H, camera, pm.rms_mm, pm.max_mm, inl, fid, scale)


# A lens is fitted to the markers (without a camera YAML) only from this many inlier fiducials (four
# markers' corners: 32 coordinates for the homography's 8 parameters and the lens' 2), when the plane fit
# misses them by LENS_MISFIT_PX or more (an edge-fitted corner errs by ~0.02 px on the renderer), and when
# the lens brings the median corner's miss down LENS_GAIN times: a sheet that is not flat, or a print out of
# scale, is no lens and does not give way to one.
LENS_MIN_FIDUCIALS = 16
LENS_MISFIT_PX = 0.1
LENS_GAIN = 3.0
LENS_K2_ALPHA = 1e-3  # k2 is fitted only when an F test tells it from k1 at this level


@dataclass(frozen=True)
class FittedLens:
    """A radial lens fitted to one photo's markers (:func:`fit_lens`).

    Attributes
    ----------
    camera : Camera, the lens (k1, k2; principal point at the photo's centre)
    cov : (2, 2) array, covariance of k1, k2 from the fit's residuals
    """

    camera: Camera
    cov: np.ndarray

    def sigma_mm(self, fid: Fiducials, inliers: np.ndarray, uv: np.ndarray) -> np.ndarray:
        """1-sigma plane errors (n, 2) mm of recorded pixels ``uv`` from the lens' own uncertainty: the
        map through k1, k2 moved by +- each principal axis of :attr:`cov`, its homography refitted to
        the markers each time (markers in four clusters at one distance from the centre leave a
        direction of k1, k2 that moves them little and the sheet's middle more)."""
        k = self.camera.dist[:2]
        vals, vecs = np.linalg.eigh(self.cov)
        var = np.zeros((len(uv), 2))
        for lam, vec in zip(vals, vecs.T):
            d = np.sqrt(max(lam, 0.0)) * vec
            var += (
                (
                    _lens_map(self.camera, k + d, fid, inliers, uv)
                    - _lens_map(self.camera, k - d, fid, inliers, uv)
                )
                / 2
            ) ** 2
        return np.sqrt(var)


def _lens_map(cam: Camera, k: np.ndarray, fid: Fiducials, inliers: np.ndarray, uv: np.ndarray) -> np.ndarray:
    """Recorded pixels (n, 2) -> plane mm through the lens ``cam`` with k1, k2 = ``k`` and the homography
    fitted through it to the inlier fiducials."""
    lens = Camera(cam.size, cam.K, np.array([k[0], k[1], 0, 0, 0.0]))
    H, _ = cv2.findHomography(lens.undistort(fid.image[inliers]), fid.plane[inliers], 0)
    return cv2.perspectiveTransform(lens.undistort(np.asarray(uv, float)).reshape(-1, 1, 2), H).reshape(-1, 2)


def fit_lens(plane: PlaneMap, size: tuple[int, int]) -> FittedLens | None:
    """A radial lens fitted to the markers of a photo whose plane fit shows distortion, or None.

    The recorded corners bend away from the plane's homography where the lens distorts; the two
    radial terms of OpenCV's model (k1, k2; the principal point at the photo's centre, the focal length
    set to the farthest corner's distance from it, which only scales k1 and k2: k1 is then the share
    by which the lens moves that corner) are fitted with the homography to the inlier fiducials by
    least squares on their misfit on the plane (mm), from the best k1 of a grid (the misfit has more
    than one minimum when the markers lie at about one distance from the centre). It must bring the median
    corner's misfit down :data:`LENS_GAIN` times (a marker that a shadow or a smudge moves stays off).

    Parameters
    ----------
    plane : PlaneMap, fitted without a camera
    size : (width, height) of the photo, px

    Returns
    -------
    FittedLens (its camera's ``rms_px`` nan: not a calibration) when the markers call for one (see
    :data:`LENS_MIN_FIDUCIALS`, :data:`LENS_MISFIT_PX`, :data:`LENS_GAIN`) and determine it, else None
    """
    from scipy.optimize import least_squares
    from scipy.stats import f as f_dist

    inl = plane.inliers
    noise = LENS_MISFIT_PX * plane.mm_per_px
    if plane.camera is not None or inl.sum() < LENS_MIN_FIDUCIALS or plane.rms_mm < noise:
        return None
    w, h = size
    uv, xy = plane.fiducials.image[inl], plane.fiducials.plane[inl]
    c = np.array([(w - 1) / 2, (h - 1) / 2])
    f = max(float(np.hypot(*(uv - c).T).max()), 0.25 * float(np.hypot(w, h)))
    K = np.array([[f, 0, c[0]], [0, f, c[1]], [0, 0, 1.0]])

    def misfit(k):  # mm, each inlier's miss (x, y) of the homography through the lens k1, k2
        ideal = Camera((w, h), K, np.array([k[0], k[1], 0, 0, 0.0])).undistort(uv)
        H, _ = cv2.findHomography(ideal, xy, 0)
        return (cv2.perspectiveTransform(ideal.reshape(-1, 1, 2), H).reshape(-1, 2) - xy).ravel()

    def miss(k):  # the median corner's miss, mm
        return float(np.median(np.hypot(*misfit(k).reshape(-1, 2).T)))

    k1 = min(np.linspace(-0.2, 0.2, 41), key=lambda a: float(np.sum(misfit([a, 0.0]) ** 2)))
    # k1 alone first; k2 only where the markers tell it from k1 (an F test): markers at about one
    # distance from the centre leave a valley k1 r^2 + k2 r^4 = const, whose far ends move the sheet's middle
    # apart -- the same photo as PNG and as JPEG settled at either end, 0.1 mm apart at the spot
    one = least_squares(lambda a: misfit([a[0], 0.0]), [k1], x_scale=0.01)
    two = least_squares(misfit, [one.x[0], 0.0], x_scale=0.01)
    dof = max(two.fun.size - 10, 1)  # 2n coordinates less the lens' 2 and the homography's 8
    ss1, ss2 = float(one.fun @ one.fun), float(two.fun @ two.fun)
    both = ss2 < ss1 and (ss1 - ss2) / (ss2 / dof) > f_dist.ppf(1 - LENS_K2_ALPHA, 1, dof)
    fit, k = (two, two.x) if both else (one, np.r_[one.x[0], 0.0])
    if miss(k) * LENS_GAIN > miss([0.0, 0.0]):
        return None
    # The covariance of the fitted terms: the residuals' variance through the normal matrix, which clear
    # parameters keep regular; a k2 not fitted has none.
    normal = fit.jac.T @ fit.jac
    if np.linalg.cond(normal) > 1e12:
        return None
    cov = np.zeros((2, 2))
    n = len(fit.x)
    cov[:n, :n] = float(fit.fun @ fit.fun) / (dof + 2 - n) * np.linalg.inv(normal)
    return FittedLens(Camera((w, h), K, np.array([k[0], k[1], 0, 0, 0.0])), cov)


def layout_markers(dictionary: str, corners: dict) -> dict:
    """The ``markers`` section for a layout YAML from ``{id: (4, 2) corners mm}``."""
    return {
        "dictionary": dictionary,
        "ids": {int(i): np.round(np.asarray(c, float), 4).tolist() for i, c in corners.items()},
    }
