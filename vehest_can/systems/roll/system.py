"""The roll system's registration (seed 003): what the demo and the reports ask of it
(:class:`~vehest_can.systems.System`)."""
from __future__ import annotations

from pathlib import Path

from .. import EcuEstimator, Registration, Setup, Study
from . import report
from .campaign import CAMPAIGN
from .faults import FAULTS
from .scenario import KINDS, RollCar, load_roll_scenario, roll_scenario_dir


class Roll(Registration):
    name = "roll"
    kinds = KINDS
    nodes = ("CHS", "ROLL")  # the 14-DOF plant with its chassis node and its roll node (sensors, actuators)
    realtime = True
    studies = (
        Study("filters", "vehest_can.systems.roll.evaluate:main",
              "the UKF off line against the plant's truth at 36 and 72 km/h, both precisions"),
        Study("control", "vehest_can.systems.roll.control_table:main",
              "active control on both plants, robust and paper SMC law against passive (docs/roll.md)"),
        Study("realtime", "vehest_can.systems.roll.realtime:main",
              "the roll loop in real time over a bus: commands lost and frame-to-actuation latency"),
    )
    faults = FAULTS
    campaign = CAMPAIGN  # vehest-can campaign
    scenario_dir = staticmethod(roll_scenario_dir)
    load = staticmethod(load_roll_scenario)
    car = staticmethod(RollCar)
    # the UKF's health is on the same scale (VH_ROLL_H_RESET is FAULT)
    estimators = (EcuEstimator("roll_ukf", "ROLL_Sensors", lambda c: c.app.roll.ukf.health, lambda c: bool(c.app.roll.heard)),)

    def configure_car(self, app, car) -> None:
        """The car into the UKF's vehicle and the controller's model terms."""
        from .api import write_car

        write_car(app.roll, car)

    def configure_ecu(self, app, part: dict | None) -> None:
        """``{"variant": "paper" | "robust", "smc": {field: value}, "ukf": {...}}``: which UKF the ECU runs (default: the
        robust one; docs/roll.md) and the controller's tuning. The controller takes the disturbance
        estimate with the robust variant only."""
        from .api import configure_variant

        if part:
            configure_variant(app.roll, part.get("variant", "robust"))
            for key, value in part.get("smc", {}).items():  # the controller's tuning, by vh_roll_smc_params_t field
                setattr(app.roll.smc, key, int(value) if key == "law" else float(value))
            for key, value in part.get("ukf", {}).items():  # the filter's, by vh_roll_params_t field
                if isinstance(value, (list, tuple)):
                    for i, v in enumerate(value):
                        getattr(app.roll.ukf, key)[i] = float(v)
                else:
                    setattr(app.roll.ukf, key, float(value))

    def metrics(self, scenario, session, out_dir: Path, setup: Setup) -> dict:
        """Against the plant, from the bus: the ECU's float32 UKF estimates (VEHEST_RollEst), the
        actuators' moments; an active run also against its passive twin (in-process)."""
        from ...carfile import car_of
        from ...sim.session import run_inprocess
        from ..ecu import Ecu, EcuConfig

        sc = scenario
        car = setup.car or car_of(sc)  # the ECU's calibration: the re-run and the twin use the same car
        arc = sc.arc_params(*_native())
        limits = tuple((float(arc[i].m_max), float(arc[i].rate_max)) for i in range(2))
        m = {"scenario": sc.name, "plant": sc.plant, "description": sc.description, "mode": session.mode,
             "control": "active" if sc.active else "passive", "speed_kmh": sc.chassis.initial_speed_kmh,
             **report.evaluate(session, limits), **report.rerun(session, car)}
        print(f"  ECU's float32 UKF on the bus == array API on the decoded samples: "
              f"{'identical' if m['ecu_equals_array_api'] else 'DIFFERENT'} ({m['steps']} steps)")
        passive = None
        if sc.active:
            twin = sc.with_mode("passive")
            passive = run_inprocess(RollCar(twin, len(session.truth) * 0.0005), Ecu(EcuConfig(car=car)))
            m["vs_passive"] = report.vs_passive(m, passive)
        m["acceptance"] = report.acceptance_entries(m)
        m["plots"] = [str(p) for p in report.plots(session, out_dir, sc.name, passive, plant=sc.plant)]
        return m

    def tables(self, metrics: list[dict]) -> list[str]:
        side = [report.plants_table(metrics)] if len({m.get("plant") for m in metrics}) > 1 else []
        return [report.table(m) for m in metrics] + side


def _native():
    from ...native import ffi, lib

    return ffi, lib


SYSTEM = Roll()
