"""What an outside tool needs to capture with its own robot script (issue 46, item 5): an empty capture
session for a layout (``lasercal new-session``), and the configurations a model computes for a point
(``lasercal configurations``: what ``validate`` would command).

The outside tool then fills the session row by row (docs/formats.md, "Session"): ``lasercal plan`` says
where to aim next, the tool moves its arm, photographs the spot, measures it (``lasercal spots --json
--layout L``) and appends ``point, t, q1..qN, [dq, tau,] photo, camera_x .. camera_note, [aim_x, aim_y]``
to captures.csv; ``solve`` reads it as it reads a session ``capture`` wrote.
"""

from __future__ import annotations

import datetime
from pathlib import Path

from lasercal.collector.sessions.spotphoto import SPOT_COLUMNS
from lasercal.collector.sessions.store import csv_line, write_atomic
from lasercal.solver.formats.captures import AIM_XY
from lasercal.solver.formats.data import reference
from lasercal.solver.formats.robots import load_model
from lasercal.solver.formats.session import captures_header, load_layout, session_meta
from lasercal.solver.whole import dump_yaml

BACKEND = "outside"  # the collector's backend of a session an outside tool fills


def write_empty_session(
    folder: Path,
    layout_file,
    robot: str,
    camera: bool = True,
    aim: str | None = None,
    per_point: int = 9,
    torques: bool = True,
) -> dict:
    """Write session.yaml and a captures.csv holding only its header into ``folder`` (which exists).

    Parameters
    ----------
    folder : Path, the session folder (empty)
    layout_file : str, the layout (file or built-in name)
    robot : str, the nominal robot (built-in name or file)
    camera : bool, the captures are measured by a camera: the header has the camera's columns
    aim : 'anywhere', 'cross' or None (camera sessions: anywhere on a sheet ``lasercal sheet`` printed, else
        beside each cross)
    per_point : int, captures per calibration point the session asks for (``plan`` and the coach count them)
    torques : bool, the header has the joint speeds and torques (``dq1..``, ``tau1..``)

    Returns
    -------
    dict, the session's ``collector`` settings (what ``plan`` reads: layout, aim, camera, per_point)

    Raises
    ------
    SessionError
        ``aim anywhere`` on a layout that is no sheet ``lasercal sheet`` printed, or without a camera.
    """
    from lasercal.collector.errors import SessionError
    from lasercal.collector.sessions.anywhere import cells
    from lasercal.collector.sessions.spotcam import BESIDE_MM

    layout = load_layout(layout_file)
    nominal = load_model(robot)
    if aim == "anywhere" and not camera:
        raise SessionError("--aim anywhere: only a camera measures where a spot planned anywhere lands")
    if camera and aim is None:  # as capture: anywhere on a printed sheet, else beside the crosses
        try:
            cells(layout, layout.path)
            aim = "anywhere"
        except SessionError:
            aim = "cross"
    if aim == "anywhere":
        cells(layout, layout.path)  # refused here: a layout whose blank paper is unknown
    columns = (list(SPOT_COLUMNS) if camera else []) + (list(AIM_XY) if aim == "anywhere" else [])
    collector = {
        "backend": BACKEND,
        "robot": robot,
        "per_point": per_point,
        "camera": BACKEND if camera else None,
        "aim": aim or "cross",
        "layout": reference("layouts", layout_file, folder),
        "aiming": layout.aiming,
        "extra_columns": columns,
        "started": datetime.datetime.now().astimezone().isoformat(timespec="seconds"),
    }
    extra = {"collector": collector}
    if camera and aim != "anywhere":
        extra["aim_offset"] = list(BESIDE_MM)
    meta = session_meta(robot, layout, None, **extra)
    write_atomic(folder / "session.yaml", dump_yaml(meta, sort_keys=False, width=120))
    header = captures_header(nominal.n, torques, torques, columns)
    write_atomic(folder / "captures.csv", csv_line(header).decode())
    return collector


def model_configurations(model_ref: str, layout_file, point: str | None, n: int, seed: int, sheet_from=None):
    """The configurations ``validate`` would command for ``point`` (:func:`~lasercal.collector.sessions.
    validate.validation_commands`: the model's effects applied), on a sheet where the model's (or
    ``sheet_from``'s) calibration found it.

    Returns
    -------
    (q (n, N) rad, point (3,) mm base frame, point name, the layout in the base frame)
    """
    from lasercal.collector.sessions.start import sheet_world
    from lasercal.collector.sessions.validate import check_layout, validation_commands, validation_point

    layout = load_layout(layout_file)
    point = validation_point(layout, point)
    model = load_model(model_ref)
    check_layout(layout, model, model_ref, point)
    sheet, _ = sheet_world({"backend": BACKEND}, layout, model, model_ref, sheet_from)
    if sheet is not None:
        layout = layout.in_base(sheet)
    return validation_commands(layout, model, model_ref, point, n, seed), layout.points[point], point, layout
