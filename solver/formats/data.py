"""The robot and layout files shipped inside the package (``lasercal.data``), found by name or path."""

from __future__ import annotations

from importlib.resources import files
from pathlib import Path

from lasercal.solver.errors import FormatError


def builtin_dir(kind: str) -> Path:
    """The folder of built-in ``robots`` or ``layouts`` YAML files inside the installed package."""
    # files() gives a real directory for an installed wheel and for an editable install alike
    return Path(str(files("lasercal.data") / kind))


def resolve(kind: str, name_or_path, base: Path | None = None) -> Path:
    """A file given by path (relative to ``base`` first, then the working folder) or a built-in name.

    Parameters
    ----------
    kind : "robots" or "layouts"
    name_or_path : str or Path, e.g. ``panda`` or ``my_robot.yaml``
    base : Path or None, the folder a relative path in another file is relative to

    Returns
    -------
    Path of an existing file

    Raises
    ------
    FormatError
        Neither a file nor a built-in name; the message lists the built-in names.
    """
    p = Path(str(name_or_path))
    shipped = builtin_dir(kind)
    candidates = (
        [p] if p.is_absolute() else ([base / p] if base else []) + [p, shipped / p, shipped / f"{p}.yaml"]
    )
    for c in candidates:
        if c.is_file():
            return c
    known = ", ".join(sorted(f.stem for f in shipped.glob("*.yaml")))
    raise FormatError(name_or_path, f"no such {kind[:-1]} file or name (built-in {kind}: {known})")
