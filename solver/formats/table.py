"""The one CSV reader: data lines of a text table with their line numbers, for errors that name them.

Every CSV file lasercal reads (captures, configurations, circle points, validations, MUKCa holes)
goes through :func:`csv_rows`: decoded by :func:`~lasercal.solver.formats.checks.read_text`
(non-UTF-8 is a one-line error), blank lines and ``#`` comment lines skipped, cells stripped, and a
last line cut short refused (:func:`check_last_line`).
"""

from __future__ import annotations

import csv
import io

from lasercal.solver.errors import FormatError, warn
from lasercal.solver.formats.checks import read_text


def csv_rows(path, repair: str | None = None) -> list[tuple[int, list[str]]]:
    """The data lines of a CSV file, checked for a last line cut short (:func:`check_last_line`).

    Parameters
    ----------
    path : str or Path
    repair : str, optional, how to mend a torn last line, for a file written row by row (a log
        grown by a running session: captures.csv, validation.csv), whose every row ends with a line end

    Returns
    -------
    list of (line, cells): the file's line number (1-based) and the stripped cells of each
    non-blank, non-comment line
    """
    text = read_text(path)
    reader = csv.reader(io.StringIO(text))
    rows = []
    for cells in reader:
        if any(c.strip() for c in cells) and not cells[0].lstrip().startswith("#"):
            rows.append((reader.line_num, [c.strip() for c in cells]))
    check_last_line(path, text, rows, repair)
    return rows


def check_last_line(path, text: str, rows: list, repair: str | None = None) -> None:
    """A last data row without a line end was cut short (a write killed, a partial copy): refused when
    it has fewer or more cells than the first row, or in a file written row by row (``repair`` says
    how to mend it); otherwise a warning (a file saved by an editor that ends no line may be whole).

    Raises
    ------
    FormatError
        Naming the file and the line.
    """
    if not rows or text.endswith("\n") or rows[-1][0] != text.count("\n") + 1:
        return
    line, cells = rows[-1]
    width = len(rows[0][1])
    if repair is not None or (len(rows) > 1 and len(cells) != width):
        raise FormatError(
            path,
            f"cut short: the last line has {len(cells)} of {width} values and no line end (a write killed, "
            f"or a partial copy); {repair or 'expected whole lines'}",
            line=line,
        )
    warn(
        f"{path}, line {line}: the last line has no line end: cut short? (expected a line end after each row)"
    )


def read_csv(path, repair: str | None = None) -> tuple[list[str], list[tuple[int, list[str]]]]:
    """A CSV file with a header: (column names, data rows as in :func:`csv_rows`; ``repair`` as there).

    Raises
    ------
    FormatError
        An empty file, or a column named twice (naming the line and column).
    """
    rows = csv_rows(path, repair)
    if not rows:
        raise FormatError(path, "empty file: expected a header line")
    line, header = rows[0]
    twice = [c for i, c in enumerate(header) if c and c in header[:i]]
    if twice:  # else the first would be read and the second passed over in silence
        raise FormatError(path, f"column {twice[0]!r} appears twice in the header", line=line, field=twice[0])
    return header, rows[1:]
