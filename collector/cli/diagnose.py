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
    numbers,
    output_argument,
    session_robot,
)
from lasercal.solver.analysis import ALPHA

PAYLOAD_KG = number(0, 100, "kg", lo_open=True)
PAYLOAD_MM = number(-5000, 5000, "mm")


def args_diagnose(p: argparse.ArgumentParser) -> None:
    """The arguments of ``lasercal diagnose``."""
    p.add_argument("session", type=INFOLDER, help="session folder")
    chain_arguments(p, SESSION_ROBOT)
    p.add_argument("--json", action="store_true", help="print one JSON object")
    output_argument(p, "--report", kind="into", metavar="DIR", help="write the plots that make the case")
    p.add_argument(
        "--alpha",
        type=number(0, 1, lo_open=True, hi_open=True),
        default=ALPHA,
        help=f"family-wise significance level (default {ALPHA})",
    )
    bootstrap_arguments(p)
    p.add_argument(
        "--payload",
        type=numbers(4, lambda i: PAYLOAD_KG if i == 0 else PAYLOAD_MM, "KG,X,Y,Z"),
        metavar="KG,X,Y,Z",
        help="mass (kg) and centre of mass at q = 0 (mm) carried by the flange, for the gravity model when "
        "torques are not logged",
    )


def parse_payload(values: tuple | None):
    """(kg, x, y, z) from ``--payload`` -> (kg, (3,) mm), or None."""
    import numpy as np

    return None if values is None else (values[0], np.array(values[1:]))


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
