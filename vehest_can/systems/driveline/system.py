"""The driveline system's registration: what the demo and the reports ask of it (:class:`~vehest_can.systems.System`)."""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from ...native import ffi, lib
from ...sim.powertrain import powertrain_car
from .. import EcuEstimator, Registration, Setup
from . import report
from .api import DkfConfig
from .campaign import CAMPAIGN
from .faults import FAULTS
from .scenario import KINDS, driveline_scenario_dir, load_driveline_scenario


@dataclass
class EcuPart:
    """The driveline's part of an EcuConfig (``systems["driveline"]``): its two filters."""

    dkf_t: DkfConfig
    dkf_s: DkfConfig

    @classmethod
    def default(cls) -> EcuPart:
        return cls(DkfConfig.default("speeds+torque"), DkfConfig.default("speeds"))


def _dls_heard(c) -> bool:
    return bool(c.app.drv.dls.rx.e2e.have_last)


class Driveline(Registration):
    campaign = CAMPAIGN  # vehest-can campaign
    name = "driveline"
    kinds = KINDS
    realtime = True
    nodes = ("DLS", "SIM", "CIS")  # the car (vh_dlsim_t): sensor node, plant; CIS when it carries inspection devices
    faults = FAULTS
    scenario_dir = staticmethod(driveline_scenario_dir)
    load = staticmethod(load_driveline_scenario)
    car = staticmethod(powertrain_car)
    estimators = (EcuEstimator("dkf_t", "DLS_Sensors", lambda c: c.app.drv.dkf[lib.VH_ECU_DKF_T].health, _dls_heard),
                  EcuEstimator("dkf_s", "DLS_Sensors", lambda c: c.app.drv.dkf[lib.VH_ECU_DKF_S].health, _dls_heard))

    def configure_ecu(self, app, part: EcuPart | None) -> None:
        part = part or EcuPart.default()
        part.dkf_t.to_c(ffi.addressof(app.drv.dkf[lib.VH_ECU_DKF_T]))
        part.dkf_s.to_c(ffi.addressof(app.drv.dkf[lib.VH_ECU_DKF_S]))

    def metrics(self, scenario, session, out_dir: Path, setup: Setup) -> dict:
        metrics = report.driveline_metrics(session)
        report.plots(session, out_dir)
        return metrics

    def tables(self, metrics: list[dict]) -> list[str]:
        return [report.table(metrics)] if metrics else []


SYSTEM = Driveline()
