"""The ``lasercal`` command: one program, subcommands registered by each package.

A thin layer: every subcommand calls library functions that tests call directly. Any
:class:`~solver.errors.LasercalError` (or ``vision``'s ``VisionError``) becomes a one-line
message and exit code 2, never a traceback.
"""
from __future__ import annotations

import argparse
import importlib
import sys

from solver.errors import LasercalError

# Packages whose ``cli.register(subparsers)`` adds subcommands, in help order.
_REGISTRARS = ("collector.demo_cli", "collector.report_cli", "solver.cli", "collector.capture_cli", "solver.diagnose_cli", "collector.study_cli", "solver.fullpose_cli", "vision.cli")


def _user_errors() -> tuple:
    errs = [LasercalError]
    try:
        from vision.errors import VisionError
    except ImportError:
        pass
    else:
        errs.append(VisionError)
    return tuple(errs)


def build_parser() -> argparse.ArgumentParser:
    """The argument parser with every package's subcommands."""
    parser = argparse.ArgumentParser(prog="lasercal", description="Kinematic calibration of a serial arm with a laser pointer, a table of reference points and a camera.")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    sub.required = True
    for name in _REGISTRARS:
        try:
            mod = importlib.import_module(name)
        except ModuleNotFoundError as e:
            if e.name != name:
                raise
            continue
        mod.register(sub)
    return parser


def main(argv=None) -> int:
    """Run ``lasercal``; returns the exit code (0 ok, 2 bad input or nothing measured)."""
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return int(args.func(args) or 0)
    except _user_errors() as e:
        print(f"lasercal: error: {e}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("lasercal: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
