"""The capture coach's design library against a simulated Panda whose truth is known."""

from __future__ import annotations

import numpy as np
import pytest

from lasercal.solver.analysis import design as D
from lasercal.solver.analysis.simulate import simulate_captures
from lasercal.solver.formats.robots import load_model
from lasercal.solver.formats.session import load_layout
from lasercal.solver.identify.spot import predict_spots
from lasercal.solver.kinematics.aim import spot_error

TRUTH = load_model("panda_thesis_identified")
NOMINAL = load_model("panda")
LAYOUT = load_layout("thesis")


@pytest.fixture(scope="module")
def coach():
    return D.Coach(NOMINAL, LAYOUT, seed=3, per_point=30)


@pytest.fixture(scope="module")
def thesis_captures():
    c = simulate_captures(TRUTH, LAYOUT, 10, 1.0, np.random.default_rng(4))
    return c.q, np.array([LAYOUT.points[p] for p in c.point])


def test_no_captures_gives_a_prior_plan_that_aims_within_limits(coach):
    st = coach.status(np.empty((0, 7)), k=6)
    assert st.rank == 0 and st.n_identifiable == 32 and st.n_params == 33
    assert 5 < st.predicted < 100  # the prior: about the nominal model's error (13.6 mm here), not 0 or inf
    assert np.all(np.diff(np.r_[st.predicted, st.plan.expected]) < 0)
    assert set(st.plan.point) <= set(LAYOUT.calibration)
    err = np.array([spot_error(NOMINAL, q[None], t)[0] for q, t in zip(st.plan.q, st.plan.target)])
    assert np.all(err < 0.5) and NOMINAL.within_limits(st.plan.q, 0.05).all()


def test_greedy_prediction_equals_the_refitted_covariance(coach, thesis_captures):
    q, tgt = thesis_captures
    post = D.posterior(NOMINAL, q, tgt)
    W = D.use_weight(post, coach.region)
    plan = D.select(post, W, coach.cand, 4)
    J = post.params.spot_jacobian(post.estimate, plan.q, plan.target[:, 2])[2].reshape(-1, post.params.size)
    C = D._posterior_cov(np.vstack([post.rows, J]), post.prior_root, post.sigma)
    assert np.sqrt(np.sum(W * C)) == pytest.approx(plan.expected[-1], rel=1e-6)
    assert plan.expected[-1] < plan.now


def test_exchange_improves_the_greedy_design_and_orders_it_greedily(coach):
    post = coach.post  # the prior: greedy is most myopic here
    W = D.use_weight(post, coach.region)
    greedy = D.select(post, W, coach.cand, 12, passes=0)
    best = D.select(post, W, coach.cand, 12)
    assert best.expected[-1] < 0.97 * greedy.expected[-1]  # the twelve together, not one by one
    assert np.all(np.diff(best.expected) < 0) and len(set(h["candidate"] for h in best.history)) == 12
    J = post.params.spot_jacobian(post.estimate, best.q, best.target[:, 2])[2].reshape(-1, post.params.size)
    C = D._posterior_cov(J, post.prior_root, post.sigma)
    assert np.sqrt(np.sum(W * C)) == pytest.approx(best.expected[-1], rel=1e-6)


def test_rank_two_updates_and_downdates_equal_a_fresh_covariance(coach, thesis_captures):
    q, tgt = thesis_captures
    post = D.posterior(NOMINAL, q, tgt)
    W = D.use_weight(post, coach.region)
    Jc = D.candidate_jacobian(post, coach.cand)
    design = D._Design(post.cov, W, Jc, post.sigma)
    for i in (3, 17, 40):
        design.add(i)
    design.remove(17)  # eq. D7's downdate: as if only 3 and 40 had been added
    C = D._posterior_cov(
        np.vstack([post.rows, Jc[[3, 40]].reshape(-1, Jc.shape[2])]), post.prior_root, post.sigma
    )
    assert design.f == pytest.approx(np.sum(W * C), rel=1e-9)
    np.testing.assert_allclose(design.A, Jc @ C, atol=1e-9 * np.abs(Jc @ C).max())
    np.testing.assert_allclose(
        design.drops(),
        [np.trace(np.linalg.solve(J @ C @ J.T + post.sigma**2 * np.eye(2), J @ C @ W @ C @ J.T)) for J in Jc],
        rtol=1e-7,
    )


def test_predicted_error_is_close_to_the_measured_one_over_seeds(coach):
    fresh = D.use_region(NOMINAL, LAYOUT, np.random.default_rng(11), n=100)
    a = predict_spots(TRUTH, fresh.q, fresh.target[:, 2])[0]
    pred, meas = [], []
    for seed in range(6):
        c = simulate_captures(TRUTH, LAYOUT, 10, 1.0, np.random.default_rng(seed))
        post = D.posterior(NOMINAL, c.q, np.array([LAYOUT.points[p] for p in c.point]))
        e, de = D.predicted_error(post, D.use_weight(post, coach.region))
        assert 0 < de < e and 0.6 < post.sigma < 1.4  # the simulated aiming noise is 1 mm
        b = predict_spots(post.model, fresh.q, fresh.target[:, 2])[0]
        pred.append(e)
        meas.append(np.sqrt(np.mean(np.sum((a - b)[:, :2] ** 2, axis=1))))
    assert 0.75 < np.sqrt(np.mean(np.square(pred)) / np.mean(np.square(meas))) < 1.33


def test_bad_requests_are_design_errors(coach):
    with pytest.raises(D.DesignError, match="positive"):
        D.select(coach.post, np.eye(33), coach.cand, 0)
    with pytest.raises(D.DesignError, match="must be <= max"):
        D.use_region(NOMINAL, LAYOUT, np.random.default_rng(0), workspace=([500, 0, -8], [400, 100, -8]))


def test_the_coach_never_suggests_a_pose_near_a_capture_at_its_point(coach, thesis_captures):
    """The design would replicate an informative pose (a new draw of the aiming noise, nothing more) and the
    capture check would then call the capture similar (joint distance 0.00 rad): with the captures taken, no
    planned capture lies within APART_RAD of one at its point -- the best pose, once captured, is not
    suggested again."""
    q, tgt = thesis_captures
    post = D.posterior(NOMINAL, q, tgt)
    W = D.use_weight(post, coach.region)
    best = D.select(post, W, coach.cand, 1)
    q, tgt = np.vstack([q, best.q]), np.vstack([tgt, best.target])  # captured exactly as suggested
    plan = D.select(post, W, coach.cand, 8, taken=(q, tgt))
    for qs, ts in zip(plan.q, plan.target):
        at = np.all(np.abs(tgt - ts) < 1e-9, axis=1)
        assert np.linalg.norm(q[at] - qs, axis=1).min() >= D.APART_RAD
    assert coach.cand.available(None, (q, tgt)).sum() < len(coach.cand.q)  # it was a candidate: now taken
