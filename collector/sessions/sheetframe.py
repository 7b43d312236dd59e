"""Which session a model was identified from, and whether two models share the base frame a sheet's pose
is stated in (eq. S2): what a validation on a sheet checks before it aims."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from lasercal.solver.errors import FormatError
from lasercal.solver.kinematics.model import RobotModel

SAME_AXIS_MM = 1e-3  # two models share a base frame when joint 1's screws agree this well (mm, and 1e-6 rad)


def model_session(model: RobotModel, model_path) -> Path | None:
    """The session folder a model was identified from (``identification.session``, relative to the model
    file's folder or absolute), or None when it names none or it is gone."""
    ref = model.identification.get("session")
    if not ref:
        return None
    p = Path(str(ref))
    if not p.is_absolute():
        p = Path(model_path).parent / p
    return p if (p / "session.yaml").is_file() else None


def check_same_frame(model: RobotModel, model_ref: str, sheet_model: RobotModel, sheet_ref: str) -> None:
    """A sheet's pose identified with ``sheet_model`` is in its robot's own base frame (eq. S2): joint 1
    as the nominal's. ``model`` must have that joint 1 too (the nominal does; so does every model solved
    on a sheet of the same robot).

    Raises
    ------
    FormatError
        Naming the sheet model's file: the two models' joint 1 differ.
    """
    a, b = model.screws[0], sheet_model.screws[0]
    if (
        model.n != sheet_model.n
        or np.abs(a[:3] - b[:3]).max() > 1e-6
        or np.abs(a[3:] - b[3:]).max() > SAME_AXIS_MM
    ):
        raise FormatError(
            sheet_ref,
            f"its sheet pose is in its robot's own base frame (joint 1 as the nominal's), but joint 1 of "
            f"{model_ref} is not that robot's (expected models of one robot: the nominal, or one solved on "
            "the sheet)",
            field="sheet",
        )
