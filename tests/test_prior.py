"""The MAP estimator with priors from manufacturing tolerances (solver.identify.prior, eqs. P1-P5).

Oracles: exact recovery as the noise prior goes to zero; a Monte-Carlo check that the posterior
sigmas are the actual spread of the estimates around truths drawn from the prior (the Bayesian
calibration of eq. P4); the coach's posterior is the solve's (the same estimate and covariance);
a prior holds what the data cannot see, and says so.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest
import yaml

from lasercal.collector.cli.main import main
from lasercal.solver.analysis.design import posterior
from lasercal.solver.analysis.simulate import simulate_captures
from lasercal.solver.errors import FormatError
from lasercal.solver.formats.robots import load_model
from lasercal.solver.formats.session import Session, load_layout
from lasercal.solver.formats.tolerances import DEFAULTS, load_tolerances, robot_tolerances
from lasercal.solver.identify.measurement import determined_by, fit, unidentifiable
from lasercal.solver.identify.spot import identify, laser_prior
from lasercal.solver.kinematics.laser import LaserParams
from tests.conftest import heldout_error

NOMINAL = load_model("panda")
LAYOUT = load_layout("thesis")


def _session(truth, per_point: int, noise: float, seed: int, tolerances="robot") -> Session:
    c = simulate_captures(truth, LAYOUT, per_point, noise, np.random.default_rng(seed))
    target = np.array([LAYOUT.points[p] for p in c.point])
    m = len(c.q)
    return Session(
        Path("."), {}, NOMINAL, LAYOUT.plane_z, None, LAYOUT.points, c.point, target, c.t, c.q,
        None, None, {}, np.arange(2, m + 2), tolerances=tolerances,
    )  # fmt: skip


def test_map_recovers_exact_data_as_the_noise_prior_vanishes(puma_exact, puma_heldout):
    """Thesis Simulation 1 (exact Puma data): with sigma_0 -> 0 the prior's weight sigma^2 / s^2 vanishes
    (eq. P2-P3) and the MAP fit is the exact least-squares one."""
    session, truth, layout = puma_exact
    tol = robot_tolerances(session.robot).with_noise("laser", 1e-9)
    res = identify(dataclasses.replace(session, tolerances=tol), "lm")
    q, tgt = puma_heldout
    assert heldout_error(res.model, q, tgt).max() < 1e-6
    assert res.sigma_mm < 1e-7


def test_posterior_sigmas_match_the_spread_of_estimates():
    """Monte Carlo (eq. P4): truths drawn from the prior, 1 mm aiming noise, 45 captures; the errors of the
    MAP estimate in units of its posterior sigma have unit spread -- parameter by parameter, and along
    the eigen-directions of eq. P5, those the data determine as well as those the prior holds."""
    P = LaserParams(NOMINAL)
    prior = laser_prior(P, robot_tolerances(NOMINAL))
    R = np.linalg.inv(prior.whitening)  # the prior covariance's root (eq. P1)
    keep = np.arange(P.size) != P.names.index("M.z")  # the aperture along the beam: a gauge, not estimated
    L = prior.whitening[np.ix_(keep, keep)]
    rng = np.random.default_rng(7)
    z_par, z_dir, ratio = [], [], []
    for rep in range(16):
        x_true = P.x0() + R @ rng.standard_normal(P.size)
        ident = fit(_session(P.to_model(x_true), 15, 1.0, 100 + rep))
        cov = ident.extra["cov"][np.ix_(keep, keep)]
        e = (ident.estimate - x_true)[keep]
        z_par.append(e / np.sqrt(np.diag(cov)))
        lam, U = np.linalg.eigh(L @ cov @ L.T)
        z_dir.append(U.T @ (L @ e) / np.sqrt(lam))
        ratio.append(np.sqrt(lam))
    z_par, z_dir, ratio = np.array(z_par), np.array(z_dir), np.array(ratio)
    # 16 x 32 standardised errors each: RMS 1 when the sigmas are honest (+-20 % is several sd of an RMS
    # over ~500 values, allowing for their correlation)
    assert 0.8 < np.sqrt(np.mean(z_par**2)) < 1.2
    data, prior = ratio < 0.5, ratio > 0.7
    assert data.sum() > 200 and prior.sum() >= 16  # both kinds of direction are in the check
    assert 0.8 < np.sqrt(np.mean(z_dir[data] ** 2)) < 1.2
    assert 0.7 < np.sqrt(np.mean(z_dir[prior] ** 2)) < 1.3  # fewer of them: a wider band


def test_the_coach_posterior_is_the_solve_fit():
    """plan/the coach and solve estimate the same thing: the same estimate and the same covariance."""
    truth = load_model("panda_thesis_identified")
    session = _session(truth, 10, 1.0, 3)
    ident = fit(session)
    post = posterior(NOMINAL, session.q, session.target, robot_tolerances(NOMINAL))
    assert np.allclose(post.estimate, ident.estimate, atol=2e-4 * np.abs(ident.estimate).max())
    sd_post, sd_fit = np.sqrt(np.diag(post.cov)), np.sqrt(np.diag(ident.extra["cov"]))
    keep = np.arange(len(sd_fit)) != LaserParams(NOMINAL).names.index("M.z")  # the gauge, slid by solve
    assert np.allclose(sd_post[keep], sd_fit[keep], rtol=0.02)


def test_a_still_joint_is_held_by_the_prior_and_named(panda_noisy):
    """Joint 4 never moves: plain least squares cannot identify its axis (refused without --allow-partial);
    under the prior nothing is left undefined, and the report names joint 4's axis as the prior's."""
    session = panda_noisy[0]
    q = session.q.copy()
    q[:, 3] = q[0, 3]
    still = dataclasses.replace(session, q=q)
    plain = fit(dataclasses.replace(still, tolerances=None))
    assert sum(d.directions for d in unidentifiable(still, plain)) >= 4
    ident = fit(still)
    assert unidentifiable(still, ident) == []
    det = determined_by(still, ident)
    named = [d.combination for d in det.from_prior]
    # frozen angles do not fit the spots: the noise estimate swells and the prior holds far more than
    # joint 4; which groups the greedy naming lists first varies with the realisation
    assert named and all("joint" in n or "aperture" in n or "laser" in n for n in named)
    assert det.prior >= 4 and det.data + det.both + det.prior == LaserParams(NOMINAL).size - 1


def test_prior_file_overrides_and_is_validated(tmp_path):
    f = tmp_path / "prior.yaml"
    f.write_text("format: lasercal-prior/1\nunits: {length: mm, angle: rad}\nprior: {offset_mm: 1.5}\n")
    tol = load_tolerances(f, NOMINAL)
    assert tol.offset_mm == 1.5 and tol.axis_rad == DEFAULTS.axis_rad
    assert load_tolerances("none", NOMINAL) is None
    f.write_text("format: lasercal-prior/1\nprior: {offset_mm: -1}\n")
    with pytest.raises(FormatError, match=r"prior\.offset_mm.*expected a number > 0"):
        load_tolerances(f, NOMINAL)
    f.write_text("format: lasercal-prior/1\nprior: {offset: 1}\n")
    with pytest.raises(FormatError, match="unknown tolerance 'offset'"):
        load_tolerances(f, NOMINAL)


def test_solve_reports_data_and_prior_and_prior_none_is_least_squares(tmp_path, capsys):
    s = tmp_path / "s"
    assert main(["simulate", "panda_thesis_identified", "--layout", "thesis", "--per-point", "15",
                 "--aim-noise", "0.5", "--seed", "4", "-o", str(s)]) == 0  # fmt: skip
    capsys.readouterr()
    assert main(["solve", str(s), "-o", str(tmp_path / "m.yaml"), "--folds", "0"]) == 0
    out = capsys.readouterr().out
    assert "determined by the data" in out
    idn = yaml.safe_load((tmp_path / "m.yaml").read_text())["identification"]
    det = idn["determined_by"]
    assert det["data"] + det["data_and_prior"] + det["prior"] == 32  # 33 parameters less the aperture gauge
    assert idn["prior"]["tolerances"]["axis_rad"] == DEFAULTS.axis_rad
    assert main(["solve", str(s), "-o", str(tmp_path / "n.yaml"), "--folds", "0", "--prior", "none"]) == 0
    assert "prior: none (plain least squares)" in capsys.readouterr().out
    idn = yaml.safe_load((tmp_path / "n.yaml").read_text())["identification"]
    assert idn["prior"] == "none (plain least squares)" and "determined_by" not in idn
