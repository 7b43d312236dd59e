"""Full pose from circle points by maximum likelihood: every measured point fitted (issue 15, item 4).

The circle-point method (:mod:`solver.identify.circlepoint`, Sensors 2013 Section 2) reduces the
m points of a configuration to one frame {E} (plane, circle, then x through P_1) and fits the
model to those frames: it keeps P_1's noise in the origin, discards what the other points say
about it, and weights the frames' rotation and position by residual levels, not by the points'
noise. With independent Gaussian sensor noise the maximum-likelihood estimate instead fits every
point y_ij = X E(q_ij) p + e_ij, e_ij ~ N(0, sigma_ij^2 I): exactly the position model of
:mod:`solver.identify.position` (unknowns: the joint screws, the sensor frame X = ^S T_base, the
target p on the last link), with each circle point a position row at its own configuration (the
last joint at that point's angle). The circle-point calibration is its start.

The frame reported stays the circle-point method's {E}, built from the fitted model by
:func:`solver.identify.circlepoint.target_frame`: origin at the target, z along the last joint's
axis, x from the axis to the target; screws and ``ee_pose`` are expressed in {S}, as
:func:`solver.identify.fullpose.calibrate_fullpose` writes them.

Cramer-Rao bound (:func:`frame_crb`): the Fisher information of the points at the truth is
J^T J / sigma^2 (J the position model's Jacobian); its pseudo-inverse in the identifiable subspace
(SVD), C = sigma^2 V S^-2 V^T, propagated through the Jacobian G of {E}'s position and rotation at
held-out configurations, E|d{E}|^2 = tr(G C G^T), bounds any unbiased estimator's error.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
from scipy.spatial.transform import Rotation

from lasercal.solver.formats.fullpose_io import CirclePointData
from lasercal.solver.formats.positions import position_session
from lasercal.solver.formats.session import Session
from lasercal.solver.identify.circlepoint import target_frame
from lasercal.solver.identify.fullpose import (
    Accuracy,
    FullPoseCalibration,
    PoseCrossValidation,
    accuracy,
    calibrate_fullpose,
    fold_accuracy,
    rebased,
)
from lasercal.solver.identify.position import PositionParams, identify_position
from lasercal.solver.identify.spot import Identification
from lasercal.solver.kinematics.model import RobotModel
from lasercal.solver.kinematics.poe import fk

TARGET = "T1"  # the one target of a circle-point session
_FD_STEP = 1e-6  # central-difference step of the {E} Jacobian (rad, mm and unitless eta alike)


def circle_positions(data: CirclePointData, robot: RobotModel, sigma: np.ndarray | None = None) -> Session:
    """Every circle point as a position row: q (g m, n) with the last joint at the point's angle,
    y (g m, 3) mm in {S}, target :data:`TARGET`.

    Parameters
    ----------
    data : CirclePointData, g configurations of m points
    robot : RobotModel, the session's nominal
    sigma : (g, m) array, optional, each point's noise, mm

    Returns
    -------
    Session (measurement 'position'), rows in configuration-major order
    """
    g, m, n = data.q.shape
    return position_session(
        robot,
        data.q.reshape(g * m, n),
        data.points.reshape(g * m, 3),
        np.full(g * m, TARGET, dtype=object),
        None if sigma is None else np.asarray(sigma, dtype=float).reshape(g * m),
        folder=data.path,
    )


def frame_model(model: RobotModel, target: str = TARGET) -> RobotModel:
    """A position model (screws in its base, ``sensor_pose`` X, ``targets``) as the full-pose model of {E}:
    screws Ad_X S in {S} and M = target_frame(Ad_X S_n, X p) (:func:`target_frame`, q = 0)."""
    X = np.asarray(model.sensor_pose)
    p = X[:3, :3] @ model.targets[target] + X[:3, 3]
    S = rebased(model, X, np.eye(4), "re-expressed in the sensor frame {S} (solver.fullpose_ml)")
    return S.replace(ee_pose=target_frame(S.screws[-1], p), sensor_pose=None, targets={})


def position_start(model: RobotModel) -> RobotModel:
    """A full-pose model in {S} (screws, ``ee_pose`` = {E}) as the start of a position fit: X = I and the
    target at {E}'s origin."""
    return model.replace(sensor_pose=np.eye(4), targets={TARGET: np.asarray(model.ee_pose)[:3, 3]})


@dataclass(frozen=True, eq=False)
class PointCalibration:
    """A maximum-likelihood calibration from raw circle points.

    Attributes
    ----------
    nominal : RobotModel, as given
    circle : FullPoseCalibration, the circle-point method's calibration (the start)
    fit : Identification, the position fit of every point (its ``model`` in the start's {S})
    model : RobotModel, the identified {E} model: screws in {S}, ``ee_pose`` {E} at q = 0
    before, after : Accuracy, of the start's nominal and of ``model`` against the circle-point poses
    """

    nominal: RobotModel
    circle: FullPoseCalibration
    fit: Identification
    model: RobotModel
    before: Accuracy
    after: Accuracy

    @property
    def alignment(self):
        """The base and tool transforms estimated for the start (None if not estimated)."""
        return self.circle.alignment


def calibrate_points(
    nominal: RobotModel,
    data: CirclePointData,
    estimate: bool | None = None,
    sigma: np.ndarray | None = None,
    robust: bool = True,
) -> PointCalibration:
    """Maximum-likelihood full-pose calibration from circle points (module docstring).

    Parameters
    ----------
    nominal : RobotModel
    data : CirclePointData
    estimate : bool, optional, estimate base and tool first for the circle-point start (as
        :func:`calibrate_fullpose`)
    sigma : (g, m) array, optional, each point's noise, mm (rows weighted by it)
    robust : bool, flag outlying points as position sessions do

    Returns
    -------
    PointCalibration
    """
    q, T = data.poses()
    circle = calibrate_fullpose(nominal, q, T, estimate)
    start = position_start(circle.model)
    fit = identify_position(circle_positions(data, start, sigma), start, robust)
    model = frame_model(fit.model)
    return PointCalibration(
        nominal, circle, fit, model, circle.before, accuracy(T, fk(model.screws, model.ee_pose, q))
    )


def cross_validate_points(
    nominal: RobotModel, data: CirclePointData, k: int = 5, seed: int = 0, estimate: bool | None = None
) -> PoseCrossValidation:
    """K-fold cross-validation of :func:`calibrate_points` over configurations, in the Table 4 form of
    :func:`solver.identify.fullpose.cross_validate` (held-out circle-point poses vs the predicted {E})."""
    q, T = data.poses()

    def calibrate(train):
        sub = replace(data, q=data.q[train], points=data.points[train], lines=data.lines[train])
        sub = replace(sub, labels=tuple(data.labels[i] for i in train))
        cal = calibrate_points(nominal, sub, estimate)
        return cal.circle.fit.reference, cal.model, cal.fit.identifiability.rank

    return fold_accuracy(q, T, k, seed, calibrate)


# ----------------------------------------------------------------------- errors of {E} and their bound
def frame_error_norms(T: np.ndarray, T_ref: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """|p - p_ref| (mm) and the rotation angle of R_ref^T R (rad) of frames (m, 4, 4): (m,), (m,)."""
    dR = np.swapaxes(T_ref[:, :3, :3], -1, -2) @ T[:, :3, :3]
    return np.linalg.norm(T[:, :3, 3] - T_ref[:, :3, 3], axis=1), Rotation.from_matrix(dR).magnitude()


def frame_crb(truth: RobotModel, q: np.ndarray, sigma_mm: float, q_eval: np.ndarray) -> tuple[float, float]:
    """Cramer-Rao prediction of the held-out RMS position and rotation error of {E} (module docstring).

    Parameters
    ----------
    truth : RobotModel, a position model (``sensor_pose``, ``targets[TARGET]``): the true geometry
    q : (M, n) array, the configurations of every measured point, rad
    sigma_mm : float, the sensor noise per axis, mm
    q_eval : (h, n) array, held-out configurations, rad

    Returns
    -------
    pos : float, sqrt(mean_h tr(G_p C G_p^T)), mm
    rot : float, sqrt(mean_h tr(G_r C G_r^T)), rad
    """
    P = PositionParams(truth, [TARGET])
    X0 = np.asarray(truth.sensor_pose)
    x0 = np.zeros(P.size)
    x0[P.col[TARGET] : P.col[TARGET] + 3] = truth.targets[TARGET]
    _, J, _ = P.jacobian(x0, X0, q, np.full(len(q), TARGET, dtype=object))
    _, s, Vt = np.linalg.svd(J.reshape(-1, P.size), full_matrices=False)
    keep = s > s[0] * 1e-10  # the identifiable subspace: never invert a rank-deficient normal matrix
    C = sigma_mm**2 * (Vt[keep].T / s[keep] ** 2) @ Vt[keep]

    def frames(x):
        E = frame_model(P.to_model(x, X0))
        return fk(E.screws, E.ee_pose, q_eval)

    G = np.zeros((len(q_eval), 6, P.size))
    for j in range(P.size):
        h = np.zeros(P.size)
        h[j] = _FD_STEP
        Tp, Tm = frames(x0 + h), frames(x0 - h)
        G[:, :3, j] = (Tp[:, :3, 3] - Tm[:, :3, 3]) / (2 * _FD_STEP)
        dR = np.swapaxes(Tm[:, :3, :3], -1, -2) @ Tp[:, :3, :3]
        G[:, 3:, j] = Rotation.from_matrix(dR).as_rotvec() / (2 * _FD_STEP)
    cov = G @ C @ G.transpose(0, 2, 1)
    tr_p = np.trace(cov[:, :3, :3], axis1=1, axis2=2)
    tr_r = np.trace(cov[:, 3:, 3:], axis1=1, axis2=2)
    return float(np.sqrt(tr_p.mean())), float(np.sqrt(tr_r.mean()))
