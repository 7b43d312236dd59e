"""``lasercal capture`` and ``lasercal validate``: thin layers over the sessions."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import TYPE_CHECKING

from lasercal.collector.cli.options import count, number
from lasercal.collector.sessions.motion import MAX_STEP, MAX_STEP_RANGE
from lasercal.solver.formats.checks import METRES_BELOW_MM
from lasercal.solver.formats.data import builtin_dir

THESIS_LAYOUT = builtin_dir("layouts") / "thesis.yaml"
DEFAULTS = {
    "robot": "panda",
    "trigger": "enter",
    "truth": "panda_thesis_identified",
    "aim_noise": 1.0,
    "seed": 0,
    "speed_threshold": 0.005,
    "hold": 0.5,
    "dynamics": 0.1,
    "ros_port": 9090,
}
# Settings a resumed session must keep: they decide what its captures mean.
FIXED = ("backend", "robot", "per_point", "truth", "perturb_seed", "aim_noise", "seed", "rangefinder")
SETTINGS = FIXED + (
    "speed_threshold",
    "hold",
    "trigger",
    "host",
    "dynamics",
    "desk_user",
    "ros_port",
    "ros_joints",
    "rangefinder_query",
    "aperture_z",
)

if TYPE_CHECKING:  # annotations only: the modules load when a command runs
    from lasercal.solver.formats.session import Layout


def _backend_options(p: argparse.ArgumentParser) -> None:
    """Options shared by capture and validate (None = not given, so a resume can tell)."""
    from lasercal.collector.cli.options import SEED
    from lasercal.collector.hardware import BACKENDS

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


def _motion_options(p: argparse.ArgumentParser, when: str = "") -> None:
    """``--yes`` and ``--max-step`` of the commands that move the arm (the bound of sessions.motion)."""
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


def args_capture(p: argparse.ArgumentParser) -> None:
    """The arguments of ``lasercal capture``."""
    p.add_argument("--layout", help="layout YAML with the reference points")
    p.add_argument(
        "--per-point", type=count(1, 10000), metavar="N", help="captures at each calibration point"
    )
    p.add_argument("-o", "--output", metavar="SESSION", help="new session folder")
    p.add_argument("--resume", metavar="SESSION", help="continue an interrupted session where it stopped")
    p.add_argument(
        "--aperture-z",
        type=number(METRES_BELOW_MM, 5000, "mm"),
        metavar="MM",
        help="measured height of the laser aperture at q = 0, mm (p_Mz)",
    )
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
    p.add_argument(
        "--auto", action="store_true", help="fake backend: the simulated operator triggers too (no keyboard)"
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
        "--guide",
        choices=("hand", "move"),
        default="hand",
        help="hand (default): the operator guides the arm to each suggested pose; move: a backend that "
        "can move takes the arm there first (preview and confirmation before the first move), the "
        "operator only refines the aim",
    )
    _motion_options(p, "with --guide move: ")
    _backend_options(p)


def args_validate(p: argparse.ArgumentParser) -> None:
    """The arguments of ``lasercal validate``."""
    p.add_argument("model", nargs="?", help="robot model YAML under test (nominal or identified)")
    p.add_argument("--point", help="validation point (default: the layout's first validation point)")
    p.add_argument("-n", type=count(1, 10000), default=60, help="configurations (default 60)")
    p.add_argument(
        "-o", "--output", metavar="DIR", help="new folder: validation.yaml, validation.csv, photos/"
    )
    p.add_argument(
        "--resume", metavar="DIR", help="continue an interrupted validation run (its settings are kept)"
    )
    p.add_argument(
        "--layout",
        help="layout YAML (required for a real robot; default with --backend fake: the thesis layout)",
    )
    _motion_options(p)
    p.add_argument(
        "--camera",
        help="fake, or an OpenCV device: index, URL or frames/%%04d.png (default: fake with --backend fake)",
    )
    p.add_argument(
        "--guide",
        action="store_true",
        help="guide the operator to each configuration even where the backend can move",
    )
    _backend_options(p)


def _settings(args) -> dict:
    return {k: getattr(args, k) for k in SETTINGS if getattr(args, k, None) is not None}


def _capture_settings(args) -> tuple[dict, Layout]:
    """The settings and layout of a new session (command line) or a resumed one (its session.yaml + command
    line)."""
    from lasercal.collector.errors import SessionError
    from lasercal.collector.sessions.store import check_output
    from lasercal.solver.formats.robots import load_yaml
    from lasercal.solver.formats.session import load_layout, session_layout

    given = _settings(args)
    for key in ("per_point", "aim_noise"):
        if getattr(args, key) is not None:
            given[key] = getattr(args, key)
    if not args.resume:
        missing = [
            f
            for f, v in (
                ("--layout", args.layout),
                ("--per-point", args.per_point),
                ("-o", args.output),
                ("--backend", args.backend),
            )
            if v is None
        ]
        if missing:
            raise SessionError(f"a new session needs {', '.join(missing)} (or --resume SESSION)")
        check_output(args.output, folder=True, instead=f"resume it with --resume {args.output}")
        return {**DEFAULTS, **given}, load_layout(args.layout)
    if args.output or args.layout:
        raise SessionError("--resume SESSION continues that folder with its own layout: drop --layout and -o")
    folder = Path(args.resume)
    if not (folder / "session.yaml").is_file():
        raise SessionError(f"{folder} is not a session folder (no session.yaml): nothing to resume")
    meta = load_yaml(folder / "session.yaml")
    stored = meta.get("collector") if isinstance(meta, dict) else None
    if not stored:
        raise SessionError(f"{folder} was not started by lasercal capture: nothing to resume")
    for k in FIXED:
        if k in given and given[k] != stored.get(k):
            raise SessionError(
                f"{folder} was started with {k.replace('_', '-')} {stored.get(k)}: it cannot change on resume"
            )
    return {**DEFAULTS, **stored, **given}, session_layout(meta, folder / "session.yaml")


def cmd_capture(args) -> int:

    from lasercal.collector.hardware import make_rangefinder, make_robot
    from lasercal.collector.hardware.triggers import AutoTrigger, make_trigger
    from lasercal.collector.sessions.capture import CaptureOptions, new_session, run_capture, session_coach
    from lasercal.collector.sessions.motion import confirmable
    from lasercal.collector.sessions.store import CaptureStore
    from lasercal.solver.errors import LasercalError
    from lasercal.solver.formats.robots import load_model

    cfg, layout = _capture_settings(args)
    if args.auto and cfg["backend"] != "fake":
        raise LasercalError("--auto needs --backend fake (only the simulated operator can trigger by itself)")
    nominal = load_model(cfg["robot"])
    robot = make_robot(cfg, nominal, layout, cfg["per_point"])
    rangefinder = make_rangefinder(cfg, robot, layout.plane_z)
    trigger = AutoTrigger(args.auto_pace or 0.0) if args.auto else make_trigger(cfg["trigger"], robot)
    move = args.guide == "move"
    if move:  # refused before the session folder exists
        if args.no_coach:
            raise LasercalError("--guide move moves the arm to the coach's suggestions: drop --no-coach")
        if not robot.can_move:
            raise LasercalError(
                f"--guide move: the {robot.name} backend cannot move the arm (use --guide hand)"
            )
        if cfg["backend"] != "fake":
            confirmable(args.yes, what="to the suggested poses ")
    if args.resume:  # devices first, folder last: a device that fails leaves nothing to clean up
        store = CaptureStore.open(args.resume)
        if store.recovered:
            print(
                f"cut off a torn last line ({store.recovered} bytes): the capture in flight when the session "
                "stopped"
            )
        print(f"resuming {store.folder}: {len(store.point)} captures on disk")
    else:
        store = new_session(args.output, cfg, layout, Path(args.layout), robot, nominal, rangefinder)
    opts = CaptureOptions(
        cfg["per_point"],
        cfg["speed_threshold"],
        cfg["hold"],
        auto_discard=args.auto,
        until_mm=args.until,
        move=move,
        yes=args.yes,
        max_step=args.max_step,
    )
    hint = (
        f"lasercal capture --resume {store.folder}"
        + (" --auto" if args.auto else "")
        + (" --guide move" if move else "")
    )
    coach = None if args.no_coach else session_coach(store, nominal, layout, cfg)
    try:
        real = cfg["backend"] != "fake"
        run_capture(store, robot, trigger, nominal, opts, sys.stdout, rangefinder, hint, coach, real)
    finally:
        store.close()
        trigger.close()
        if rangefinder is not None:
            rangefinder.close()
    return 0


def _validate_settings(args) -> tuple[dict, dict]:
    """The settings of a new validation run (command line) or a resumed one (its validation.yaml)."""
    from lasercal.collector.errors import SessionError
    from lasercal.collector.sessions.store import check_output
    from lasercal.solver.errors import FormatError
    from lasercal.solver.formats.data import resolve
    from lasercal.solver.formats.robots import load_yaml

    if args.resume is None:
        missing = [
            f for f, v in (("MODEL", args.model), ("-o", args.output), ("--backend", args.backend)) if not v
        ]
        if missing:
            raise SessionError(f"validate needs {', '.join(missing)} (or --resume DIR)")
        if args.layout is None and args.backend != "fake":
            raise SessionError(
                f"--layout: a real robot (--backend {args.backend}) needs the layout of the points on your "
                "table (there is no default for real robots)"
            )
        check_output(args.output, folder=True, instead=f"resume it with --resume {args.output}")
        run = {
            "model": str(resolve("robots", args.model).resolve()),
            "layout": str(resolve("layouts", args.layout).resolve()) if args.layout else str(THESIS_LAYOUT),
            "point": args.point,
            "n": args.n,
            "camera": args.camera,
            "guide": args.guide,
            "max_step": args.max_step,
        }
        return {**DEFAULTS, **_settings(args), "backend": args.backend}, run
    if args.output or args.model or args.layout or args.point:
        raise SessionError("--resume DIR continues that run with its own model, layout and point: drop them")
    folder = Path(args.resume)
    if not (folder / "validation.yaml").is_file():
        raise SessionError(
            f"--resume {folder}: not a validation folder (no validation.yaml): nothing to resume"
        )
    meta = load_yaml(folder / "validation.yaml")
    stored = meta.get("collector") if isinstance(meta, dict) else None
    if not isinstance(stored, dict) or "settings" not in stored:
        raise FormatError(folder / "validation.yaml", "written without resume settings", field="collector")
    given = _settings(args)
    for k in FIXED:
        if k in given and given[k] != stored["settings"].get(k):
            raise SessionError(
                f"--resume {folder}: started with {k.replace('_', '-')} {stored['settings'].get(k)}"
            )
    return {**DEFAULTS, **stored["settings"], **given}, stored["run"]


def cmd_validate(args) -> int:
    from lasercal.collector.hardware import make_robot
    from lasercal.collector.hardware.triggers import AutoTrigger, make_trigger
    from lasercal.collector.sessions.validate import (
        ValidateOptions,
        check_layout,
        make_camera,
        run_validation,
        validation_point,
    )
    from lasercal.solver.analysis.stats import spot_stats
    from lasercal.solver.formats.robots import load_model
    from lasercal.solver.formats.session import load_layout

    cfg, run = _validate_settings(args)
    layout = load_layout(run["layout"])
    point = validation_point(layout, run["point"])
    model = load_model(run["model"])
    check_layout(layout, model, run["model"], point)
    robot = make_robot(cfg, load_model(cfg["robot"]), layout)
    camera, measure = make_camera(run["camera"], cfg, robot, layout, point, run["layout"])
    trigger = None
    if run["guide"] or not robot.can_move:
        trigger = AutoTrigger() if cfg["backend"] == "fake" else make_trigger(cfg["trigger"], robot)
    opts = ValidateOptions(
        run["n"],
        cfg["seed"],
        run["guide"],
        cfg["speed_threshold"],
        cfg["hold"],
        yes=args.yes,
        max_step=run["max_step"],
    )
    folder = args.resume or args.output
    res = run_validation(
        folder,
        model,
        str(run["model"]),
        layout,
        point,
        robot,
        camera,
        opts,
        trigger,
        measure,
        out=sys.stdout,
        meta_extra={"collector": {"settings": cfg, "run": run}},
        resume=args.resume is not None,
        confirm_moves=cfg["backend"] != "fake",
    )
    print(f"wrote {res.path} ({res.photos} photos this run; {res.summary()})")
    if not res.complete:
        print(f"continue with: lasercal validate --resume {folder}")
    if len(res.spots) > 1:
        s = spot_stats(res.spots, layout.points[point])
        print(
            f"{point}: {s.n} spots measured: scatter mean {s.scatter_mean:.3f} mm (std {s.scatter_std:.3f}), "
            f"error mean {s.error_mean:.3f} mm (max {s.error_max:.3f})"
        )
    elif res.spots.size == 0 and res.photos:
        print(
            f"measure the photos with: lasercal spots {res.path.parent}/photos/*.png --layout "
            "LAYOUT_WITH_MARKERS.yaml"
        )
    return 0
