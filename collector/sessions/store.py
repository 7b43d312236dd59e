"""Crash-safe session folders: session.yaml written atomically, captures.csv appended row by row.

Every capture is one line written with a single ``write`` on a file opened in append
mode, then ``fsync``-ed before :meth:`CaptureStore.append` returns: a kill at any moment
loses at most the capture in flight. A kill (or power cut) in the middle of a write can
leave a torn last line; :meth:`CaptureStore.open` cuts it off, never touching the rows
before it, and then checks the whole folder with :func:`solver.session.load_session`.
"""

from __future__ import annotations

import csv
import io
import os
import shutil
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import numpy as np

from lasercal.collector.errors import SessionError
from lasercal.solver.formats.robots import load_model, load_yaml
from lasercal.solver.formats.session import Session, captures_header, format_row, load_session
from lasercal.solver.whole import dump_yaml


def _fsync_dir(folder: Path) -> None:
    """Make a new or renamed file's directory entry durable."""
    fd = os.open(folder, os.O_RDONLY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


def write_atomic(path: Path, text: str) -> None:
    """Replace ``path`` by ``text`` all at once (write a temporary file, fsync, rename)."""
    tmp = path.with_name(path.name + ".tmp")
    with open(tmp, "w") as f:
        f.write(text)
        f.flush()
        os.fsync(f.fileno())
    os.replace(tmp, path)
    _fsync_dir(path.parent)


def write_atomic_bytes(path: Path, data: bytes) -> None:
    """Replace ``path`` by ``data`` all at once: a kill leaves the old file or the new one, never half."""
    tmp = path.with_name(path.name + ".tmp")
    with open(tmp, "wb") as f:
        f.write(data)
        f.flush()
        os.fsync(f.fileno())
    os.replace(tmp, path)
    _fsync_dir(path.parent)


def check_output(
    path,
    *,
    folder: bool = False,
    force: bool = False,
    option: str = "-o",
    instead: str = "pass --force to replace it",
    into: bool = False,
) -> Path:
    """Check an output path before any work starts: its folder exists, it is not kept unless ``force``.

    Parameters
    ----------
    path : str or Path, a file (``folder=False``) or a folder to be written
    folder : bool, the output is a folder (an existing empty folder is fine)
    force : bool, an existing output may be replaced
    into : bool, a folder that files are written into (``--overlay``, ``--report``): it may exist
        and hold other files
    option : str, how the command line named it (for the message)
    instead : str, what to do when the output exists (the message's end)

    Raises
    ------
    SessionError
        One line naming the option and the path: what is wrong and what was expected.
    """
    p = Path(path)
    where = f"{option} {p}"
    if not str(path).strip():
        raise SessionError(f"{option}: an empty path (expected a {'folder' if folder else 'file'} name)")
    parent = p.resolve().parent
    if parent.exists() and not parent.is_dir():
        raise SessionError(f"{where}: {parent} is a file (expected a folder)")
    if not parent.is_dir():
        raise SessionError(f"{where}: the folder {parent} does not exist (expected an existing folder)")
    for f in (parent, p) if into and p.is_dir() else (parent,):
        try:  # a probe, not os.access: root passes access() on a read-only or pseudo file system
            tempfile.TemporaryFile(dir=f).close()
        except OSError as e:
            raise SessionError(f"{where}: cannot write in the folder {f} ({e.strerror})") from None
    if p.exists():
        if folder and not p.is_dir():
            raise SessionError(f"{where}: is a file (expected a folder)")
        if not folder and p.is_dir():
            raise SessionError(f"{where}: is a folder (expected a file name)")
        if not force and not into and (not folder or any(p.iterdir())):
            raise SessionError(f"{where}: exists and is kept ({instead})")
    return p


def _umask() -> int:
    """The process's umask (read by setting it, the only portable way, and set back at once)."""
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


@contextmanager
def atomic_output(path, *, folder: bool = False) -> Iterator[Path]:
    """A temporary sibling of ``path`` to write; on success it replaces ``path`` in one rename.

    A file is replaced with ``os.replace``; a folder is renamed into place (an old one is moved
    aside first and removed after). On an exception the temporary is removed and ``path`` is
    untouched. Check the path first with :func:`check_output`.
    """
    p = Path(path)
    parent = p.resolve().parent
    tmp = Path(tempfile.mkdtemp(prefix=f".{p.name}.", dir=parent))
    if folder:  # mkdtemp makes it private (0700): an output folder gets what mkdir gives, as every other
        tmp.chmod(0o777 & ~_umask())
    target = tmp if folder else tmp / p.name
    try:
        yield target
        if folder:
            old = None
            if p.exists():
                old = parent / f".{p.name}.old-{os.getpid()}"
                os.replace(p, old)
            os.replace(tmp, p)
            if old is not None:
                shutil.rmtree(old)
        else:
            os.replace(target, p)
            shutil.rmtree(tmp)
        _fsync_dir(parent)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise


def csv_line(cells: list) -> bytes:
    """One CSV row, numbers at full precision, ending in a newline."""
    buf = io.StringIO()
    csv.writer(buf, lineterminator="\n").writerow(
        [c if isinstance(c, str) else format_row([c])[0] for c in cells]
    )
    return buf.getvalue().encode("utf-8")


def append_durably(fd: int, line: bytes, path) -> None:
    """Append one line with a single write and fsync it before returning."""
    if os.write(fd, line) != len(line):
        raise SessionError(f"{path}: short write (disk full?); the last row was not saved")
    os.fsync(fd)


def cut_torn_line(path: Path) -> int:
    """Cut anything after the last newline (a row torn by a kill); returns the bytes cut."""
    data = path.read_bytes()
    keep = data.rfind(b"\n") + 1
    if keep < len(data):
        with open(path, "r+b") as f:
            f.truncate(keep)
            os.fsync(f.fileno())
    return len(data) - keep


class CsvLog:
    """A CSV file grown one durable row at a time (validation runs).

    Parameters
    ----------
    path : Path, created with ``comment`` lines (each starting with '#') and the header
    header : list of str
    comment : list of str
    resume : bool, append to an existing log (a torn last row is cut off first)
    """

    def __init__(self, path: Path, header: list[str], comment=(), resume: bool = False):
        if resume:
            cut_torn_line(path)
        elif path.exists():
            raise SessionError(f"{path} exists: choose another folder")
        else:
            write_atomic(path, "".join(f"# {c}\n" for c in comment) + csv_line(header).decode())
        self.path, self.header = path, header
        self._fd = os.open(path, os.O_WRONLY | os.O_APPEND)

    def append(self, row: dict) -> None:
        """Append a row given as column -> value (missing columns left empty)."""
        append_durably(self._fd, csv_line([row.get(h, "") for h in self.header]), self.path)

    def close(self) -> None:
        """Close the file (again: nothing)."""
        if self._fd is not None:
            os.close(self._fd)
            self._fd = None


class CaptureStore:
    """The captures of one session folder, appended crash-safely.

    Use :meth:`create` for a new session and :meth:`open` to resume one.

    Attributes
    ----------
    folder : Path
    meta : dict, the session.yaml mapping
    header : list of str, the captures.csv columns
    point : list of str, the point of each capture on disk
    t : list of float, s
    q : list of (n,) arrays, rad
    target : list of (3,) arrays or None, where each capture's spot was, layout frame, mm (a camera
        session's measured spot, else where it was aimed: :func:`solver.session.load_session`'s ``target``)
    measured : list of bool, a camera measured the capture's spot
    recovered : int, bytes of a torn last line cut off when the session was opened
    """

    def __init__(
        self, folder: Path, meta: dict, header: list[str], session: Session | None, recovered: int = 0
    ):
        self.folder, self.meta, self.header, self.recovered = folder, meta, header, recovered
        self.point = [] if session is None else [str(p) for p in session.point]
        self.t = [] if session is None else [float(t) for t in session.t]
        self.q = [] if session is None else list(session.q)
        self.target = [] if session is None else list(session.target)
        self.measured = [] if session is None else list(session.measured)
        self._fd = os.open(self.path, os.O_WRONLY | os.O_APPEND)

    @property
    def path(self) -> Path:
        """captures.csv"""
        return self.folder / "captures.csv"

    @classmethod
    def create(cls, folder, meta: dict, n: int, extra_columns=()) -> CaptureStore:
        """Start a new session folder: session.yaml, then captures.csv holding only its header.

        Raises
        ------
        SessionError
            The folder already holds captures (resume it instead).
        """
        folder = Path(folder)
        if (folder / "captures.csv").exists():
            raise SessionError(
                f"{folder} already holds a session: resume it with --resume {folder}, or choose another "
                "folder"
            )
        folder.mkdir(parents=True, exist_ok=True)
        write_atomic(folder / "session.yaml", dump_yaml(meta, sort_keys=False, width=120))
        header = captures_header(n, dq=True, tau=True, extra=extra_columns)
        write_atomic(folder / "captures.csv", csv_line(header).decode())
        return cls(folder, meta, header, None)

    @classmethod
    def open(cls, folder) -> CaptureStore:
        """Reopen an interrupted session: cut a torn last line, validate, and append after it.

        Raises
        ------
        SessionError
            Not a session folder started by ``lasercal capture``.
        FormatError
            A malformed session.yaml or captures.csv (names file, line and column).
        """
        folder = Path(folder)
        cpath = folder / "captures.csv"
        if not (folder / "session.yaml").is_file():
            raise SessionError(f"{folder} is not a session folder (no session.yaml): nothing to resume")
        meta = load_yaml(folder / "session.yaml")
        if not cpath.exists():  # killed between writing session.yaml and the header
            n = load_model(meta.get("robot"), base=folder).n
            extra = (meta.get("collector") or {}).get("extra_columns", [])
            write_atomic(cpath, csv_line(captures_header(n, True, True, extra)).decode())
        data = cpath.read_bytes()
        keep = data.rfind(b"\n") + 1  # every row ends with a newline: anything after the last one is torn
        if keep < len(data):
            with open(cpath, "r+b") as f:
                f.truncate(keep)
                os.fsync(f.fileno())
        session = load_session(folder)
        header = next(csv.reader(io.StringIO(data[:keep].decode("utf-8", "replace").split("\n", 1)[0])))
        return cls(folder, meta, [h.strip() for h in header], session, len(data) - keep)

    def append(self, values: dict) -> None:
        """Append one capture and make it durable before returning.

        Parameters
        ----------
        values : dict column -> value: 'point' (str), 't' (s), 'q' (n,) rad, 'dq' (n,) rad/s,
            'tau' (n,) Nm, 'target' (3,) mm (where the spot was, layout frame; kept in memory, not a
            column), and extra columns by name (missing extras are left empty)
        """
        cells = {"point": values["point"], "t": values["t"]}
        for key in ("q", "dq", "tau"):
            cells.update({f"{key}{j + 1}": v for j, v in enumerate(np.asarray(values[key], dtype=float))})
        append_durably(
            self._fd,
            csv_line([cells[h] if h in cells else values.get(h, "") for h in self.header]),
            self.path,
        )
        self.point.append(str(values["point"]))
        self.t.append(float(values["t"]))
        self.q.append(np.asarray(values["q"], dtype=float))
        self.target.append(values.get("target"))
        self.measured.append(values.get("camera_x") not in (None, ""))

    def discard_last(self) -> str | None:
        """Remove the last capture from the file (durably); returns its point, or None if there is none."""
        if not self.point:
            return None
        data = self.path.read_bytes()
        cut = data.rstrip(b"\n").rfind(b"\n") + 1
        os.ftruncate(self._fd, cut)
        os.fsync(self._fd)
        self.t.pop()
        self.q.pop()
        self.target.pop()
        self.measured.pop()
        return self.point.pop()

    def remove_empty(self) -> None:
        """Remove a session that holds no capture (session.yaml, the header and the folder if then empty):
        a new session that could not start leaves nothing behind."""
        for name in ("captures.csv", "session.yaml"):
            (self.folder / name).unlink(missing_ok=True)
        if not any(self.folder.iterdir()):
            self.folder.rmdir()

    def counts(self, names) -> dict:
        """Captures on disk per point name."""
        return {nm: self.point.count(nm) for nm in names}

    def close(self) -> None:
        """Close the file (again: nothing)."""
        if self._fd is not None:
            os.close(self._fd)
            self._fd = None
