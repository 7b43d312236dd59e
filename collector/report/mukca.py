"""The MUKCa study's report: ``report.md`` (tables) and its PNG figures, from the study's plain dicts.

:func:`markdown` renders the report dict that ``report.json`` holds
(:func:`collector.studies.mukca.run_study`); :func:`write_plots` draws the residuals against the
finding's regressor, the measured against the simulated per-socket residuals, the robots' compliances
and stiffnesses, and the held-out spread per tool position, with the one plotting set-up
(:mod:`collector.report.plots`). Rendering only: no fit and no test here. Sign of a compliance (as
in the study): in q_true = q + c tau a physical sag has c < 0, and the stiffness is k = -1/c (Nm/rad).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np


def _table(header: list, rows: list) -> str:
    """A Markdown table."""
    lines = ["| " + " | ".join(header) + " |", "|" + "|".join("---" for _ in header) + "|"]
    return "\n".join(lines + ["| " + " | ".join(str(c) for c in r) + " |" for r in rows])


def _p(p) -> str:
    return "n/a" if p is None else f"{p:.2g}"


def stiffness(c: np.ndarray, se: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Stiffness k = -1/c (Nm/rad) of a sag compliance c (rad/Nm), and its first-order SE se/c^2."""
    c, se = np.asarray(c, float), np.asarray(se, float)
    return -1.0 / c, se / c**2


def _reading(c: float, se: float) -> str:
    """What a compliance estimate says physically (sag: c < 0, see the module docstring)."""
    if c < -2 * se:
        return "sag (a stiffness)"
    if c > 2 * se:
        return "anti-sag: not a stiffness"
    return "not resolved"


def _summary(rep: dict) -> list[str]:
    """The title, the conclusion per robot, the data and the metrics.

    Parameters
    ----------
    rep : dict
        The study's report dict (``report.json``).

    Returns
    -------
    list of str
        The section's Markdown lines, in order.
    """
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
    return md


def _calibration(rep: dict) -> list[str]:
    """Section 1: nominal against geometric calibration, leave one tool position out.

    Parameters and Returns as :func:`_summary`'s: the report dict in, the section's Markdown lines out.
    """
    R = rep["robots"]
    md: list[str] = []
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
    return md


def _mukca_metric(rep: dict) -> list[str]:
    """MUKCa's metric beside their published figures.

    Parameters and Returns as :func:`_summary`'s: the report dict in, the section's Markdown lines out.
    """
    R = rep["robots"]
    md: list[str] = []
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
    return md


def _held_out_positions(rep: dict) -> list[str]:
    """The calibration per held-out position (test).

    Parameters and Returns as :func:`_summary`'s: the report dict in, the section's Markdown lines out.
    """
    R = rep["robots"]
    md: list[str] = []
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
    return md


def _simulation(rep: dict) -> list[str]:
    """Section 2: what the simulation gets wrong.

    Parameters and Returns as :func:`_summary`'s: the report dict in, the section's Markdown lines out.
    """
    R = rep["robots"]
    o = rep["options"]
    md: list[str] = []
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
    return md


def _candidate_regressors(rep: dict) -> list[str]:
    """The candidate regressors, the top six per robot.

    Parameters and Returns as :func:`_summary`'s: the report dict in, the section's Markdown lines out.
    """
    R = rep["robots"]
    md: list[str] = []
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
    return md


def _causes(rep: dict) -> list[str]:
    """Section 3: the causes, the diagnosis of the whole session.

    Parameters and Returns as :func:`_summary`'s: the report dict in, the section's Markdown lines out.
    """
    R = rep["robots"]
    md: list[str] = []
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
    return md


def _extended_model(rep: dict) -> list[str]:
    """Section 4: the extended model's held-out gain.

    Parameters and Returns as :func:`_summary`'s: the report dict in, the section's Markdown lines out.
    """
    R = rep["robots"]
    md: list[str] = []
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
    return md


def _compliance(rep: dict) -> list[str]:
    """The joint compliance at the gravity-loaded joints, and the robots' agreement.

    Parameters and Returns as :func:`_summary`'s: the report dict in, the section's Markdown lines out.
    """
    R = rep["robots"]
    md: list[str] = []
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
    return md


def _outliers(rep: dict) -> list[str]:
    """Section 5: the outliers and the positions the authors removed.

    Parameters and Returns as :func:`_summary`'s: the report dict in, the section's Markdown lines out.
    """
    R = rep["robots"]
    md: list[str] = []
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
    return md


def _authors_cleaning(rep: dict) -> list[str]:
    """Per robot the authors cleaned: their cleaning against our robust loss.

    Parameters and Returns as :func:`_summary`'s: the report dict in, the section's Markdown lines out.
    """
    R = rep["robots"]
    md: list[str] = []
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
    return md


def markdown(rep: dict) -> str:
    """The study as a Markdown report (tables; the plots are separate PNG files)."""
    sections = (
        _summary,
        _calibration,
        _mukca_metric,
        _held_out_positions,
        _simulation,
        _candidate_regressors,
        _causes,
        _extended_model,
        _compliance,
        _outliers,
        _authors_cleaning,
    )
    md = [line for section in sections for line in section(rep)]
    md += ["", "Plots: " + ", ".join(f"`{f}`" for f in rep["files"] if f.endswith(".png")), ""]
    return "\n".join(md)


def _hom(h: dict) -> list:
    return [", ".join(f"{1e6 * v:.1f}" for v in h["mean"]), f"{h['chi2']:.1f}", h["dof"], _p(h["p"])]


def _plot_residuals_vs_regressor(plt, rep: dict, plots: dict, robots: list):
    """The residuals against the finding's regressor, a panel per robot.

    Parameters
    ----------
    plt : module
        matplotlib's pyplot, set up (:func:`collector.report.plots.pyplot`).
    rep : dict
        The study's report dict (``report.json``).
    plots : dict
        The plotted data per robot (``plots[robot]``).
    robots : list of str
        The robots, in the order drawn.

    Returns
    -------
    matplotlib.figure.Figure
        The figure, not yet saved.
    """
    n = len(robots)
    fig, axs = plt.subplots(1, n, figsize=(4.2 * n, 3.6), squeeze=False)
    for ax, r in zip(axs[0], robots):
        g = plots[r]["regressor"]
        if not g:  # no candidate the data could see
            ax.set_title(f"{r}: no candidate regressor", fontsize=9)
            continue
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
    return fig


def _plot_measured_vs_simulated(plt, rep: dict, plots: dict, robots: list):
    """The measured per-socket residual RMS against the simulated band, a row per robot.

    Parameters and Returns as :func:`_plot_residuals_vs_regressor`'s.
    """
    n = len(robots)
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
    return fig


def _plot_stiffness(plt, rep: dict, plots: dict, robots: list):
    """The robots' sag compliances and the stiffnesses resolved as a sag.

    Parameters and Returns as :func:`_plot_residuals_vs_regressor`'s.
    """
    n = len(robots)
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
    return fig


def _plot_loto_positions(plt, rep: dict, plots: dict, robots: list):
    """The held-out spread per tool position, a panel per robot.

    Parameters and Returns as :func:`_plot_residuals_vs_regressor`'s.
    """
    n = len(robots)
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
    return fig


def write_plots(rep: dict, plots: dict, out: Path) -> list[Path]:
    """residuals_vs_regressor.png (component plus residual of the finding's first joint),
    measured_vs_simulated.png
    (per-socket residual RMS against the simulated band), stiffness.png, loto_positions.png (held-out
    spread per position)."""
    from lasercal.collector.report.plots import pyplot
    from lasercal.collector.report.plots import save as save_png

    plt = pyplot()
    figures = (
        ("residuals_vs_regressor.png", _plot_residuals_vs_regressor),
        ("measured_vs_simulated.png", _plot_measured_vs_simulated),
        ("stiffness.png", _plot_stiffness),
        ("loto_positions.png", _plot_loto_positions),
    )
    return [save_png(draw(plt, rep, plots, list(plots)), out / name) for name, draw in figures]
