"""A soak run: the real-time ECU daemon (its own process) against a simulated car on ``udp_multicast``
(this host only, a port of the run's own), with a bounded hostile sender beside them, for a given time.

What it watches, for a process meant to run under systemd for weeks: the daemon's resident
memory and open file descriptors (``/proc/<pid>``, sampled), its frame-to-estimate latency and tick
lateness p50/p99/p99.9 per window, and its fault counters' rates per window (from ``daemon --report``:
totals since start, so a window's rate is a difference of two totals, never of a counter stuck at a
limit). The acceptance checks (:meth:`SoakResult.checks`): resident memory grows at most 1 MB after the
warm-up, the fd count is flat after it, and every fault the hostile sender keeps producing keeps being
counted in every window (no counter saturated), with the totals past 65535 when the run is long enough.

The car is a lean loop (plant + sensor node, sent at 2 kHz, nothing recorded), so the soak itself
holds bounded memory for any duration.
"""
from __future__ import annotations

import json
import os
import socket
import subprocess
import sys
import tempfile
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path

import can

from ..bus import bus as busmod
from ..bus.frames import TICK_S, frame_id, message, to_message, unused_frame_id
from ..bus.rt import Ticker
from ..errors import VehestError
from ..sim.powertrain import powertrain_car
from ..systems import load_any_scenario
from .daemon import stop_process

#: what the hostile sender sends, per cycle of 10: (kind, count); kinds and the counter each raises
HOSTILE_MIX = (("crc", 6), ("unknown_id", 2), ("dlc", 1), ("undecodable", 1))
HOSTILE_COUNTER = {"crc": "crc_error", "unknown_id": "unknown_id", "dlc": "dlc_error", "undecodable": "rx_undecodable"}
RSS_GROWTH_LIMIT_KB = 1024


@dataclass
class SoakConfig:
    duration_s: float = 300.0
    interval_s: float = 60.0      # a report (latency percentiles, rates) per interval
    warmup_s: float = 60.0        # memory and fds are judged after this
    hostile_rate: float = 500.0   # hostile frames per second (bounded)
    scenario: str = "tip_in_tip_out"
    sample_s: float = 5.0         # how often RSS and fds are read


@dataclass
class SoakResult:
    config: SoakConfig
    samples: list = field(default_factory=list)   # (t_s, rss_kb, fds)
    reports: list = field(default_factory=list)   # the daemon's --report lines
    hostile_sent: list = field(default_factory=list)  # (t_s, {kind: total sent so far})
    car_frames: int = 0
    car_deadline_misses: int = 0
    daemon_stats: dict = field(default_factory=dict)
    bus: str = ""

    def after_warmup(self) -> list:
        return [s for s in self.samples if s[0] >= self.config.warmup_s] or self.samples[-1:]

    def windows(self) -> list[dict]:
        """Per report interval: the daemon's RSS and fds at its end, latency and lateness
        percentiles, and each counter's rate per minute (a difference of totals)."""
        out, prev = [], None
        for r in self.reports:
            t0 = prev["t_s"] if prev else 0.0
            span_min = (r["t_s"] - t0) / 60.0
            totals = _totals(r)
            before = _totals(prev) if prev else dict.fromkeys(totals, 0)
            sample = min(self.samples, key=lambda s: abs(s[0] - r["t_s"])) if self.samples else (0, 0, 0)
            out.append({"t_s": r["t_s"], "rss_kb": sample[1], "fds": sample[2],
                        "latency_us": r["latency_us"], "lateness_us": r["lateness_us"],
                        "per_min": {k: (totals[k] - before.get(k, 0)) / span_min for k in totals
                                    if totals[k] - before.get(k, 0)}})
            prev = r
        return out

    def checks(self) -> list[tuple[str, bool, str]]:
        """(what, passed, figures) of each acceptance line."""
        late = self.after_warmup()
        rss = [s[1] for s in late]
        fds = [s[2] for s in late]
        growth = rss[-1] - rss[0]
        out = [(f"RSS growth after the first {self.config.warmup_s:g} s <= {RSS_GROWTH_LIMIT_KB} kB",
                growth <= RSS_GROWTH_LIMIT_KB,
                f"{rss[0]} -> {rss[-1]} kB ({growth:+d} kB; min {min(rss)}, max {max(rss)})"),
               (f"open fds flat after the first {self.config.warmup_s:g} s", max(fds) == min(fds),
                f"{min(fds)}..{max(fds)}")]
        # every window after the first kept counting each hostile fault: nothing saturated
        stuck = []
        for prev, r in zip(self.reports, self.reports[1:]):
            a, b = _totals(prev), _totals(r)
            stuck += [f"{c} at {r['t_s']:.0f} s" for c in HOSTILE_COUNTER.values() if b.get(c, 0) <= a.get(c, 0)]
        final = _totals(self.reports[-1]) if self.reports else {}
        over = [f"{c}={final.get(c, 0)}" for c in HOSTILE_COUNTER.values()]
        out.append(("no counter saturated (each hostile fault counted in every window)",
                    bool(self.reports) and not stuck, ("stuck: " + ", ".join(stuck)) if stuck else ", ".join(over)))
        return out


def _totals(report: dict) -> dict[str, int]:
    out = {f"{k}": v for k, v in report["counters"].items()}
    out.update({f"chassis_{k}": v for k, v in report["chassis_counters"].items()})
    out["rx_undecodable"] = report["rx_undecodable"]
    return out


def _proc(pid: int) -> tuple[int, int]:
    """(VmRSS kB, open fds) of a process."""
    rss = 0
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            rss = int(line.split()[1])
    return rss, len(os.listdir(f"/proc/{pid}/fd"))


def _hostile_frames() -> dict[str, can.Message]:
    dls, length = frame_id("DLS_Sensors"), message("DLS_Sensors").length  # the DBC's length: a CRC error, not a DLC one
    return {"crc": can.Message(arbitration_id=dls, is_extended_id=False, is_fd=True,
                               data=bytes([0x55] + [0] * (length - 1))),
            "unknown_id": can.Message(arbitration_id=unused_frame_id(), is_extended_id=False, data=bytes(8)),
            "dlc": can.Message(arbitration_id=dls, is_extended_id=False, is_fd=True, data=bytes(12))}


class Soak:
    def __init__(self, config: SoakConfig, progress=None):
        self.config = config
        self.progress = progress
        self.stop_event = threading.Event()
        self.result = SoakResult(config)

    def stop(self) -> None:
        self.stop_event.set()

    def run(self) -> SoakResult:
        cfg = self.config
        bus_cfg = busmod.private_multicast()
        res = self.result
        res.bus = f"udp_multicast {bus_cfg['channel']} port {bus_cfg['port']} (this host only)"
        _, scenario = load_any_scenario(cfg.scenario)
        car = powertrain_car(scenario)
        with tempfile.TemporaryDirectory(prefix="vh-soak-", dir="/tmp") as tmp:
            report, stats = Path(tmp) / "report.jsonl", Path(tmp) / "stats.json"
            proc, notify = self._start_daemon(bus_cfg, report, stats, Path(tmp) / "notify")
            threads = [threading.Thread(target=self._car, args=(bus_cfg, car), name="soak-car", daemon=True),
                       threading.Thread(target=self._hostile, args=(bus_cfg,), name="soak-hostile", daemon=True)]
            t0 = time.monotonic()
            self._t0 = t0
            try:
                for t in threads:
                    t.start()
                while not self.stop_event.is_set() and time.monotonic() - t0 < cfg.duration_s:
                    if proc.poll() is not None:
                        raise VehestError(f"the ECU daemon exited during the soak: {proc.communicate()[1][-2000:]}")
                    res.samples.append((time.monotonic() - t0, *_proc(proc.pid)))
                    if self.progress:
                        self.progress(int(time.monotonic() - t0), int(cfg.duration_s))
                    self.stop_event.wait(min(cfg.sample_s, max(0.0, cfg.duration_s - (time.monotonic() - t0))))
                res.samples.append((time.monotonic() - t0, *_proc(proc.pid)))
            finally:
                self.stop_event.set()
                for t in threads:
                    t.join(10.0)
                err = stop_process(proc, timeout=30)
                notify.close()
            if proc.returncode != 0:
                raise VehestError(f"the ECU daemon failed (exit {proc.returncode}): {err[-2000:]}")
            res.reports = [json.loads(line) for line in report.read_text().splitlines() if line.strip()]
            res.daemon_stats = json.loads(stats.read_text())
        return res

    def _start_daemon(self, bus_cfg: dict, report: Path, stats: Path, notify_path: Path):
        """The daemon as systemd would run it; READY=1 on a notify socket says its bus is open."""
        notify = socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM)
        notify.bind(str(notify_path))
        notify.settimeout(0.2)
        cmd = [sys.executable, "-m", "vehest_can.cli", "daemon", "--mode", "realtime", "--report", str(report),
               "--report-every", str(self.config.interval_s), "--stats", str(stats), *busmod.cli_args(bus_cfg)]
        proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
                                env={**os.environ, "NOTIFY_SOCKET": str(notify_path)})
        end = time.monotonic() + 60.0
        while time.monotonic() < end and proc.poll() is None:
            try:
                if b"READY=1" in notify.recv(4096):
                    return proc, notify
            except TimeoutError:
                continue
        proc.kill()
        notify.close()
        raise VehestError(f"the ECU daemon did not get ready: {proc.communicate()[1][-2000:]}")

    def _car(self, bus_cfg: dict, car) -> None:
        """The plant and its sensor node at 2 kHz, looping the scenario's drive; nothing kept."""
        bus = busmod.open_bus(bus_cfg)
        ticker = Ticker(TICK_S)
        k = 0
        try:
            ticker.start()
            while not self.stop_event.is_set():
                ticker.wait()
                for f in car.tick(k % car.n):
                    bus.send(to_message(f))
                    self.result.car_frames += 1
                k += 1
        finally:
            self.result.car_deadline_misses = ticker.misses
            bus.shutdown()

    def _hostile(self, bus_cfg: dict) -> None:
        """A bounded hostile sender: bad CRCs, unknown IDs, wrong lengths on the bus, and datagrams the
        transport cannot decode on its port, at hostile_rate per second in all."""
        bus = busmod.open_bus(bus_cfg)
        raw = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        raw.setsockopt(socket.IPPROTO_IP, socket.IP_MULTICAST_TTL, 0)  # this host only, like the bus
        raw.setsockopt(socket.IPPROTO_IP, socket.IP_MULTICAST_IF, socket.inet_aton(busmod.LOOPBACK_V4))
        frames = _hostile_frames()
        cycle = [kind for kind, n in HOSTILE_MIX for _ in range(n)]
        sent = dict.fromkeys(HOSTILE_COUNTER, 0)
        period = 1.0 / self.config.hostile_rate
        due = time.monotonic()
        try:
            i = 0
            while not self.stop_event.is_set():
                kind = cycle[i % len(cycle)]
                if kind == "undecodable":
                    raw.sendto(b"\xc1 not msgpack", (bus_cfg["channel"], bus_cfg["port"]))
                else:
                    bus.send(frames[kind])
                sent[kind] += 1
                i += 1
                if i % 100 == 0:
                    self.result.hostile_sent.append((time.monotonic() - self._t0, dict(sent)))
                due += period
                self.stop_event.wait(max(0.0, due - time.monotonic()))
        finally:
            self.result.hostile_sent.append((time.monotonic() - self._t0, dict(sent)))
            raw.close()
            bus.shutdown()


def format_result(res: SoakResult) -> list[str]:
    """The per-window table, the totals and the acceptance lines."""
    head = ("t s", "RSS MB", "fds", "lat p50", "p99", "p99.9 µs", "late p99 µs", "faults per minute")
    rows = []
    for w in res.windows():
        lat, late = w["latency_us"], w["lateness_us"]
        rates = ", ".join(f"{k} {v:.0f}" for k, v in sorted(w["per_min"].items()))
        rows.append((f"{w['t_s']:.0f}", f"{w['rss_kb'] / 1024:.1f}", str(w["fds"]),
                     f"{lat.get('p50', float('nan')):.0f}", f"{lat.get('p99', float('nan')):.0f}",
                     f"{lat.get('p99.9', float('nan')):.0f}", f"{late.get('p99', float('nan')):.0f}", rates))
    widths = [max(len(r[i]) for r in (head, *rows)) for i in range(len(head) - 1)]
    lines = ["  ".join([*(c.rjust(w) for c, w in zip(r[:-1], widths)), r[-1]]) for r in (head, *rows)]
    st = res.daemon_stats
    sent = res.hostile_sent[-1][1] if res.hostile_sent else {}
    lines.append(f"bus {res.bus}; car: {res.car_frames} frames, {res.car_deadline_misses} deadline misses; "
                 f"hostile sent: " + ", ".join(f"{k} {v}" for k, v in sent.items()))
    lines.append(f"daemon: {st.get('ticks', 0)} ticks, {st.get('frames_rx', 0)} frames in, "
                 f"{st.get('deadline_misses', 0)} deadline misses; whole-run latency µs "
                 + " ".join(f"{k}={v:.0f}" for k, v in st.get("latency_us", {}).items() if k != "n"))
    lines.append("fault totals: " + ", ".join(f"{k}={v}" for k, v in st.get("counters", {}).items() if v)
                 + f", rx_undecodable={st.get('rx_undecodable', 0)}; receive FIFO overruns {st.get('rx_overrun', 0)}")
    for what, ok, figures in res.checks():
        lines.append(f"  [{'pass' if ok else 'FAIL'}] {what}: {figures}")
    return lines
