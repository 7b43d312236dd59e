"""``lasercal import-justin``: DLR's Agile Justin records -> a position session (thin layer)."""

from __future__ import annotations

import argparse

from lasercal.collector.cli.options import INFILE, output_argument


def args_import_justin(p: argparse.ArgumentParser) -> None:
    """The arguments of ``lasercal import-justin``."""
    p.add_argument("measurements", type=INFILE, help="DLR's measurements.csv (joints rad, markers m)")
    output_argument(
        p, "-o", "--output", kind="folder", required=True, help="position session folder to write"
    )
    p.add_argument("--force", action="store_true", help="replace an existing output")


def cmd_import_justin(args) -> int:
    from lasercal.collector.sessions.store import atomic_output
    from lasercal.solver.formats.justin import write_justin_session

    with atomic_output(args.output, folder=True) as tmp:
        m = write_justin_session(args.measurements, tmp)
    print(f"wrote {args.output}: {m} records x 2 hand markers (robot justin, mm in the camera frame)")
    return 0
