"""The roll loop in real time over a bus: the ECU daemon (its own process, its own 2 kHz clock) and the
roll car (its own 2 kHz clock) on one python-can bus, active mode, the paper's 72 km/h 5 deg ramp held
for the whole run. Reports the actuator commands lost (E2E counter gaps of what the car received, the
actuators' timeouts and refused frames) and the frame-to-actuation latency: from a ROLL_Sensors frame
leaving the car to the car's tick that applies the first VEHEST_RollCmd received after it (the command
acts from the tick after it arrived; resolution one 0.5 ms tick; the ECU steps every 5 ms on its own
clock, so a sample waits up to 5 ms for the next step).

``vehest-can study roll.realtime --seconds 60`` prints the figures.
"""
from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from ...bus import bus as busmod
from ...bus.frames import TICK_S, message
from ...schema import read_toml
from ...sim.session import SimMaster
from .scenario import RollCar, roll_scenario_from_dict, roll_scenario_path


def _gaps(counters: list[int]) -> int:
    return sum((b - a - 1) % 15 for a, b in zip(counters, counters[1:]))


def run(seconds: float = 60.0, config: dict | None = None) -> dict:
    path = roll_scenario_path("roll_paper_72kph_active")
    doc = read_toml(path)
    doc["duration_s"] = float(seconds)
    sc = roll_scenario_from_dict(doc, path)
    config = config or busmod.private_multicast()
    with tempfile.TemporaryDirectory() as tmp:
        stats = Path(tmp) / "daemon.json"
        proc = subprocess.Popen([sys.executable, "-m", "vehest_can.cli", "daemon", *busmod.cli_args(config),
                                 "--mode", "realtime", "--stats", str(stats)],
                                stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        time.sleep(1.0)
        bus = busmod.open_bus(config)
        car = RollCar(sc)
        try:
            session = SimMaster(bus, car).run_realtime()
        finally:
            bus.shutdown()
            proc.terminate()
            _, err = proc.communicate(timeout=20)
        daemon = json.loads(stats.read_text()) if stats.exists() else {"error": err[-400:]}
    cmd, sens = message("VEHEST_RollCmd"), message("ROLL_Sensors")
    fr, ticks = session.frames, session.frame_tick
    is_cmd, is_sens = fr["id"] == cmd.frame_id, fr["id"] == sens.frame_id
    cmd_ticks, sens_ticks = ticks[is_cmd], ticks[is_sens]
    counters = [int(f["data"][1]) & 0x0F for f in fr[is_cmd]]
    # each sensor frame to the first command that reached the car at or after its tick, applied one tick later
    j = np.searchsorted(cmd_ticks, sens_ticks, side="left")
    ok = j < len(cmd_ticks)
    lat_us = (cmd_ticks[j[ok]] + 1 - sens_ticks[ok]) * TICK_S * 1e6
    arc = session.truth["arc_state"]
    from .report import estimates

    est = estimates(session)
    late = est["tick"] >= int(1.0 / TICK_S)   # after the controller's start-up ramp
    tripped = (est["RollSmc_Health"][late].astype(int) & 64) != 0
    onset = np.flatnonzero(np.diff(tripped.astype(int)) == 1) + 1
    # why each trip: the estimate's health, RX fault bits and missing measurements a few frames before it
    causes = [{"ukf_health": [int(v) for v in est["RollUkf_Health"][late][max(i - 8, 0):i + 1]],
               "rx_fault": [int(v) for v in est["RollRxFault"][late][max(i - 8, 0):i + 1]],
               "missing": [int(v) for v in est["RollMeasMissing"][late][max(i - 8, 0):i + 1]]} for i in onset[:5]]
    return {
        "trip_causes": causes, "ukf_resets": int(np.nanmax(est["RollCntReset"])) if est["tick"].size else 0,
        "smc_trips": int(np.sum(np.diff(tripped.astype(int)) == 1)),
        # the car's own stalls do not show in its ticks (its clock skips ahead): the ECU's estimates (every
        # 10 ms) queued up meanwhile arrive in one car tick; their number x 10 ms is the stall
        "longest_car_stall_ms": 10.0 * float(np.bincount(ticks[fr["id"] == message("VEHEST_RollEst").frame_id]).max())
        if np.any(fr["id"] == message("VEHEST_RollEst").frame_id) else float("nan"),
        "longest_command_gap_ms": float(np.diff(cmd_ticks).max() * TICK_S * 1e3) if len(cmd_ticks) > 1 else float("nan"),
        "ukf_not_ok_pct": 100 * float(np.mean(est["RollUkf_Health"][late] != 1)) if late.any() else float("nan"),
        "smc_tripped_pct": 100 * float(np.mean((est["RollSmc_Health"][late].astype(int) & 64) != 0))
        if late.any() else float("nan"),
        "seconds": len(session.truth) * TICK_S, "commands_received": int(is_cmd.sum()),
        "commands_expected": int(round(len(session.truth) * TICK_S / 0.005)),
        "commands_lost_in_counters": _gaps(counters), "actuator_timeouts": int(car.node.cnt_timeout),
        "actuator_refused": int(car.node.cnt_rejected),
        "arc_failsafe_ticks": int(np.sum(arc == 3)), "arc_hold_ticks": int(np.sum(arc == 2)),
        "latency_us": {"p50": float(np.percentile(lat_us, 50)), "p99": float(np.percentile(lat_us, 99)),
                       "max": float(lat_us.max())} if lat_us.size else {},
        "peak_roll_deg": float(np.degrees(np.abs(session.truth["phi"]).max())),
        "car_deadline_misses": int(session.stats.get("deadline_misses", 0)),
        "ecu_deadline_misses": int(daemon.get("deadline_misses", -1)), "ecu_ticks": int(daemon.get("ticks", -1)),
    }


def main(argv: list[str], prog: str) -> int:
    ap = argparse.ArgumentParser(prog=prog, description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=60.0)
    args = ap.parse_args(argv)
    print(json.dumps(run(args.seconds), indent=1))
    return 0

