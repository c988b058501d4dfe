"""What a campaign asks of the driveline system (:mod:`vehest_can.campaign`): a scenario from a
document, and one in-process run (plant + sensor node + ECU, lockstep) to its figures."""
from __future__ import annotations

from ...sim.scenario import scenario_from_dict
from ...sim.session import drive_from_scenario, run_inprocess
from .. import CampaignRunner
from ..ecu import Ecu
from .report import driveline_metrics


def _run(scenario) -> dict:
    m = driveline_metrics(run_inprocess(drive_from_scenario(scenario), Ecu()))
    return {s["measurement_set"]: {k: v for k, v in s.items() if k != "measurement_set"} for s in m["sets"]}


CAMPAIGN = CampaignRunner(from_dict=scenario_from_dict, run=_run)
