"""Plots that make a case to a person (matplotlib, headless). Reporting only: no identification here."""

from __future__ import annotations

from pathlib import Path

import numpy as np

DIAGNOSIS_PLOTS = ("residuals_vs_regressor.png", "measured_vs_simulated.png", "before_after.png")
"""The files :func:`diagnosis_plots` may write into its folder."""


def pyplot():
    """matplotlib's pyplot on the headless Agg backend, imported when a plot is made (the one set-up)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def save(fig, path: Path, dpi: int = 110) -> Path:
    """Lay out, write ``fig`` as a PNG at ``path`` and close it."""
    fig.tight_layout()
    fig.savefig(path, dpi=dpi)
    pyplot().close(fig)
    return path


def diagnosis_plots(d, out) -> list[Path]:
    """Residuals vs the winning regressor, measured vs simulated statistics, before/after (PNG files).

    Parameters
    ----------
    d : Diagnosis
    out : folder to write into

    Returns
    -------
    list of written paths
    """
    plt = pyplot()
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    res = d.geometric.residuals
    written = []

    if d.extension is not None or d.tests:  # with no candidate the data can see, no regressor to plot
        written.append(_residuals_vs_regressor(plt, d, res, out))

    b = d.bootstrap
    if b:
        fig, axs = plt.subplots(1, 2, figsize=(9, 3.6))
        axs[0].hist(b["rms_mm"], bins=15, color="0.7", label="simulated")
        axs[0].axvline(b["observed_rms_mm"], color="r", label="measured")
        axs[0].set_xlabel("geometric-fit residual RMS (mm)")
        axs[0].legend()
        axs[1].hist(b["best_stat"], bins=15, color="0.7", label="simulated")
        axs[1].axvline(b["observed_best_stat"], color="r", label="measured")
        axs[1].set_xlabel("strongest candidate, -log10 p")
        axs[1].set_title(f"bootstrap p = {b['p_value']:.3g}")
        axs[1].legend()
        written.append(save(fig, out / DIAGNOSIS_PLOTS[1]))

    fig, ax = plt.subplots(figsize=(5, 5))
    # the extension's (filled, below) and the geometry's (open rings, above): neither hides the other
    for key, style in (
        ("extended", {"c": "tab:blue"}),
        ("geometric", {"facecolors": "none", "edgecolors": "tab:red"}),
    ):
        r = d.residuals_holdout[key]
        ax.scatter(r[:, 0], r[:, 1], s=14, lw=0.8, label=f"{key}: RMS {d.holdout_rms[key]:.3f} mm", **style)
    ax.set_aspect("equal")
    ax.set_xlabel("held-out error x (mm)")
    ax.set_ylabel("held-out error y (mm)")
    ax.legend()
    ax.set_title("held-out errors, before/after the extension", fontsize=10)
    written.append(save(fig, out / DIAGNOSIS_PLOTS[2]))
    return written


def _residuals_vs_regressor(plt, d, res: np.ndarray, out: Path) -> Path:
    """The geometric fit's residuals against the finding's (or best candidate's) regressor."""
    s, geo = d.session, d.geometric
    ext = (d.extension or d.tests[0].extension).parts[0]  # a combination: its first effect
    fitted = d.extension.parts[0] if d.extension is not None else None
    fig, ax = plt.subplots(figsize=(6, 4))
    if ext.effect == "reference_point_offset":
        names = list(dict.fromkeys(s.point))
        for nm in names:
            sel = s.point == nm
            ax.scatter(res[sel, 0], res[sel, 1], s=10, label=nm)
        ax.set_xlabel("residual x (mm)")
        ax.set_ylabel("residual y (mm)")
        ax.set_aspect("equal")
        ax.legend()
        ax.set_title("geometric-fit residuals per reference point")
    else:
        from lasercal.solver.analysis.diagnose import joint_jacobian

        idx, G = ext.regressors(s.q, s.t, s.tau)
        col = joint_jacobian(s, geo.model, s.q)[:, :, idx[0]]
        along = -np.sum(res * col, axis=1) / np.maximum(
            np.linalg.norm(col, axis=1) ** 2, 1e-12
        )  # rad of joint motion that would remove it
        ax.scatter(G[:, 0], 1e3 * along, s=8, label="captures")
        if fitted is not None:
            gx = np.linspace(G[:, 0].min(), G[:, 0].max(), 50)
            ax.plot(
                gx,
                1e3 * fitted.params[0] * gx,
                "r",
                label=f"fitted {fitted.names[0]} (the geometric fit absorbs part of it)",
            )
            ax.legend()
        lo, hi = np.percentile(1e3 * along, [3, 97])
        pad = 0.3 * (hi - lo)
        ax.set_ylim(lo - pad, hi + pad)  # a few captures with a tiny lever would hide the trend
        tag = ext.tags[0]  # the joint as every report names it ('2', or 'torso_2' on a tree)
        xlab = {
            "joint_compliance": f"tau{tag} (Nm)" if tag.isdigit() else f"tau[{tag}] (Nm)",
            "lateral_compliance": f"tau[{tag}] (Nm)",
            "encoder_eccentricity": f"sin q{tag}" if tag.isdigit() else f"sin q[{tag}]",
            "drift": "t (s)",
        }[ext.effect]
        ax.set_xlabel(xlab)
        ax.set_ylabel(f"residual as joint {tag} motion (mrad)")
        ax.set_title(f"geometric-fit residuals vs the {ext.effect} regressor")
    return save(fig, out / DIAGNOSIS_PLOTS[0])
