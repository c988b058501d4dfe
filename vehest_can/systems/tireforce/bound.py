"""Coverage and width of SKFMEC-A's per-tyre bound (docs/tireforce.md, "Per-tyre bound") over its design
runs and held-out runs on both plants.

    vehest-can study tireforce.bound [--fixed] [--plant P] [--only NAME ...] [--markdown]

The bound's model constants (``AdaptiveConfig.bound_*``) were chosen on the ``design`` runs only; the
``held-out`` runs (other scenarios, payloads, friction, speeds) judge it. Coverage is the share of
published steps (past INIT, t >= settle) with |F_y - F̂_i| <= b_i per tyre, the width the mean b_i in % of
that tyre's peak |F_y|; ``ok`` the coverage over the steps SKFMEC-A calls OK.
"""
from __future__ import annotations

import argparse
from dataclasses import dataclass

import numpy as np

from ...errors import ConfigError
from . import adaptive as A
from . import api as tf
from . import report as tr

PLANTS = ("veh14", "commonroad_mb")


@dataclass(frozen=True)
class BoundRun:
    """A scenario of firmware_sim/scenarios/tireforce/ (``stress/...`` for the stress set) with overrides."""

    label: str
    role: str                       # "design" or "held-out"
    scenario: str
    mass_delta_kg: float | None = None
    mu: float | None = None         # one friction for the whole run (None: the scenario's)
    speed_kmh: float | None = None
    plants: tuple = PLANTS          # split friction: the MB plant has one friction for all wheels


RUNS = (
    BoundRun("relation ramp", "design", "chassis_relation_70kph"),
    BoundRun("paper mu drop", "design", "chassis_paper_mu_drop"),
    BoundRun("lane change", "held-out", "stress/stress_lane_change_payload", 300.0, 0.8),
    BoundRun("highway sine", "held-out", "stress/stress_highway_sine_payload", -100.0, 1.0, 90.0),
    BoundRun("step steer 4 deg", "held-out", "stress/stress_step_steer_4deg_p400", 400.0, 1.0),
    BoundRun("power-on cornering", "held-out", "stress/stress_power_on_cornering", 0.0, 0.9),
    BoundRun("low-mu corner", "held-out", "stress/stress_low_mu_corner_p200", 200.0, 0.5),
    BoundRun("braking ramp", "held-out", "stress/stress_payload_p200kg", 100.0, 1.1, 60.0),
    BoundRun("relation ramp", "held-out", "chassis_relation_70kph", 250.0, 0.7, 85.0),
    BoundRun("split-mu braking", "held-out", "stress/stress_split_mu_braking", 100.0, None, 70.0, ("veh14",)),
)


def scenario(run: BoundRun, plant: str, duration_s: float | None = None):
    """The run's scenario on a plant, with the car file that plant builds (``paper_mb`` on CommonRoad's)."""
    from ...schema import read_toml
    from .scenario import tireforce_scenario_dir, tireforce_scenario_from_dict

    path = tireforce_scenario_dir() / f"{run.scenario}.toml"
    doc = read_toml(path)
    doc["plant"] = plant
    if plant == "commonroad_mb":
        doc["car"] = "paper_mb"
    if run.mass_delta_kg is not None:
        doc.setdefault("vehicle", {})["mass_delta_kg"] = run.mass_delta_kg
    if run.mu is not None:
        doc["road"]["mu"] = [[0.0, run.mu]]
    if run.speed_kmh is not None:
        doc["initial_speed_kmh"] = run.speed_kmh
    if duration_s is not None:
        doc["duration_s"] = duration_s
    doc["name"] = f"bound_{run.role}_{path.stem}_{plant}"
    return tireforce_scenario_from_dict(doc, path)


def simulate(sc) -> tuple:
    """(truth, double run, fixed-point run) of SKFMEC-A calibrated for the scenario's car."""
    from ...carfile import car_of
    from ...native import ffi, lib

    car = car_of(sc)
    truth, frames = sc.run_with_frames(ffi, lib)
    dec = tr.decode_inputs(frames)
    args = (tf.SkfConfig.for_car(car), A.AdaptiveConfig.for_car(car)) if car is not None else ()
    u = dec.for_filter()
    return truth, A.AdaptiveSkfmec(*args).run(u, dec.mask, dec.ride), A.AdaptiveFixed(*args).run(u, dec.mask, dec.ride)


def coverage(truth, run: A.AdaptiveRun, settle_s: float = tr.SETTLE_S) -> dict:
    """Per tyre FL FR RL RR: coverage [%] over published steps and over OK steps, mean width and RMS error
    [% of peak |F_y|]."""
    t, fy = np.asarray(truth["t"]), np.asarray(truth["fy"], dtype=np.float64)
    peak = np.abs(fy).max(0)
    s = (t - t[0] >= settle_s - 1e-9) & (run.health != A.H_INIT)
    ok = s & (run.health == A.H_OK)
    err = np.abs(run.fy - fy)
    if run.bound is None:
        raise ConfigError("the run has no bound (an SKFMEC-A run has)")
    inside = err <= run.bound
    return {"coverage": 100.0 * inside[s].mean(0), "coverage_ok": 100.0 * inside[ok].mean(0) if ok.any() else None,
            "width": 100.0 * run.bound[s].mean(0) / peak, "rms": 100.0 * np.sqrt((err[s] ** 2).mean(0)) / peak,
            "ok_share": 100.0 * ok.sum() / max(s.sum(), 1)}


def _f(v) -> str:
    return "-" if v is None else " ".join(f"{x:.1f}" for x in v)


def main(argv: list[str], prog: str) -> int:
    ap = argparse.ArgumentParser(prog=prog, description=__doc__.split("\n")[0])
    ap.add_argument("--fixed", action="store_true", help="the fixed-point run's bound (default: double)")
    ap.add_argument("--plant", choices=PLANTS, action="append", help="only this plant (repeatable)")
    ap.add_argument("--only", action="append", help="only runs whose scenario contains this (repeatable)")
    args = ap.parse_args(argv)
    print("| role | run | plant | payload kg, mu, km/h | coverage % | coverage on OK % | OK % | mean width % | "
          "RMS error % | fixed-double max % | sat |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    for run in RUNS:
        if args.only and not any(o in run.scenario for o in args.only):
            continue
        for plant in run.plants:
            if args.plant and plant not in args.plant:
                continue
            sc = scenario(run, plant)
            truth, dbl, fix = simulate(sc)
            c = coverage(truth, fix if args.fixed else dbl)
            peak = np.abs(np.asarray(truth["fy"])).max(0)
            dev = 100.0 * np.abs(fix.bound - dbl.bound).max() / peak.min()
            mu = "split" if run.mu is None and "split" in run.scenario else (run.mu if run.mu is not None else "scenario")
            print(f"| {run.role} | {run.label} | {plant} | {sc.mass_delta_kg:+g}, {mu}, {sc.initial_speed_kmh:g} | "
                  f"{_f(c['coverage'])} | {_f(c['coverage_ok'])} | {c['ok_share']:.0f} | {_f(c['width'])} | "
                  f"{_f(c['rms'])} | {dev:.3f} | {fix.saturations} |", flush=True)
    return 0

