"""Plain-text renderings of results for the terminal and the HTML report (one place for each wording)."""

from __future__ import annotations

import numpy as np

from lasercal.solver.kinematics.effects import drift_t0
from lasercal.solver.kinematics.sheet import SHAPE_KEYS, SheetPose


def _finding_lines(d) -> list[str]:
    """The finding: the effect named and its parameters, or none and the best candidate.

    Parameters
    ----------
    d : Diagnosis
        The diagnosis.

    Returns
    -------
    list of str
        The summary's lines, in order.
    """
    o = d.as_dict()
    lines = []
    if o["effect"] == "none":
        best = "no candidate the data can see"
        if d.tests:
            best = f"best candidate {d.tests[0].label}, corrected p = {o['p_value']:.3g}"
        what = "the noise" if d.geometric.extra.get("noise") else "aiming noise"
        lines.append(f"finding: none -- the geometric model and {what} explain the data ({best})")
    else:
        where = f"point {o['point']}" if o["point"] else "joint " + ", ".join(d.extension.tags)
        line = f"finding: {o['effect']} at {where} (corrected p = {o['p_value']:.3g}"
        if "folds_agree" in d.acceptance:  # the gain of the selection made inside each fold
            acc = d.acceptance
            line += (
                f"; held-out gain {o['gain_percent']:.1f} %, chosen by {acc['folds_agree']} of "
                f"{len(acc['fold_choices'])} folds"
            )
        lines.append(line + ")")
        for nm, v in o["parameters"].items():
            if not nm.startswith("map"):  # a joint map's hundreds of knots: one line below
                lines.append(f"  {nm} = {v['value']:.4g} +- {v['std_error']:.2g} {v['units']}")
        if d.ambiguous_with:
            lines.append(
                "  (explains the data almost as well: "
                + ", ".join(d.ambiguous_with)
                + " -- only data that move them differently tell them apart: more varied configurations, "
                "more reference points; none, when they share their axis and load)"
            )
    return lines


def _remains_lines(d) -> list[str]:
    """What remains beyond the camera, and the simulated re-runs of the experiment.

    Parameters and Returns as :func:`_finding_lines`'s: the diagnosis in, the summary's lines out.
    """
    lines = []
    noise = (d.extended or d.geometric).extra.get("noise")
    if noise and noise["measured"]:  # a camera session: what remains beyond the camera, said plainly
        lines.append(
            f"remains: {noise['unseen_mm']:.3f} mm per axis beyond what the camera sees "
            f"({noise['camera_mm']:.3f}), unexplained by the model -- the arm's repeatability (a Panda's: "
            "about 0.05 mm at the spot), or an effect no candidate describes (backlash, friction, a sheet "
            "that is not flat)"
        )
    b = d.bootstrap
    if b:
        lines.append(
            f"simulation: {b['replicates']} first-order re-runs of the experiment on the identified "
            "geometric robot; the measured strongest-candidate statistic beats "
            f"{100 * (1 - b['p_value']):.1f}% of them (bootstrap p = {b['p_value']:.3g})"
        )
        if b["rms_mm"]:
            lines.append(
                f"  residual RMS: measured {b['observed_rms_mm']:.3f} mm, simulated "
                f"{np.mean(b['rms_mm']):.3f} +- {np.std(b['rms_mm']):.3f} mm ({b['refits']} full refits)"
            )
    return lines


def _decision_lines(d) -> list[str]:
    """How the finding was decided: the F test's proposal, the held-out folds, the joint map.

    Parameters and Returns as :func:`_finding_lines`'s: the diagnosis in, the summary's lines out.
    """
    lines = []
    acc = d.acceptance
    if d.proposed is not None and d.extension is None:
        lines.append(
            f"proposed by the F test: {d.proposed.effect} {d.proposed.names} -- not kept: "
            + acc.get("rejected", "")
        )
    if acc.get("decided_by") == "cross-validation":
        ci = acc.get("gain_percent_ci95")
        h = acc["holdout_rms_mm"]
        cand = d.proposed.effect if d.proposed else "no extension"
        kinds = acc.get("holdout_by_kind", {})
        if kinds:  # a camera session: each kind of capture at its own noise
            h = "; ".join(
                f"{k} {v['geometric']:.3f} mm, with {cand} {v['extended']:.3f} mm"
                for k, v in kinds.items()
                if v["geometric"] is not None
            )
            h += "; decided in units of each capture's noise"
        else:
            h = f"geometric {h['geometric']:.3f} mm, with {cand} {h['extended']:.3f} mm"
        lines.append(
            f"held-out ({acc['folds']} folds {acc['grouping']}): {h}; gain per fold "
            + (f"95% CI [{ci[0]:.1f}, {ci[1]:.1f}]%" if ci else "n/a")
            + f"  (torques: {d.torque_source})"
        )
        if "fold_choices" in acc:
            chose = {}
            for c in acc["fold_choices"]:
                chose[c["label"]] = chose.get(c["label"], 0) + 1
            lines.append(
                "  each fold's own choice, from its training rows alone: "
                + ", ".join(f"{lb} in {n}" for lb, n in chose.items())
                + f" (a cause is named when {acc['folds_needed']} of them agree)"
            )
        for i, why in acc.get("failed_folds", {}).items():
            lines.append(f"  fold {i} could not be fitted: {why}")
    else:
        lines.append(f"no cross-validation: the F test decided alone  (torques: {d.torque_source})")
    jm = acc.get("joint_map")
    if jm:
        h, ci = jm["holdout_rms_mm"], jm["gain_percent_ci95"]
        verdict = "kept" if jm["accepted"] else "asked for: kept" if jm["asked_for"] else "not kept"
        lines.append(
            f"{jm['label']} ({jm['knots']} knots), held-out ({jm['folds']} folds by configuration): "
            f"{h['without']:.3f} mm without, {h['with']:.3f} mm with; gain per fold "
            + (f"95% CI [{ci[0]:.1f}, {ci[1]:.1f}]%" if ci else "n/a")
            + f" (the keep decision's own folds): {verdict}"
        )
    return lines


def _statistics_lines(d) -> list[str]:
    """The RMS table, what was not tested or not seen, and the candidates' F tests.

    Parameters and Returns as :func:`_finding_lines`'s: the diagnosis in, the summary's lines out.
    """
    st = d.statistics
    lines = []
    if st:
        lines.append(f"{'RMS (mm)':10} {'nominal':>9} {'geometric':>10} {'extended':>9}")
        for part in ("train", "holdout"):
            vals = [st[m][part] for m in ("nominal", "geometric", "extended")]
            lines.append(
                f"{part:10} " + " ".join(f"{v:9.3f}" if v is not None else f"{'-':>9}" for v in vals)
            )
    for eff, why in d.untested.items():
        lines.append(f"not tested: {eff} -- {why}")
    if d.unseen:
        lines.append(
            "not seen by the data beyond the geometry (the prior would decide them; never selected): "
            + ", ".join(f"{k} ({v:.2f})" for k, v in list(d.unseen.items())[:8])
            + (f" and {len(d.unseen) - 8} more" if len(d.unseen) > 8 else "")
            + "  (posterior / prior sigma)"
        )
    if d.extension is not None and d.robot_extension is None:
        line = f"{d.effect} is a session effect: fitted and reported, not written to the robot model"
        t0 = drift_t0(d.extension)
        if t0 is not None:
            line += (
                f"; it is zero at t = {t0:.1f} s, the mean capture time, the instant the geometry describes"
            )
        lines.append(line)
    lines.append("candidates (F test against the geometric model, Bonferroni over all):")
    for t in d.tests[:6]:
        lines.append(f"  {t.label:38} F = {t.F:9.3f}  df {t.df}  p = {t.p:.3g}  corrected {t.p_adjusted:.3g}")
    return lines


def format_diagnosis(d) -> str:
    """A person's summary of a Diagnosis."""
    return "\n".join(_finding_lines(d) + _remains_lines(d) + _decision_lines(d) + _statistics_lines(d))


def identifiable_text(rank: int, parameters: int, possible: int | None = None) -> str:
    """The one wording of the identifiable count (``solve``, the report, ``plan``, the capture coach), over
    the parameters :func:`~lasercal.solver.identify.laser_parameters.counted_parameters` defines:
    'identifiable: rank 30 of 31 parameters (30 possible from spots)'."""
    text = f"identifiable: rank {rank} of {parameters} parameters"
    return text + (f" ({possible} possible from spots)" if possible is not None else "")


def _print_and_tilt(pose, std=None) -> str:
    """A sheet's print scale (in percent off exact) and tilt (mrad) along its x, y axes, with their standard
    deviations (a dict of SheetPose's keys) when given: 'printed at +0.070 ± 0.010, -0.162 ± 0.010 %,
    tilted 4.78 ± 0.10, -0.30 ± 0.10 mrad along its x, y'."""

    def pm(v, k, f):
        return f"{v:+.{f}f}" + (
            "" if std is None else f" ± {abs(std.get(k, 0.0)) * (100 if f == 3 else 1000):.{f}f}"
        )

    scale = ", ".join(pm(100 * (getattr(pose, k) - 1), k, 3) for k in ("scale_x", "scale_y"))
    tilt = ", ".join(pm(1000 * getattr(pose, k), k, 2) for k in ("tilt_x_rad", "tilt_y_rad"))
    return f"printed at {scale} %, tilted {tilt} mrad along its x, y"


def sheet_shape_line(d: dict) -> str:
    """``solve``'s finding on the sheet's shape (:mod:`solver.identify.sheetshape`'s record), one line that
    names the sheet, never a joint: 'finding (the sheet): not flat -- curl 1.6 mm over the sheet, shear
    0.4 mm per m; modelled (F = 27.8, p = 1.8e-12; held out 0.594 -> 0.356 mm)'."""
    if not d.get("tested"):
        return f"finding (the sheet): shape not tested -- {d.get('reason', '')}"
    ho = d.get("holdout") or {}
    held = f"; held out {ho['flat_mm']:.3f} -> {ho['shaped_mm']:.3f} mm" if ho else "; no folds"
    test = f"F = {d['F']:.3g}, p = {d['p_value']:.2g}{held}" if d.get("F") is not None else d["reason"]
    sizes = f"curl {d['curl_mm']:.2f} mm over the sheet, shear {abs(d['shear_mm_per_m']):.2f} mm per m"
    if d["kept"]:
        cam = d.get("camera_warp_mm") or 0.0
        how = "from where it stood (eq. S8)" if d.get("camera_view") == "S8" else "this session's (eq. S7)"
        seen = f"; the camera saw the raised paper {cam:.2f} mm RMS askew, {how}" if cam else ""
        return f"finding (the sheet): not flat -- {sizes}; modelled ({test}){seen}"
    reg = d.get("regions") or {}
    why = test if d.get("F") is None else f"{test}; {d['reason']}"  # no F test: the reason is the test
    line = f"finding (the sheet): flat and square within what the data see ({why})"
    if reg and reg["p"] < 0.01:  # structure beyond the noise that no sheet term holds: its size and where
        worst = reg["cells"][reg["worst"]]["mean_mm"]
        line += (
            f"; yet its residuals vary over the sheet beyond their noise: {reg['structure_mm']:.3f} mm RMS "
            f"(p = {reg['p']:.2g}), most at {reg['worst']} ({np.hypot(*worst):.3f} mm)"
        )
    return line


def format_true_sheet(found, true, laid, G) -> str:
    """A simulated sheet session's check of ``solve``'s sheet pose against the truth (one line).

    Parameters
    ----------
    found : dict x_mm, y_mm, yaw_deg[, scale_x, scale_y] (and ``std``: the same keys), the identified pose
    true : SheetPose, where the sheet truly lies in the true robot's own base frame
    laid : SheetPose, where it was laid, in the truth file's base frame
    G : (4, 4) array, the truth file's base frame to its own, mm
    """
    turn = np.degrees(np.arctan2(G[1, 0], G[0, 0]))
    tilt = np.degrees(np.arccos(np.clip(G[2, 2], -1.0, 1.0)))
    found = SheetPose(**{k: v for k, v in found.items() if k != "std"}).as_dict() | {"std": found["std"]}
    keys = [k for k in found["std"] if k in found and k not in SHAPE_KEYS]  # the truth's shape: not a pose's
    z = [(found[k] - getattr(true, k)) / max(found["std"][k], 1e-12) for k in keys]
    return (
        f"simulated: the sheet truly lies at x {true.x_mm:.2f} mm, y {true.y_mm:.2f} mm, yaw "
        f"{true.yaw_deg:.3f} deg in that frame, {_print_and_tilt(true)} (found - true: "
        f"{', '.join(f'{v:+.1f}' for v in z)} sigma); "
        f"it was laid at x {laid.x_mm:.2f}, y {laid.y_mm:.2f} mm, yaw {laid.yaw_deg:.3f} deg in the true "
        f"robot's file frame, which its own frame turns by {turn:.3f} deg about z, tilts by {tilt:.3f} deg "
        f"and shifts by {np.hypot(G[0, 3], G[1, 3]):.2f} mm\n"
    )


def noise_by_kind_line(k: dict) -> str:
    """One line: the noise found for measured and aimed captures (mm per axis)."""
    aimed = (
        f"{k['aimed']} aimed where the camera could not measure them, aiming noise {k['aimed_mm']:.3f} mm"
        if k["aimed"]
        else "none aimed"
    )
    return (
        f"noise by kind: {k['measured']} measured by the camera, {k['measured_mm']:.3f} mm per axis (camera "
        f"{k['camera_mm']:.3f}, beyond what it sees {k['unseen_mm']:.3f}); {aimed}"
    )


def fit_by_kind_text(fit: dict, noise: dict) -> str:
    """A camera session's fit residuals per kind of capture: '42 measured, fit residual RMS 0.072 mm; 3
    aimed, fit residual RMS 7.316 mm (their aim's error)'."""
    m, a = fit["measured"], fit["aimed"]
    text = f"{noise['measured']} measured, fit residual RMS {m['rms_mm']:.3f} mm"
    if noise["aimed"]:
        rms = "-" if a["rms_mm"] is None else f"{a['rms_mm']:.3f} mm"
        text += f"; {noise['aimed']} aimed, fit residual RMS {rms} (their aim's error, not the model's)"
    return text


def _not_counted(rep: dict, det: dict) -> str:
    """What the data/prior count leaves out of the parameters, e.g. ' of 30 (not counted: the beam's start
    along itself, held by the aperture's height; the sheet's print scale and tilt, 4, on its line)'."""
    counted = det["data"] + det["data_and_prior"] + det["prior"]
    left = rep["identifiability"]["parameters"] - counted
    if left <= 0:
        return ""
    what = []
    if rep.get("measurement") not in ("point", "position"):
        what.append("the beam's start along itself, held by the aperture's height")
    if rep.get("sheet"):
        what.append("the sheet's print scale and tilt, 4, on its line below")
    return f" of {counted} ({left} not counted: {'; '.join(what) or 'held by convention'})"


def _print_fit(rep: dict, w) -> None:
    """The method's convergence and the fit's residual and noise.

    Parameters
    ----------
    rep : dict
        The solve's statistics (:func:`~lasercal.solver.analysis.stats.solve_report`).
    w : callable
        Writes one piece of text.
    """
    w(
        f"method {rep['method']}: {'converged' if rep['converged'] else 'NOT converged'} after "
        f"{rep['iterations']} iterations, {rep['seconds']:.3f} s\n"
    )
    noise = "measurement" if rep.get("measurement") == "position" else "aiming"  # a tracker aims nothing
    kinds = rep.get("noise_by_kind")
    if kinds:  # a camera session: each kind of capture with its own figures
        w(f"captures {rep['captures']}: {fit_by_kind_text(rep['fit_by_kind'], kinds)}\n")
        w(noise_by_kind_line(kinds) + "\n")
    else:
        w(
            f"captures {rep['captures']}, fit residual RMS {rep['fit_rms_mm']:.3f} mm, {noise} noise "
            f"estimate {rep['sigma_mm']:.3f} mm per axis\n"
        )


def _print_identifiability(rep: dict, w) -> None:
    """What the data identify, and what the prior determines.

    Parameters as :func:`_print_fit`'s: the solve's statistics, and what writes the text.
    """
    idf = rep["identifiability"]
    w(
        f"{identifiable_text(idf['rank'], idf['parameters'], idf.get('possible'))}, condition number "
        f"{idf['condition']:.3g}\n"
    )
    if idf.get("counted"):
        w(f"  parameters: {idf['counted']}\n")
    if rep.get("warning"):
        w(f"WARNING: {rep['warning']}\n")
    det = rep.get("determined_by")
    if det is None:
        for u in idf["unidentifiable"]:
            w(f"  not seen by the data (held at nominal): {u}\n")
        w("prior: none (plain least squares)\n")
    else:
        w(
            f"determined by the data {det['data']}, by data and prior {det['data_and_prior']}, by the prior "
            f"{det['prior']}{_not_counted(rep, det)} (posterior / prior sigma < "
            f"{det['thresholds']['data_below']:g}, between, > {det['thresholds']['prior_above']:g}; prior: "
            "the robot's tolerances, docs/formats.md)\n"
        )
        for d in det["from_prior"]:
            n = d["directions"]
            w(
                f"  from the prior: {d['combination']} ({n} direction{'s' * (n > 1)}): {d['affects']}; "
                f"{d['fix']}\n"
            )


def _print_sheet_and_outliers(rep: dict, w) -> None:
    """Where the sheet lies and its shape, and the outlier captures left out.

    Parameters as :func:`_print_fit`'s: the solve's statistics, and what writes the text.
    """
    sh = rep.get("sheet")
    if sh:
        p, sd = sh["pose"], sh["std"]
        w(
            f"the sheet lies at x {p['x_mm']:.2f} ± {sd['x_mm']:.2f} mm, y {p['y_mm']:.2f} ± "
            f"{sd['y_mm']:.2f} mm, yaw {p['yaw_deg']:.3f} ± {sd['yaw_deg']:.3f} deg, "
            f"{_print_and_tilt(SheetPose(**p), sd)} (its origin and x axis "
            "in the robot's own base frame: joint 1's axis is the nominal's, joint 2 points as the "
            "nominal's; a robot whose base differs from the nominal's sees a sheet laid at its placement "
            "elsewhere, docs/formats.md)\n"
        )
    if rep.get("sheet_shape"):
        w(sheet_shape_line(rep["sheet_shape"]) + "\n")
    if rep["outliers"]:
        w(
            f"outlier captures (left out): {len(rep['outliers'])}: "
            + ", ".join(f"#{o['index']} (line {o['line']}, {o['point']})" for o in rep["outliers"][:20])
            + ("..." if len(rep["outliers"]) > 20 else "")
            + "\n"
        )


def _print_by_measurement(rep: dict, w) -> None:
    """The before/after table of the session's measurement: points, targets or spots.

    Parameters as :func:`_print_fit`'s: the solve's statistics, and what writes the text.
    """
    if rep.get("measurement") == "point":
        w(f"\n{'point':24} {'spread RMS before':>18} {'after':>8}   (mm, tool points about their mean)\n")
        for nm, b in rep["before"]["points"].items():
            w(
                f"{nm:24} {b['spread_rms_mm']:18.3f} "
                f"{rep['after']['points'].get(nm, {}).get('spread_rms_mm', float('nan')):8.3f}\n"
            )
        for nm, b in rep["before"]["distances"].items():
            w(
                f"|d - d0| {nm}: before {b:.3f} mm, after "
                f"{rep['after']['distances'].get(nm, float('nan')):.3f} mm\n"
            )
    elif rep.get("measurement") == "position":
        w(f"gauge: {rep['gauge']}\n")
        w(
            f"\n{'target':12} {'n':>4} {'RMS nominal':>12} {'identified':>11}"
            "   (mm, sensor frame; target at q = 0)\n"
        )
        for nm, d in rep["targets"].items():
            w(
                f"{nm:12} {d['n']:4d} {d['before_rms_mm']:12.4f} {d['after_rms_mm']:11.4f}"
                f"   {d['target_mm']}\n"
            )
    else:
        _print_points(rep, w)


def _print_cross_validation(rep: dict, w) -> None:
    """The cross-validated prediction error.

    Parameters as :func:`_print_fit`'s: the solve's statistics, and what writes the text.
    """
    cv = rep.get("cross_validation")
    if cv:
        of = " of the measured captures" if "by_kind" in cv else ""
        w(
            f"\n{cv['folds']}-fold cross-validated prediction error{of}: RMS {cv['holdout_rms_mm']:.3f} mm, "
            f"mean {cv['holdout_mean_mm']:.3f}, max {cv['holdout_max_mm']:.3f} (nominal RMS "
            f"{cv['nominal_rms_mm']:.3f})\n"
        )
        a = cv.get("by_kind", {}).get("aimed")
        if a and a["captures"]:
            w(
                f"  aimed captures ({a['captures']}): held-out RMS {a['rms_mm']:.3f} mm, max "
                f"{a['max_mm']:.3f} (their aim's error)\n"
            )


def format_solve(rep: dict) -> str:
    """``lasercal solve``'s statistics (:func:`~lasercal.solver.analysis.stats.solve_report`) as a table."""
    lines = []
    w = lines.append
    for section in (
        _print_fit,
        _print_identifiability,
        _print_sheet_and_outliers,
        _print_by_measurement,
        _print_cross_validation,
    ):
        section(rep, w)
    return "".join(lines)


def _print_points(rep: dict, w) -> None:
    """Per reference point: spot statistics before and after (laser sessions); a camera session's over its
    measured captures, its aimed ones apart."""
    kinds = "; before, after: the measured captures; aimed: the aimed ones" if "fit_by_kind" in rep else ""
    w(
        f"\n{'point':8} {'':7} {'n':>4} {'scatter mean':>13} {'scatter std':>12} {'error mean':>11} "
        f"{'error max':>10}   (mm{kinds})\n"
    )
    for nm, d in rep["points"].items():
        for lab in ("before", "after", "aimed"):
            s = d.get(lab)
            if s:
                w(
                    f"{nm:8} {lab:7} {s['n']:4d} {s['scatter_mean']:13.3f} {s['scatter_std']:12.3f} "
                    f"{s['error_mean']:11.3f} {s['error_max']:10.3f}\n"
                )
