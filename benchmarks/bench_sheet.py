"""Benchmark of the printed reference sheet (issue 23): the print round trip and a phone photo of it.

Run from the repository root (needs the ``test`` extra for pypdfium2)::

    python benchmarks/bench_sheet.py            # ~30 s on 2 cores
    python benchmarks/bench_sheet.py --quick    # fewer photos

1. Round trip, per paper: ``lasercal sheet`` draws the sheet, PDFium (pypdfium2) rasterises the PDF at
   ``--dpi``; the ArUco markers are detected (``vision.plane.find_fiducials``) and each cross's centre
   is located from its four arms (below). Every marker corner and cross centre, taken from the raster's
   own scale (page mm = (px + 0.5) / px-per-mm), is compared with where layout.yaml says it is; the
   crosses also through the markers' homography, as ``spots --layout`` maps a spot. The SVG is checked
   by parsing its paths (matplotlib writes each marker and cross as one path with an id): their
   outlines against the layout, and their polygons filled by OpenCV then decoded as markers.
2. Phone photos: the sheet's markers and crosses rendered by ``vision.render``'s phone camera model
   (auto exposure, Bayer, blooming, tone curve, 4:2:0 JPEG) with a red laser spot on a sheet point,
   seen from a random camera pose; the spot measured by ``measure_photo`` in sheet mm against the point.

A cross's centre: along each arm, the darkness-weighted centroid across the line at every pixel
column (row) of the arm, then a straight line through both arms of a direction; the centre is where
the two lines cross. Symmetric blur does not move a centroid.
"""

from __future__ import annotations

import argparse
import re
import tempfile
import time
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from lasercal.vision.measure import Options, measure_photo
from lasercal.vision.plane import MarkerLayout, find_fiducials, fit_plane, load_markers
from lasercal.vision.render import PhoneCamera, Photo, Print, aruco_print, look_down, render, tilted_spot
from lasercal.vision.sheet import (
    ARM,
    LINE,
    SheetDesign,
    design_sheet,
    page_to_sheet,
    sheet_to_page,
    write_sheet,
)

PAPERS = ("A4", "A3", "letter", "350x250")
PT_MM = 25.4 / 72


def rasterise_pdf(path, dpi: float) -> tuple[np.ndarray, np.ndarray]:
    """The PDF's first page as a grey image and its scale.

    Returns
    -------
    gray : (h, w) uint8 array
    k : (2,) array, px per mm along u and v: the bitmap's size over the page's (PDFium rounds it)
    page : (2,) array, the page's size, mm
    """
    import pypdfium2 as pdfium

    page = pdfium.PdfDocument(str(path))[0]
    size = np.array(page.get_size()) * PT_MM
    gray = page.render(scale=dpi / 72, grayscale=True).to_numpy()
    gray = gray if gray.ndim == 2 else gray[..., 0]
    return gray, np.array([gray.shape[1], gray.shape[0]]) / size, size


def px_to_page(uv: np.ndarray, k: np.ndarray, height: float) -> np.ndarray:
    """Pixels (n, 2), OpenCV convention, of a page raster -> page mm (u right, v up)."""
    uv = np.asarray(uv, float).reshape(-1, 2)
    return np.column_stack([(uv[:, 0] + 0.5) / k[0], height - (uv[:, 1] + 0.5) / k[1]])


def page_to_px(up: np.ndarray, k: np.ndarray, height: float) -> np.ndarray:
    """Page mm (n, 2) -> pixels of a page raster (OpenCV convention)."""
    up = np.asarray(up, float).reshape(-1, 2)
    return np.column_stack([up[:, 0] * k[0] - 0.5, (height - up[:, 1]) * k[1] - 0.5])


def cross_centre(gray: np.ndarray, uv: np.ndarray, k: float) -> np.ndarray:
    """The centre (2,) px of a printed cross near ``uv`` px, from its four arms (module docstring).

    Parameters
    ----------
    gray : (h, w) uint8 array, white paper
    uv : (2,) array, the centre's rough position, px (within ~1 mm)
    k : float, px per mm
    """
    dark = 1 - gray.astype(float) / 255
    u0, v0 = np.round(uv).astype(int)
    r = int(round(1.0 * k))  # the window across an arm: +-1 mm
    steps = np.arange(int(np.ceil(ARM[0] * k)) + 2, int(np.floor(ARM[1] * k)) - 1)
    across = np.arange(-r, r + 1)
    lines = []
    for horizontal in (True, False):
        at = (
            np.concatenate([u0 - steps, u0 + steps])
            if horizontal
            else np.concatenate([v0 - steps, v0 + steps])
        )
        if horizontal:
            w = dark[v0 + across[:, None], at[None, :]]  # (across, along)
            c = v0 + (across[:, None] * w).sum(0) / w.sum(0)
        else:
            w = dark[at[None, :], u0 + across[:, None]]
            c = u0 + (across[:, None] * w).sum(0) / w.sum(0)
        lines.append(np.polyfit(at, c, 1))  # horizontal: v = a u + b; vertical: u = a v + b
    (a1, b1), (a2, b2) = lines
    u = (a2 * b1 + b2) / (1 - a2 * a1)
    return np.array([u, a1 * u + b1])


@dataclass(frozen=True)
class RoundTrip:
    """Errors of one printed sheet against its layout, mm (sheet frame).

    Attributes
    ----------
    markers_found, markers : int, detected and printed markers
    marker_max : float, largest marker-corner error, from the raster's scale
    cross_max : float, largest cross-centre error, from the raster's scale
    cross_homography_max : float, largest cross-centre error through the markers' homography
    page_error : float, the page size's difference from the paper's, mm
    """

    markers_found: int
    markers: int
    marker_max: float
    cross_max: float
    cross_homography_max: float
    page_error: float


def pdf_round_trip(pdf, layout_path, design: SheetDesign, dpi: float = 200) -> RoundTrip:
    """Rasterise the sheet's PDF and measure every marker and cross against the layout (module docstring)."""
    gray, k, size = rasterise_pdf(pdf, dpi)
    layout = load_markers(layout_path)
    fid = find_fiducials(gray, layout, gamma=1.0)
    H = design.height
    marker_err = np.linalg.norm(
        page_to_sheet(px_to_page(fid.image, k, H), design.width, H) - fid.plane, axis=1
    )
    plane = fit_plane(fid, layout, None, gray.shape[::-1])
    direct, mapped = [], []
    for xy in design.points.values():
        c = cross_centre(gray, page_to_px(sheet_to_page(xy, design.width, H), k, H)[0], float(k.mean()))
        direct.append(np.linalg.norm(page_to_sheet(px_to_page(c, k, H), design.width, H)[0] - xy))
        mapped.append(np.linalg.norm(plane.to_plane(c)[0] - xy))
    return RoundTrip(
        len(fid.marker_ids),
        len(design.markers),
        float(marker_err.max()),
        float(max(direct)),
        float(max(mapped)),
        float(np.abs(size - [design.width, H]).max()),
    )


def svg_paths(svg) -> tuple[np.ndarray, dict]:
    """The page size (2,) mm and the polygons of every path group with an id, in page mm.

    Returns
    -------
    size : (2,) array, the SVG's width and height, mm
    groups : dict id -> list of (k, 2) arrays, page mm (u right, v up)
    """
    root = ET.parse(svg).getroot()
    size = np.array([float(root.get(a).removesuffix("pt")) for a in ("width", "height")]) * PT_MM
    ns = {"s": "http://www.w3.org/2000/svg"}
    groups = {}
    for g in root.iter("{http://www.w3.org/2000/svg}g"):
        gid = g.get("id", "")
        if not re.fullmatch(r"(marker|cross)-\w+", gid):
            continue
        polys = []
        for path in g.findall("s:path", ns):
            if path.get("transform") or g.get("transform"):
                raise ValueError(f"{svg}: {gid} has a transform (expected absolute coordinates)")
            for sub in re.split(r"[zZ]", path.get("d")):
                xy = np.array(re.findall(r"[-+]?\d*\.?\d+(?:e[-+]?\d+)?", sub), float).reshape(-1, 2)
                if len(xy):
                    polys.append(np.column_stack([xy[:, 0] * PT_MM, size[1] - xy[:, 1] * PT_MM]))
        groups[gid] = polys
    return size, groups


def svg_round_trip(svg, layout_path, design: SheetDesign, px_per_mm: float = 8.0) -> RoundTrip:
    """The SVG's markers and crosses against the layout: outlines parsed, markers filled and decoded."""
    size, groups = svg_paths(svg)
    W, H = design.width, design.height
    layout = load_markers(layout_path)
    outline = []
    for i, corners in layout.corners.items():
        pts = np.concatenate(groups[f"marker-{i}"])
        box = page_to_sheet([[pts[:, 0].min(), pts[:, 1].max()], [pts[:, 0].max(), pts[:, 1].min()]], W, H)
        outline.append(np.abs(box - corners[[0, 2]]).max())  # top-left and bottom-right corners
    crosses = [
        np.linalg.norm(page_to_sheet(np.concatenate(groups[f"cross-{n}"]).mean(0), W, H)[0] - xy)
        for n, xy in design.points.items()
    ]
    # Fill the polygons 8x finer, then average 8 x 8 blocks: each pixel's ink coverage, as a rasteriser's.
    sup = 8
    k = np.array([px_per_mm, px_per_mm])
    fine = np.full((int(round(H * px_per_mm)) * sup, int(round(W * px_per_mm)) * sup), 255, np.uint8)
    polys = [p for i in layout.corners for p in groups[f"marker-{i}"]]
    shift = 4
    cv2.fillPoly(
        fine, [np.round(page_to_px(p, k * sup, H) * 2**shift).astype(np.int32) for p in polys], 0, 8, shift
    )
    canvas = cv2.resize(fine, (fine.shape[1] // sup, fine.shape[0] // sup), interpolation=cv2.INTER_AREA)
    fid = find_fiducials(canvas, layout, gamma=1.0)
    decoded = np.linalg.norm(page_to_sheet(px_to_page(fid.image, k, H), W, H) - fid.plane, axis=1)
    return RoundTrip(
        len(fid.marker_ids),
        len(design.markers),
        float(max(max(outline), decoded.max())),
        float(max(crosses)),
        float("nan"),
        float(np.abs(size - [W, H]).max()),
    )


def cross_print(xy, texel: float = 0.05) -> Print:
    """The sheet's cross at ``xy`` (sheet mm) as a renderer print: four arms, a white centre."""
    n = int(round(2 * ARM[1] / texel)) | 1
    c, w = n // 2, max(1, int(round(LINE / texel / 2)))
    a0 = int(round(ARM[0] / texel))
    img = np.ones((n, n), np.float32)
    img[c - w : c + w + 1, : c - a0] = img[c - w : c + w + 1, c + a0 + 1 :] = 0.05
    img[: c - a0, c - w : c + w + 1] = img[c + a0 + 1 :, c - w : c + w + 1] = 0.05
    half = n * texel / 2
    x, y = xy
    return Print(
        img,
        np.array([[x - half, y + half], [x + half, y + half], [x + half, y - half], [x - half, y - half]]),
    )


def sheet_photo(layout: MarkerLayout, points: dict, target: str, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """A phone photo of the sheet with a red laser spot on ``target``; the plane is the sheet frame.

    Returns
    -------
    (h, w, 3) uint8 BGR JPEG-decoded image, the spot's true position (2,) sheet mm, the scale (mm/px)
    """
    rng = np.random.default_rng([seed, 23])
    size = np.array([1600, 1200])
    yaw = rng.choice([0.0, 90.0, 180.0, 270.0]) + rng.uniform(-8, 8)  # the phone held either way
    corners = np.concatenate(list(layout.corners.values()))
    c, s = np.cos(np.radians(yaw)), np.sin(np.radians(yaw))
    extent = np.ptp(
        corners @ np.array([[c, -s], [s, c]]), axis=0
    )  # the sheet's extent along the photo's axes
    scale = float((extent / size).max() * rng.uniform(1.25, 1.35))  # the whole sheet in the photo, mm/px
    view = look_down(
        tuple(size),
        scale,
        centre=tuple(rng.uniform(-5, 5, 2)),
        yaw_deg=yaw,
        tilt_deg=tuple(rng.uniform(-2, 2, 2)),  # perspective; it also moves the view by up to ~25 mm
        height=rng.uniform(500, 700),
    )
    prints = tuple(aruco_print(layout.dictionary, i, c) for i, c in layout.corners.items())
    prints += tuple(cross_print(p) for p in points.values())
    xy = np.asarray(points[target], float)
    uv = view.project(xy)[0]
    spot = tilted_spot(
        *uv, rng.uniform(1.5, 3.0), rng.choice([0.5, 3.0, 10.0]), rng.uniform(0, 35), speckle=0.2
    )
    photo = Photo(
        view,
        prints,
        (spot,),
        colour="red",
        camera=PhoneCamera(jpeg=int(rng.integers(85, 93))),
        paper=rng.uniform(0.45, 0.65),
        gradient=rng.uniform(-0.15, 0.15),
        vignetting=rng.uniform(0, 0.1),
    )
    return render(photo, seed), xy, scale


def photo_errors(layout_path, design: SheetDesign, seeds) -> tuple[np.ndarray, np.ndarray]:
    """Sheet-mm errors (n, 2) of the laser spot measured in phone photos, one per seed (targets cycle),
    and the photos' scales (n,) mm/px."""
    layout = load_markers(layout_path)
    names = list(design.points)
    out, scales = [], []
    for s in seeds:
        img, xy, scale = sheet_photo(layout, design.points, names[s % len(names)], s)
        res = measure_photo(img, f"photo {s}", Options(), layout, subsampled=True)
        out.append([res.spots[0].x_mm - xy[0], res.spots[0].y_mm - xy[1]])
        scales.append(scale)
    return np.array(out), np.array(scales)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="fewer photos")
    ap.add_argument("--dpi", type=float, default=200.0, help="PDF raster resolution (default 200)")
    args = ap.parse_args()
    t0 = time.time()
    print(f"## Round trip at {args.dpi:g} dpi: max error against layout.yaml, mm (sheet frame)")
    print(f"{'paper':<9} {'file':<4} {'markers':>8} {'corners':>8} {'crosses':>8} {'via H':>8} {'page':>8}")
    with tempfile.TemporaryDirectory() as tmp:
        folders = {}
        for paper in PAPERS:
            design = design_sheet(paper)
            (Path(tmp) / paper).mkdir()
            files = write_sheet(Path(tmp) / paper, design, -8.0)
            folders[paper] = (design, files)
            for kind, rt in (
                ("pdf", pdf_round_trip(files["pdf"], files["layout"], design, args.dpi)),
                ("svg", svg_round_trip(files["svg"], files["layout"], design)),
            ):
                print(
                    f"{paper:<9} {kind:<4} {rt.markers_found:>4d}/{rt.markers:<3d} {rt.marker_max:8.4f} "
                    f"{rt.cross_max:8.4f} {rt.cross_homography_max:8.4f} {rt.page_error:8.4f}"
                )
        n = 10 if args.quick else 40
        print(
            f"\n## Phone photos of the sheet, a red spot on a sheet point: error in sheet mm over {n} photos"
        )
        head = ("paper", "mm/px", "RMS x", "RMS y", "mean 2-D", "max 2-D", "max px")
        print("{:<9} {:>11} {:>7} {:>7} {:>9} {:>8} {:>7}".format(*head))
        for paper in ("A4", "A3"):
            design, files = folders[paper]
            e, scales = photo_errors(files["layout"], design, range(n))
            d = np.hypot(*e.T)
            rx, ry = np.sqrt((e**2).mean(0))
            print(
                f"{paper:<9} {scales.min():5.3f}-{scales.max():5.3f} {rx:7.4f} {ry:7.4f} {d.mean():9.4f} "
                f"{d.max():8.4f} {(d / scales).max():7.3f}"
            )
    print(f"\n(benchmark took {time.time() - t0:.0f} s)")


if __name__ == "__main__":
    main()
