"""CommonRoad's multi-body vehicle model as a plant of the 14-DOF car: a model nobody here wrote.

``vehicle_dynamics_mb`` of the ``commonroad-vehicle-models`` package (29 states: sprung mass with roll
and pitch, unsprung axles with their own roll, lateral compliances, PAC2002-type combined-slip tyres)
is used through the package, not copied: its functions are compiled as they are with numba (their
globals re-bound to the compiled versions of their callees) and called from a C callback
(``vh_v14car_set_plant``), so the car keeps its C lockstep, its chassis node, ride heights, roll node
and actuators. This adapter adds only what the package has no input for, each as a generalised force
on the package's right-hand side: the wheel torques of the scenario (drive, brake), aerodynamic drag
and the active roll actuators' moments (on the sprung mass, the reaction on the axle). The road's
friction scales the tyre's peak friction (``p_dx1``, ``p_dy1``); the package's tyre has one friction
for all four wheels, so split friction is refused. The schema and the mapping are in ``docs/car.md``.
"""
from __future__ import annotations

import collections
import functools
import math
import types
from dataclasses import dataclass

import numpy as np

from ..errors import ScenarioError

#: MB's state vector length, and the context laid out before the parameters: x, time, drag factor
NX = 29
_T, _DRAG, _NCTX = NX, NX + 1, NX + 2
#: the road-wheel angle follows the scenario at the package's steering-rate limit at most
G = 9.81
#: brake torque fades linearly below this wheel speed [rad/s] (as in our plant: a regularised Coulomb brake)
_BRAKE_W_EPS = 0.05
#: the hidden physics (tyre, compliances, unsprung roll inertias, steering limits) of this CommonRoad
#: vehicle where a car gives none of its own: the BMW 320i
BASE_VEHICLE = 2


def _vehicle(n: int):
    import importlib

    return getattr(importlib.import_module(f"vehiclemodels.parameters_vehicle{n}"), f"parameters_vehicle{n}")()


# ---- parameters ----------------------------------------------------------------------------

def _groups(p) -> dict[str, list[str]]:
    """The float fields of a VehicleParameters, by group ('' the top level)."""
    out: dict[str, list[str]] = {"": []}
    for k, v in vars(p).items():
        if k == "trailer":
            continue
        if isinstance(v, (int, float)) and not isinstance(v, bool):
            out[""].append(k)
        elif v is not None and hasattr(v, "__dict__"):
            out[k] = [f for f, x in vars(v).items() if isinstance(x, (int, float))]
    return out


def base_vehicle(car) -> int:
    """The CommonRoad vehicle whose hidden physics the MB plant keeps: the car's own where the car is
    one of CommonRoad's parameter sets (a car file ``commonroad_vehicleN``), else BASE_VEHICLE."""
    name = getattr(car, "name", "") or ""
    return int(name[-1]) if name.startswith("commonroad_vehicle") and name[-1].isdigit() else BASE_VEHICLE


def mb_parameters(prm, base: int = BASE_VEHICLE, lateral_compliance: float | None = None):
    """The package's ``VehicleParameters`` for the car of a ``vh_v14_params_t`` (our plant's data
    sheet): its masses, inertias, geometry, springs, dampers, anti-roll bars (the bar rate that gives
    the car's roll stiffness with these springs and tyres), tyre vertical stiffness, wheel radius and
    inertia, and its tyre where that is a PAC2002 set (with `lateral_compliance`, the car's K_lt); the
    rest (the tyre's other terms, compliances, unsprung roll inertias, steering) from CommonRoad's
    vehicle `base`."""
    from ..native import ffi, lib

    plant = ffi.new("vh_v14_t *")
    if lib.vh_v14_init(plant, prm) != lib.VH_OK:
        raise ScenarioError("vehicle: the car's data do not make a valid plant")
    p = _vehicle(base)
    p.m_s, p.m_uf, p.m_ur = prm.ms, 2.0 * prm.m_uf, 2.0 * prm.m_ur  # CommonRoad's unsprung masses are per axle
    p.m = p.m_s + p.m_uf + p.m_ur
    p.a, p.b = prm.lf, prm.lr
    p.I_Phi_s, p.I_y_s, p.I_z, p.I_xz_s = prm.ix, prm.iy, prm.iz, 0.0
    p.T_f, p.T_r = 2.0 * prm.tf, 2.0 * prm.tr
    p.h_s, p.h_raf, p.h_rar = prm.h, prm.hf, prm.hr
    p.R_w, p.I_y_w, p.K_zt = prm.rw, prm.iw, prm.kt
    p.h_cg = (p.m_s * p.h_s + (p.m_uf + p.m_ur) * p.R_w) / p.m
    p.K_sf, p.K_sr = prm.k_f, prm.k_r
    p.K_sdf, p.K_sdr = plant.c_f, plant.c_r       # per corner, from the roll damping
    # MB's auxiliary torsion roll stiffness per axle: the bars, with MB's sign (a restoring bar is negative)
    p.K_tsf, p.K_tsr = -plant.k_arb_f, -plant.k_arb_r
    p.T_sb, p.T_se = 0.5, 0.5  # unused: the wheel torques are the scenario's
    # The tyre's offsets (ply steer, conicity) at zero, as the car's data have them: the package's
    # formula_lateral multiplies them by sign(camber), a relay at zero camber that, on a car without
    # static camber, drives a self-sustained roll and lateral oscillation on a straight road
    # (docs/car.md, "The tyre's offsets"). The camber thrust (p_hy3, p_vy3: continuous) is kept.
    p.tire.p_hy1 = p.tire.p_vy1 = 0.0
    if prm.tyre.model == lib.VH_MFT_PAC2002:  # the car's own tyre (a 1987 set the package cannot run)
        from ..carfile import PAC_FIELDS

        for i, f in enumerate(PAC_FIELDS):
            setattr(p.tire, f, float(prm.tyre.p[i]))
        if lateral_compliance is not None:
            p.K_lt = lateral_compliance
    return p


def flat(p) -> np.ndarray:
    """The float fields of `p` in the order the compiled model unpacks them."""
    g = _groups(p)
    vals = [getattr(p, k) for k in g[""]]
    for grp, fields in g.items():
        if grp:
            sub = getattr(p, grp)
            vals += [getattr(sub, f) for f in fields]
    return np.asarray(vals, dtype=np.float64)


# ---- the compiled model --------------------------------------------------------------------

@functools.cache
def compiled():
    """The package's model compiled with numba, and the tick the C car calls (a numba cfunc). Once
    per process (a few seconds)."""
    import numba
    import vehiclemodels.utils.tire_model as tm
    import vehiclemodels.utils.vehicle_dynamics_ks_cog as kscog
    import vehiclemodels.vehicle_dynamics_mb as vmb
    from numba import types as nt

    from ..native import ffi

    def jit(fn, **globs):
        """`fn` compiled as it is, its globals re-bound to compiled callees."""
        g = dict(fn.__globals__)
        g.update(globs)
        return numba.njit(error_model="numpy")(
            types.FunctionType(fn.__code__, g, fn.__name__, fn.__defaults__, fn.__closure__))

    sign = jit(tm.sign)
    tyre = types.ModuleType("tire_model")
    for name in ("formula_longitudinal", "formula_lateral", "formula_longitudinal_comb", "formula_lateral_comb"):
        setattr(tyre, name, jit(getattr(tm, name), sign=sign))
    steering = jit(vmb.steering_constraints)
    accel = jit(vmb.acceleration_constraints)
    ks_cog = jit(kscog.vehicle_dynamics_ks_cog, steering_constraints=steering, acceleration_constraints=accel)
    mb = jit(vmb.vehicle_dynamics_mb, steering_constraints=steering, acceleration_constraints=accel,
             vehicle_dynamics_ks_cog=ks_cog, tireModel=tyre)

    # the parameters as nested namedtuples, unpacked from a flat array (generated from the field names)
    groups = _groups(_vehicle(BASE_VEHICLE))
    classes = {grp: collections.namedtuple(f"P_{grp or 'top'}", fields) for grp, fields in groups.items()}
    top = collections.namedtuple("P", groups[""] + [grp for grp in groups if grp])
    args = [f"a[{i}]" for i in range(len(groups[""]))]
    i = len(args)
    for grp, fields in groups.items():
        if not grp:
            continue
        inner = []
        for f in fields:
            scale = "mu * " if grp == "tire" and f in ("p_dx1", "p_dy1") else ""
            inner.append(f"{scale}a[{i}]")
            i += 1
        args.append(f"C_{grp}({', '.join(inner)})")
    src = f"def unpack(a, mu):\n    return P({', '.join(args)})\n"
    ns = {"P": top, **{f"C_{g}": c for g, c in classes.items() if g}}
    exec(src, ns)  # noqa: S102 - generated from the package's field names only
    unpack = numba.njit(ns["unpack"])
    n_par = i

    # the truth record's fields as indices into doubles (vh_v14_truth_t is doubles, then one int)
    def off(name, i=0):
        return ffi.offsetof("vh_v14_truth_t", name) // 8 + i

    names = ("t", "px", "py", "yaw", "vx", "vy", "r", "ax", "ay", "z", "vz", "phi", "p", "theta", "q", "steer", "fx",
             "fy", "fxv", "fyv", "fz", "kappa", "alpha", "omega", "torque", "mu", "zu", "spring_defl", "fyf", "fyr")
    T = collections.namedtuple("TruthAt", names)(*[off(k) for k in names])
    vzu0 = 16  # VH_V14_X_VZU

    @numba.njit(error_model="numpy")
    def rhs(x, u, p, torque, drag, m_roll):
        f = np.array(mb(x.copy(), u, p))
        for i in range(4):  # the scenario's wheel torques (the package's own drive input is zero)
            f[23 + (i ^ 1)] += torque[i] / p.I_y_w
        f[3] -= drag * x[3] * abs(x[3]) / p.m
        # the actuators (+ left side up, i.e. - in MB's roll): on the sprung mass, reaction on each axle
        mt = -(m_roll[0] + m_roll[1])
        f[5] += p.I_xz_s / p.I_Phi_s * mt / (p.I_z - p.I_xz_s ** 2 / p.I_Phi_s)
        f[7] += mt / (p.I_Phi_s - p.I_xz_s ** 2 / p.I_z)
        f[14] += m_roll[0] / p.I_uf
        f[19] += m_roll[1] / p.I_ur
        return f

    @numba.njit(error_model="numpy")
    def corners(x, p):
        """Per corner (FL FR RL RR): tyre compression, its rate, MB's suspension extension z_S and the
        spring's compression from its free length (the ride-height sensors')."""
        c, dc, zs, s = np.empty(4), np.empty(4), np.empty(4), np.empty(4)
        for j in range(2):
            zu, vzu, phu, pu = (x[16], x[17], x[13], x[14]) if j == 0 else (x[21], x[22], x[18], x[19])
            half = 0.5 * (p.T_f if j == 0 else p.T_r)
            arm = p.a if j == 0 else -p.b
            ks = p.K_sf if j == 0 else p.K_sr
            share = (p.b if j == 0 else p.a) / (2 * (p.a + p.b))
            for side in range(2):
                k = 2 * j + side
                sg = -1.0 if side == 0 else 1.0  # MB's "left" wheels (sg +1) are on our right
                c[k] = zu + p.R_w * (math.cos(phu) - 1) - sg * half * math.sin(phu)
                dc[k] = vzu - (p.R_w * math.sin(phu) + sg * half * math.cos(phu)) * pu
                zs[k] = ((p.h_s - p.R_w + zu - x[11]) / math.cos(x[6]) - p.h_s + p.R_w + arm * x[8]
                         + sg * half * (x[6] - phu))
                s[k] = p.m_s * G * share / ks - zs[k]
        return c, dc, zs, s

    @numba.njit(error_model="numpy")
    def truth_of(x, f, p, torque, mu, t, out):
        """Our truth record from MB's state at a tick's start and its right-hand side there; the tyre
        forces again from the package's tyre functions on MB's own slips, loads and cambers."""
        delta = x[2]
        vx, vy, r = x[3], x[10], x[5]
        c, _, zs, s = corners(x, p)
        out[T.t] = t
        out[T.px], out[T.py], out[T.yaw] = x[0], x[1], x[4]
        out[T.vx], out[T.vy], out[T.r] = vx, vy, r
        out[T.ax] = f[3] - r * vy   # sum X / m
        out[T.ay] = f[10] + r * vx  # the sprung mass's: sum Y_s / m_s
        out[T.z], out[T.vz] = -x[11], -x[12]  # MB's z points down
        out[T.phi], out[T.p] = -x[6], -x[7]   # MB's roll: + right side up; ours + left side up
        out[T.theta], out[T.q] = -x[8], -x[9]  # ours: + nose down
        out[T.steer] = delta
        moving = abs(vx) >= 0.1  # the package's kinematic switch
        for k in range(4):
            front = k < 2
            sg = -1.0 if k % 2 == 0 else 1.0  # MB's "left" wheels (sg +1) are on our right
            w = 23 + (k ^ 1)                  # MB's spin state of our wheel k
            half = 0.5 * (p.T_f if front else p.T_r)
            fz = c[k] * p.K_zt
            vw = vx + sg * half * r
            dl = delta if front else 0.0
            if front:
                lat = vy + p.a * r - x[14] * (p.R_w - x[16])
                uw = vw * math.cos(dl) + (vy + p.a * r) * math.sin(dl)
                d, e = p.D_f, p.E_f
            else:
                lat = vy - p.b * r - x[19] * (p.R_w - x[21])
                uw = vw
                d, e = p.D_r, p.E_r
            uw = max(uw, 0.0)
            slip = 1 - p.R_w * x[w] / uw if moving and uw > 0 else 0.0
            alpha = math.atan(lat / vw) - dl if moving else 0.0
            gam = x[6] + sg * (d * zs[k] + e * zs[k] ** 2)
            fx0 = tyre.formula_longitudinal(slip, gam, fz, p.tire)
            lat_f = tyre.formula_lateral(alpha, gam, fz, p.tire)
            fx = tyre.formula_longitudinal_comb(slip, alpha, fx0, p.tire)
            fy = tyre.formula_lateral_comb(slip, alpha, gam, lat_f[1], fz, lat_f[0], p.tire)
            out[T.fx + k], out[T.fy + k] = fx, fy
            out[T.fxv + k] = fx * math.cos(dl) - fy * math.sin(dl)
            out[T.fyv + k] = fx * math.sin(dl) + fy * math.cos(dl)
            out[T.fz + k] = fz
            out[T.kappa + k] = -slip   # ours: + driving
            out[T.alpha + k] = -alpha  # ours: + where the force is + (left)
            out[T.omega + k] = x[w]
            out[T.torque + k] = torque[k]
            out[T.mu + k] = mu
            load0 = (p.m_s * (p.b if front else p.a) / (p.a + p.b) + (p.m_uf if front else p.m_ur)) * G
            out[T.zu + k] = load0 / (2 * p.K_zt) - c[k]  # unsprung heave from static, + up (init_mb's)
            out[T.spring_defl + k] = s[k]
        out[T.fyf] = 0.5 * (out[T.fy] + out[T.fy + 1])
        out[T.fyr] = 0.5 * (out[T.fy + 2] + out[T.fy + 3])

    @numba.njit(error_model="numpy")
    def step(ctx, inp, m_roll, truth, xs, dt):
        """One tick: the truth at its start, then RK4 over it (sub-steps where the wheel spin is stiff)."""
        x = ctx[:NX]
        pa = ctx[_NCTX:_NCTX + n_par]
        mu = inp[9] if np.isfinite(inp[9]) else 1.0
        mu = min(max(mu, 0.05), 3.0)
        p = unpack(pa, mu)
        steer = inp[0] if np.isfinite(inp[0]) else 0.0
        u = np.array([(steer - x[2]) / dt, 0.0])  # steering rate towards the scenario's angle
        torque = np.empty(4)
        for i in range(4):
            dr = inp[1 + i] if np.isfinite(inp[1 + i]) else 0.0
            br = abs(inp[5 + i]) if np.isfinite(inp[5 + i]) else 0.0
            fade = min(x[23 + (i ^ 1)] / _BRAKE_W_EPS, 1.0)
            torque[i] = dr - br * fade
        drag = ctx[_DRAG]
        f = rhs(x, u, p, torque, drag, m_roll)
        truth_of(x, f, p, torque, mu, ctx[_T], truth)
        # sub-steps: the wheel spin's rate R^2 C_kappa / (I_w v) at the heaviest load, RK4 stable to ~2.8
        lam = p.R_w ** 2 * abs(p.tire.p_kx1) * p.m * G / (p.I_y_w * max(abs(x[3]), 0.5))
        n = max(1, int(math.ceil(lam * dt / 2.0)))
        h = dt / n
        for _ in range(n):
            k1 = rhs(x, u, p, torque, drag, m_roll)
            k2 = rhs(x + 0.5 * h * k1, u, p, torque, drag, m_roll)
            k3 = rhs(x + 0.5 * h * k2, u, p, torque, drag, m_roll)
            k4 = rhs(x + h * k3, u, p, torque, drag, m_roll)
            x += h / 6.0 * (k1 + 2 * k2 + 2 * k3 + k4)
            for i in range(23, 27):  # negative wheel spin forbidden, as in the package
                if x[i] < 0.0:
                    x[i] = 0.0
        ctx[_T] += dt
        _, dc, _, _ = corners(x, p)
        for i in range(4):
            xs[vzu0 + i] = -dc[i]  # unsprung heave rate, + up
        return n

    dt = 0.0005
    sig = nt.void(nt.CPointer(nt.float64), nt.CPointer(nt.float64), nt.CPointer(nt.float64),
                  nt.CPointer(nt.float64), nt.CPointer(nt.float64))
    n_ctx = _NCTX + n_par

    def c_tick(ctx, inp, m_roll, truth, xs):
        step(numba.carray(ctx, n_ctx), numba.carray(inp, 13), numba.carray(m_roll, 2),
             numba.carray(truth, T.fyr + 1), numba.carray(xs, 32), dt)

    if not numba.config.DISABLE_JIT:  # NUMBA_DISABLE_JIT=1: the Python functions, for a debugger
        c_tick = numba.cfunc(sig)(c_tick)

    return types.SimpleNamespace(mb=mb, unpack=unpack, step=step, rhs=rhs, c_tick=c_tick, n_par=n_par)


@dataclass
class MbPlant:
    """One MB plant's state and parameters (the context its C callback gets)."""

    p: object              # the package's VehicleParameters
    v0: float              # initial speed [m/s]
    drag: float = 0.0      # rho CdA / 2 [kg/m]

    def __post_init__(self):
        from vehiclemodels.init_mb import init_mb

        self._x0 = np.asarray(init_mb([0.0, 0.0, 0.0, self.v0, 0.0, 0.0, 0.0], self.p), dtype=np.float64)
        self.ctx = np.zeros(_NCTX + len(flat(self.p)))
        self.ctx[_NCTX:] = flat(self.p)
        self.ctx[_DRAG] = self.drag
        self.reset()

    def reset(self) -> None:
        self.ctx[:NX] = self._x0
        self.ctx[_T] = 0.0

    @property
    def x(self) -> np.ndarray:
        return self.ctx[:NX]

    def attach(self, car) -> None:
        """Make this the plant of a ``vh_v14car_t *``."""
        from ..native import ffi, lib

        fn = compiled().c_tick
        self._fn = ffi.cast("vh_v14car_plant_fn", fn.address)
        lib.vh_v14car_set_plant(car, self._fn, ffi.from_buffer("double[]", self.ctx))


__all__ = ["MbPlant", "mb_parameters", "compiled", "flat", "BASE_VEHICLE", "NX"]
