"""``lasercal capture``: a thin layer over :mod:`sessions.settings` and :mod:`sessions.start`."""

from __future__ import annotations

import argparse
import sys

from lasercal.collector.cli.options import (
    INFOLDER,
    LAYOUT,
    backend_arguments,
    count,
    motion_arguments,
    number,
    output_argument,
    photo_arguments,
    photo_options_used,
    resume_or_another,
    unused,
    view_arguments,
    view_options,
)
from lasercal.collector.errors import InputEnded
from lasercal.solver.formats.checks import METRES_BELOW_MM


def _session_arguments(p: argparse.ArgumentParser) -> None:
    """The session's layout, folder and laser: --layout, --per-point, -o, --resume, --aperture-z.

    Parameters
    ----------
    p : argparse.ArgumentParser
        ``lasercal capture``'s parser (added to).
    """
    p.add_argument("--layout", type=LAYOUT, help="layout YAML with the reference points")
    p.add_argument(
        "--per-point", type=count(1, 10000), metavar="N", help="captures at each calibration point"
    )
    output_argument(
        p,
        "-o",
        "--output",
        kind="folder",
        instead=resume_or_another(
            "capture", "session.yaml", "a capture session", {"validation.yaml": "a validation run"}
        ),
        metavar="SESSION",
        help="new session folder",
    )
    p.add_argument(
        "--resume",
        type=INFOLDER,
        metavar="SESSION",
        help="continue an interrupted session where it stopped",
    )
    p.add_argument(
        "--aperture-z",
        type=number(METRES_BELOW_MM, 5000, "mm"),
        metavar="MM",
        help="measured height of the laser aperture at q = 0, mm (p_Mz)",
    )


def _rangefinder_arguments(p: argparse.ArgumentParser) -> None:
    """The laser rangefinder: --rangefinder, --rangefinder-query.

    Parameters as :func:`_session_arguments`'s: the parser, added to.
    """
    p.add_argument(
        "--rangefinder",
        metavar="URL",
        help="serial laser rangefinder (pyserial URL; 'fake' with --backend fake): log the laser length",
    )
    p.add_argument(
        "--rangefinder-query",
        metavar="TEXT",
        help="sent before each reading (e.g. 'D\\n'); default: the device streams",
    )


def _simulated_operator_arguments(p: argparse.ArgumentParser) -> None:
    """The simulated operator: --auto, --auto-pace, --aim-noise.

    Parameters as :func:`_session_arguments`'s: the parser, added to.
    """
    p.add_argument(
        "--auto",
        action="store_true",
        help="the fake and MuJoCo backends (--backend fake, --backend mujoco): the simulated operator aims "
        "and triggers by itself (no keyboard), and discards the captures the check flags",
    )
    p.add_argument(
        "--auto-pace",
        type=number(0, 60, "s"),
        metavar="S",
        help="with --auto: real seconds per capture, to watch (default 0)",
    )
    p.add_argument(
        "--aim-noise",
        type=number(0, 100, "mm"),
        metavar="MM",
        help="fake backend: aiming noise per in-plane axis, mm (default 1.0)",
    )


def _camera_arguments(p: argparse.ArgumentParser) -> None:
    """The camera and what it photographs: --camera, --aim, --effects.

    Parameters as :func:`_session_arguments`'s: the parser, added to.
    """
    p.add_argument(
        "--camera",
        help="photograph each capture and measure its spot on the sheet through the sheet's markers: fake "
        "(the simulated world; off --backend fake: the nominal model's beam at the angles the robot "
        "reports), "
        "or an OpenCV device: index, URL or frames/%%04d.png (the layout needs markers)",
    )
    p.add_argument(
        "--aim",
        choices=("anywhere", "cross"),
        help="with --camera: anywhere (the default with the coach on a sheet lasercal sheet printed): the "
        "coach plans each spot anywhere on the sheet's white paper, for what the fit lacks; cross: beside "
        "each cross",
    )
    p.add_argument(
        "--effects",
        metavar="LIST",
        help="fake backend: the simulated world's effects, all, none or a comma list of "
        "repeatability, distortion, occlusion, ellipse, print-scale, sheet-height (default: all with "
        "--camera fake, none without; docs/sessions.md)",
    )


def _coach_arguments(p: argparse.ArgumentParser) -> None:
    """The coach: --until, --no-coach, --guide.

    Parameters as :func:`_session_arguments`'s: the parser, added to.
    """
    p.add_argument(
        "--until",
        type=number(0, 1e4, "mm", lo_open=True),
        metavar="MM",
        help="stop once the coach predicts at most this error at the validation points, mm",
    )
    p.add_argument(
        "--no-coach",
        action="store_true",
        help="no status block, suggested poses or stopping rule after each capture",
    )
    p.add_argument(
        "--plan-effects",
        action="store_true",
        default=None,
        help="the coach also plans poses that tell the joint compliances the diagnosis tests from the "
        "geometry and the sheet (docs/diagnosis.md); its promise stays the geometry's",
    )
    p.add_argument(
        "--guide",
        choices=("hand", "move"),
        default="hand",
        help="hand (default): the operator guides the arm to each suggested pose; move: a backend that "
        "can move takes the arm there first (preview and confirmation before the first move), the "
        "operator only refines the aim",
    )


def args_capture(p: argparse.ArgumentParser) -> None:
    """The arguments of ``lasercal capture``."""
    _session_arguments(p)
    _rangefinder_arguments(p)
    _simulated_operator_arguments(p)
    _camera_arguments(p)
    _coach_arguments(p)
    motion_arguments(p, "with --guide move: ")
    photo_arguments(p)
    view_arguments(p)
    backend_arguments(p)


def cmd_capture(args) -> int:
    from lasercal.collector.sessions.settings import capture_settings, given_settings
    from lasercal.collector.sessions.start import CaptureGuide, start_capture

    if not args.auto:
        unused(args, "it paces --auto", "auto_pace")
    if args.guide != "move":
        unused(args, "only --guide move commands moves", "max_step", "yes")
    settings = capture_settings(given_settings(vars(args)), args.layout, args.output, args.resume)
    photo_options_used(args, settings.cfg.get("camera"))
    guide = CaptureGuide(
        auto=args.auto,
        auto_pace=args.auto_pace or 0.0,
        move=args.guide == "move",
        coach=not args.no_coach,
        until_mm=args.until,
        yes=args.yes,
        max_step=args.max_step,
    )
    started = start_capture(settings, guide)
    if settings.resume:
        store = started.store
        if store.recovered:
            print(
                f"cut off a torn last line ({store.recovered} bytes): the capture in flight when the session "
                "stopped"
            )
        print(f"resuming {store.folder}: {len(store.point)} captures on disk")
    before = len(started.store.point)
    try:
        started.run(sys.stdout, view_options(args, settings.cfg))
    except InputEnded as e:
        return input_ended(started, before, e)
    return 0


def input_ended(started, before: int, e) -> int:
    """The trigger's standard input ended mid-session: a stop, not an operator's quit. Every capture stays
    on disk, resumable (exit 1: the session is short); none at all (exit 2): a new session, still empty,
    is not kept, a resumed one is."""
    from lasercal.solver.errors import LasercalError

    store = started.store
    taken = len(store.point) - before
    if not store.point and not started.settings.resume:
        store.remove_empty()
        raise LasercalError(f"{e}: nothing captured, and the new session {store.folder} is not kept")
    k = len(store.point)
    kept = f"{k} capture{'' if k == 1 else 's'} in {store.path}; resume with: {started.hint}"
    if not taken:
        raise LasercalError(f"{e}: nothing captured this run; {kept}")
    print(f"lasercal: warning: stopped: {e}; {kept}", file=sys.stderr)
    return 1
