"""The MUKCa study's statistical checks: what the data say beyond the calibration figures.

The measured residuals against the same experiment simulated on the identified robot (size, spread
per socket and per position, lag-1 correlation, the share each candidate regressor explains:
:func:`simulation_check`), the robust loss's flagged rows against the positions the authors removed
by hand (:func:`outlier_audit`), and the robots' compliance estimates compared by a chi-square
homogeneity test with formal and jackknife variances (:func:`agreement`, :func:`homogeneity`,
:func:`jackknife_se`). Each takes the solver's results or the study's plain dicts and returns a
JSON-ready dict; the study (:mod:`collector.studies.mukca`) calls them.
"""

from __future__ import annotations

import numpy as np

from lasercal.solver.analysis.diagnose import Diagnosis, Tester
from lasercal.solver.formats.mukca import position_of
from lasercal.solver.formats.session import Session
from lasercal.solver.identify.spot import Identification
from lasercal.solver.kinematics.effects import Extension, candidates


# ------------------------------------------------------------------ statistics
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


def _regressors(T: Tester, R: np.ndarray) -> list[dict]:
    """Each candidate regressor's partial R^2, against the simulated experiment's, and its overlap.

    Parameters
    ----------
    T : Tester
        The candidates' tests on the geometric fit (their columns ``Q`` beyond the geometry).
    R : ndarray, shape (rows, replicates)
        The simulated residuals, refitted to first order.

    Returns
    -------
    list of dict
        A row per candidate with columns, the largest partial R^2 first (:func:`simulation_check`).
    """
    rss, rss_sim = float(T.res @ T.res), np.sum(R**2, axis=0)
    tests = T.tests()
    test_of = {id(t.extension): t for t in tests}
    Q_best = T.Q[[id(e) for e in T.exts].index(id(tests[0].extension))]
    rows = []
    for e, Q in zip(T.exts, T.Q):
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
    return sorted(rows, key=lambda r: -r["partial_r2"])


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
    out["regressors"] = _regressors(T, R)
    return out, plot


def _regressor_name(e: Extension) -> str:
    """What a joint candidate regresses on, in words."""
    j = e.joints[0]
    return {
        "joint_compliance": f"gravity torque tau{j}",
        "encoder_eccentricity": f"sin q{j}, cos q{j}",
        "drift": f"recording order (joint {j})",
    }[e.effect]


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


# ------------------------------------------------------------------ 4: the robots compared
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
