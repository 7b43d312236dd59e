"""``lasercal demo``: the thesis's Panda experiment (Section 4.3) on the built-in simulated robot.

The truth is the thesis's identified Panda (Table 4.3); an operator with 1 mm aiming
noise captures 15 configurations at each of P1-P3; both methods calibrate; the P4
validation of the thesis (60 configurations computed by each model, spots of the true
robot) gives the before/after statistics, printed beside the thesis's.
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from solver.identify import identify
from solver.model import load_model
from solver.session import load_layout, load_session, session_meta, write_session
from solver.simulate import simulate_captures, validation_spots
from solver.stats import spot_stats

# Thesis Section 4.3 / Figures 4.5-4.6, at P4 (mm).
THESIS_P4 = {"before": {"scatter_mean": 6.86, "scatter_std": 5.016, "error_mean": 9.76, "error_max": 26.993},
             "after": {"scatter_mean": 1.11, "scatter_std": 1.00, "error_mean": 1.057, "error_max": 4.92}}


def run_demo(out: Path, seed: int = 0, per_point: int = 15, aim_noise: float = 1.0, n_validation: int = 60, progress=None) -> dict:
    """Run the simulated experiment, write its files under ``out`` and return the summary.

    Returns
    -------
    dict with 'p4' -> {'nominal', 'lm', 'thesis'} spot statistics (mm), 'thesis' (published),
    and per-method 'iterations' and 'seconds'
    """
    step = progress or (lambda msg: None)
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    truth = load_model("panda_thesis_identified")
    layout = load_layout(Path(__file__).resolve().parent.parent / "data" / "layouts" / "thesis.yaml")
    rng = np.random.default_rng(seed)
    step("capturing 15 configurations at each of P1-P3 (simulated operator, 1 mm aiming noise)")
    c = simulate_captures(truth, layout, per_point, aim_noise, rng)
    meta = session_meta("panda", layout, truth.aperture[2], simulated={"truth": truth.name, "aim_noise_mm": aim_noise, "seed": seed})
    session = load_session(write_session(out / "session", meta, c.point, c.t, c.q))
    p4 = layout.points[layout.validation[0]]
    summary = {"p4": {}, "thesis": THESIS_P4, "methods": {}}
    models = {"nominal": session.robot}
    for method in ("lm", "thesis"):
        step(f"calibrating by the {method} method")
        ident = identify(session, method)
        ident.model.save(out / f"model_{method}.yaml")
        models[method] = ident.model
        summary["methods"][method] = {"iterations": ident.iterations, "converged": ident.converged, "seconds": round(ident.seconds, 3), "fit_rms_mm": round(ident.rms_mm, 4)}
    for name, model in models.items():
        step(f"validating the {name} model at P4 (60 configurations)")
        spots = validation_spots(truth, model, p4, n_validation, rng, **layout.aim_kwargs())
        summary["p4"][name] = spot_stats(spots, p4).as_dict()
    (out / "summary.json").write_text(json.dumps(summary, indent=2))
    return summary


def format_summary(s: dict) -> str:
    """The demo's printed table: P4 statistics beside the thesis's."""
    rows = [f"{'P4 (441, 160, -8) mm':26} {'scatter mean':>12} {'scatter std':>11} {'error mean':>10} {'error max':>9}"]
    for label, key, ref in (("nominal (before)", "nominal", "before"), ("lm (ours)", "lm", None), ("thesis method", "thesis", None), ("thesis paper, before", None, "before"), ("thesis paper, after", None, "after")):
        d = s["p4"][key] if key else s["thesis"][ref]
        rows.append(f"{label:26} {d['scatter_mean']:12.3f} {d['scatter_std']:11.3f} {d['error_mean']:10.3f} {d['error_max']:9.3f}")
    for m, d in s["methods"].items():
        rows.append(f"{m}: {d['iterations']} iterations, {d['seconds']} s, {'converged' if d['converged'] else 'stopped at the iteration cap'}")
    return "\n".join(rows)
