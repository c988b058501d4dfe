"""Synthetic manoeuvres for the tests of the fixed-point filter against the double one: quick drives
with a simple nonlinear vehicle, no plant to build or step. The estimators' truth is the 14-DOF chassis
plant (vehest_can.systems.tireforce.scenario); these only feed both filters the same inputs."""
import math

import numpy as np

from vehest_can.systems.tireforce.api import Inputs

# --------------------------------------------------------------------------------------------
# 9 DOF (x, y, yaw, roll, 4 wheel spins) with the paper's rigid-body equations (eq. 29-30, the
# appendix sums) but *not* the monitoring model's shortcuts: tire forces from slip (a
# Magic-Formula-like curve with friction mu and a friction-circle limit), rigid-body load
# transfer with the half-tracks (twice eq. 39's lateral bracket, and the roll term with gravity's
# sign), a heavier vehicle than the estimator's. Integrated by RK4 at the estimator step.
# --------------------------------------------------------------------------------------------

VEHICLE = dict(m=1814.0, ms=1661.0, iz=2560.0, ix=580.0, lf=1.076, lr=1.617, h=0.55, e=0.48, hf=0.114,
               hr=0.004, kphif=108205.8, kphir=81436.7, cphif=826.8, cphir=658.9, rw=0.305, iw=2.0,
               tf=0.784, tr=0.760, g=9.81)
NOISE = dict(ax=0.05, ay=0.05, r=0.002, p=0.003, omega=0.02, torque=1.0)


def _ramp(t, t0, t1, a, b):
    if t <= t0:
        return a
    if t >= t1:
        return b
    return a + (b - a) * (t - t0) / (t1 - t0)


def paper_profile(t):
    """Sec. 4: steer 1 deg then 2 deg, brake 60 Nm front / 40 Nm rear, friction 1.1 -> 0.2."""
    delta = math.radians(_ramp(t, 0.5, 1.0, 0.0, 1.0) + _ramp(t, 3.0, 3.5, 0.0, 1.0))
    b = 1.0 if t >= 1.5 else 0.0
    return delta, (-60 * b, -60 * b, -40 * b, -40 * b), _ramp(t, 5.5, 5.7, 1.1, 0.2)


def ramp_profile(t):
    """Sec. 3.1: steer 0 -> 4 deg over 10 s, no brake, dry road."""
    return math.radians(_ramp(t, 0.0, 10.0, 0.0, 4.0)), (0.0, 0.0, 0.0, 0.0), 1.1


def sine_profile(t):
    """0.5 Hz, 2 deg sine steer with a light drive torque, dry road."""
    return math.radians(2.0 * math.sin(2 * math.pi * 0.5 * t)) if t > 0.5 else 0.0, (20.0, 20.0, 0.0, 0.0), 1.1


PROFILES = {"paper": paper_profile, "ramp": ramp_profile, "sine": sine_profile}


def synthetic_manoeuvre(profile="paper", duration=8.0, ts=5e-4, v0=70 / 3.6, dm=200.0, seed=0, noise=True):
    """Simulate a drive. Returns (truth dict, Inputs): truth has t, x (n,7 with Fyf/Fyr the axle
    averages), fy, fz, fx (n,4) wheel-frame tire forces, mu."""
    prof = PROFILES[profile] if isinstance(profile, str) else profile
    p = VEHICLE
    m, ms = p["m"] + dm, p["ms"] + dm
    lf, lr, h, e, tf, tr, g, rw, iw = (p[k] for k in ("lf", "lr", "h", "e", "tf", "tr", "g", "rw", "iw"))
    l = lf + lr
    kphi, cphi = p["kphif"] + p["kphir"], p["cphif"] + p["cphir"]
    kf = p["kphif"] / kphi
    ixx = p["ix"] + ms * e * e
    det = m * ixx - (ms * e) ** 2

    def forces(s, delta, mu, acc):
        vx, vy, r, phi = s[0], s[1], s[2], s[3]
        ax, ay = acc
        dfx = m * h * ax / (2 * l)
        roll_m = m * ay * h + ms * g * e * math.sin(phi)
        latf, latr = kf * roll_m / (2 * tf), (1 - kf) * roll_m / (2 * tr)
        fz0f, fz0r = m * g * lr / (2 * l), m * g * lf / (2 * l)
        fz = [max(v, 0.0) for v in (fz0f - dfx - latf, fz0f - dfx + latf, fz0r + dfx - latr, fz0r + dfx + latr)]
        fx, fy = [0.0] * 4, [0.0] * 4
        for i in range(4):
            front, side = i < 2, (1.0 if i % 2 == 0 else -1.0)  # left wheels at y = +t
            vxi = vx - side * (tf if front else tr) * r
            vyi = vy + (lf if front else -lr) * r
            d = delta if front else 0.0
            vw = vxi * math.cos(d) + vyi * math.sin(d)
            vlat = -vxi * math.sin(d) + vyi * math.cos(d)
            alpha = -math.atan2(vlat, max(abs(vw), 0.5))
            kap = (s[5 + i] * rw - vw) / max(abs(vw), 0.5)
            dmax = mu * fz[i] * (1.0 - 0.08 * fz[i] / 5000.0)
            fy0 = dmax * math.sin(1.3 * math.atan(10.0 * alpha))
            fx0 = dmax * math.sin(1.6 * math.atan(12.0 * kap))
            tot = math.hypot(fx0, fy0)
            if tot > dmax > 0.0:
                fx0, fy0 = fx0 * dmax / tot, fy0 * dmax / tot
            fx[i], fy[i] = fx0, fy0
        return fx, fy, fz

    def deriv(s, delta, tq, mu, acc):
        vx, vy, r, phi, pp = s[:5]
        fx, fy, fz = forces(s, delta, mu, acc)
        c, sn = math.cos(delta), math.sin(delta)
        sfyf = sum(fx[i] * sn + fy[i] * c for i in (0, 1))
        sfx = sum(fx[i] * c - fy[i] * sn for i in (0, 1)) + fx[2] + fx[3]
        sfy = sfyf + fy[2] + fy[3]
        smz = (lf * sfyf - lr * (fy[2] + fy[3]) + tf * (-(fx[0] * c - fy[0] * sn) + (fx[1] * c - fy[1] * sn))
               + tr * (fx[3] - fx[2]))
        smx = p["hf"] * sfyf + p["hr"] * (fy[2] + fy[3]) - kphi * phi - cphi * pp
        g1, g4 = sfy - m * r * vx, smx + ms * e * r * vx
        d = np.empty(9)
        d[0] = (sfx + m * r * vy - ms * e * pp * r) / m
        d[1] = (ixx * g1 + ms * e * g4) / det
        d[2] = smz / p["iz"]
        d[3] = pp
        d[4] = (ms * e * g1 + m * g4) / det
        d[5:] = [(tq[i] - fx[i] * rw) / iw for i in range(4)]
        return d, fx, fy, fz

    n = int(round(duration / ts))
    s = np.array([v0, 0.0, 0.0, 0.0, 0.0] + [v0 / rw] * 4)
    acc = (0.0, 0.0)
    tr_ = {k: np.empty((n,) + sh) for k, sh in dict(t=(), x=(7,), fy=(4,), fz=(4,), fx=(4,), mu=()).items()}
    meas = {k: np.empty((n,) + sh) for k, sh in dict(ax=(), ay=(), r=(), p=(), delta=(), omega=(4,),
                                                       torque=(4,)).items()}
    for k in range(n):
        t = k * ts
        delta, tq, mu = prof(t)
        k1, fx, fy, fz = deriv(s, delta, tq, mu, acc)
        ax, ay = k1[0] - s[2] * s[1], k1[1] + s[2] * s[0]
        tr_["t"][k], tr_["mu"][k] = t, mu
        tr_["x"][k] = [s[0], s[1], s[2], s[3], s[4], 0.5 * (fy[0] + fy[1]), 0.5 * (fy[2] + fy[3])]
        tr_["fy"][k], tr_["fz"][k], tr_["fx"][k] = fy, fz, fx
        meas["ax"][k], meas["ay"][k], meas["r"][k], meas["p"][k] = ax, ay, s[2], s[4]
        meas["delta"][k], meas["omega"][k], meas["torque"][k] = delta, s[5:], tq
        acc = (ax, ay)
        k2 = deriv(s + ts / 2 * k1, delta, tq, mu, acc)[0]
        k3 = deriv(s + ts / 2 * k2, delta, tq, mu, acc)[0]
        k4 = deriv(s + ts * k3, delta, tq, mu, acc)[0]
        s = s + ts / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
    if noise:
        rng = np.random.default_rng(seed)
        for name, sigma in NOISE.items():
            meas[name] = meas[name] + rng.normal(0.0, sigma, meas[name].shape)
    return tr_, Inputs(**meas)
