"""What a campaign asks of the camber system (:mod:`vehest_can.campaign`): a scenario from a
document, and one in-process inspection to its figures: each device calibrated from its two fixture
captures (x-down and z-down, simulated like the demo's, kept in memory), then the standing car
inspected with those calibrations loaded, the ECU's published camber against the truth."""
from __future__ import annotations

from dataclasses import replace

from ...sim.powertrain import powertrain_car
from ...sim.session import run_inprocess
from .. import CampaignRunner
from ..ecu import Ecu
from . import inspection
from .api import WHEELS, load_into_ecu
from .scenario import camber_scenario_from_dict

FIXTURE_S = 6.0  # each calibration capture, as the demo's


def _run(scenario) -> dict:
    captures = []
    for pose in ("x_down", "z_down"):
        drive = powertrain_car(replace(scenario, camber=replace(scenario.camber, pose=pose)), FIXTURE_S)
        captures.append(inspection.capture_messages(run_inprocess(drive, Ecu()).messages()))
    ecu = Ecu()
    load_into_ecu(ecu, inspection.calibrate_wheels(*captures))
    results = inspection.ecu_results(run_inprocess(powertrain_car(scenario), ecu).messages()) or {}
    nan = float("nan")
    out: dict = {}
    errors = []
    for i, w in enumerate(WHEELS):
        r = results.get(w, {"reason": "NO_RESULT_YET", "camber_deg": nan, "bound_deg": nan})
        ok = r["reason"] == "OK"
        err = r["camber_deg"] - scenario.camber.theta_deg[i] if ok else nan
        out[w] = {"camber_error_deg": err, "abs_camber_error_deg": abs(err), "ok": float(ok),
                  "bound_deg": r["bound_deg"] if ok else nan}
        errors.append(abs(err))
    # a wheel without a result makes the worst case unknown (NaN fails every acceptance line)
    out["worst_abs_camber_error_deg"] = max(errors) if all(e == e for e in errors) else float("nan")
    return out


CAMPAIGN = CampaignRunner(from_dict=camber_scenario_from_dict, run=_run)
