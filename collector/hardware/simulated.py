"""What the command line knows of the simulated worlds: the backends that are simulated and the effects a
fake world can switch -- names and options only, so that parsing a command never imports a world
(:mod:`lasercal.collector.worlds`)."""

from __future__ import annotations

from lasercal.solver.errors import LasercalError

SIMULATED = ("fake", "mujoco")  # backends whose arm is simulated: their moves need no confirmation
EFFECTS = (
    "repeatability",
    "distortion",
    "occlusion",
    "ellipse",
    "print-scale",
    "sheet-height",
    "table-slope",
    "paper-curl",
    "print-shear",
    "subsurface",
)


def parse_effects(text: str | None, camera: bool) -> tuple:
    """The effects a ``--effects`` value switches on: ``all``, ``none`` or names separated by commas.

    Parameters
    ----------
    text : str or None, the option's value (None: all with a fake camera, none without)
    camera : bool, the session has a fake camera

    Raises
    ------
    LasercalError
        An unknown name, naming the option and the names it takes.
    """
    if text is None:
        return EFFECTS if camera else ()
    text = text.strip()
    if text == "all":
        return EFFECTS
    if text == "none":
        return ()
    names = [t.strip() for t in text.split(",")]
    bad = [t for t in names if t not in EFFECTS]
    if bad or not names:
        raise LasercalError(
            f"--effects {text!r}: unknown effect {bad[0] if bad else ''!r} (expected all, none or a comma "
            f"list of {', '.join(EFFECTS)})"
        )
    return tuple(e for e in EFFECTS if e in names)
