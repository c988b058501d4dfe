"""Independent numpy reference of the roll UKF (docs/roll.md): the 9-DOF model (eq. 1-10) written
again from the equations, vectorised over the sigma points, and the paper's UKF steps (eq. 13-26)
with the same symmetric sigma points and weights as the C. Double precision only.

``filterpy_ukf`` builds filterpy's ``UnscentedKalmanFilter`` on the same model as a second,
outside reference (its sigma points redrawn after the prediction, as eq. 19 does)."""
from __future__ import annotations

import numpy as np

G = 9.81
NX, NZ, NU = 21, 14, 4   # states at most (the robust variant's), measurements, inputs
NX_PAPER = 16            # the paper's variant carries the first 16
ROBUST = 1               # vh_roll_params_t.variant of the robust variant
X_VY, X_R, X_P = 0, 1, 5  # lateral velocity, yaw rate, roll rate (VH_ROLL_X_*)
Z_LAT = (0, 13)          # the lateral measurements a_y and r (VH_ROLL_Z_AY, VH_ROLL_Z_R)
Z_AZU = (1, 2, 3, 4)     # the unsprung vertical accelerations (VH_ROLL_Z_AZU): not in the robust variant


def n_states(p: dict) -> int:
    """States the variant carries: 16 (the paper's) or 21 (+ the roll-moment disturbance [kN m] and the
    four tyre-load disturbances [kN])."""
    return NX if int(p.get("variant", 0)) == ROBUST else NX_PAPER


class RollModel:
    """The model of docs/roll.md from a parameter mapping (``api.params_dict`` or a dict)."""

    def __init__(self, p: dict):
        self.p = p
        l = p["lf"] + p["lr"]
        h_ra = p["hf"] + (p["hr"] - p["hf"]) * p["lf"] / l
        self.e = p["h"] - h_ra
        self.hp = p["h"]
        self.ms = p["ms"]
        self.m = p["ms"] + 2 * p["m_uf"] + 2 * p["m_ur"]
        self.ip = p["ix"] + p["ms"] * self.e**2
        self.iq = p["iy"] + p["ms"] * self.hp**2
        self.a = p["ms"] * self.hp
        self.b = p["ms"] * self.e
        self.det_x = self.m * self.iq - self.a**2
        self.det_y = self.m * self.ip - self.b**2
        t = np.array([p["tf"], p["tf"], p["tr"], p["tr"]])
        front = np.array([True, True, False, False])
        self.cx = np.where(front, p["lf"], -p["lr"])
        self.cy = np.array([1.0, -1.0, 1.0, -1.0]) * t
        self.kw = np.where(front, p["k_f"], p["k_r"])
        self.cw = np.where(front, p["cphi_f"], p["cphi_r"]) / (2 * t**2)
        fs0 = p["ms"] * G * np.where(front, p["lr"], p["lf"]) / (2 * l)
        self.mu_c = np.where(front, p["m_uf"], p["m_ur"])
        self.fz0 = fs0 + self.mu_c * G
        self.jack = np.where(front, p["hf"], p["hr"]) / t * np.array([-1.0, 1.0, -1.0, 1.0])
        self.t = t
        def ks(kphi, tt):  # suspension roll stiffness from the total (springs in series with the tyres)
            return 1.0 / (1.0 / kphi - 1.0 / (2 * p["kt"] * tt**2))
        self.arb_f = (ks(p["kphi_f"], p["tf"]) - 2 * p["k_f"] * p["tf"] ** 2) / (4 * p["tf"] ** 2)
        self.arb_r = (ks(p["kphi_r"], p["tr"]) - 2 * p["k_r"] * p["tr"] ** 2) / (4 * p["tr"] ** 2)
        dpk = p["mu"] * p["mu_load"]
        self.mf_d = dpk
        self.mf_b = np.where(front, p["calpha_f"], p["calpha_r"]) / (p["mf_c"] * dpk)
        self.front = front
        self.n = n_states(p)
        self.ay_gravity = bool(int(p.get("ay_gravity", 0)))

    def deriv(self, X: np.ndarray, u: np.ndarray):
        """dX for states X (k, NX); returns (dX, ay)."""
        p = self.p
        delta, vx, mf, mr = u
        vy, r, z, vz, phi, pr, th, q = (X[:, i] for i in range(8))
        zu, vzu = X[:, 8:12], X[:, 12:16]
        zs = z[:, None] + self.cy * phi[:, None] - self.cx * th[:, None]          # eq. 9
        vzs = vz[:, None] + self.cy * pr[:, None] - self.cx * q[:, None]
        d = zu - zs
        fsd = self.kw * d + self.cw * (vzu - vzs)                                  # eq. 8
        farb = np.stack([self.arb_f * (d[:, 0] - d[:, 1]), -self.arb_f * (d[:, 0] - d[:, 1]),
                         self.arb_r * (d[:, 2] - d[:, 3]), -self.arb_r * (d[:, 2] - d[:, 3])], axis=1)
        mom = np.array([mf, -mf, mr, -mr])
        fa = mom / (2 * self.t)
        cd, sd = np.cos(delta), np.sin(delta)
        vxc = vx - r[:, None] * self.cy
        vyc = vy[:, None] + r[:, None] * self.cx
        vxw = np.where(self.front, vxc * cd + vyc * sd, vxc)
        vyw = np.where(self.front, -vxc * sd + vyc * cd, vyc)
        ta = -vyw / np.maximum(np.abs(vxw), p["v_low"])                          # eq. 7
        fz = self.fz0 - p["kt"] * zu - p["ct"] * vzu                             # eq. 10
        if self.n > NX_PAPER:
            fz = fz + 1000.0 * X[:, 17:21]                                      # eq. 10d [kN]
        fz = np.maximum(fz, 0.0)
        fy = self.mf_d * fz * np.sin(p["mf_c"] * np.arctan(self.mf_b * ta))       # eq. 11-12
        fxv = np.where(self.front, -fy * sd, 0.0)
        fyv = np.where(self.front, fy * cd, fy)
        fb = fsd + farb + self.jack * fyv + fa
        sfx, sfy = fxv.sum(1), fyv.sum(1)
        smz = (self.cx * fyv - self.cy * fxv).sum(1)
        smx = (self.cy * (fsd + farb + fa)).sum(1) + self.ms * G * self.e * np.sin(phi)
        if self.n > NX_PAPER:
            smx = smx + 1000.0 * X[:, 16]                                      # eq. 4d [kN m]
        smy = -(self.cx * fb).sum(1) + self.ms * G * self.hp * np.sin(th)
        rx = sfx + self.m * r * vy - self.b * pr * r
        rq = smy + self.a * r * vy
        ry = sfy - self.m * r * vx - self.a * q * r
        rp = smx + self.b * r * vx
        dX = np.empty_like(X)
        dX[:, 0] = (self.ip * ry + self.b * rp) / self.det_y
        dX[:, 1] = smz / p["iz"]
        dX[:, 2] = vz
        dX[:, 3] = fb.sum(1) / self.ms
        dX[:, 4] = pr
        dX[:, 5] = (self.m * rp + self.b * ry) / self.det_y
        dX[:, 6] = q
        dX[:, 7] = (self.m * rq - self.a * rx) / self.det_x
        dX[:, 8:12] = vzu
        dX[:, 12:16] = (fz - self.fz0 - fb) / self.mu_c
        if X.shape[1] > NX_PAPER:
            dX[:, 16:] = 0.0                                                    # eq. 4d, 10d: random walks
        return dX, dX[:, 0] + r * vx

    def f(self, X, u):
        X = np.atleast_2d(X)
        dt = self.p["dt"]
        k1, _ = self.deriv(X, u)
        k2, _ = self.deriv(X + dt * k1, u)
        return X + 0.5 * dt * (k1 + k2)                                          # eq. 16 (Heun)

    def h(self, X, u):
        X = np.atleast_2d(X)
        dX, ay = self.deriv(X, u)
        if self.ay_gravity:
            ay = ay * np.cos(X[:, 4]) + G * np.sin(X[:, 4])                     # eq. 20g: body-fixed
        zs = X[:, 2:3] + self.cy * X[:, 4:5] - self.cx * X[:, 6:7]
        return np.column_stack([ay, dX[:, 12:16], -X[:, 8:12], X[:, 8:12] - zs, X[:, 1]])   # eq. 20


def sigma_weights(n: int, kappa: float):
    w = np.full(2 * n + 1, 0.5 / (n + kappa))
    w[0] = kappa / (n + kappa)
    return np.sqrt(n + kappa), w


def sigma_points(x, P, gamma):
    L = np.linalg.cholesky(P)
    return np.vstack([x, x + gamma * L.T, x - gamma * L.T])                     # eq. 15 / 19


class _Filter:
    """What both reference filters share: a run over arrays, step by step, and the robust variant's
    adaptive noise (eq. 18a-b)."""

    x: np.ndarray
    p: dict
    n: int

    def _init_q(self) -> None:
        p = self.p
        self.q = np.asarray(p["q"][: self.n], float)
        adapt = p["variant"] == ROBUST and p["qp_adapt_tau"] > 0.0
        self.nis_alpha = min(p["dt"] / p["qp_adapt_tau"], 1.0) if adapt else 0.0
        self.qp_max = p["qp_adapt_max"] if adapt else 1.0
        self.nis = 0.0
        self.z_use = np.ones(NZ, bool)
        if p["variant"] == ROBUST:
            self.z_use[list(Z_AZU)] = False

    def reset(self):
        self.x = np.zeros(self.n)                                               # eq. 13
        self.P = np.diag(np.asarray(self.p["p0"][: self.n], float))             # eq. 14
        self.nis_lp = 1.0
        self.nis_lat_lp = 1.0

    def _Q(self) -> np.ndarray:
        """eq. 18a-b: Q with the roll rate's noise scaled by s^2, s = the low-passed NIS per body-motion
        measurement, and the lateral velocity's and yaw rate's by the same from a_y and r, within
        [1, qp_max]."""
        q = self.q.copy()
        q[X_P] *= min(max(self.nis_lp, 1.0), self.qp_max) ** 2
        q[[X_VY, X_R]] *= min(max(self.nis_lat_lp, 1.0), self.qp_max) ** 2
        return np.diag(q)

    def _nis(self, nu: np.ndarray, S: np.ndarray, sel: np.ndarray) -> None:
        """The step's NIS and eq. 18a-b's low-passes: nu^T S^-1 nu split by measurement as the C does,
        the squares of L^-1 nu (S = L L^T, the valid measurements in their order)."""
        w2 = np.linalg.solve(np.linalg.cholesky(S), nu) ** 2
        lat = np.isin(np.flatnonzero(sel), Z_LAT)
        self.nis = float(w2.sum())
        if (~lat).any():
            self.nis_lp += self.nis_alpha * (float(w2[~lat].sum()) / int((~lat).sum()) - self.nis_lp)
        if lat.any():
            self.nis_lat_lp += self.nis_alpha * (float(w2[lat].sum()) / int(lat.sum()) - self.nis_lat_lp)

    def step(self, u, z, mask: int = (1 << NZ) - 1) -> None:
        raise NotImplementedError

    def run(self, u, z, mask=None) -> np.ndarray:
        """States after each step (n of the variant's); ``mask`` (bit j: measurement j valid) per step,
        all valid if None."""
        xs = np.zeros((len(u), len(self.x)))
        for k in range(len(u)):
            self.step(u[k], z[k], (1 << NZ) - 1 if mask is None else int(mask[k]))
            xs[k] = self.x
        return xs


class RefUkf(_Filter):
    """The paper's UKF steps (eq. 13-26) in numpy, on RollModel."""

    def __init__(self, p: dict):
        self.model = RollModel(p)
        self.p = p
        self.n = n = self.model.n
        self.gamma, self.w = sigma_weights(n, p["kappa"])
        self._init_q()
        self.R = np.diag(p["r"])
        self.reset()

    def step(self, u, z, mask: int = (1 << NZ) - 1):
        w = self.w
        X = sigma_points(self.x, self.P, self.gamma)                            # eq. 15
        Xf = self.model.f(X, u)                                                 # eq. 16
        xp = w @ Xf                                                             # eq. 17
        dX = Xf - xp
        Pp = (w[:, None] * dX).T @ dX + self._Q()                               # eq. 18, 18a
        X = sigma_points(xp, Pp, self.gamma)                                    # eq. 19
        Z = self.model.h(X, u)                                                  # eq. 20
        zp = w @ Z                                                              # eq. 21
        sel = np.array([(mask >> i) & 1 for i in range(NZ)], bool) & np.isfinite(z) & self.z_use
        self.x, self.P = xp, Pp
        if not sel.any():
            return
        dZ = (Z - zp)[:, sel]
        dX = X - xp
        Pzz = (w[:, None] * dZ).T @ dZ + self.R[np.ix_(sel, sel)]
        Pxz = (w[:, None] * dX).T @ dZ
        K = np.linalg.solve(Pzz, Pxz.T).T                                       # eq. 22
        nu = np.asarray(z)[sel] - zp[sel]
        self._nis(nu, Pzz, sel)
        self.x = xp + K @ nu                                                    # eq. 25
        self.P = Pp - K @ Pzz @ K.T                                             # eq. 26
        self.P = 0.5 * (self.P + self.P.T)



def filterpy_ukf(p: dict):
    """filterpy's UnscentedKalmanFilter on RollModel with Julier's symmetric set (kappa), the
    same weights; call ``filterpy_step`` to run it the paper's way (sigma points redrawn)."""
    from filterpy.kalman import JulierSigmaPoints, UnscentedKalmanFilter

    model = RollModel(p)
    n = model.n
    pts = JulierSigmaPoints(n, kappa=p["kappa"])
    ukf = UnscentedKalmanFilter(dim_x=n, dim_z=NZ, dt=p["dt"], hx=lambda x, u: model.h(x, u)[0],
                                fx=lambda x, dt, u: model.f(x, u)[0], points=pts)
    ukf.x = np.zeros(n)
    ukf.P = np.diag(np.asarray(p["p0"][:n], float))
    ukf.Q = np.diag(p["q"][:n])
    ukf.R = np.diag(p["r"])
    return ukf


def filterpy_step(ukf, u, z):
    ukf.predict(u=u)
    ukf.sigmas_f = ukf.points_fn.sigma_points(ukf.x, ukf.P)    # eq. 19: redrawn
    ukf.update(z, u=u)


class RefEkf(_Filter):
    """An EKF on the same model (RollModel), tuning (Q, R, P0) and masking, for the comparison
    the issue asks for (the paper argues the UKF beats the EKF here). Jacobians by central
    differences of the discrete model F and of H (step 1e-6 of each state's sqrt(p0))."""

    def __init__(self, p: dict):
        self.model = RollModel(p)
        self.p = p
        self.n = n = self.model.n
        self._init_q()
        self.R = np.diag(p["r"])
        self.hstep = 1e-6 * np.sqrt(np.asarray(p["p0"][:n], float))
        self.reset()

    def _jac(self, fn, x, u):
        n = self.n
        d = np.diag(self.hstep)
        Y = fn(np.vstack([x + d, x - d]), u)
        return ((Y[:n] - Y[n:]) / (2 * self.hstep[:, None])).T

    def step(self, u, z, mask: int = (1 << NZ) - 1):
        F = self._jac(self.model.f, self.x, u)
        xp = self.model.f(self.x, u)[0]
        Pp = F @ self.P @ F.T + self._Q()
        sel = np.array([(mask >> i) & 1 for i in range(NZ)], bool) & np.isfinite(z) & self.z_use
        self.x, self.P = xp, Pp
        if not sel.any():
            return
        Hm = self._jac(self.model.h, xp, u)[sel]
        zp = self.model.h(xp, u)[0][sel]
        S = Hm @ Pp @ Hm.T + self.R[np.ix_(sel, sel)]
        K = np.linalg.solve(S, Hm @ Pp).T
        nu = np.asarray(z)[sel] - zp
        self._nis(nu, S, sel)
        self.x = xp + K @ nu
        IKH = np.eye(self.n) - K @ Hm
        self.P = IKH @ Pp @ IKH.T + K @ self.R[np.ix_(sel, sel)] @ K.T   # Joseph form

