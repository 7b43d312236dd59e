"""The floors a camera session's error is measured against (issue 45 item 8): what the true robot itself
achieves at a point of the fake world's true paper, photographed as ``validate`` does.

A study, not a world: it runs a validation's pieces (standstill, measurement) in a world it reaches through
the backend factory, as a session does.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from lasercal.collector.hardware import make_robot, session_world, top_camera
from lasercal.solver.formats.robots import load_model, load_yaml


def floors(session, layout_file, point: str, n: int = 30, seed: int = 0) -> tuple[float, float]:
    """What no model can beat at ``point`` in a simulated session's world: the true robot itself, aimed at
    the point where it truly lies on the paper (its bulge, skew, slope and height included) and commanded
    through its own effects, validated as ``validate --backend fake -n N`` photographs (the same camera,
    spot and repeatability; the configurations the truth's aiming IK finds with ``seed``).

    Parameters
    ----------
    session : a simulated sheet session's folder (``capture --backend fake``)
    layout_file : its layout (the sheet's printed points)
    point : str, the point to validate at
    n : int, configurations; seed : int, their seed (validate's ``--seed``)

    Returns
    -------
    (honest, repeatability) : mean distances on the paper, mm: the honest floor (the spot as the camera
    measures it, against the printed point) and the repeatability floor (where the true beam truly meets the
    paper, the camera left out)
    """
    from lasercal.collector.sessions.standstill import wait_still
    from lasercal.collector.sessions.validate import ValidateOptions, measure_known_view
    from lasercal.solver.formats.session import load_layout
    from lasercal.solver.kinematics.aim import aim

    world = session_world(session)
    layout = load_layout(layout_file)
    effects = world.effects
    paper = effects.paper(world.sheet, layout.plane_z)
    printed = np.asarray(layout.points[point][:2], dtype=float)
    cfg = {**load_yaml(Path(session) / "session.yaml")["collector"], "seed": seed}
    robot = make_robot(
        cfg, load_model(cfg["robot"]), layout, truth=world.truth, repeat_sigma=effects.repeat_sigma
    )
    camera = top_camera(robot, printed, layout.plane_z, seed, paper, effects)
    robot.connect()
    opts = ValidateOptions()
    measured, true = [], []
    for q in aim(world.truth, paper.surface(printed[None])[0], n, seed, **layout.aim_kwargs()):
        robot.move_to(robot.effects.encoders(q[None], robot.clock.now())[0])
        wait_still(robot, opts.speed_threshold, opts.hold, opts.still_timeout, opts.poll)  # as validate waits
        a, d = robot.true_beam()
        true.append(np.linalg.norm(paper.hit(a, d)[0][0] - printed))
        measured.append(np.linalg.norm(measure_known_view(camera.photo(), "floor", camera.view)[0] - printed))
    return float(np.mean(measured)), float(np.mean(true))
