"""How a joint is named in everything a person reads: one function for every command and report.

A serial arm's joint is its number ('joint 4', 'c4'), which is also what its name says (``panda_joint4``).
A tree's joints are numbered over its branches and lateral axes (DLR's Justin: ``torso_2`` is joint 4,
``left_7`` joint 52), so a number would name a joint the user cannot find: there every joint is named by
its name, ``torso_1`` too (whose name happens to say 1).
"""

from __future__ import annotations


def _numbered(names) -> bool:
    """Whether every joint's name says its 1-based number (panda_joint1..7, joint1..6)."""
    return all("".join(ch for ch in nm if ch.isdigit()) == str(i + 1) for i, nm in enumerate(names))


def joint_tags(joints, names=()) -> list[str]:
    """What follows 'joint ' for each 1-based joint: its number on a model whose names say the numbers,
    else its name ('torso_2'); the numbers when the names are not known.

    Parameters
    ----------
    joints : iterable of int, 1-based joint numbers
    names : sequence of n str, the model's joint names (all of them)

    Returns
    -------
    list of str, e.g. ['2', '3'] or ['torso_2', 'right_1.x']
    """
    names = tuple(names)
    if not names or _numbered(names):
        return [str(j) for j in joints]
    return [names[j - 1] for j in joints]


def joint_label(j: int, names) -> str:
    """'joint 4' for the 0-based index j, or 'joint left_7' on a tree (whose lateral axes count among the
    joints: left_7 is its joint 52). ``names``: the model's joint names."""
    return f"joint {joint_tags([j + 1], names)[0]}"


def parameter_name(letter: str, tag: str) -> str:
    """A joint effect's parameter: 'c4' on a numbered joint, 'c[torso_2]' on a named one."""
    return f"{letter}{tag}" if tag.isdigit() else f"{letter}[{tag}]"
