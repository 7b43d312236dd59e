"""``lasercal diagnose``: the model-discrepancy finding, as text, JSON and plots."""

from __future__ import annotations

import argparse
import json
import sys

from lasercal.collector.cli.options import (
    INFOLDER,
    SESSION_ROBOT,
    bootstrap_arguments,
    chain_arguments,
    number,
    output_argument,
    parse_payload,
    payload_argument,
    session_robot,
)
from lasercal.collector.report.plots import DIAGNOSIS_PLOTS
from lasercal.solver.analysis import ALPHA


def args_diagnose(p: argparse.ArgumentParser) -> None:
    """The arguments of ``lasercal diagnose``."""
    p.add_argument("session", type=INFOLDER, help="session folder")
    chain_arguments(p, SESSION_ROBOT)
    p.add_argument("--json", action="store_true", help="print one JSON object")
    output_argument(
        p,
        "--report",
        kind="into",
        metavar="DIR",
        help="write the plots that make the case",
        writes=lambda args: DIAGNOSIS_PLOTS,  # checked: none may be an input
    )
    p.add_argument(
        "--alpha",
        type=number(0, 1, lo_open=True, hi_open=True),
        default=ALPHA,
        help=f"family-wise significance level (default {ALPHA})",
    )
    bootstrap_arguments(p)
    payload_argument(p)


def cmd_diagnose(args) -> int:
    from lasercal.collector.report.text import format_diagnosis
    from lasercal.solver.analysis.diagnose import diagnose
    from lasercal.solver.formats.session import load_session
    from lasercal.solver.identify.measurement import check_data

    session = load_session(args.session, **session_robot(args))
    check_data(session)
    d = diagnose(
        session,
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
