"""``lasercal import-mukca`` and ``lasercal study-mukca``: real Panda data as point sessions, and the study on
them."""

from __future__ import annotations

import argparse
from dataclasses import replace

from lasercal.collector.studies.mukca import QUICK, ROBOTS, StudyOptions


def args_import_mukca(p: argparse.ArgumentParser) -> None:
    """The arguments of ``lasercal import-mukca``."""
    p.add_argument("robot_dir", help="e.g. ../shared/data/mukca/panda_1")
    p.add_argument("-o", "--output", required=True, help="session folder to write")
    p.add_argument("--positions", help="comma-separated tool positions to import (default: all)")


def args_study_mukca(p: argparse.ArgumentParser) -> None:
    """The arguments of ``lasercal study-mukca``."""
    p.add_argument(
        "data_dir", help="folder holding panda_1 ... (and panda_k_clean), e.g. ../shared/data/mukca"
    )
    p.add_argument(
        "-o", "--output", required=True, help="report folder (report.json, report.md, PNG plots, sessions/)"
    )
    p.add_argument(
        "--robots",
        default=",".join(ROBOTS),
        help=f"comma-separated robot folders (default {','.join(ROBOTS)})",
    )
    p.add_argument(
        "--bootstrap",
        type=int,
        help=f"simulated replicates (default {StudyOptions.bootstrap}; --quick {QUICK.bootstrap})",
    )
    p.add_argument(
        "--quick",
        action="store_true",
        help=f"{QUICK.bootstrap} replicates and {QUICK.refits} full refits instead of "
        f"{StudyOptions.bootstrap} and {StudyOptions.refits}",
    )
    p.add_argument("--seed", type=int, default=0)


def cmd_import(args) -> int:
    from lasercal.collector.studies.mukca_import import import_mukca

    only = [p.strip() for p in args.positions.split(",")] if args.positions else None
    out = import_mukca(args.robot_dir, args.output, only)
    print(f"wrote {out}")
    return 0


def cmd_study(args) -> int:
    from lasercal.collector.studies.mukca import run_study

    opts = replace(QUICK if args.quick else StudyOptions(), seed=args.seed)
    if args.bootstrap is not None:
        opts = replace(opts, bootstrap=args.bootstrap)
    robots = [r.strip() for r in args.robots.split(",") if r.strip()]
    rep = run_study(args.data_dir, args.output, robots, opts)
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
