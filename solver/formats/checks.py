"""One place that checks numbers at the edge: finite, in a range, in the right units.

File readers and command-line options describe what they accept with a :class:`Range`
(bounds and unit); :meth:`Range.problem` says what is wrong with a value in one phrase
ending in what was expected, e.g. ``"-1 s is out of range (expected > 0 s)"``. Readers
wrap it in a :class:`~lasercal.solver.errors.FormatError` (file, line, column), options in
a command-line error (the option's name). Suspicious values -- positions that look like
metres, angles that look like degrees -- are errors too, with the hint
(:func:`metres_hint`, :func:`degrees_hint`).
"""

from __future__ import annotations

import copy
import math
import threading
from dataclasses import dataclass

import numpy as np

# A reference point or aperture closer than this to the base in every coordinate is not a table
# point in mm: it is (almost surely) a position in metres.
METRES_BELOW_MM = 5.0


@dataclass(frozen=True)
class Range:
    """The accepted values of one number.

    Attributes
    ----------
    lo, hi : float or None, bounds (None: unbounded)
    unit : str, printed after the numbers ('' for counts)
    lo_open, hi_open : bool, the bound itself is excluded
    integer : bool, only whole numbers
    """

    lo: float | None = None
    hi: float | None = None
    unit: str = ""
    lo_open: bool = False
    hi_open: bool = False
    integer: bool = False

    def _u(self, x) -> str:
        return f"{x:g} {self.unit}".rstrip() if isinstance(x, float | int) else str(x)

    def expected(self) -> str:
        """What is accepted, e.g. 'a number > 0 s', 'a whole number >= 1', 'a number in (0, 0.3]'."""
        kind = "a whole number" if self.integer else "a finite number"
        if self.lo is not None and self.hi is not None:
            lb, rb = "(" if self.lo_open else "[", ")" if self.hi_open else "]"
            return f"{kind} in {lb}{self.lo:g}, {self.hi:g}{rb} {self.unit}".rstrip()
        if self.lo is not None:
            return f"{kind} {'>' if self.lo_open else '>='} {self._u(self.lo)}"
        if self.hi is not None:
            return f"{kind} {'<' if self.hi_open else '<='} {self._u(self.hi)}"
        return f"{kind}{' in ' + self.unit if self.unit else ''}"

    def problem(self, x) -> str | None:
        """None when ``x`` is accepted, else 'what is wrong (expected ...)'."""
        try:
            v = float(x)
        except (TypeError, ValueError):
            return f"{x!r} is not a number (expected {self.expected()})"
        if not math.isfinite(v):
            return f"{x!r} is not finite (expected {self.expected()})"
        if self.integer and v != int(v):
            return f"{x!r} is not a whole number (expected {self.expected()})"
        below = self.lo is not None and (v <= self.lo if self.lo_open else v < self.lo)
        above = self.hi is not None and (v >= self.hi if self.hi_open else v > self.hi)
        if below or above:
            return f"{self._u(v)} is out of range (expected {self.expected()})"
        return None

    def parse(self, text) -> float | int:
        """The value of ``text``; ValueError with :meth:`problem`'s phrase when it is not accepted."""
        msg = self.problem(text)
        if msg is not None:
            raise ValueError(msg)
        return int(float(text)) if self.integer else float(text)


def metres_hint(xyz: np.ndarray) -> str | None:
    """A hint when points (k, 3) given in mm are all within a few mm of the base: metres, not mm."""
    a = np.abs(np.asarray(xyz, dtype=float)).reshape(-1, 3)
    if a.size and a.max() > 0 and a.max() < METRES_BELOW_MM:
        return f"every coordinate is below {METRES_BELOW_MM:g} mm: these look like metres (expected mm)"
    return None


def degrees_hint(q: np.ndarray, limits: np.ndarray) -> str | None:
    """A hint when joint angles (m, n) outside ``limits`` (n, 2) rad would fit them read as degrees."""
    q = np.asarray(q, dtype=float).reshape(-1, limits.shape[0])
    r = np.radians(q)
    if np.abs(q).max(initial=0) > 2 * np.pi and np.all((r >= limits[:, 0]) & (r <= limits[:, 1])):
        return "these look like degrees (expected rad)"
    return None


SHEET_POSE = (Range(-1e4, 1e4, "mm"), Range(-1e4, 1e4, "mm"), Range(-360, 360, "deg"))
"""x_mm, y_mm, yaw_deg of a printed sheet's pose on the table: within 10 m, within a full turn."""


def sheet_pose_problem(values, absolute: bool = True) -> tuple[int | None, str] | None:
    """What is wrong with a sheet's pose ``(x mm, y mm, yaw deg)``: (index of the culprit value, or None
    for the pose as a whole; phrase), or None.

    A value not finite or out of :data:`SHEET_POSE`; for a placement in the base frame (``absolute``; not
    a displacement) x and y both within :data:`METRES_BELOW_MM` of the base, where the robot stands:
    metres.
    """
    for i, (v, rng) in enumerate(zip(values, SHEET_POSE)):
        msg = rng.problem(v)
        if msg:
            return i, msg
    if absolute and metres_hint([values[0], values[1], 0.0]):
        return None, (
            f"x, y = {float(values[0]):g}, {float(values[1]):g} mm puts the sheet's centre at the robot's "
            "base: these look like metres (expected mm)"
        )
    return None


def radians_hint(deg: float) -> str | None:
    """A hint when an angle meant in degrees is a round angle (a non-zero multiple of 15 deg) written in
    radians, e.g. 1.5708 (pi/2); 0.5 or 2 deg pass."""
    step = math.pi / 12
    k = round(deg / step)
    if k and abs(deg) <= 2 * math.pi and abs(deg - k * step) < 5e-3:
        return f"{deg:g} deg: {k * 15} deg written in radians? (expected degrees)"
    return None


def read_text(path) -> str:
    """A text file's contents: UTF-8 (a leading byte-order mark dropped), or UTF-16 with its byte-order
    mark (what a Windows editor saves as 'Unicode'); line ends normalised to ``\\n``.

    Raises
    ------
    FormatError
        Naming the file (and the line of a bad byte): missing, a folder, unreadable, binary (NUL bytes:
        UTF-16 without a byte-order mark, a spreadsheet, an image) or not UTF-8 text.
    """
    import codecs
    from pathlib import Path

    from lasercal.solver.errors import FormatError

    p = Path(path)
    if p.is_dir():
        raise FormatError(path, "is a folder (expected a text file)")
    try:
        data = p.read_bytes()
    except FileNotFoundError:
        raise FormatError(path, "no such file") from None
    except OSError as e:
        raise FormatError(path, f"cannot read file ({e.strerror})") from None
    if data.startswith((codecs.BOM_UTF16_LE, codecs.BOM_UTF16_BE)):
        try:
            return data.decode("utf-16").replace("\r\n", "\n")
        except UnicodeDecodeError:
            raise FormatError(path, "not valid UTF-16 text after its byte-order mark") from None
    if b"\0" in data:
        line = data[: data.index(b"\0")].count(b"\n") + 1
        raise FormatError(path, "a binary file, not text (NUL bytes; expected a UTF-8 text file)", line=line)
    try:
        return data.decode("utf-8-sig").replace("\r\n", "\n")
    except UnicodeDecodeError as e:
        line = data[: e.start].count(b"\n") + 1
        raise FormatError(
            path, f"byte 0x{data[e.start]:02x} is not UTF-8 text (expected a UTF-8 text file)", line=line
        ) from None


def load_yaml(path):
    """Parse a YAML file, turning I/O and syntax errors into a FormatError with the line, and a file cut
    short (:func:`cut_short`) into one naming it."""
    from pathlib import Path

    import yaml  # (here: the command line's options load this module for every command)

    from lasercal.solver.errors import FormatError
    from lasercal.solver.whole import cut_short

    path = Path(path)
    text = read_text(path)
    with _PARSED_LOCK:
        known = _PARSED.get(text)
    if known is not None:
        return copy.deepcopy(known)  # the caller's to change
    torn = cut_short(text)
    if torn is not None:
        raise FormatError(
            path,
            "cut short: the file ends before its last line '...' (a write killed, or a partial copy; "
            "expected the whole file)",
            line=torn,
        )
    try:
        doc = yaml.safe_load(text)
    except yaml.YAMLError as e:
        mark = getattr(e, "problem_mark", None)
        raise FormatError(
            path, f"invalid YAML: {getattr(e, 'problem', e)}", line=None if mark is None else mark.line + 1
        ) from None
    bad = non_finite(yaml.compose(text))
    if bad is not None:
        field, line, value = bad
        raise FormatError(path, f"{value} on line {line} (expected a finite number)", field=field)
    with _PARSED_LOCK:
        _PARSED[text] = copy.deepcopy(doc)
        while len(_PARSED) > 256:
            del _PARSED[next(iter(_PARSED))]  # the oldest
    return doc


# The documents parsed so far in this process, by their text (only those that passed every check above):
# the same robot, layout and session files are read again and again (a robot's YAML costs ~10 ms to parse
# twice, a copy of what it gave ~0.1 ms).
_PARSED: dict = {}
_PARSED_LOCK = threading.Lock()


def non_finite(node, where: str = ""):
    """The first NaN or infinity of a composed YAML document (``yaml.compose``): (field, line, text), or None;
    the field as the loaders name it (``sheet.x_mm``, ``points.P1``: a list is one field).

    lasercal writes no such number, and none is a length, an angle or a setting: one in any field of a file
    it reads -- a field the command uses or not -- is a corruption, named here (issue 47's sweep: a NaN in a
    layout's marker, a model's statistics or a session's simulated pose passed in silence).
    """
    import yaml

    if isinstance(node, yaml.MappingNode):
        for key, value in node.value:
            found = non_finite(value, f"{where}.{key.value}" if where else str(key.value))
            if found is not None:
                return found
    elif isinstance(node, yaml.SequenceNode):
        for value in node.value:  # a list is one field (points.P1), as the loaders name it
            found = non_finite(value, where)
            if found is not None:
                return found
    elif isinstance(node, yaml.ScalarNode) and node.tag == "tag:yaml.org,2002:float":
        text = node.value.lower().replace("_", "")
        try:
            finite = math.isfinite(float(text.replace(".inf", "inf").replace(".nan", "nan")))
        except ValueError:  # YAML 1.1's base-60 floats (1:30.5): finite
            finite = True
        if not finite:  # .nan, .inf, and a number too large for a float (1.0e400)
            return where, node.start_mark.line + 1, node.value
    return None
