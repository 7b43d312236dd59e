"""Issue 46: a world lasercal did not draw -- the mujoco backend and camera, the world-file contract, the
default scene, the pieces an outside tool needs, and a short calibration in MuJoCo.

Truths here are independent of lasercal's kinematics: MuJoCo's own forward kinematics and ray of the world
(franky-sim's FR3, MuJoCo Menagerie's model), checked against Franka's published DH table (lasercal's
``fr3``) on the unperturbed scene; a passive spring's deflection against its stiffness and MuJoCo's
gravity torque. Without MuJoCo every test skips with the pip command; without a renderer (Mesa's EGL) the
tests that photograph skip with one reason.
"""

from __future__ import annotations

import csv
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml

os.environ.setdefault("MUJOCO_GL", "egl")  # before MuJoCo is imported: it picks its renderer then
pytest.importorskip("mujoco", reason="MuJoCo is not installed: pip install 'lasercal[mujoco]'")
pytest.importorskip(
    "franky_sim", reason="the default scene's arm is franky-sim's: pip install 'lasercal[sim]'"
)
pytest.importorskip("pypdfium2", reason="the sheet's texture needs pypdfium2: pip install 'lasercal[mujoco]'")

from lasercal.collector.sessions.spotcam import measure_spot  # noqa: E402
from lasercal.collector.sessions.standstill import wait_still  # noqa: E402
from lasercal.collector.worlds.mujoco import MujocoCamera, MujocoRobot, MujocoWorld  # noqa: E402
from lasercal.solver.formats.robots import load_model  # noqa: E402
from lasercal.solver.formats.session import load_layout  # noqa: E402
from lasercal.solver.identify.spot import predict_spots  # noqa: E402
from lasercal.solver.kinematics.aim import aim  # noqa: E402
from lasercal.vision.plane import load_markers  # noqa: E402
from tests.conftest import made_once  # noqa: E402


def lasercal(*args, cwd=None):
    """The command line in a child process: (exit code, stdout, stderr)."""
    p = subprocess.run(
        [sys.executable, "-m", "lasercal.collector.cli.main", *map(str, args)],
        capture_output=True,
        text=True,
        cwd=cwd,
        env={**os.environ, "MUJOCO_GL": os.environ.get("MUJOCO_GL", "egl")},
    )
    return p.returncode, p.stdout, p.stderr


def make_sheet(folder: Path) -> None:
    code, _, err = lasercal("sheet", "-o", folder / "sheet", "--robot", "fr3", "--place", 450, 0, 0)
    assert code == 0, err


@pytest.fixture(scope="module")
def scenes(tmp_path_factory):
    """A printed sheet at 450 0 0, its exact scene (no perturbation) and a perturbed one with a spring of
    1e-4 rad/Nm after joint 2."""

    def make(folder: Path) -> None:
        make_sheet(folder)
        for name, extra in (("exact", ["--exact"]), ("spring", ["--seed", 1, "--spring", "2:1e-4"])):
            code, _, err = lasercal(
                "mujoco-scene", "--layout", folder / "sheet" / "layout.yaml", "-o", folder / name, *extra
            )
            assert code == 0, err

    return made_once(tmp_path_factory, "mujoco_scenes", make)


@pytest.fixture(scope="module")
def renders(scenes):
    """Skip (one reason) where MuJoCo cannot render headless."""
    cam = MujocoCamera(MujocoWorld(scenes / "exact" / "scene.xml"))
    try:
        cam.photo()
    except Exception as e:
        pytest.skip(f"MuJoCo cannot render here (MUJOCO_GL={os.environ.get('MUJOCO_GL')}): {e}")
    finally:
        cam.close()


def settle_at(world: MujocoWorld, q) -> None:
    world.command(q)
    world.step(world._path[1] + 1.5)


def test_the_exact_scene_is_franka_published_kinematics(scenes):
    """Unperturbed, MuJoCo's beam (the laser site on franky-sim's FR3, cast with mj_ray onto the sheet body)
    meets the sheet where lasercal's nominal fr3 (Franka's DH table, the laser 101 mm past the flange) puts
    its spot, on the sheet at its placement: one world, two independent descriptions."""
    layout = load_layout(scenes / "sheet" / "layout.yaml")
    nominal = load_model("fr3")
    world = MujocoWorld(scenes / "exact" / "scene.xml")
    rng = np.random.default_rng(4)
    for p in layout.in_base().points.values():
        q = aim(nominal, p, 1, rng)[0]
        world.d.qpos[world.c.qadr] = q
        hit = world.ray()[0]
        spot, _ = predict_spots(nominal, q[None], layout.plane_z)
        on_sheet = layout.sheet.from_base(spot)[0]
        assert np.abs(world.on_sheet(hit)[:2] - on_sheet).max() < 1e-6  # mm
        assert abs(world.on_sheet(hit)[2]) < 1e-9


def test_the_beam_meets_what_the_camera_sees(scenes):
    """Issue 53: the ray is cast against the geom groups MuJoCo's renderer draws (0-2, never lasercal's
    spot, 5); a geom moved to a collision-only group (3) no longer stops the beam, as it no longer shows."""
    layout = load_layout(scenes / "sheet" / "layout.yaml")
    world = MujocoWorld(scenes / "exact" / "scene.xml")
    drawn = np.asarray(world.mj.MjvOption().geomgroup)
    assert world.ray_groups.tolist() == [int(g < 5 and drawn[g] > 0) for g in range(6)] == [1, 1, 1, 0, 0, 0]
    p = layout.in_base().points["P6"]
    world.d.qpos[world.c.qadr] = aim(load_model("fr3"), p, 1, np.random.default_rng(0))[0]
    hit, paper, _ = world.ray()
    assert abs(world.on_sheet(hit)[2]) < 1e-9  # on the paper
    world.m.geom_group[paper] = 3
    through, behind, _ = world.ray()
    assert behind != paper and (through is None or world.on_sheet(through)[2] < -1e-6)  # past the paper


def test_a_curled_sheet_is_the_parabola_the_beam_meets_and_the_flat_page_the_camera_sees(scenes, tmp_path):
    """``mujoco-scene --curl MM`` (issue 52): the paper is a mesh rising as z = curl (x / half height)^2
    (eq. M1) -- the beam meets it there, to the mesh's chord error (1.3 um at 41 vertices a side); at a
    vanishing curl the camera's photo is the flat plane's (the texture laid the same way: measured mean
    difference 0.009 of 255; a page flipped or mirrored differs by ~2)."""
    sheet = scenes / "sheet" / "layout.yaml"
    for name, curl in (("c2", 2), ("c0", 1e-6)):
        code, _, err = lasercal(
            "mujoco-scene", "--layout", sheet, "-o", tmp_path / name, "--exact", "--curl", curl
        )
        assert code == 0, err
    layout = load_layout(sheet)
    half = yaml.safe_load(sheet.read_text())["paper"]["height_mm"] / 2
    world = MujocoWorld(tmp_path / "c2" / "scene.xml")
    for k, p in enumerate(layout.in_base().points.values()):
        world.d.qpos[world.c.qadr] = aim(load_model("fr3"), p, 1, np.random.default_rng(k))[0]
        x, _, z = world.on_sheet(world.ray()[0])
        assert abs(z - 2 * (x / half) ** 2) < 2e-3, (x, z)
    flat = MujocoCamera(MujocoWorld(scenes / "exact" / "scene.xml")).photo().astype(float)
    mesh = MujocoCamera(MujocoWorld(tmp_path / "c0" / "scene.xml")).photo().astype(float)
    assert np.abs(flat - mesh).mean() < 0.1


def test_eq_s8_explains_what_the_camera_sees_of_a_curled_page(tmp_path, renders):
    """MuJoCo's photos of a page curled by 2 mm (eq. M1), measured as a capture measures them: the spots lie
    0.4-0.7 mm RMS from where MuJoCo's ray meets the paper, and eq. S8 (from the eye the photo's markers
    gave, with M1's curl) leaves at most 0.15 of it. benchmarks/bench_parallax_mujoco.py measured the ratio
    over 20 draws: median 0.071; over the 9 draws with 5-6 photos measured (as this one: seed 1, 6) at most
    0.115. A field 25 % too large leaves 0.2 here, the raw view 1. What remains (0.03-0.05 mm along the
    camera's side, 7 % of the field) is not in the exact ray geometry with ideal corners
    (tests/test_parallax.py): see docs/diagnosis.md."""
    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
    from bench_parallax_mujoco import curled_scene, seen_and_true

    scene = curled_scene(tmp_path, 2.0)
    e = seen_and_true(scene, tmp_path / "sheet" / "layout.yaml", 2.0, 6, seed=1)
    rms = np.sqrt(np.mean(e**2, axis=0))  # (as measured, after eq. S8, the field) x (x, y)
    print("RMS as measured, after eq. S8, of the field (x, y):", rms)
    assert len(e) >= 5
    assert np.linalg.norm(rms[0]) > 0.3, rms  # the curl's view is there to explain
    assert np.linalg.norm(rms[1]) < 0.15 * np.linalg.norm(rms[0]), rms


def test_the_camera_stands_where_camera_at_puts_it_and_its_markers_say_so(scenes, tmp_path, renders):
    """``mujoco-scene --camera-at DX DY DZ`` (issue 53: other placements): MuJoCo's camera stands there from
    the sheet's centre (scene.yaml records it), and a photo's markers put it there (eq. V2) within 1 % of its
    distance: over 5 placements (350 0 600, 0 450 600, -250 -350 700, 200 200 500, 0 -300 900) the markers
    said 0.04-0.45 %. A camera under the sheet is refused."""
    from lasercal.vision.images import to_gray
    from lasercal.vision.plane import camera_eye, find_fiducials, fit_plane

    sheet = scenes / "sheet" / "layout.yaml"
    at = np.array([0.0, 450.0, 600.0])
    code, _, err = lasercal(
        "mujoco-scene", "--layout", sheet, "-o", tmp_path / "side", "--exact", "--camera-at", *at
    )
    assert code == 0, err
    assert yaml.safe_load((tmp_path / "side" / "scene.yaml").read_text())["camera_at_mm"] == at.tolist()
    world = MujocoWorld(tmp_path / "side" / "scene.xml")
    np.testing.assert_allclose(world.on_sheet(world.d.cam_xpos[world.c.camera]), at, atol=1e-6)
    world.d.qpos[world.c.qadr] = [0, -0.8, 0, -2.6, 0, 1.9, 0.8]  # the arm folded back, out of the view
    world.mj.mj_forward(world.m, world.d)
    img = MujocoCamera(world).photo()
    markers, size = load_markers(sheet), (img.shape[1], img.shape[0])
    plane = fit_plane(find_fiducials(to_gray(img), markers, 1.0, None), markers, None, size, "side")
    assert np.linalg.norm(camera_eye(plane.H, size) - at) < 0.01 * np.linalg.norm(at)
    code, _, err = lasercal("mujoco-scene", "--layout", sheet, "-o", tmp_path / "x", "--camera-at", 0, 0, -5)
    assert code == 2 and "above it" in err


def test_the_arm_holds_a_commanded_pose_and_reports_its_gravity_torques(scenes):
    """Position servos with gravity compensation: after a move and standstill the encoders read the command
    (to 1e-5 rad), the speeds are still, and the torques are MuJoCo's gravity torques of the arm there."""
    world = MujocoWorld(scenes / "exact" / "scene.xml")
    robot = MujocoRobot(world)
    robot.connect()
    q = np.array([0.3, -0.4, 0.2, -2.3, 0.1, 1.9, 0.6])
    robot.move_to(q)
    state, _ = wait_still(robot, 0.005, 0.5, 30.0, 1 / 64)
    assert state is not None and np.abs(state.q - q).max() < 1e-5  # the servo's last settling, < 0.01 mm
    import mujoco

    d = mujoco.MjData(world.m)
    d.qpos[:] = world.d.qpos
    mujoco.mj_forward(world.m, d)  # qfrc_bias at rest: gravity
    np.testing.assert_allclose(state.tau, d.qfrc_bias[world.c.dadr], atol=2e-3)  # still settling: mNm
    assert np.abs(state.tau[1]) > 5  # joint 2 carries the arm


def test_a_passive_spring_bends_by_its_compliance_times_the_torque(scenes):
    """The spring after joint 2 (1e-4 rad/Nm): at rest its deflection is the compliance times joint 2's
    torque (the weight of everything after it), which the encoder of joint 2 does not see."""
    world = MujocoWorld(scenes / "spring" / "scene.xml")
    spring = world.m.joint("passive_joint2")
    for q in ([0, -0.3, 0, -2.2, 0, 1.9, 0.8], [0.5, 0.4, -0.3, -1.6, 0.2, 2.4, 0.0]):
        settle_at(world, np.array(q))
        state = world.state()
        bend = world.d.qpos[spring.qposadr[0]]
        assert np.abs(state.q - q).max() < 1e-6  # joint 2 holds; the link bends beyond it
        np.testing.assert_allclose(bend, -1e-4 * state.tau[1], rtol=0.01)
        assert abs(bend) > 5e-4


def test_the_simulated_operator_puts_mujoco_beam_on_the_printed_point(scenes):
    """Hand-guiding without noise: from a pose of the nominal robot the operator nudges the arm, watching
    MuJoCo's spot, until the beam meets the point where the sheet body holds it (the perturbed world with
    its spring, where the nominal pose misses by millimetres)."""
    from lasercal.collector.worlds.mujoco import make_mujoco_robot

    layout = load_layout(scenes / "sheet" / "layout.yaml")
    cfg = {"world": scenes / "spring" / "scene.xml", "aim_noise": 0.0, "seed": 0}
    robot = make_mujoco_robot(cfg, load_model("fr3"), layout.in_base(), 1, layout.sheet)
    robot.connect()
    for name in ("P1", "P5"):
        robot.prompt_point(name, layout.in_base().points[name], 0)
        hit = robot.world.ray()[0]
        assert np.abs(robot.world.on_sheet(hit)[:2] - layout.points[name][:2]).max() < 1e-3  # mm


def test_a_backlash_is_a_passive_joint_gravity_takes_to_an_end(tmp_path, scenes):
    """--backlash 2:0.002: a passive hinge after joint 2 free over 2 mrad; joint 2's torque (tens of Nm)
    takes it to the end of its range its sign says (a spring's bend's sign, -compliance x torque), where the
    arm comes to rest."""
    code, _, err = lasercal(
        "mujoco-scene", "--layout", scenes / "sheet" / "layout.yaml", "-o", tmp_path / "bl", "--exact",
        "--backlash", "2:0.002",
    )  # fmt: skip
    assert code == 0, err
    world = MujocoWorld(tmp_path / "bl" / "scene.xml")
    j = world.m.joint("passive_joint2")
    assert world.m.jnt_range[j.id].tolist() == [-0.001, 0.001]
    robot = MujocoRobot(world)
    robot.connect()
    for q in ([0, -0.3, 0, -2.2, 0, 1.9, 0.8], [0, 0.5, 0, -1.5, 0, 2.0, 0.8]):
        robot.move_to(np.array(q))
        state, peak = wait_still(robot, 0.005, 0.5, 30.0, 1 / 64)
        assert state is not None, peak  # it comes to rest at its end (no chatter)
        tau2 = state.tau[1]
        # at the end its torque pushes it to, and past it by the soft limit's give (~1e-4 rad/Nm)
        bend = -world.d.qpos[j.qposadr[0]] * np.sign(tau2)
        assert 0.001 - 1e-5 < bend < 0.001 + 2e-4 * abs(tau2)


def test_a_friction_holds_the_spring_where_the_motion_stopped(tmp_path, scenes):
    """--spring 2:1e-4 --friction 2:3: the hinge rests within +-friction x compliance (3e-4 rad) of the
    spring's rest, where the motion left it, so one pose reached from two sides rests at two bends; and it
    stays there (MuJoCo's default soft friction crept to the spring's rest: the two bends agreed to 1e-9)."""
    code, _, err = lasercal(
        "mujoco-scene", "--layout", scenes / "sheet" / "layout.yaml", "-o", tmp_path / "fr", "--exact",
        "--spring", "2:1e-4", "--friction", "2:3",
    )  # fmt: skip
    assert code == 0, err
    world = MujocoWorld(tmp_path / "fr" / "scene.xml")
    j = world.m.joint("passive_joint2").qposadr[0]
    q = np.array([0, -0.3, 0, -2.2, 0, 1.9, 0.8])
    off = []
    for before in ([0, -0.9, 0, -2.2, 0, 1.9, 0.8], [0, 0.3, 0, -2.2, 0, 1.9, 0.8]):
        settle_at(world, np.array(before))
        settle_at(world, q)
        tau2, bend = world.state().tau[1], world.d.qpos[j]
        world.step(2.0)
        assert abs(world.d.qpos[j] - bend) < 1e-5  # it stays: 0.007 mm at the flange's 0.7 m
        off.append(bend + 1e-4 * tau2)  # from the spring's rest, -compliance x torque
    assert all(abs(o) <= 3e-4 * 1.01 for o in off), off
    assert abs(off[0] - off[1]) > 1e-4, off


@pytest.mark.usefixtures("renders")
def test_the_camera_measures_the_spot_where_mujoco_ray_meets_the_sheet(scenes):
    """Photos rendered by MuJoCo (the spot drawn where mj_ray hits), measured through the sheet's markers as
    a real camera's are: within 3 stated sigmas of the ray's hit on the printed sheet, RMS <= 0.05 mm."""
    layout = load_layout(scenes / "sheet" / "layout.yaml")
    markers = load_markers(scenes / "sheet" / "layout.yaml")
    world = MujocoWorld(scenes / "exact" / "scene.xml")
    cam = MujocoCamera(world)
    nominal = load_model("fr3")
    rng = np.random.default_rng(2)
    err = []
    for xy in ([10, -30], [-30, 50], [25, 60], [-20, -70], [0, 20]):
        q = aim(nominal, layout.sheet.to_base(np.array([xy], float), layout.plane_z)[0], 1, rng)[0]
        settle_at(world, q)
        m = measure_spot(cam.photo(), "p", markers)
        err.append(m.xy - world.on_sheet(cam.last_hit)[:2])
        assert np.all(np.abs(err[-1]) < 3 * m.sigma)  # within its stated uncertainty
    cam.close()
    assert np.sqrt((np.array(err) ** 2).mean()) < 0.05


# CI's MuJoCo session (issue 51): the README's row (45 captures, seed 0, validate -n 30: nominal 8.814 ->
# 0.024 mm; with --spring 2:1e-4 the spring named at joint 2, c = -1.0039e-4, 8.912 -> 0.103 mm) at the
# smallest size that still tests it: 30 captures (--per-point 6; 15 named no spring on seeds 0 and 1) in
# the spring scene, validate -n 4 at P6. Measured by benchmarks/bench_mujoco_short.py (docs/sessions.md):
# at this size the spring is named at joint 2 on seeds 1-3, c -1.0049e-4 to -0.9957e-4; calibrated at P6
# 0.889 (seed 1: its validation poses lie where its 30 captures did not pin the geometry), 0.103, 0.137
# mm; the README's own session (45 captures, seed 0) gives 0.165 mm at -n 4. The session is
# deterministic (MuJoCo's photos carry no noise draw; the arm's and the coach's draws are keyed by the
# capture, not by q's bits), so the figures of its seed are the ones to reproduce, within 2x. Seed 3: every
# configuration but one (the arm hides its spot from the camera) measured in both validations.
SEED, PER_POINT = 3, 6
FIGURE = {"nominal": 6.437, "calibrated": 0.137}  # validate -n 4 at P6, error mean, mm
HIDDEN = {"nominal": [2], "calibrated": [2]}  # the configurations whose spot the arm hides from the camera


@pytest.fixture(scope="module")
def session(scenes, renders, tmp_path_factory):
    """Capture (hands-free: the arm driven through the coach's poses, each photographed by MuJoCo's camera
    and measured), solve --extend auto, validate the nominal and the calibrated model at P6: made once per
    run (shared by the xdist workers), every command's exit code and output kept."""

    def make(d: Path) -> None:
        sheet, world = scenes / "sheet" / "layout.yaml", d / "scene" / "scene.xml"
        runs = {}
        runs["scene"] = lasercal(
            "mujoco-scene", "--layout", sheet, "-o", d / "scene", "--seed", SEED, "--spring", "2:1e-4"
        )
        common = ["--backend", "mujoco", "--world", world, "--robot", "fr3"]
        runs["capture"] = lasercal(
            "capture", *common, "--layout", sheet, "--camera", "mujoco", "--guide", "move", "--auto",
            "--per-point", PER_POINT, "-o", d / "s",
        )  # fmt: skip
        runs["solve"] = lasercal("solve", d / "s", "-o", d / "m.yaml", "--folds", 0, "--extend", "auto")
        for name, model, extra in (
            ("nominal", "fr3", ["--sheet-from", d / "m.yaml"]),
            ("calibrated", d / "m.yaml", []),
        ):
            at = ["--layout", sheet, "--point", "P6", "-n", 4]
            runs[name] = lasercal("validate", model, *at, *common, *extra, "-o", d / name)
        (d / "runs.json").write_text(json.dumps(runs))

    d = made_once(tmp_path_factory, "mujoco_session", make)
    return d, json.loads((d / "runs.json").read_text())


def test_a_hands_free_session_names_the_spring_at_joint_2(session):
    """The spring after joint 2 (1e-4 rad/Nm, which the encoder does not see) is what solve --extend auto
    finds: a compliance of joint 2 whose c -- lasercal's sign: q_link = q + c tau, tau the torque holding the
    arm, so a link sagging under it has c < 0 (the spring's bend is -1e-4 tau, as the test above measures)
    -- is the spring's within 4 of its reported sigmas (their calibration: README, standardised errors RMS
    1.01-1.05, so 4 sigma fails 1 in 7,000; measured: 0.31, 0.11, 0.10 sigma on seeds 1-3 at this size,
    0.53 on the README's 45 captures: lasercal's gravity model, franka_description's inertials, agrees with
    franky-sim's MuJoCo arm below that)."""
    d, runs = session
    assert [runs[k][0] for k in ("scene", "capture", "solve")] == [0, 0, 0], runs
    out = runs["solve"][1]
    assert "finding: joint_compliance at joint 2 (" in out, out
    jc = yaml.safe_load((d / "m.yaml").read_text())["extensions"]["joint_compliance"]
    assert jc["joints"] == [2], jc
    c = jc["c"][0]
    se = float(out.split("c2 = ")[1].split("+-")[1].split()[0])
    assert c < 0 and abs(c + 1e-4) < 4 * se, (c, se)


def test_a_mujoco_session_records_its_own_backends_settings(session):
    """Issue 53: session.yaml names the MuJoCo world and the simulated operator's aim, not the fake arm's
    true robot (a MuJoCo session has none: the world file is its truth)."""
    d, _ = session
    meta = yaml.safe_load((d / "s" / "session.yaml").read_text())
    assert meta["collector"]["backend"] == "mujoco" and "truth" not in meta["collector"], meta["collector"]
    assert meta["simulated"]["world"] == meta["collector"]["world"] and "truth" not in meta["simulated"]


def test_a_hands_free_mujoco_session_keeps_no_clipped_spot(session):
    """Issue 53: the exposure keeps adjusting until a spot is read unclipped (before: settled at the first
    photo whatever it showed, then 38 of 39 spots kept clipped over 70-93 px); and the coach plans for the
    camera's view, so the arm hides no spot it asked for (measured: 45 of 45 on seeds 0-2 of the default
    scene, bench_mujoco.py; 40 before). Here every kept spot is unclipped and the coach says where the
    camera stands."""
    d, runs = session
    with open(d / "s" / "captures.csv") as f:
        rows = list(csv.DictReader(line for line in f if not line.startswith("#")))
    assert rows and not [r["camera_note"] for r in rows if "clipped" in r.get("camera_note", "")]
    assert "coach: the camera stands at" in runs["capture"][1] + runs["capture"][2]


def test_a_hands_free_session_calibrates_in_mujoco(session, scenes, tmp_path):
    """validate at P6 through the mujoco backend: each model's error mean within 2x of this session's
    measured figure (and the calibrated far nearer than the nominal), the exit code exact -- 1, the
    configuration the arm hides from the camera said, the others measured -- and the configurations command
    gives the very configurations validate commanded."""
    d, runs = session
    means = {}
    for name in ("nominal", "calibrated"):
        code, out, err = runs[name]
        assert code == (1 if HIDDEN[name] else 0), (code, err)
        rows = np.genfromtxt(d / name / "validation.csv", delimiter=",", skip_header=2, usecols=(0, 9))
        assert sorted(rows[np.isnan(rows[:, 1]), 0].astype(int).tolist()) == HIDDEN[name], out
        assert int(out.split(" spots measured")[0].split()[-1]) == 4 - len(HIDDEN[name]), out
        means[name] = float(out.split("error mean ")[1].split(" mm")[0])
        assert FIGURE[name] / 2 < means[name] < 2 * FIGURE[name], (name, means[name], FIGURE[name])
    assert means["calibrated"] < means["nominal"] / 5
    sheet = scenes / "sheet" / "layout.yaml"
    code, _, err = lasercal(
        "configurations", d / "m.yaml", "--layout", sheet, "--point", "P6", "-n", 4, "-o", tmp_path / "c.csv"
    )
    assert code == 0, err
    planned = np.loadtxt(tmp_path / "c.csv", delimiter=",", skiprows=2)
    done = np.genfromtxt(d / "calibrated" / "validation.csv", delimiter=",", skip_header=2)
    index = done[:, 0].astype(int)  # the rows validate wrote, by configuration
    assert np.abs(planned[index, 1:8] - done[:, 1:8]).max() < 1e-5  # the arm reached what it was commanded


def test_new_session_is_what_plan_reads(scenes, tmp_path):
    """An empty camera session for a printed sheet: aim anywhere, the camera's and the aim's columns, and
    plan plans spots anywhere on it (aim_x, aim_y) from no capture at all."""
    code, out, err = lasercal(
        "new-session", "-o", tmp_path / "s", "--layout", scenes / "sheet" / "layout.yaml", "--robot", "fr3",
        "--camera",
    )  # fmt: skip
    assert code == 0, err
    header = (tmp_path / "s" / "captures.csv").read_text().strip().split(",")
    assert header[-8:] == [
        "photo",
        "camera_x",
        "camera_y",
        "camera_sx",
        "camera_sy",
        "camera_note",
        "aim_x",
        "aim_y",
    ]
    code, out, err = lasercal("plan", tmp_path / "s", "--next", 2)
    assert code == 0, err
    assert out.splitlines()[-3].endswith("aim_x,aim_y")


CAPTURE = ["capture", "--backend", "mujoco", "--robot", "fr3", "--layout", "{L}"]


@pytest.mark.parametrize(
    "args, names",
    [
        (["mujoco-scene", "--layout", "{L}", "-o", "{T}/x", "--spring", "2:nan"], "--spring"),
        (["mujoco-scene", "--layout", "{L}", "-o", "{T}/x", "--spring", "9:1e-4"], "--spring"),
        (["mujoco-scene", "--layout", "{L}", "-o", "{T}/x", "--friction", "2:0.5"], "--friction"),
        (["mujoco-scene", "--layout", "{L}", "-o", "{T}/x", "--light", "-1"], "--light"),
        (["mujoco-scene", "--layout", "{L}", "-o", "{S}"], "-o"),
        ([*CAPTURE, "--per-point", "3", "-o", "{T}/x"], "--world"),
        ([*CAPTURE, "--world", "{T}/no.xml", "--per-point", "3", "-o", "{T}/x"], "--world"),
        ([*CAPTURE, "--world", "{B}", "--per-point", "3", "-o", "{T}/x"], "bad.xml"),
        (["new-session", "-o", "{T}/x", "--layout", "{L}", "--per-point", "-2"], "--per-point"),
        (["new-session", "-o", "{S}", "--layout", "{L}"], "-o"),
        (["configurations", "fr3", "--layout", "{L}", "-n", "nan", "-o", "{T}/x.csv"], "-n"),
        (["configurations", "fr3", "--layout", "{L}", "-o", "{L}", "--force"], "-o"),
    ],
)  # fmt: skip
def test_bad_input_is_one_line_exit_2_nothing_written(scenes, tmp_path, args, names):
    """NaN, a joint that is not there, friction on nothing, a negative count, a missing or torn world file,
    an output naming an input or a kept folder: exit 2, one stderr line naming it, nothing written."""
    (tmp_path / "bad.xml").write_text("<mujoco><worldbody><body name='a'>")  # torn
    layout = scenes / "sheet" / "layout.yaml"
    subs = {"{L}": layout, "{T}": tmp_path, "{S}": scenes / "sheet", "{B}": tmp_path / "bad.xml"}
    argv = []
    for a in args:
        for k, v in subs.items():
            a = a.replace(k, str(v))
        argv.append(a)
    before = sorted(p.name for p in tmp_path.iterdir())
    sheet_before = sorted(p.name for p in (scenes / "sheet").iterdir())
    code, out, err = lasercal(*argv)
    assert code == 2, (out, err)
    assert len(err.strip().splitlines()) == 1 and names in err, err
    assert sorted(p.name for p in tmp_path.iterdir()) == before
    assert sorted(p.name for p in (scenes / "sheet").iterdir()) == sheet_before
