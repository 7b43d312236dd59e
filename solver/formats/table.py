"""The one CSV reader: data lines of a text table with their line numbers, for errors that name them.

Every CSV file lasercal reads (captures, configurations, circle points, validations, MUKCa holes)
goes through :func:`csv_rows`: decoded by :func:`~lasercal.solver.formats.checks.read_text`
(non-UTF-8 is a one-line error), blank lines and ``#`` comment lines skipped, cells stripped.
"""

from __future__ import annotations

import csv
import io

from lasercal.solver.errors import FormatError
from lasercal.solver.formats.checks import read_text


def csv_rows(path) -> list[tuple[int, list[str]]]:
    """The data lines of a CSV file.

    Parameters
    ----------
    path : str or Path

    Returns
    -------
    list of (line, cells): the file's line number (1-based) and the stripped cells of each
    non-blank, non-comment line
    """
    reader = csv.reader(io.StringIO(read_text(path)))
    rows = []
    for cells in reader:
        if any(c.strip() for c in cells) and not cells[0].lstrip().startswith("#"):
            rows.append((reader.line_num, [c.strip() for c in cells]))
    return rows


def read_csv(path) -> tuple[list[str], list[tuple[int, list[str]]]]:
    """A CSV file with a header: (column names, data rows as in :func:`csv_rows`).

    Raises
    ------
    FormatError
        An empty file, or a column named twice (naming the line and column).
    """
    rows = csv_rows(path)
    if not rows:
        raise FormatError(path, "empty file: expected a header line")
    line, header = rows[0]
    twice = [c for i, c in enumerate(header) if c and c in header[:i]]
    if twice:  # else the first would be read and the second passed over in silence
        raise FormatError(path, f"column {twice[0]!r} appears twice in the header", line=line, field=twice[0])
    return header, rows[1:]
