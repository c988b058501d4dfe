"""The driveline system's registration: what the demo and the reports ask of it (:class:`~vehest_can.systems.System`)."""
from __future__ import annotations

from pathlib import Path

from ...sim.scenario import load_scenario, scenario_dir
from ...sim.session import drive_from_scenario
from .. import Registration, Setup
from . import report
from .campaign import CAMPAIGN
from .faults import FAULTS


class Driveline(Registration):
    campaign = CAMPAIGN  # vehest-can campaign
    name = "driveline"
    kinds: tuple[str, ...] = ()   # driveline scenario files carry no `kind`
    realtime = True
    nodes = ("DLS", "SIM", "CIS")  # the car (vh_dlsim_t): sensor node, plant; CIS when it carries inspection devices
    faults = FAULTS
    scenario_dir = staticmethod(scenario_dir)
    load = staticmethod(load_scenario)
    car = staticmethod(drive_from_scenario)

    def claims(self, doc: dict) -> bool:
        return "kind" not in doc and "camber" not in doc

    def metrics(self, scenario, session, out_dir: Path, setup: Setup) -> dict:
        metrics = report.driveline_metrics(session)
        report.plots(session, out_dir)
        return metrics

    def tables(self, metrics: list[dict]) -> list[str]:
        return [report.table(metrics)] if metrics else []


SYSTEM = Driveline()
