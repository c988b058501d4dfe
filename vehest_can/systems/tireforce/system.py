"""The tireforce system's registration: what the demo and the reports ask of it (:class:`~vehest_can.systems.System`)."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from ...native import ffi
from ...sim.report import decode
from ...sim.veh14 import Veh14Car
from .. import EcuCounters, EcuEstimator, Registration, Setup, Study
from . import api as tf
from . import report
from .adaptive import ADAPTIVE, AdaptiveConfig, AdaptiveFixed
from .campaign import CAMPAIGN
from .scenario import KINDS, load_tireforce_scenario, tireforce_scenario_dir

#: the tyre-force application's own counters (VEHEST_ChassisStatus)
CHASSIS_COUNTERS = (
    "crc_error", "counter_repeat", "counter_skip", "dlc_error", "timeout", "signal_invalid",
    "filter_reset", "rx_burst", "saturation",
)


class TireForce(Registration):
    campaign = CAMPAIGN  # vehest-can campaign
    name = "tireforce"
    kinds = KINDS
    realtime = False
    nodes = ("CHS",)  # the 14-DOF plant and its chassis sensor node
    studies = (
        Study("report", "vehest_can.systems.tireforce.report:main",
              "SKFMEC and SKFMEC-A in process against the plant: tables, metrics.json and plots"),
        Study("ablation", "vehest_can.systems.tireforce.ablation:main",
              "SKFMEC-A against the SKFMEC, with its ablations (docs/results.md)"),
        Study("bound", "vehest_can.systems.tireforce.bound:main",
              "each tyre's 95 % bound: coverage and width per plant and run (docs/tireforce.md)"),
    )
    faults = None
    scenario_dir = staticmethod(tireforce_scenario_dir)
    load = staticmethod(load_tireforce_scenario)
    car = staticmethod(Veh14Car)
    estimators = (EcuEstimator("skfmec_q", "CHS_Sensors", lambda c: c.app.tf.skf.health, lambda c: bool(c.app.tf.heard)),
                  EcuEstimator("skfmec_a", "CHS_Sensors", lambda c: c.app.tf.tfa.health, lambda c: bool(c.app.tf.heard)))
    ecu_counters = (EcuCounters("chassis", CHASSIS_COUNTERS, lambda c: c.app.tf.cnt),)

    def configure_car(self, app, car) -> None:
        """The car into the SKFMEC's and SKFMEC-A's configurations (the same fields the off-line references take)."""
        from .adaptive import car_fields as tfa_fields

        for k, v in tf.car_fields(car).items():
            setattr(app.tf.skf, k, v)
        for k, v in tfa_fields(car).items():
            if isinstance(v, tuple):
                getattr(app.tf.tfa, k)[0:len(v)] = list(v)
            else:
                setattr(app.tf.tfa, k, v)

    def configure_ecu(self, app, part: tf.SkfConfig | None) -> None:
        """Its part (``systems["tireforce"]``): the SKFMEC the ECU runs in fixed point; None: the C core's default."""
        if part is not None:
            part.to_c(ffi.addressof(app.tf, "skf"))

    def metrics(self, scenario, session, out_dir: Path, setup: Setup) -> dict:
        """Against the plant: the ECU's fixed-point estimates from the bus, and the double SKFMEC and
        the paper's plain EKF re-run off-line on the same decoded CHS_Sensors samples."""
        from ...carfile import car_of, paper_car
        from ...sim.car import played_by

        sc = scenario
        car = setup.car or car_of(sc)  # the ECU's calibration: the references use the same car
        dec = report.decode_inputs(session.messages())
        runs = report.run_estimators(dec, car=car)
        ecu_car = car or paper_car()
        played = played_by(ecu_car, sc.plant)
        if played is not ecu_car:  # this plant runs another tyre than the ECU's car file says
            runs[report.PLANT_CAR] = report.run_estimators(dec, (ADAPTIVE,), car=played)[ADAPTIVE]
            print(f"  the ECU is calibrated for {ecu_car.name}; this plant plays {played.name} "
                  f"(another tyre): '{report.PLANT_CAR}' is SKFMEC-A calibrated for that car")
        est = decode(session, "VEHEST_TireForceEst")
        on = est["SkfmecQ_Health"] > 0  # published (NaN elsewhere) and past INIT: SNA before
        bus_fy = np.column_stack([est[f"Fy{i}"] for i in range(1, 5)])[on]
        same = bool(np.array_equal(bus_fy, np.floor(runs[tf.FIXED].fy[on] / 0.5 + 0.5) * 0.5))
        print(f"  ECU's fixed-point Fy on the bus == array API on the decoded samples: "
              f"{'identical' if same else 'DIFFERENT'} ({int(on.sum())} frames)")
        # SKFMEC-A in the ECU (VEHEST_TireForceAdaptive, every 10 ms) against its fixed-point array API
        ada = decode(session, "VEHEST_TireForceAdaptive")
        on_a = ada["SkfmecA_Health"] > 0
        ref_a = (AdaptiveFixed() if car is None else AdaptiveFixed(tf.SkfConfig.for_car(car), AdaptiveConfig.for_car(car))
                 ).run(dec.for_filter(), dec.mask, dec.ride)
        bus_a = np.column_stack([ada[f"FyA{i}"] for i in range(1, 5)] + [ada["EstMass"]])[on_a]
        mass_a = np.asarray(ref_a.mass)
        want_a = np.column_stack([np.floor(ref_a.fy / 0.5 + 0.5) * 0.5, np.floor(mass_a / 0.5 + 0.5) * 0.5])[on_a]
        same_a = bool(np.array_equal(bus_a, want_a))
        print(f"  ECU's SKFMEC-A Fy and mass on the bus == array API on the decoded samples: "
              f"{'identical' if same_a else 'DIFFERENT'} ({int(on_a.sum())} frames)")
        true_mass = report.true_mass(sc)
        metrics = {"scenario": sc.name, "plant": sc.plant, "description": sc.description, "mass_delta_kg": sc.mass_delta_kg,
                   "mode": session.mode, "ecu_equals_array_api": same, "ecu_adaptive_equals_array_api": same_a,
                   **report.evaluate(session.truth, runs, true_mass_kg=true_mass,
                                     model_mass_kg=None if car is None else car.total_mass_kg),
                   "relations": report.relations(session.truth)}
        files = report.plots("relations", session.truth, None, out_dir, title=sc.name)
        files += report.plots("forces", session.truth, runs, out_dir, title=sc.name, true_mass_kg=true_mass)
        metrics["plots"] = [str(p) for p in files]
        return metrics

    def tables(self, metrics: list[dict]) -> list[str]:
        side = [report.plants_table(metrics)] if len({m.get("plant") for m in metrics}) > 1 else []
        return [report.table(m, m["scenario"]) for m in metrics] + side


SYSTEM = TireForce()
