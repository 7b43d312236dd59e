"""Model discrepancy: where measured data disagree with the geometric model, which effect explains it.

Procedure (documented in README "Diagnosis"):

1. Fit the geometric model (``lm``). Its residuals should be aiming noise: unstructured,
   of one size.
2. Test every candidate extension of :mod:`solver.effects` (each effect on each joint, or
   an offset of each reference point) against the geometric model with a nested-model
   F test, linearised at the geometric solution (the score form: the residual's squared
   projection on the candidate's columns after removing what the geometry can already
   explain). Candidate p-values are Bonferroni-corrected over all candidates. The
   smallest corrected p-value below ``alpha`` names the effect; further joints of the same
   effect are added while their conditional test (after refitting) stays significant.
   Otherwise the answer is ``none``.
3. Show the disagreement by simulation: a parametric bootstrap re-runs the experiment on
   the identified geometric robot (same poses, the estimated aiming noise) -- many
   first-order replicates recompute the strongest candidate's statistic (the measured
   value's rank among them is a significance level that needs no F-distribution
   assumption), and a few full nonlinear re-simulations with refits give the residual
   size the experiment should show.
4. Accept by held-out data, not only by the F test: fit the winning extension jointly with
   the geometry and cross-validate both models on the same grouped folds (a point session
   leaves one tool position out, :func:`solver.analysis.stats.grouped_folds`). The extension
   is kept only when its held-out RMS is smaller than the geometric model's; otherwise the
   finding is ``none``, with the numbers (per-fold gains and their confidence interval).
   Without cross-validation (``k`` < 2) the F test decides alone, and the result says so.

Effects that need what the session lacks (drift without a real clock, ``clock: order``;
compliance without torques or a gravity model) are not candidates; ``untested`` says which
and why.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field, replace

import numpy as np
from scipy.special import (
    chdtrc,  # survival function of the chi^2 distribution (scipy.stats.chi2.sf)
    fdtrc,  # survival function of the F distribution (scipy.stats.f.sf)
    stdtrit,  # quantile of Student's t (scipy.stats.t.ppf)
)

from lasercal.solver.analysis import ALPHA
from lasercal.solver.analysis.nested import fold_agreement, nested_holdout
from lasercal.solver.analysis.stats import (
    HeldOut,
    capture_kinds,
    carriers,
    grouped_folds,
    held_out_all,
    nested_fitter,
    rms_by_kind,
)
from lasercal.solver.errors import IdentificationError, ModelError
from lasercal.solver.formats.session import Session
from lasercal.solver.identify.degenerate import DATA_RATIO
from lasercal.solver.identify.measurement import fit, residuals
from lasercal.solver.identify.point import polish_point, session_targets, tip_joint_jacobian
from lasercal.solver.identify.position import point_joint_jacobian, sensor_points
from lasercal.solver.identify.spot import Identification, base_targets, placed_targets, sheet_start
from lasercal.solver.kinematics.aim import polish
from lasercal.solver.kinematics.effects import (
    ROBOT_EFFECTS,
    Combination,
    Extension,
    candidates,
    combine,
    drift_t0,
    untested,
)
from lasercal.solver.kinematics.gravity import gravity_torques, model_torques
from lasercal.solver.kinematics.joint_map import POSITION_STEP_RAD, JointMap, with_joint_map
from lasercal.solver.kinematics.laser import spot_joint_jacobian
from lasercal.solver.kinematics.sheet import sheet_residual
from lasercal.solver.streams import Seed, root, stream

_RTOL = 1e-6
# 0.1 um: a candidate that explains less than this (root of its drop in squared residual, mm) explains
# round-off, not an effect -- exact data leave residuals of 1e-13 mm whose pattern an F test may find
# "significant" (as the outlier test's floor, solver/identify/lsq.py)
ROUNDOFF_MM = 1e-4
_AMBIGUOUS = (
    0.97  # a runner-up explaining this share of the winner's residual drop is reported as indistinguishable
)


@dataclass(frozen=True)
class CandidateTest:
    """Nested-model F test of one candidate extension against the current model."""

    extension: Extension
    F: float
    df: int
    p: float
    p_adjusted: float
    rss_drop: float

    @property
    def label(self) -> str:
        e = self.extension
        return f"{e.effect}[{e.point}]" if e.point else f"{e.effect}[joint {','.join(e.tags)}]"


@dataclass(frozen=True, eq=False)
class Diagnosis:
    """The finding, with the evidence.

    Attributes
    ----------
    effect : str, one of effects.EFFECTS
    extension : Extension or None, the fitted effect with standard errors
    p_value : float, Bonferroni-corrected p of the first selected candidate (or of the best one, for 'none')
    tests : list of CandidateTest, every candidate against the geometric model, best first
    geometric, extended : Identification
    holdout_rms : dict 'geometric'/'extended' -> mm, K-fold cross-validated, over the captures
        the robust geometric fit does not flag as outliers
    bootstrap : dict, the simulated distribution of the best statistic and of the residual RMS
    torque_source : str, 'logged' or 'gravity model' or 'none'
    seconds : float
    session : Session, the diagnosed session (with the torques used)
    residuals_holdout : dict 'geometric'/'extended' -> (m, 2) cross-validated residuals, mm
    ambiguous_with : tuple of str, candidates that explain the data (nearly) as well as the winner
        -- e.g. with three reference points an offset of any one of them looks alike, because the
        geometry absorbs a planar similarity of the whole layout
    proposed : Extension or None, the F test's choice (fitted), kept or not
    acceptance : dict, the held-out decision: 'decided_by' ('cross-validation' or 'F test only'),
        'accepted', 'folds', 'grouping', 'failed_folds', 'fold_rms_mm' (model -> per fold; a camera
        session's in units of each capture's noise, :func:`acceptance`), 'gain_percent_folds',
        'gain_percent_ci95', 'holdout_by_kind' (a camera session: kind -> model -> held-out RMS mm);
        'selection' (how the folds chose), and with ``--extend auto`` the outer folds' own choices
        (:func:`~lasercal.solver.analysis.nested.fold_agreement`: 'fold_choices', 'folds_agree',
        'folds_same_cause', 'folds_needed', 'folds_agreed', 'disagreement')
    statistics : dict, model ('nominal', 'geometric', 'extended') -> 'train' and 'holdout' RMS, mm
        (over the captures the robust geometric fit keeps; holdout None without cross-validation)
    untested : dict effect -> why the data cannot test it
    robust : bool, whether the robust loss was used (in every fit, folds included)
    unseen : dict candidate label -> posterior / prior sigma: candidates the data cannot see beyond the
        geometry (the prior would determine them), never tested or selected (:class:`Tester`)
    """

    effect: str
    extension: Extension | None
    p_value: float
    tests: list
    geometric: Identification
    extended: Identification | None
    holdout_rms: dict
    bootstrap: dict
    torque_source: str
    seconds: float
    residuals_holdout: dict = field(default_factory=dict)
    ambiguous_with: tuple = ()
    session: Session | None = None
    proposed: Extension | None = None
    acceptance: dict = field(default_factory=dict)
    statistics: dict = field(default_factory=dict)
    untested: dict = field(default_factory=dict)
    robust: bool = True
    unseen: dict = field(default_factory=dict)

    @property
    def robot_extension(self) -> Extension | Combination | None:
        """The kept extension if it is a robot effect (what MODEL.yaml carries), else None."""
        e = self.extension
        return e if e is not None and all(p.effect in ROBOT_EFFECTS for p in e.parts) else None

    @property
    def gain_percent(self) -> float:
        g, e = self.holdout_rms["geometric"], self.holdout_rms["extended"]
        return float(100.0 * (g - e) / g) if g > 0 else 0.0

    def as_dict(self) -> dict:
        """The ``lasercal diagnose --json`` object."""
        ext = self.extension
        t0 = drift_t0(ext)
        params = {}
        if ext is not None:
            for nm, v, se, u in zip(
                ext.names,
                ext.params,
                ext.std_errors if ext.std_errors is not None else [np.nan] * ext.size,
                ext.units,
            ):
                params[nm] = {"value": float(v), "std_error": float(se), "units": u}
        return {
            "effect": self.effect,
            "joints": [int(j) for j in ext.joints] if ext else [],
            "point": ext.point if ext else None,
            "parts": [{"effect": e.effect, "joints": [int(j) for j in e.joints]} for e in ext.parts]
            if ext
            else [],
            "label": ext.label if ext else "none",
            "parameters": params,
            **({} if t0 is None else {"t0_s": round(t0, 6)}),
            "p_value": float(self.p_value),
            "holdout_rms_mm": {k: round(float(v), 6) for k, v in self.holdout_rms.items()},
            "gain_percent": round(self.gain_percent, 3),
            "proposed": None
            if self.proposed is None
            else {
                "effect": self.proposed.effect,
                "joints": [int(j) for j in self.proposed.joints],
                "point": self.proposed.point,
            },
            "acceptance": self.acceptance,
            "statistics": self.statistics,
            "untested": dict(self.untested),
            "unseen": {k: round(v, 4) for k, v in self.unseen.items()},
            "exported": self.robot_extension is not None,
            "robust": self.robust,
            "details": {
                "alpha": ALPHA,
                "bootstrap_p_value": self.bootstrap.get("p_value"),
                "bootstrap_replicates": self.bootstrap.get("replicates"),
                "torques": self.torque_source,
                "ambiguous_with": list(self.ambiguous_with),
                "seconds": round(self.seconds, 3),
                "candidates": [
                    {
                        "candidate": t.label,
                        "F": round(t.F, 4),
                        "df": t.df,
                        "p": float(f"{t.p:.4g}"),
                        "p_adjusted": float(f"{t.p_adjusted:.4g}"),
                    }
                    for t in self.tests[:8]
                ],
            },
        }


# The torque sensor's noise (std, Nm) a session with logged torques is read with (none states its own): the
# simulated Panda's and the fake arm's sensor noise (tau_noise of solver/analysis/simulate.py and of
# collector/hardware/fake.py; docs/sessions.md, "gravity torques of the true robot + 0.05 Nm noise").
TORQUE_NOISE_NM = 0.05
# A logged-torque regressor (a compliance's tau_j) is testable when its std over the captures is at least this
# many times the sensor's noise: the noise is then at most 1 / 5^2 = 4 % of its variance, and a compliance
# fitted to it is one of the load (attenuated by at most 4 %, errors in variables), not of the sensor's
# noise. A vertical joint 1 carries no gravity load: its logged torque is the noise alone (issue 45's camera
# world, seed 1: a joint-1 compliance named on 0.11 Nm of it).
TORQUE_SPREAD_RATIO = 5.0


def noise_dominated(exts: list, session: Session, tau: np.ndarray, noise: float = TORQUE_NOISE_NM) -> dict:
    """Candidates whose regressor is a logged torque that the sensor's noise dominates, with the reason.

    Parameters
    ----------
    exts : list of Extension, the candidates
    session : Session, the captures (q, t)
    tau : (m, n) array, the logged joint torques, Nm
    noise : float, the torque sensor's noise (std), Nm

    Returns
    -------
    dict label -> why it is not tested: the regressor's std over the captures below
    :data:`TORQUE_SPREAD_RATIO` x ``noise``
    """
    out = {}
    for e in exts:
        if "tau" not in e.needs():
            continue
        spread = float(np.min(e.regressors(session.q, session.t, tau)[1].std(axis=0)))
        if spread < TORQUE_SPREAD_RATIO * noise:
            out[e.label] = (
                f"the logged torque varies by {spread:.3g} Nm (std over the captures), less than "
                f"{TORQUE_SPREAD_RATIO:g} x the torque sensor's {noise:g} Nm noise: a compliance fitted to "
                "it would be fitted to the sensor's noise, not to a load"
            )
    return out


def session_torques(session: Session, payload=None) -> tuple[np.ndarray | None, str]:
    """Logged joint torques, or the robot's gravity model at the logged poses (with
    :func:`carried_payload`), or None."""
    if session.tau is not None:
        return session.tau, "logged"
    if session.measurement == "position":  # URDFs of industrial arms often carry no inertias
        return model_torques(session.robot, session.q)
    if session.robot.links:
        return gravity_torques(session.robot, session.q, carried_payload(session, payload)), "gravity model"
    return None, "none"


def carried_payload(session: Session, payload=None):
    """The payload :func:`session_torques` puts in a session's torques: ``payload`` when they come from
    the gravity model of a serial robot (a laser or point session that logs none), else None (logged
    torques, a position session's, a tree's, a robot without a gravity model). What ``solve`` records.

    Parameters
    ----------
    session : Session
    payload : (mass kg, (3,) centre of mass at q = 0 in mm), or None

    Returns
    -------
    ``payload`` or None
    """
    uses = session.tau is None and session.measurement != "position" and session.robot.links
    return payload if uses and not session.robot.parents else None


def joint_jacobian(session: Session, model, q: np.ndarray) -> np.ndarray:
    """d(residual)/dq (m, d, n) of the fitted model: spot in the plane, or tool point."""
    if session.measurement == "position":  # in the sensor frame
        P = np.array([model.targets[nm] for nm in session.point])
        return model.sensor_pose[:3, :3] @ point_joint_jacobian(model, q, P, session.point)[1]
    if session.measurement == "point":
        return tip_joint_jacobian(model, q)[1]
    if session.frame != "sheet":
        return spot_joint_jacobian(model, q, session.target[:, 2])[1]
    pose = model.sheet or sheet_start(session, model)  # in the sheet's own units, as lm fits (eq. S4)
    J = spot_joint_jacobian(model, q, placed_targets(session, pose)[:, 2])[1]
    return np.einsum("ij,mjk->mik", sheet_residual(pose.vector, np.zeros((1, 2)))[1], J)


def _candidate_columns(ext: Extension, session: Session, Jq: np.ndarray, tau) -> np.ndarray:
    """d(residual)/d(parameters) of a candidate at zero effect, (m, 2, k)."""
    m = session.m
    if ext.effect == "reference_point_offset":  # laser sessions only: point sessions identify their points
        C = np.zeros((m, 2, 2))
        C[(session.point == ext.point) & ~session.measured] = -np.eye(2)  # a measured spot uses no point
        return C
    idx, G = ext.regressors(session.q, session.t, tau)
    return Jq[:, :, idx] * G[:, None, :]


def _orthonormal(A: np.ndarray) -> np.ndarray:
    """Orthonormal basis of the column space of A (rank by SVD with a relative tolerance)."""
    if A.shape[1] == 0:
        return A
    scale = np.linalg.norm(A, axis=0)
    scale[scale == 0] = 1.0
    U, s, _ = np.linalg.svd(A / scale, full_matrices=False)
    return U[:, : int(np.sum(s > _RTOL * max(s[0], 1e-300)))]


class Tester:
    """Nested-model F tests of candidate extensions against a fitted model (linearised at its solution).

    F = (drop / k) / ((RSS - drop) / (N - r - k)), drop = |Q^T res|^2 with Q the candidate's
    columns made orthogonal to what the fit could absorb (rank r); Bonferroni over the candidates.
    Prepared once, it tests any residual vector: the data's, or simulated ones.

    Under a prior (the session's tolerances) a candidate the data cannot see is no candidate: with
    C_perp its columns beyond the fit's span and s its prior sigmas, the data's information in units of
    the prior's is the smallest eigenvalue S^2 of (C_perp s)^T (C_perp s) / sigma^2, and the posterior
    sigma of that term would be at least 1 / sqrt(1 + S^2) of its prior sigma (eq. P5). A term whose
    ratio exceeds DATA_RATIO (the prior, not the data, would determine it; e.g. a compliance at a
    joint that carries almost no torque) is set aside in ``unseen`` and never tested or selected.

    Parameters
    ----------
    session : Session
    ident : Identification, the fitted model (geometric, or already extended)
    exts : list of Extension, the candidates
    tau : (m, n) array or None

    Attributes
    ----------
    exts : list of Extension, the candidates tested (those the data can see)
    unseen : dict label -> posterior / prior sigma, the candidates set aside
    """

    def __init__(self, session: Session, ident: Identification, exts: list, tau):
        used = ident.weights > 0
        qt = ident.extension.true_q(session.q, session.t, tau) if ident.extension else session.q
        Jq = joint_jacobian(session, ident.model, qt)
        d = ident.residuals.shape[1]  # 2 (spot in the plane) or 3 (tool point)
        # What the fit could absorb: its Jacobian in its own identifiable subspace (extension included),
        # with its constraint rows -- without them a world scaling, which scales every residual, would
        # seem to explain any residual (the known distances are what pin the scale).
        Jc = ident.extra.get("constraint_span", np.zeros((0, ident.extra["span"].shape[2])))
        self.U = _orthonormal(np.vstack([ident.extra["span"][used].reshape(d * used.sum(), -1), Jc]))
        self.n_capture_rows = d * used.sum()
        # a camera session's fit weighs each capture by its own noise (eq. K1): tested on the same scale
        scale = ident.extra.get("scale", np.ones(len(used)))[:, None]
        self.res = np.r_[
            (ident.residuals / scale)[used].ravel(), ident.extra.get("constraint_residuals", np.zeros(0))
        ]
        self.exts, self.Q, self.C, self.unseen = [], [], [], {}
        tol = session.tolerances
        for e in exts:
            C = np.vstack(
                [
                    (_candidate_columns(e, session, Jq, tau) / scale[..., None])[used].reshape(
                        self.n_capture_rows, -1
                    ),
                    np.zeros((len(Jc), e.size)),
                ]
            )
            C_perp = C - self.U @ (self.U.T @ C)
            if tol is not None:
                A = C_perp * tol.std(e.kinds)
                S2 = float(np.linalg.eigvalsh(A.T @ A)[0]) / max(ident.sigma_mm, 1e-12) ** 2
                ratio = 1.0 / np.sqrt(1.0 + S2)
                if ratio > DATA_RATIO:
                    self.unseen[e.label] = float(ratio)
                    continue
            self.exts.append(e)
            self.Q.append(_orthonormal(C_perp))
            self.C.append(C)

    def tests(self, res: np.ndarray | None = None) -> list[CandidateTest]:
        """Every candidate's test on ``res`` (default: the data's residuals), best first."""
        res = self.res if res is None else res
        rss, N, r = float(res @ res), res.size, self.U.shape[1]
        out = []
        for e, Q in zip(self.exts, self.Q):
            k = Q.shape[1]
            if k == 0 or N - r - k <= 0:
                out.append(CandidateTest(e, 0.0, 0, 1.0, 1.0, 0.0))
                continue
            drop = float(np.sum((Q.T @ res) ** 2))
            F = (drop / k) / max((rss - drop) / (N - r - k), 1e-300)
            p = float(fdtrc(k, N - r - k, F)) if drop > ROUNDOFF_MM**2 else 1.0
            out.append(CandidateTest(e, F, k, p, min(1.0, p * len(self.exts)), drop))
        return sorted(out, key=lambda c: (c.p, -c.F))

    def best_statistic(self, R: np.ndarray) -> np.ndarray:
        """max over candidates of -log10 p for each column of R (N, B): vectorised for simulations."""
        rss = np.sum(R**2, axis=0)
        N, r = R.shape[0], self.U.shape[1]
        best = np.zeros(R.shape[1])
        for Q in self.Q:
            k = Q.shape[1]
            if k == 0 or N - r - k <= 0:
                continue
            drop = np.sum((Q.T @ R) ** 2, axis=0)
            F = (drop / k) / np.maximum((rss - drop) / (N - r - k), 1e-300)
            p = np.where(drop > ROUNDOFF_MM**2, fdtrc(k, N - r - k, F), 1.0)
            best = np.maximum(best, -np.log10(np.maximum(p, 1e-300)))
        return best


LINEAR_SELECTION = 40  # more candidates than this: terms selected on the linearisation (one fit at the end)


def linear_selection(tester: Tester, alpha: float) -> list[CandidateTest]:
    """Forward selection of single-joint terms on the linearisation at the fitted model.

    For a robot with many candidates (a humanoid's joint and lateral compliances: one refit per added
    term would cost a nonlinear fit each) the nested F test of :class:`Tester` is repeated with the
    chosen terms' columns added to what the fit absorbs: at each step the candidate with the smallest
    p (columns and residual made orthogonal to the fit's span and the chosen terms' columns) is added
    while its p, Bonferroni-corrected over the remaining candidates, is below ``alpha``. Exact for
    effects small enough that the model is linear in them (a compliance bends a joint milliradians).

    Returns
    -------
    list of CandidateTest, the chosen terms in the order chosen (joint effects only)
    """
    U, res = tester.U, tester.res.copy()
    N = res.size
    rest = [i for i, e in enumerate(tester.exts) if e.acts_on_joints]
    chosen = []
    while rest:
        r, rss = U.shape[1], float(res @ res)
        best = None
        for i in rest:
            Q = _orthonormal(tester.C[i] - U @ (U.T @ tester.C[i]))
            k = Q.shape[1]
            if k == 0 or N - r - k <= 0:
                continue
            drop = float(np.sum((Q.T @ res) ** 2))
            F = (drop / k) / max((rss - drop) / (N - r - k), 1e-300)
            p = float(fdtrc(k, N - r - k, F)) if drop > ROUNDOFF_MM**2 else 1.0
            if best is None or (p, -F) < (best[0], -best[1]):
                best = (p, F, k, i, Q, drop)
        if best is None or best[0] * len(rest) >= alpha:
            break
        p, F, k, i, Q, drop = best
        chosen.append(CandidateTest(tester.exts[i], F, k, p, min(1.0, p * len(rest)), drop))
        U, res = np.hstack([U, Q]), res - Q @ (Q.T @ res)
        rest.remove(i)
    return chosen


STEPWISE_ROUNDS = 4  # at most this many rounds of linearised forward selection, refit and pruning


def stepwise_selection(session: Session, geo: Identification, exts: list, tau, alpha: float, sus):
    """Terms chosen by :func:`linear_selection` at the current fit, refitted, pruned, repeated.

    A round adds the terms the linearisation at the current fit selects, refits them all (one nonlinear
    fit), and drops every term whose Wald test at that fit (chi^2 of its parameters over their standard
    errors, Bonferroni over the terms) is no longer significant -- a term chosen where the geometric fit
    had absorbed part of another's signal -- and refits; until a round changes nothing.

    Returns
    -------
    (Extension or Combination, Identification of it) or (None, None) when no term is chosen
    """
    chosen, ext_fit = [], geo
    for _ in range(STEPWISE_ROUNDS):
        have = {(t.effect, t.joints) for t in chosen}
        rest = [e for e in exts if (e.effect, e.joints) not in have]
        new = [t.extension for t in linear_selection(Tester(session, ext_fit, rest, tau), alpha)]
        if not new and chosen:
            break
        chosen += new
        if not chosen:
            return None, None
        ext_fit = _fit(session, _merge(chosen), sus)
        fitted = {(e.effect, j): pairs for e in ext_fit.extension.parts for j, pairs in _per_joint(e)}
        p = [
            float(chdtrc(t.size, sum((c / max(s, 1e-300)) ** 2 for c, s in fitted[(t.effect, t.joints[0])])))
            for t in chosen
        ]
        keep = [t for t, pi in zip(chosen, p) if pi * len(chosen) < alpha]
        if len(keep) == len(chosen):
            if not new:
                break
            continue
        chosen = keep
        if not chosen:
            return None, None
        ext_fit = _fit(session, _merge(chosen), sus)
    return _merge(chosen), ext_fit


def _per_joint(e: Extension):
    """(joint, [(value, std error) of its parameters]) of a fitted single-effect extension."""
    per = e.size // len(e.joints)
    se = e.std_errors if e.std_errors is not None else np.full(e.size, np.inf)
    for k, j in enumerate(e.joints):
        yield j, list(zip(e.params[k * per : (k + 1) * per], se[k * per : (k + 1) * per]))


def score_tests(session: Session, ident: Identification, exts: list, tau) -> list[CandidateTest]:
    """:class:`Tester` on the data's residuals (the candidates the data can see), best first."""
    return Tester(session, ident, exts, tau).tests()


_NO_TEST = CandidateTest(Extension("none"), 0.0, 0, 1.0, 1.0, 0.0)  # no candidate the data can see


def best_test(session: Session, ident: Identification, exts: list, tau) -> CandidateTest:
    """The best of :func:`score_tests`, or a test that never passes when there is no candidate to test."""
    return (score_tests(session, ident, exts, tau) or [_NO_TEST])[0]


def bootstrap(
    session: Session, ident: Identification, tester: Tester, B: int, n_refit: int, rng: Seed
) -> dict:
    """Parametric bootstrap: the experiment re-simulated on the identified geometric robot.

    Two levels. (1) ``B`` first-order simulations: Gaussian aiming noise at the estimated
    sigma on the same poses, refitted to first order (the residual is the noise minus its
    projection on what the fit absorbs), tested like the data -- this calibrates the
    strongest-candidate statistic, multiple comparisons included, with no F-distribution
    assumption. (2) ``n_refit`` full simulations (the robot's true configurations polished onto
    noisy targets, a nonlinear refit) give the residual RMS the experiment should show.
    """
    seed = root(rng)
    N = tester.res.size
    E = np.zeros((N, B))
    E[: tester.n_capture_rows] = stream(seed, "replicates").normal(
        0, ident.sigma_mm, (tester.n_capture_rows, B)
    )
    R = E - tester.U @ (tester.U.T @ E)
    best = tester.best_statistic(R)
    observed = float(tester.best_statistic(tester.res[:, None])[0])
    used = ident.weights > 0
    s = session.subset(used)
    point = s.measurement == "point"
    target = session_targets(s, ident.extra.get("points", {})) if point else base_targets(s, ident.model)
    rms = []
    for i in range(n_refit):
        rng = stream(seed, "refit", i)  # one stream per refit: a refit's draws never shift another's
        if s.measurement == "position":  # the sensor's noise is on the positions, the poses are exact
            yb = sensor_points(ident.model, s.q, s.point) + rng.normal(0, ident.sigma_mm, s.target.shape)
            rms.append(fit(replace(s, target=yb), nominal=ident.model, robust=False).rms_mm)
            continue
        if point:
            qb = polish_point(ident.model, s.q, target + rng.normal(0, ident.sigma_mm, target.shape))
        else:
            each = ident.sigma_mm * ident.extra.get("scale", np.ones(len(used)))[used]  # eq. K1: own noise
            qb = polish(
                ident.model, s.q, target + np.c_[rng.normal(0, 1.0, (s.m, 2)) * each[:, None], np.zeros(s.m)]
            )
        rms.append(fit(replace(s, q=qb), nominal=ident.model, robust=False).rms_mm)
    return {
        "replicates": B,
        "refits": n_refit,
        "best_stat": best.tolist(),
        "rms_mm": rms,
        "observed_best_stat": observed,
        "observed_rms_mm": ident.rms_mm,
        "p_value": float((1 + np.sum(best >= observed)) / (B + 1)),
    }


def _ci95(x: np.ndarray) -> list | None:
    """Student-t 95 % confidence interval of the mean of x (finite values; None with fewer than 2)."""
    x = x[np.isfinite(x)]
    if len(x) < 2:
        return None
    h = stdtrit(len(x) - 1, 0.975) * x.std(ddof=1) / np.sqrt(len(x))
    return [float(x.mean() - h), float(x.mean() + h)]


def acceptance(
    h_geo: HeldOut, h_ext: HeldOut, keep: np.ndarray, grouping: str, scale=None, counted=None
) -> dict:
    """The held-out decision on one extension: kept when its pooled held-out error beats the geometry's.

    The decision weighs each capture's held-out residual by its own noise, r_i / c_i (eq. K1's c_i: a
    camera session's measured captures at the camera's noise, its aimed ones at the aiming noise), so that
    every capture speaks in the same units whatever its kind (an effect only aimed captures show, a point
    offset, is judged by them). The figures reported (mm) are those of the ``counted`` captures.

    Parameters
    ----------
    h_geo, h_ext : HeldOut, the two models' cross-validations on the same folds
    keep : (m,) bool array, the captures that decide (the robust geometric fit's inliers)
    grouping : str, how the folds were formed (for the report)
    scale : (m,) array or None, c_i, each capture's noise relative to the fit's reference (default ones)
    counted : (m,) bool array or None, the captures the mm figures count (default ``keep``)
    """
    ok = keep & np.all(np.isfinite(h_geo.residuals), axis=1) & np.all(np.isfinite(h_ext.residuals), axis=1)
    w = np.ones(len(ok)) if scale is None else 1.0 / np.asarray(scale)
    mine = ok & (True if counted is None else counted)

    def rms(h, sel, weight=1.0):
        return float(np.sqrt(np.mean(np.sum((h.residuals * weight)[sel] ** 2, axis=1))))

    pair = (("geometric", h_geo), ("extended", h_ext))
    rms_mm = {k: rms(h, mine) for k, h in pair}
    decide = {k: rms(h, ok, w[:, None]) for k, h in pair}
    fg, fe = (HeldOut(h.residuals * w[:, None], h.fold, h.failed).fold_rms(ok) for _, h in pair)
    gains = 100.0 * (fg - fe) / fg
    return {
        "decided_by": "cross-validation",
        "accepted": bool(decide["extended"] < decide["geometric"]),
        "holdout_rms_mm": rms_mm,
        **({} if scale is None else {"holdout_rms_noise_units": decide}),
        "folds": len(fg),
        "grouping": grouping,
        "failed_folds": {str(i): why for i, why in {**h_geo.failed, **h_ext.failed}.items()},
        "fold_rms_mm": {"geometric": fg.tolist(), "extended": fe.tolist()},
        "gain_percent_folds": gains.tolist(),
        "gain_percent_ci95": _ci95(gains),
    }


def _grow(session: Session, first: Extension, fixed: list, exts: list, tau, alpha: float, sus):
    """Forward selection of one effect's joints: start at ``first`` and add the joint of the same effect
    whose conditional score test (Bonferroni over the remaining joints, at the refit) is significant, while
    one is. ``fixed`` are other effects fitted alongside (a combination's first part). ``sus``: the
    :func:`_fit` arguments (robust loss, the geometric fit's outliers as the only suspects).

    Returns
    -------
    (Extension, the grown effect), (Identification, the fit of ``fixed`` + it)
    """
    grown = first
    ext_fit = _fit(session, combine(fixed + [grown]), sus)
    if first.effect == "reference_point_offset":
        return grown, ext_fit
    while True:
        rest = [e for e in exts if e.effect == grown.effect and e.joints[0] not in grown.joints]
        if not rest:
            return grown, ext_fit
        nxt = best_test(session, ext_fit, rest, tau)
        if nxt.p_adjusted >= alpha:
            return grown, ext_fit
        grown = replace(
            grown,
            joints=tuple(sorted(grown.joints + nxt.extension.joints)),
            params=np.zeros(grown.size + nxt.extension.size),
        )
        ext_fit = _fit(session, combine(fixed + [grown]), sus)


def _fit(session: Session, extension, sus) -> Identification:
    """An extension fitted on the geometric fit's rows: ``sus`` = (robust, that fit's outliers), the only
    captures its outlier test may flag (:mod:`solver.identify.lsq`, nested fits)."""
    return fit(session, extension, robust=sus[0], suspects=sus[1])


def _merge(terms: list) -> Extension | Combination:
    """One extension from single-joint terms: an Extension per effect (joints sorted), combined."""
    parts = []
    for eff in dict.fromkeys(t.effect for t in terms):
        mine = [t for t in terms if t.effect == eff]
        joints = tuple(sorted(j for t in mine for j in t.joints))
        parts.append(replace(mine[0], joints=joints, params=np.zeros(sum(t.size for t in mine))))
    return combine(parts)


def _combination(
    session: Session, chosen: Extension, ext_fit: Identification, exts: list, tau, alpha: float, sus
) -> dict | None:
    """The other robot effect on further joints, given the chosen one.

    Proposed when its score test (Bonferroni over its joints, at the chosen effect's fit) is significant;
    its joints are grown like the first effect's. Then every term (one effect on one joint) must pass the
    nested F test given all the others (score test at the fit without it, Bonferroni over the terms): the
    least significant failing term is dropped and the rest retested -- e.g. eccentricity on the joint
    whose compliance is in the model, which gravity torques ~ sin q make nearly collinear with it. What
    remains is a combination only when both effects keep a joint.

    Returns
    -------
    None, or dict: 'extension' (Combination, parameters zero), 'fit' (Identification), 'term_p' (term
    label -> Bonferroni-corrected p given the other terms), 'dropped' (labels of the terms that failed)
    """
    others = [e for e in exts if e.effect in ROBOT_EFFECTS and e.effect != chosen.effect]
    if not others:
        return None
    nxt = best_test(session, ext_fit, others, tau)
    if nxt.p_adjusted >= alpha:
        return None
    second, _ = _grow(session, nxt.extension, [chosen], exts, tau, alpha, sus)
    terms = [
        replace(e, joints=(j,), params=np.zeros(e.size // len(e.joints)), std_errors=None)
        for e in (chosen, second)
        for j in e.joints
    ]
    dropped = []
    while True:
        p = [
            min(
                1.0,
                len(terms)
                * best_test(session, _fit(session, _merge(terms[:i] + terms[i + 1 :]), sus), [t], tau).p,
            )
            for i, t in enumerate(terms)
        ]
        worst = int(np.argmax(p))
        if p[worst] < alpha:
            break
        dropped.append(terms.pop(worst).label)
        if len({t.effect for t in terms}) < 2:
            return None
    combo = _merge(terms)
    return {
        "extension": combo,
        "fit": _fit(session, combo, sus),
        "term_p": {t.label: pi for t, pi in zip(terms, p)},
        "dropped": dropped,
    }


def _select(
    session: Session,
    geo: Identification,
    tester: Tester,
    tests: list,
    exts: list,
    alpha: float,
    robust: bool,
    forced: bool,
):
    """The F tests' choice on these rows (the whole session's, or one fold's training rows): the best
    candidate when significant (or ``forced``: asked for by name), its joints grown; with many candidates
    a stepwise selection on the linearisation; a combination with the other robot effect proposed.

    Parameters
    ----------
    session : Session, with its torques
    geo : Identification, the geometric fit of ``session``
    tester : Tester, and tests : its tests, best first
    exts : list of Extension, the candidates
    alpha : float
    robust : bool
    forced : bool, an effect asked for by name: its best candidate even when not significant, no combination

    Returns
    -------
    (chosen Extension or Combination or None, its Identification or None, the combination proposed -- dict
    of :func:`_combination` -- or None)
    """
    best = (tests or [_NO_TEST])[0]
    if best.p_adjusted >= alpha and not forced:
        return None, None, None
    sus = (robust, geo.weights == 0)
    if not forced and len(tester.exts) > LINEAR_SELECTION:  # many candidates: a few fits in all
        chosen, ext_fit = stepwise_selection(session, geo, exts, session.tau, alpha, sus)
        if chosen is not None:
            return chosen, ext_fit, None
    chosen, ext_fit = _grow(session, best.extension, [], exts, session.tau, alpha, sus)
    combo = None
    if not forced and chosen.effect in ROBOT_EFFECTS:
        combo = _combination(session, chosen, ext_fit, exts, session.tau, alpha, sus)
    return chosen, ext_fit, combo


def _grouping(session: Session, fold: np.ndarray) -> str:
    """How :func:`grouped_folds` formed ``fold`` (for the report)."""
    if session.measurement == "point" and fold.max() > 0:
        return "by tool position"
    return "by configuration" if session.measurement == "position" else "stratified by point"


def _combination_held_out(
    session: Session, geo: Identification, chosen, combo: dict, robust: bool, fold: np.ndarray, grouping: str
) -> dict:
    """Whether a proposed combination predicts held-out data better than its first effect alone, on
    ``fold`` (each fold fits both from the nominal); the record goes into ``combo`` ('accepted',
    'holdout_rms_mm' single/combination, 'gain_percent_folds').

    Returns
    -------
    dict, :func:`acceptance` of the combination (as 'extended') against the first effect (as 'geometric')
    """
    inlier = geo.weights > 0
    _, h_single, h_combo = held_out_all(session, nested_fitter([chosen, combo["extension"]], robust), fold)
    vs = acceptance(h_single, h_combo, inlier, grouping, geo.extra.get("scale"), inlier & carriers(session))
    combo["accepted"] = vs["accepted"]
    combo["holdout_rms_mm"] = {
        "single": vs["holdout_rms_mm"]["geometric"],
        "combination": vs["holdout_rms_mm"]["extended"],
    }
    combo["gain_percent_folds"] = vs["gain_percent_folds"]
    return vs


def _fold_choice(train: Session, exts: list, alpha: float, robust: bool):
    """One outer fold's whole selection from its training rows alone: the geometry, the F tests (the
    candidates the training rows can see), the effect and its joints, and a combination when its terms'
    nested F tests propose one. The whole session decides a proposed combination by a cross-validation;
    a fold takes it on its F tests (as ``k`` < 2 does): an inner cross-validation in every fold cost 3.4
    times the CPU of a session that holds one (tests/test_extend.py's compliance + eccentricity).

    Parameters
    ----------
    train : Session, the fold's training rows (with their torques)
    exts : list of Extension, the whole session's candidates
    alpha : float
    robust : bool

    Returns
    -------
    (geometric Identification, chosen extension or None, its Identification or None, best corrected p)
    """
    geo = fit(train, robust=robust)
    tester = Tester(train, geo, exts, train.tau)
    tests = tester.tests()
    chosen, ext_fit, combo = _select(train, geo, tester, tests, exts, alpha, robust, False)
    if combo is not None:
        chosen, ext_fit = combo["extension"], combo["fit"]
    return geo, chosen, ext_fit, (tests or [_NO_TEST])[0].p_adjusted


def diagnose(
    session: Session,
    alpha: float = ALPHA,
    n_boot: int = 2000,
    seed: int = 0,
    k: int = 5,
    payload=None,
    effect: str | None = None,
    n_refit: int = 10,
    robust: bool = True,
) -> Diagnosis:
    """Find, name and fit the non-geometric effect the data carry (or 'none').

    Parameters
    ----------
    session : Session
    alpha : float, family-wise significance level of the decision
    n_boot : int, first-order parametric-bootstrap replicates (0 skips the bootstrap)
    n_refit : int, full (nonlinear) simulations with refits, for the residual RMS distribution
    seed : int
    k : int, cross-validation folds of a laser session (point sessions leave one tool position
        out); 0 or 1: no cross-validation, the F test decides alone and fit residuals stand in
    payload : (kg, (3,) mm), extra mass on the flange for the gravity model when torques are not logged
    effect : str, restrict the catalogue to one effect (``solve --extend EFFECT``): the best
        candidate of that effect is fitted even when not significant, and kept whatever the
        cross-validation says (its numbers are reported)
    robust : bool, the robust loss in every fit (folds included)

    Returns
    -------
    Diagnosis
    """
    t0 = time.perf_counter()
    map_only, effect = _joint_map_named(session, effect)  # --extend joint_map: joint_map_stage alone
    rng = np.random.default_rng(seed)
    tau, tau_src = session_torques(session, payload)
    session = replace(session, tau=tau)  # model torques travel with the captures through subsets and folds
    geo = fit(session, robust=robust)
    # a misplaced reference point: a laser session's measured points (point and position sessions identify
    # theirs; a printed sheet's are where the printer put them, its scale and tilt fitted with its pose) at
    # the captures aimed at them (a camera's measured spot does not use its point)
    offsets = session.measurement == "laser" and session.frame != "sheet"
    pts = list(dict.fromkeys(session.point[~session.measured])) if offsets else []
    clock_ok = session.clock == "seconds" and session.t is not None and np.ptp(session.t) > 0
    lateral = [j + 1 for j, b in enumerate(session.robot.lateral_of) if b >= 0]
    # a drift is zero at the mean capture time: the geometry written is the arm's then (Extension.t0)
    t0 = float(np.mean(session.t)) if clock_ok else 0.0
    exts = candidates(session.robot.n, pts, tau is not None, clock_ok, lateral, session.robot.joint_names, t0)
    cannot = untested(
        session.measurement,
        tau is not None,
        session.clock,
        session.t is not None and np.ptp(session.t) > 0,
        session.frame,
    )
    if tau_src == "logged":  # a compliance only where the joint carries a load well above the sensor's noise
        refused = noise_dominated(exts, session, tau)
        exts = [e for e in exts if e.label not in refused]
        cannot |= refused
    exts = [] if map_only else exts
    if effect is not None:
        exts = [e for e in exts if e.effect == effect]
        if not exts:
            raise ModelError(
                f"effect {effect!r} cannot be tested on this session: {cannot.get(effect, 'no candidate')}"
            )
    tester = Tester(session, geo, exts, tau)
    tests = tester.tests()
    if effect is not None and not tests:  # asked for by name: its best candidate, seen or not
        tester = Tester(replace(session, tolerances=None), geo, exts, tau)
        tests = tester.tests()
    best = (tests or [_NO_TEST])[0]
    chosen, ext_fit, combo = _select(session, geo, tester, tests, exts, alpha, robust, effect is not None)
    ambiguous = tuple(
        t.label
        for t in tests[1:]
        if chosen is not None and t.rss_drop >= _AMBIGUOUS * best.rss_drop and t.p_adjusted < alpha
    )
    boot = bootstrap(session, geo, tester, n_boot, n_refit, rng) if n_boot else {}

    # captures the robust fit flags (mis-aims) are reported, not averaged in; a camera session's figures are
    # its measured captures' (its aimed ones, at 100 times their noise, would otherwise be all they show),
    # its decision every capture's at its own noise (eq. K1)
    inlier = geo.weights > 0
    counted = inlier & carriers(session)
    scale = geo.extra.get("scale")
    rms = lambda r: float(np.sqrt(np.mean(np.sum(r[counted] ** 2, axis=1))))  # noqa: E731
    nominal_rms = rms(residuals(session.robot, None, session))
    if k > 1:
        f = grouped_folds(session, k, seed)
        grouping = _grouping(session, f)
        if combo is not None:  # kept only when it predicts held-out data better than its first effect alone
            vs = _combination_held_out(session, geo, chosen, combo, robust, f, grouping)
            if vs["accepted"]:
                chosen, ext_fit = combo["extension"], combo["fit"]
        if (
            effect is None
        ):  # every choice made again on each fold's training rows, scored on its held-out rows
            nested = nested_holdout(session, f, lambda train: _fold_choice(train, exts, alpha, robust))
            h_geo, h_ext = nested.geometric, nested.extended
            agreement = fold_agreement(chosen, nested.choices)
        else:  # asked for by name: that choice refitted in each fold
            h_geo, h_ext = held_out_all(session, nested_fitter([chosen], robust), f)
            agreement = {}
        acc = acceptance(h_geo, h_ext, inlier, grouping, scale, counted)
        acc["selection"] = (
            "inside each fold" if effect is None else "asked for by name, refitted in each fold"
        )
        acc |= agreement
        kinds = {
            kind: {
                m: rms_by_kind(np.linalg.norm(h.residuals, axis=1), session, inlier)[kind]["rms_mm"]
                for m, h in (("geometric", h_geo), ("extended", h_ext))
            }
            for kind in capture_kinds(session)
        }
        if kinds:
            acc["holdout_by_kind"] = kinds
        if chosen is not None and effect is None:
            if not acc["accepted"]:
                acc["rejected"] = "the extension does not predict held-out data better than the geometry"
            elif not agreement["folds_agreed"]:
                acc["rejected"] = (
                    f"the folds chose different causes ({agreement['folds_agree']} of "
                    f"{len(agreement['fold_choices'])} chose {chosen.label}, "
                    f"{agreement['folds_needed']} needed: "
                    + "; ".join(f"{lb} in {len(fs)}" for lb, fs in agreement["disagreement"].items())
                    + ")"
                )
            acc["accepted"] = acc["accepted"] and agreement["folds_agreed"]
        r_geo, r_ext = h_geo.residuals, h_ext.residuals
        held = acc["holdout_rms_mm"]
    else:  # no cross-validation asked for (benchmarks): the fit residuals stand in
        if combo is not None:
            combo["accepted"] = True
            chosen, ext_fit = combo["extension"], combo["fit"]
        acc = {"decided_by": "F test only", "accepted": chosen is not None}
        r_geo = geo.residuals
        r_ext = ext_fit.residuals if chosen else r_geo
        held = {"geometric": rms(r_geo), "extended": rms(r_ext)}
    if combo is not None:
        acc["combination"] = {k: v for k, v in combo.items() if k not in ("extension", "fit")} | {
            "label": combo["extension"].label
        }
    keep = chosen is not None and (acc["accepted"] or effect is not None)
    statistics = {
        "nominal": {"train": nominal_rms, "holdout": nominal_rms if k > 1 else None},
        "geometric": {"train": rms(geo.residuals), "holdout": held["geometric"] if k > 1 else None},
        "extended": {
            "train": rms(ext_fit.residuals if keep else geo.residuals),
            "holdout": (held["extended"] if keep else held["geometric"]) if k > 1 else None,
        },
    }
    d = Diagnosis(
        chosen.effect if keep else "none",
        ext_fit.extension if keep else None,
        best.p_adjusted,
        tests,
        geo,
        ext_fit if keep else None,
        {"geometric": held["geometric"], "extended": held["extended"] if keep else held["geometric"]},
        boot,
        tau_src,
        time.perf_counter() - t0,
        {"geometric": r_geo, "extended": r_ext if keep else r_geo},
        ambiguous if keep else (),
        session,
        ext_fit.extension if chosen else None,
        acc,
        statistics,
        cannot,
        robust,
        tester.unseen,
    )
    if session.measurement == "position" and (effect is None or map_only):
        d = joint_map_stage(session, d, k, seed, robust, forced=map_only)
    return d


# ----------------------------------------------------------------------------- the joint error map
def _joint_map_named(session: Session, effect: str | None) -> tuple[bool, str | None]:
    """(whether ``effect`` names the joint error map, the catalogue effect left: None for the map)."""
    if effect != JointMap.effect:
        return False, effect
    if session.measurement != "position":
        raise ModelError(
            f"--extend joint_map: a joint error map is fitted to position and pose sessions, not to "
            f"{session.measurement} sessions"
        )
    return True, None


def joint_map_stage(
    session: Session, d: Diagnosis, k: int, seed: int, robust: bool, forced: bool
) -> Diagnosis:
    """The joint error map on top of a position session's finding (:mod:`solver.kinematics.joint_map`,
    knots every :data:`~lasercal.solver.kinematics.joint_map.POSITION_STEP_RAD` on every joint that moves):
    fitted jointly with the kept effect (or alone) and kept only when it predicts held-out configurations
    better -- a lower pooled RMS, the test of every extension (:func:`acceptance`) -- over K folds by
    configuration (the diagnosis's K, or 5 without one: a map is never kept on an F test). Each fold fits
    the kept effect and the effect + map from the nominal, the map's knots over the fold's own angles.
    ``forced`` (``--extend joint_map``): kept, with its numbers.

    Why no stricter rule for hundreds of knots: the held-out RMS already pays for the knots' variance. On
    sessions without a map effect the map lost in every fold (21 of 21 simulated sessions, 1-106 %); the
    "95 % interval of the fold gains above 0" rule kept no more of those, but dropped a real map (8.8 %
    better on new configurations) and, on Justin's 5-fold CV, the map in 4 folds of 5: 3.59 mm against
    3.51 (docs/position.md, "The joint error map on a position session").
    """
    t0 = time.perf_counter()
    names = session.robot.joint_names
    moving = [j + 1 for j in range(session.robot.n) if np.ptp(session.q[:, j]) > 0]
    base = d.extension if d.effect != "none" else None

    def own_map(q):
        return JointMap.covering(q, moving, POSITION_STEP_RAD, names)

    def fitter(train: Session) -> list:
        try:
            geo = fit(train, robust=robust)
            sus = geo.weights == 0
            fits = [geo if base is None else fit(train, base, robust=robust, suspects=sus)]
            fits.append(fit(train, with_joint_map(base, own_map(train.q)), robust=robust, suspects=sus))
        except IdentificationError as e:
            return [e, e]
        return [(f.model, f.extension, f.extra.get("points")) for f in fits]

    fold = grouped_folds(session, k if k > 1 else 5, seed)
    h_base, h_map = held_out_all(session, fitter, fold)
    acc = acceptance(h_base, h_map, d.geometric.weights > 0, "by configuration")
    ci, better = acc["gain_percent_ci95"], acc["accepted"]
    jm = own_map(session.q)
    record = {
        "label": jm.label,
        "knots": jm.size,
        "folds": acc["folds"],
        "holdout_rms_mm": {
            "without": acc["holdout_rms_mm"]["geometric"],
            "with": acc["holdout_rms_mm"]["extended"],
        },
        "gain_percent_folds": acc["gain_percent_folds"],
        "gain_percent_ci95": ci,
        "failed_folds": acc["failed_folds"],
        "accepted": bool(better),
        "asked_for": forced,
        # the keep decision is made on the folds whose gain is reported: that gain is the chosen map's,
        # optimistic by the choice (a nested split would refit hundreds of knots k x k times)
        "gain_is": "chosen on these folds",
    }
    seconds = d.seconds + time.perf_counter() - t0
    if not (better or forced):
        return replace(d, acceptance=d.acceptance | {"joint_map": record}, seconds=seconds)
    fitted = _fit(session, with_joint_map(base, jm), (robust, d.geometric.weights == 0))
    cv = k > 1  # the diagnosis's own folds: the same as these (grouped_folds, k, seed)
    held = acc["holdout_rms_mm"]["extended"] if cv else fitted.rms_mm
    stats = dict(d.statistics)
    stats["extended"] = {"train": fitted.rms_mm, "holdout": held if cv else None}
    return replace(
        d,
        effect=jm.effect if base is None else f"{d.effect}+{jm.effect}",
        extension=fitted.extension,
        extended=fitted,
        holdout_rms={"geometric": d.holdout_rms["geometric"], "extended": held},
        residuals_holdout=d.residuals_holdout | {"extended": h_map.residuals if cv else fitted.residuals},
        acceptance=d.acceptance | {"joint_map": record},
        statistics=stats,
        seconds=seconds,
    )
