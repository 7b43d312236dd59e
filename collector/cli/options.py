"""The one validation layer of the command line: every option declares what it accepts here.

* Numbers: ``type=number(0, None, "s", lo_open=True)`` makes argparse refuse ``--hold -1`` (and NaN,
  inf, text) with one line naming the option: ``argument --hold: -1 s is out of range (expected a
  finite number > 0 s)`` (through :class:`solver.formats.checks.Range`); ``metres=True`` names a mm
  value below a few mm as metres.
* Input paths: ``type=existing("file")`` (or ``"folder"``, or a built-in ``names="robots"``) refuses a
  missing path, or a folder where a file is expected and the other way round, naming the option.
* Output paths: :func:`output_argument` declares ``-o``, ``--overlay``, ``--report`` ... with their kind
  (a new file, a new folder, or a folder written into); :func:`check_outputs` checks them all
  (:func:`collector.sessions.store.check_output`) before the handler does any work.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from lasercal.solver.formats.checks import METRES_BELOW_MM, Range


def number(
    lo: float | None = None,
    hi: float | None = None,
    unit: str = "",
    *,
    lo_open: bool = False,
    hi_open: bool = False,
    integer: bool = False,
    metres: bool = False,
):
    """An argparse ``type`` accepting finite numbers in [lo, hi] (open ends as asked), in ``unit``.

    ``metres``: a length in mm whose size is below :data:`METRES_BELOW_MM` (but not 0) is refused as
    metres. The returned function carries the :class:`Range` as ``.range`` (the tests read it).
    """
    rng = Range(lo, hi, unit, lo_open, hi_open, integer)
    expected = rng.expected()
    if integer and lo is not None and hi is not None:  # whole bounds in full, not 4.29497e+09
        lb, rb = "(" if lo_open else "[", ")" if hi_open else "]"
        expected = f"a whole number in {lb}{int(lo)}, {int(hi)}{rb} {unit}".rstrip()

    def parse(text: str):
        try:
            v = rng.parse(text)
        except ValueError as e:
            said = str(e).replace(rng.expected(), expected)
            if integer:  # nan, inf: not a whole number, as 1.5 is not
                said = said.replace("is not finite (", "is not a whole number (")
            raise argparse.ArgumentTypeError(said) from None
        if metres and 0 < abs(v) < METRES_BELOW_MM:
            raise argparse.ArgumentTypeError(
                f"{v:g} mm is below {METRES_BELOW_MM:g} mm: this looks like metres (expected mm)"
            )
        return v

    parse.__name__ = expected  # argparse names the type in some messages
    parse.range = rng
    return parse


def count(lo: int = 0, hi: int | None = None):
    """An argparse ``type`` for whole numbers in [lo, hi]."""
    return number(lo, hi, integer=True)


def numbers(k: int, rng_of, what: str):
    """An argparse ``type`` for ``k`` comma-separated numbers (e.g. ``KG,X,Y,Z``), each checked by the
    ``number`` type ``rng_of(i)``; returns a tuple of floats."""

    def parse(text: str):
        cells = [c.strip() for c in str(text).split(",")]
        if len(cells) != k:
            raise argparse.ArgumentTypeError(f"{text!r}: expected {k} comma-separated numbers {what}")
        return tuple(rng_of(i)(c) for i, c in enumerate(cells))

    parse.__name__ = what
    return parse


def whole_numbers(lo: int, hi: int):
    """An argparse ``type`` for a comma-separated list of whole numbers in [lo, hi] (e.g. joints 2,4)."""
    one = count(lo, hi)

    def parse(text: str):
        cells = [c.strip() for c in str(text).split(",")]
        if not all(cells):
            raise argparse.ArgumentTypeError(f"{text!r}: expected comma-separated whole numbers")
        return tuple(one(c) for c in cells)

    parse.__name__ = f"whole numbers in [{lo}, {hi}]"
    return parse


def name(text: str) -> str:
    """An argparse ``type`` for one name (not blank; spaces around it dropped)."""
    if not str(text).strip():
        raise argparse.ArgumentTypeError(f"{text!r} names nothing (expected a NAME)")
    return str(text).strip()


def names_list(text: str) -> tuple:
    """An argparse ``type`` for a comma-separated list of names (at least one; blanks dropped)."""
    names = tuple(n.strip() for n in str(text).split(",") if n.strip())
    if not names:
        raise argparse.ArgumentTypeError(f"{text!r} names nothing (expected NAME[,NAME...])")
    return names


def existing(kind: str = "file", names: str | None = None):
    """An argparse ``type`` for an input path that must exist as a ``file`` or a ``folder``.

    Parameters
    ----------
    kind : "file" or "folder"
    names : "robots" or "layouts": a built-in name (``panda``, ``thesis``) is accepted too

    Returns
    -------
    callable str -> str (the text unchanged)
    """

    def parse(text: str) -> str:
        p = Path(text)
        if p.exists():
            if kind == "file" and p.is_dir():
                raise argparse.ArgumentTypeError(f"{text} is a folder (expected a file)")
            if kind == "folder" and not p.is_dir():
                raise argparse.ArgumentTypeError(f"{text} is a file (expected a folder)")
            return text
        if names is not None:
            from lasercal.solver.errors import FormatError
            from lasercal.solver.formats.data import resolve

            if not str(text).lower().endswith(".urdf"):
                try:
                    resolve(names, text)
                    return text
                except FormatError as e:
                    raise argparse.ArgumentTypeError(f"{text}: {e.reason}") from None
        raise argparse.ArgumentTypeError(f"{text}: no such {kind}")

    parse.__name__ = kind
    return parse


def trigger(text: str) -> str:
    """An argparse ``type`` for ``--trigger``: enter, serial:URL or pilot (checked even where unused)."""
    if text in ("enter", "pilot") or (text.startswith("serial:") and len(text) > len("serial:")):
        return text
    raise argparse.ArgumentTypeError(f"{text!r}: expected enter, serial:URL or pilot")


def world_file(text: str) -> str:
    """An argparse ``type`` for ``--world``: an existing file, kept as its absolute path (a resumed session
    finds it from any folder, and compares equal)."""
    return str(Path(existing("file")(text)).resolve())


INFILE = existing("file")
INFOLDER = existing("folder")
ROBOT = existing("file", "robots")
LAYOUT = existing("file", "layouts")

OUTPUT_KINDS = ("file", "folder", "into")


def output_argument(
    p: argparse.ArgumentParser,
    *flags: str,
    kind: str = "file",
    instead: str | None = None,
    writes=None,
    **kw,
) -> argparse.Action:
    """Declare an output path option; :func:`check_outputs` checks it before the handler runs.

    Parameters
    ----------
    p : the command's parser
    flags : e.g. ``"-o", "--output"``
    kind : "file" (a new file), "folder" (a new or empty folder) or "into" (a folder written into,
        created if missing; files of the same names are replaced)
    instead : what to do when the output exists ('{path}' is replaced), or a function of the path giving
        it (what the folder holds decides: a session resumes, another folder does not); default: pass --force
    writes : for ``kind="into"``: a function of the parsed arguments giving the names of the files
        written into the folder (each is checked not to be an input)
    kw : the other ``add_argument`` arguments (help, required, metavar, default)
    """
    action = p.add_argument(*flags, **kw)
    declared = list(p.get_default("_outputs") or [])
    declared.append((action.dest, flags[-1] if len(flags) == 1 else flags[0], kind, instead))
    p.set_defaults(_outputs=declared)
    if writes is not None:
        p.set_defaults(_writes={**(p.get_default("_writes") or {}), action.dest: writes})
    return action


def input_paths(args) -> list[tuple[str, Path]]:
    """(argument, resolved path) of every path the command was given that exists, outputs excluded.

    A folder stands for every file below it: the command may read any of them (a session's robot
    URDF, a validation's photos).
    """
    outputs = {dest for dest, *_ in getattr(args, "_outputs", None) or ()}
    return [
        (k, Path(v).resolve())
        for k, vals in vars(args).items()
        if k not in outputs and k != "command" and not k.startswith("_")  # 'report -o report' is fine
        for v in (vals if isinstance(vals, list | tuple) else [vals])
        if isinstance(v, str) and v.strip() and Path(v).exists()
    ]


def replaced_input(out: Path, kind: str, inputs) -> str | None:
    """What writing the output ``out`` (resolved) would replace of the command's inputs, or None.

    An output replaces an input when it is the input (by path, through a symbolic link, or the same
    file under another name: a hard link); when it is an existing path inside an input folder, which
    the command may read (``kind`` "file" or "folder"; a file written into an "into" folder has a
    name of its own); or, for a folder replaced whole (``kind="folder"``), when it holds an input.
    """
    exists = out.exists()
    linked = exists and out.is_file() and out.stat().st_nlink > 1  # other names: one may be read
    for k, p in inputs:
        if p == out or (exists and out.samefile(p)):
            return f"the input {p} (argument {k})"
        if linked and p.is_dir():
            same = next((f for f in p.rglob("*") if f.is_file() and f.samefile(out)), None)
            if same is not None:
                return f"{same} (the same file), inside the input folder {p} (argument {k})"
        if kind != "into" and exists and p.is_dir() and p in out.parents:
            return f"{out}, inside the input folder {p} (argument {k}), which the command reads"
        if kind == "folder" and out in p.parents:
            return f"the input {p} (argument {k}) it holds"
    return None


def check_outputs(args) -> None:
    """Check every output path the command declared (:func:`output_argument`), before any work: it is
    writable, not kept unless ``--force``, and never one of the command's inputs, even with ``--force``
    (:func:`replaced_input`).

    Raises
    ------
    SessionError
        One line naming the option and the path (missing or unwritable folder, a file where a folder
        is expected or the other way round, an output that exists and is kept, an input).
    """
    declared = getattr(args, "_outputs", None) or ()
    if not declared:
        return
    from lasercal.collector.errors import SessionError
    from lasercal.collector.sessions.store import check_output

    inputs = input_paths(args)
    writes = getattr(args, "_writes", None) or {}
    seen = {}
    for dest, flag, kind, instead in declared:
        value = getattr(args, dest, None)
        if value is None:
            continue
        out = Path(value).resolve() if str(value).strip() else None
        if out is not None:
            if out in seen:
                raise SessionError(f"{flag} {value}: the same path as {seen[out]} (expected two outputs)")
            seen[out] = flag
            targets = [out / n for n in writes.get(dest, lambda a: ())(args)] if kind == "into" else [out]
            if kind == "into":  # the folder itself an input, or inside one (not a folder of input files)
                targets.insert(0, out)
            for target in targets:
                hit = replaced_input(target, "file" if kind == "into" and target == out else kind, inputs)
                if hit is not None:
                    what = "" if target == out else f" ({target.name})"
                    raise SessionError(f"{flag} {value}{what}: would replace {hit} (expected another path)")
        check_output(
            value,
            folder=kind != "file",
            into=kind == "into",
            force=bool(getattr(args, "force", False)),
            option=flag,
            instead=(
                instead(value) if callable(instead) else (instead or "pass --force to replace it")
            ).replace("{path}", str(value)),
        )


def resume_or_another(command: str, marker: str, what: str, others: dict):
    """An ``instead`` of :func:`output_argument` for a folder ``lasercal COMMAND --resume`` continues: the
    resume where the folder's ``marker`` file says ``command`` started it (its stored settings, the key
    ``collector``), else choose another ``-o``, saying what the folder is (``others``: file name -> what a
    folder holding it is)."""

    def instead(path) -> str:
        from lasercal.solver.errors import LasercalError
        from lasercal.solver.formats.robots import load_yaml

        folder, why = Path(path), f"not {what}, no {marker}"
        if (folder / marker).is_file():
            try:
                meta = load_yaml(folder / marker)
            except LasercalError:
                meta = None
            if isinstance(meta, dict) and meta.get("collector"):
                return "resume it with --resume {path}"
            why = f"its {marker} was not written by lasercal {command}"
        else:
            why = next((f"{v}, not {what}" for k, v in others.items() if (folder / k).is_file()), why)
        return f"{why}: nothing to resume there, choose another -o"

    return instead


def unused(args, why: str, *dests: str) -> None:
    """Warn about each option among ``dests`` that was given (differs from its default) but is not used:
    ``--imagej-box 32`` without ``--method imagej`` would otherwise be dropped in silence."""
    from lasercal.solver.errors import warn

    defaults = getattr(args, "_defaults", {})
    for d in dests:
        value = getattr(args, d, None)
        if d in defaults and value != defaults[d] and value not in (None, False):
            shown = " ".join(map(str, value)) if isinstance(value, list | tuple) else value
            warn(f"--{d.replace('_', '-')} {shown}: ignored ({why})")


def sheet_pose(values, flag: str, absolute: bool = True):
    """The :class:`~solver.kinematics.sheet.SheetPose` of an ``X_MM Y_MM YAW_DEG`` option (``--place``,
    ``--sheet-pose``; each a finite number by its type), checked as a layout's placement is
    (:func:`~solver.formats.checks.sheet_pose_problem`: a yaw beyond a full turn; metres, when
    ``absolute`` -- a pose in the base frame, not a displacement); a yaw in radians is a warning.

    Raises
    ------
    LasercalError
        One line naming the option.
    """
    from lasercal.solver.errors import LasercalError, warn
    from lasercal.solver.formats.checks import radians_hint, sheet_pose_problem
    from lasercal.solver.kinematics.sheet import SheetPose

    bad = sheet_pose_problem(values, absolute)
    if bad:
        raise LasercalError(
            f"argument {flag}: {'' if bad[0] is None else ('X ', 'Y ', 'YAW ')[bad[0]]}{bad[1]}"
        )
    hint = radians_hint(values[2])
    if hint:
        warn(f"{flag} {' '.join(f'{v:g}' for v in values)}: YAW {hint}")
    return SheetPose(*(float(v) for v in values))


SEED = count(0, 2**32 - 1)
"""A random seed: numpy accepts 0 .. 2**32 - 1."""


def _folds(text: str) -> int:
    """K of a K-fold cross-validation: 0 (none) or 2 .. 1000."""
    k = count(0, 1000)(text)
    if k == 1:
        raise argparse.ArgumentTypeError("1 fold holds nothing out (expected 0 for none, or at least 2)")
    return k


FOLDS = _folds


def sheet_pose_argument(p: argparse.ArgumentParser, help: str) -> None:
    """``--sheet-pose X Y YAW`` (mm, mm, deg): where a simulated sheet truly lies (:func:`sheet_pose`)."""
    p.add_argument("--sheet-pose", type=number(-1e4, 1e4), nargs=3, metavar=("X", "Y", "YAW"), help=help)


def chain_arguments(p: argparse.ArgumentParser, robot_help: str | None = None) -> None:
    """``--base-link`` and ``--tip-link`` (a URDF chain's ends), and ``--robot`` when ``robot_help``; a
    session's robot (``SESSION_ROBOT``) comes with ``--prior``, the prior of its fits."""
    if robot_help:
        p.add_argument("--robot", type=ROBOT, metavar="ROBOT", help=robot_help)
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


def prior_spec(text: str) -> str:
    """An argparse ``type`` for ``--prior``: none, default, or an existing file (read by the command)."""
    if str(text).strip().lower() in ("none", "default"):
        return text
    if not str(text).strip() or not Path(text).exists():
        raise argparse.ArgumentTypeError(
            f"{text!r}: no such file (expected none, default or a lasercal-prior/1 YAML)"
        )
    return INFILE(text)


def prior_argument(p: argparse.ArgumentParser) -> None:
    """``--prior``: the prior of every fit (docs/formats.md, "Priors")."""
    p.add_argument(
        "--prior",
        type=prior_spec,
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
    p.add_argument(
        "--seed",
        type=SEED,
        default=0,
        metavar="S",
        help="diagnosis: seed of its simulated replicates and refits; the same seed gives the same figures "
        "(a whole number, default 0)",
    )


PAYLOAD_KG = number(0, 100, "kg", lo_open=True)
PAYLOAD_MM = number(-5000, 5000, "mm")


def payload_argument(p: argparse.ArgumentParser, recorded: bool = False) -> None:
    """``--payload KG,X,Y,Z``: the flange's load for the gravity torques of a session that logs none
    (``diagnose``, ``solve --extend``), or of configurations without torques (``predict``, ``correct``:
    ``recorded``, the model's own by default)."""
    p.add_argument(
        "--payload",
        type=numbers(4, lambda i: PAYLOAD_KG if i == 0 else PAYLOAD_MM, "KG,X,Y,Z"),
        metavar="KG,X,Y,Z",
        help="mass (kg) and centre of mass at q = 0 (mm) carried by the flange, for the gravity model when "
        "torques are not logged"
        + (" (default: the payload the model's fit took, solve --payload)" if recorded else ""),
    )


def parse_payload(values: tuple | None):
    """(kg, x, y, z) from ``--payload`` -> (kg, (3,) mm), or None."""
    import numpy as np

    return None if values is None else (values[0], np.array(values[1:]))


def backend_arguments(p: argparse.ArgumentParser) -> None:
    """Options shared by capture and validate (None = not given, so a resume can tell)."""
    from lasercal.collector.hardware import BACKENDS  # here: the commands without a robot skip its import

    g = p.add_argument_group("robot backend")
    g.add_argument(
        "--backend",
        choices=BACKENDS,
        help="fake (simulated Panda), mujoco (--world), franky, panda-py or ros",
    )
    g.add_argument(
        "--world",
        type=world_file,
        metavar="SCENE.xml",
        help="mujoco: the MuJoCo world file (MJCF; its contract: docs/formats.md; lasercal mujoco-scene "
        "writes one)",
    )
    g.add_argument(
        "--robot", type=ROBOT, help="nominal robot model: name under data/robots/ or YAML (default panda)"
    )
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
        type=trigger,
        metavar="enter|serial:URL|pilot",
        help="enter (default), serial:URL (button box / foot pedal, pyserial URL) or pilot",
    )
    f = p.add_argument_group("fake backend")
    f.add_argument(
        "--truth",
        type=ROBOT,
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


def photo_arguments(p: argparse.ArgumentParser) -> None:
    """``--photos``, ``--photo-format`` (capture, validate): which photos are kept (every one is measured)."""
    from lasercal.collector.sessions.photos import FORMATS, KEEP

    p.add_argument(
        "--photos",
        choices=KEEP,
        help="photos kept (each is measured as it is taken, its spot and sigma in the CSV): all (default), "
        "first (the first at each point and every one whose spot could not be measured) or none",
    )
    p.add_argument(
        "--photo-format",
        choices=FORMATS,
        help="png (default, lossless) or jpg (quality 95, a tenth of the size)",
    )


def photo_options_used(args, camera) -> None:
    """Refuse ``--photos`` / ``--photo-format`` where they would change nothing: a session without a camera
    takes no photo; ``--photos none`` keeps none, in no format.

    Raises
    ------
    LasercalError
        One line naming the option.
    """
    from lasercal.solver.errors import LasercalError

    given = [
        f"--{d.replace('_', '-')} {getattr(args, d)}" for d in ("photos", "photo_format") if getattr(args, d)
    ]
    if given and not camera:
        raise LasercalError(
            f"{' '.join(given)}: no photo is taken without a camera (expected --camera, or drop "
            f"{'it' if len(given) == 1 else 'them'})"
        )
    if args.photos == "none" and args.photo_format:
        raise LasercalError(
            f"--photo-format {args.photo_format}: --photos none keeps no photo, in any format (drop one)"
        )


def view_arguments(p: argparse.ArgumentParser) -> None:
    """``--view``, ``--view-host``, ``--view-port`` (capture, validate, beam-check): the live view."""
    p.add_argument(
        "--view",
        action="store_const",
        const=True,
        help="serve a live view of the session on this machine (127.0.0.1): the camera's frames with what is "
        "found, the coach's instruction, progress, problems; needs pip install 'lasercal[view]'",
    )
    p.add_argument(
        "--view-host",
        metavar="ADDR",
        help="with --view: serve it on this address instead, for another device (a phone, a tablet): its "
        "link is printed with the run's token; 0.0.0.0: every address of this machine, one link each",
    )
    p.add_argument(
        "--view-port",
        type=count(0, 65535),
        metavar="PORT",
        help="with --view: the port (default 8765; 0: any)",
    )


def view_options(args, stored: dict | None = None):
    """The live view's options from the command line (and a resumed session's stored ``view``), or None."""
    from lasercal.collector.view import DEFAULT_PORT, ViewOptions

    stored = stored or {}
    if not (args.view or stored.get("view")):
        unused(args, "it places the live view (--view)", "view_host", "view_port")
        return None
    port = args.view_port if args.view_port is not None else stored.get("view_port", DEFAULT_PORT)
    return ViewOptions(host=args.view_host or "127.0.0.1", port=port)
