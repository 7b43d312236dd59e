"""Point-constraint measurements: a tool point held at fixed (possibly unknown) points.

The position-only model of thesis Section 3.1 with the tip identified instead of the beam:
p_t = E(q) p_tool (eq. 3.1.4 without the laser joint), E(q) = e^[S1]q1 ... e^[Sn]qn.
Unknown points (``null`` in session.yaml) are identified with the robot; known distances
between points enter as extra residual rows.

Gauge. With unknown points a rigid motion of the whole world (robot base frame, points)
leaves every residual unchanged, so the base pose (6 DOF) is not observable. It is fixed
explicitly: joint 1's screw is held at nominal (this fixes the base z axis and its line,
4 DOF), and the two joint-2 parameters that a rotation about and a translation along
joint 1's axis would move are held too (2 DOF) -- the base frame is defined by joints 1
and 2, as in Denavit-Hartenberg conventions. Without a known distance the scale is not
observable either; the SVD identifiability report then lists it.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from lasercal.solver.errors import IdentificationError
from lasercal.solver.formats.session import Session
from lasercal.solver.identify.lsq import fit_subspace
from lasercal.solver.identify.prior import make_prior
from lasercal.solver.identify.spot import Identification
from lasercal.solver.kinematics.effects import Extension, require
from lasercal.solver.kinematics.minimal import anchor_heights, link_frame, screw_from_eta
from lasercal.solver.kinematics.model import RobotModel
from lasercal.solver.kinematics.poe import ad, adjoint, dexp_A, poe_chain, space_jacobian

DISTANCE_WEIGHT = 10.0  # a caliper-checked distance counts as ten tip positions


def tips(model: RobotModel, q: np.ndarray, tool: np.ndarray | None = None) -> np.ndarray:
    """Tool-point positions (m, 3) mm: p_t = E(q) p_tool (eq. 3.1.4)."""
    tool = model.tool_point if tool is None else tool
    E = poe_chain(model.screws, q)[:, -1]
    return E[:, :3, :3] @ tool + E[:, :3, 3]


def tip_joint_jacobian(
    model: RobotModel, q: np.ndarray, tool: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Tips (m, 3) and d(tip)/dq (m, 3, n): omega_j x p + v_j."""
    tool = model.tool_point if tool is None else tool
    chain = poe_chain(model.screws, q)
    E = chain[:, -1]
    p = E[:, :3, :3] @ tool + E[:, :3, 3]
    J = space_jacobian(model.screws, chain)
    return p, np.cross(J[:, :3], p[:, :, None], axis=1) + J[:, 3:]


def gauge_holds(model: RobotModel) -> list[int]:
    """Indices (into the 4n joint parameters) held to fix the base pose: joint 1's four, and the
    joint-2 parameters moved by a rotation about / translation along joint 1's axis."""
    S1, S2 = model.screws[0], model.screws[1]
    _, dS2 = screw_from_eta(link_frame(S2), np.zeros(4))
    held = [0, 1, 2, 3]
    for xi in (S1, np.r_[np.zeros(3), S1[:3]]):  # world rotation about joint 1, translation along it
        d_eta = np.linalg.lstsq(dS2, ad(xi) @ S2, rcond=None)[0]
        for k in np.argsort(-np.abs(d_eta)):
            if 4 + k not in held and abs(d_eta[k]) > 1e-9:
                held.append(4 + k)
                break
    return held


class PointParams:
    """Parameters of a point-measurement model: joint etas (minus the gauge), tool point, unknown points."""

    def __init__(self, model: RobotModel, session: Session):
        if model.tool_point is None and session.tool_point is None:
            raise IdentificationError("a point session needs a tool point (tool: {point: [...]})")
        self.model = model
        self.frames = [link_frame(S) for S in model.screws]
        n = model.n
        self.unknown = [nm for nm, p in session.points.items() if p is None]
        held = gauge_holds(model) if self.unknown else []
        self.free = [i for i in range(4 * n) if i not in held]
        self.names = [f"{jn}.{p}" for jn in model.joint_names for p in ("wx", "wy", "qx", "qy")]
        self.names = (
            [self.names[i] for i in self.free]
            + ["tool.x", "tool.y", "tool.z"]
            + [f"{nm}.{c}" for nm in self.unknown for c in "xyz"]
        )
        joint_kinds = ["axis", "axis", "offset", "offset"] * n
        self.kinds = [joint_kinds[i] for i in self.free] + ["tool"] * 3 + ["point"] * 3 * len(self.unknown)
        self.n_free = len(self.free)
        self.size = self.n_free + 3 + 3 * len(self.unknown)
        self.slice_tool = slice(self.n_free, self.n_free + 3)
        self.col = {nm: self.n_free + 3 + 3 * k for k, nm in enumerate(self.unknown)}
        # a model that already has a tool point (an identified one) wins over the session's nominal guess
        self.tool0 = np.asarray(
            model.tool_point if model.tool_point is not None else session.tool_point, float
        )

    def x0(self, session: Session) -> np.ndarray:
        """Start: nominal geometry and tool; each unknown point at the mean of its captures' nominal tips."""
        x = np.zeros(self.size)
        x[self.slice_tool] = self.tool0
        p = tips(self.model, session.q, self.tool0)
        for nm, c in self.col.items():
            x[c : c + 3] = p[session.point == nm].mean(axis=0)
        return x

    def geometry(self, x: np.ndarray):
        """Screws (n, 6), their derivatives (list of (6, 4)), tool point (3,), points dict."""
        eta = np.zeros(4 * len(self.frames))
        eta[self.free] = x[: self.n_free]
        out = [screw_from_eta(T, eta[4 * i : 4 * i + 4]) for i, T in enumerate(self.frames)]
        points = {nm: x[c : c + 3] for nm, c in self.col.items()}
        return np.array([o[0] for o in out]), [o[1] for o in out], x[self.slice_tool], points

    def targets(self, x: np.ndarray, session: Session) -> np.ndarray:
        """(m, 3) point of each capture (identified ones from x)."""
        return session_targets(session, self.geometry(x)[3])

    def to_model(self, x: np.ndarray, **changes) -> RobotModel:
        screws, _, tool, _ = self.geometry(x)
        return self.model.replace(screws=screws, tool_point=tool, **changes)

    def jacobian(self, x: np.ndarray, q: np.ndarray, session: Session) -> tuple[np.ndarray, np.ndarray]:
        """Tips (m, 3) and the residual Jacobian (m, 3, size)."""
        screws, dS, tool, _ = self.geometry(x)
        chain = poe_chain(screws, q)
        E = chain[:, -1]
        p = E[:, :3, :3] @ tool + E[:, :3, 3]
        tw = np.concatenate(
            [adjoint(chain[:, i]) @ (dexp_A(screws[i], q[:, i]) @ dS[i]) for i in range(len(screws))], axis=2
        )
        Jeta = (np.cross(tw[:, :3], p[:, :, None], axis=1) + tw[:, 3:])[
            :, :, self.free
        ]  # eq. 3.1.6 without R_h dp_M
        J = np.zeros((len(q), 3, self.size))
        J[:, :, : self.n_free] = Jeta
        J[:, :, self.slice_tool] = E[:, :3, :3]
        for nm, c in self.col.items():
            J[session.point == nm, :, c : c + 3] = -np.eye(3)
        return p, J

    def distance_rows(self, x: np.ndarray, session: Session) -> tuple[np.ndarray, np.ndarray]:
        """Weighted rows (|P_A - P_B| - d) and their Jacobian, for the known distances."""
        tg = dict(session.points)
        tg.update(self.geometry(x)[3])
        r, J = [], []
        for a, b, dist in session.distances:
            u = tg[a] - tg[b]
            nu = np.linalg.norm(u)
            row = np.zeros(self.size)
            if a in self.col:
                row[self.col[a] : self.col[a] + 3] = u / nu
            if b in self.col:
                row[self.col[b] : self.col[b] + 3] = -u / nu
            r.append(DISTANCE_WEIGHT * (nu - dist))
            J.append(DISTANCE_WEIGHT * row)
        return np.array(r), np.array(J).reshape(len(r), self.size)


@dataclass(frozen=True, eq=False)
class PointProblem:
    """:func:`identify_point`'s model of parameters v = [x, theta] (the robot's and the points' x, then the
    extension's theta): the tips at the true configurations against the reference points, and the known
    distances between points as constraint rows.

    Attributes
    ----------
    P : PointParams
    session : Session, with measurement 'point'
    extension : Extension or None, a joint effect
    idx, G : the extension's joints and regressors (m, k) (:meth:`Extension.regressors`; None without one)
    """

    P: PointParams
    session: Session
    extension: Extension | None
    idx: np.ndarray | None
    G: np.ndarray | None

    @property
    def k(self) -> int:
        return self.extension.size if self.extension else 0

    def true_q(self, v: np.ndarray) -> np.ndarray:
        """The true configurations (m, n) rad under the extension's parameters (the logged ones without)."""
        s, ext = self.session, self.extension
        return ext.with_params(v[self.P.size :]).true_q(s.q, s.t, s.tau) if ext else s.q

    def residual(self, v: np.ndarray) -> np.ndarray:
        """Tip minus reference point, (m, 3) mm."""
        p = self.P.size
        return tips(self.P.to_model(v[:p]), self.true_q(v)) - self.P.targets(v[:p], self.session)

    def jacobian(self, v: np.ndarray) -> np.ndarray:
        """d :meth:`residual` / dv, (m, 3, p + k)."""
        p = self.P.size
        qt = self.true_q(v)
        _, J = self.P.jacobian(v[:p], qt, self.session)
        if not self.extension:
            return J
        _, Jq = tip_joint_jacobian(self.P.to_model(v[:p]), qt)
        return np.concatenate([J, Jq[:, :, self.idx] * self.G[:, None, :]], axis=2)

    def constraints(self, v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The known distances' rows (c,) and their Jacobian (c, p + k)."""
        r, J = self.P.distance_rows(v[: self.P.size], self.session)
        return r, np.hstack([J, np.zeros((len(r), self.k))])


def identify_point(
    session: Session,
    nominal: RobotModel | None = None,
    robust: bool = True,
    extension: Extension | None = None,
    suspects: np.ndarray | None = None,
) -> Identification:
    """Identify screws, tool point and unknown points from point-constraint captures (lm).

    Parameters
    ----------
    session : Session with measurement 'point'
    nominal : RobotModel (default: the session's robot)
    robust : bool, flag outlier captures
    extension : Extension, optional joint effect identified jointly
    suspects : (m,) bool array, optional: the only captures the outlier test may flag (an extension fitted
        on its geometric fit's rows: that fit's outliers; :func:`solver.identify.lsq.fit_subspace`)

    Returns
    -------
    Identification; ``extra['points']`` holds the identified points (mm)
    """
    t0 = time.perf_counter()
    nominal = nominal or session.robot
    P = PointParams(nominal, session)
    idx = G = None
    if extension:
        require(extension, session.t, session.tau)
        if not extension.acts_on_joints:
            raise IdentificationError(f"{extension.effect} does not apply to point measurements")
        idx, G = extension.regressors(session.q, session.t, session.tau)
    prob = PointProblem(P, session, extension, idx, G)
    k = prob.k
    names = P.names + (extension.names if extension else [])
    x0 = np.r_[P.x0(session), np.zeros(k)]
    kinds = P.kinds + (extension.kinds if extension else [])
    fit = fit_subspace(
        prob.residual,
        prob.jacobian,
        x0,
        names,
        robust,
        constraints=prob.constraints if session.distances else None,
        groups=session.positions,
        suspects=suspects,
        prior=make_prior(
            session.tolerances,
            kinds,
            x0,
            "point",
            names,
            nominal.joint_names,
            anchor_heights(nominal.screws, P.tool0),
        ),
    )
    return point_identification(prob, nominal, fit, names, t0)


def point_identification(
    prob: PointProblem, nominal: RobotModel, fit, names: list, t0: float
) -> Identification:
    """The :class:`Identification` of a point session from its fit: the model with its extension, the
    identified points (``extra['points']``, mm), the standard errors (``t0``: the start's
    ``time.perf_counter()``)."""
    P, extension, p, k = prob.P, prob.extension, prob.P.size, prob.k
    se = np.sqrt(np.clip(np.diag(fit.cov), 0, None))
    meta = {
        "method": "lm",
        "measurement": "point",
        "converged": fit.converged,
        "iterations": fit.iterations,
        "rank": fit.identifiability.rank,
        "n_params": p + k,
    }
    fitted = extension.with_params(fit.v[p:], se[p:]) if extension else None
    model = P.to_model(fit.v[:p], identification=meta, extensions=fitted.model_entries() if fitted else {})
    points = {nm: fit.v[c : c + 3].tolist() for nm, c in P.col.items()}
    return Identification.from_fit(
        nominal,
        model,
        fit,
        names,
        se,
        t0,
        {
            "cov": fit.cov,
            "points": points,
            "span": fit.span,
            "constraint_span": fit.constraint_span,
            "constraint_residuals": fit.constraint_residuals,
        },
        fitted,
    )


def polish_point(model: RobotModel, q: np.ndarray, targets: np.ndarray, iters: int = 8) -> np.ndarray:
    """Minimum-norm Newton steps that put each configuration's tool point on its target (m, 3) mm."""
    q = np.array(q, dtype=float)
    for _ in range(iters):
        p, J = tip_joint_jacobian(model, q)
        q = q + np.einsum(
            "mkn,mk->mn",
            J,
            np.linalg.solve(J @ np.swapaxes(J, 1, 2) + 1e-12 * np.eye(3), (targets - p)[..., None])[..., 0],
        )
    return q


def session_targets(session: Session, points: dict) -> np.ndarray:
    """(m, 3) each capture's point, unknown ones taken from ``points`` (identified values)."""
    tg = session.target.copy()
    for nm, p in points.items():
        tg[session.point == nm] = p
    return tg
