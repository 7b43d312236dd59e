"""Kinematics against independent oracles: scipy expm/logm, finite differences, Franka's DH table."""

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays
from scipy.linalg import expm, logm

from lasercal.solver.formats.robots import load_model
from lasercal.solver.kinematics.laser import LaserParams
from lasercal.solver.kinematics.minimal import link_frame, screw_from_eta
from lasercal.solver.kinematics.poe import ad, adjoint, dexp_A, exp6, inv_T, log6, poe_chain, space_jacobian
from tests.conftest import franka_flange

finite = st.floats(-3, 3, allow_nan=False)


def hat(xi):
    H = np.zeros((4, 4))
    H[:3, :3] = [[0, -xi[2], xi[1]], [xi[2], 0, -xi[0]], [-xi[1], xi[0], 0]]
    H[:3, 3] = xi[3:]
    return H


@settings(max_examples=60, deadline=None)
@given(arrays(float, 6, elements=finite))
def test_exp6_matches_scipy_expm(xi):
    assert np.allclose(exp6(xi), expm(hat(xi)), atol=1e-10)


@settings(max_examples=60, deadline=None)
@given(arrays(float, 3, elements=st.floats(-1.7, 1.7)), arrays(float, 3, elements=st.floats(-500, 500)))
def test_log6_inverts_exp6_and_matches_logm(w, v):
    xi = np.r_[w, v]
    T = exp6(xi)
    assert np.allclose(log6(T), xi, atol=1e-8)
    L = logm(T).real
    assert np.allclose(log6(T), np.r_[L[2, 1], L[0, 2], L[1, 0], L[:3, 3]], atol=1e-6)


def test_log6_near_pi_and_zero():
    for xi in (np.r_[0, 0, np.pi - 1e-9, 10, 0, 0], np.r_[1e-12, 0, 0, 1, 2, 3], np.zeros(6)):
        assert np.allclose(exp6(log6(exp6(xi))), exp6(xi), atol=1e-8)


def test_adjoint_conjugation_identity():
    rng = np.random.default_rng(0)
    T = exp6(rng.normal(size=6) * [1, 1, 1, 100, 100, 100])
    S = rng.normal(size=6)
    assert np.allclose(exp6(adjoint(T) @ S), T @ exp6(S) @ inv_T(T), atol=1e-9)
    assert np.allclose(ad(S) @ S, 0)


def test_dexp_A_is_the_derivative_of_the_exponential():
    """Eq. 2.3.26: [(d e^[S]t) e^-[S]t]^vee = A dS, by central differences, revolute and prismatic."""
    rng = np.random.default_rng(1)
    for S in (np.r_[[0.6, 0.0, 0.8], [10.0, -20.0, 5.0]], np.r_[0, 0, 0, 0.0, 0.6, 0.8]):
        th = np.array([0.0, 1e-4, 0.7, -2.5])
        A = dexp_A(S, th)
        dS = rng.normal(size=6)
        h = 1e-6
        for k, t in enumerate(th):
            D = (exp6((S + h * dS) * t) - exp6((S - h * dS) * t)) / (2 * h) @ inv_T(exp6(S * t))
            num = np.r_[D[2, 1], D[0, 2], D[1, 0], D[:3, 3]]
            assert np.allclose(A[k] @ dS, num, atol=1e-6 * (1 + np.abs(num).max()))


def test_link_frames_follow_eqs_2215_2216():
    for S in (
        load_model("panda").screws.tolist()
        + load_model("puma560_thesis_actual").screws.tolist()
        + [[0, 0, 0, 0, 0, -1]]
    ):
        S = np.array(S)
        T = link_frame(S)
        R = T[:3, :3]
        assert np.allclose(R.T @ R, np.eye(3)) and np.isclose(np.linalg.det(R), 1)
        # the screw seen from its own frame is the unit z screw through the origin (eta = 0)
        local = np.r_[0, 0, 0, 0, 0, 1] if np.linalg.norm(S[:3]) == 0 else np.r_[0, 0, 1, 0, 0, 0]
        assert np.allclose(adjoint(T) @ local, S, atol=1e-12)
        S0, dS = screw_from_eta(T, np.zeros(dS_size := (2 if np.linalg.norm(S[:3]) == 0 else 4)))
        assert np.allclose(S0, S, atol=1e-12)
        B = np.linalg.solve(adjoint(T), dS)  # thesis B_i (below eq. 2.3.26)
        B_thesis = np.zeros((6, dS_size))
        if dS_size == 4:
            B_thesis[0, 0] = B_thesis[1, 1] = B_thesis[3, 3] = 1
            B_thesis[4, 2] = -1
        else:
            B_thesis[3, 0] = B_thesis[4, 1] = 1
        assert np.allclose(B, B_thesis, atol=1e-12)


def test_screw_from_eta_derivative_and_constraints():
    rng = np.random.default_rng(2)
    T = exp6(rng.normal(size=6) * [1, 1, 1, 100, 100, 100])
    for eta in (rng.normal(0, 0.1, 4) * [1, 1, 50, 50], rng.normal(0, 0.1, 2)):
        S, dS = screw_from_eta(T, eta)
        w, v = S[:3], S[3:]
        if eta.size == 4:
            assert (
                np.isclose(np.linalg.norm(w), 1) and abs(w @ v) < 1e-9
            )  # unit axis, zero pitch: no constraints needed
        else:
            assert np.allclose(w, 0) and np.isclose(np.linalg.norm(v), 1)
        h = 1e-7
        num = np.stack(
            [
                (screw_from_eta(T, eta + h * e)[0] - screw_from_eta(T, eta - h * e)[0]) / (2 * h)
                for e in np.eye(eta.size)
            ],
            1,
        )
        assert np.allclose(dS, num, atol=1e-6)


def test_panda_nominal_equals_franka_dh_table():
    """Thesis Table 4.3 nominal screws reproduce Franka's (Craig) DH table to round-off."""
    model = load_model("panda")
    rng = np.random.default_rng(3)
    q = rng.uniform(model.limits[:, 0], model.limits[:, 1], (20, 7))
    M = np.diag([1.0, -1.0, -1.0, 1.0])  # flange at q = 0: (88, 0, 926) mm, z down
    M[:3, 3] = 88, 0, 926
    assert np.allclose(poe_chain(model.screws, q)[:, -1] @ M, franka_flange(q), atol=1e-9)


def test_space_jacobian_by_finite_differences():
    model = load_model("panda_thesis_identified")
    q = np.array([[0.1, -0.5, 0.3, -2.0, 0.2, 1.8, 0.4]])
    J = space_jacobian(model.screws, poe_chain(model.screws, q))[0]
    T = poe_chain(model.screws, q)[0, -1]
    h = 1e-7
    for i in range(7):
        dq = np.zeros((1, 7))
        dq[0, i] = h
        D = (
            (poe_chain(model.screws, q + dq)[0, -1] - poe_chain(model.screws, q - dq)[0, -1])
            / (2 * h)
            @ inv_T(T)
        )
        assert np.allclose(J[:, i], np.r_[D[2, 1], D[0, 2], D[1, 0], D[:3, 3]], atol=1e-5)


def test_laser_jacobians_by_finite_differences():
    """Tip Jacobian (eqs. 3.1.9-3.1.13) and in-plane spot Jacobian against central differences."""
    model = load_model("panda")
    P = LaserParams(model)
    rng = np.random.default_rng(4)
    x = P.x0() + rng.normal(0, 1e-2, P.size)
    q = np.array([[0.1, -0.5, 0.3, -2.0, 0.2, 1.8, 0.4], [-0.4, 0.2, -0.1, -1.5, 0.5, 2.2, -0.8]])
    length = np.array([300.0, 450.0])
    _, K = P.tip_jacobian(x, q, length)
    _, _, Js = P.spot_jacobian(x, q, -8.0)

    def tip(xx):
        b = P.beam(xx, q)
        return b.aperture + length[:, None] * b.direction

    h = 1e-6
    for k in range(P.size):
        e = np.zeros(P.size)
        e[k] = h
        assert np.allclose(
            K[:, :, k], (tip(x + e) - tip(x - e)) / (2 * h), atol=1e-4 * (1 + np.abs(K[:, :, k]).max())
        )
        ds = (P.spots(x + e, q, -8.0)[0] - P.spots(x - e, q, -8.0)[0])[:, :2] / (2 * h)
        assert np.allclose(Js[:, :, k], ds, atol=1e-4 * (1 + np.abs(ds).max()))
