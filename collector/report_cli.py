"""``lasercal report`` and ``lasercal export``: thin layers over collector.report and solver.export."""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

from solver.diagnose import diagnose
from solver.errors import FormatError
from solver.export import FORMATS, export
from solver.measurement import fit
from solver.model import load_model
from solver.session import load_session

from .errors import SessionError
from .report import load_validation, write_report


def register(sub: argparse._SubParsersAction) -> None:
    """Add report and export to the ``lasercal`` subcommands."""
    p = sub.add_parser("report", help="an HTML report with plots: calibration, validation before/after, diagnosis")
    p.add_argument("folders", nargs="+", metavar="SESSION",
                   help="one capture session folder (session.yaml) and any number of lasercal validate folders "
                        "(validation.yaml) at one point, shown in the order given (e.g. the nominal model's first)")
    p.add_argument("-o", "--output", required=True, metavar="DIR", help="folder for index.html and its PNG plots")
    p.add_argument("--method", choices=("lm", "thesis"), default="lm", help="identification method (default lm)")
    p.add_argument("--bootstrap", type=int, default=2000, help="diagnosis: first-order bootstrap replicates (default 2000)")
    p.add_argument("--refits", type=int, default=10, help="diagnosis: full simulations with refits (default 10)")
    p.add_argument("--seed", type=int, default=0)
    p.set_defaults(func=cmd_report)

    e = sub.add_parser("export", help="the calibrated model as a URDF, a DH-style table or YAML")
    e.add_argument("model", help="robot model YAML (e.g. written by lasercal solve) or a built-in name")
    e.add_argument("--format", choices=FORMATS, default="urdf", help="urdf (default), dh or yaml")
    e.add_argument("-o", "--output", metavar="FILE", help="write here (default: standard output)")
    e.set_defaults(func=cmd_export)


def cmd_report(args) -> int:
    sessions, validations = [], []
    for f in map(Path, args.folders):
        if (f / "session.yaml").is_file():
            sessions.append(f)
        elif (f / "validation.yaml").is_file():
            validations.append(load_validation(f))
        else:
            raise FormatError(f, "neither a capture session (session.yaml) nor a validation folder (validation.yaml)")
    if len(sessions) != 1:
        raise SessionError(f"report needs exactly one capture session folder (with session.yaml) among its folders, got {len(sessions)}")
    session = load_session(sessions[0])
    if session.measurement != "laser":
        raise FormatError(sessions[0], "the report covers laser sessions (spots on a plane)", field="measurement")
    ident = fit(session, method=args.method)
    d = diagnose(session, n_boot=args.bootstrap, n_refit=args.refits, seed=args.seed)
    index = write_report(args.output, session, ident, d, validations)
    print(f"wrote {index}")
    return 0


def cmd_export(args) -> int:
    text = export(load_model(args.model), args.format)
    if args.output:
        Path(args.output).write_text(text)
        print(f"wrote {args.output}", file=sys.stderr)
    else:
        sys.stdout.write(text)
    return 0
