"""The fake world's joints: where a true robot's links stand when its encoders read q, by the world's own
code (issue 52 item 3) -- not the solver's effect models, its gravity torques or its fixed point
(``Extension``, ``JointMap``, ``gravity_torques``, ``deflected``), so that a diagnosis is tested on data its
own forms did not draw.

The world reads the truth file's numbers (``links``, ``extensions``) and computes, per configuration:

* the gravity torques that hold the links still, a Jacobian-transpose sum over the links' weights
  (base z up; w_j, p_j joint j's axis and a point on it, c_i link i's centre of mass, all carried by the
  world's own frames, :func:`truearm.link_frames_many`; mm -> m)

      tau_j(q) = sum_{i >= j} m_i g (w_j x (c_i - p_j))_z / 1000                     (eq. W4, Nm)

* each joint's error, every effect the truth holds summed (compliance c, eccentricity a, b, drift r since
  t0, a joint map's table h_j: linear between its knots, its end values beyond them)

      dq_j(q, t, tau) = c_j tau_j + a_j sin q_j + b_j cos q_j + r_j (t - t0) + h_j(q_j)  (eq. W5, rad)

* the links where the encoders read q: the fixed point of their own weight (eq. W6)

      q_link = q + dq(q, t, tau(q_link)),

  and its inverse, the encoders' reading with the links at q_link: q = q_link - dq(q, t, tau(q_link)).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from lasercal.collector.worlds.truearm import link_frames_many

G = 9.81  # m/s^2
TOL_RAD = 1e-14  # a fixed point is reached when no joint moves more than this
MAX_STEPS = 60  # c tau is milliradians: each step shrinks the change ~100-fold


@dataclass(frozen=True)
class TrueJoints:
    """A true robot's joint errors (eq. W5) and the weights that bend it (eq. W4), read from its file.

    Attributes
    ----------
    screws : (n, 6) joint screws (omega, v), rad and mm
    mass : (b,) kg, each body's mass (b = n: one per link, the flange's load merged into the last)
    com : (b, 3) mm, each body's centre of mass at q = 0, base frame
    c : (n,) rad/Nm; a, b : (n,) rad; r : (n,) rad/s; t0 : s
    maps : tuple of (joint index 0-based, knots (k,) rad, values (k,) rad)
    """

    screws: np.ndarray
    mass: np.ndarray
    com: np.ndarray
    c: np.ndarray
    a: np.ndarray
    b: np.ndarray
    r: np.ndarray
    t0: float = 0.0
    maps: tuple = ()

    @property
    def bends(self) -> bool:
        """The errors depend on the torques (a compliance)."""
        return bool(np.any(self.c))

    def torques(self, q_link: np.ndarray) -> np.ndarray:
        """Gravity torques (m, n) Nm at the links' angles (m, n) rad, eq. W4."""
        q_link = np.atleast_2d(np.asarray(q_link, dtype=float))
        T = link_frames_many(self.screws, q_link)  # (m, n + 1, 4, 4)
        n = len(self.screws)
        w0, v0 = self.screws[:, :3], self.screws[:, 3:]
        w = np.einsum("mjab,jb->mja", T[:, :n, :3, :3], w0)
        p = np.einsum("mjab,jb->mja", T[:, :n, :3, :3], np.cross(w0, v0)) + T[:, :n, :3, 3]
        c = np.einsum("miab,ib->mia", T[:, 1:, :3, :3], self.com) + T[:, 1:, :3, 3]  # (m, n, 3)
        arm = c[:, None, :, :] - p[:, :, None, :]  # (m, j, i, 3)
        z = w[:, :, None, 0] * arm[..., 1] - w[:, :, None, 1] * arm[..., 0]  # (w_j x (c_i - p_j))_z
        below = np.arange(n)[None, :] >= np.arange(n)[:, None]  # link i moves with joint j when i >= j
        return G / 1000.0 * np.einsum("i,mji->mj", self.mass, z * below)

    def error(self, q: np.ndarray, t, tau) -> np.ndarray:
        """dq (m, n) rad of eq. W5 at encoder angles q (m, n) rad, times t (m,) s, torques tau (m, n) Nm."""
        q = np.atleast_2d(q)
        dq = self.a * np.sin(q) + self.b * np.cos(q) + self.r * (np.asarray(t, float)[:, None] - self.t0)
        if tau is not None:
            dq = dq + self.c * tau
        for j, knots, values in self.maps:
            dq[:, j] += np.interp(q[:, j], knots, values)
        return dq

    def links(self, q: np.ndarray, t) -> np.ndarray:
        """The links' angles (m, n) rad where the encoders read q (m, n) at times t (m,) s: eq. W6."""
        q = np.atleast_2d(np.asarray(q, dtype=float))
        link = q + self.error(q, t, self.torques(q) if self.bends else None)
        for _ in range(MAX_STEPS if self.bends else 0):
            link, prev = q + self.error(q, t, self.torques(link)), link
            if np.abs(link - prev).max() < TOL_RAD:
                break
        return link

    def encoders(self, q_link: np.ndarray, t) -> np.ndarray:
        """The encoders' reading (m, n) rad with the links at q_link (m, n) at times t (m,) s: eq. W6's
        inverse, q = q_link - dq(q, t, tau(q_link)) (the torques are the links' own: no iteration on them)."""
        q_link = np.atleast_2d(np.asarray(q_link, dtype=float))
        tau = self.torques(q_link) if self.bends else None
        q = q_link - self.error(q_link, t, tau)
        for _ in range(MAX_STEPS):
            q, prev = q_link - self.error(q, t, tau), q
            if np.abs(q - prev).max() < TOL_RAD:
                break
        return q


def per_joint(entry: dict | None, key: str, n: int) -> np.ndarray:
    """A model file's per-joint values ``entry[key]`` at ``entry['joints']`` (1-based), (n,); 0 elsewhere."""
    out = np.zeros(n)
    if entry:
        out[np.asarray(entry["joints"], int) - 1] = np.asarray(entry[key], float)
    return out


def true_joints(truth, payload=None) -> TrueJoints:
    """The world's joints of a true robot (its ``links`` and ``extensions``, as the file states them; no
    ``links``: weightless). ``payload``: (kg, (3,) mm) carried by the last link, merged into it.

    The file is checked by :func:`fakeeffects.arm_effects` first (a malformed entry is refused there,
    naming the file and field); here it is only read.
    """
    ext = dict(truth.extensions or {})
    n = truth.n
    mass = np.array([lk.mass for lk in truth.links], float) if truth.links else np.zeros(n)
    com = np.array([lk.com for lk in truth.links], float) if truth.links else np.zeros((n, 3))
    if payload is not None:  # one body: masses added, centres of mass averaged by mass
        kg, centre = float(payload[0]), np.asarray(payload[1], float)
        com[-1] = (mass[-1] * com[-1] + kg * centre) / (mass[-1] + kg)
        mass[-1] += kg
    jm = ext.get("joint_map")
    maps = ()
    if jm:
        maps = tuple(
            (int(j) - 1, float(a) + float(jm["step"]) * np.arange(len(v)), np.asarray(v, float))
            for j, a, v in zip(jm["joints"], jm["start"], jm["values"])
        )
    drift = ext.get("drift") or {}
    return TrueJoints(
        np.asarray(truth.screws, float),
        mass,
        com,
        per_joint(ext.get("joint_compliance"), "c", n),
        per_joint(ext.get("encoder_eccentricity"), "a", n),
        per_joint(ext.get("encoder_eccentricity"), "b", n),
        per_joint(drift, "r", n),
        float(drift.get("t0_s", 0.0)),
        maps,
    )
