"""The MUKCa real-data study (issue 6): four real Franka Pandas, leave-one-tool-position-out.

For each robot folder ``DIR/panda_k`` (a MUKCa socket dataset, :mod:`collector.mukca`):

1. Calibration. Nominal, geometric and extended models are fitted on all tool positions but
   one and tested on the held-out one (LOTO-CV). The held-out sockets are unknown points, so
   the test metric is self-consistency: per socket the spread of the predicted ball centres
   about their own mean (RMS and mean distance, mm) and per position the socket-distance
   error |d - 50| between the two sockets' mean centres (mm). MUKCa's own metric is
   computed beside it (:func:`consistency`).
2. Simulation check. The experiment is re-run on the identified geometric robot (same
   configurations, Gaussian noise at the per-axis sigma the fit implies), refitted to first
   order (the noise minus its projection on what the fit absorbs, exactly as
   :func:`solver.diagnose.bootstrap` does) and compared with the measured residuals: size,
   spread per socket and per position, lag-1 correlation in recording order, and the share
   of residual each candidate regressor explains (:func:`simulation_check`). Each comparison
   is a test: the measured statistic's rank among the simulated ones.
3. Diagnosis. :func:`solver.diagnose.diagnose` on the whole session (Bonferroni-corrected
   F tests, forward selection of joints, parametric bootstrap).
4. Extension. The held-out gain of an extension, by LOTO twice: with the effect selected
   inside each fold (nested, no selection leak) and with the whole-session finding refitted
   per fold. Joint compliance at the gravity-loaded joints is fitted on every robot, turned
   into a stiffness, and the robots are compared by a chi-square homogeneity test.
5. Outliers. The rows the robust loss flags, against the tool positions the authors removed
   by hand (``panda_k_clean`` folders): a confusion table and a position-level screen.

Torques. The data log no torques: the gravity model of the link masses (Gaz et al.) plus
:data:`PAYLOAD` (the Franka hand, 0.73 kg, and the ball tool, about 0.1 kg, not in the link
masses) stands in for them (:func:`solver.diagnose.session_torques`).

Sign of a compliance. ``tau`` is the torque holding the arm against gravity, tau = dV/dq
(:mod:`solver.gravity`). An elastic element between a joint's encoder and its load lets the
load sag downhill, q_true = q - tau / k, so in the catalogue's form q_true = q + c tau a
physical sag has c < 0 and the stiffness is k = -1/c (Nm/rad). libfranka's ``q`` is measured
on the link side of the gearbox and torque sensor, so the joint's own elasticity is already
in ``q``; a sag it misses is bending beyond the sensor (link, bearing, flange), expressed
about the joint axis, or something the gravity regressor stands in for.
"""

from __future__ import annotations

import json
import time
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np
from scipy.special import stdtrit  # quantile of Student's t (scipy.stats.t.ppf)

from lasercal.collector.studies.mukca_import import import_mukca, positions
from lasercal.collector.studies.options import ROBOTS, StudyOptions
from lasercal.solver.analysis.diagnose import Diagnosis, Tester, diagnose, session_torques
from lasercal.solver.errors import FormatError
from lasercal.solver.formats.session import Session, load_session
from lasercal.solver.identify.measurement import fit
from lasercal.solver.identify.point import tip_joint_jacobian, tips
from lasercal.solver.identify.spot import Identification
from lasercal.solver.kinematics.effects import Extension, candidates
from lasercal.solver.kinematics.model import RobotModel

LOADED_NM = 10.0  # a joint gets a compliance estimate when its gravity torque spans this much in every robot
PUBLISHED = {
    "robot": "panda_1",
    "metric": "MUKCa 'mean absolute error' (m), see consistency()",
    "train_m": [8.28e-3, 1.68e-4],
    "test_m": [7.79e-3, 3.47e-4],
    "abstract": "mean absolute error from about 10 mm to about 0.2 mm (arXiv 2503.12584)",
    "source": "platonics-delft/kinematics_calibration README; calibrate_fk/utils.py evaluate_model, "
    "compute_improved_performance",
}
MODELS = ("nominal", "plain", "geometric", "nested", "nested_plain", "fixed", "compliance")  # see loto()
PLAIN_TOLERANCE = 0.02  # the robust fit's held-out spread may exceed plain least squares' by this share


@dataclass(frozen=True, eq=False)
class RobotStudy:
    """One robot's results: ``report`` (JSON-ready) and ``plot`` (arrays for the figures)."""

    report: dict
    plot: dict = field(default_factory=dict)


# ------------------------------------------------------------------ machinery
def load_robot(data_dir, robot: str, workdir) -> Session:
    """Import ``data_dir/robot`` as a point session in ``workdir/robot`` and load it."""
    folder = Path(data_dir) / robot
    if not folder.is_dir():
        raise FormatError(folder, f"no MUKCa robot folder {robot!r} in {data_dir}")
    return load_session(import_mukca(folder, Path(workdir) / robot))


def position_of(session: Session) -> np.ndarray:
    """Tool position of each capture (m,) ('front' for point 'front/hole_0')."""
    return np.array([nm.rsplit("/", 1)[0] for nm in session.point])


def ball_centres(model: RobotModel, ext: Extension | None, session: Session) -> np.ndarray:
    """Ball centres (m, 3) mm the model (and its extension) predicts for the captured joint angles."""
    q = ext.true_q(session.q, session.t, session.tau) if ext is not None else session.q
    return tips(model, q, model.tool_point if model.tool_point is not None else session.tool_point)


def consistency(p: np.ndarray, session: Session) -> dict:
    """Self-consistency of predicted ball centres: ours and MUKCa's.

    Parameters
    ----------
    p : (m, 3) array, predicted ball centres of the session's captures, mm
    session : Session, the captures (points ``<position>/hole_k``, 50 mm distances)

    Returns
    -------
    dict with
    'sockets' : name -> n, 'rms_mm' and 'mean_mm': the centres' distance from their own mean
    'positions' : name -> 'distance_error_mm' = | |mean_0 - mean_1| - 50 |; 'mukca_mae_m', the
        N-weighted mean over the two sockets of 'mean_mm' (MUKCa's "mean absolute error",
        calibrate_fk/utils.py evaluate_model), and 'mukca_sigma_m' = sqrt of the N-weighted
        mean of the sockets' total variances (their "consistency"); both in metres
    """
    socks, centre = {}, {}
    for nm in dict.fromkeys(session.point):
        x = p[session.point == nm]
        centre[nm] = x.mean(axis=0)
        r = np.linalg.norm(x - centre[nm], axis=1)
        socks[nm] = {"n": int(len(x)), "rms_mm": float(np.sqrt(np.mean(r**2))), "mean_mm": float(r.mean())}
    pos = {}
    for a, b, d0 in session.distances:
        if a in centre and b in centre:
            na, nb = socks[a]["n"], socks[b]["n"]
            pos[a.rsplit("/", 1)[0]] = {
                "distance_error_mm": float(abs(np.linalg.norm(centre[a] - centre[b]) - d0)),
                "mukca_mae_m": 1e-3 * (na * socks[a]["mean_mm"] + nb * socks[b]["mean_mm"]) / (na + nb),
                "mukca_sigma_m": 1e-3
                * float(np.sqrt((na * socks[a]["rms_mm"] ** 2 + nb * socks[b]["rms_mm"] ** 2) / (na + nb))),
            }
    return {"sockets": socks, "positions": pos}


def summarise(c: dict) -> dict:
    """Counts, and means over sockets (spread) and over positions (distance error, MUKCa's metrics) of
    :func:`consistency`."""
    s, p = list(c["sockets"].values()), list(c["positions"].values())
    return {
        "positions": len(p),
        "captures": int(sum(v["n"] for v in s)),
        "spread_rms_mm": float(np.mean([v["rms_mm"] for v in s])),
        "spread_mean_mm": float(np.mean([v["mean_mm"] for v in s])),
        "distance_error_mm": float(np.mean([v["distance_error_mm"] for v in p])),
        "mukca_mae_m": float(np.mean([v["mukca_mae_m"] for v in p])),
        "mukca_sigma_m": float(np.mean([v["mukca_sigma_m"] for v in p])),
    }


def _merge(parts: list) -> dict:
    """One :func:`consistency` dict from several (disjoint sockets and positions)."""
    return {k: {nm: v for c in parts for nm, v in c[k].items()} for k in ("sockets", "positions")}


def loaded_joints(tau: np.ndarray, min_range: float = LOADED_NM) -> tuple:
    """1-based joints whose gravity torque spans at least ``min_range`` Nm over the captures."""
    return tuple(int(j) + 1 for j in np.flatnonzero(np.ptp(tau, axis=0) >= min_range))


def compliance_ext(joints) -> Extension:
    """A zero joint-compliance extension on ``joints`` (1-based)."""
    return Extension("joint_compliance", tuple(joints), None, np.zeros(len(joints)))


def _ext_cov(ident: Identification) -> np.ndarray:
    """Covariance (k, k) of the extension's parameters (the last k of the estimate)."""
    k = ident.extension.size
    return ident.extra["cov"][-k:, -k:]


def stiffness(c: np.ndarray, se: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Stiffness k = -1/c (Nm/rad) of a sag compliance c (rad/Nm), and its first-order SE se/c^2."""
    c, se = np.asarray(c, float), np.asarray(se, float)
    return -1.0 / c, se / c**2


def homogeneity(values: np.ndarray, covs: np.ndarray) -> dict:
    """Chi-square test that R estimates of one vector agree within their covariances.

    Parameters
    ----------
    values : (R, k) array, one estimate per robot
    covs : (R, k, k) array, their covariances

    Returns
    -------
    dict: 'mean' (k,) the inverse-covariance-weighted mean, 'chi2', 'dof' = k (R - 1), 'p'
    """
    values = np.atleast_2d(values)
    W = np.linalg.inv(covs)
    mean = np.linalg.solve(W.sum(axis=0), np.einsum("rij,rj->i", W, values))
    d = values - mean
    chi2 = float(np.einsum("ri,rij,rj->", d, W, d))
    dof = values.shape[1] * (len(values) - 1)
    from scipy import stats  # imported when a study runs: it is slow to load

    return {"mean": mean.tolist(), "chi2": chi2, "dof": dof, "p": float(stats.chi2.sf(chi2, dof))}


# ------------------------------------------------------------------ 1 and 4: leave one tool position out
def loto(session: Session, common: tuple, fixed: Extension | None, opts: StudyOptions) -> dict:
    """Leave-one-tool-position-out cross-validation of every model.

    Per fold, fitted on the other positions (robust loss on): plain least squares ('plain', no
    outlier test: MUKCa's own optimiser), the geometric model and the effect :func:`diagnose`
    selects and accepts on them by its own inner leave-one-position-out ('nested': no selection
    leak; the geometric model when nothing is kept), that model fitted by plain least squares
    ('nested_plain': what the outlier test costs it), the whole-session finding refitted
    ('fixed'), and joint compliance on ``common`` ('compliance'). Train metrics use the
    training captures the geometric fit kept; test metrics use every held-out capture.

    Parameters
    ----------
    session : Session (a MUKCa robot)
    common : 1-based joints of the compliance model
    fixed : Extension or None, the whole-session finding (parameters ignored)
    opts : StudyOptions

    Returns
    -------
    dict: 'folds' (list of per-fold records), 'train' and 'test' model -> :func:`summarise`
    dict, 'test_detail' model -> :func:`consistency` dict, 'compliance_folds' (F, len(common))
    """
    pos = position_of(session)
    s = replace(session, tau=session_torques(session, opts.payload)[0])
    nominal = session.robot.replace(tool_point=session.tool_point)
    folds, test_parts, c_folds = [], {m: [] for m in MODELS}, []
    for held in dict.fromkeys(pos):
        train, test = s.subset(pos != held), s.subset(pos == held)
        d = diagnose(replace(train, tau=None), alpha=opts.alpha, n_boot=0, k=5, payload=opts.payload)
        geo, sus = d.geometric.model, d.geometric.weights == 0  # extensions are fitted on its rows
        comp = fit(train, compliance_ext(common), suspects=sus)
        fits = {
            "nominal": (nominal, None),
            "plain": (fit(train, robust=False).model, None),
            "geometric": (geo, None),
            "nested": (d.extended.model, d.extended.extension) if d.extended else (geo, None),
            "compliance": (comp.model, comp.extension),
        }
        if d.extended is not None:  # the same extended model without the outlier test
            npl = fit(train, d.extension.with_params(np.zeros(d.extension.size)), robust=False)
            fits["nested_plain"] = (npl.model, npl.extension)
        else:
            fits["nested_plain"] = fits["plain"]
        if fixed is not None:
            fx = fit(train, fixed.with_params(np.zeros(fixed.size)), suspects=sus)
            fits["fixed"] = (fx.model, fx.extension)
        else:
            fits["fixed"] = fits["geometric"]
        used = train.subset(d.geometric.weights > 0)
        rec = {
            "held_out": held,
            "captures": {"train": train.m, "test": test.m},
            "flagged": len(d.geometric.outliers),
            "nested_effect": d.effect,
            "nested_joints": list(d.extension.joints) if d.extension else [],
            "nested_label": d.extension.label if d.extension else "none",
            "nested_p": d.p_value,
            "nested_proposed": d.proposed.effect if d.proposed else "none",
            "converged": bool(d.geometric.converged),
            "train": {},
            "test": {},
        }
        for name, (model, ext) in fits.items():
            rec["train"][name] = summarise(consistency(ball_centres(model, ext, used), used))
            c = consistency(ball_centres(model, ext, test), test)
            rec["test"][name] = summarise(c)
            test_parts[name].append(c)
        g, pl = rec["test"]["geometric"]["spread_rms_mm"], rec["test"]["plain"]["spread_rms_mm"]
        rec["geometric_over_plain"] = g / pl
        rec["nested_over_plain"] = rec["test"]["nested"]["spread_rms_mm"] / pl
        rec["nested_over_nested_plain"] = (
            rec["test"]["nested"]["spread_rms_mm"] / rec["test"]["nested_plain"]["spread_rms_mm"]
        )
        c_folds.append(comp.extension.params.tolist())
        folds.append(rec)
    detail = {m: _merge(test_parts[m]) for m in MODELS}
    train = {
        m: {k: float(np.mean([f["train"][m][k] for f in folds])) for k in folds[0]["train"][m]}
        for m in MODELS
    }
    return {
        "folds": folds,
        "train": train,
        "test": {m: summarise(detail[m]) for m in MODELS},
        "test_detail": detail,
        "compliance_folds": c_folds,
    }


def single_position(session: Session) -> dict:
    """MUKCa's protocol: calibrate (geometry) on one tool position, test on every other one.

    Returns
    -------
    dict: 'train' and 'test' -> [nominal, calibrated] MUKCa metric (m), averaged over the choice
    of training position; 'per_position' -> training position -> the same numbers
    """
    pos = position_of(session)
    nominal = session.robot.replace(tool_point=session.tool_point)
    per = {}
    for P in dict.fromkeys(pos):
        train, test = session.subset(pos == P), session.subset(pos != P)
        g = fit(train)
        per[P] = {
            part: [
                summarise(consistency(ball_centres(m, None, s), s))["mukca_mae_m"] for m in (nominal, g.model)
            ]
            for part, s in (("train", train), ("test", test))
        }
    return {part: np.mean([v[part] for v in per.values()], axis=0).tolist() for part in ("train", "test")} | {
        "per_position": per
    }


def jackknife_se(estimates) -> np.ndarray:
    """Jackknife standard error over leave-one-out estimates (F, k)."""
    e = np.asarray(estimates, float)
    n = len(e)
    return np.sqrt((n - 1) / n * np.sum((e - e.mean(axis=0)) ** 2, axis=0))


# ------------------------------------------------------------------ 2: what the simulation gets wrong
def _group_ms(sq: np.ndarray, groups: np.ndarray) -> tuple[list, np.ndarray, np.ndarray]:
    """Group names, sizes and mean squared residual per group ((G,) or (G, B))."""
    names = list(dict.fromkeys(groups))
    n = np.array([np.sum(groups == g) for g in names])
    return names, n, np.array([sq[groups == g].mean(axis=0) for g in names])


def _bartlett(n: np.ndarray, ms: np.ndarray) -> np.ndarray:
    """Heterogeneity of group mean squares: sum_g n_g log(pooled / ms_g) (0 when all agree)."""
    n = n.reshape(-1, *([1] * (ms.ndim - 1)))
    pooled = np.sum(n * ms, axis=0) / n.sum()
    return np.sum(n * np.log(pooled / ms), axis=0)


def _lag1(R: np.ndarray, groups: np.ndarray) -> np.ndarray:
    """Lag-1 correlation of residuals (m, 3[, B]) within groups, in capture (recording) order."""
    num = 0.0
    for g in dict.fromkeys(groups):
        r = R[groups == g]
        num = num + np.sum(r[1:] * r[:-1], axis=(0, 1))
    return num / np.sum(R * R, axis=(0, 1))


def _upper_p(sim: np.ndarray, observed: float) -> float:
    """Share of simulated statistics at least as large as the observed one (rank p-value)."""
    return float((1 + np.sum(sim >= observed)) / (len(sim) + 1))


def _scaled_chi2_p(sim: np.ndarray, observed: np.ndarray) -> np.ndarray:
    """Upper-tail p of each observed mean square against its simulated ones (G, B), through the
    scaled chi-square with the simulated mean and variance (Satterthwaite): smooth beyond 1/B."""
    mean, var = sim.mean(axis=1), sim.var(axis=1)
    from scipy import stats  # imported when a study runs: it is slow to load

    return stats.chi2.sf(observed * 2 * mean / var, 2 * mean**2 / var)


def simulation_check(d: Diagnosis, n_sim: int, rng: np.random.Generator) -> tuple[dict, dict]:
    """Measured geometric-fit residuals against the same experiment simulated on the fitted robot.

    The simulation: the identified geometric robot, the same configurations, Gaussian noise
    at the fit's per-axis sigma on every kept capture, refitted to first order (noise minus
    its projection on the fit's identifiable span, constraint rows included). Compared:

    * size: RMS (mm) -- equal by construction (sigma comes from these residuals), a check;
      the diagnosis's full nonlinear refits are reported beside it;
    * per socket and per position: the spread of the mean squares, sum_g n_g log(pooled/ms_g),
      and each group's mean square against its simulated ones (scaled chi-square, Bonferroni);
    * lag-1 correlation within each socket in recording order;
    * per candidate regressor (gravity torque, sin/cos q, recording order, at each joint): the
      share of the residual's sum of squares its columns explain beyond the geometry (partial R^2),
      and its overlap with the strongest candidate (largest canonical correlation of the two column
      spaces beyond the geometry: near 1, the data cannot tell the two apart).

    Other p-values are the measured statistic's rank among the simulated ones (upper tail).

    Returns
    -------
    (report dict, plot dict with per-socket measured and simulated RMS)
    """
    s, geo = d.session, d.geometric
    used = geo.weights > 0
    exts = candidates(s.robot.n, [], s.tau is not None, s.clock == "seconds" and np.ptp(s.t) > 0)
    T = Tester(s, geo, exts, s.tau)
    n3 = T.n_capture_rows
    E = np.zeros((T.res.size, n_sim))
    E[:n3] = rng.normal(0.0, geo.sigma_mm, (n3, n_sim))
    R = E - T.U @ (T.U.T @ E)
    Rc = R[:n3].reshape(-1, 3, n_sim)
    rc = T.res[:n3].reshape(-1, 3)
    sq_sim, sq = np.sum(Rc**2, axis=1), np.sum(rc**2, axis=1)
    sock = s.point[used]
    pos = position_of(s)[used]
    out = {"sigma_mm": geo.sigma_mm, "captures_used": int(used.sum()), "replicates": n_sim}
    rms_sim = np.sqrt(sq_sim.mean(axis=0))
    boot = d.bootstrap or {}
    out["size"] = {
        "measured_rms_mm": float(np.sqrt(sq.mean())),
        "simulated_rms_mm": [float(rms_sim.mean()), float(rms_sim.std())],
        "full_refits_rms_mm": [float(np.mean(boot["rms_mm"])), float(np.std(boot["rms_mm"]))]
        if boot.get("rms_mm")
        else None,
        "full_refits": len(boot.get("rms_mm", [])),
    }
    plot = {}
    for key, groups in (("sockets", sock), ("positions", pos)):
        names, n, ms = _group_ms(sq, groups)
        _, _, ms_sim = _group_ms(sq_sim, groups)
        H, H_sim = float(_bartlett(n, ms)), _bartlett(n, ms_sim)
        lo, mid, hi = np.sqrt(np.percentile(ms_sim, [5, 50, 95], axis=1))
        p = _scaled_chi2_p(ms_sim, ms)
        groups_out = {
            nm: {
                "n": int(k),
                "measured_rms_mm": float(np.sqrt(m)),
                "simulated_rms_mm_5_50_95": [float(a), float(b), float(c)],
                "p": float(pi),
                "p_bonferroni": float(min(1.0, pi * len(names))),
            }
            for nm, k, m, a, b, c, pi in zip(names, n, ms, lo, mid, hi, p)
        }
        out[key] = {
            "heterogeneity": H,
            "simulated_heterogeneity_95": float(np.percentile(H_sim, 95)),
            "p": _upper_p(H_sim, H),
            "groups": groups_out,
        }
        plot[key] = {"names": names, "measured": np.sqrt(ms), "band": np.vstack([lo, mid, hi])}
    rho, rho_sim = float(_lag1(rc, sock)), _lag1(Rc, sock)
    out["lag1"] = {
        "measured": rho,
        "simulated_95": float(np.percentile(rho_sim, 95)),
        "p": _upper_p(rho_sim, rho),
    }
    rss, rss_sim = float(T.res @ T.res), np.sum(R**2, axis=0)
    tests = T.tests()
    test_of = {id(t.extension): t for t in tests}
    Q_best = T.Q[[id(e) for e in exts].index(id(tests[0].extension))]
    rows = []
    for e, Q in zip(exts, T.Q):
        if Q.shape[1] == 0:
            continue
        r2 = float(np.sum((Q.T @ T.res) ** 2) / rss)
        r2_sim = np.sum((Q.T @ R) ** 2, axis=0) / rss_sim
        t = test_of[id(e)]
        rows.append(
            {
                "candidate": t.label,
                "regressor": _regressor_name(e),
                "partial_r2": r2,
                "simulated_r2_95": float(np.percentile(r2_sim, 95)),
                "p_simulated": _upper_p(r2_sim, r2),
                "p_F": t.p,
                "p_F_bonferroni": t.p_adjusted,
                "overlap_with_best": float(np.linalg.svd(Q_best.T @ Q, compute_uv=False)[0]),
            }
        )
    out["regressors"] = sorted(rows, key=lambda r: -r["partial_r2"])
    return out, plot


def _regressor_name(e: Extension) -> str:
    """What a joint candidate regresses on, in words."""
    j = e.joints[0]
    return {
        "joint_compliance": f"gravity torque tau{j}",
        "encoder_eccentricity": f"sin q{j}, cos q{j}",
        "drift": f"recording order (joint {j})",
    }[e.effect]


# ------------------------------------------------------------------ 3: diagnosis
def diagnosis_summary(d: Diagnosis) -> dict:
    """:meth:`Diagnosis.as_dict` without its fit-residual 'held-out' numbers (k = 0; the study's gain is
    LOTO's)."""
    o = d.as_dict()
    for k in ("holdout_rms_mm", "gain_percent"):
        o.pop(k)
    o["geometric_rms_mm"] = d.geometric.rms_mm
    o["extended_rms_mm"] = d.extended.rms_mm if d.extended else None
    o["converged"] = {
        "geometric": d.geometric.converged,
        "extended": d.extended.converged if d.extended else None,
    }
    return o


def _regressor_plot(d: Diagnosis) -> dict:
    """Component-plus-residual data for the finding's first joint: the extended fit's residuals as that
    joint's motion plus the fitted effect, against its regressor (the geometric fit's residuals for
    'none')."""
    s = d.session
    fitted = d.extended or d.geometric
    ext = (d.extension or d.tests[0].extension).parts[0]  # a combination: its first effect
    j = ext.joints[0] - 1
    used = fitted.weights > 0
    q = d.extension.true_q(s.q, s.t, s.tau) if d.extension else s.q
    col = tip_joint_jacobian(fitted.model, q)[1][:, :, j]
    along = -np.sum(fitted.residuals * col, axis=1) / np.maximum(
        np.sum(col**2, axis=1), 1e-12
    )  # rad that would remove it
    x = {"joint_compliance": s.tau[:, j], "encoder_eccentricity": s.q[:, j], "drift": s.t}[ext.effect]
    xlabel = {
        "joint_compliance": f"gravity torque tau{j + 1} (Nm)",
        "encoder_eccentricity": f"q{j + 1} (rad)",
        "drift": "recording order",
    }[ext.effect]
    effect = np.zeros(s.m)
    if d.extension is not None:
        p = d.extension.parts[0].params
        effect = p[0] * np.sin(x) + p[1] * np.cos(x) if ext.effect == "encoder_eccentricity" else p[0] * x
    order = np.argsort(x[used])
    return {
        "x": x[used],
        "y": (along + effect)[used],
        "effect": effect[used][order],
        "x_sorted": x[used][order],
        "xlabel": xlabel,
        "joint": j + 1,
        "name": ext.effect if d.extension else "none",
        "fitted": d.extension is not None,
    }


# ------------------------------------------------------------------ 5: outliers
def outlier_audit(
    raw: Session,
    geo: Identification,
    removed: list,
    alpha: float,
    size_p: dict,
    clean: Session | None = None,
    clean_geo: Identification | None = None,
) -> dict:
    """The robust loss's flagged rows against the tool positions the authors removed by hand.

    Parameters
    ----------
    raw : Session, every position
    geo : Identification, robust geometric fit of ``raw``
    removed : tool positions missing from the authors' cleaned folder
    alpha : float, family-wise level of the position screens
    size_p : position -> Bonferroni-corrected p that its kept rows' residual mean square exceeds
        the simulated experiment's (:func:`simulation_check`)
    clean, clean_geo : the cleaned session and its robust fit, optional

    Returns
    -------
    dict: 'confusion' (rows by removed/kept x flagged/not), 'precision', 'recall', 'positions'
    (per position: captures, flagged, one-sided Fisher exact p that its flag share exceeds the
    other positions', Bonferroni-corrected), 'screened' (positions with corrected p < alpha),
    'screened_by_size' (positions whose kept rows are larger than simulated, corrected p < alpha),
    and 'clean' (rows of the kept positions flagged in the raw and in the clean fit)
    """
    from scipy import stats  # imported when a study runs: it is slow to load

    pos = position_of(raw)
    flagged = geo.weights == 0
    rem = np.isin(pos, list(removed))
    names = list(dict.fromkeys(pos))
    per = {}
    for P in names:
        sel = pos == P
        k, n, k2, n2 = int(flagged[sel].sum()), int(sel.sum()), int(flagged[~sel].sum()), int((~sel).sum())
        p = float(stats.fisher_exact([[k, n - k], [k2, n2 - k2]], alternative="greater").pvalue)
        per[P] = {
            "captures": n,
            "flagged": k,
            "p": p,
            "p_bonferroni": min(1.0, p * len(names)),
            "removed_by_authors": P in removed,
            "size_p_bonferroni": size_p.get(P),
        }
    conf = {
        "removed_flagged": int(np.sum(rem & flagged)),
        "removed_not_flagged": int(np.sum(rem & ~flagged)),
        "kept_flagged": int(np.sum(~rem & flagged)),
        "kept_not_flagged": int(np.sum(~rem & ~flagged)),
    }
    out = {
        "removed_by_authors": sorted(removed),
        "flagged": int(flagged.sum()),
        "captures": raw.m,
        "confusion": conf,
        "precision": conf["removed_flagged"] / max(flagged.sum(), 1),
        "recall": conf["removed_flagged"] / rem.sum() if rem.any() else None,
        "positions": per,
        "screened": [P for P in names if per[P]["p_bonferroni"] < alpha],
        "screened_by_size": [P for P in names if size_p.get(P, 1.0) < alpha],
    }
    if clean is not None:
        same = (
            clean.m == int((~rem).sum())
            and np.array_equal(clean.q, raw.q[~rem])
            and np.array_equal(clean.point, raw.point[~rem])
        )
        fc, fr = clean_geo.weights == 0, flagged[~rem]
        out["clean"] = {
            "captures": clean.m,
            "flagged": int(fc.sum()),
            "rows_match_raw": bool(same),
            "flagged_in_both": int(np.sum(fc & fr)) if same else None,
            "only_raw": int(np.sum(fr & ~fc)) if same else None,
            "only_clean": int(np.sum(fc & ~fr)) if same else None,
        }
    return out


# ------------------------------------------------------------------ one robot, the whole study
def study_robot(
    session: Session, common: tuple, opts: StudyOptions, clean: Session | None = None, removed=()
) -> RobotStudy:
    """Parts 1-5 for one robot.

    Parameters
    ----------
    session : Session, the robot's MUKCa data (every position)
    common : 1-based joints of the compliance compared across robots
    opts : StudyOptions
    clean : Session, the authors' cleaned subset, optional
    removed : tool positions the cleaned subset lacks

    Returns
    -------
    RobotStudy
    """
    if len(set(position_of(session))) < 2:
        raise FormatError(session.path, "leaving one tool position out needs at least two positions")
    t0 = time.perf_counter()
    rng = np.random.default_rng(opts.seed)
    d = diagnose(
        session,
        alpha=opts.alpha,
        n_boot=opts.bootstrap,
        seed=opts.seed,
        k=5,  # point sessions: leave one tool position out decides whether the F test's finding is kept
        payload=opts.payload,
        n_refit=opts.refits,
    )
    sim, sim_plot = simulation_check(d, opts.bootstrap, rng)
    comp = fit(d.session, compliance_ext(common))
    cv = loto(session, common, d.extension, opts)
    c, cov = comp.extension.params, _ext_cov(comp)
    se = np.sqrt(np.diag(cov))
    rep = {
        "captures": session.m,
        "positions": list(dict.fromkeys(position_of(session))),
        "torques": d.torque_source,
        "calibration": {
            "train": cv["train"],
            "test": cv["test"],
            "folds": cv["folds"],
            "test_detail": cv["test_detail"],
            "mukca_protocol": single_position(session),
        },
        "simulation": sim,
        "diagnosis": diagnosis_summary(d),
        "extension": {
            "gain_percent": {m: _gain(cv["test"], m) for m in ("nested", "fixed", "compliance")},
            "compliance": {
                "joints": list(common),
                "c_rad_per_nm": c.tolist(),
                "se_rad_per_nm": se.tolist(),
                "cov": cov.tolist(),
                "se_jackknife_rad_per_nm": jackknife_se(cv["compliance_folds"]).tolist(),
                "folds_rad_per_nm": cv["compliance_folds"],
                "rms_mm": comp.rms_mm,
                "geometric_rms_mm": d.geometric.rms_mm,
            },
        },
    }
    clean_geo = None
    if clean is not None:
        dc = diagnose(clean, alpha=opts.alpha, n_boot=0, k=0, payload=opts.payload)
        cc = fit(dc.session, compliance_ext(common))
        clean_geo = dc.geometric
        rep["clean"] = {
            "captures": clean.m,
            "diagnosis": diagnosis_summary(dc),
            "compliance": {
                "c_rad_per_nm": cc.extension.params.tolist(),
                "cov": _ext_cov(cc).tolist(),
                "se_rad_per_nm": np.sqrt(np.diag(_ext_cov(cc))).tolist(),
            },
        }
    size_p = {P: g["p_bonferroni"] for P, g in sim["positions"]["groups"].items()}
    if removed:
        kept = {
            m: {k: {nm: v for nm, v in det[k].items() if nm.rsplit("/", 1)[0] not in removed} for k in det}
            for m, det in cv["test_detail"].items()
        }
        rep["calibration"]["test_kept"] = {m: summarise(det) for m, det in kept.items()}
    rep["outliers"] = outlier_audit(session, d.geometric, list(removed), opts.alpha, size_p, clean, clean_geo)
    rep["conclusion"] = conclusion(rep)
    rep["seconds"] = time.perf_counter() - t0
    return RobotStudy(rep, {"regressor": _regressor_plot(d), "simulation": sim_plot})


def conclusion(rep: dict) -> dict:
    """The robot's one-line conclusion: the effect kept (or none) and its held-out gain over the folds.

    The effect is the whole-session diagnosis's, kept only if leave-one-tool-position-out improved
    (:func:`solver.analysis.diagnose.diagnose`); the gain is that of the nested model (selected and
    accepted inside each fold) over the geometric one in held-out spread RMS, per fold, with a
    Student-t 95 % interval over the folds.
    """
    folds = rep["calibration"]["folds"]
    g = np.array([f["test"]["geometric"]["spread_rms_mm"] for f in folds])
    e = np.array([f["test"]["nested"]["spread_rms_mm"] for f in folds])
    gains = 100.0 * (g - e) / g
    h = stdtrit(len(gains) - 1, 0.975) * gains.std(ddof=1) / np.sqrt(len(gains)) if len(gains) > 1 else np.nan
    dg = rep["diagnosis"]
    kept = dg["label"]
    worst = max(max(f["geometric_over_plain"], f["nested_over_nested_plain"]) for f in folds)
    line = (
        f"{kept}; held-out spread geometric {g.mean():.3f} -> extended {e.mean():.3f} mm, gain "
        f"{gains.mean():+.1f}% (95% CI {gains.mean() - h:+.1f} to {gains.mean() + h:+.1f}% over "
        f"{len(g)} folds); "
        f"robust/plain worst fold {worst:.3f}"
    )
    if dg.get("proposed") and dg["effect"] == "none":
        line += f" (F test proposed {dg['proposed']['effect']}, held-out rejected it)"
    return {
        "effect": dg["effect"],
        "joints": dg["joints"],
        "gain_percent_mean": float(gains.mean()),
        "gain_percent_ci95": [float(gains.mean() - h), float(gains.mean() + h)],
        "gain_percent_folds": gains.tolist(),
        "worst_geometric_over_plain": float(worst),
        "line": line,
    }


def _gain(test: dict, model: str) -> float:
    """Held-out gain (%) of a model over the geometric one in per-socket spread RMS."""
    g = test["geometric"]["spread_rms_mm"]
    return 100.0 * (g - test[model]["spread_rms_mm"]) / g


def agreement(studies: dict) -> dict | None:
    """Chi-square homogeneity of the robots' compliance vectors, jointly and per joint.

    Formal covariances from the fits, and jackknife (leave-one-position-out) variances, which
    also carry the scatter between positions that the formal ones assume away.
    """
    if len(studies) < 2:
        return None
    comps = [st.report["extension"]["compliance"] for st in studies.values()]
    c = np.array([x["c_rad_per_nm"] for x in comps])
    cov = np.array([x["cov"] for x in comps])
    jack = np.array([np.diag(np.square(x["se_jackknife_rad_per_nm"])) for x in comps])
    joints = comps[0]["joints"]
    out = {"robots": list(studies), "joints": joints}
    for name, C in (("formal", cov), ("jackknife", jack)):
        out[name] = {
            "all_joints": homogeneity(c, C),
            "per_joint": {
                str(j): homogeneity(c[:, [i]], C[:, i : i + 1, i : i + 1]) for i, j in enumerate(joints)
            },
        }
    clean = {r: st.report["clean"]["compliance"] for r, st in studies.items() if "clean" in st.report}
    if clean:
        cc = np.array(
            [clean[r]["c_rad_per_nm"] if r in clean else x["c_rad_per_nm"] for r, x in zip(studies, comps)]
        )
        cv = np.array([clean[r]["cov"] if r in clean else x["cov"] for r, x in zip(studies, comps)])
        out["formal_clean_subsets"] = {"all_joints": homogeneity(cc, cv), "substituted": sorted(clean)}
    return out


def run_study(data_dir, out, robots=ROBOTS, opts: StudyOptions | None = None) -> dict:
    """The whole study: every robot, the agreement test, report files and plots.

    Parameters
    ----------
    data_dir : folder holding ``panda_k`` (and ``panda_k_clean``) MUKCa folders
    out : report folder: report.json, report.md, PNG plots, sessions/ (the imported sessions)
    robots : robot folder names
    opts : StudyOptions

    Returns
    -------
    the report dict (as written to report.json)
    """
    opts = opts or StudyOptions()
    t0 = time.perf_counter()
    data_dir, out = Path(data_dir), Path(out)
    out.mkdir(parents=True, exist_ok=True)
    sessions = {r: load_robot(data_dir, r, out / "sessions") for r in robots}
    cleans = {
        r: load_robot(data_dir, f"{r}_clean", out / "sessions")
        for r in robots
        if (data_dir / f"{r}_clean").is_dir()
    }
    common = tuple(
        sorted(
            set.intersection(
                *(set(loaded_joints(session_torques(s, opts.payload)[0])) for s in sessions.values())
            )
        )
    )
    studies = {}
    for r, s in sessions.items():
        removed = (
            sorted(set(positions(data_dir / r)) - set(positions(data_dir / f"{r}_clean")))
            if r in cleans
            else []
        )
        studies[r] = study_robot(s, common, opts, cleans.get(r), removed)
    report = {
        "dataset": str(data_dir),
        "robots": {r: st.report for r, st in studies.items()},
        "agreement": agreement(studies),
        "published": PUBLISHED,
        "compliance_joints": list(common),
        "options": {
            "bootstrap": opts.bootstrap,
            "refits": opts.refits,
            "alpha": opts.alpha,
            "seed": opts.seed,
            "payload_kg": opts.payload[0],
            "payload_com_mm": list(opts.payload[1]),
        },
    }
    report["files"] = ["report.json", "report.md"] + [
        f.name for f in write_plots(report, {r: st.plot for r, st in studies.items()}, out)
    ]
    report["seconds"] = time.perf_counter() - t0
    report = _jsonable(report)
    (out / "report.json").write_text(json.dumps(report, indent=1) + "\n")
    (out / "report.md").write_text(markdown(report))
    return report


# ------------------------------------------------------------------ report files
def _jsonable(o):
    """Plain JSON types, floats to 6 significant digits."""
    if isinstance(o, dict):
        return {str(k): _jsonable(v) for k, v in o.items()}
    if isinstance(o, (list, tuple, np.ndarray)):
        return [_jsonable(v) for v in o]
    if isinstance(o, (bool, np.bool_)):
        return bool(o)
    if isinstance(o, (int, np.integer)):
        return int(o)
    if isinstance(o, (float, np.floating)):
        return float(f"{o:.6g}") if np.isfinite(o) else None
    return o


def _table(header: list, rows: list) -> str:
    """A Markdown table."""
    lines = ["| " + " | ".join(header) + " |", "|" + "|".join("---" for _ in header) + "|"]
    return "\n".join(lines + ["| " + " | ".join(str(c) for c in r) + " |" for r in rows])


def _p(p) -> str:
    return "n/a" if p is None else f"{p:.2g}"


def _reading(c: float, se: float) -> str:
    """What a compliance estimate says physically (sag: c < 0, see the module docstring)."""
    if c < -2 * se:
        return "sag (a stiffness)"
    if c > 2 * se:
        return "anti-sag: not a stiffness"
    return "not resolved"


def markdown(rep: dict) -> str:
    """The study as a Markdown report (tables; the plots are separate PNG files)."""
    R = rep["robots"]
    o = rep["options"]
    md = ["# MUKCa real-data study: four Franka Pandas", ""]
    md += ["## Conclusion per robot", ""]
    md += [f"- **{r}**: {x['conclusion']['line']}" for r, x in R.items()]
    md += [
        "",
        "Not tested on these data: "
        + "; ".join(f"{e} ({why})" for e, why in next(iter(R.values()))["diagnosis"]["untested"].items()),
        "",
    ]
    md.append(
        f"Data `{rep['dataset']}` (joint angles only). Robust loss on. Gravity torques from the link masses "
        "plus a payload of "
        f"{o['payload_kg']} kg at {o['payload_com_mm']} mm (q = 0): the Franka hand and the ball tool. Alpha "
        f"= {o['alpha']} "
        f"(family-wise); {o['bootstrap']} simulated replicates, {o['refits']} full refits. Study time "
        f"{rep['seconds']:.0f} s."
    )
    md += [
        "",
        "Metrics. Ours, per socket: the spread of the predicted ball centres about their own mean (RMS and "
        "mean "
        "distance, mm); per tool position: |d - 50|, the error of the distance between the two sockets' mean "
        "centres (mm). "
        "MUKCa's metric (calibrate_fk/utils.py `evaluate_model`, printed by `compute_improved_performance` "
        'as "mean absolute '
        'error", metres): per position the N-weighted mean over both sockets of the mean distance from the '
        "socket's mean "
        "(our mean spread, pooled over the two sockets), averaged over positions. Leave one tool position "
        "out: train = the "
        "other positions (the captures the robust fit kept), averaged over folds; test = the held-out "
        "position, predicted by "
        "a model that never saw it (its sockets are unknown: the predicted centres' own means).",
    ]
    md += ["", "## 1. Nominal vs geometric calibration (leave one tool position out)", ""]
    rows = []
    for r, x in R.items():
        for part, label in (
            ("train", "train"),
            ("test", "test"),
            ("test_kept", "test, positions the authors kept"),
        ):
            if part not in x["calibration"]:
                continue
            c = x["calibration"][part]
            rows.append(
                [r, label, f"{c['nominal']['positions']:.0f}", f"{c['nominal']['captures']:.0f}"]
                + [f"{c[m]['spread_rms_mm']:.3f}" for m in ("nominal", "geometric", "nested")]
                + [f"{c[m]['spread_mean_mm']:.3f}" for m in ("nominal", "geometric", "nested")]
                + [f"{c[m]['distance_error_mm']:.3f}" for m in ("nominal", "geometric", "nested")]
            )
    md.append(
        _table(
            [
                "robot",
                "set",
                "positions",
                "captures",
                "RMS nominal",
                "RMS geometric",
                "RMS extended",
                "mean nominal",
                "mean geometric",
                "mean extended",
                "abs(d-50) nominal",
                "abs(d-50) geometric",
                "abs(d-50) extended",
            ],
            rows,
        )
    )
    md += [
        "",
        "Spreads and distance errors in mm, means over sockets (positions); train: per fold, averaged over "
        "folds. 'Extended': the effect the diagnosis selects on "
        "the training positions, fitted with the geometry (nested: no selection leak; section 4 has the "
        "whole-session finding).",
        "",
        "### MUKCa's metric beside their published figures",
        "",
    ]
    pub = rep["published"]
    arrow = lambda v: f"{v[0]:.2e} -> {v[1]:.2e}"  # noqa: E731
    rows = [[f"{pub['robot']} (MUKCa, published)", arrow(pub["train_m"]), arrow(pub["test_m"]), "", ""]]
    for r, x in R.items():
        c, mp = x["calibration"], x["calibration"]["mukca_protocol"]
        rows.append(
            [f"{r} (ours)"]
            + [
                arrow([c[s]["nominal"]["mukca_mae_m"], c[s]["geometric"]["mukca_mae_m"]])
                for s in ("train", "test")
            ]
            + [arrow(mp["train"]), arrow(mp["test"])]
        )
    md.append(
        _table(
            [
                "robot",
                "LOTO train: nominal -> calibrated (m)",
                "LOTO test",
                "one position -> the others: train",
                "test",
            ],
            rows,
        )
    )
    md += [
        "",
        "Their protocol (`run_optimizer.py`, `compute_improved_performance`): calibrate on the positions "
        "given, test on the "
        "robot's other folders; the last two columns calibrate on one position and test on all others, "
        "averaged over the choice "
        "of position. Their panda_1 folders (front, side_right, window, right) are not all in this copy of "
        "the data "
        f"(back-high, front, right). Their paper's abstract: {pub['abstract']}.",
        "",
        "### Per held-out position (test)",
        "",
    ]
    rows = []
    for r, x in R.items():
        for f in x["calibration"]["folds"]:
            t = f["test"]
            rows.append(
                [r, f["held_out"], f["captures"]["test"]]
                + [f"{t[m]['spread_rms_mm']:.3f}" for m in ("nominal", "geometric", "nested", "fixed")]
                + [f"{t[m]['distance_error_mm']:.3f}" for m in ("nominal", "geometric", "nested", "fixed")]
                + [f["nested_label"]]
            )
    md.append(
        _table(
            [
                "robot",
                "held out",
                "captures",
                "RMS nominal",
                "RMS geometric",
                "RMS nested",
                "RMS whole-session finding",
                "abs(d-50) nominal",
                "abs(d-50) geometric",
                "abs(d-50) nested",
                "abs(d-50) whole-session finding",
                "effect selected in the fold",
            ],
            rows,
        )
    )
    md += [
        "",
        "## 2. What the simulation gets wrong",
        "",
        "The experiment re-run on the identified geometric robot: same configurations, Gaussian noise at the "
        "per-axis sigma "
        "the fit implies, refitted to first order. Each p is the measured statistic's rank among the "
        "simulated ones (it cannot "
        f"go below 1/(replicates + 1) = {1 / (o['bootstrap'] + 1):.2g}). The RMS "
        "agrees by construction (sigma is estimated from the same residuals); the structure is what the "
        "simulation cannot "
        "reproduce.",
        "",
    ]
    rows = []
    for r, x in R.items():
        s = x["simulation"]
        top = s["regressors"][0]
        full = s["size"]["full_refits_rms_mm"]
        rows.append(
            [
                r,
                f"{s['sigma_mm']:.3f}",
                f"{s['size']['measured_rms_mm']:.3f}",
                f"{s['size']['simulated_rms_mm'][0]:.3f}",
                f"{full[0]:.3f} +- {full[1]:.3f}" if full else "n/a",
                f"{s['sockets']['heterogeneity']:.1f} ({s['sockets']['simulated_heterogeneity_95']:.1f}); p "
                f"= {_p(s['sockets']['p'])}",
                f"{s['positions']['heterogeneity']:.1f} "
                f"({s['positions']['simulated_heterogeneity_95']:.1f}); p = {_p(s['positions']['p'])}",
                f"{s['lag1']['measured']:.3f} ({s['lag1']['simulated_95']:.3f}); p = {_p(s['lag1']['p'])}",
                f"{top['regressor']}: {top['partial_r2']:.3f} ({top['simulated_r2_95']:.4f}); p = "
                f"{_p(top['p_simulated'])}",
                _p(x["diagnosis"]["details"]["bootstrap_p_value"]),
            ]
        )
    md.append(
        _table(
            [
                "robot",
                "sigma (mm/axis)",
                "RMS measured",
                "RMS simulated",
                "RMS full refits",
                "socket heterogeneity (sim 95 %)",
                "position heterogeneity (sim 95 %)",
                "lag-1 correlation (sim 95 %)",
                "strongest regressor: partial R2 (sim 95 %)",
                "bootstrap p, best of all candidates",
            ],
            rows,
        )
    )
    md += [
        "",
        "Partial R2: the share of the residual sum of squares a candidate's columns explain beyond the "
        "geometry. "
        "'Recording order' is the order of the imported rows: within a socket the recording order, across "
        "positions alphabetical "
        "(the data carry no times).",
        "",
        "### Candidate regressors (top 6 per robot)",
        "",
    ]
    rows = [
        [
            r,
            g["regressor"],
            g["candidate"],
            f"{g['partial_r2']:.4f}",
            f"{g['simulated_r2_95']:.4f}",
            _p(g["p_simulated"]),
            _p(g["p_F_bonferroni"]),
            f"{g['overlap_with_best']:.2f}",
        ]
        for r, x in R.items()
        for g in x["simulation"]["regressors"][:6]
    ]
    md.append(
        _table(
            [
                "robot",
                "regressor",
                "candidate",
                "partial R2",
                "simulated 95 %",
                "p (simulated)",
                "p (F, Bonferroni)",
                "overlap with the strongest",
            ],
            rows,
        )
    )
    md += [
        "",
        "Overlap: the largest canonical correlation between a candidate's columns and the strongest "
        "candidate's, both beyond "
        "the geometry; near 1 the data cannot tell them apart (a joint's gravity torque and sin q of the "
        "same joint, say).",
    ]
    md += ["", "## 3. Causes (diagnosis of the whole session)", ""]
    rows = []
    for r, x in R.items():
        dg = x["diagnosis"]
        params = ", ".join(
            f"{k} = {v['value']:.3g} +- {v['std_error']:.2g}" for k, v in dg["parameters"].items()
        )
        runner = "; ".join(
            f"{c['candidate']} ({_p(c['p_adjusted'])})" for c in dg["details"]["candidates"][1:4]
        )
        rows.append(
            [
                r,
                dg["effect"],
                ",".join(map(str, dg["joints"])),
                _p(dg["p_value"]),
                _p(dg["details"]["bootstrap_p_value"]),
                params
                + (
                    f" ({'; '.join(dict.fromkeys(v['units'] for v in dg['parameters'].values()))})"
                    if params
                    else ""
                ),
                runner,
            ]
        )
    md.append(
        _table(
            [
                "robot",
                "finding",
                "joints",
                "p (Bonferroni)",
                "p (bootstrap)",
                "parameters",
                "runners-up (p, Bonferroni)",
            ],
            rows,
        )
    )
    md += ["", "## 4. Extended model: held-out gain, stiffness", ""]
    rows = []
    for r, x in R.items():
        t, g = x["calibration"]["test"], x["extension"]["gain_percent"]
        rows.append(
            [
                r,
                f"{t['geometric']['spread_rms_mm']:.3f}",
                f"{t['nested']['spread_rms_mm']:.3f} ({g['nested']:+.1f} %)",
                f"{t['fixed']['spread_rms_mm']:.3f} ({g['fixed']:+.1f} %)",
                f"{t['compliance']['spread_rms_mm']:.3f} ({g['compliance']:+.1f} %)",
            ]
        )
    joints = ",".join(map(str, rep["compliance_joints"]))
    md.append(
        _table(
            [
                "robot",
                "geometric",
                "nested (selected per fold)",
                "whole-session finding",
                f"compliance at {joints}",
            ],
            rows,
        )
    )
    md += [
        "",
        "Held-out per-socket spread RMS (mm) and gain over the geometric model, leave one position out.",
        "",
        f"### Joint compliance at the gravity-loaded joints ({joints})",
        "",
        "Sign: tau is the torque holding the arm (dV/dq), so a sag has c < 0 and the stiffness is k = -1/c. "
        "SE: formal "
        "(from the fit) and jackknife over tool positions.",
        "",
    ]
    rows = []
    for r, x in R.items():
        cm = x["extension"]["compliance"]
        k, sk = stiffness(cm["c_rad_per_nm"], cm["se_rad_per_nm"])
        for i, j in enumerate(cm["joints"]):
            c, se, sj = cm["c_rad_per_nm"][i], cm["se_rad_per_nm"][i], cm["se_jackknife_rad_per_nm"][i]
            rows.append(
                [
                    r,
                    j,
                    f"{1e6 * c:.1f} +- {1e6 * se:.1f}",
                    f"{1e6 * sj:.1f}",
                    f"{1e-3 * k[i]:.1f} +- {1e-3 * sk[i]:.1f}" if c < -2 * se else "-",
                    _reading(c, se),
                ]
            )
    md.append(
        _table(
            ["robot", "joint", "c (urad/Nm) +- SE", "jackknife SE", "k = -1/c (kNm/rad) +- SE", "reading"],
            rows,
        )
    )
    ag = rep["agreement"]
    if ag:
        md += ["", "Agreement of the robots (chi-square homogeneity of c):", ""]
        rows = []
        for name in ("formal", "jackknife"):
            a = ag[name]
            rows.append([name, "all"] + _hom(a["all_joints"]))
            rows += [[name, j] + _hom(h) for j, h in a["per_joint"].items()]
        if "formal_clean_subsets" in ag:
            rows.append(
                [f"formal, clean subsets for {', '.join(ag['formal_clean_subsets']['substituted'])}", "all"]
                + _hom(ag["formal_clean_subsets"]["all_joints"])
            )
        md.append(_table(["covariance", "joint", "weighted mean c (urad/Nm)", "chi2", "dof", "p"], rows))
    md += ["", "## 5. Outliers and the sets the authors removed", ""]
    rows = []
    for r, x in R.items():
        a = x["outliers"]
        cf = a["confusion"]
        rows.append(
            [
                r,
                ", ".join(a["removed_by_authors"]) or "-",
                a["flagged"],
                f"{cf['removed_flagged']} / {cf['removed_flagged'] + cf['removed_not_flagged']}",
                f"{cf['kept_flagged']} / {cf['kept_flagged'] + cf['kept_not_flagged']}",
                ", ".join(a["screened"]) or "-",
                ", ".join(a["screened_by_size"]) or "-",
                ", ".join(
                    f"{p} {v['flagged']}/{v['captures']}" for p, v in a["positions"].items() if v["flagged"]
                )
                or "-",
            ]
        )
    md.append(
        _table(
            [
                "robot",
                "removed by the authors",
                "rows flagged",
                "flagged / rows in removed positions",
                "flagged / rows in kept positions",
                "positions: share flagged (Fisher)",
                "positions: residual size (simulation)",
                "flagged per position",
            ],
            rows,
        )
    )
    md += [
        "",
        "Position screens, both Bonferroni over positions at alpha: the share of flagged rows against the "
        "other positions' "
        "(one-sided Fisher exact test), and the kept rows' residual mean square against the simulated "
        "experiment's.",
    ]
    for r, x in R.items():
        a = x["outliers"]
        if not a["removed_by_authors"]:
            continue
        cf = a["confusion"]
        md += [
            "",
            f"{r}: rows by the authors' cleaning and our robust loss",
            "",
            _table(
                ["", "flagged", "not flagged"],
                [
                    ["removed by the authors", cf["removed_flagged"], cf["removed_not_flagged"]],
                    ["kept by the authors", cf["kept_flagged"], cf["kept_not_flagged"]],
                ],
            ),
        ]
        if "clean" in a:
            c = a["clean"]
            dc = x["clean"]["diagnosis"]
            md += [
                "",
                f"On the authors' subset ({c['captures']} rows) the robust fit flags {c['flagged']} rows "
                f"({c['flagged_in_both']} of them also "
                f"flagged in the full set); the diagnosis finds {dc['effect']} at "
                f"{','.join(map(str, dc['joints'])) or '-'} (p = {_p(dc['p_value'])}).",
            ]
    md += ["", "Plots: " + ", ".join(f"`{f}`" for f in rep["files"] if f.endswith(".png")), ""]
    return "\n".join(md)


def _hom(h: dict) -> list:
    return [", ".join(f"{1e6 * v:.1f}" for v in h["mean"]), f"{h['chi2']:.1f}", h["dof"], _p(h["p"])]


def write_plots(rep: dict, plots: dict, out: Path) -> list[Path]:
    """residuals_vs_regressor.png (component plus residual of the finding's first joint),
    measured_vs_simulated.png
    (per-socket residual RMS against the simulated band), stiffness.png, loto_positions.png (held-out
    spread per position)."""
    from lasercal.collector.report.plots import pyplot
    from lasercal.collector.report.plots import save as save_png

    plt = pyplot()
    robots = list(plots)
    n = len(robots)
    written = []

    def save(fig, name):
        written.append(save_png(fig, out / name))

    fig, axs = plt.subplots(1, n, figsize=(4.2 * n, 3.6), squeeze=False)
    for ax, r in zip(axs[0], robots):
        g = plots[r]["regressor"]
        ax.scatter(
            g["x"],
            1e3 * g["y"],
            s=6,
            alpha=0.5,
            label="residual + fitted effect" if g["fitted"] else "geometric-fit residual",
        )
        bins = np.array_split(np.arange(len(g["x_sorted"])), max(len(g["x_sorted"]) // 25, 1))
        ys = 1e3 * g["y"][np.argsort(g["x"])]
        ax.plot(
            [g["x_sorted"][b].mean() for b in bins],
            [np.median(ys[b]) for b in bins],
            "k.-",
            label="binned median",
        )
        if g["fitted"]:
            ax.plot(g["x_sorted"], 1e3 * g["effect"], "r", label="fitted effect")
        lo, hi = np.percentile(1e3 * g["y"], [2, 98])
        ax.set_ylim(lo - 0.3 * (hi - lo), hi + 0.3 * (hi - lo))
        ax.set_xlabel(g["xlabel"])
        ax.set_ylabel(f"joint {g['joint']} motion (mrad)")
        ax.set_title(f"{r}: {g['name']}, joint {g['joint']}", fontsize=10)
    axs[0][0].legend(fontsize=7)
    save(fig, "residuals_vs_regressor.png")

    fig, axs = plt.subplots(n, 1, figsize=(10, 2.6 * n), squeeze=False)
    for ax, r in zip(axs[:, 0], robots):
        sp = plots[r]["simulation"]["sockets"]
        x = np.arange(len(sp["names"]))
        lo, mid, hi = sp["band"]
        ax.bar(x, hi - lo, bottom=lo, color="0.8", label="simulated 5-95 %")
        ax.plot(x, mid, "k_", ms=12, label="simulated median")
        ax.plot(x, sp["measured"], "ro", ms=4, label="measured")
        ax.set_xticks(x, sp["names"], rotation=60, ha="right", fontsize=6)
        ax.set_ylabel("residual RMS (mm)")
        s = rep["robots"][r]["simulation"]
        ax.set_title(f"{r}: per-socket RMS, heterogeneity p = {_p(s['sockets']['p'])}", fontsize=10)
    axs[0][0].legend(fontsize=7, ncol=3)
    save(fig, "measured_vs_simulated.png")

    joints = rep["compliance_joints"]
    fig, axs = plt.subplots(1, 2, figsize=(10, 3.8))
    w = 0.8 / n
    for i, r in enumerate(robots):
        cm = rep["robots"][r]["extension"]["compliance"]
        c, se, sj = (np.array(cm[k]) for k in ("c_rad_per_nm", "se_rad_per_nm", "se_jackknife_rad_per_nm"))
        x = np.arange(len(joints)) + (i - (n - 1) / 2) * w
        axs[0].errorbar(x, -1e6 * c, yerr=1e6 * sj, fmt="none", ecolor="0.6", capsize=4)
        axs[0].errorbar(x, -1e6 * c, yerr=1e6 * se, fmt="o", capsize=2, label=r)
        ok = c < -2 * se
        k, sk = stiffness(c, se)
        axs[1].errorbar(x[ok], 1e-3 * k[ok], yerr=1e-3 * sk[ok], fmt="o", capsize=2, label=r)
    for ax, lab in zip(axs, ("sag compliance -c (urad/Nm)", "stiffness k = -1/c (kNm/rad)")):
        ax.set_xticks(range(len(joints)), [f"joint {j}" for j in joints])
        ax.set_ylabel(lab)
    axs[0].axhline(0, color="k", lw=0.5)
    axs[0].set_title("formal SE (colour), jackknife SE (grey)", fontsize=9)
    axs[1].set_title("estimates resolved as a sag (c < -2 SE)", fontsize=9)
    axs[0].legend(fontsize=7)
    save(fig, "stiffness.png")

    fig, axs = plt.subplots(1, n, figsize=(4.2 * n, 3.6), squeeze=False)
    for ax, r in zip(axs[0], robots):
        folds = rep["robots"][r]["calibration"]["folds"]
        x = np.arange(len(folds))
        for k, (m, col, lab) in enumerate(
            (
                ("nominal", "0.6", "nominal"),
                ("geometric", "tab:red", "geometric"),
                ("nested", "tab:blue", "extended (nested)"),
            )
        ):
            ax.bar(
                x + (k - 1) * 0.27, [f["test"][m]["spread_rms_mm"] for f in folds], 0.27, color=col, label=lab
            )
        ax.set_yscale("log")
        ax.set_xticks(x, [f["held_out"] for f in folds], rotation=45, ha="right", fontsize=7)
        ax.set_ylabel("held-out spread RMS (mm)")
        ax.set_title(r, fontsize=10)
    axs[0][0].legend(fontsize=7)
    save(fig, "loto_positions.png")
    return written
