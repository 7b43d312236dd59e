"""Before/after error statistics and cross-validation (thesis Section 4.3, Figures 4.5-4.6).

For a set of laser spots meant to hit one reference point:

* scatter radius -- distance of each spot from the spots' own mean (mean, std), Figure 4.5;
* absolute error -- distance of each spot from the reference point (mean, max), Figure 4.6.

For a session, the spots are where a model says each captured beam lands: with the
nominal model they scatter as the thesis's "before" photos did, with the identified
model as its "after" photos (to first order the same errors, seen from the other side).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field, replace

import numpy as np

from lasercal.solver.errors import IdentificationError
from lasercal.solver.formats.session import Session
from lasercal.solver.identify.laser_parameters import unseen_by_spots
from lasercal.solver.identify.measurement import determined_by, fit, residuals
from lasercal.solver.identify.point import tips
from lasercal.solver.identify.spot import Identification, base_targets, predict_spots
from lasercal.solver.kinematics.model import RobotModel


@dataclass(frozen=True)
class SpotStats:
    """Statistics of k spots aimed at one point (mm)."""

    n: int
    scatter_mean: float
    scatter_std: float
    error_mean: float
    error_max: float
    error_rms: float

    def as_dict(self) -> dict:
        return {k: (round(v, 6) if isinstance(v, float) else v) for k, v in asdict(self).items()}


def spot_stats(spots: np.ndarray, point: np.ndarray) -> SpotStats:
    """Scatter radius about the spots' mean and absolute error from the point (Figures 4.5-4.6).

    Parameters
    ----------
    spots : (k, 2) or (k, 3) array, mm (only x, y are used)
    point : (2,) or (3,) array, mm; or (k, 2) or (k, 3): each spot's own target (a camera session's
        measured spots), the scatter then that of the spots' offsets from their targets
    """
    off = np.asarray(spots, dtype=float)[:, :2] - np.asarray(point, dtype=float)[..., :2]
    radius = np.linalg.norm(off - off.mean(axis=0), axis=1)
    err = np.linalg.norm(off, axis=1)
    return SpotStats(
        len(off),
        float(radius.mean()),
        float(radius.std(ddof=1)) if len(off) > 1 else 0.0,
        float(err.mean()),
        float(err.max()),
        float(np.sqrt(np.mean(err**2))),
    )


def per_point(model: RobotModel, session: Session, mask: np.ndarray | None = None) -> dict:
    """:func:`spot_stats` per reference point of the spots ``model`` predicts for the captures, each against
    its own target (the point, or where the camera measured its spot; base frame, a sheet session's through
    the model's sheet pose)."""
    mask = np.ones(session.m, bool) if mask is None else mask
    target = base_targets(session, model)[mask]
    spots, _ = predict_spots(model, session.q[mask], target[:, 2])
    names = session.point[mask]
    return {nm: spot_stats(spots[names == nm], target[names == nm]) for nm in dict.fromkeys(names)}


def capture_kinds(session: Session) -> dict:
    """A camera session's captures by kind: 'measured' (the camera measured the spot) and 'aimed' (the
    operator aimed at the point or the coach's aim), (m,) bool masks; {} for a session with no measured
    capture (every capture of one kind)."""
    meas = session.measured
    if session.measurement != "laser" or not meas.any():
        return {}
    return {"measured": meas, "aimed": ~meas}


def carriers(session: Session) -> np.ndarray:
    """(m,) bool: the captures that carry the fit and its figures -- a camera session's measured ones (its
    aimed captures weigh 1/100 as much at their noise), else all."""
    return capture_kinds(session).get("measured", np.ones(session.m, bool))


def rms_by_kind(errors: np.ndarray, session: Session, keep: np.ndarray) -> dict:
    """Per kind of capture (:func:`capture_kinds`): captures counted and the RMS, mean and max of their
    errors (m,) mm over ``keep`` (m,) bool; {} for a session of one kind."""
    out = {}
    for kind, sel in capture_kinds(session).items():
        e = errors[sel & keep & np.isfinite(errors)]
        out[kind] = {
            "captures": int(e.size),
            "rms_mm": round(float(np.sqrt(np.mean(e**2))), 6) if e.size else None,
            "mean_mm": round(float(e.mean()), 6) if e.size else None,
            "max_mm": round(float(e.max()), 6) if e.size else None,
        }
    return out


MISFIT = 10.0  # a noise estimate this many times the prior's: the data do not fit the model at all
POSE_TOL_RAD = 1e-4  # rad: revolute readings this close are one pose (a still robot read again)
POSE_TOL_MM = 1e-2  # mm: the same for a prismatic joint


def configurations(robot: RobotModel, q: np.ndarray) -> np.ndarray:
    """Configuration index (m,) of each row: rows whose joint readings agree within the pose tolerance are
    one configuration.

    Rows i and j are linked when max_j |q_ij - q_kj| / tol_j <= 1 (Chebyshev distance, tol_j =
    :data:`POSE_TOL_RAD` or :data:`POSE_TOL_MM` for a prismatic joint); configurations are the connected
    components of these links, in any order of the rows.

    Parameters
    ----------
    robot : RobotModel, whose ``prismatic`` joints are in mm
    q : (m, n) array, rad (mm for prismatic joints)

    Returns
    -------
    (m,) int array, the component of each row
    """
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components
    from scipy.spatial import cKDTree

    x = np.asarray(q, float) / np.where(robot.prismatic, POSE_TOL_MM, POSE_TOL_RAD)
    pairs = cKDTree(x).query_pairs(1.0, p=np.inf, output_type="ndarray")
    m = len(x)
    links = coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(m, m))
    return connected_components(links, directed=False)[1]


def folds(session: Session, k: int, seed: int = 0) -> np.ndarray:
    """Fold index (m,) for K-fold cross-validation.

    Captures sharing a ``group`` column value (repeated captures of one pose) stay in one
    fold, so that no capture is predicted by a fit that saw it or its twin. Laser and point
    sessions are stratified by point. Position sessions without a ``group`` column group rows by
    :func:`configurations` (the targets measured at one pose stay together: a held-out pose is
    one the fit never saw) and assign whole configurations to folds at random.
    """
    rng = np.random.default_rng(seed)
    position = session.measurement == "position"
    default = configurations(session.robot, session.q) if position else np.arange(session.m)
    groups = np.asarray(session.extra.get("group", default.astype(str)))
    strata = np.zeros(session.m, dtype=int) if position else session.point
    out = np.empty(session.m, dtype=int)
    for nm in dict.fromkeys(strata):
        sel = np.flatnonzero(strata == nm)
        uniq = list(dict.fromkeys(groups[sel]))
        order = rng.permutation(len(uniq))
        fold_of = {uniq[g]: i % k for i, g in enumerate(order)}
        out[sel] = [fold_of[g] for g in groups[sel]]
    return out


def grouped_folds(session: Session, k: int, seed: int = 0) -> np.ndarray:
    """Fold index (m,) of the cross-validation the statistics and the model selection use.

    Point sessions: leave one tool position out (:attr:`Session.positions`; k is ignored), so that a
    model is judged on a placement of the tool it never saw. Laser and position sessions: :func:`folds`.
    """
    pos = session.positions
    names = list(dict.fromkeys(pos))
    if session.measurement == "point" and len(names) >= 2:
        return np.array([names.index(p) for p in pos])
    return folds(session, k, seed)


@dataclass(frozen=True)
class HeldOut:
    """Held-out residuals of a cross-validation.

    Attributes
    ----------
    residuals : (m, d) array, mm; NaN rows for the captures of a fold that could not be fitted
    fold : (m,) array of int
    failed : dict fold -> reason, the folds that could not be fitted (reported, never fatal)
    """

    residuals: np.ndarray
    fold: np.ndarray
    failed: dict

    def fold_rms(self, keep: np.ndarray | None = None) -> np.ndarray:
        """RMS (mm) of each fold's held-out residuals over the captures ``keep`` (NaN: failed/empty)."""
        keep = np.ones(len(self.fold), bool) if keep is None else keep
        out = np.full(int(self.fold.max()) + 1, np.nan)
        for i in range(len(out)):
            sel = (self.fold == i) & keep & np.all(np.isfinite(self.residuals), axis=1)
            if sel.any():
                out[i] = np.sqrt(np.mean(np.sum(self.residuals[sel] ** 2, axis=1)))
        return out


def held_out(session: Session, fitter, fold: np.ndarray) -> HeldOut:
    """Cross-validated residuals: ``fitter(train) -> (model, extension, points)`` predicts each fold.

    A fold whose fit fails (too few captures for the parameters) is recorded in ``failed`` and its
    captures get NaN: one fold that cannot be fitted is no reason to refuse a calibration.
    """
    return held_out_all(session, lambda train: [_attempt(fitter, train)], fold)[0]


def held_out_all(session: Session, fitter, fold: np.ndarray) -> list[HeldOut]:
    """:func:`held_out` of several models fitted together per fold: ``fitter(train)`` returns a list of
    (model, extension, points), or of the IdentificationError of a model that could not be fitted."""
    d = 2 if session.measurement == "laser" else 3  # in-plane spot error, or a 3-D point
    out, failed = None, None
    for i in range(int(fold.max()) + 1):
        test = fold == i
        if not test.any():
            continue
        fits = fitter(session.subset(~test))
        if out is None:
            out, failed = [np.full((session.m, d), np.nan) for _ in fits], [{} for _ in fits]
        sub = session.subset(test)
        for j, f in enumerate(fits):
            if isinstance(f, IdentificationError):
                failed[j][i] = str(f)
            else:
                out[j][test] = residuals(f[0], f[1], sub, f[2])
    return [HeldOut(o, fold, fl) for o, fl in zip(out, failed)]


def _attempt(fitter, train: Session):
    """``fitter(train)``, or the IdentificationError that says why it cannot be fitted."""
    try:
        return fitter(train)
    except IdentificationError as e:
        return e


def fitter(
    method: str = "lm",
    robust: bool = True,
    extension=None,
    suspects: np.ndarray | None = None,
):
    """The ``fitter`` of :func:`held_out` for :func:`solver.identify.measurement.fit`, from the session's
    nominal robot (never from a fit that saw the held-out captures: the directions a fold cannot identify
    stay at the start); ``suspects`` (training captures) the only ones the outlier test may flag."""

    def f(train: Session):
        r = fit(train, extension, robust=robust, method=method, suspects=suspects)
        return r.model, r.extension, r.extra.get("points")

    return f


def nested_fitter(extensions: list, robust: bool = True):
    """The ``fitter`` of :func:`held_out_all` for the geometric model and its extensions (``lm``).

    Per fold the geometric fit, then each extension fitted on the rows it kept (its outliers the only
    suspects, :mod:`solver.identify.lsq`): nested models are compared on one set of rows. Every fit
    starts at the session's nominal robot: a start elsewhere (the fold's geometric fit, the whole
    session's) holds a rank-deficient fold's unidentifiable combinations at other values and changes its
    held-out prediction (MUKCa panda_1, back-high held out, extended plain fit: 1.06 mm became 1.21 mm).
    """

    def f(train: Session):
        geo = _attempt(lambda s: fit(s, robust=robust), train)
        if isinstance(geo, IdentificationError):
            return [geo] * (1 + len(extensions))
        out = [(geo.model, None, geo.extra.get("points"))]
        sus = geo.weights == 0
        return out + [_attempt(fitter("lm", robust, e, sus), train) for e in extensions]

    return f


@dataclass(frozen=True)
class CrossValidation:
    """K-fold held-out prediction errors (mm): per capture and summarised.

    ``inlier`` marks the captures the summary counts: a capture the robust fit of the whole
    session flags as an outlier (a mis-aim) says nothing about the model's accuracy and would
    dominate an RMS, so it is reported as an outlier, not averaged in.
    """

    k: int
    errors: np.ndarray
    fold: np.ndarray
    nominal_errors: np.ndarray
    inlier: np.ndarray | None = None
    failed: dict = field(default_factory=dict)
    session: Session | None = None

    @property
    def _inlier(self) -> np.ndarray:
        return np.ones(len(self.errors), bool) if self.inlier is None else self.inlier

    def as_dict(self) -> dict:
        """The summary over the counted captures (a camera session's measured ones, which carry the fit),
        with ``by_kind`` (measured, aimed) for a camera session."""
        inlier = self._inlier
        if self.session is not None:
            inlier = inlier & carriers(self.session)
        keep = inlier & np.isfinite(self.errors)
        e, e0 = self.errors[keep], self.nominal_errors[keep]
        if not e.size:  # every fold failed
            e = np.full(1, np.nan)
        kinds = {} if self.session is None else rms_by_kind(self.errors, self.session, self._inlier)
        return {
            "folds": self.k,
            "failed_folds": {str(i): why for i, why in self.failed.items()},
            "captures_counted": int(keep.sum()),
            "holdout_rms_mm": float(np.sqrt(np.mean(e**2))),
            "holdout_mean_mm": float(e.mean()),
            "holdout_max_mm": float(e.max()),
            "nominal_rms_mm": float(np.sqrt(np.mean(e0**2))),
            **({"by_kind": kinds} if kinds else {}),
        }


def cross_validate(
    session: Session,
    method: str = "lm",
    k: int = 5,
    seed: int = 0,
    inlier: np.ndarray | None = None,
    robust: bool = True,
    extension=None,
) -> CrossValidation:
    """Held-out error of each capture, predicted by a model fitted on the other folds.

    Parameters
    ----------
    session : Session
    method : str, identification method
    k : int, number of folds (laser sessions; point sessions leave one tool position out)
    seed : int, fold assignment seed
    inlier : (m,) bool array, the captures the summary counts (default: all)
    robust : bool, the robust loss in every fold's fit
    extension : Extension, optional effect fitted with the geometry in every fold

    Returns
    -------
    CrossValidation (in-plane spot errors, or tool-point errors against the training fit's points;
    NaN for the captures of a fold that could not be fitted, listed in ``failed``)
    """
    h = held_out(session, fitter(method, robust, extension), grouped_folds(session, k, seed))
    return CrossValidation(
        int(h.fold.max()) + 1,
        np.linalg.norm(h.residuals, axis=1),
        h.fold,
        np.linalg.norm(residuals(session.robot, None, session), axis=1),
        inlier,
        h.failed,
        session,
    )


def point_session_stats(model: RobotModel, session: Session, mask: np.ndarray | None = None) -> dict:
    """Per point: spread of the model's tool points about their mean (RMS, mean; mm); per known
    distance: |d - d0| between the mean tool points (mm). MUKCa's self-consistency metrics."""
    mask = np.ones(session.m, bool) if mask is None else mask
    p = tips(model, session.q[mask], model.tool_point if model.tool_point is not None else session.tool_point)
    names = session.point[mask]
    centre, out = {}, {"points": {}, "distances": {}}
    for nm in dict.fromkeys(names):
        x = p[names == nm]
        centre[nm] = x.mean(axis=0)
        r = np.linalg.norm(x - centre[nm], axis=1)
        out["points"][nm] = {
            "n": int(len(x)),
            "spread_rms_mm": round(float(np.sqrt(np.mean(r**2))), 6),
            "spread_mean_mm": round(float(r.mean()), 6),
        }
    for a, b, d0 in session.distances:
        if a in centre and b in centre:
            out["distances"][f"{a}-{b}"] = round(float(abs(np.linalg.norm(centre[a] - centre[b]) - d0)), 6)
    return out


def position_target_stats(ident: Identification, session: Session, used: np.ndarray) -> dict:
    """Per target: captures, RMS distance (mm) of the measured positions from the nominal's (after its best
    sensor frame and targets) and from the identified model's predictions, and the identified target."""
    r0 = np.linalg.norm(residuals(ident.nominal, None, session), axis=1)
    r1 = np.linalg.norm(residuals(ident.model, ident.extension, session), axis=1)
    out = {}
    for nm in dict.fromkeys(session.point):
        sel = session.point == nm
        out[nm] = {
            "n": int(sel.sum()),
            "before_rms_mm": round(float(np.sqrt(np.mean(r0[sel] ** 2))), 6),
            "after_rms_mm": round(float(np.sqrt(np.mean(r1[sel & used] ** 2))), 6),
            "target_mm": [round(float(x), 4) for x in ident.model.targets[nm]],
        }
    return out


def one_point_warning(point: str, det) -> str:
    """Why captures at a single point leave the prior in charge, and what it holds (``det``: a
    :class:`~lasercal.solver.identify.degenerate.Determination`)."""
    held = "; ".join(
        f"{d.combination} ({d.directions} direction{'s' if d.directions > 1 else ''})" for d in det.from_prior
    )
    return (
        f"every capture is at one point, {point}: beams through one point cannot tell the robot from itself "
        f"turned about that point, so the prior alone determines {det.prior} combination"
        f"{'s' if det.prior != 1 else ''}{': ' + held if held else ''}; capture at two more points, far "
        "apart (docs/sessions.md)"
    )


def kind_noise(noise: dict) -> dict:
    """A camera session's noise per kind of capture (:func:`solver.identify.spot.fit_kinds`), rounded."""
    return {k: (None if v is None else round(v, 6) if isinstance(v, float) else v) for k, v in noise.items()}


def solve_report(session: Session, ident: Identification, cv: CrossValidation | None = None) -> dict:
    """The statistics ``lasercal solve`` prints, as a JSON-ready mapping.

    'after' is the identified model with its extension (if any) applied to the logged angles.
    """
    used = ident.weights > 0
    before = session
    if ident.extension is not None:
        session = replace(session, q=ident.extension.true_q(session.q, session.t, session.tau))
    idf = ident.identifiability
    # a camera session's figures are its measured captures' (they carry the fit), and each kind's apart
    carry = carriers(session)
    fit_errors = np.linalg.norm(ident.residuals, axis=1)
    noise = ident.extra.get("noise")
    rep = {
        "method": ident.method,
        "converged": ident.converged,
        "iterations": ident.iterations,
        "seconds": round(ident.seconds, 4),
        "captures": session.m,
        "fit_rms_mm": round(float(np.sqrt(np.mean(fit_errors[used & carry] ** 2))), 6),
        "sigma_mm": round(ident.sigma_mm if noise is None else noise["measured_mm"], 6),
        **({"noise_by_kind": kind_noise(noise)} if noise is not None else {}),
        **({"fit_by_kind": k} if (k := rms_by_kind(fit_errors, session, used)) else {}),
        "outliers": [
            {"index": i, "line": int(session.lines[i]), "point": str(session.point[i])}
            for i in ident.outliers
        ],
        "identifiability": {
            "parameters": idf.n_params,
            "rank": idf.rank,
            "condition": round(idf.condition, 3),
            "unidentifiable": idf.unidentifiable,
        },
    }
    if "counted" in ident.extra:  # a laser fit: what the count is (laser_parameters: what spots never see)
        rep["identifiability"] |= {
            "possible": idf.n_params - unseen_by_spots(session.frame == "sheet"),
            "counted": ident.extra["counted"],
        }
    if session.measurement == "point":
        nominal = (
            ident.nominal
            if ident.nominal.tool_point is not None
            else ident.nominal.replace(tool_point=session.tool_point)
        )
        rep["measurement"] = "point"
        rep["before"] = point_session_stats(nominal, before)
        rep["after"] = point_session_stats(ident.model, session, used)
        rep["identified_points"] = {
            k: [round(x, 4) for x in v] for k, v in ident.extra.get("points", {}).items()
        }
    elif session.measurement == "position":
        rep["measurement"] = "position"
        rep["gauge"] = ident.extra.get("gauge", "")
        rep["targets"] = position_target_stats(ident, before, used)  # logged q: the extension applies once
    else:
        aimed = capture_kinds(session).get("aimed", np.zeros(session.m, bool)) & used
        before, after = per_point(ident.nominal, before, carry), per_point(ident.model, session, used & carry)
        off = per_point(ident.model, session, aimed)  # a camera session's aimed captures: the aim's error
        rep["points"] = {
            nm: {
                "before": before[nm].as_dict() if nm in before else None,
                "after": after[nm].as_dict() if nm in after else None,
                **({"aimed": off[nm].as_dict()} if nm in off else {}),
            }
            for nm in dict.fromkeys(session.point)
        }
    if ident.model.sheet is not None:
        rep["sheet"] = {"pose": ident.model.sheet.as_dict(), "std": ident.model.sheet_std, "frame": "base"}
    if ident.std_errors:
        rep["std_errors"] = {k: float(f"{v:.4g}") for k, v in ident.std_errors.items()}
    prior = ident.extra.get("prior")
    rep["prior"] = (
        {"tolerances": session.tolerances.as_dict(), "robot": session.robot.name}
        if prior is not None and session.tolerances is not None
        else "none (plain least squares)"
    )
    det = determined_by(session, ident)
    if det is not None:
        rep["determined_by"] = det.as_dict()
        s0 = session.tolerances.noise(session.measurement)
        warnings = []
        # (a 3-D sensor's noise spans three orders, a tracker's 0.01 mm to a camera's 1 mm: no such check)
        if session.measurement != "position" and ident.sigma_mm > MISFIT * s0:
            warnings.append(
                f"the fit leaves {ident.rms_mm:.3g} mm RMS, a noise of {ident.sigma_mm:.3g} mm per axis "
                f"against the prior's {s0:g} mm: these data do not fit this robot (a wrong robot or layout, "
                "swapped or frozen columns, wrong units?)"
            )
        if session.measurement != "position" and len(set(session.point[used])) == 1:
            warnings.append(one_point_warning(str(session.point[used][0]), det))
        if warnings:
            rep["warning"] = "; ".join(warnings)
    if cv is not None:
        rep["cross_validation"] = cv.as_dict()
    return rep
