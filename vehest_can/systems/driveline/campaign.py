"""What a campaign asks of the driveline system (:mod:`vehest_can.campaign`): a scenario from a
document, and one in-process run (plant + sensor node + ECU, lockstep) to its figures."""
from __future__ import annotations

from ...sim.powertrain import powertrain_car
from ...sim.session import run_inprocess
from .. import CampaignRunner
from ..ecu import Ecu
from .report import driveline_metrics
from .scenario import driveline_scenario_from_dict


def _run(scenario) -> dict:
    m = driveline_metrics(run_inprocess(powertrain_car(scenario), Ecu()))
    return {s["measurement_set"]: {k: v for k, v in s.items() if k != "measurement_set"} for s in m["sets"]}


CAMPAIGN = CampaignRunner(from_dict=driveline_scenario_from_dict, run=_run)
