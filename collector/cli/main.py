"""The ``lasercal`` command: one table of subcommands, each imported only when it runs.

Every subcommand is a thin handler (parse arguments, call one library function, print) in a
module of this package. ``lasercal --help`` imports none of them, so it starts fast. Any
:class:`~lasercal.solver.errors.LasercalError` (or ``vision``'s ``VisionError``, or an ``OSError``
on a file the user named) becomes a one-line message and exit code 2, never a traceback; a
:class:`~lasercal.solver.errors.LasercalWarning` becomes a line ``lasercal: warning: ...`` and the
command goes on. Standard output closed early (``lasercal predict ... | head -1``) ends the command
quietly, exit code 141. Output paths (declared with :func:`options.output_argument`) are checked before
the handler runs (:func:`outputs_checked`).
"""

from __future__ import annotations

import argparse
import copy
import importlib
import sys
import warnings
from contextlib import contextmanager
from typing import NamedTuple

from lasercal.solver.errors import LasercalError  # one small module: no numpy


class Command(NamedTuple):
    """One subcommand: ``module`` (in lasercal.collector.cli) holds ``args_<name>`` and ``handler``."""

    name: str
    module: str
    handler: str
    help: str
    description: str | None = None


COMMANDS = (
    Command(
        "demo",
        "demo",
        "cmd_demo",
        "the whole calibration story on the built-in simulated Panda (no robot, camera or keyboard)",
    ),
    Command(
        "capture",
        "capture",
        "cmd_capture",
        "guided capture session on a robot, or on the simulated one (--backend fake --auto)",
    ),
    Command("solve", "solve", "cmd_solve", "identify the robot's geometry from a capture session"),
    Command(
        "plan",
        "plan",
        "cmd_plan",
        "the next captures that most lower the predicted error where the robot is used, and that error",
    ),
    Command(
        "validate",
        "validate",
        "cmd_validate",
        "photograph the spot at N configurations a model computes for a point (thesis Section 4.3)",
    ),
    Command(
        "report",
        "report",
        "cmd_report",
        "an HTML report with plots: calibration, validation before/after, diagnosis",
    ),
    Command("export", "report", "cmd_export", "the calibrated model as a URDF, a DH-style table or YAML"),
    Command(
        "correct",
        "correct",
        "cmd_correct",
        "joint and Cartesian commands that reach goals on the calibrated robot (for a nominal controller)",
    ),
    Command(
        "predict", "solve", "cmd_predict", "where a model's beam meets the plane, for configurations in a CSV"
    ),
    Command("simulate", "solve", "cmd_simulate", "a synthetic capture session whose truth is a given robot"),
    Command(
        "diagnose",
        "diagnose",
        "cmd_diagnose",
        "find the non-geometric effect the geometric model misses (or 'none')",
    ),
    Command(
        "sheet",
        "sheet",
        "cmd_sheet",
        "a printable reference sheet (PDF, SVG at 1:1: crosses, markers, scale bars) and its layout",
    ),
    Command(
        "mujoco-scene",
        "mujoco",
        "cmd_mujoco_scene",
        "a MuJoCo world for a printed sheet: a perturbed outside arm, the sheet, a laser, a camera",
    ),
    Command(
        "new-session",
        "outside",
        "cmd_new_session",
        "an empty capture session for a layout, for a robot script of your own to fill (docs/formats.md)",
    ),
    Command(
        "configurations",
        "outside",
        "cmd_configurations",
        "the configurations a model computes for a point (what validate would command), as CSV",
    ),
    Command(
        "spots",
        "vision",
        "spots_command",
        "measure laser spots in photos (px, and mm with a layout)",
        "Detect laser spots and report sub-pixel centroids, and their position on the plane "
        "(mm, base frame) when the layout has markers.",
    ),
    Command(
        "beam-check",
        "vision",
        "beam_check_command",
        "laser alignment: circle of spots while joint 7 turns",
        "Fit a circle to the spots of photos taken while only joint 7 turns; report the beam's tilt "
        "from the axis and the axis on the plane.",
    ),
    Command(
        "camera-calibrate",
        "vision",
        "camera_calibrate_command",
        "camera intrinsics and lens distortion from pattern photos",
        "Calibrate a camera (cv2.calibrateCamera) from photos of a chessboard or a ChArUco board "
        "and write a camera YAML.",
    ),
    Command(
        "fullpose",
        "fullpose",
        "cmd_fullpose",
        "full-pose POE calibration from circle-point measurements (or measured poses)",
    ),
    Command(
        "simulate-fullpose",
        "fullpose",
        "cmd_simulate_fullpose",
        "synthetic circle-point measurements whose truth is a given robot (Sensors 2013, Section 3)",
    ),
    Command(
        "import-mukca",
        "study",
        "cmd_import",
        "one point session from a MUKCa robot folder (real Panda socket data)",
    ),
    Command(
        "import-justin",
        "justin",
        "cmd_import_justin",
        "a position session from DLR's Agile Justin measurement records (both hands, robot justin)",
    ),
    Command(
        "import-ipa",
        "poses",
        "cmd_import_ipa",
        "a pose session from one series of the ipa-robot-accuracy UR10 laser-tracker data set",
    ),
    Command(
        "register",
        "poses",
        "cmd_register",
        "place a calibrated robot anew: keep the robot, fit only a new session's sensor and tool frames",
    ),
    Command(
        "study-mukca",
        "study",
        "cmd_study",
        "the real-data study on MUKCa robots: calibration by leave-one-position-out, "
        "simulation check, diagnosis, extension, outliers",
    ),
)
BY_NAME = {c.name: c for c in COMMANDS}


class UsageError(LasercalError):
    """The command line itself is wrong (argparse's message); ``prog`` the parser's name."""

    def __init__(self, message: str, prog: str):
        super().__init__(message)
        self.prog = prog


class UsageArgumentParser(argparse.ArgumentParser):
    """A parser whose errors are one line naming the command (``lasercal capture: error: argument --hold:
    ...``), not usage + error."""

    def error(self, message: str):
        raise UsageError(message, self.prog)


class DefaultsHelpFormatter(argparse.HelpFormatter):
    """``--help`` with every option's default: ``(default: X)`` after a help text that names none.

    Like argparse's ``ArgumentDefaultsHelpFormatter``, but silent where the default is no value (None,
    False: an option not given) or the help already says it (``default ...``), and an option without a
    help text still shows its default.
    """

    @staticmethod
    def _has_default(action) -> bool:
        d = action.default
        return bool(action.option_strings) and d is not None and d is not False and d is not argparse.SUPPRESS

    def _format_action(self, action) -> str:
        if action.help is None and self._has_default(action):
            action = copy.copy(action)
            action.help = "(default: %(default)s)"
        return super()._format_action(action)

    def _get_help_string(self, action) -> str:
        text = action.help or ""
        if "default" in text or not self._has_default(action):
            return text
        d = action.default
        shown = " ".join(map(str, d)) if isinstance(d, list | tuple) else d
        return f"{text} (default: {str(shown).replace('%', '%%')})"


def load(cmd: Command):
    """The command's module, imported now (``lasercal.collector.cli.<module>``)."""
    return importlib.import_module(f"lasercal.collector.cli.{cmd.module}")


def outputs_checked(handler):
    """``handler`` preceded by the check of every output path its command declared
    (:func:`options.check_outputs`): nothing runs, and nothing is written, for an output that is kept."""
    from functools import wraps

    from lasercal.collector.cli.options import check_outputs

    @wraps(handler)
    def run(args):
        check_outputs(args)
        return handler(args)

    return run


def parsed_defaults(p: argparse.ArgumentParser) -> dict:
    """Each option's default as parsing leaves it (argparse converts a string default with its type)."""
    return {
        a.dest: a.type(a.default) if isinstance(a.default, str) and callable(a.type) else a.default
        for a in p._actions
    }


def build_parser(selected: str | None = None) -> argparse.ArgumentParser:
    """The parser: every command listed, only ``selected``'s arguments (and module) loaded."""
    parser = UsageArgumentParser(
        prog="lasercal",
        description="Kinematic calibration of a serial arm with a laser pointer, a table of reference points "
        "and a camera.",
    )
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    sub.required = True
    for c in COMMANDS:
        p = sub.add_parser(
            c.name,
            help=c.help,
            description=c.description or c.help[:1].upper() + c.help[1:],
            formatter_class=DefaultsHelpFormatter,
        )
        if c.name == selected:
            mod = load(c)
            getattr(mod, "args_" + c.name.replace("-", "_"))(p)
            p.set_defaults(func=outputs_checked(getattr(mod, c.handler)))
            p.set_defaults(_defaults=parsed_defaults(p))  # a handler tells an option given (options.unused)
    return parser


def _user_errors() -> tuple:
    from lasercal.solver.errors import LasercalError
    from lasercal.vision.errors import VisionError

    return LasercalError, VisionError


def quiet_libraries() -> None:
    """Keep third-party chatter off the terminal: OpenCV's own log lines (``[ WARN:0@0.03] global
    grfmt_png.cpp ...``: each photo's problem is reported by lasercal, naming it) and what libraries
    send to Python's logging (matplotlib's font cache). Nothing is imported for it: OpenCV reads its
    level when first imported; when already imported (a second command in one process), it is set."""
    import logging
    import os

    os.environ.setdefault("OPENCV_LOG_LEVEL", "SILENT")
    cv2 = sys.modules.get("cv2")
    if cv2 is not None and os.environ["OPENCV_LOG_LEVEL"] == "SILENT":
        cv2.utils.logging.setLogLevel(cv2.utils.logging.LOG_LEVEL_SILENT)
    root = logging.getLogger()
    if not root.handlers:  # else Python's last-resort handler prints libraries' warnings
        root.addHandler(logging.NullHandler())


@contextmanager
def warnings_as_lines():
    """Show each :class:`LasercalWarning` as one line ``lasercal: warning: ...`` on stderr (each message
    once); other warnings (numpy's overflow notes, scipy's and matplotlib's) not at all -- what they
    concern is checked and named by lasercal -- unless Python's ``-W`` options ask for them."""
    from lasercal.solver.errors import LasercalWarning

    def show(message, category, filename, lineno, file=None, line=None):
        if issubclass(category, LasercalWarning):
            print(f"lasercal: warning: {message}", file=sys.stderr)
        else:
            shown(message, category, filename, lineno, file, line)

    with warnings.catch_warnings():
        shown = warnings.showwarning
        if not sys.warnoptions:  # third-party chatter: results are checked, and named, by lasercal
            warnings.simplefilter("ignore")
        warnings.simplefilter("default", LasercalWarning)
        warnings.showwarning = show
        yield


def stdout_closed() -> bool:
    """Whether standard output is a pipe whose reader has gone (``lasercal predict ... | head -1``): the
    kernel flags its write end with an error (Linux: ``POLLERR``; BSD/macOS: ``POLLHUP``). A broken pipe
    elsewhere (a robot's or a camera's socket) stays an error the user is told about."""
    import select

    try:
        fd = sys.stdout.fileno()
    except (AttributeError, OSError, ValueError):  # not a file (a test's capture): it cannot break
        return False
    poller = select.poll()
    poller.register(fd, select.POLLOUT)
    return any(ev & (select.POLLERR | select.POLLHUP) for _, ev in poller.poll(0))


def quiet_exit_for_closed_stdout() -> int:
    """Python's recipe for a closed pipe (docs: signal, "Note on SIGPIPE"): standard output goes to
    ``os.devnull``, so the flush at exit cannot fail again, and nothing is printed. Returns 141
    (128 + SIGPIPE), what a shell reports for a program a closed pipe ended, as 130 is for Ctrl-C."""
    import os

    devnull = os.open(os.devnull, os.O_WRONLY)
    os.dup2(devnull, sys.stdout.fileno())
    os.close(devnull)
    return 141


def main(argv=None) -> int:
    """Run ``lasercal``; returns the exit code (0 ok, 2 bad input or nothing measured, 130 interrupted,
    141 standard output closed early)."""
    argv = sys.argv[1:] if argv is None else list(argv)
    selected = next((a for a in argv if not a.startswith("-")), None)
    try:
        try:
            args = build_parser(selected if selected in BY_NAME else None).parse_args(argv)
        except UsageError as e:  # one line that names the command (the top parser's errors too)
            prog = f"lasercal {selected}" if selected in BY_NAME else e.prog
            more = f" ({prog} --help lists its options)" if str(e).startswith("unrecognized") else ""
            print(f"{prog}: error: {e}{more}", file=sys.stderr)
            return 2
        quiet_libraries()
        with warnings_as_lines():
            code = int(args.func(args) or 0)
        sys.stdout.flush()  # a reader gone (``| head -1``) shows here, not at exit as Python's own message
        return code
    except SystemExit:  # --help: matched first, so the error classes (and numpy) are not imported
        raise
    except _user_errors() as e:
        print(f"lasercal: error: {e}", file=sys.stderr)
        return 2
    except OSError as e:  # a file or folder the user named cannot be read or written (disk full, ...)
        if isinstance(e, BrokenPipeError) and stdout_closed():
            return quiet_exit_for_closed_stdout()
        where = f"{e.filename}: " if e.filename else ""
        print(f"lasercal: error: {where}{e.strerror or e}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("lasercal: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
