"""``lasercal diagnose``: the model-discrepancy finding, as text, JSON and plots."""

from __future__ import annotations

import argparse
import json
import sys

from lasercal.collector.cli.options import SEED, count, number
from lasercal.solver.analysis import ALPHA


def args_diagnose(p: argparse.ArgumentParser) -> None:
    """The arguments of ``lasercal diagnose``."""
    p.add_argument("session", help="session folder")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.add_argument("--report", metavar="DIR", help="write the plots that make the case")
    p.add_argument(
        "--alpha",
        type=number(0, 1, lo_open=True, hi_open=True),
        default=ALPHA,
        help=f"family-wise significance level (default {ALPHA})",
    )
    p.add_argument(
        "--bootstrap",
        type=count(0, 10**6),
        default=2000,
        help="first-order parametric-bootstrap replicates (default 2000; 0 skips)",
    )
    p.add_argument(
        "--refits",
        type=count(0, 10**4),
        default=10,
        help="full simulations of the experiment with refits (default 10)",
    )
    p.add_argument("--seed", type=SEED, default=0)
    p.add_argument(
        "--payload",
        metavar="KG,X,Y,Z",
        help="mass (kg) and centre of mass at q = 0 (mm) carried by the flange, for the gravity model when "
        "torques are not logged",
    )


def parse_payload(text: str | None):
    """'KG,X,Y,Z' -> (kg, (3,) mm), or None."""
    import numpy as np

    from lasercal.solver.errors import FormatError

    if not text:
        return None
    try:
        vals = [float(v) for v in text.split(",")]
    except ValueError:
        vals = []
    if len(vals) != 4 or not np.all(np.isfinite(vals)) or not 0 < vals[0] <= 100:
        raise FormatError("--payload", f"expected KG,X,Y,Z (0 < kg <= 100, finite mm), got {text!r}")
    return vals[0], np.array(vals[1:])


def format_diagnosis(d) -> str:
    """A person's summary of a Diagnosis."""
    import numpy as np

    o = d.as_dict()
    lines = []
    if o["effect"] == "none":
        lines.append(
            "finding: none -- the geometric model and aiming noise explain the data (best candidate "
            f"{d.tests[0].label}, corrected p = {o['p_value']:.3g})"
        )
    else:
        where = f"point {o['point']}" if o["point"] else "joint " + ", ".join(map(str, o["joints"]))
        lines.append(f"finding: {o['effect']} at {where} (corrected p = {o['p_value']:.3g})")
        for nm, v in o["parameters"].items():
            lines.append(f"  {nm} = {v['value']:.4g} +- {v['std_error']:.2g} {v['units']}")
        if d.ambiguous_with:
            lines.append(
                "  (explains the data almost as well: "
                + ", ".join(d.ambiguous_with)
                + " -- more reference points would tell them apart)"
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
    acc, st = d.acceptance, d.statistics
    if d.proposed is not None and d.extension is None:
        lines.append(
            f"proposed by the F test: {d.proposed.effect} {d.proposed.names} -- not kept: "
            + acc.get("rejected", "")
        )
    if acc.get("decided_by") == "cross-validation":
        ci = acc.get("gain_percent_ci95")
        h = acc["holdout_rms_mm"]
        cand = d.proposed.effect if d.proposed else "no extension"
        lines.append(
            f"held-out ({acc['folds']} folds by {acc['grouping']}): geometric {h['geometric']:.3f} mm, "
            f"with {cand} {h['extended']:.3f} mm; gain per fold "
            + (f"95% CI [{ci[0]:.1f}, {ci[1]:.1f}]%" if ci else "n/a")
            + f"  (torques: {d.torque_source})"
        )
        for i, why in acc.get("failed_folds", {}).items():
            lines.append(f"  fold {i} could not be fitted: {why}")
    else:
        lines.append(f"no cross-validation: the F test decided alone  (torques: {d.torque_source})")
    if st:
        lines.append(f"{'RMS (mm)':10} {'nominal':>9} {'geometric':>10} {'extended':>9}")
        for part in ("train", "holdout"):
            vals = [st[m][part] for m in ("nominal", "geometric", "extended")]
            lines.append(
                f"{part:10} " + " ".join(f"{v:9.3f}" if v is not None else f"{'-':>9}" for v in vals)
            )
    for eff, why in d.untested.items():
        lines.append(f"not tested: {eff} -- {why}")
    if d.extension is not None and d.robot_extension is None:
        lines.append(f"{d.effect} is a session effect: fitted and reported, not written to the robot model")
    lines.append("candidates (F test against the geometric model, Bonferroni over all):")
    for t in d.tests[:6]:
        lines.append(f"  {t.label:38} F = {t.F:9.3f}  df {t.df}  p = {t.p:.3g}  corrected {t.p_adjusted:.3g}")
    return "\n".join(lines)


def cmd_diagnose(args) -> int:
    from lasercal.solver.analysis.diagnose import diagnose
    from lasercal.solver.formats.session import load_session

    d = diagnose(
        load_session(args.session),
        alpha=args.alpha,
        n_boot=args.bootstrap,
        seed=args.seed,
        n_refit=args.refits,
        payload=parse_payload(args.payload),
    )
    if args.report:
        from lasercal.collector.report.plots import diagnosis_plots

        for path in diagnosis_plots(d, args.report):
            print(f"wrote {path}", file=sys.stderr)
    print(json.dumps(d.as_dict(), indent=2) if args.json else format_diagnosis(d))
    return 0
