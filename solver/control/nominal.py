"""The nominal model a calibrated model refers to: what a controller that keeps its factory kinematics
computes (the Cartesian commands of ``lasercal correct``, the goals of a joint-space program).

Found, in this order, from:

1. the model's ``nominal:`` key (a built-in name, or a model YAML or URDF path relative to the model file;
   ``lasercal solve`` writes it);
2. the URDF the model came from (``urdf: {file, base_link, tip_link}``);
3. the robot of the session it was identified from (``identification.session``, when that folder exists);
4. its name, when that is a built-in robot ('panda', 'fr3', ...).

A model none of these names is refused with the key to add.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from lasercal.solver.errors import FormatError
from lasercal.solver.formats.data import builtin_dir
from lasercal.solver.formats.robots import load_model, load_yaml, resolve_robot_path
from lasercal.solver.kinematics.gravity import with_payload
from lasercal.solver.kinematics.model import RobotModel


def robot_reference(ref, base: Path | None = None) -> str:
    """How a model file names a robot so that it is found from any folder: a built-in name as it is, a file
    (YAML or URDF, relative to ``base`` first) as its absolute path."""
    ref = str(ref)
    if ref.lower().endswith(".urdf"):
        p = Path(ref)
        if not p.is_absolute() and base is not None and (Path(base) / p).exists():
            p = Path(base) / p
        return str(p.resolve())
    path = resolve_robot_path(ref, base)
    return path.stem if path.resolve().parent == builtin_dir("robots").resolve() else str(path.resolve())


def _chain(model: RobotModel) -> dict:
    return {k: model.urdf.get(k) for k in ("base_link", "tip_link")} if model.urdf else {}


def _from_session(model: RobotModel) -> RobotModel | None:
    folder = model.identification.get("session")
    if not folder or not (Path(folder) / "session.yaml").is_file():
        return None
    meta = load_yaml(Path(folder) / "session.yaml")
    if not isinstance(meta, dict) or not meta.get("robot"):
        return None
    urdf = str(meta["robot"]).lower().endswith(".urdf")
    chain = {k: meta.get(k) for k in ("base_link", "tip_link")} if urdf else {}
    return load_model(meta["robot"], base=Path(folder), **chain)


def nominal_model(model: RobotModel, path=None) -> RobotModel:
    """The nominal model that ``model`` calibrates (module docstring).

    Parameters
    ----------
    model : RobotModel, a calibrated (or nominal) model
    path : str or Path, optional, the model's file: a relative ``nominal:`` path is relative to its folder

    Returns
    -------
    RobotModel with the same number of joints
    """
    where = path if path is not None else model.name
    if model.nominal:
        urdf = model.nominal.lower().endswith(".urdf")
        base = Path(path).resolve().parent if path is not None else None
        nominal = load_model(model.nominal, base=base, **(_chain(model) if urdf else {}))
    elif model.urdf:
        nominal = load_model(model.urdf["file"], **_chain(model))
    else:
        nominal = _from_session(model)
        if nominal is None and (builtin_dir("robots") / f"{model.name}.yaml").is_file():
            nominal = load_model(model.name)
    if nominal is None:
        raise FormatError(
            where,
            f"cannot tell which nominal model {model.name!r} calibrates: add 'nominal: NAME' to the model "
            "file (a built-in name, a model YAML or a URDF; a path relative to the model file)",
            field="nominal",
        )
    if nominal.n != model.n:
        raise FormatError(
            where,
            f"the nominal model {nominal.name!r} has {nominal.n} joints, the model {model.n}",
            field="nominal",
        )
    return nominal


def recorded_payload(model: RobotModel, path=None) -> tuple[float, np.ndarray] | None:
    """The flange's load the model's fit put in its gravity torques (``identification.payload``, written
    by ``lasercal solve --extend ... --payload``), or None.

    Parameters
    ----------
    model : RobotModel, a calibrated model
    path : str or Path, optional, the model's file (named in errors)

    Returns
    -------
    (mass kg, (3,) centre of mass at q = 0 in mm), or None when the model records none

    Raises
    ------
    FormatError
        A record that is not ``{mass: KG, com: [X, Y, Z]}`` with a positive mass and finite numbers.
    """
    rec = model.identification.get("payload")
    if rec is None:
        return None
    try:
        mass, com = float(rec["mass"]), np.array(rec["com"], dtype=float)
        ok = np.isfinite(mass) and mass > 0 and com.shape == (3,) and np.isfinite(com).all()
    except (TypeError, KeyError, ValueError):
        ok = False
    if not ok:
        raise FormatError(
            path if path is not None else model.name,
            f"expected {{mass: KG, com: [X, Y, Z]}} (kg > 0, mm at q = 0), got {rec!r}",
            field="identification.payload",
        )
    return mass, com


def gravity_robot(
    model: RobotModel, path=None, nominal: RobotModel | None = None, payload=None
) -> RobotModel:
    """The robot whose gravity model gives the joint torques of ``model``'s effects at commanded poses
    when none are logged: its nominal robot, whose torques the fit took (``solve`` takes the session's
    robot's at the logged poses, :func:`solver.analysis.diagnose.session_torques`), so that ``predict``
    and ``correct`` reproduce the fit's figures; ``model`` itself when it names no nominal, or when
    only it has a gravity model. Its last link carries the payload the fit's torques carried
    (:func:`recorded_payload`), or the one given.

    Parameters
    ----------
    model : RobotModel, a calibrated model
    path : str or Path, optional, the model's file (a relative ``nominal:`` is relative to its folder)
    nominal : RobotModel, optional, its nominal model when already loaded (:func:`nominal_model`)
    payload : (mass kg, (3,) centre of mass at q = 0 in mm), optional, the flange's load (default: the one
        the model records; :func:`solver.kinematics.gravity.with_payload`)

    Returns
    -------
    RobotModel
    """
    if payload is None:
        payload = recorded_payload(model, path)
    if nominal is None:
        try:
            nominal = nominal_model(model, path)
        except FormatError:
            return with_payload(model, payload)
    return with_payload(nominal if nominal.links or not model.links else model, payload)
