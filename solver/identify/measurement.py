"""The two measurement types behind one interface: laser spots on a plane, tool points at points.

``session.measurement`` selects the model: 'laser' (the beam meets the plane; residuals in the
plane, (m, 2) mm), 'point' (a tool point held at fixed points; residuals (m, 3) mm) or
'position' (targets measured by a 3-D sensor; residuals (m, 3) mm in the sensor frame).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from lasercal.solver.errors import FormatError, IdentificationError
from lasercal.solver.formats.captures import MIN_PER_POINT, Session
from lasercal.solver.identify.degenerate import (
    Deficiency,
    Determination,
    deficiencies,
    determination,
    laser_gauge,
)
from lasercal.solver.identify.laser_parameters import SHAPE_NAMES, SHEET_NAMES, WARP_NAMES
from lasercal.solver.identify.point import identify_point, session_targets, tips
from lasercal.solver.identify.position import identify_position, position_residuals
from lasercal.solver.identify.spot import Identification, identify, plane_residuals
from lasercal.solver.kinematics.effects import Extension
from lasercal.solver.kinematics.model import RobotModel


def fit(
    session: Session,
    extension: Extension | None = None,
    nominal: RobotModel | None = None,
    robust: bool = True,
    method: str = "lm",
    suspects: np.ndarray | None = None,
) -> Identification:
    """Identify the session's model ('lm' for both measurement types; 'thesis' for laser sessions).

    ``suspects`` (m,) bool: the only captures the outlier test may flag -- an extension is fitted on the
    rows of its geometric fit, ``suspects=geometric.weights == 0`` (:mod:`solver.identify.lsq`).
    """
    if session.measurement == "point":
        return identify_point(session, nominal, robust, extension, suspects)
    if session.measurement == "position":
        return identify_position(session, nominal, robust, extension, suspects=suspects)
    if method == "thesis":
        return identify(session, "thesis", nominal)
    return identify(session, "lm", nominal, robust=robust, extension=extension, suspects=suspects)


def residuals(
    model: RobotModel, ext: Extension | None, session: Session, points: dict | None = None
) -> np.ndarray:
    """Residuals (m, d) of a model (and its extension) on captures: spot or tip minus target, mm.

    For point sessions, unknown points come from ``points`` (e.g. a training fit's), or else are
    taken as the mean of this model's own tips per point (a self-consistency residual).
    """
    if session.measurement == "position":
        return position_residuals(model, ext, session)
    q = ext.true_q(session.q, session.t, session.tau) if ext else session.q
    if session.measurement == "point":
        p = tips(model, q, model.tool_point if model.tool_point is not None else session.tool_point)
        known = dict(points or {})
        for nm in dict.fromkeys(session.point):
            if session.points[nm] is None and nm not in known:
                known[nm] = p[session.point == nm].mean(axis=0)
        return p - session_targets(session, known)
    off = ext.target_offset(session.point, ~session.measured) if ext is not None else 0.0
    return plane_residuals(model, q, session) - off


def check_data(session) -> None:
    """Refuse data that cannot identify the geometry: a point with too few captures, collinear points.

    Raises
    ------
    IdentificationError
        Naming the point or points, what cannot be identified and what data would fix it.
    """
    if session.m == 0:
        raise FormatError(
            Path(session.path) / "captures.csv",
            "no captures (a header and no rows): nothing to identify",
            line=2,
        )
    unknown = [nm for nm, xyz in session.points.items() if xyz is None]
    if session.measurement == "point" and unknown and not session.distances:
        raise FormatError(
            Path(session.path) / "session.yaml",
            f"points {', '.join(unknown[:4])}{' ...' if len(unknown) > 4 else ''} are unknown (null) and no "
            "known distance fixes the scale: a scaled robot fits as well (add constraints: {distances: "
            "[[A, B, mm]]}, or give a point's coordinates)",
            field="constraints.distances",
        )
    names, counts = np.unique(np.asarray(session.point, dtype=str), return_counts=True)
    # a point's own position is told from its captures' spread only where it is measured apart from the
    # others (a base-frame layout); a printed sheet's points move together with its pose, print and tilt
    printed = session.measurement == "laser" and session.frame == "sheet"
    few = [] if printed else [f"{nm} ({c})" for nm, c in zip(names, counts) if c < MIN_PER_POINT]
    if few:
        where = f"{Path(session.path) / 'captures.csv'}: " if session.path else ""
        raise IdentificationError(
            f"{where}too few captures at {', '.join(few)}: that point's position cannot be told from the "
            f"model's error (capture at least {MIN_PER_POINT} configurations there, or drop the point)"
        )
    if session.measurement != "laser" or len(names) < 3:
        return
    xy = np.array([session.points[nm][:2] for nm in names])
    if np.linalg.svd(xy - xy.mean(axis=0), compute_uv=False)[1] < 1.0:
        raise IdentificationError(
            f"points {', '.join(names)} are collinear: the base rotation about their line and the offset "
            "across it are unidentifiable (add a point off that line)"
        )


def unidentifiable(session: Session, ident: Identification) -> list[Deficiency]:
    """What neither the session's data nor the prior identifies beyond the gauge, named
    (:mod:`solver.identify.degenerate`).

    Laser sessions hold the aperture's component along the beam (the gauge of spot data); point and
    position identifications hold their base-frame gauge outside the parameter vector already. A
    parameter with a prior is held by it (its direction is reported by :func:`determined_by` instead).

    Returns
    -------
    list of Deficiency, empty for a full-rank fit (always, under a prior on every parameter)
    """
    names = list(ident.param_names)
    held = laser_gauge(names, ident.model.laser_dir) if session.measurement == "laser" else []
    prior = ident.extra.get("prior")
    if prior is not None:
        held = sorted(set(held) | set(np.flatnonzero(prior.finite).tolist()))
    return deficiencies(ident.identifiability, names, session.robot.joint_names, session.q, held)


def determined_by(session: Session, ident: Identification) -> Determination | None:
    """Which combinations the data and which the prior determined (eq. P5; None for a fit without prior)."""
    prior = ident.extra.get("prior")
    if prior is None or "cov" not in ident.extra:
        return None
    names = list(ident.param_names)
    held = laser_gauge(names, ident.model.laser_dir) if session.measurement == "laser" else []
    # a sheet's print scale and tilt are the set-up's, not the robot's: the sheet's line gives their sigmas
    # (an aimed session leaves them to the prior), and the verdict is about the robot
    held += [i for i, nm in enumerate(names) if nm in SHEET_NAMES[3:] + SHAPE_NAMES + WARP_NAMES]
    joints = session.robot.joint_names
    rows = np.flatnonzero(prior.finite)
    return determination(ident.extra["cov"], prior.whitening, rows, names, joints, session.q, held)


def refuse_partial(missing: list[Deficiency]) -> None:
    """Refuse a rank-deficient fit, naming what is unidentifiable and the data that would fix it.

    Raises
    ------
    IdentificationError
        When ``missing`` is not empty.
    """
    if missing:
        k = sum(d.directions for d in missing)
        raise IdentificationError(
            f"the data cannot identify {k} parameter combination{'s' * (k > 1)}: "
            + "; ".join(map(str, missing))
            + " (or pass --allow-partial to write a model marked partial)"
        )
