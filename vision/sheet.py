"""A printable reference sheet and the layout that describes it (``lasercal sheet``).

The sheet carries numbered reference crosses (the points the laser is aimed at), the ArUco markers
that ``spots --layout`` maps photos with, a 200 mm and a 100 mm scale bar to check the print with a
ruler, the origin and axes of the sheet frame and how to lay the sheet. It is drawn as vectors at 1:1
(figure size = paper size), written as PDF and SVG, and described by a ``lasercal-layout/1`` YAML with
``frame: sheet``.

Frames, mm:

* the page: u to the right, v up, origin at the lower-left corner, as printed and read upright;
* the sheet frame of the layout: origin at the centre cross, which is the page centre; x up the page
  (laid pointing away from the robot), y to the left, z out of the paper (right-handed: up when the
  sheet lies face up). For a page W wide and H high::

      x = v - H/2,   y = W/2 - u                                                  (eq. P1)

Named papers are laid out landscape: their long side runs across the robot's front (the sheet's y),
where an arm's reach spreads most.
"""

from __future__ import annotations

import math
import re
import textwrap
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from lasercal.vision.camera import aruco_dictionary, whole_yaml
from lasercal.vision.errors import SheetError
from lasercal.vision.plane import LAYOUT_FORMAT, layout_markers

PAPERS = {"A4": (297.0, 210.0), "A3": (420.0, 297.0), "letter": (279.4, 215.9)}  # landscape W x H, mm
DICTIONARY = "DICT_4X4_50"
MARKER_SPACING = 200.0  # largest distance between neighbouring marker centres along a page edge, mm
CLEAR = 5.0  # white kept around markers (ArUco's quiet zone), scale bars and text, mm
ARM = (1.5, 7.0)  # a cross's arms run from 1.5 to 7 mm off its centre: the laser spot lands on white paper
LINE = 0.35  # line width of crosses and scale bars, mm
TICK = 4.0  # height of a scale bar's end ticks, mm
BAR_BAND = 9.0  # room of a scale bar with its label, mm
TEXT_PT = 6.5  # instructions, pt
LABEL_PT = 8.0  # point names, pt
TEXT_LINES = 4
PT_MM = 25.4 / 72  # mm per typographic point
CHAR_MM = 0.52 * TEXT_PT * PT_MM  # a generous average character width of the instructions, mm
# The crosses in the free area, as fractions of its half-width (u) and half-height (v) from the page
# centre: five calibration points at its corners and centre (spread, not collinear), two validation
# points between them, where neither was calibrated.
CALIBRATION = {"P1": (-1.0, 1.0), "P2": (1.0, 1.0), "P3": (0.0, 0.0), "P4": (-1.0, -1.0), "P5": (1.0, -1.0)}
VALIDATION = {"P6": (0.5, 0.5), "P7": (-0.5, -0.5)}


def paper_size(text: str) -> tuple[str, float, float]:
    """A paper by name (A4, A3, letter; landscape) or as ``WxH`` in mm (W across, H away from the robot).

    Returns
    -------
    (name, W mm, H mm)

    Raises
    ------
    ValueError
        Neither a known name nor two positive numbers.
    """
    for name, (w, h) in PAPERS.items():
        if text.strip().lower() == name.lower():
            return name, w, h
    m = re.fullmatch(r"\s*([0-9.]+)\s*[x×X*]\s*([0-9.]+)\s*(mm)?\s*", text)
    try:
        w, h = (float(m.group(1)), float(m.group(2))) if m else (math.nan, math.nan)
    except ValueError:
        w = h = math.nan
    if not (0 < w <= 2000 and 0 < h <= 2000):
        raise ValueError(f"paper {text!r}: expected {', '.join(PAPERS)} or WxH in mm (each up to 2000)")
    return f"{w:g}x{h:g}", w, h


def page_to_sheet(uv: np.ndarray, width: float, height: float) -> np.ndarray:
    """Page points (n, 2) mm -> sheet frame (n, 2) mm (eq. P1)."""
    uv = np.asarray(uv, float).reshape(-1, 2)
    return np.column_stack([uv[:, 1] - height / 2, width / 2 - uv[:, 0]])


def sheet_to_page(xy: np.ndarray, width: float, height: float) -> np.ndarray:
    """Sheet frame points (n, 2) mm -> page (n, 2) mm (eq. P1 inverted)."""
    xy = np.asarray(xy, float).reshape(-1, 2)
    return np.column_stack([width / 2 - xy[:, 1], height / 2 + xy[:, 0]])


@dataclass(frozen=True)
class ScaleBar:
    """A scale bar: ``length`` mm from ``start`` (page mm) along the page's u (``axis`` 0) or v (1)."""

    length: float
    start: tuple[float, float]
    axis: int


@dataclass(frozen=True)
class SheetDesign:
    """Everything printed on a sheet (lengths in mm).

    Attributes
    ----------
    paper : str, the paper's name (A4, A3, letter) or WxH
    width, height : float, the page, W across (the sheet's y), H away from the robot (the sheet's x)
    margin : float, white border left for the printer
    marker : float, side of the ArUco markers (their black square)
    dictionary : str, OpenCV ArUco dictionary
    points : dict name -> (2,) array, the crosses' centres, sheet frame
    validation : tuple of str, the points kept for validation (the others calibrate)
    markers : dict id -> (4, 2) array, the markers' outer corners, sheet frame, OpenCV order
        (top-left, top-right, bottom-right, bottom-left as printed)
    bars : tuple of ScaleBar
    text_box : (u0, v0, u1, v1), page, the instructions' area
    """

    paper: str
    width: float
    height: float
    margin: float
    marker: float
    dictionary: str
    points: dict
    validation: tuple
    markers: dict
    bars: tuple
    text_box: tuple

    @property
    def calibration(self) -> tuple:
        """The calibration points' names."""
        return tuple(n for n in self.points if n not in self.validation)


def _edge_centres(lo: float, hi: float) -> np.ndarray:
    """Marker centres from ``lo`` to ``hi`` along an edge, evenly, at most MARKER_SPACING apart."""
    return np.linspace(lo, hi, max(1, math.ceil((hi - lo) / MARKER_SPACING - 1e-9)) + 1)


def _marker_ring(width: float, height: float, margin: float, side: float) -> list:
    """Lower-left page corners of the markers around the page, clockwise from the top-left one."""
    c = margin + side / 2
    us, vs = _edge_centres(c, width - c), _edge_centres(c, height - c)
    centres = (
        [(u, height - c) for u in us]
        + [(width - c, v) for v in vs[-2:0:-1]]
        + [(u, c) for u in us[::-1]]
        + [(c, v) for v in vs[1:-1]]
    )
    return [(u - side / 2, v - side / 2) for u, v in centres]


def design_sheet(paper: str = "A4", margin: float = 10.0, marker: float = 30.0) -> SheetDesign:
    """Lay out a sheet: markers around the edge, scale bars, instructions, crosses spread over the rest.

    The 200 mm bar runs along the page's longer side, the 100 mm bar along the other, so a print
    scaled in one direction only is caught. The crosses spread over the free area (see
    ``CALIBRATION`` and ``VALIDATION``), rounded to whole mm in the sheet frame.

    Parameters
    ----------
    paper : str, A4, A3, letter or WxH (mm; see :func:`paper_size`)
    margin : float, white border for the printer, mm
    marker : float, ArUco marker side, mm

    Returns
    -------
    SheetDesign

    Raises
    ------
    SheetError
        The paper is too small for the markers, both scale bars and a spread of points.
    """
    try:
        name, W, H = paper_size(paper)
    except ValueError as e:
        raise SheetError(str(e)) from None
    if not (margin >= 0 and marker > 0):
        raise SheetError(f"margin {margin:g} mm and marker side {marker:g} mm: expected >= 0 and > 0")
    corners = _marker_ring(W, H, margin, marker)
    s = marker
    markers = {
        i: page_to_sheet([[u, v + s], [u + s, v + s], [u + s, v], [u, v]], W, H)
        for i, (u, v) in enumerate(corners)
    }
    inner = margin + marker + CLEAR  # the free area starts here on every side
    long_u = W >= H
    # An L along the free area's lower-left: the u bar along its bottom, the v bar up its left side,
    # starting above the u bar; the instructions run along the top, right of the v bar.
    u_bar = ScaleBar(200.0 if long_u else 100.0, ((W - (200.0 if long_u else 100.0)) / 2, inner + 2), 0)
    v_start = inner + BAR_BAND + 2
    v_bar = ScaleBar(100.0 if long_u else 200.0, (inner + 2, v_start), 1)
    left = inner + BAR_BAND + CLEAR  # right of the v bar and its label
    text_box = (left, H - inner - TEXT_LINES * TEXT_PT * PT_MM * 1.5, W - inner, H - inner)
    label_w = 8 * LABEL_PT * PT_MM * 0.6  # "P1" beside a cross, with room to spare
    u0, u1 = left + ARM[1], W - inner - ARM[1] - label_w
    v0, v1 = inner + BAR_BAND + CLEAR + ARM[1], text_box[1] - CLEAR - ARM[1] - LABEL_PT * PT_MM
    cu, cv = W / 2, H / 2
    half_u, half_v = math.floor(min(cu - u0, u1 - cu)), math.floor(min(cv - v0, v1 - cv))
    too_small = (
        u_bar.start[0] < margin
        or v_start + v_bar.length > H - inner
        or text_box[2] - text_box[0] < 100
        or half_u < 20
        or half_v < 20
    )
    if too_small:
        raise SheetError(
            f"paper {name} ({W:g} x {H:g} mm) is too small for markers of {marker:g} mm, a {margin:g} mm "
            "margin, the 200 mm and 100 mm scale bars and a spread of points (A4 landscape fits; try "
            "--paper A4, a smaller --marker or --margin)"
        )
    pattern = {**CALIBRATION, **VALIDATION}
    page = np.array([[cu + fu * half_u, cv + fv * half_v] for fu, fv in pattern.values()])
    points = dict(zip(pattern, np.round(page_to_sheet(page, W, H)) + 0.0))  # + 0.0: no -0
    return SheetDesign(
        name, W, H, margin, marker, DICTIONARY, points, tuple(VALIDATION), markers, (u_bar, v_bar), text_box
    )


def layout_doc(design: SheetDesign, plane_z: float, placement: dict | None = None) -> dict:
    """The ``lasercal-layout/1`` mapping of a sheet: ``frame: sheet``, points [x, y, 0] and markers, mm.

    Parameters
    ----------
    design : SheetDesign
    plane_z : float, the sheet's height in the robot base frame, mm
    placement : dict or None, a rough placement ``{x_mm, y_mm, yaw_deg}`` of the sheet frame in the
        base frame (eq. S1 of ``solver.kinematics.sheet``)
    """
    doc = {
        "format": LAYOUT_FORMAT,
        "units": {"length": "mm", "angle": "deg"},
        "frame": "sheet",
        "plane": {"z": float(plane_z)},
    }
    if placement is not None:
        doc["sheet"] = {k: float(v) for k, v in placement.items()}
    doc["points"] = {n: [float(p[0]), float(p[1]), 0.0] for n, p in design.points.items()}
    doc["calibration"] = list(design.calibration)
    doc["validation"] = list(design.validation)
    doc["markers"] = layout_markers(design.dictionary, design.markers)
    doc["paper"] = {
        "name": design.paper,
        "width_mm": design.width,
        "height_mm": design.height,
        "margin_mm": design.margin,
        "marker_mm": design.marker,
    }
    return doc


LAYOUT_HEADER = """\
# A printed reference sheet, made by `lasercal sheet` ({paper}, {w:g} x {h:g} mm; sheet.pdf and sheet.svg
# beside this file). frame: sheet -- points and markers are in the sheet's own frame, mm: origin at the
# centre cross P3, x up the printed page (laid pointing away from the robot), y to the left, z out of
# the paper. plane.z is the sheet's height in the robot base frame, mm. {placement}
"""


def write_layout(path, design: SheetDesign, plane_z: float, placement: dict | None = None) -> None:
    """Write the sheet's layout YAML (see :func:`layout_doc`) with a header saying its frames and units."""
    where = (
        "sheet: a rough placement of the sheet frame in the base frame (x_mm, y_mm, yaw_deg; solve "
        "identifies the true one)."
        if placement is not None
        else "Where the sheet lies on the table is identified by solve."
    )
    head = LAYOUT_HEADER.format(paper=design.paper, w=design.width, h=design.height, placement=where)
    doc = layout_doc(design, plane_z, placement)
    Path(path).write_text(whole_yaml(doc, head, sort_keys=False, default_flow_style=None))


def _rects_path(rects):
    """One compound path of axis-aligned rectangles (u0, v0, u1, v1), page mm.

    One path, so a rasteriser fills the union: touching rectangles leave no seam.
    """
    from matplotlib.path import Path as MplPath

    verts, codes = [], []
    for u0, v0, u1, v1 in rects:
        verts += [(u0, v0), (u1, v0), (u1, v1), (u0, v1), (u0, v0)]
        codes += [MplPath.MOVETO] + [MplPath.LINETO] * 3 + [MplPath.CLOSEPOLY]
    return MplPath(verts, codes)


def _marker_rects(dictionary: str, marker_id: int, u: float, v: float, side: float) -> list:
    """The black cells of an ArUco marker whose lower-left page corner is (u, v)."""
    d = aruco_dictionary(dictionary)
    cells = d.markerSize + 2
    bits = cv2.aruco.generateImageMarker(d, int(marker_id), cells) < 128  # row 0 at the top
    k = side / cells
    top = v + side
    return [(u + c * k, top - (r + 1) * k, u + (c + 1) * k, top - r * k) for r, c in zip(*np.nonzero(bits))]


def _cross_rects(u: float, v: float) -> list:
    """The four arms of a cross centred at (u, v), page mm, its centre left white."""
    a0, a1, w = ARM[0], ARM[1], LINE / 2
    return [
        (u + a0, v - w, u + a1, v + w),
        (u - a1, v - w, u - a0, v + w),
        (u - w, v + a0, u + w, v + a1),
        (u - w, v - a1, u + w, v - a0),
    ]


def _bar_rects(bar: ScaleBar) -> list:
    """A scale bar: a line with end ticks exactly ``length`` apart and 10 mm ticks, page mm."""
    w, t = LINE / 2, TICK / 2
    along = [(0.0, bar.length, -w, w)]  # (from, to, across from, across to), in the bar's own axes
    along += [(x - w, x + w, -t, t) for x in (0.0, bar.length)]
    along += [(x - w, x + w, 0.0, t / 2) for x in np.arange(10.0, bar.length, 10.0)]
    u, v = bar.start
    if bar.axis == 0:
        return [(u + a0, v + b0, u + a1, v + b1) for a0, a1, b0, b1 in along]
    return [(u - b1, v + a0, u - b0, v + a1) for a0, a1, b0, b1 in along]


def instructions(design: SheetDesign, plane_z: float) -> str:
    """The text printed on the sheet: how to print, check, lay and use it."""
    (b1, b2) = sorted(b.length for b in design.bars)
    return (
        f"lasercal reference sheet, {design.paper} ({design.width:g} x {design.height:g} mm), described by "
        f"layout.yaml (frame: sheet, mm; plane z = {plane_z:g} mm in the robot base frame). "
        f"1. Print at 100 % (actual size, not 'fit to page'). "
        f"2. Check with a ruler: the bars measure {b2:g} mm and {b1:g} mm between their end ticks (within "
        f"0.5 mm), else fix the printer's scaling. 3. Lay the sheet flat in the robot's reach, the x arrow "
        f"pointing away from the robot; tape its corners. 4. lasercal capture --layout layout.yaml ...; aim "
        f"at the white centre of each cross ({', '.join(design.validation)}: validation)."
    )


def draw_sheet(design: SheetDesign, plane_z: float):
    """The sheet as a matplotlib Figure the size of the paper, one data unit = 1 mm of the page.

    Returns
    -------
    matplotlib.figure.Figure (no pyplot state); save it as PDF or SVG for a 1:1 vector print
    """
    from matplotlib.figure import Figure
    from matplotlib.patches import FancyArrow, PathPatch

    W, H = design.width, design.height
    fig = Figure(figsize=(W / 25.4, H / 25.4))
    ax = fig.add_axes((0, 0, 1, 1))
    ax.set_xlim(0, W)
    ax.set_ylim(0, H)
    ax.set_axis_off()

    def patch(rects, gid):
        p = PathPatch(_rects_path(rects), facecolor="black", edgecolor="none", linewidth=0)
        p.set_gid(gid)
        ax.add_patch(p)

    for i, c in design.markers.items():
        u, v = sheet_to_page(c, W, H).min(0)
        patch(_marker_rects(design.dictionary, i, u, v, design.marker), f"marker-{i}")
    for bar in design.bars:
        patch(_bar_rects(bar), f"bar-{bar.length:g}")
        above = TICK / 2 + 1  # the label sits beside the bar, clear of its ticks
        u, v = bar.start
        at = (u + bar.length / 2, v + above) if bar.axis == 0 else (u + above, v + bar.length / 2)
        ax.text(
            *at,
            f"{bar.length:g} mm: check with a ruler",
            fontsize=TEXT_PT,
            ha="center" if bar.axis == 0 else "left",
            va="bottom" if bar.axis == 0 else "center",
            rotation=0 if bar.axis == 0 else 90,
            rotation_mode="anchor",
        )
    for name, xy in design.points.items():
        u, v = sheet_to_page(xy, W, H)[0]
        patch(_cross_rects(u, v), f"cross-{name}")
        label = f"{name} (validation)" if name in design.validation else name
        ax.text(u + ARM[1] * 0.4, v + ARM[1] * 0.4, label, fontsize=LABEL_PT, ha="left", va="bottom")
    # The sheet frame's axes from the origin cross: x up the page, y to the left (eq. P1).
    u, v = sheet_to_page([0.0, 0.0], W, H)[0]
    span = ARM[1] + 2
    length = min(25.0, 0.6 * min(W, H) / 4)
    kw = dict(width=LINE, head_width=2.5, head_length=3.5, length_includes_head=True, color="black", lw=0)
    ax.add_patch(FancyArrow(u, v + span, 0, length, **kw))
    ax.add_patch(FancyArrow(u - span, v, -length, 0, **kw))
    ax.text(u + 1.5, v + span + length, "x: lay it pointing away from the robot", fontsize=TEXT_PT, va="top")
    ax.text(u - span - length, v - 1.5, "y", fontsize=TEXT_PT, ha="left", va="top")
    ax.text(u - 1.5, v - 1.5, "origin", fontsize=TEXT_PT, ha="right", va="top")
    u0, v0, u1, v1 = design.text_box
    wrapped = textwrap.fill(instructions(design, plane_z), width=int((u1 - u0) / CHAR_MM))
    ax.text(u0, v1, wrapped, fontsize=TEXT_PT, ha="left", va="top", linespacing=1.3)
    return fig


def write_sheet(folder, design: SheetDesign, plane_z: float, placement: dict | None = None) -> dict:
    """Write ``sheet.pdf``, ``sheet.svg`` (vector, 1:1) and ``layout.yaml`` into ``folder``.

    Returns
    -------
    dict file kind ("pdf", "svg", "layout") -> Path
    """
    import matplotlib

    folder = Path(folder)
    out = {"pdf": folder / "sheet.pdf", "svg": folder / "sheet.svg", "layout": folder / "layout.yaml"}
    # No simplification (every corner is kept exactly) and no dates or random ids: the same sheet
    # gives the same bytes.
    rc = {"path.simplify": False, "svg.hashsalt": "lasercal-sheet", "pdf.fonttype": 42}
    with matplotlib.rc_context(rc):
        fig = draw_sheet(design, plane_z)
        fig.savefig(out["pdf"], metadata={"CreationDate": None, "Creator": "lasercal sheet"})
        fig.savefig(out["svg"], metadata={"Date": None, "Creator": "lasercal sheet"})
    write_layout(out["layout"], design, plane_z, placement)
    return out


def span_grid(design: SheetDesign, step: float) -> np.ndarray:
    """The grid of points ``step`` mm apart, on multiples of ``step`` in the sheet frame, inside the
    markers' span: (k, 2) array, sheet frame, mm (x outer, y inner)."""
    corners = np.concatenate(list(design.markers.values()))
    lo, hi = corners.min(axis=0), corners.max(axis=0)
    gx = np.arange(np.ceil(lo[0] / step), np.floor(hi[0] / step) + 1) * step
    gy = np.arange(np.ceil(lo[1] / step), np.floor(hi[1] / step) + 1) * step
    return np.stack(np.meshgrid(gx, gy, indexing="ij"), axis=-1).reshape(-1, 2)


def drawn_blank_spots(
    design: SheetDesign, step: float = 10.0, clear: float = 8.0, px_mm: float = 4.0
) -> np.ndarray:
    """:func:`blank_spots` found on the sheet as :func:`draw_sheet` rasterises it (a distance transform of
    its ink): the check of the geometry's cells against whatever the drawing prints (tests, and
    benchmarks/bench_capture_start.py's before and after). Draws the whole sheet: ~0.2-1.4 s.

    Parameters
    ----------
    design : SheetDesign
    step : float, grid spacing, mm
    clear : float, least distance from any ink, mm
    px_mm : float, pixels per mm of the rasterised page (4: the 0.35 mm lines are drawn solid; at 2 the
        rasteriser renders them half grey)

    Returns
    -------
    (k, 2) array, sheet frame, mm
    """
    import cv2
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    W, H = design.width, design.height
    fig = draw_sheet(design, 0.0)
    fig.set_dpi(25.4 * px_mm)
    canvas = FigureCanvasAgg(fig)
    canvas.draw()
    page = np.asarray(canvas.buffer_rgba())[..., :3].min(axis=2)  # row 0 at the page's top
    white = (page > 200).astype(np.uint8)  # anti-aliased edges count as ink
    reach = cv2.distanceTransform(white, cv2.DIST_L2, 5) / px_mm  # mm to the nearest ink
    xy = span_grid(design, step)
    uv = sheet_to_page(xy, W, H)
    col = np.clip(np.round(uv[:, 0] * px_mm - 0.5).astype(int), 0, reach.shape[1] - 1)
    row = np.clip(np.round((H - uv[:, 1]) * px_mm - 0.5).astype(int), 0, reach.shape[0] - 1)
    return xy[reach[row, col] >= clear]


# The advance widths of the characters of matplotlib's default font (DejaVu Sans), 1/2048 em: digits,
# lower case, capitals, then the punctuation of PUNCTUATION and the space; any other character counts 1 em.
PUNCTUATION = "!\"#$%&'()*+,-./:;<=>?@[\\]^_`{|}~ "
ADVANCE = dict(
    zip(
        "0123456789abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ" + PUNCTUATION,
        (1303,) * 10
        + (
            1255,
            1300,
            1126,
            1300,
            1260,
            721,
            1300,
            1298,
            569,
            569,
            1186,
            569,
            1995,
            1298,
            1253,
            1300,
            1300,
            842,
            1067,
            803,
            1298,
            1212,
            1675,
            1212,
            1212,
            1075,
        )
        + (
            1401,
            1405,
            1430,
            1577,
            1294,
            1178,
            1587,
            1540,
            604,
            604,
            1343,
            1141,
            1767,
            1532,
            1612,
            1235,
            1612,
            1423,
            1300,
            1251,
            1499,
            1401,
            2025,
            1403,
            1251,
            1403,
        )
        + (
            821,
            942,
            1716,
            1303,
            1946,
            1597,
            563,
            799,
            799,
            1024,
            1716,
            651,
            739,
            651,
            690,
            690,
            690,
            1716,
            1716,
            1716,
            1087,
            2048,
            799,
            690,
            799,
            1716,
            1024,
            1024,
            1303,
            690,
            1303,
            1716,
            651,
        ),
    )
)
EM_LINE = 1.3  # a text line's height with its spacing, em (draw_sheet's instructions: linespacing 1.3)
HINTING = 1.08  # a rasteriser's hinting widens small text, by up to 8 % (matplotlib's Agg: 7 % at 6.5 pt)


def _text_width(text: str) -> float:
    """A line of text's width, em: its characters' advances (``ADVANCE``), kerning left out, widened by the
    rasteriser's ``HINTING``."""
    return HINTING * sum(ADVANCE.get(c, 2048) for c in text) / 2048


def _text_box(u: float, v: float, lines: list, pt: float, ha: str, va: str, upright: bool = True) -> tuple:
    """The page box (u0, v0, u1, v1) a text's ink stays inside, drawn at (u, v) as :func:`draw_sheet` does.

    Parameters
    ----------
    u, v : float
        The text's anchor, page mm.
    lines : list of str
        The text's lines.
    pt : float
        Its font size, points.
    ha, va : str
        Its alignment at the anchor along and across its lines: 'left', 'center', 'right'; 'bottom',
        'center', 'top'.
    upright : bool
        Lines along the page's u; else turned a quarter anticlockwise (along v, anchored as matplotlib's
        ``rotation_mode="anchor"``).

    Returns
    -------
    tuple of float
        The box, page mm: the characters' advances (:func:`_text_width`), every line ``EM_LINE`` high.
    """
    em = pt * PT_MM
    along, across = em * max(_text_width(t) for t in lines), EM_LINE * em * len(lines)
    a0 = {"left": 0.0, "center": -along / 2, "right": -along}[ha]
    b0 = {"bottom": 0.0, "center": -across / 2, "top": -across}[va]
    if upright:
        return (u + a0, v + b0, u + a0 + along, v + b0 + across)
    return (u - b0 - across, v + a0, u - b0, v + a0 + along)


def ink_boxes(design: SheetDesign, plane_z: float = 0.0) -> dict:
    """Boxes that hold everything :func:`draw_sheet` prints, from the design's geometry (nothing drawn).

    Parameters
    ----------
    design : SheetDesign
    plane_z : float
        The plane height the instructions name, mm.

    Returns
    -------
    dict
        Kind -> (k, 4) array of boxes (u0, v0, u1, v1), page mm. The marks as printed: 'markers' (each
        whole square), 'bars' (the scale bars' lines and ticks), 'crosses' (their arms); and generous boxes
        about 'arrows' (the sheet frame's, shaft and head) and 'text' (the bars' and crosses' labels, the
        arrows' words and the instructions' lines, :func:`_text_box`).
    """
    W, H = design.width, design.height
    marks = {"markers": [], "bars": [], "crosses": []}
    text = []
    for c in design.markers.values():
        u, v = sheet_to_page(c, W, H).min(0)
        marks["markers"].append((u, v, u + design.marker, v + design.marker))
    above = TICK / 2 + 1  # draw_sheet's bar label, beside the bar clear of its ticks
    for bar in design.bars:
        marks["bars"] += _bar_rects(bar)
        label = [f"{bar.length:g} mm: check with a ruler"]
        u, v = bar.start
        if bar.axis == 0:
            text.append(_text_box(u + bar.length / 2, v + above, label, TEXT_PT, "center", "bottom"))
        else:
            text.append(_text_box(u + above, v + bar.length / 2, label, TEXT_PT, "left", "center", False))
    for name, xy in design.points.items():
        u, v = sheet_to_page(xy, W, H)[0]
        marks["crosses"] += _cross_rects(u, v)
        label = [f"{name} (validation)" if name in design.validation else name]
        text.append(_text_box(u + ARM[1] * 0.4, v + ARM[1] * 0.4, label, LABEL_PT, "left", "bottom"))
    u, v = sheet_to_page([0.0, 0.0], W, H)[0]  # the origin cross: the frame's arrows and their words
    span, length, head = ARM[1] + 2, min(25.0, 0.6 * min(W, H) / 4), 2.5 / 2
    arrows = [
        (u - head, v + span, u + head, v + span + length),
        (u - span - length, v - head, u - span, v + head),
    ]
    words = ["x: lay it pointing away from the robot"]
    text.append(_text_box(u + 1.5, v + span + length, words, TEXT_PT, "left", "top"))
    text.append(_text_box(u - span - length, v - 1.5, ["y"], TEXT_PT, "left", "top"))
    text.append(_text_box(u - 1.5, v - 1.5, ["origin"], TEXT_PT, "right", "top"))
    u0, v0, u1, v1 = design.text_box
    wrapped = textwrap.wrap(instructions(design, plane_z), width=int((u1 - u0) / CHAR_MM))
    step = EM_LINE * TEXT_PT * PT_MM
    text += [_text_box(u0, v1 - k * step, [t], TEXT_PT, "left", "top") for k, t in enumerate(wrapped)]
    kinds = {**marks, "arrows": arrows, "text": text}
    return {k: np.array(b, dtype=float).reshape(-1, 4) for k, b in kinds.items()}


def box_distances(xy: np.ndarray, boxes: np.ndarray) -> np.ndarray:
    """Distances from points to axis-aligned boxes.

    Parameters
    ----------
    xy : (k, 2) array
        The points.
    boxes : (b, 4) array
        The boxes (x0, y0, x1, y1), in the points' frame.

    Returns
    -------
    (k, b) array
        Each point's distance to each box (0 inside it).
    """
    xy, boxes = np.asarray(xy, float), np.asarray(boxes, float)
    dx = np.maximum(np.maximum(boxes[None, :, 0] - xy[:, None, 0], xy[:, None, 0] - boxes[None, :, 2]), 0.0)
    dy = np.maximum(np.maximum(boxes[None, :, 1] - xy[:, None, 1], xy[:, None, 1] - boxes[None, :, 3]), 0.0)
    return np.hypot(dx, dy)


def blank_spots(design: SheetDesign, step: float = 10.0, clear: float = 8.0) -> np.ndarray:
    """Where on a sheet a laser spot lands on white paper inside the markers' span: the grid points at
    least ``clear`` mm from every ink (markers, crosses, labels, scale bars, arrows, instructions), from the
    sheet's geometry as :func:`draw_sheet` lays it (:func:`ink_boxes`; nothing is drawn). The drawing's
    blank cells (:func:`drawn_blank_spots`) or a few fewer: the texts' boxes are generous.

    A camera measures a spot's centre there without ink swallowing part of it; ``clear`` leaves room for
    the spot itself (a few mm across) and a rough aim.

    Parameters
    ----------
    design : SheetDesign
    step : float, grid spacing, mm
    clear : float, least distance from any ink, mm

    Returns
    -------
    (k, 2) array, sheet frame, mm
    """
    xy = span_grid(design, step)
    uv = sheet_to_page(xy, design.width, design.height)
    ink = np.concatenate(list(ink_boxes(design).values()))
    return xy[box_distances(uv, ink).min(axis=1) >= clear]
