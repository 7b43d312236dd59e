"""``lasercal import-mukca`` and ``lasercal study-mukca``: real Panda data as point sessions, and the study on
them."""

from __future__ import annotations

import argparse
from dataclasses import replace
from pathlib import Path

from lasercal.collector.cli.options import INFOLDER, SEED, count, names_list, output_argument, prior_argument
from lasercal.collector.studies.options import QUICK, ROBOTS, StudyOptions


def args_import_mukca(p: argparse.ArgumentParser) -> None:
    """The arguments of ``lasercal import-mukca``."""
    p.add_argument("robot_dir", type=INFOLDER, help="e.g. ../shared/data/mukca/panda_1")
    output_argument(p, "-o", "--output", kind="folder", required=True, help="session folder to write")
    p.add_argument(
        "--positions", type=names_list, help="comma-separated tool positions to import (default: all)"
    )
    p.add_argument("--force", action="store_true", help="replace an existing output")


def args_study_mukca(p: argparse.ArgumentParser) -> None:
    """The arguments of ``lasercal study-mukca``."""
    p.add_argument(
        "data_dir",
        type=INFOLDER,
        help="folder holding panda_1 ... (and panda_k_clean), e.g. ../shared/data/mukca",
    )
    output_argument(
        p,
        "-o",
        "--output",
        kind="folder",
        required=True,
        help="report folder (report.json, report.md, PNG plots, sessions/)",
    )
    p.add_argument(
        "--robots",
        type=names_list,
        default=",".join(ROBOTS),
        help=f"comma-separated robot folders (default {','.join(ROBOTS)})",
    )
    p.add_argument(
        "--bootstrap",
        type=count(1, 10**6),
        help=f"simulated replicates (default {StudyOptions.bootstrap}; --quick {QUICK.bootstrap})",
    )
    p.add_argument(
        "--quick",
        action="store_true",
        help=f"{QUICK.bootstrap} replicates and {QUICK.refits} full refits instead of "
        f"{StudyOptions.bootstrap} and {StudyOptions.refits}",
    )
    p.add_argument("--seed", type=SEED, default=0)
    prior_argument(p)
    p.add_argument(
        "--jobs",
        type=count(0, 256),
        default=0,
        help="robots studied at once, one process each (default 0: one per CPU core)",
    )
    p.add_argument("--force", action="store_true", help="replace an existing output")


def cmd_import(args) -> int:
    from lasercal.collector.sessions.store import atomic_output
    from lasercal.solver.formats.mukca import import_mukca

    only = list(args.positions) if args.positions else None
    with atomic_output(args.output, folder=True) as tmp:
        import_mukca(args.robot_dir, tmp, only)
    print(f"wrote {args.output}")
    return 0


def cmd_study(args) -> int:
    from lasercal.collector.sessions.store import atomic_output
    from lasercal.collector.studies.mukca import run_study
    from lasercal.solver.errors import LasercalError

    opts = replace(QUICK if args.quick else StudyOptions(), seed=args.seed, jobs=args.jobs, prior=args.prior)
    if args.bootstrap is not None:
        opts = replace(opts, bootstrap=args.bootstrap)
    robots = list(args.robots)
    missing = [r for r in robots if not (Path(args.data_dir) / r).is_dir()]
    if missing:
        raise LasercalError(f"--robots: no folder {missing[0]} in {args.data_dir}")
    with atomic_output(args.output, folder=True) as tmp:
        rep = run_study(args.data_dir, tmp, robots, opts)
    print(
        f"{'robot':10} {'held-out spread RMS, nominal -> geometric -> extended (mm)':60} finding (whole "
        "session)"
    )
    for r, x in rep["robots"].items():
        t, dg = x["calibration"]["test"], x["diagnosis"]
        spreads = " -> ".join(f"{t[m]['spread_rms_mm']:.3f}" for m in ("nominal", "geometric", "nested"))
        print(
            f"{r:10} {spreads:60} {dg['effect']} {','.join(map(str, dg['joints']))} (p = {dg['p_value']:.2g})"
        )
    for f in rep["files"]:
        print(f"wrote {args.output}/{f}")
    print(f"study time {rep['seconds']:.1f} s")
    return 0
