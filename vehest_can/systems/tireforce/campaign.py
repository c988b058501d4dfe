"""What a campaign asks of the tyre-force system (:mod:`vehest_can.campaign`): a scenario from a
document, and one run to its figures: the 14-DOF plant and chassis sensor node, the decoded
frames through every variant's array API (the fixed-point one is the ECU's C, bit for bit)."""
from __future__ import annotations

from .. import CampaignRunner
from . import report
from .scenario import tireforce_scenario_from_dict


def _run(scenario) -> dict:
    truth, _, runs = report.simulate(scenario)
    m = report.evaluate(truth, runs)
    m.pop("acceptance", None)
    return m


CAMPAIGN = CampaignRunner(from_dict=tireforce_scenario_from_dict, run=_run)
