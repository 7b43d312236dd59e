"""``lasercal report``: one HTML page with PNG plots that a person reads.

The page (``index.html``) and its plots are files in one folder, with relative links and
no scripts, styles or fonts from elsewhere: copy or zip the folder and it still opens.

Contents, in the thesis's terms (Section 4.3), after two sentences at the top -- simulated or
measured data, and the verdict (e.g. "calibrated: 9.2 → 0.54 mm at P4, 60 of 60 configurations";
"partial" when the data cannot identify every combination, or fewer spots were measured than planned):

* the laser spots at the validation point, before and after calibration (Figure 4.5),
  and their mean and max absolute error (Figure 4.6), from ``lasercal validate`` folders;
* the corrections per joint in physical units: each axis's change of direction (deg) and position (mm);
* the parameter table, nominal vs identified with standard errors (Table 4.3): the joint
  screws (omega, v), the laser direction and the aperture, the standard errors propagated
  from the fit's covariance through the minimal-POE parametrisation;
* per reference point: the spot statistics before and after, and residual plots;
* the identifiability summary (rank, condition number, what the data cannot see);
* the diagnosis (``solver.diagnose``): the finding, its evidence and plots.
"""

from __future__ import annotations

import html
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from lasercal.collector.report.plots import diagnosis_plots, pyplot, save
from lasercal.collector.report.text import fit_by_kind_text, format_diagnosis, noise_by_kind_line
from lasercal.solver.analysis.diagnose import Diagnosis
from lasercal.solver.analysis.stats import SpotStats, carriers, solve_report, spot_stats
from lasercal.solver.errors import FormatError
from lasercal.solver.formats.checks import metres_hint
from lasercal.solver.formats.robots import load_yaml
from lasercal.solver.formats.session import Session
from lasercal.solver.formats.table import csv_rows
from lasercal.solver.identify.measurement import unidentifiable
from lasercal.solver.identify.spot import Identification, base_targets, spot_residuals
from lasercal.solver.kinematics.laser import LaserParams

_STAT_KEYS = ("scatter_mean", "scatter_std", "error_mean", "error_max")


@dataclass(frozen=True, eq=False)
class Validation:
    """A validation run read back from its folder.

    Attributes
    ----------
    folder : Path
    label : str, the folder's name (how the report names the run)
    model : str, how validation.yaml names the model under test
    point : str, the validation point
    xyz : (3,) array, its position, mm
    spots : (k, 2) array, the measured spots, mm
    photos : int, rows in validation.csv (measured or not)
    planned : int, configurations the run planned (validation.yaml ``n``)
    simulated : bool, a simulated run (the fake backend or camera, or ``simulated`` in validation.yaml)
    """

    folder: Path
    label: str
    model: str
    point: str
    xyz: np.ndarray
    spots: np.ndarray
    photos: int
    planned: int
    simulated: bool

    @property
    def completeness(self) -> str:
        """'20 of 60', and 'partial: ' before it when fewer spots were measured than planned."""
        done = f"{len(self.spots)} of {self.planned}"
        return done if len(self.spots) >= self.planned else f"partial: {done}"

    @property
    def stats(self) -> SpotStats:
        """Scatter radius and absolute error of the spots (Figures 4.5-4.6)."""
        return spot_stats(self.spots, self.xyz)


def load_validation(folder) -> Validation:
    """Read a folder written by ``lasercal validate`` (validation.yaml and validation.csv with x_mm, y_mm).

    Raises
    ------
    FormatError
        A missing or malformed file, or no measured spot (naming file, line and column).
    """
    folder = Path(folder)
    ypath, cpath = folder / "validation.yaml", folder / "validation.csv"
    meta = load_yaml(ypath)
    try:
        point, xyz = str(meta["point"]["name"]), np.array(meta["point"]["xyz"], dtype=float).reshape(3)
        if not np.all(np.abs(xyz) <= 1e5):  # NaN (a blank) fails too
            raise ValueError
    except (TypeError, KeyError, ValueError):
        raise FormatError(
            ypath, "not a lasercal validation (expected point: {name, xyz: [x, y, z] in mm})", field="point"
        ) from None
    if metres_hint(xyz):
        raise FormatError(ypath, f"point xyz {xyz.tolist()}: {metres_hint(xyz)}", field="point.xyz")
    rows = csv_rows(cpath, f"`lasercal validate --resume {cpath.parent}` cuts the torn row off")
    if not rows or not {"x_mm", "y_mm"} <= set(rows[0][1]):
        raise FormatError(cpath, "expected a header with x_mm and y_mm", line=rows[0][0] if rows else None)
    header = rows[0][1]
    n = meta.get("n")
    if not isinstance(n, int) or n < 1:
        raise FormatError(
            ypath, f"n = {n!r} (expected the number of configurations, a whole number >= 1)", field="n"
        )
    ix, iy = header.index("x_mm"), header.index("y_mm")
    qcols = [j for j, h in enumerate(header) if h.startswith("q") and h[1:].isdigit()]
    for ln, r in rows[1:]:
        for j in qcols:
            try:
                v = float(r[j])
            except (ValueError, IndexError):
                continue
            if not abs(v) <= 2 * np.pi:  # NaN too: a logged angle is a number
                what = "looks like degrees" if np.isfinite(v) else "is not a finite number"
                raise FormatError(cpath, f"{r[j]} {what} (expected rad)", line=ln, field=header[j])
    spots = []
    for ln, r in rows[1:]:
        if len(r) != len(header):
            raise FormatError(cpath, f"expected {len(header)} values, found {len(r)}", line=ln)
        if not r[ix].strip() and not r[iy].strip():
            continue  # a photo not measured
        for j in (ix, iy):
            try:
                v = float(r[j])
            except ValueError:
                v = np.nan
            if not np.isfinite(v):
                raise FormatError(cpath, f"not a finite number: {r[j]!r}", line=ln, field=header[j])
        spots.append((float(r[ix]), float(r[iy])))
    if not spots:
        raise FormatError(
            cpath,
            "no measured spot (x_mm, y_mm empty): validate measures its photos through a layout with "
            "markers (lasercal sheet prints one) or the fake camera; validate again with one",
        )
    hint = metres_hint(np.c_[np.array(spots), np.zeros(len(spots))])
    if hint:
        raise FormatError(cpath, f"measured spots: {hint}", field="x_mm")
    simulated = bool(meta.get("simulated")) or "fake" in (meta.get("backend"), meta.get("camera"))
    return Validation(
        folder,
        folder.resolve().name,
        str(meta.get("model", "?")),
        point,
        xyz,
        np.array(spots),
        len(rows) - 1,
        n,
        simulated,
    )


@dataclass(frozen=True, eq=False)
class ParameterRow:
    """One row of the parameter table: a 3-vector of the model, nominal and identified.

    Attributes
    ----------
    name : str, e.g. 'joint2 omega', 'laser v', 'M'
    unit : str
    nominal, identified : (3,) arrays
    std_error : (3,) array or None (the thesis method gives none)
    """

    name: str
    unit: str
    nominal: np.ndarray
    identified: np.ndarray
    std_error: np.ndarray | None


def parameter_table(ident: Identification) -> list[ParameterRow]:
    """Nominal vs identified screws, laser direction and aperture, with standard errors (Table 4.3).

    The standard errors of the vectors come from the fit's covariance of the minimal-POE
    parameters (``ident.extra['cov']``) through the exact derivative of the parametrisation
    (:func:`solver.minimal.screw_from_eta`); the aperture's height along the beam is fixed by the
    measured p_Mz, so its covariance is already the gauge-fixed one.
    """
    nom, mod = ident.nominal, ident.model
    cov = ident.extra.get("cov")
    se = None
    if cov is not None:
        P = LaserParams(nom)
        p = P.size
        # the laser robot's block by name: a sheet session holds a few of them (the gauge), with no spread
        idx = {nm: i for i, nm in enumerate(ident.param_names)}
        at = np.array([idx.get(nm, -1) for nm in P.names])
        x, C = P.x0(), np.zeros((p, p))
        x[at >= 0] = ident.estimate[at[at >= 0]]
        C[np.ix_(at >= 0, at >= 0)] = cov[np.ix_(at[at >= 0], at[at >= 0])]
        _, dS, _, dvp, _ = P.geometry(x)
        D = np.zeros((6 * nom.n + 6, p))
        for i, d in enumerate(dS):
            D[6 * i : 6 * i + 6, 4 * i : 4 * i + 4] = d
        D[6 * nom.n : 6 * nom.n + 3, P.slice_laser] = dvp
        D[6 * nom.n + 3 :, P.slice_M] = np.eye(3)
        se = np.sqrt(np.clip(np.diag(D @ C @ D.T), 0, None))
    rows = []
    for i, nm in enumerate(nom.joint_names):
        for k, (part, unit) in enumerate((("omega", ""), ("v", "mm"))):
            sl = slice(6 * i + 3 * k, 6 * i + 3 * k + 3)
            rows.append(
                ParameterRow(
                    f"{nm} {part}",
                    unit,
                    nom.screws[i, 3 * k : 3 * k + 3],
                    mod.screws[i, 3 * k : 3 * k + 3],
                    None if se is None else se[sl],
                )
            )
    n6 = 6 * nom.n
    rows.append(
        ParameterRow("laser v", "", nom.laser_dir, mod.laser_dir, None if se is None else se[n6 : n6 + 3])
    )
    rows.append(
        ParameterRow("M (aperture)", "mm", nom.aperture, mod.aperture, None if se is None else se[n6 + 3 :])
    )
    return rows


def corrections(ident: Identification) -> list[list]:
    """Per-joint corrections in physical units: how far calibration moved each axis, the beam, the aperture.

    Joint i: the angle between the nominal and identified axis directions, arccos(w_n . w_i) (deg), and
    the distance of the identified axis from the nominal axis's point nearest the base origin,
    |(p_n - p_i) x w_i| with p = w x v (mm). Laser: the angle between the beam directions (deg) and the
    aperture's shift across the identified beam (mm; along the beam it is the gauge, fixed by p_Mz).

    Returns
    -------
    list of [name, direction change (deg), position change (mm)]
    """
    nom, mod = ident.nominal, ident.model

    def angle(a, b):
        return float(np.degrees(np.arccos(np.clip(np.sum(a * b, axis=-1), -1.0, 1.0))))

    rows = []
    for nm, Sn, Si, pr in zip(nom.joint_names, nom.screws, mod.screws, nom.prismatic):
        if pr:  # a prismatic joint: its direction only (it has no line)
            rows.append([nm, angle(Sn[3:], Si[3:]), 0.0])
            continue
        pn, pi = np.cross(Sn[:3], Sn[3:]), np.cross(Si[:3], Si[3:])
        rows.append([nm, angle(Sn[:3], Si[:3]), float(np.linalg.norm(np.cross(pn - pi, Si[:3])))])
    dM = mod.aperture - nom.aperture
    across = dM - (dM @ mod.laser_dir) * mod.laser_dir
    rows.append(
        ["laser (beam, aperture)", angle(nom.laser_dir, mod.laser_dir), float(np.linalg.norm(across))]
    )
    return rows


def data_kind(session: Session, validations=()) -> str:
    """One sentence: simulated or measured data, from session.yaml's ``simulated`` and the validation runs."""
    sim = session.meta.get("simulated")
    runs = [v.label for v in validations if v.simulated]
    if sim:
        what = ", ".join(f"{k} {v}" for k, v in sim.items() if k in ("truth", "aim_noise_mm", "seed"))
        return f"Simulated data: the session was simulated ({what}), not measured on a robot."
    if runs:
        return f"Measured calibration session; simulated validation run(s): {', '.join(runs)}."
    backend = (session.meta.get("collector") or {}).get("backend")
    return f"Measured data: captured on a robot{f' ({backend} backend)' if backend else ''}."


def verdict(
    session: Session, ident: Identification, validations=(), missing=(), from_prior=(), warning=None
) -> str:
    """The report in one sentence, e.g. 'calibrated: 9.2 → 0.54 mm at P4, 60 of 60 configurations'.

    At each validation point (in the order the runs are given), with two or more runs there: the first
    run's mean error (e.g. the nominal model's) to the last one's, and how many of the last run's planned
    configurations were measured; with one: its error; with none: the RMS spot error on the calibration
    captures, nominal → identified (outliers left out). A rank-deficient fit is 'partial', a fit that did
    not converge says so, and the combinations the prior rather than the data determined (``from_prior``,
    names) are named.
    """
    state = "NOT calibrated" if warning else "partial calibration" if missing else "calibrated"
    if not ident.converged:
        state += " (NOT converged)"
    if validations:
        text = f"{state}: " + "; ".join(_point_verdict(runs) for runs in by_point(validations).values())
    else:  # a camera session's figure is its measured captures' (they carry the fit)
        used = (ident.weights > 0) & carriers(session)
        r = spot_residuals(ident.nominal, session.q, base_targets(session, ident.nominal))[used]
        before = float(np.sqrt(np.mean(np.sum(r**2, axis=1))))
        after = float(np.sqrt(np.mean(np.sum(ident.residuals[used] ** 2, axis=1))))
        which = "measured " if session.measured.any() else ""
        text = (
            f"{state}: {mm(before)} → {mm(after)} mm RMS on the calibration captures, "
            f"{int(used.sum())} of {session.m} {which}captures (not validated at a point the fit did not see)"
        )
    if missing:
        text += "; not identified: " + ", ".join(d.combination for d in missing)
    if from_prior:
        text += "; from the prior, not calibrated by the data: " + ", ".join(from_prior)
    if warning:
        text += f"; {warning}"
    return text


def by_point(validations) -> dict:
    """The validation runs grouped by point: point name -> runs there, both in the order given."""
    out: dict = {}
    for v in validations:
        out.setdefault(v.point, []).append(v)
    return out


def _point_verdict(runs) -> str:
    """'9.2 → 0.54 mm at P4, 60 of 60 configurations' (first run to last), or one run's error."""
    b = runs[-1]
    if len(runs) == 1:
        return f"{mm(b.stats.error_mean)} mm at {b.point} ({b.label}), {b.completeness} configurations"
    before = runs[0].stats.error_mean
    return f"{mm(before)} → {mm(b.stats.error_mean)} mm at {b.point}, {b.completeness} configurations"


def mm(x: float) -> str:
    """A length for the headline: two decimals from 1 mm up, three below ('9.16', '0.075')."""
    return f"{x:.2f}" if abs(x) >= 1 else f"{x:.3f}"


def check_not_calibration_points(session: Session, ident: Identification, validations) -> None:
    """A model is not validated on the data it was fitted to: no run's point may be a calibration point of
    the session (a sheet session's points placed where the calibration found the sheet, eq. S1).

    Raises
    ------
    FormatError
        Naming the run's validation.yaml and the calibration point.
    """
    names = sorted(set(session.point))
    xyz = np.array([session.points[nm] for nm in names], dtype=float)
    if session.frame == "sheet" and ident.model.sheet is not None:
        xyz = ident.model.sheet.to_base(xyz, session.plane_z)
    for v in validations:
        for nm, p in zip(names, xyz):
            if np.linalg.norm(p - v.xyz) < 1.0:
                raise FormatError(
                    v.folder / "validation.yaml",
                    f"validated at {v.point}, which is calibration point {nm} of the session (expected a "
                    "point the model was not fitted to)",
                    field="point",
                )


# ------------------------------------------------------------------ plots


def _save(fig, path: Path) -> Path:
    return save(fig, path, dpi=100)


def scatter_plot(validations, path: Path) -> Path:
    """Figure 4.5: the spots at the validation point, one panel per run (mm from the point)."""
    plt = pyplot()
    k = len(validations)
    fig, axs = plt.subplots(1, k, figsize=(3.6 * k, 3.8), squeeze=False)
    for ax, v in zip(axs[0], validations):
        s = v.stats
        d = v.spots - v.xyz[:2]
        lim = 1.15 * max(np.abs(d).max(), 1.0)
        ax.scatter(d[:, 0], d[:, 1], s=10, c="tab:red", alpha=0.8, label="spots")
        ax.plot(*(d.mean(axis=0)), "k+", ms=10, label="their mean")
        ax.plot(0, 0, "bx", ms=9, mew=2, label=v.point)
        ax.add_patch(plt.Circle((0, 0), s.error_mean, fill=False, ls="--", color="0.4"))
        ax.set_xlim(-lim, lim)
        ax.set_ylim(-lim, lim)
        ax.set_aspect("equal")
        ax.set_title(
            f"{v.label}: error {s.error_mean:.2f} mm mean\nscatter {s.scatter_mean:.2f} mm mean", fontsize=9
        )
        ax.set_xlabel(f"x - {v.point}x (mm)")
        ax.set_ylabel(f"y - {v.point}y (mm)")
    axs[0][0].legend(fontsize=7, loc="lower left")
    return _save(fig, path)


def error_bars(validations, reference: dict, path: Path) -> Path:
    """Figure 4.6: mean and max absolute error at the validation point per run (and published references)."""
    plt = pyplot()
    labels = [v.label for v in validations] + list(reference)
    stats = [v.stats.as_dict() for v in validations] + list(reference.values())
    x = np.arange(len(labels))
    fig, ax = plt.subplots(figsize=(max(5.0, 1.3 * len(labels)), 3.8))
    hatch = [""] * len(validations) + ["//"] * len(reference)
    for off, key, colour in ((-0.2, "error_mean", "tab:blue"), (0.2, "error_max", "tab:orange")):
        vals = [s[key] for s in stats]
        bars = ax.bar(x + off, vals, 0.4, color=colour, label=key.replace("_", " "))
        for b, h, val in zip(bars, hatch, vals):
            b.set_hatch(h)
            ax.annotate(
                f"{val:.2f}", (b.get_x() + b.get_width() / 2, val), ha="center", va="bottom", fontsize=7
            )
    ax.set_xticks(x, labels, rotation=20, ha="right", fontsize=8)
    ax.set_ylabel("absolute error (mm)")
    ax.set_yscale("log")
    ax.legend(fontsize=8)
    ax.set_title(
        f"error at {validations[0].point}" + (" (hatched: published)" if reference else ""), fontsize=9
    )
    return _save(fig, path)


def residual_plots(session: Session, ident: Identification, path: Path) -> Path:
    """Per reference point: the nominal model's spot errors on the captures (top) and the fit's residuals
    (bottom)."""
    plt = pyplot()
    names = list(dict.fromkeys(session.point))
    before = spot_residuals(ident.nominal, session.q, base_targets(session, ident.nominal))
    fig, axs = plt.subplots(2, len(names), figsize=(3.4 * len(names), 6.6), squeeze=False)
    used = ident.weights > 0
    for j, nm in enumerate(names):
        sel = session.point == nm
        for row, (r, what) in enumerate(
            ((before, "nominal model"), (ident.residuals, f"identified ({ident.method})"))
        ):
            ax = axs[row][j]
            ok = sel & (used if row else np.ones_like(used))
            if session.measured.any():  # a camera session: measured and aimed captures apart
                for kind, marker, colour in ((True, "o", "tab:blue"), (False, "^", "tab:orange")):
                    k = ok & (session.measured == kind)
                    ax.scatter(
                        r[k, 0],
                        r[k, 1],
                        s=9 if kind else 16,
                        marker=marker,
                        c="tab:red" if row == 0 else colour,
                        label=("measured by the camera" if kind else "aimed by the operator")
                        if row
                        else None,
                    )
                if row:
                    ax.legend(fontsize=7)
            else:
                ax.scatter(r[ok, 0], r[ok, 1], s=9, c="tab:red" if row == 0 else "tab:blue")
            if row and np.any(sel & ~used):
                ax.scatter(
                    r[sel & ~used, 0], r[sel & ~used, 1], marker="x", c="k", s=25, label="outliers (left out)"
                )
                ax.legend(fontsize=7)
            rms = float(np.sqrt(np.mean(np.sum(r[ok] ** 2, axis=1))))
            ax.axhline(0, color="0.8", lw=0.8)
            ax.axvline(0, color="0.8", lw=0.8)
            ax.set_aspect("equal", adjustable="datalim")
            ax.set_title(f"{nm}, {what}: RMS {rms:.2f} mm", fontsize=9)
            ax.set_xlabel("spot - point, x (mm)")
            ax.set_ylabel("y (mm)")
    return _save(fig, path)


# ------------------------------------------------------------------ HTML

_CSS = """body{font-family:sans-serif;max-width:1150px;margin:1.5em auto;padding:0 1em;color:#222}
h1{font-size:1.5em}h2{font-size:1.2em;border-bottom:1px solid #ccc;padding-bottom:.2em;margin-top:1.6em}
table{border-collapse:collapse;margin:.5em 0;font-size:.85em}
th,td{border:1px solid #ccc;padding:.2em .5em;text-align:right}
th:first-child,td:first-child{text-align:left}tr.ref td{color:#777;font-style:italic}
img{max-width:100%;display:block;margin:.6em 0}
pre{background:#f6f6f6;padding:.6em;font-size:.8em;overflow-x:auto}
.note{color:#555;font-size:.9em}"""


def _table(tid: str, header, rows, classes=None) -> str:
    esc = html.escape
    out = [f'<table id="{tid}"><tr>' + "".join(f"<th>{esc(str(h))}</th>" for h in header) + "</tr>"]
    for i, r in enumerate(rows):
        cls = f' class="{classes[i]}"' if classes and classes[i] else ""
        out.append(f"<tr{cls}>" + "".join(f"<td>{esc(str(c))}</td>" for c in r) + "</tr>")
    return "\n".join(out) + "</table>"


def _vec(a, fmt: str) -> str:
    return "—" if a is None else ", ".join(format(float(x), fmt) for x in a)


def _img(name: str, alt: str) -> str:
    return f'<img src="{name}" alt="{html.escape(alt)}">'


def validation_section(runs, reference: dict, out: Path, suffix: str = "") -> list[str]:
    """The HTML of the runs at one validation point (in the order given, e.g. nominal first): their
    statistics (table ``validation-stats`` + ``suffix``) beside the published ``reference``, and Figures 4.5
    and 4.6 written into ``out`` (``validation_spots`` + ``suffix`` + ``.png``, ``validation_errors``...).
    """
    esc = html.escape
    v0 = runs[0]
    spots, errors = f"validation_spots{suffix}.png", f"validation_errors{suffix}.png"
    scatter_plot(runs, out / spots)
    error_bars(runs, reference, out / errors)
    rows = [
        [v.label, v.model, v.completeness] + [f"{v.stats.as_dict()[k]:.3f}" for k in _STAT_KEYS] for v in runs
    ]
    rows += [[lab, "published", ""] + [f"{r[k]:.3f}" for k in _STAT_KEYS] for lab, r in reference.items()]
    classes = [""] * len(runs) + ["ref"] * len(reference)
    return [
        f"<h2>Validation at {esc(v0.point)} ({', '.join(f'{c:.1f}' for c in v0.xyz)}) mm</h2>",
        (
            '<p class="note">Each model computes configurations that put its beam on the point; the arm '
            "goes there and a camera photographs the spot. Scatter radius: distance of each spot from the "
            "spots' mean; error: distance from the point (thesis Figures 4.5 and 4.6).</p>"
        ),
        _table(
            f"validation-stats{suffix.replace('_', '-')}",
            ["run", "model", "spots measured", "scatter mean", "scatter std", "error mean", "error max"],
            rows,
            classes,
        ),
        _img(spots, f"laser spots at {v0.point} (Figure 4.5)"),
        _img(errors, f"mean and max error at {v0.point} (Figure 4.6)"),
    ]


def _head(
    session: Session, ident: Identification, validations, rep: dict, missing: list, title: str | None
) -> list[str]:
    """The page's head: its title, the kind of data, the verdict and what the session is.

    Parameters
    ----------
    session : Session
        The calibration session.
    ident : Identification
        Its calibration.
    validations : sequence of Validation
        The validation runs shown.
    rep : dict
        The solve's report (:func:`solve_report`).
    missing : list
        What the data leave unidentified (:func:`unidentifiable`).
    title : str or None
        The page's heading (None: named after the session's folder).

    Returns
    -------
    list of str
        The section's HTML pieces, in order.
    """
    esc = html.escape
    held = [d["combination"] for d in rep.get("determined_by", {}).get("from_prior", [])]
    warning = rep.get("warning")
    title = title or f"lasercal report: {session.path.resolve().name}"
    return [
        '<!DOCTYPE html>\n<html lang="en"><head><meta '
        f'charset="utf-8"><title>{esc(title)}</title><style>{_CSS}</style></head><body>',
        f"<h1>{esc(title)}</h1>",
        f'<p id="data-kind"><b>{esc(data_kind(session, validations))}</b></p>',
        f'<p id="verdict"><b>{esc(verdict(session, ident, validations, missing, held, warning))}</b></p>',
        (
            f'<p class="note">Session {esc(str(session.path))}: {session.m} captures at '
            f"{esc(', '.join(dict.fromkeys(session.point)))}, "
            f"nominal robot {esc(session.robot.name)}, calibrated by the <b>{esc(ident.method)}</b> method "
            f"({ident.iterations} iterations, {'converged' if ident.converged else 'not converged'}). "
            "Lengths in mm.</p>"
        ),
    ]


def _parameters_section(ident: Identification) -> list[str]:
    """The parameters, nominal against identified, with their standard errors.

    Parameters
    ----------
    ident : Identification
        Its calibration.

    Returns
    -------
    list of str
        The section's HTML pieces, in order.
    """
    prow = [
        [
            r.name + (f" ({r.unit})" if r.unit else ""),
            _vec(r.nominal, ".6g"),
            _vec(r.identified, ".6g"),
            _vec(r.std_error, ".2g"),
        ]
        for r in parameter_table(ident)
    ]
    return [
        "<h2>Parameters: nominal vs identified</h2>",
        (
            '<p class="note">Joint screws (omega, v) in the base frame at q = 0, the laser direction and the '
            "aperture M "
            "(thesis Table 4.3); standard errors from the fit's covariance (one standard deviation).</p>"
        ),
        _table("parameters", ["parameter", "nominal", "identified", "standard error"], prow),
    ]


def _corrections_section(ident: Identification) -> list[str]:
    """How far calibration moved each joint axis and the laser.

    Parameters and Returns as :func:`_parameters_section`'s: the calibration in, the section's HTML out.
    """
    crows = [[nm, f"{deg:.3f}", f"{mm:.3f}"] for nm, deg, mm in corrections(ident)]
    return [
        "<h2>Corrections per joint</h2>",
        (
            '<p class="note">How far calibration moved each joint axis from the nominal: the angle between '
            "the axis directions and the distance of the identified axis from the nominal axis's point "
            "nearest the base origin; for the laser, the beam's angle and the aperture's shift across the "
            "beam.</p>"
        ),
        _table("corrections", ["joint", "axis direction change (deg)", "axis position change (mm)"], crows),
    ]


def _points_section(session: Session, ident: Identification, rep: dict, out: Path) -> list[str]:
    """The calibration points before and after, their residual plot, and a camera session's every capture.

    Parameters
    ----------
    session, ident, rep
        As :func:`_head`'s: the session, its calibration and the solve's report.
    out : Path
        The report's folder, where the plots go.

    Returns
    -------
    list of str
        The section's HTML pieces, in order.
    """
    prows = []
    for nm, d in rep["points"].items():
        for when in ("before", "after", "aimed"):
            s = d.get(when)
            if s is not None:
                prows.append([nm, when, s["n"]] + [f"{s[k]:.3f}" for k in _STAT_KEYS])
    residual_plots(session, ident, out / "residuals.png")
    parts = [
        "<h2>Calibration points</h2>",
        (
            '<p class="note">Where each model says the captured beams land, per reference point (before: '
            "nominal; after: "
            "identified, outliers left out; a camera session's rows count its measured captures, each "
            "against its measured spot, and 'aimed' its aimed captures under the identified model, against "
            "where they were aimed).</p>"
        ),
        _table(
            "points",
            ["point", "model", "captures", "scatter mean", "scatter std", "error mean", "error max"],
            prows,
        ),
        _img("residuals.png", "residuals per reference point"),
    ]
    if session.measured.any():  # a camera session: every capture's residual, and what it was fitted to
        kind = np.where(session.measured, "measured", "aimed")
        sig = np.where(session.measured, session.spot_sigma, np.nan)
        crows = [
            [int(session.lines[i]), session.point[i], kind[i]]
            + [f"{v:.3f}" for v in (*ident.residuals[i], np.hypot(*ident.residuals[i]))]
            + ["" if np.isnan(sig[i]) else f"{sig[i]:.3f}", "left out" if ident.weights[i] == 0 else ""]
            for i in range(session.m)
        ]
        parts += [
            '<p class="note">Each capture\'s residual (mm): a measured one is fitted to the spot the camera '
            "measured, with its uncertainty; an aimed one to where it was aimed (its cross, or the coach's "
            "aim), with the aiming noise.</p>",
            _table(
                "captures",
                ["line", "point", "kind", "dx", "dy", "|r|", "uncertainty", "outlier"],
                crows,
            ),
        ]
    return parts


def _identifiability_section(rep: dict, missing: list) -> list[str]:
    """The identifiability: rank, condition, noise, outliers, prior and sheet pose.

    Parameters
    ----------
    rep : dict
        The solve's report (:func:`solve_report`).
    missing : list
        What the data leave unidentified (:func:`unidentifiable`).

    Returns
    -------
    list of str
        The section's HTML pieces, in order.
    """
    idf = rep["identifiability"]
    irows = [
        ["parameters", idf["parameters"]],
        ["rank", idf["rank"]],
        *(
            [["what the parameters are", idf["counted"]], ["possible from spots", idf["possible"]]]
            if "counted" in idf
            else []
        ),
        ["condition number", f"{idf['condition']:.1f}"],
        *(
            [["fit residual RMS", fit_by_kind_text(rep["fit_by_kind"], rep["noise_by_kind"])]]
            + [["noise by kind", noise_by_kind_line(rep["noise_by_kind"])]]
            if rep.get("noise_by_kind")  # a camera session: each kind of capture with its own figures
            else [
                ["fit residual RMS (mm)", f"{rep['fit_rms_mm']:.3f}"],
                ["aiming noise estimate per axis (mm)", f"{rep['sigma_mm']:.3f}"],
            ]
        ),
        ["outliers", ", ".join(f"line {o['line']} ({o['point']})" for o in rep["outliers"]) or "none"],
    ]
    det = rep.get("determined_by")
    if det is None:
        irows += [["prior", "none (plain least squares)"]]
        irows += [[f"not identifiable ({k + 1})", u] for k, u in enumerate(idf["unidentifiable"])]
    else:
        counts = f"{det['data']} / {det['data_and_prior']} / {det['prior']}"
        irows += [["determined by the data / data and prior / the prior", counts]]
        irows += [
            [f"from the prior: {d['combination']}", f"{d['affects']} ({d['fix']})"] for d in det["from_prior"]
        ]
    irows += [["partial: not identified", str(d)] for d in missing]
    sh = rep.get("sheet")
    if sh:
        p, sd = sh["pose"], sh["std"]
        irows += [
            ["sheet pose (base frame)", f"x {p['x_mm']:.2f} ± {sd['x_mm']:.2f} mm, y {p['y_mm']:.2f} ± "
             f"{sd['y_mm']:.2f} mm, yaw {p['yaw_deg']:.3f} ± {sd['yaw_deg']:.3f} deg"],
        ]  # fmt: skip
    return [
        "<h2>Identifiability</h2>",
        '<p class="note">SVD of the column-scaled Jacobian (the data alone), and which combinations the '
        "data and which the prior (the robot's manufacturing tolerances) determined: posterior / prior sigma "
        "below 0.5, between, above 0.9 (docs/formats.md, Priors).</p>",
        _table("identifiability", ["", ""], irows),
    ]


def _diagnosis_section(diagnosis: Diagnosis, out: Path) -> list[str]:
    """The diagnosis: what the geometric model misses, and its plots.

    Parameters
    ----------
    diagnosis : Diagnosis
        The session's diagnosis.
    out : Path
        The report's folder, where the plots go.

    Returns
    -------
    list of str
        The diagnosis's heading, summary and plots.
    """
    esc = html.escape
    names = [p.name for p in diagnosis_plots(diagnosis, out)]
    parts = [
        "<h2>Diagnosis: what the geometric model misses</h2>",
        f'<pre id="diagnosis">{esc(format_diagnosis(diagnosis))}</pre>',
    ]
    parts += [_img(nm, nm.replace("_", " ").removesuffix(".png")) for nm in names]
    return parts


def write_report(
    out,
    session: Session,
    ident: Identification,
    diagnosis: Diagnosis | None = None,
    validations=(),
    reference: dict | None = None,
    title: str | None = None,
) -> Path:
    """Write ``index.html`` and its PNG plots into the folder ``out``.

    Parameters
    ----------
    out : folder (created)
    session : Session, the calibration session (laser spots)
    ident : Identification, its calibration (parameter table, residuals, identifiability)
    diagnosis : Diagnosis or None
    validations : sequence of Validation, in the order to show (e.g. nominal first); a section per point
    reference : dict label -> {scatter_mean, scatter_std, error_mean, error_max}, published figures
        shown beside the first point's runs
    title : str, the page's heading

    Returns
    -------
    Path of index.html
    """
    if session.measurement != "laser":
        raise FormatError(
            session.path, "the report covers laser sessions (spots on a plane)", field="measurement"
        )
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    reference = reference or {}
    rep = solve_report(session, ident)
    missing = unidentifiable(session, ident)
    parts = _head(session, ident, validations, rep, missing, title)

    check_not_calibration_points(session, ident, validations)
    for k, runs in enumerate(
        by_point(validations).values()
    ):  # the published figures beside the first point's
        first = k == 0
        parts += validation_section(
            runs, reference if first else {}, out, "" if first else f"_{runs[0].point}"
        )
    parts += _parameters_section(ident)
    parts += _corrections_section(ident)
    parts += _points_section(session, ident, rep, out)
    parts += _identifiability_section(rep, missing)
    if diagnosis is not None:
        parts += _diagnosis_section(diagnosis, out)
    parts.append("</body></html>\n")
    index = out / "index.html"
    index.write_text("\n".join(parts), encoding="utf-8")
    return index
