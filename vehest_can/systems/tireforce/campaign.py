"""What a campaign asks of the tyre-force system (:mod:`vehest_can.campaign`): a scenario from a
document, and one run to its figures: the 14-DOF plant and chassis sensor node, the decoded
frames through every variant's array API (the fixed-point one is the ECU's C, bit for bit)."""
from __future__ import annotations

import dataclasses

import numpy as np

from .. import CampaignRunner
from . import report
from .scenario import tireforce_scenario_from_dict


def _run(scenario) -> dict:
    from ...carfile import car_of, paper_car
    from ...sim.car import played_by
    from ...sim.session import left_range

    car = played_by(car_of(scenario) or paper_car(), scenario.plant)  # the ECU of this run's plant
    truth, _, runs = report.simulate(scenario, car=car)
    # a car that left its plant's range (spun: the multi-body plant's state leaves the finite numbers) is
    # judged up to then, as the demo judges a session (Session.diverged_s)
    k = left_range(truth)
    if k is not None:
        truth = truth[:k]
        runs = {n: dataclasses.replace(r, **{f.name: getattr(r, f.name)[:k] for f in dataclasses.fields(r)
                                             if isinstance(getattr(r, f.name), np.ndarray)}) for n, r in runs.items()}
    m = report.evaluate(truth, runs, true_mass_kg=report.true_mass(scenario), model_mass_kg=car.total_mass_kg)
    m.pop("acceptance", None)
    m["judged_s"] = float(truth["t"][-1] - truth["t"][0])  # the whole run unless the car left its range
    return m


CAMPAIGN = CampaignRunner(from_dict=tireforce_scenario_from_dict, run=_run)
