"""Fault campaigns: a drive with faults in simulated time (car -> injector -> wire model -> ECU), the fault
table of ``vehest-can faults`` (what the ECU detects, its health response, recovery), and the real-time
bus run through one serialising wire."""
from __future__ import annotations

import logging
import math
import threading
import time
from dataclasses import dataclass
from typing import Any

import can
import numpy as np

from ..bus.bus import open_bus
from ..bus.busload import bus_load
from ..bus.frames import TICK_S, database, message, to_message
from ..carfile import car_of
from ..errors import ConfigError
from ..paths import dbc_path
from ..service.daemon import EcuDaemon
from ..sim.session import SimMaster
from ..systems import FaultCase, FaultStudy, fault_study
from ..systems.ecu import COUNTERS, Ecu, EcuConfig
from .injector import FaultInjector
from .spec import FaultConfig, faults_from_cli
from .wire import EXT_FLAG, FaultBus, Wire, WireModel

log = logging.getLogger(__name__)


# ---- in-process runs: car -> injector -> wire model -> ECU, in simulated time ----------------------

@dataclass
class FaultRun:
    """One drive with faults, tick by tick. ``est`` holds the raw payload of the study's estimate frame
    every tick; the methods decode its health, valid bits and estimates (the study knows how)."""

    config: FaultConfig
    est: np.ndarray            # (n, the estimate frame's length) uint8
    counters: np.ndarray       # (n, len(ecu.COUNTERS)) after each step
    sample_age: np.ndarray     # (n,) s from the making of the newest sample the ECU accepted to its step
    truth: np.ndarray          # (n,) the plant's value of the first filter's estimate
    rx: list                   # per tick: the frames the ECU received before its step
    tx: list                   # (tick, can.Message) of every ECU frame
    applied: list              # frames each fault changed
    overflow: dict             # transmit-queue overflows per node
    load: float                # bus load the wire carried over the run (0..1)
    study: FaultStudy

    @property
    def n(self) -> int:
        return len(self.est)

    def health(self, which: str) -> np.ndarray:
        """Health of one of the study's filters per tick: 0 INIT .. 3 FAULT."""
        return self.study.health(self.est, which)

    def valid(self, which: str) -> np.ndarray:
        return self.study.valid(self.est, which)

    def estimate(self, which: str) -> np.ndarray:
        return self.study.estimate(self.est, which)

    def counter(self, name: str) -> np.ndarray:
        return self.counters[:, COUNTERS.index(name)]


def run_with_faults(car, config: FaultConfig | None = None, *, bitrate: int = 500_000,
                    data_bitrate: int | None = 4_000_000, stuffing: str = "worst", tx_queue: int = 10,
                    tx_policy: str = "fifo", study: FaultStudy | None = None) -> FaultRun:
    """The drive in simulated time with the car's and the ECU's frames through injectors and one wire.

    Tick k: the car's frames (and the ECU's frames of step k-1) are ready at k * 500 µs plus their
    delay; what the wire completes by (k + 1) * 500 µs reaches the ECU before its step k. Without
    faults this equals ``run_inprocess`` frame for frame (a load of 47 % leaves every frame inside
    its tick). Floods come from a node of their own. `study`: whose response is recorded (default: the
    first registered system's that has one).
    """

    config = config or FaultConfig()
    study = study or fault_study()
    wire = WireModel(bitrate, data_bitrate, stuffing=stuffing, tx_queue=tx_queue, tx_policy=tx_policy)
    for spec in config.floods:
        wire.add_flood(spec, "FLOOD")
    ecu = Ecu(EcuConfig(car=car_of(getattr(car, "scenario", None))))  # calibrated for the car's car file
    car.reset()
    closed = car.closed   # the car takes the ECU's frames (actuators): from the wire, as they arrive
    sensors, vehest = FaultInjector(config, stream=0), FaultInjector(config, stream=1)
    est_id, sensor_id = message(study.estimate_message).frame_id, message(study.sensor_message).frame_id
    # the counters of the study's application (default: the powertrain side's)
    cnt = study.counters_of(ecu) if hasattr(study, "counters_of") else ecu.c.cnt
    n = car.n
    est = np.zeros((n, message(study.estimate_message).length), dtype=np.uint8)
    counters = np.zeros((n, len(COUNTERS)), dtype=np.int64)
    sample_age = np.full(n, np.nan)
    truth = np.zeros(n)
    rx, tx = [], []
    out: list[can.Message] = []
    sample_t = math.nan
    for k in range(n):
        t = k * TICK_S
        for msg, delay in sensors.apply([to_message(f, timestamp=t) for f in car.tick(k)], t):
            wire.submit(msg, t + delay, study.sensor_node)
        for msg, delay in vehest.apply(out, t):
            wire.submit(msg, t + delay, "VEHEST")
        delivered = wire.advance(t + TICK_S)
        got = [tr.msg for tr in delivered if tr.node != "VEHEST"]
        if closed:   # the ECU's frames of step k - 1, on the wire in tick k: applied from tick k + 1
            for tr in delivered:
                if tr.node == "VEHEST":
                    car.rx(tr.msg)
        for msg in got:
            refused = cnt.crc_error + cnt.counter_repeat + cnt.dlc_error
            ecu.rx(msg)
            if msg.arbitration_id == sensor_id and not msg.is_extended_id and \
                    cnt.crc_error + cnt.counter_repeat + cnt.dlc_error == refused:
                sample_t = msg.timestamp   # when the sensor node made it
        out = ecu.step(timestamp=t + TICK_S)
        rx.append(got)
        if k > 0:   # an estimate frame slower than the tick: its last payload holds
            est[k] = est[k - 1]
        for msg in out:
            tx.append((k, msg))
            if msg.arbitration_id == est_id:
                est[k] = np.frombuffer(bytes(msg.data), dtype=np.uint8)
        counters[k] = [getattr(cnt, name) for name in COUNTERS]
        sample_age[k] = t + TICK_S - sample_t
        truth[k] = study.truth(car)
    for msg, delay in vehest.apply(out, n * TICK_S):   # the last step's frames, sent as the run ends
        wire.submit(msg, n * TICK_S + delay, "VEHEST")
    wire.advance((n + 1) * TICK_S)
    load = sum(wire.busy_s.values()) / (n * TICK_S)    # the frames of the run's n ticks, over n ticks
    applied = [a + b for a, b in zip(sensors.applied, vehest.applied)]
    return FaultRun(config, est, counters, sample_age, truth, rx, tx, applied, dict(wire.overflow), load, study)


# ---- the fault table: each fault run, what the ECU detects, its health response, recovery -----------

_HEALTH = ("INIT", "OK", "DEGRADED", "FAULT")


@dataclass
class FaultRow:
    label: str
    fault: str                    # command-line form ("" for the reference run), plus wire options
    expect: tuple[str, ...]
    window: tuple[int, int]       # ticks [first, end) of the fault
    detected: dict                # counter -> rise from the fault's start to the end of the run
    first_detect: int | None      # ticks from the fault's start to the first rise of an expected counter
    health: dict                  # filter -> health states during the fault, in order of appearance
    valid_pct: dict               # filter -> % of the fault's ticks with the estimate marked valid
    recovery: int | None          # ticks after the fault until all valid; 0: never lost; None: not again
    oldest_ms: float              # oldest sample behind an estimate marked valid, fault to run end [ms]
    rms_error: float              # first filter's error vs the plant while valid during the fault; nan: < 10 ticks
    applied: int                  # frames the fault changed
    run: FaultRun | None = None

    def detect_text(self) -> str:
        if not self.detected:
            return "nothing"
        items = [f"{k} +{v}" for k, v in self.detected.items()]
        after = "" if self.first_detect is None else f" (first after {self.first_detect + 1} tick" \
            f"{'s' if self.first_detect else ''})"
        return ", ".join(items) + after

    def health_text(self) -> str:
        states = {w: "→".join(h) for w, h in self.health.items()}
        valid = list(self.valid_pct.values())
        if len(set(states.values())) == 1 and max(valid) - min(valid) < 0.05:
            return f"{', '.join(states)}: {next(iter(states.values()))}; valid {valid[0]:.1f} %"
        return "; ".join(f"{w}: {t}, valid {self.valid_pct[w]:.1f} %" for w, t in states.items())

    def recovery_text(self) -> str:
        if self.recovery == 0:
            return "never lost"
        if self.recovery is None:
            return "not within the run"
        return f"valid at tick {self.recovery} after the fault"


def analyse(run: FaultRun, label: str, fault: str, expect: tuple[str, ...],
            window_s: tuple[float, float]) -> FaultRow:
    """One row of the fault table from a run; window_s = the fault's [start, end) in seconds."""

    a = int(math.ceil(window_s[0] / TICK_S - 1e-9))
    b = min(run.n, int(math.ceil(window_s[1] / TICK_S - 1e-9)))
    before = run.counters[a - 1] if a > 0 else np.zeros(len(COUNTERS), dtype=np.int64)
    rise = run.counters[-1] - before
    detected = {COUNTERS[i]: int(v) for i, v in enumerate(rise) if v}
    first = None
    for name in expect:
        col = run.counters[a:, COUNTERS.index(name)] - before[COUNTERS.index(name)]
        hits = np.flatnonzero(col > 0)
        if hits.size and (first is None or hits[0] < first):
            first = int(hits[0])
    filters = run.study.filters
    health, valid_pct = {}, {}
    for w in filters:
        states = []
        for h in run.health(w)[a:b]:
            if _HEALTH[h] not in states:
                states.append(_HEALTH[h])
        health[w] = states
        valid_pct[w] = 100.0 * float(run.valid(w)[a:b].mean()) if b > a else 100.0
    every = np.logical_and.reduce([run.valid(w) for w in filters])
    if every[a:b].all():
        recovery: int | None = 0
    else:
        again = np.flatnonzero(every[b:])
        recovery = int(again[0]) + 1 if again.size else None
    vt = run.valid(filters[0])
    ages = run.sample_age[a:][vt[a:]]
    oldest = 1e3 * float(np.nanmax(ages)) if ages.size else math.nan
    sel = np.flatnonzero(vt[a:b]) + a
    err = run.estimate(filters[0])[sel] - run.truth[sel]
    rms = float(np.sqrt(np.mean(err ** 2))) if sel.size >= 10 else math.nan   # too few valid ticks to say
    applied = sum(run.applied)
    return FaultRow(label, fault, expect, (a, b), detected, first, health, valid_pct, recovery, oldest, rms,
                    applied, run)


def fault_table(car, catalogue: tuple[FaultCase, ...] | None = None, *, seed: int = 1, keep_runs: bool = False,
                progress=None, study: FaultStudy | None = None, **wire) -> list[FaultRow]:
    """Run every case (default: the study's catalogue) on the drive and analyse it (``wire``: bit rates,
    stuffing, queue for every case)."""
    study = study or fault_study()
    catalogue = study.catalogue if catalogue is None else catalogue
    rows = []
    for i, case in enumerate(catalogue):
        config = faults_from_cli([case.fault] if case.fault else [], seed=seed)
        window = (config.faults[0].start_s, config.faults[0].end_s) if config.faults else (2.0, 2.5)
        run = run_with_faults(car, config, study=study, **{**wire, **case.wire})
        text = " ".join([case.fault, *(f"{k}={v}" for k, v in case.wire.items())])
        row = analyse(run, case.label, text, case.expect, window)
        if not keep_runs:
            row.run = None
        rows.append(row)
        if progress:
            progress(i + 1, len(catalogue))
    return rows


def format_table(rows: list[FaultRow], *, markdown: bool = False, study: FaultStudy | None = None,
                 width: int = 100) -> list[str]:
    """The fault table: one row per fault when it fits `width` columns, else one block per fault."""
    study = study or fault_study()
    head = ("fault", "injected as", "ECU detects (counter rise)", "health during the fault", "recovery",
            "oldest sample, valid est.", study.error_label)
    body = [(r.label, r.fault or "-", r.detect_text(), r.health_text(), r.recovery_text(), f"{r.oldest_ms:.1f} ms",
             "-" if math.isnan(r.rms_error) else f"{r.rms_error:.1f} {study.error_unit} RMS") for r in rows]
    if markdown:
        def cell(x):
            return x.replace("|", "\\|")
        lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
        lines += ["| " + " | ".join(cell(c) if j != 1 or c == "-" else f"`{c}`" for j, c in enumerate(row)) + " |"
                  for row in body]
        return lines
    widths = [max(len(r[i]) for r in (head, *body)) for i in range(len(head))]
    wide = ["  ".join(c.ljust(w) for c, w in zip(row, widths)).rstrip() for row in (head, *body)]
    if max(map(len, wide)) <= width:
        return wide
    import textwrap

    label = max(len(h) for h in head[2:]) + 2
    out: list[str] = []
    for row in body:
        out.append(f"{row[0]}" + (f"  (injected as {row[1]})" if row[1] != "-" else ""))
        for h, c in zip(head[2:], row[2:]):
            out += textwrap.wrap(c, width, initial_indent=f"  {h + ':':<{label}}", subsequent_indent=" " * (label + 2),
                                 break_on_hyphens=False) or [f"  {h}:"]
    return out




# ---- the acceptance run: real time, both nodes through one serialising wire --------------------------

@dataclass
class BusRun:
    """What a real-time run through a :class:`Wire` produced, measured over its steady middle."""

    window_s: float               # length of the measurement window (wall clock)
    load: dict                    # frame name -> measured load (0..1) in the window; "total" for all
    expected_worst: dict          # frame name -> busload's worst case (0..1); "total" for the cyclic frames
    expected_nominal: dict
    rate_hz: dict                 # frame name -> frames per second in the window
    wire_us: dict                 # frame name -> measured busy time per frame [µs]
    stuffing: str
    sim: dict                     # SimMaster.run_realtime statistics
    daemon: Any                   # DaemonStats of the ECU
    late_ms: float                # worst lateness of a delivery behind its modelled wire end
    overflow: int
    send_errors: int
    ticks_expected: int
    session: object = None        # the simulator's Session (its frames and what it received)
    expected_names: frozenset = frozenset()   # every frame of the DBC

    def lines(self) -> list[str]:
        ref = self.expected_worst if self.stuffing == "worst" else self.expected_nominal
        out = [f"bus load over {self.window_s:.2f} s of real time, {self.stuffing}-case stuffing, "
               f"against `vehest-can busload` ({self.stuffing}):"]
        for name in self.load:
            exp = ref.get(name)
            rate = f"{self.rate_hz[name]:7.1f} frames/s, {self.wire_us[name]:6.2f} µs each, " \
                if name in self.rate_hz else ""
            head = f"  {name:22s} {rate}measured {100 * self.load[name]:6.2f} %"
            if exp:
                out.append(f"{head}, busload {100 * exp:6.2f} %  ({100 * (self.load[name] / exp - 1):+.1f} %)")
            else:
                out.append(f"{head} ({'event frame' if name in self.expected_names else 'not in the DBC'})")
        out.append(f"real time: simulator {self.sim.get('deadline_misses')} deadline misses, ECU "
                   f"{self.daemon.deadline_misses}; deliveries at most {self.late_ms:.2f} ms behind the wire; "
                   f"queue overflows {self.overflow}, bus send errors {self.send_errors}")
        faults = {k: v for k, v in self.daemon.counters.items() if v}
        out.append("ECU: " + (", ".join(f"{k}={v}" for k, v in faults.items()) or "no faults") +
                   "; health " + ", ".join(f"{k}={v}" for k, v in self.daemon.health.items()))
        return out

    def undisturbed(self, tolerance: float = 0.01) -> bool:
        """Both real-time loops kept their 2 kHz schedule (deadline misses within `tolerance` of the ticks)."""
        limit = tolerance * self.ticks_expected
        return self.sim.get("deadline_misses", 0) <= limit and self.daemon.deadline_misses <= limit


def bus_run(car, config=None, *, bus_config: dict | None = None, bitrate: int = 500_000,
            data_bitrate: int | None = 4_000_000, stuffing: str = "worst", tx_queue: int = 10,
            tx_policy: str = "fifo", settle_s: float = 0.5, switch_interval: float | None = 2e-4) -> BusRun:
    """The drive in real time: the ECU daemon (a thread) and the simulator, each on its own python-can bus
    (`bus_config`, default a fresh ``virtual`` channel) wrapped in a FaultBus on one shared wire. The
    simulator's node carries `config`'s faults. The load is measured between `settle_s` after the start
    and `settle_s` before the end of the drive.

    `switch_interval`: Python's GIL switch interval during the run (two 2 kHz loops share one interpreter;
    the default 5 ms lets one spinning loop starve the other); None leaves it alone.
    """
    import sys
    import uuid


    config = config or FaultConfig()
    bus_config = dict(bus_config or {"interface": "virtual", "channel": f"faultbus-{uuid.uuid4().hex[:8]}"})
    no_flood = FaultConfig(tuple(f for f in config.faults if f.kind != "flood"), config.seed)
    duration = car.n * TICK_S
    if duration <= 2 * settle_s + 0.2:
        raise ConfigError(f"a bus run needs a drive longer than {2 * settle_s + 0.2:g} s, not {duration:g} s")
    old_interval = sys.getswitchinterval()
    if switch_interval is not None:
        sys.setswitchinterval(switch_interval)
    wire = Wire(bitrate, data_bitrate, stuffing=stuffing, tx_queue=tx_queue, tx_policy=tx_policy)
    buses: list = []
    daemon: EcuDaemon | None = None
    thread: threading.Thread | None = None
    result: dict = {}
    snaps: list = []
    try:
        ecu_bus = FaultBus(open_bus(bus_config), FaultInjector(no_flood, stream=1), wire=wire)
        buses.append(ecu_bus)
        sim_bus = FaultBus(open_bus(bus_config), FaultInjector(config), wire=wire)
        buses.append(sim_bus)
        daemon = EcuDaemon(ecu_bus)
        thread = threading.Thread(target=lambda: result.setdefault("stats", daemon.serve_realtime()),
                                  name="vehest-ecu", daemon=True)
        thread.start()
        time.sleep(0.1)

        def measure():
            time.sleep(settle_s)
            snaps.append(wire.snapshot())
            time.sleep(duration - 2 * settle_s)
            snaps.append(wire.snapshot())

        meter = threading.Thread(target=measure, name="vehest-meter", daemon=True)
        sim = SimMaster(sim_bus, car)
        meter.start()
        session = sim.run_realtime(settle_s=0.1)
        meter.join()
    finally:
        if daemon is not None and thread is not None:
            daemon.stop_event.set()
            thread.join(5)
        for b in buses:
            b.shutdown()
        wire.close()
        sys.setswitchinterval(old_interval)
    a, b = snaps
    expected = bus_load(dbc_path("pt"), bitrate, data_bitrate)
    db = database("pt")
    names = {m.frame_id: m.name for m in db.messages}
    load, rate, per_frame = {}, {}, {}
    for key in sorted(b.frames):
        name = names.get(key, f"0x{key & ~EXT_FLAG:X}")
        load[name] = b.load_since(a, [key])
        n = b.frames_since(a, key)
        rate[name] = n / (b.t - a.t)
        per_frame[name] = 1e6 * (b.busy_s[key] - a.busy_s.get(key, 0.0)) / n if n else 0.0
    load["total"] = b.load_since(a)
    worst = {f.name: f.worst_pct / 100 for f in expected.frames if not f.event}
    nominal = {f.name: f.nominal_pct / 100 for f in expected.frames if not f.event}
    # total: the cyclic frames this run put on the wire (some are in the DBC but on the bus only
    # at times, e.g. while a device is clamped on)
    seen = [n for n in load if n != "total" and n in worst]
    worst["total"], nominal["total"] = sum(worst[n] for n in seen), sum(nominal[n] for n in seen)
    return BusRun(b.t - a.t, load, worst, nominal, rate, per_frame, stuffing, session.stats,
                  result.get("stats"), 1e3 * wire.late_s, sum(wire.model.overflow.values()), wire.send_errors,
                  car.n, session, frozenset(names.values()))


