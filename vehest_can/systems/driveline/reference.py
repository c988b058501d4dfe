"""Independent numpy reference of the seed-001 Kalman filter, written from the paper's equations.

Deliberately literal: the paper's 4x4 H (with its zero rows) and 4x4 R, a matrix inverse for
eq. 13, scipy's Pade ``expm`` for the ZOH discretisation. It shares no code with the C filter,
so agreement between the two checks both. Same start-up rule as the C filter (state seeded
from the first sample with both speeds), Joseph-form update of eq. 14.
"""
from __future__ import annotations

import numpy as np


def model(cfg) -> tuple[np.ndarray, np.ndarray]:
    """Continuous A, B of eq. 8 (eq. 5 with J_v)."""
    a = np.array([
        [0.0, 0.0, -cfg.rd / cfg.jo, 0.0],
        [0.0, -cfg.c / cfg.jv, 1.0 / cfg.jv, -1.0 / cfg.jv],
        [cfg.ks * cfg.rd, -cfg.ks, 0.0, 0.0],
        [0.0, 0.0, 0.0, 0.0],
    ])
    b = np.array([1.0 / (cfg.jo * cfg.ri), 0.0, 0.0, 0.0])
    return a, b


def discretise(a, b, ts, disc):
    if disc == "euler":  # eq. 10
        return np.eye(4) + ts * a, ts * b
    import scipy.linalg  # the test/bench baseline only: `pip install .` needs no scipy

    m = np.zeros((5, 5))
    m[:4, :4], m[:4, 4] = a, b
    e = scipy.linalg.expm(m * ts)
    return e[:4, :4], e[:4, 4]


def paper_h_r(cfg):
    """The paper's H = diag[1 1 1 0] or diag[1 1 0 0] and R = diag[r1 r2 r3 1]."""
    h = np.diag([1.0, 1.0, 1.0 if cfg.meas == "speeds+torque" else 0.0, 0.0])
    r = np.diag([*cfg.r, 1.0])
    return h, r


def run(cfg, u, z):
    """Filter over u (n,), z (n, 3); all samples valid. Returns x (n, 4), k (n, 4, 4)."""
    ad, bd = discretise(*model(cfg), cfg.ts, cfg.disc)
    h, r = paper_h_r(cfg)
    q = np.diag(cfg.q)
    n = len(u)
    xs, ks = np.empty((n, 4)), np.empty((n, 4, 4))
    x = None
    p = np.diag(cfg.p0).astype(float)
    eye = np.eye(4)
    for t in range(n):
        ut = u[t] if cfg.use_input else 0.0
        zt = np.array([z[t, 0], z[t, 1], z[t, 2], 0.0])
        if x is None:  # seed from the first sample, as the C filter does
            to0 = zt[2] if cfg.meas == "speeds+torque" else ut / (cfg.ri * cfg.rd)
            x = np.array([zt[0], zt[1], to0, 0.0])
        xm = ad @ x + bd * ut                                     # eq. 10
        pm = ad @ p @ ad.T + q                                    # eq. 15
        k = pm @ h.T @ np.linalg.inv(h @ pm @ h.T + r)            # eq. 13
        x = xm + k @ (h @ zt - h @ xm)
        ikh = eye - k @ h
        p = ikh @ pm @ ikh.T + k @ r @ k.T                        # eq. 14, Joseph form
        p = 0.5 * (p + p.T)
        xs[t], ks[t] = x, k
    return xs, ks
