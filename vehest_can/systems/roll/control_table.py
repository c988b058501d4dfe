"""The active-control table of docs/roll.md ("Active control, measured"): design and held-out runs on
both plants, the ECU (robust UKF) with the robust SMC law and with the paper's law, each against its
passive twin (in-process, lockstep). ``vehest-can study roll.control [design|held]``
prints one Markdown row per run and plant."""
from __future__ import annotations

import argparse
import math

import numpy as np

from ...carfile import car_of
from ...sim import PLANTS
from ...sim.scenario import DT
from ...sim.session import run_inprocess
from ..ecu import Ecu, EcuConfig
from . import report
from .scenario import RollCar, load_roll_scenario, roll_scenario_from_dict

#: the paper's law with its own constants (the baseline; vh_roll_smc_params_default for the paper's UKF)
PAPER_LAW = {"smc": {"law": 0, "lambda": 10.0, "k": 5.0, "p": 0.1, "ay_tau": 0.02, "ref_tau": 0.05,
                     "dist_gain": 1.0}}


def _sine(t0: float, t1: float, f: float, a: float, dt: float = 0.05) -> list:
    ts = np.arange(t0, t1 + 1e-9, dt)
    return [[0.0, 0.0]] + [[float(t), float(a * np.sin(2 * np.pi * f * (t - t0)))] for t in ts] + [[t1 + 0.5, 0.0]]


def _doc(name, kmh, steer, dm=0.0, mu=1.0, brake=None, seed=7) -> dict:
    d = {"kind": "roll", "name": name, "duration_s": 6.0, "seed": seed, "initial_speed_kmh": kmh,
         "driver": {"steer_deg": steer}, "road": {"mu": [[0.0, mu]]},
         "vehicle": {"drag_area_m2": 0.0, "mass_delta_kg": dm}, "control": {"mode": [[0.0, "active"]]}}
    if brake:
        d["driver"]["brake_nm"] = brake
    return d


#: the runs the robust law's constants were chosen on (besides roll_paper_{72,36}kph_active)
DESIGN = [
    _doc("lane change 80 km/h mu 1.0", 80, [[0, 0], [1.0, 0], [1.35, 2.5], [2.05, -2.5], [2.4, 0]], seed=3),
    _doc("sine 0.5 Hz 60 km/h", 60, _sine(0.5, 4.5, 0.5, 3.0), seed=3),
    _doc("fishhook at the limit 80 km/h +70 kg mu 0.58", 80.26, [[0, 0], [0.5, 0], [0.8, 3], [1.5, 3], [1.9, -4]],
         70, 0.5772),
]
#: runs no constant was chosen on
HELD_OUT = [
    _doc("H1 lane change 100 km/h +250 kg mu 0.9", 100, [[0, 0], [1.0, 0], [1.4, 2.0], [2.2, -2.0], [2.6, 0]], 250, 0.9),
    _doc("H2 fishhook 60 km/h -100 kg mu 0.9", 60, [[0, 0], [0.5, 0], [0.8, 3.5], [1.5, 3.5], [1.9, -4.5]], -100, 0.9),
    _doc("H3 step to steady turn 80 km/h +300 kg mu 1.1", 80, [[0, 0], [0.5, 0], [0.8, 2.5]], 300, 1.1),
    _doc("H4 sine 0.7 Hz 72 km/h +100 kg mu 0.7", 72, _sine(0.5, 4.5, 0.7, 2.5), 100, 0.7),
    _doc("H5 ramp 0-6 deg 50 km/h mu 0.6", 50, [[0, 0], [0.5, 0], [2.5, 6.0]], 0, 0.6),
    _doc("H6 braking in a turn 60 km/h +150 kg", 60, [[0, 0], [0.5, 0], [0.8, 3.5]], 150, 1.0,
         brake=[[0, 0, 0, 0, 0], [2.5, 0, 0, 0, 0], [2.8, 900, 900, 450, 450]]),
    _doc("H7 step 120 km/h +200 kg mu 0.5", 120, [[0, 0], [0.5, 0], [0.8, 1.0]], 200, 0.5),
    _doc("H8 fishhook 36 km/h +300 kg mu 1.1", 36, [[0, 0], [0.5, 0], [0.8, 6.0], [1.5, 6.0], [1.9, -7.0]], 300, 1.1),
]


def _run(sc, extra=None):
    cfg = EcuConfig(car=car_of(sc), systems={"roll": {"variant": "robust", **(extra or {})}})
    return run_inprocess(RollCar(sc), Ecu(cfg))


def energy_above(m: np.ndarray, f_hz: float = 3.0) -> float:
    """Share [%] of the signal's energy (mean removed) above f_hz."""
    spec = np.abs(np.fft.rfft(m - m.mean())) ** 2
    f = np.fft.rfftfreq(len(m), DT)
    tot = spec.sum()
    return 100 * float(spec[f > f_hz].sum() / tot) if tot > 0 else 0.0


def figures(active, passive, limits) -> dict:
    """One active session against its passive twin."""
    m, mp = report.evaluate(active, limits), report.evaluate(passive, limits)
    tr = active.truth
    work = float(np.sum(np.abs(tr["m_applied"][:, 0] * tr["p"]) + np.abs(tr["m_applied"][:, 1] * tr["p"])) * DT)
    return {"reduction_pct": 100 * (1 - m["peak_roll_deg"] / mp["peak_roll_deg"]), "passive_peak_deg": mp["peak_roll_deg"],
            "roll_rms_deg": m["ukf_roll_rms_deg"], "rate_rms_deg_s": m["ukf_roll_rate_rms_deg_s"],
            "bias_deg_s": m["steady_turn_rate_bias_deg_s"], "resets": m["ukf_resets"],
            "limits_respected": m["limits_respected"], "above_3hz_pct": energy_above(tr["m_applied"].sum(axis=1)),
            "work_j": work}


def measure(name: str, sc) -> dict:
    """Both laws on one scenario: {"robust": figures, "paper": figures}."""
    from ...native import ffi, lib

    arc = sc.arc_params(ffi, lib)
    limits = tuple((float(arc[i].m_max), float(arc[i].rate_max)) for i in range(2))
    passive = _run(sc.with_mode("passive"))
    return {law: figures(_run(sc, extra), passive, limits) for law, extra in (("robust", None), ("paper", PAPER_LAW))}


def cases(which: str) -> list:
    if which == "design":
        return ([(n + " (design)", load_roll_scenario(n)) for n in ("roll_paper_72kph_active", "roll_paper_36kph_active")]
                + [(d["name"] + " (design)", roll_scenario_from_dict(d)) for d in DESIGN])
    return [(d["name"], roll_scenario_from_dict(d)) for d in HELD_OUT]


def row(name: str, plant: str, f: dict) -> str:
    r, p = f["robust"], f["paper"]
    bias = "–" if math.isnan(r["bias_deg_s"]) else f"{r['bias_deg_s']:.3f}"
    return (f"| {name} | {'MB' if plant == 'commonroad_mb' else plant} | {r['passive_peak_deg']:.2f}° | "
            f"**{r['reduction_pct']:.1f}** / {p['reduction_pct']:.1f} % | "
            f"{r['roll_rms_deg']:.3f}° / {r['rate_rms_deg_s']:.2f} °/s | "
            f"{r['above_3hz_pct']:.1f} %, {r['work_j']:.0f} J | {p['above_3hz_pct']:.1f} %, {p['work_j']:.0f} J | "
            f"{r['resets']} / {p['resets']} | {bias} |")


def main(argv: list[str], prog: str) -> int:
    ap = argparse.ArgumentParser(prog=prog, description=__doc__.split("\n\n")[0])
    ap.add_argument("runs", nargs="?", choices=("design", "held"), default="held",
                    help="the design runs or the held-out ones (default: held)")
    args = ap.parse_args(argv)
    for name, sc in cases(args.runs):
        for plant in PLANTS:
            print(row(name, plant, measure(name, sc.with_plant(plant))), flush=True)
    return 0

