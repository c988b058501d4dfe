"""Off-line evaluation of the roll UKF against the 14-DOF plant's truth (seed 003's cases).

The paper's cases: front road-wheel steer ramped to 5 deg on a level road at 36 and 72 km/h
(Fig. 2-6). The 14 measurements are synthesised from the plant's truth with Gaussian noise (the
roll sensor node of issue 11 section 1 is not on the bus yet); the UKF runs at its own step
(default 1 ms, every second plant tick) in both precisions, and its roll angle and rate are
compared with the truth.

``python -m vehest_can.systems.roll.evaluate`` prints the figures.
"""
from __future__ import annotations

import argparse
from dataclasses import dataclass

import numpy as np

from . import native as rn

PLANT_DT = 0.0005
# Sensor noise (1 sigma) of the synthesised measurements, in the order of MEAS_NAMES' groups.
NOISE = {"ay": 0.05, "azu": 0.2, "dt": 0.0002, "ds": 0.0005, "r": 0.005, "vx": 0.05, "steer": 0.0001}


def paper_case(speed_kmh: float, steer_deg: float = 5.0, t_ramp=(0.5, 2.5), duration_s: float = 6.0,
               seed: int = 1) -> dict:
    """A chassis scenario document: steer ramp 0 -> steer_deg between t_ramp[0] and t_ramp[1],
    held; level dry road (mu 1); no aerodynamic drag (the paper neglects it)."""
    return {
        "kind": "chassis", "name": f"roll_paper_{int(speed_kmh)}kph",
        "description": f"seed 003 Fig. 2: steer ramp to {steer_deg} deg at {speed_kmh} km/h",
        "duration_s": duration_s, "seed": seed, "initial_speed_kmh": speed_kmh,
        "driver": {"steer_deg": [[0.0, 0.0], [t_ramp[0], 0.0], [t_ramp[1], steer_deg]]},
        "road": {"mu": [[0.0, 1.0]]},
        "vehicle": {"drag_area_m2": 0.0},
    }


def run_plant(doc: dict) -> np.ndarray:
    from vehest_can.chassis import chassis_scenario_from_dict
    from vehest_can.native import ffi, lib

    sc = chassis_scenario_from_dict(doc)
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


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seed", type=int, default=1)
    args = ap.parse_args(argv)
    for v in (36.0, 72.0):
        for line in evaluate_case(v, seed=args.seed).lines():
            print(line)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
