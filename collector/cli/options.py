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
    """``--base-link`` and ``--tip-link`` (a URDF chain's ends), and ``--robot`` when ``robot_help``; a
    session's robot (``SESSION_ROBOT``) comes with ``--prior``, the prior of its fits."""
    if robot_help:
        p.add_argument("--robot", metavar="ROBOT", help=robot_help)
    if robot_help is SESSION_ROBOT:
        prior_argument(p)
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
    return {"robot": args.robot, "base_link": args.base_link, "tip_link": args.tip_link, "prior": args.prior}


def prior_argument(p: argparse.ArgumentParser) -> None:
    """``--prior``: the prior of every fit (docs/formats.md, "Priors")."""
    p.add_argument(
        "--prior",
        metavar="none|FILE",
        help="the prior of every fit: the robot's manufacturing tolerances (default), a lasercal-prior/1 "
        "YAML overriding some of them, or 'none' for plain least squares (the thesis's comparisons)",
    )


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


def backend_arguments(p: argparse.ArgumentParser) -> None:
    """Options shared by capture and validate (None = not given, so a resume can tell)."""
    from lasercal.collector.hardware import BACKENDS  # here: the commands without a robot skip its import

    g = p.add_argument_group("robot backend")
    g.add_argument("--backend", choices=BACKENDS, help="fake (simulated Panda), franky, panda-py or ros")
    g.add_argument("--robot", help="nominal robot model: name under data/robots/ or YAML (default panda)")
    g.add_argument("--host", help="robot FCI address (franky, panda-py) or rosbridge host (ros)")
    g.add_argument(
        "--dynamics",
        type=number(0, 0.3, lo_open=True),
        metavar="F",
        help="franky/panda-py: speed of commanded moves, fraction of the limits, in (0, 0.3] (default 0.1)",
    )
    g.add_argument(
        "--desk-user",
        metavar="USER",
        help="Desk user for --trigger pilot (password in $LASERCAL_DESK_PASSWORD)",
    )
    g.add_argument("--ros-port", type=count(1, 65535), metavar="PORT", help="rosbridge port (default 9090)")
    g.add_argument(
        "--ros-joints",
        metavar="NAMES",
        help="comma-separated arm joint names in /joint_states (default: found by name)",
    )
    g.add_argument(
        "--trigger",
        metavar="enter|serial:URL|pilot",
        help="enter (default), serial:URL (button box / foot pedal, pyserial URL) or pilot",
    )
    f = p.add_argument_group("fake backend")
    f.add_argument(
        "--truth",
        metavar="ROBOT.yaml",
        help="the fake robot's true geometry: robot YAML or name (default panda_thesis_identified)",
    )
    f.add_argument(
        "--perturb-seed",
        type=SEED,
        metavar="S",
        help="instead of --truth: a seeded random perturbation of the nominal robot",
    )
    f.add_argument("--seed", type=SEED, metavar="S", help="seed of the simulation (default 0)")
    s = p.add_argument_group("standstill")
    s.add_argument(
        "--speed-threshold",
        type=number(0, 1, "rad/s", lo_open=True),
        metavar="RAD_S",
        help="the arm is still when every joint is slower (default 0.005)",
    )
    s.add_argument(
        "--hold", type=number(0, 60, "s", lo_open=True), metavar="S", help="... for this long (default 0.5)"
    )


def motion_arguments(p: argparse.ArgumentParser, when: str = "") -> None:
    """``--yes`` and ``--max-step`` of the commands that move the arm (the bound of sessions.motion)."""
    from lasercal.collector.sessions.motion import MAX_STEP, MAX_STEP_RANGE  # as BACKENDS above

    p.add_argument(
        "--yes",
        action="store_true",
        help=f"{when}confirm the arm's moves in advance (scripts; else type yes)",
    )
    r = MAX_STEP_RANGE
    p.add_argument(
        "--max-step",
        type=number(r.lo, r.hi, r.unit, lo_open=r.lo_open, hi_open=r.hi_open),
        default=MAX_STEP,
        metavar="RAD",
        help=f"{when}largest joint change of one commanded move; larger moves are split (default {MAX_STEP})",
    )
