"""Off-line evaluation of the roll UKF against the 14-DOF plant's truth (seed 003's cases).

The paper's cases: front road-wheel steer ramped to 5 deg on a level road at 36 and 72 km/h
(Fig. 2-6). The 14 measurements are synthesised from the plant's truth with Gaussian noise (off the
bus: the roll node's frames are the demo's and :func:`filters_on_bus`'s); the UKF runs at its own step
(default 1 ms, every second plant tick) in both precisions, and its roll angle and rate are
compared with the truth.

``vehest-can study roll.filters`` prints the figures.
"""
from __future__ import annotations

import argparse
from dataclasses import dataclass

import numpy as np

from . import api as rn

PLANT_DT = 0.0005
# Sensor noise (1 sigma) of the synthesised measurements, in the order of MEAS_NAMES' groups.
NOISE = {"ay": 0.05, "azu": 0.2, "dt": 0.0002, "ds": 0.0005, "r": 0.005, "vx": 0.05, "steer": 0.0001}


def paper_case(speed_kmh: float, steer_deg: float = 5.0, t_ramp=(0.5, 2.5), duration_s: float = 6.0,
               seed: int = 1) -> dict:
    """A chassis scenario document: steer ramp 0 -> steer_deg between t_ramp[0] and t_ramp[1],
    held; level dry road (mu 1); no aerodynamic drag (the paper neglects it)."""
    return {
        "kind": "roll", "name": f"roll_paper_{int(speed_kmh)}kph",
        "description": f"seed 003 Fig. 2: steer ramp to {steer_deg} deg at {speed_kmh} km/h",
        "duration_s": duration_s, "seed": seed, "initial_speed_kmh": speed_kmh,
        "driver": {"steer_deg": [[0.0, 0.0], [t_ramp[0], 0.0], [t_ramp[1], steer_deg]]},
        "road": {"mu": [[0.0, 1.0]]},
        "vehicle": {"drag_area_m2": 0.0},
    }


def run_plant(doc: dict) -> np.ndarray:
    from vehest_can.native import ffi, lib
    from vehest_can.sim.veh14 import veh14_scenario_from_dict

    sc = veh14_scenario_from_dict(doc, "<scenario>", doc["kind"])
    return sc.run_truth(ffi, lib)


def corner_geometry(prm=None):
    prm = prm if prm is not None else rn.default_params()
    cx = np.array([prm.lf, prm.lf, -prm.lr, -prm.lr])
    cy = np.array([prm.tf, -prm.tf, prm.tr, -prm.tr])
    return cx, cy


def synthesise(truth: np.ndarray, decim: int = 2, seed: int = 1, noise: dict | None = None,
               prm=None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(u (n, NU), z (n, NZ), index of the plant samples) at every decim-th plant tick.

    Unsprung vertical accelerations are the second difference of the truth's zu (0.5 ms); tyre
    deflection is -zu; suspension deflection zu - (z + y phi - x theta); vx and steer as the
    wheel-speed and steering sensors would give them."""
    noise = dict(NOISE, **(noise or {}))
    rng = np.random.default_rng(seed)
    cx, cy = corner_geometry(prm)
    zu = truth["zu"]
    azu = np.zeros_like(zu)
    azu[1:-1] = (zu[2:] - 2 * zu[1:-1] + zu[:-2]) / PLANT_DT**2
    zs = truth["z"][:, None] + cy[None, :] * truth["phi"][:, None] - cx[None, :] * truth["theta"][:, None]
    idx = np.arange(1, len(truth) - 1, decim)
    n = len(idx)
    z = np.zeros((n, rn.NZ))
    z[:, 0] = truth["ay"][idx] + noise["ay"] * rng.standard_normal(n)
    z[:, 1:5] = azu[idx] + noise["azu"] * rng.standard_normal((n, 4))
    z[:, 5:9] = -zu[idx] + noise["dt"] * rng.standard_normal((n, 4))
    z[:, 9:13] = (zu - zs)[idx] + noise["ds"] * rng.standard_normal((n, 4))
    z[:, 13] = truth["r"][idx] + noise["r"] * rng.standard_normal(n)
    u = np.zeros((n, rn.NU))
    u[:, 0] = truth["steer"][idx] + noise["steer"] * rng.standard_normal(n)
    u[:, 1] = truth["vx"][idx] + noise["vx"] * rng.standard_normal(n)
    return u, z, idx


@dataclass
class CaseResult:
    speed_kmh: float
    peak_phi: float
    peak_p: float
    peak_ay: float
    rms_phi: dict
    rms_p: dict
    f32_vs_f64_phi: float
    f32_vs_f64_p: float
    resets: dict
    health_ok_frac: dict

    def lines(self) -> list[str]:
        out = [f"{self.speed_kmh:.0f} km/h: peak roll {np.degrees(self.peak_phi):.3f} deg, peak roll rate "
               f"{np.degrees(self.peak_p):.3f} deg/s, peak a_y {self.peak_ay:.2f} m/s^2"]
        for prec in ("f32", "f64"):
            out.append(
                f"  {prec}: roll RMS error {np.degrees(self.rms_phi[prec]):.4f} deg = "
                f"{100 * self.rms_phi[prec] / self.peak_phi:.2f} % of peak (target <= 5 %); roll rate RMS "
                f"{np.degrees(self.rms_p[prec]):.4f} deg/s = {100 * self.rms_p[prec] / self.peak_p:.2f} % of peak "
                f"(target <= 10 %); resets {self.resets[prec]}, health OK {100 * self.health_ok_frac[prec]:.1f} %")
        out.append(f"  f32 vs f64: max |d roll| {np.degrees(self.f32_vs_f64_phi):.2e} deg, max |d roll rate| "
                   f"{np.degrees(self.f32_vs_f64_p):.2e} deg/s")
        return out


def evaluate_case(speed_kmh: float, seed: int = 1, prm=None, skip_s: float = 0.0, **case_kw) -> CaseResult:
    truth = run_plant(paper_case(speed_kmh, seed=seed, **case_kw))
    prm = prm if prm is not None else rn.default_params()
    decim = int(round(prm.dt / PLANT_DT))
    u, z, idx = synthesise(truth, decim=decim, seed=seed, prm=prm)
    phi_t, p_t = truth["phi"][idx], truth["p"][idx]
    sel = truth["t"][idx] >= skip_s
    res = {}
    for prec in ("f32", "f64"):
        k = rn.Ukf(prm, prec)
        x, _, h = k.run(u, z)
        res[prec] = (x.astype(float), h, k.c.resets)
    rms_phi = {k: float(np.sqrt(np.mean((v[0][sel, 4] - phi_t[sel]) ** 2))) for k, v in res.items()}
    rms_p = {k: float(np.sqrt(np.mean((v[0][sel, 5] - p_t[sel]) ** 2))) for k, v in res.items()}
    return CaseResult(
        speed_kmh=speed_kmh, peak_phi=float(np.max(np.abs(phi_t))), peak_p=float(np.max(np.abs(p_t))),
        peak_ay=float(np.max(np.abs(truth["ay"]))), rms_phi=rms_phi, rms_p=rms_p,
        f32_vs_f64_phi=float(np.max(np.abs(res["f32"][0][:, 4] - res["f64"][0][:, 4]))),
        f32_vs_f64_p=float(np.max(np.abs(res["f32"][0][:, 5] - res["f64"][0][:, 5]))),
        resets={k: int(v[2]) for k, v in res.items()},
        health_ok_frac={k: float(np.mean(v[1] == rn.lib.VH_ROLL_H_OK)) for k, v in res.items()},
    )


def main(argv: list[str], prog: str) -> int:
    ap = argparse.ArgumentParser(prog=prog, description=__doc__.splitlines()[0])
    ap.add_argument("--seed", type=int, default=1)
    args = ap.parse_args(argv)
    for v in (36.0, 72.0):
        for line in evaluate_case(v, seed=args.seed).lines():
            print(line)
    if hasattr(__import__("vehest_can.native", fromlist=["lib"]).lib, "vh_v14_set_roll_moment"):
        for v in (36.0, 72.0):
            for line in plant_loop_summary(v, seed=args.seed):
                print(line)
    return 0




# ---- closed loop on the estimator's own 9-DOF model ------------------------------------------

@dataclass
class LoopResult:
    t: np.ndarray
    x: np.ndarray          # plant (model) state
    xhat: np.ndarray       # UKF estimate
    m_cmd: np.ndarray      # (n, 2) commanded roll moments front, rear [Nm]
    m_act: np.ndarray      # (n, 2) applied (after the actuator lag)
    smc_health: np.ndarray
    ukf_health: np.ndarray
    ay: np.ndarray


def closed_loop_model(speed_kmh: float = 72.0, active: bool = True, duration_s: float = 4.0,
                      steer_deg: float = 5.0, t_ramp=(0.5, 2.5), smc_over: dict | None = None,
                      prec: str = "f32", seed: int = 1, act_tau: float = 0.03,
                      health_override=None, noise: dict | None = None) -> LoopResult:
    """UKF + SMC (C, precision prec) closing the loop on the 9-DOF model of docs/roll.md (numpy
    reference model as the plant, so no model error: this checks the controller's mechanics, not
    its performance on the 14-DOF truth). Measurements: the model's h with Gaussian noise. The
    actuators lag the command with act_tau; the UKF takes the applied moments as known inputs
    (an actuator status frame would report them). health_override(k, health) may replace the
    estimator health the controller sees (fault injection)."""
    from . import reference as ref

    noise = dict(NOISE, **(noise or {}))
    prm = rn.default_params()
    model = ref.RollModel(rn.params_dict(prm))
    sp = rn.default_smc_params(prm)
    for k, v in (smc_over or {}).items():
        setattr(sp, k, v)
    ukf, smc = rn.Ukf(prm, prec), rn.Smc(sp, prec)
    dt = prm.dt
    n = int(round(duration_s / dt))
    rng = np.random.default_rng(seed)
    sig = np.array([noise["ay"]] + [noise["azu"]] * 4 + [noise["dt"]] * 4 + [noise["ds"]] * 4 + [noise["r"]])
    t = np.arange(n) * dt
    steer = np.radians(np.interp(t, [0.0, t_ramp[0], t_ramp[1]], [0.0, 0.0, steer_deg]))
    vx = speed_kmh / 3.6
    x = np.zeros(rn.NX)
    m_act = np.zeros(2)
    out_x, out_xh = np.zeros((n, rn.NX)), np.zeros((n, rn.NX))
    out_mc, out_ma = np.zeros((n, 2)), np.zeros((n, 2))
    out_sh, out_uh, out_ay = np.zeros(n, np.uint32), np.zeros(n, np.uint32), np.zeros(n)
    for k in range(n):
        u = np.array([steer[k], vx, m_act[0], m_act[1]])
        z = model.h(x, u)[0]
        out_ay[k] = z[0]
        zm = z + sig * rng.standard_normal(rn.NZ)
        um = u.copy()
        um[0] += noise["steer"] * rng.standard_normal()
        um[1] += noise["vx"] * rng.standard_normal()
        uh = ukf.step(um, zm)
        eh = health_override(k, uh) if health_override is not None else uh
        xh = ukf.x
        mf, mr, sh = smc.step(float(xh[4]), float(xh[5]), float(ukf.c.ay_post), int(eh), active)
        out_x[k], out_xh[k], out_mc[k], out_ma[k] = x, xh, (mf, mr), m_act
        out_sh[k], out_uh[k] = sh, uh
        x = model.f(x, u)[0]
        m_act = m_act + dt / act_tau * (np.array([mf, mr]) - m_act)
    return LoopResult(t, out_x, out_xh, out_mc, out_ma, out_sh, out_uh, out_ay)


def chatter_figures(m: np.ndarray, dt: float, f_hz: float = 50.0) -> tuple[float, float]:
    """(total variation [Nm], fraction of the signal's energy (mean removed) above f_hz)."""
    tv = float(np.sum(np.abs(np.diff(m))))
    spec = np.abs(np.fft.rfft(m - np.mean(m))) ** 2
    f = np.fft.rfftfreq(len(m), dt)
    tot = spec.sum()
    return tv, float(spec[f > f_hz].sum() / tot) if tot > 0 else 0.0


# ---- closed loop on the 14-DOF plant ------------------------------------------------------------

@dataclass
class PlantLoopResult:
    truth: np.ndarray      # plant truth, every 0.5 ms tick
    idx: np.ndarray        # plant ticks of the UKF steps
    xhat: np.ndarray       # UKF estimate at those ticks
    m_cmd: np.ndarray      # (n, 2) commanded by the SMC
    m_act: np.ndarray      # (n_plant, 2) applied by the plant's actuators
    smc_health: np.ndarray
    ukf_health: np.ndarray


def closed_loop_plant(speed_kmh: float = 72.0, active: bool = True, prec: str = "f32", seed: int = 1,
                      noise: dict | None = None, smc_over: dict | None = None, **case_kw) -> PlantLoopResult:
    """The paper's case on the 14-DOF plant with its active roll actuators (vh_v14_set_roll_moment),
    the C UKF and SMC of precision prec in the loop, off the bus: the measurements are synthesised
    from the truth (noise as synthesise(); unsprung acceleration as the mean over the plant tick),
    the applied moments (an actuator status would report them) are the UKF's known inputs, and the
    SMC's command reaches the actuators one plant tick (0.5 ms) later."""
    from vehest_can.native import ffi, lib
    from vehest_can.sim.veh14 import veh14_scenario_from_dict

    noise = dict(NOISE, **(noise or {}))
    rng = np.random.default_rng(seed)
    doc = paper_case(speed_kmh, seed=seed, **case_kw)
    sc = veh14_scenario_from_dict(doc, "<scenario>", doc["kind"])
    plant = sc.make_plant(ffi, lib)
    inputs = sc.inputs(ffi)
    n = sc.n_steps
    prm = rn.default_params()
    decim = int(round(prm.dt / PLANT_DT))
    sp = rn.default_smc_params(prm)
    for k, v in (smc_over or {}).items():
        setattr(sp, k, v)
    ukf, smc = rn.Ukf(prm, prec), rn.Smc(sp, prec)
    cx, cy = corner_geometry(prm)
    sig = np.array([noise["ay"]] + [noise["azu"]] * 4 + [noise["dt"]] * 4 + [noise["ds"]] * 4 + [noise["r"]])
    out = ffi.new("vh_v14_truth_t[]", n)
    m_act = np.zeros((n, 2))
    idx, xh, mc, sh, uh = [], [], [], [], []
    vzu_prev = np.array([plant.x[16 + i] for i in range(4)])
    for k in range(n):
        lib.vh_v14_step(plant, inputs + k)
        out[k] = plant.truth
        m_act[k] = (plant.arc.m[0], plant.arc.m[1])
        vzu = np.array([plant.x[16 + i] for i in range(4)])
        azu = (vzu - vzu_prev) / PLANT_DT
        vzu_prev = vzu
        if k % decim != decim - 1:
            continue
        t = plant.truth
        zu = np.array(list(t.zu))
        zs = t.z + cy * t.phi - cx * t.theta
        z = np.concatenate([[t.ay], azu, -zu, zu - zs, [t.r]]) + sig * rng.standard_normal(rn.NZ)
        u = np.array([t.steer + noise["steer"] * rng.standard_normal(),
                      t.vx + noise["vx"] * rng.standard_normal(), m_act[k, 0], m_act[k, 1]])
        h = ukf.step(u, z)
        x = ukf.x
        mf, mr, hs = smc.step(float(x[4]), float(x[5]), float(ukf.c.ay_post), int(h), active)
        lib.vh_v14_set_roll_moment(plant, mf, mr)
        idx.append(k)
        xh.append(x)
        mc.append((mf, mr))
        sh.append(hs)
        uh.append(h)
    from vehest_can.sim.veh14 import truth_to_numpy
    return PlantLoopResult(truth_to_numpy(ffi, out, n), np.array(idx), np.array(xh, float), np.array(mc),
                           m_act, np.array(sh, np.uint32), np.array(uh, np.uint32))


def plant_loop_summary(speed_kmh: float = 72.0, seed: int = 1) -> list[str]:
    pas = closed_loop_plant(speed_kmh, active=False, seed=seed)
    act = closed_loop_plant(speed_kmh, active=True, seed=seed)
    lines = [f"{speed_kmh:.0f} km/h closed loop on the 14-DOF plant (C float32 UKF + SMC):"]
    for name, r in (("passive", pas), ("active", act)):
        tr = r.truth
        e_phi = np.sqrt(np.mean((r.xhat[:, 4] - tr["phi"][r.idx]) ** 2))
        e_p = np.sqrt(np.mean((r.xhat[:, 5] - tr["p"][r.idx]) ** 2))
        tv, hf = chatter_figures(r.m_act.sum(1), PLANT_DT)
        lines.append(
            f"  {name}: peak roll {np.degrees(np.abs(tr['phi']).max()):.3f} deg, peak roll rate "
            f"{np.degrees(np.abs(tr['p']).max()):.3f} deg/s, peak yaw rate {np.degrees(np.abs(tr['r']).max()):.2f} deg/s, "
            f"peak a_y {np.abs(tr['ay']).max():.2f} m/s^2; UKF RMS error roll {np.degrees(e_phi):.4f} deg, rate "
            f"{np.degrees(e_p):.4f} deg/s; moment peak front/rear {np.abs(r.m_act[:, 0]).max():.0f} / "
            f"{np.abs(r.m_act[:, 1]).max():.0f} Nm, total variation {tv:.0f} Nm, energy above 50 Hz {100 * hf:.3f} %")
    red = 1 - np.abs(act.truth["phi"]).max() / np.abs(pas.truth["phi"]).max()
    lines.append(f"  peak roll reduced by {100 * red:.1f} %")
    return lines


# ---- UKF against an EKF on the same model ---------------------------------------------------------

def sine_case(amp_deg: float = 6.0, f_hz: float = 0.7, speed_kmh: float = 72.0, mu: float = 1.0,
              duration_s: float = 6.0, seed: int = 1) -> dict:
    """A harder manoeuvre than the paper's: sinusoidal steer from 0.5 s (amp_deg, f_hz), road mu."""
    doc = paper_case(speed_kmh, duration_s=duration_s, seed=seed)
    t = np.arange(0.0, duration_s, 0.02)
    doc["name"] = f"roll_sine_{amp_deg:g}deg_{f_hz:g}hz"
    doc["driver"] = {"steer_deg": [[float(x), float(amp_deg * np.sin(2 * np.pi * f_hz * (x - 0.5))) if x > 0.5 else 0.0]
                                   for x in t]}
    doc["road"] = {"mu": [[0.0, mu]]}
    return doc


def ukf_vs_ekf(doc: dict, seed: int = 1) -> dict:
    """RMS errors (fraction of the peak) of roll and roll rate: C double UKF vs the numpy EKF
    (same model, Q, R, P0) on one scenario's synthesised measurements."""
    from . import reference as ref

    truth = run_plant(doc)
    prm = rn.default_params()
    u, z, idx = synthesise(truth, decim=int(round(prm.dt / PLANT_DT)), seed=seed, prm=prm)
    phi_t, p_t = truth["phi"][idx], truth["p"][idx]
    xu, _, _ = rn.Ukf(prm, "f64").run(u, z)
    xe = ref.RefEkf(rn.params_dict(prm)).run(u, z)
    out: dict = {"peak_ay": float(np.abs(truth["ay"]).max())}
    for name, x in (("ukf", xu), ("ekf", xe)):
        out[name] = (float(np.sqrt(np.mean((x[:, 4] - phi_t) ** 2)) / np.abs(phi_t).max()),
                     float(np.sqrt(np.mean((x[:, 5] - p_t) ** 2)) / np.abs(p_t).max()))
    return out



# ---- the robust model as UKF and as EKF, on what the ECU took from the bus ---------------------------

#: the 95 % interval of the NIS of the robust variant's 10 measurements (chi-square, 10 degrees of freedom)
NIS_95_10 = (3.247, 20.483)


def filters_on_bus(session, car=None, skip_s: float = 0.2) -> dict:
    """The robust model (docs/roll.md, eq. 4d/10d) run as the numpy reference UKF and as its EKF (double,
    the same Q, R, P0) on the samples the ECU decoded from the bus of one run, against the plant's truth
    after `skip_s`: roll and roll-rate RMS error in % of the run's peak, the mean NIS per measurement
    (1 for a filter whose covariance tells the truth) and the share of steps with the NIS inside its 95 %
    interval (clean runs: all 10 of its measurements every step), the cost of one step of each (numpy, so one
    against the other, not against the C build)."""
    import time

    from . import reference as ref
    from .report import bus_samples

    prm, u, z, steps = bus_samples(session, car)
    prm.variant = rn.VARIANTS["robust"]
    p = rn.params_dict(prm)
    phi, rate = session.truth["phi"][steps], session.truth["p"][steps]
    keep = np.arange(len(steps)) >= int(round(skip_s / prm.dt))
    out: dict = {"steps": int(len(steps))}
    for name, cls in (("ukf", ref.RefUkf), ("ekf", ref.RefEkf)):
        f = cls(p)
        xs, nis = np.zeros((len(u), 2)), np.zeros(len(u))
        t0 = time.perf_counter()
        for k in range(len(u)):
            f.step(u[k], z[k])
            xs[k], nis[k] = f.x[4:6], f.nis
        step_s = (time.perf_counter() - t0) / len(u)
        out[name] = {
            "roll_pct": float(100 * np.sqrt(np.mean((xs[keep, 0] - phi[keep]) ** 2)) / np.abs(phi).max()),
            "rate_pct": float(100 * np.sqrt(np.mean((xs[keep, 1] - rate[keep]) ** 2)) / np.abs(rate).max()),
            "nis_per_measurement": float(nis[keep].mean() / int(f.z_use.sum())),
            "nis_in_95_pct": float(100 * np.mean((nis[keep] > NIS_95_10[0]) & (nis[keep] < NIS_95_10[1]))),
            "step_us": step_s * 1e6}
    return out

