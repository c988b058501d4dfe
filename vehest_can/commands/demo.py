"""``vehest-can demo``: the main job. Car and ECU as two processes on a bus, every shipped
driveline scenario, then a table beside the paper's figures, plots, metrics and candump logs."""
from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import can
import numpy as np

from dataclasses import replace

from .. import bus as busmod
from .. import inspection, report, tfreport
from .. import tireforce as tf
from ..chassis import ChassisCar, ChassisScenario, chassis_scenario_dir, load_chassis_scenario
from ..camber import WHEELS, Calibration, load_calibrations, save_calibrations
from ..ecu import Ecu
from ..frames import database
from ..replay import read_log
from ..errors import VehestError
from ..progress import Progress
from ..scenario import load_scenario, read_toml, scenario_dir
from ..sim import SimMaster, drive_from_scenario, run_inprocess


def add_subparser(subparsers) -> None:
    p = subparsers.add_parser("demo", help="the full loop: plant -> bus -> ECU -> estimates, with table and plots",
                              description="Start the ECU daemon as its own process, run the driveline, camber and "
                                          "tyre-force scenarios in lockstep over the bus, and report against the papers.")
    p.add_argument("scenarios", nargs="*", metavar="SCENARIO",
                   help="scenario files, driveline or chassis (default: every scenario shipped in "
                        "firmware_sim/scenarios and firmware_sim/scenarios/chassis)")
    p.add_argument("-o", "--out", default="out/demo", metavar="DIR", help="output folder (default: out/demo)")
    p.add_argument("--realtime", type=float, default=0.0, metavar="S",
                   help="also run S seconds in real time (2 kHz wall clock on both sides)")
    busmod.add_arguments(p)
    p.set_defaults(func=run)


def _daemon_cmd(config: dict, mode: str, extra: list[str]) -> list[str]:
    return [sys.executable, "-m", "vehest_can.cli", "daemon", "--mode", mode, *extra, *busmod.cli_args(config)]


def _stop(proc: subprocess.Popen) -> str:
    if proc.poll() is None:
        proc.send_signal(signal.SIGTERM)
    try:
        _, err = proc.communicate(timeout=10)
    except subprocess.TimeoutExpired:
        proc.kill()
        _, err = proc.communicate()
    return err


def _load(path: Path):
    """A driveline scenario, or a chassis one (``kind = "chassis"``)."""
    if path.suffix == ".toml" and path.is_file() and read_toml(path).get("kind") == "chassis":
        return load_chassis_scenario(path)
    return load_scenario(path)


def _is_chassis(sc) -> bool:
    return isinstance(sc, ChassisScenario)


def run(args) -> int:
    paths = [Path(p) for p in args.scenarios] or (sorted(scenario_dir().glob("*.toml"))
                                                  + sorted(chassis_scenario_dir().glob("*.toml")))
    scenarios = [_load(p) for p in paths]
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    config = busmod.bus_config(args)
    if config == {"interface": busmod.DEFAULT_INTERFACE, "channel": busmod.DEFAULT_CHANNEL, "fd": True}:
        # nothing chosen and both processes are ours: a bus of this run's own keeps other runs out
        config = busmod.private_multicast()
    port = f" port {config['port']}" if "port" in config else ""
    print(f"bus: {config['interface']} {config.get('channel')}{port}; ECU daemon in its own process; output in {out}/")

    camber_args, cals = [], {}
    camber_sc = next((sc for sc in scenarios if not _is_chassis(sc) and sc.camber is not None), None)
    if camber_sc is not None:
        cal_file = _calibrate_devices(camber_sc, out)
        cals = load_calibrations(cal_file)
        camber_args = ["--camber-cal", str(cal_file)]
    ecu_proc = subprocess.Popen(_daemon_cmd(config, "lockstep", ["--idle-timeout", "60", *camber_args]),
                                stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=os.environ.copy())
    all_metrics = []
    try:
        bus = busmod.open_bus(config)
        try:
            for sc in scenarios:
                drive = ChassisCar(sc) if _is_chassis(sc) else drive_from_scenario(sc)
                sdir = out / sc.name
                sdir.mkdir(parents=True, exist_ok=True)
                progress = Progress(f"{sc.name} (lockstep)")
                with can.Logger(str(sdir / "session.log")) as writer:
                    master = SimMaster(bus, drive, log_writer=writer, progress=progress)
                    session = master.run_lockstep(end=False)
                progress.done(f"{session.stats['realtime_factor']:.1f}x real time over the bus")
                local_ecu = Ecu()  # configured like the daemon
                local_ecu.set_camber_calibrations(cals)
                local = run_inprocess(ChassisCar(sc) if _is_chassis(sc) else drive_from_scenario(sc), local_ecu)
                same = (len(local.frames) == len(session.frames)
                        and np.array_equal(local.frames, session.frames))
                print(f"  bus lockstep == in-process lockstep: {'identical' if same else 'DIFFERENT'} "
                      f"({len(session.frames)} frames)")
                if _is_chassis(sc):
                    metrics = _tireforce_report(sc, session, sdir)
                elif sc.camber is not None:
                    metrics = _camber_report(sc, session, sdir)
                else:
                    metrics = report.driveline_metrics(session)
                    report.plots(session, sdir)
                metrics["bus_equals_inprocess"] = bool(same)
                metrics["inprocess_realtime_factor"] = local.stats["realtime_factor"]
                all_metrics.append(metrics)
        finally:
            bus.shutdown()
    finally:
        err = _stop(ecu_proc)
    print("ECU daemon: " + " | ".join(line for line in err.strip().splitlines()[-4:]))

    if args.realtime > 0:
        driveline = [sc for sc in scenarios if not _is_chassis(sc) and sc.camber is None]
        all_metrics.append(_realtime(args, config, (driveline or scenarios)[0], out))

    report.write_metrics(all_metrics, out / "metrics.json")
    print()
    if any("sets" in m for m in all_metrics):
        print(report.table([m for m in all_metrics if "sets" in m]))
    for m in all_metrics:
        if "tires" in m or "acceptance" in m:
            print()
            print(tfreport.table(m, m["scenario"]))
    print(f"\nplots: {', '.join(str(p) for p in sorted(out.glob('*/*.png')))}")
    print(f"metrics: {out / 'metrics.json'}; candump logs: {', '.join(str(p) for p in sorted(out.glob('*/session.log')))}")
    return 0


def _write_log(session, path: Path) -> Path:
    with can.Logger(str(path)) as writer:
        for m in session.messages():
            writer.on_message_received(m)
    return path


def _calibrate_devices(sc, out: Path) -> Path:
    """The calibration step of an inspection line: each device in its x-down and z-down fixture
    (simulated in-process, logged as candump), then `camber calibrate` from those logs."""
    sdir = out / sc.name
    sdir.mkdir(parents=True, exist_ok=True)
    captures = []
    for pose in ("x_down", "z_down"):
        drive = drive_from_scenario(replace(sc, camber=replace(sc.camber, pose=pose)), duration_s=6.0)
        log = _write_log(run_inprocess(drive), sdir / f"calibration_{pose}.log")
        captures.append(inspection.capture_messages(read_log(log)))
    cals = inspection.calibrate_wheels(*captures)
    path = out / "camber_cal.json"
    save_calibrations(path, cals)
    print(f"camber: calibrated {', '.join(cals)} from fixture captures -> {path}")
    return path


def _camber_report(sc, session, sdir: Path) -> dict:
    """The ECU's published camber beside the truth, and what it would be without calibration."""
    truth = {w: (sc.camber.theta_deg[i], sc.camber.psi_deg[i]) for i, w in enumerate(WHEELS)}
    results = inspection.ecu_results(session.messages())
    uncal_ecu = Ecu()
    uncal_ecu.set_camber_calibrations({w: Calibration.identity(sc.camber.lsb_mg * 1e-3) for w in WHEELS})
    uncal = inspection.ecu_results(run_inprocess(drive_from_scenario(sc), uncal_ecu).messages())
    print(inspection.results_table(results, truth))
    for w in WHEELS:
        if uncal[w]["reason"] == "OK":
            print(f"  {w} without calibration: {uncal[w]['camber_deg']:.3f}° "
                  f"(error {uncal[w]['camber_deg'] - truth[w][0]:+.3f}°)")
    inspection.bound_plot(sdir / "bound.png", sc.camber.lsb_mg)
    print(f"  eq. 22 minimum worst-case error at camber 0: {inspection.min_worst_case_deg(sc.camber.lsb_mg):.4f}° "
          f"(paper: 0.2292° at 4 mg)")
    return {"scenario": sc.name, "mode": session.mode, "camber": results, "uncalibrated": uncal,
            "truth_deg": {w: {"camber": t[0], "misalign": t[1]} for w, t in truth.items()}}


def _tireforce_report(sc, session, sdir: Path) -> dict:
    """Seed 000 against the plant: the ECU's fixed-point estimates from the bus, and the double
    SKFMEC and the paper's plain EKF re-run off-line on the same decoded CHS_Sensors samples."""
    chs = database("ch").get_message_by_name("CHS_Sensors")
    dec = tfreport.decode_inputs(m for m in session.messages() if m.arbitration_id == chs.frame_id)
    runs = tfreport.run_estimators(dec)
    est = report.decode(session, "VEHEST_TireForceEst")
    on = est["SkfmecQ_Health"] > 0  # published (NaN elsewhere) and past INIT: SNA before
    bus_fy = np.column_stack([est[f"Fy{i}"] for i in range(1, 5)])[on]
    same = bool(np.array_equal(bus_fy, np.floor(runs[tf.FIXED].fy[on] / 0.5 + 0.5) * 0.5))
    print(f"  ECU's fixed-point Fy on the bus == array API on the decoded samples: "
          f"{'identical' if same else 'DIFFERENT'} ({int(on.sum())} frames)")
    metrics = {"scenario": sc.name, "description": sc.description, "mass_delta_kg": sc.mass_delta_kg,
               "mode": session.mode, "ecu_equals_array_api": same,
               **tfreport.evaluate(session.truth, runs), "relations": tfreport.relations(session.truth)}
    files = tfreport.plots("relations", session.truth, None, sdir, title=sc.name)
    files += tfreport.plots("forces", session.truth, runs, sdir, title=sc.name)
    metrics["plots"] = [str(p) for p in files]
    return metrics


def _realtime(args, config, sc, out: Path) -> dict:
    drive = drive_from_scenario(sc, duration_s=args.realtime)
    stats_file = out / "realtime_daemon.json"
    stats_file.unlink(missing_ok=True)
    # no --duration: the daemon runs until the car is done and SIGTERM stops it (clean shutdown)
    ecu_proc = subprocess.Popen(_daemon_cmd(config, "realtime", ["--stats", str(stats_file)]),
                                stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    time.sleep(1.0)  # let the daemon open its bus
    bus = busmod.open_bus(config)
    try:
        progress = Progress(f"{sc.name} (real time)")
        session = SimMaster(bus, drive, progress=progress).run_realtime()
        progress.done()
    finally:
        bus.shutdown()
        err = _stop(ecu_proc)
    if ecu_proc.returncode not in (0, -signal.SIGTERM):
        raise VehestError(f"real-time ECU daemon failed: {err}")
    if not stats_file.exists():
        raise VehestError(f"real-time ECU daemon wrote no statistics: {err}")
    summary = report.realtime_summary(session, json.loads(stats_file.read_text()))
    print("real time: " + summary["line"])
    return summary
