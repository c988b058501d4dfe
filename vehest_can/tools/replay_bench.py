"""The replay benchmark of ``vehest-can bench``: a generated lockstep candump -L log of N frames
(driveline sessions back to back, each from a SIM_Sync RESET), replayed end to end (read + ECU +
compare with the ECU frames in the log) beside python-can's ``LogReader`` alone and cantools'
decode alone on the same log. Each measurement runs in a process of its own, so its peak resident
memory is its own; the two baselines read a prefix of the log (they are ~100x slower) and are
given as rates. Replay and LogReader runs alternate (median of each), so a shared machine's load
weighs on both alike; CPU time is given beside wall time."""
from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from ..bus import lockstep
from ..bus.frames import TICK_S
from ..bus.log import bus_of_id
from ..errors import VehestError
from ..service.replay import ECU_TX
from ..sim.powertrain import powertrain_car
from ..sim.session import run_inprocess
from ..systems.driveline.scenario import load_driveline_scenario
from ..systems.ecu import Ecu

EPOCH = 1764620000.0


def _segment_lines(seconds: float) -> tuple[list[str], np.ndarray, int]:
    """One lockstep session as candump -L line bodies (all after the timestamp) and their ticks."""
    s = run_inprocess(powertrain_car(load_driveline_scenario("tip_in_tip_out"), duration_s=seconds), Ecu())
    bus = bus_of_id()
    ecu = np.isin(s.frames["id"], np.array(sorted(ECU_TX)))
    n_ticks = len(s.truth)
    # per tick: the car's frames, SIM_Sync, the ECU's (RESET first)
    keys = np.concatenate((s.frame_tick.astype(np.int64) * 3 + np.where(ecu, 2, 0),
                           np.arange(n_ticks, dtype=np.int64) * 3 + 1, [-1]))
    bodies = []
    for f, e in zip(s.frames, ecu):
        fd = int(f["flags"]) & 2
        sep = f"##{1 if int(f['flags']) & 4 else 0}" if fd else "#"
        bodies.append(f"{bus.get(int(f['id']), 'pt')} {int(f['id']):03X}{sep}{bytes(f['data'][:f['len']]).hex().upper()}"
                      f" {'T' if e else 'R'}")
    for k in range(n_ticks):
        bodies.append(f"pt {lockstep.SYNC.frame_id:03X}#{bytes(lockstep.sync_message(k).data).hex().upper()} R")
    bodies.append(f"pt {lockstep.SYNC.frame_id:03X}#"
                  f"{bytes(lockstep.sync_message(lockstep.RESET_TICK_BASE, lockstep.RESET).data).hex().upper()} R")
    ticks = np.concatenate((s.frame_tick, np.arange(n_ticks), [0]))
    order = np.argsort(keys, kind="stable")
    return [bodies[i] for i in order], ticks[order], n_ticks


def generate(path: Path, n_frames: int, segment_s: float = 30.0) -> int:
    """Write a lockstep candump -L log of at least n_frames frames; returns how many."""
    bodies, ticks, n_ticks = _segment_lines(segment_s)
    written = 0
    t = EPOCH
    with open(path, "w") as f:
        while written < n_frames:
            stamps = t + ticks * TICK_S
            f.write("".join(f"({ts:.6f}) {b}\n" for ts, b in zip(stamps, bodies)))
            written += len(bodies)
            t += n_ticks * TICK_S
    return written


_CHILD = r"""
import json, resource, sys, time
what, path, limit = sys.argv[1], sys.argv[2], int(sys.argv[3])
import can
from vehest_can.service.replay import replay_file  # imports (and the DBCs) outside the timing
t0, c0 = time.perf_counter(), time.process_time()
if what == "replay":
    r = replay_file(path)
    n, extra = r.frames_in, {"identical": r.identical, "ecu_frames": r.n_produced}
elif what == "logreader":
    n = 0
    for m in can.LogReader(path):
        n += 1
        if n == limit:
            break
    extra = {}
else:
    import cantools
    from vehest_can.paths import dbc_path
    dbs = {b: cantools.database.load_file(str(dbc_path(b))) for b in ("pt", "ch")}
    for db in dbs.values():  # the simulator's sync frames ride on each bus, in their own DBC
        db.add_dbc_file(str(dbc_path("sim")))
    msgs = []
    for m in can.LogReader(path):
        msgs.append(m)
        if len(msgs) == limit:
            break
    t0, c0 = time.perf_counter(), time.process_time()  # decode alone, the messages read beforehand
    n = 0
    for m in msgs:
        dbs[m.channel].decode_message(m.arbitration_id, m.data, decode_choices=False)
        n += 1
    extra = {}
s, cpu = time.perf_counter() - t0, time.process_time() - c0
print(json.dumps({"frames": n, "seconds": s, "cpu_seconds": cpu,
                  "peak_rss_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
                  **extra}))
"""


def _child(what: str, path: Path, limit: int = 0) -> dict:
    out = subprocess.run([sys.executable, "-c", _CHILD, what, str(path), str(limit)], capture_output=True, text=True)
    if out.returncode != 0:
        tail = "\n".join(out.stderr.strip().splitlines()[-3:])
        raise VehestError(f"replay bench: the {what} run failed (exit {out.returncode}):\n{tail}")
    return json.loads(out.stdout.strip().splitlines()[-1])


def run(n_frames: int = 10_000_000, repeats: int = 3, baseline_frames: int = 300_000) -> dict:
    with tempfile.TemporaryDirectory(prefix="vehest-replay-bench-") as tmp:
        path = Path(tmp) / "bench.log"
        t0 = time.perf_counter()
        n = generate(path, n_frames)
        gen_s = time.perf_counter() - t0
        runs, readers = [], []
        for _ in range(repeats):  # interleaved, so that both see the same load of a shared machine
            runs.append(_child("replay", path))
            readers.append(_child("logreader", path, baseline_frames))
        decode = _child("cantools", path, baseline_frames)
        size_mb = path.stat().st_size / 1e6
    med = float(np.median([r["seconds"] for r in runs]))
    med_cpu = float(np.median([r["cpu_seconds"] for r in runs]))
    return {
        "frames": n, "log_mb": size_mb, "generate_s": gen_s,
        "replay_s_median": med, "replay_fps": n / med, "replay_cpu_fps": n / med_cpu,
        "replay_peak_rss_mb": max(r["peak_rss_mb"] for r in runs),
        "replay_identical": all(r["identical"] for r in runs),
        "logreader_fps": float(np.median([r["frames"] / r["seconds"] for r in readers])),
        "logreader_frames": readers[0]["frames"],
        "logreader_cpu_fps": float(np.median([r["frames"] / r["cpu_seconds"] for r in readers])),
        "logreader_peak_rss_mb": max(r["peak_rss_mb"] for r in readers),
        "cantools_fps": decode["frames"] / decode["seconds"], "cantools_frames": decode["frames"],
        "repeats": repeats,
    }


def table(r: dict) -> str:
    ratio = r["replay_fps"] / r["logreader_fps"]
    return "\n".join([
        f"replay of a generated lockstep candump -L log: {r['frames']:,} frames, {r['log_mb']:.0f} MB",
        f"{'  replay end to end (read + ECU + compare)':<44}{r['replay_fps'] / 1e6:>9.2f} M frames/s"
        f"   median of {r['repeats']}, peak RSS {r['replay_peak_rss_mb']:.0f} MB, "
        f"{'identical' if r['replay_identical'] else 'DIFFERENT'} (target >= 1 M frames/s)",
        f"{'  python-can LogReader alone':<44}{r['logreader_fps'] / 1e6:>9.3f} M frames/s"
        f"   first {r['logreader_frames']:,} frames, median of {r['repeats']}, peak RSS {r['logreader_peak_rss_mb']:.0f} MB",
        f"{'  cantools decode_message alone':<44}{r['cantools_fps'] / 1e6:>9.3f} M frames/s"
        f"   {r['cantools_frames']:,} frames read beforehand",
        f"  replay vs LogReader: {ratio:.1f}x in wall time (target >= 15x); per CPU second "
        f"{r['replay_cpu_fps'] / 1e6:.2f} vs {r['logreader_cpu_fps'] / 1e6:.3f} M frames/s = "
        f"{r['replay_cpu_fps'] / r['logreader_cpu_fps']:.1f}x (the replay reads the log on a second thread)",
        f"  load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} CPUs",
    ])
