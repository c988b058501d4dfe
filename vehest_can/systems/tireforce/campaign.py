"""What a campaign asks of the tyre-force system (:mod:`vehest_can.campaign`): a scenario from a
document, and one run to its figures: the 14-DOF plant and chassis sensor node, the decoded
frames through every variant's array API (the fixed-point one is the ECU's C, bit for bit)."""
from __future__ import annotations

from pathlib import Path

from . import report
from .scenario import tireforce_scenario_from_dict


class TireForceCampaign:
    @staticmethod
    def from_dict(doc: dict, path: Path):
        return tireforce_scenario_from_dict(doc, path)

    @staticmethod
    def run(scenario) -> dict:
        truth, _, runs = report.simulate(scenario)
        m = report.evaluate(truth, runs)
        m.pop("acceptance", None)
        return m


CAMPAIGN = TireForceCampaign()
