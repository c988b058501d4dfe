"""What a campaign asks of the roll system (:mod:`vehest_can.campaign`): a scenario from a document,
and one in-process closed-loop run (14-DOF plant with its actuators, chassis and roll nodes, the ECU:
float32 UKF + SMC, lockstep) to its figures: the UKF's roll angle and rate against the plant's truth
(RMS, absolute and as % of the peak, over the estimates it published as valid), peaks, moments,
health; the same run once more with the paper's UKF as the ECU's estimator (the baseline variant,
its figures under ``paper.*``); for an active run its passive twin (the same run in passive mode): the
peak roll's reduction and the control line ``lines.control`` (>= 50 %). No plots (a campaign runs
hundreds)."""
from __future__ import annotations

import numpy as np

from ...carfile import car_of
from ...sim.session import run_inprocess
from .. import CampaignRunner
from ..ecu import Ecu, EcuConfig
from . import report
from .scenario import RollCar, roll_scenario_from_dict

_KEEP = ("peak_roll_deg", "peak_roll_rate_deg_s", "peak_yaw_rate_deg_s", "peak_ay_m_s2", "ukf_roll_rms_deg",
         "ukf_roll_rate_rms_deg_s", "ukf_roll_rms_pct_of_peak", "ukf_roll_rate_rms_pct_of_peak", "estimates",
         "ukf_health_ok_pct", "ukf_resets", "moment_total_variation_nm", "moment_energy_above_50hz_pct",
         "steady_turn_rate_bias_deg_s")
_BASELINE = ("ukf_roll_rms_pct_of_peak", "ukf_roll_rate_rms_pct_of_peak", "ukf_roll_rate_rms_deg_s", "ukf_roll_rms_deg",
             "steady_turn_rate_bias_deg_s", "peak_roll_deg", "ukf_resets")


def _session(scenario, variant: str):
    cfg = EcuConfig(car=car_of(scenario), systems={"roll": {"variant": variant}})  # calibrated for its car
    return run_inprocess(RollCar(scenario), Ecu(cfg))


def _run(scenario) -> dict:
    s = _session(scenario, "robust")
    arc = scenario.arc_params(*_native())
    limits = tuple((float(arc[i].m_max), float(arc[i].rate_max)) for i in range(2))
    m = report.evaluate(s, limits)
    out: dict = {k: float(m[k]) for k in _KEEP}
    base = report.evaluate(_session(scenario, "paper"), limits)
    out["paper"] = {k: float(base[k]) for k in _BASELINE}
    out["lines"] = report.lines_met(m)
    out["paper"]["lines"] = report.lines_met(base)
    if scenario.active:
        # no twin to compare with (it left its plant's range): NaN, the line not met
        twin = report.vs_passive(m, _session(scenario.with_mode("passive"), "robust"))
        red = twin.get("peak_roll_reduction_pct", float("nan"))
        out["peak_roll_reduction_pct"] = red
        out["lines"]["control"] = float(red >= 100 * report.TARGET_REDUCTION)
    out["moment_peak_nm"] = {"front": m["moment_peak_nm"][0], "rear": m["moment_peak_nm"][1]}
    out["limits_respected"] = float(m["limits_respected"])
    e = report.estimates(s)
    out["smc_tripped_pct"] = 100 * float(np.mean((e["RollSmc_Health"].astype(int) & 64) != 0)) if e["tick"].size else 100.0
    return out


def _native():
    from ...native import ffi, lib

    return ffi, lib


CAMPAIGN = CampaignRunner(from_dict=roll_scenario_from_dict, run=_run)
