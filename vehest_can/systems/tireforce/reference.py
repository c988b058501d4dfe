"""Independent numpy reference of the seed-000 tire-force estimators (SKFMEC and the plain EKF).

Written from the paper's equations, deliberately literal and sharing no code with the C core:

* the monitoring model as printed: the appendix sums, eq. 35 solved with the printed E matrix
  (``numpy.linalg.solve``), the outputs a_x = v'_x - r v_y and a_y = v'_y + r v_x of eq. 29;
* Jacobians by complex-step differentiation of those functions (exact to rounding, so it checks
  the C core's hand-derived Jacobians too);
* the batch Kalman update with a matrix inverse and the Joseph form (the C core does sequential
  scalar updates);
* the same discretisation and step order as the C core (docs/tireforce.md, "Discretisation"):
  forward Euler for the state (eq. 38 with the MEC term), Phi = I + Ts F* for the covariance,
  discrete measurement update at every step.

``cfg`` is any object with the fields of ``tireforce.SkfConfig``.
"""
from __future__ import annotations

import numpy as np

N_X = 7
N_Y = 4


def loads(cfg, phi, ax, ay, nu_ay, mec):
    """Normal loads Fz1..4 (FL, FR, RL, RR): eq. 39 for the front, its rear counterpart."""
    l = cfg.lf + cfg.lr
    kf = cfg.kphif / (cfg.kphif + cfg.kphir)
    kr = cfg.kphir / (cfg.kphif + cfg.kphir)
    lat_f = cfg.lt_gain * kf * (cfg.h * ay / (2 * cfg.tf * cfg.g) - cfg.ms * cfg.e / (2 * cfg.m * cfg.tf) * np.sin(phi))
    lat_r = cfg.lt_gain * kr * (cfg.h * ay / (2 * cfg.tr * cfg.g) - cfg.ms * cfg.e / (2 * cfg.m * cfg.tr) * np.sin(phi))
    base_f = cfg.lr / l - cfg.h * ax / (cfg.g * l)
    base_r = cfg.lf / l + cfg.h * ax / (cfg.g * l)
    half = cfg.m * cfg.g / 2
    fz = [half * (base_f - lat_f), half * (base_f + lat_f), half * (base_r - lat_r), half * (base_r + lat_r)]
    if mec:
        fz[0] = fz[0] + cfg.gy[0] * nu_ay
        fz[1] = fz[1] + cfg.gy[1] * nu_ay
    return fz


def static_loads(cfg):
    """Fzf, Fzr: static load of one front / one rear tire (the ratios of eq. 33-34 are 1 when straight)."""
    l = cfg.lf + cfg.lr
    return cfg.m * cfg.g * cfg.lr / (2 * l), cfg.m * cfg.g * cfg.lf / (2 * l)


def tire_lateral(cfg, fyf, fyr, fz):
    """Eq. 36-37."""
    fzf, fzr = static_loads(cfg)
    return [fyf * fz[0] / fzf, fyf * fz[1] / fzf, fyr * fz[2] / fzr, fyr * fz[3] / fzr]


def e_matrix(cfg):
    m, mse = cfg.m, cfg.ms * cfg.e
    e = np.eye(N_X)
    e[0, 0] = e[1, 1] = m
    e[1, 4] = e[4, 1] = -mse
    e[2, 2] = cfg.iz
    e[4, 4] = cfg.ix + cfg.ms * cfg.e ** 2
    return e


def derivative(cfg, x, u):
    """x' = E^-1 [...] of eq. 35 with the appendix sums; u = (ax, ay, delta, fx[4], nu_ay, mec)."""
    ax, ay, delta, fx, nu_ay, mec = u
    vx, vy, r, phi, p, fyf, fyr = x
    fz = loads(cfg, phi, ax, ay, nu_ay, mec)
    fy = tire_lateral(cfg, fyf, fyr, fz)
    c, s = np.cos(delta), np.sin(delta)
    sfx = sum(fx[i] * c - fy[i] * s for i in (0, 1)) + fx[2] + fx[3]
    sfy_front = sum(fx[i] * s + fy[i] * c for i in (0, 1))
    sfy = sfy_front + fy[2] + fy[3]
    smz = (cfg.lf * sfy_front - cfg.lr * (fy[2] + fy[3])
           + cfg.tf * sum((-1) ** (i + 1) * (fx[i] * c - fy[i] * s) for i in (0, 1))
           + cfg.tr * sum((-1) ** (i + 1) * fx[i] for i in (2, 3)))
    kphi, cphi = cfg.kphif + cfg.kphir, cfg.cphif + cfg.cphir
    smx = cfg.hf * sfy_front + cfg.hr * (fy[2] + fy[3]) - kphi * phi - cphi * p
    mse = cfg.ms * cfg.e
    g = np.array([
        sfx + cfg.m * r * vy - mse * p * r,
        sfy - cfg.m * r * vx,
        smz,
        p,
        smx + mse * r * vx,
        cfg.zeta1 * p,
        cfg.zeta2 * p,
    ])
    return np.linalg.solve(e_matrix(cfg).astype(g.dtype), g)


def outputs(cfg, x, u):
    """y^ = [a_x, a_y, r, p]: a_x = v'_x - r v_y, a_y = v'_y + r v_x (eq. 29)."""
    xd = derivative(cfg, x, u)
    return np.array([xd[0] - x[2] * x[1], xd[1] + x[2] * x[0], x[2], x[4]])


def jacobian(fun, x, h=1e-20):
    """Complex-step Jacobian: exact to rounding for analytic functions."""
    cols = []
    for j in range(len(x)):
        xc = np.array(x, dtype=complex)
        xc[j] += 1j * h
        cols.append(np.imag(fun(xc)) / h)
    return np.array(cols).T


def scaling(cfg):
    return np.diag(cfg.s) if cfg.scaled else np.eye(N_X)


def seed(cfg, y, omega):
    """Initial state from the first sample: v_x from the wheel speeds, axle forces from quasi-steady a_y."""
    l = cfg.lf + cfg.lr
    fyf = cfg.m * y[1] * cfg.lr / (2 * l)
    fyr = cfg.m * y[1] * cfg.lf / (2 * l)
    return np.array([cfg.rw * np.mean(omega), 0.0, y[2], fyf / cfg.zeta1, y[3], fyf, fyr])


def run(cfg, ax, ay, r, p, delta, omega, torque):
    """Filter over n samples (all valid). Returns dict x (n,7), fy (n,4), fz (n,4), k (n,7,4) batch gains,
    p (n,7,7) covariances (filter coordinates), innov (n,4)."""
    n = len(ax)
    s = scaling(cfg)
    s_inv = np.linalg.inv(s)
    q, rr, p0 = np.diag(cfg.q), np.diag(cfg.r), np.diag(cfg.p0)
    if not cfg.scaled:  # q, p0 are given in scaled coordinates: P = S^-1 P* S^-T
        sp = np.diag(cfg.s)
        q = np.linalg.inv(sp) @ q @ np.linalg.inv(sp)
        p0 = np.linalg.inv(sp) @ p0 @ np.linalg.inv(sp)
        gp = np.linalg.inv(sp) @ np.array(cfg.gp)
    else:
        gp = np.array(cfg.gp, dtype=float)
    mec = bool(cfg.mec)
    w = np.ones(N_X) if cfg.scaled else np.asarray(cfg.s, dtype=float) ** 2  # filter -> scaled variance
    ts = cfg.ts
    alpha = ts / (cfg.tau_wdot + ts)
    out = {k: np.empty(sh) for k, sh in (("x", (n, 7)), ("fy", (n, 4)), ("fz", (n, 4)), ("k", (n, 7, 4)),
                                          ("p", (n, 7, 7)), ("innov", (n, 4)))}
    xs = pm = None
    w_prev = wdot = None
    nu_ay = 0.0
    eye = np.eye(N_X)
    for t in range(n):
        y = np.array([ax[t], ay[t], r[t], p[t]])
        if xs is None:
            xs = s @ seed(cfg, y, omega[t])
            pm = p0.copy()
            w_prev, wdot = np.array(omega[t], dtype=float), np.zeros(4)
        # wheel accelerations by a first-order filtered difference, then eq. 30
        wdot = wdot + alpha * ((omega[t] - w_prev) / ts - wdot)
        w_prev = np.array(omega[t], dtype=float)
        fx = (np.asarray(torque[t]) - cfg.iw * wdot) / cfg.rw
        x = s_inv @ xs
        u = (ax[t], ay[t], delta[t], fx, nu_ay, mec)
        f = derivative(cfg, x, u)
        fj = jacobian(lambda xx: derivative(cfg, xx, u), x)
        # eq. 38 discretised: S x+ = S x + Ts (S f + Gp (r - r^))
        mec_term = gp * (y[2] - x[2]) if mec else 0.0
        x_pred = xs + ts * (s @ f + mec_term)
        phi = eye + ts * (s @ fj @ s_inv)  # F* = S F S^-1 (eq. 28)
        p_pred = phi @ pm @ phi.T + q
        xp = s_inv @ x_pred
        yhat = outputs(cfg, xp, u)
        hj = jacobian(lambda xx: outputs(cfg, xx, u), xp) @ s_inv  # H* = H S^-1 (eq. 28)
        innov = y - yhat
        k = p_pred @ hj.T @ np.linalg.inv(hj @ p_pred @ hj.T + rr)
        xs = x_pred + k @ innov
        ikh = eye - k @ hj
        pm = ikh @ p_pred @ ikh.T + k @ rr @ k.T
        pm = 0.5 * (pm + pm.T)
        for i in range(N_X):  # variance cap on the unobservable states: congruence with 1/2 at i
            if pm[i, i] * w[i] > cfg.p_cap:
                d = np.ones(N_X)
                d[i] = 0.5
                pm = d[:, None] * pm * d[None, :]
        for i in (0, 1):  # vx, vy: unobservable, clamped to |x*| <= x_max
            lim = cfg.x_max * s[i, i] / cfg.s[i]
            xs[i] = min(max(xs[i], -lim), lim)
        nu_ay = innov[1]
        x = s_inv @ xs
        fz = loads(cfg, x[3], ax[t], ay[t], nu_ay, mec)
        out["x"][t] = x
        out["fz"][t] = fz
        out["fy"][t] = tire_lateral(cfg, x[5], x[6], fz)
        out["k"][t] = k
        out["p"][t] = pm
        out["innov"][t] = innov
    return out
