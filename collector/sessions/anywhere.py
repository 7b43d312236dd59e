"""Aim anywhere: where on the sheet a camera session's coach may plan a spot (issue 38, item 3).

A measured spot need not sit on a cross: the camera says where it landed. So the coach may plan a spot
wherever the camera measures it well -- on white paper inside the markers' span, clear of every ink the
sheet prints (:func:`vision.sheet.blank_spots`) -- and choose among them for what the fit still lacks.
Each spot belongs to the cell of the calibration point nearest to it: the session still counts its
captures per point (``--per-point``), and the coach keeps its rule of no pose twice per point.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from lasercal.collector.errors import SessionError
from lasercal.solver.formats.session import Layout

# the noise per axis a camera session's coach fits its measured captures with (the prior's sigma_0, eq. D3;
# its 4 pseudo-observations fade after a few captures): what such sessions showed before the sheet's print
# and tilt were fitted (0.07-0.10 mm); with them, 0.055-0.06 mm (docs/sessions.md)
CAMERA_NOISE_MM = 0.1
STEP_MM = 10.0  # grid of planned spots: finer adds candidates, not information (a rough aim is 3 mm)
CLEAR_MM = 8.0  # least distance from ink: the spot (~2 mm across) plus a rough aim's 2.5 sigma


def cells(layout: Layout, layout_file) -> dict:
    """The spots a camera session's coach may plan, by the calibration point whose cell holds them.

    Parameters
    ----------
    layout : Layout, a sheet's (points in its own frame)
    layout_file : path of the layout file ``lasercal sheet`` wrote (its ``paper`` section names the print)

    Returns
    -------
    dict name -> (k, 3) array, the spots in the layout's frame (z 0: on the sheet), mm

    Raises
    ------
    SessionError
        The layout is no sheet ``lasercal sheet`` printed (no ``paper`` section, or the print it names
        differs from the layout's points or markers): what is printed where is then unknown.
    """
    from lasercal.solver.formats.robots import load_yaml
    from lasercal.vision.plane import load_markers
    from lasercal.vision.sheet import blank_spots, design_sheet

    refuse = f"--aim anywhere needs a sheet printed by lasercal sheet: {layout_file} "
    paper = (load_yaml(Path(layout_file)) or {}).get("paper")
    if layout.frame != "sheet" or not isinstance(paper, dict):
        raise SessionError(refuse + "has no paper section (use --aim cross)")
    try:
        design = design_sheet(str(paper["name"]), float(paper["margin_mm"]), float(paper["marker_mm"]))
    except (KeyError, TypeError, ValueError, LookupError) as e:
        raise SessionError(refuse + f"names no print lasercal sheet makes ({e}; use --aim cross)") from None
    markers = load_markers(layout_file)
    same = set(design.points) >= set(layout.calibration) and all(
        np.allclose(design.points[k], layout.points[k][:2]) for k in layout.calibration
    )
    same &= markers is not None and all(
        k in design.markers and np.allclose(design.markers[k], c) for k, c in markers.corners.items()
    )
    if not same:
        raise SessionError(refuse + "differs from the print its paper section names (use --aim cross)")
    spots = blank_spots(design, STEP_MM, CLEAR_MM)
    names = list(layout.calibration)
    centres = np.array([layout.points[k][:2] for k in names])
    owner = np.argmin(np.linalg.norm(spots[:, None, :] - centres[None], axis=2), axis=1)
    return {k: np.c_[spots[owner == i], np.zeros(np.sum(owner == i))] for i, k in enumerate(names)}


def session_layout_file(collector: dict, folder) -> Path:
    """The layout file a capture session was started with: its settings' ``layout`` (``collector`` in
    session.yaml), relative to the session ``folder``."""
    ref = Path(str(collector.get("layout", "")))
    return ref if ref.is_absolute() else Path(folder) / ref
