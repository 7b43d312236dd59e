"""``lasercal diagnose``: the model-discrepancy finding, as text, JSON and plots."""

from __future__ import annotations

import argparse
import json
import sys

from lasercal.collector.cli.options import (
    SESSION_ROBOT,
    bootstrap_arguments,
    chain_arguments,
    number,
    session_robot,
)
from lasercal.solver.analysis import ALPHA


def args_diagnose(p: argparse.ArgumentParser) -> None:
    """The arguments of ``lasercal diagnose``."""
    p.add_argument("session", help="session folder")
    chain_arguments(p, SESSION_ROBOT)
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.add_argument("--report", metavar="DIR", help="write the plots that make the case")
    p.add_argument(
        "--alpha",
        type=number(0, 1, lo_open=True, hi_open=True),
        default=ALPHA,
        help=f"family-wise significance level (default {ALPHA})",
    )
    bootstrap_arguments(p)
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


def cmd_diagnose(args) -> int:
    from lasercal.collector.report.text import format_diagnosis
    from lasercal.solver.analysis.diagnose import diagnose
    from lasercal.solver.formats.session import load_session

    d = diagnose(
        load_session(args.session, **session_robot(args)),
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
