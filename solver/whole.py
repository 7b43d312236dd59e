"""Whole files: every YAML file lasercal writes says where it ends, so a copy cut short is refused.

A kill in the middle of a write, a disk filling up or a partial copy leaves the first part of a file.
A YAML file cut at a line end still parses, and the keys it lost take their defaults (a session cut
inside ``requested:`` loses ``frame: sheet``, and its sheet's points are read as base-frame points).
So each file lasercal writes opens with :data:`WHOLE` and ends with YAML's end of document ``...``
(:func:`dump_yaml`): any YAML reader reads it, and one that opens with that line and lacks the end is
cut short (:func:`cut_short`). A file written by hand or by another program makes no such claim and
is checked by its keys alone. ``vision/camera.py`` keeps the same line (vision stands alone).
"""

from __future__ import annotations

WHOLE = "# whole file: it ends with the line '...' (a copy cut short lacks it)"
"""The first line of every YAML file lasercal writes (module docstring)."""


def dump_yaml(doc, head: str = "", **kw) -> str:
    """``doc`` as the text of a whole YAML file: :data:`WHOLE`, ``head`` (comment lines), then
    ``yaml.safe_dump(doc, **kw)`` and ``...``."""
    import yaml

    return f"{WHOLE}\n{head}" + yaml.safe_dump(doc, explicit_end=True, **kw)


def cut_short(text: str) -> int | None:
    """The number of lines of a YAML text that says it is whole (:data:`WHOLE`) and does not end with
    its end line ``...``; None for a whole text, or one that makes no such claim."""
    lines = text.split("\n")
    if WHOLE not in (ln.rstrip() for ln in lines):
        return None
    body = [ln.rstrip() for ln in lines if ln.strip()]
    return None if body[-1] == "..." else len(lines) - (not lines[-1])
