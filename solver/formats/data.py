"""The robot and layout files shipped inside the package (``lasercal.data``), found by name or path."""

from __future__ import annotations

import os
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


def reference(kind: str, name_or_path, folder, base: Path | None = None) -> str:
    """How a file written in ``folder`` names a robot or layout so that the folder can move: a built-in
    by its name, any other file by its path relative to ``folder`` (read back with ``base=folder``).

    Parameters
    ----------
    kind : "robots" or "layouts"
    name_or_path : str or Path, a built-in name or a file (relative to ``base`` first, then the working
        folder)
    folder : str or Path, the folder of the file that stores the reference (it need not exist yet)
    base : Path or None, the folder a relative ``name_or_path`` is relative to

    Returns
    -------
    str
    """
    path = resolve(kind, name_or_path, base).resolve()
    if path.parent == builtin_dir(kind).resolve():
        return path.stem
    return os.path.relpath(path, Path(folder).resolve())


def truth_references(truth: Path, folder, robot=None) -> tuple[str, str]:
    """How a simulated session in ``folder`` names its truth and its nominal robot (:func:`reference`).

    Parameters
    ----------
    truth : Path, the true robot's file
    folder : the session folder
    robot : str or None, the nominal robot given (a name, or a file from the working folder); None: the
        truth file's ``nominal`` key (relative to the truth file), else the truth itself

    Returns
    -------
    (truth, nominal) : str, str
    """
    from lasercal.solver.formats.checks import load_yaml

    truth = Path(truth)
    raw = load_yaml(truth) if truth.suffix.lower() != ".urdf" else {}
    if robot is not None:
        nominal = reference("robots", robot, folder)
    elif isinstance(raw, dict) and raw.get("nominal"):
        nominal = reference("robots", raw["nominal"], folder, base=truth.parent)
    else:
        nominal = reference("robots", truth, folder)
    return reference("robots", truth, folder), nominal
