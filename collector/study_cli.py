"""``lasercal import-mukca`` (and the MUKCa study): real Panda data as point sessions."""
from __future__ import annotations

import argparse

from .mukca import import_mukca


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("import-mukca", help="one point session from a MUKCa robot folder (real Panda socket data)")
    p.add_argument("robot_dir", help="e.g. ../shared/data/mukca/panda_1")
    p.add_argument("-o", "--output", required=True, help="session folder to write")
    p.add_argument("--positions", help="comma-separated tool positions to import (default: all)")
    p.set_defaults(func=cmd_import)


def cmd_import(args) -> int:
    only = [p.strip() for p in args.positions.split(",")] if args.positions else None
    out = import_mukca(args.robot_dir, args.output, only)
    print(f"wrote {out}")
    return 0
