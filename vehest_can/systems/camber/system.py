"""The camber system's registration: what the demo and the reports ask of it (:class:`~vehest_can.systems.System`)."""
from __future__ import annotations

from dataclasses import replace
from pathlib import Path

from ...bus.log import SessionLog, read_log
from ...sim.powertrain import powertrain_car
from ...sim.session import run_inprocess
from .. import Registration, Setup
from ..ecu import Ecu
from . import inspection
from .api import WHEELS, Calibration, load_calibrations, load_into_ecu, save_calibrations
from .campaign import CAMPAIGN
from .scenario import KINDS, camber_scenario_dir, load_camber_scenario


class Camber(Registration):
    name = "camber"
    kinds = KINDS
    realtime = False
    nodes = ("DLS", "SIM", "CIS")  # the powertrain car carrying the inspection devices
    faults = None
    campaign = CAMPAIGN  # vehest-can campaign
    scenario_dir = staticmethod(camber_scenario_dir)
    load = staticmethod(load_camber_scenario)
    car = staticmethod(powertrain_car)

    def setup(self, scenarios: list, out: Path) -> Setup:
        """The calibration step of an inspection line, on the first camber scenario: each device in its
        x-down and z-down fixture (simulated in-process, logged as candump), then calibrated from those
        logs; the ECU loads the calibrations."""
        if not scenarios:
            return Setup()
        cal_file = _calibrate_devices(scenarios[0], out)
        cals = load_calibrations(cal_file)
        return Setup(["--camber-cal", str(cal_file)], lambda ecu: load_into_ecu(ecu, cals))

    def metrics(self, scenario, session, out_dir: Path, setup: Setup) -> dict:
        """The ECU's published camber beside the truth, and what it would be without calibration."""
        sc = scenario
        truth = {w: (sc.camber.theta_deg[i], sc.camber.psi_deg[i]) for i, w in enumerate(WHEELS)}
        results = inspection.ecu_results(session.messages())
        uncal_ecu = Ecu()
        load_into_ecu(uncal_ecu, {w: Calibration.identity(sc.camber.lsb_mg * 1e-3) for w in WHEELS})
        uncal = inspection.ecu_results(run_inprocess(powertrain_car(sc), uncal_ecu).messages())
        assert results is not None and uncal is not None, "the ECU published no camber"
        print(inspection.results_table(results, truth))
        for w in WHEELS:
            if uncal[w]["reason"] == "OK":
                print(f"  {w} without calibration: {uncal[w]['camber_deg']:.3f}° "
                      f"(error {uncal[w]['camber_deg'] - truth[w][0]:+.3f}°)")
        inspection.bound_plot(out_dir / "bound.png", sc.camber.lsb_mg)
        print(f"  eq. 22 minimum worst-case error at camber 0: {inspection.min_worst_case_deg(sc.camber.lsb_mg):.4f}° "
              f"(paper: 0.2292° at 4 mg)")
        return {"scenario": sc.name, "mode": session.mode, "camber": results, "uncalibrated": uncal,
                "truth_deg": {w: {"camber": t[0], "misalign": t[1]} for w, t in truth.items()}}

    def tables(self, metrics: list[dict]) -> list[str]:
        return []   # printed with each session (results_table)


def _write_log(session, path: Path) -> Path:
    with SessionLog(path, {"VEHEST"}) as writer:  # as every session log: absolute time, Tx/Rx, bus channels
        for m in session.messages():
            writer.on_message_received(m)
    return path


def _calibrate_devices(sc, out: Path) -> Path:
    sdir = out / sc.name
    sdir.mkdir(parents=True, exist_ok=True)
    captures = []
    for pose in ("x_down", "z_down"):
        drive = powertrain_car(replace(sc, camber=replace(sc.camber, pose=pose)), duration_s=6.0)
        log = _write_log(run_inprocess(drive, Ecu()), sdir / f"calibration_{pose}.log")
        captures.append(inspection.capture_messages(read_log(log)))
    cals = inspection.calibrate_wheels(*captures)
    path = out / "camber_cal.json"
    save_calibrations(path, cals)
    print(f"camber: calibrated {', '.join(cals)} from fixture captures -> {path}")
    return path


SYSTEM = Camber()
