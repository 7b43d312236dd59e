"""Command-line option types that check range and units (through :class:`solver.formats.checks.Range`).

``type=number(0, None, "s", lo_open=True)`` makes argparse refuse ``--hold -1`` with one line
naming the option: ``argument --hold: -1 s is out of range (expected a finite number > 0 s)``.
"""

from __future__ import annotations

import argparse

from lasercal.solver.formats.checks import Range


def number(
    lo: float | None = None,
    hi: float | None = None,
    unit: str = "",
    *,
    lo_open: bool = False,
    hi_open: bool = False,
    integer: bool = False,
):
    """An argparse ``type`` accepting finite numbers in [lo, hi] (open ends as asked), in ``unit``."""
    rng = Range(lo, hi, unit, lo_open, hi_open, integer)

    def parse(text: str):
        try:
            return rng.parse(text)
        except ValueError as e:
            raise argparse.ArgumentTypeError(str(e)) from None

    parse.__name__ = rng.expected()  # argparse names the type in some messages
    return parse


def count(lo: int = 0, hi: int | None = None):
    """An argparse ``type`` for whole numbers in [lo, hi]."""
    return number(lo, hi, integer=True)


SEED = count(0, 2**32 - 1)
"""A random seed: numpy accepts 0 .. 2**32 - 1."""


def _folds(text: str) -> int:
    """K of a K-fold cross-validation: 0 (none) or 2 .. 1000."""
    k = count(0, 1000)(text)
    if k == 1:
        raise argparse.ArgumentTypeError("1 fold holds nothing out (expected 0 for none, or at least 2)")
    return k


FOLDS = _folds


def chain_arguments(p: argparse.ArgumentParser, robot_help: str | None = None) -> None:
    """``--base-link`` and ``--tip-link`` (a URDF chain's ends), and ``--robot`` when ``robot_help``."""
    if robot_help:
        p.add_argument("--robot", metavar="ROBOT", help=robot_help)
    p.add_argument(
        "--base-link", metavar="LINK", help="URDF robot: the chain's first link (default: the root)"
    )
    p.add_argument(
        "--tip-link",
        metavar="LINK",
        help="URDF robot: the chain's last link (needed when the tree branches; default: the deepest leaf)",
    )


SESSION_ROBOT = (
    "robot in place of the session's 'robot' (built-in name, model YAML or URDF, a path from the working "
    "folder); the session's base_link and tip_link then do not apply"
)


def session_robot(args) -> dict:
    """The keyword arguments of :func:`solver.formats.session.load_session` from :func:`chain_arguments`."""
    return {"robot": args.robot, "base_link": args.base_link, "tip_link": args.tip_link}


def bootstrap_arguments(p: argparse.ArgumentParser) -> None:
    """The diagnosis's simulation options, shared by ``diagnose`` and ``report``."""
    p.add_argument(
        "--bootstrap",
        type=count(0, 10**6),
        default=2000,
        help="diagnosis: first-order parametric-bootstrap replicates (default 2000; 0 skips)",
    )
    p.add_argument(
        "--refits",
        type=count(0, 10**4),
        default=10,
        help="diagnosis: full simulations of the experiment with refits (default 10)",
    )
    p.add_argument("--seed", type=SEED, default=0)
