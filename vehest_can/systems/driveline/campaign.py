"""What a campaign asks of the driveline system (:mod:`vehest_can.campaign`): a scenario from a
document, and one in-process run (plant + sensor node + ECU, lockstep) to its figures."""
from __future__ import annotations

from pathlib import Path

from ...sim.scenario import scenario_from_dict
from ...sim.session import drive_from_scenario, run_inprocess
from ..ecu import Ecu
from .report import driveline_metrics


class DrivelineCampaign:
    @staticmethod
    def from_dict(doc: dict, path: Path):
        return scenario_from_dict(doc, path)

    @staticmethod
    def run(scenario) -> dict:
        m = driveline_metrics(run_inprocess(drive_from_scenario(scenario), Ecu()))
        return {s["measurement_set"]: {k: v for k, v in s.items() if k != "measurement_set"} for s in m["sets"]}


CAMPAIGN = DrivelineCampaign()
