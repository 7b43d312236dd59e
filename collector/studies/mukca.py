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
   of residual each candidate regressor explains
   (:func:`collector.studies.mukca_checks.simulation_check`). Each comparison
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

The statistical checks (parts 2, 4 and 5) are in :mod:`collector.studies.mukca_checks`, the
Markdown report and the figures in :mod:`collector.report.mukca`; this module runs the study.
"""

from __future__ import annotations

import json
import os
import time
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np
from scipy.special import stdtrit  # quantile of Student's t (scipy.stats.t.ppf)

from lasercal.calibration import calibrate
from lasercal.collector.report.mukca import markdown, write_plots
from lasercal.collector.studies.mukca_checks import agreement, jackknife_se, outlier_audit, simulation_check
from lasercal.collector.studies.options import ROBOTS, StudyOptions
from lasercal.solver.analysis.diagnose import Diagnosis, diagnose, session_torques
from lasercal.solver.errors import FormatError
from lasercal.solver.formats.mukca import import_mukca, position_of, positions
from lasercal.solver.formats.session import Session, load_session
from lasercal.solver.identify.measurement import fit
from lasercal.solver.identify.point import tip_joint_jacobian, tips
from lasercal.solver.identify.spot import Identification
from lasercal.solver.kinematics.effects import Extension
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
def load_robot(data_dir, robot: str, workdir, prior: str | None = None) -> Session:
    """Import ``data_dir/robot`` as a point session in ``workdir/robot`` and load it (with ``prior``, as
    :func:`~lasercal.solver.formats.session.load_session`)."""
    folder = Path(data_dir) / robot
    if not folder.is_dir():
        raise FormatError(folder, f"no MUKCa robot folder {robot!r} in {data_dir}")
    return load_session(import_mukca(folder, Path(workdir) / robot), prior=prior)


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


# ------------------------------------------------------------------ 1 and 4: leave one tool position out
def loto(session: Session, common: tuple, fixed: Extension | None, opts: StudyOptions) -> dict:
    """Leave-one-tool-position-out cross-validation of every model.

    Per fold, fitted on the other positions (robust loss on): plain least squares ('plain', no
    outlier test: MUKCa's own optimiser; ``lasercal.calibrate(robust=False)``), the geometric model and
    the effect ``lasercal.calibrate(extend="auto")`` selects and accepts on them by its diagnosis's own
    inner leave-one-position-out ('nested': no selection leak; the geometric model when nothing is kept),
    that model fitted by plain least squares ('nested_plain': what the outlier test costs it), the
    whole-session finding refitted ('fixed'), and joint compliance on ``common`` ('compliance'). Train
    metrics use the training captures the geometric fit kept; test metrics use every held-out capture.

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
        # lasercal solve --extend auto on the training positions: its diagnosis selects and accepts
        nested = calibrate(
            replace(train, tau=None),
            extend="auto",
            alpha=opts.alpha,
            payload=opts.payload,
            allow_partial=True,
        )
        d = nested.diagnosis
        geo, sus = d.geometric.model, d.geometric.weights == 0  # extensions are fitted on its rows
        comp = fit(train, compliance_ext(common), suspects=sus)
        plain = calibrate(train, robust=False, folds=0, allow_partial=True).identification
        fits = {
            "nominal": (nominal, None),
            "plain": (plain.model, None),
            "geometric": (geo, None),
            "nested": (nested.identification.model, nested.identification.extension),
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
    """MUKCa's protocol: calibrate (geometry, :func:`lasercal.calibrate`) on one tool position, test on every
    other one.

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
        g = calibrate(train, folds=0, allow_partial=True).identification  # lasercal solve on one position
        per[P] = {
            part: [
                summarise(consistency(ball_centres(m, None, s), s))["mukca_mae_m"] for m in (nominal, g.model)
            ]
            for part, s in (("train", train), ("test", test))
        }
    return {part: np.mean([v[part] for v in per.values()], axis=0).tolist() for part in ("train", "test")} | {
        "per_position": per
    }


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
    if d.extension is None and not d.tests:  # no candidate the data can see: no regressor
        return {}
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
        dc = calibrate(  # the cleaned subset's finding: the F test decides alone (no folds)
            clean, extend="auto", folds=0, alpha=opts.alpha, payload=opts.payload, allow_partial=True
        ).diagnosis
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


def _removed(data_dir: Path, robot: str) -> list:
    """Tool positions the MUKCa authors' cleaned copy of ``robot`` leaves out."""
    return sorted(set(positions(data_dir / robot)) - set(positions(data_dir / f"{robot}_clean")))


def study_work(data_dir: Path, sessions_dir: Path, robots, opts: StudyOptions) -> tuple[dict, tuple]:
    """Each robot's :func:`study_robot` arguments, and the joints whose compliance is compared.

    Parameters
    ----------
    data_dir : folder holding ``panda_k`` (and ``panda_k_clean``) MUKCa folders
    sessions_dir : where the imported sessions are written
    robots : robot folder names
    opts : StudyOptions

    Returns
    -------
    work : {robot: (session, common, opts, clean session or None, removed positions)}
    common : 1-based joints loaded in every robot's session (the compliance compared across robots)
    """
    sessions = {r: load_robot(data_dir, r, sessions_dir, opts.prior) for r in robots}
    cleans = {
        r: load_robot(data_dir, f"{r}_clean", sessions_dir, opts.prior)
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
    work = {
        r: (s, common, opts, cleans.get(r), _removed(data_dir, r) if r in cleans else [])
        for r, s in sessions.items()
    }
    return work, common


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
    work, common = study_work(data_dir, out / "sessions", robots, opts)
    jobs = min(opts.jobs or os.cpu_count() or 1, len(work))
    if jobs > 1:  # the robots are independent: one process each, up to ``jobs`` at once
        with ProcessPoolExecutor(jobs) as pool:
            futures = {r: pool.submit(study_robot, *a) for r, a in work.items()}
            studies = {r: f.result() for r, f in futures.items()}
    else:
        studies = {r: study_robot(*a) for r, a in work.items()}
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
