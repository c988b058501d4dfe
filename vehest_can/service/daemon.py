"""The ECU prototype daemon: the C core behind a python-can bus, in lockstep or real time.

* lockstep: driven by SIM_Sync frames (see ``lockstep.py``); deterministic on any bus.
* real time: the daemon's own 2 kHz wall clock; received frames are handed to the core as they
  arrive (the core holds the last sample of each signal), deadline misses, tick lateness and
  frame-to-estimate latency are measured.

Bus errors (``can.CanError``/``OSError`` on send or receive, e.g. a SocketCAN link that goes
down) do not stop the daemon: it counts them, warns once per outage, keeps ticking and goes on
when the bus is back; the outages and failures are in the statistics.

Several buses (a HIL bench's powertrain and chassis adapters): the daemon hears every one, and each
frame it sends goes to the bus whose DBC has it (``routes``: frame ID -> bus; anything else to the
first bus, which with one bus is every frame); a lockstep SIM_Sync is answered on the bus it came
from, its VEHEST_SyncAck counting the frames sent there. With one bus, nothing changes.

Stops cleanly on SIGINT/SIGTERM (or END in lockstep with ``exit_on_end``): log flushed, bus
closed, summary returned.
"""
from __future__ import annotations

import collections
import logging
import queue
import signal
import subprocess
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field

import can

from ..bus import lockstep
from ..bus.bus import is_undecodable
from ..bus.frames import TICK_S, frame_id, is_own, sent_by
from ..bus.rt import Durations, Ticker, percentiles_us
from ..systems.ecu import Ecu
from . import sdnotify

log = logging.getLogger(__name__)

#: real-time receive FIFO, frames (all buses): about 0.2 s of this project's traffic; older frames are
#: far past every RX timeout (a few ticks) and of no use to the estimators
RX_FIFO = 512


@dataclass
class DaemonStats:
    mode: str
    ticks: int = 0
    frames_rx: int = 0
    frames_tx: int = 0
    sessions: int = 0
    wall_s: float = 0.0
    lateness_us: dict = field(default_factory=dict)
    latency_us: dict = field(default_factory=dict)
    deadline_misses: int = 0
    counters: dict = field(default_factory=dict)
    chassis_counters: dict = field(default_factory=dict)
    health: dict = field(default_factory=dict)
    bus_outages: int = 0      # runs of bus errors, each ended by a frame sent or received
    send_failures: int = 0    # frames the bus refused (not sent, not logged)
    recv_errors: int = 0      # errors raised by the bus's receive
    rx_undecodable: int = 0   # datagrams/frames the transport could not turn into a CAN frame
    bus_down_s: float = 0.0   # wall time from the first error of an outage to its end
    buses: dict = field(default_factory=dict)  # per bus: {"rx": frames in, "tx": frames out}
    not_heard: list = field(default_factory=list)  # estimators whose sensor frame never arrived
    rx_overrun: int = 0       # real time: frames dropped (the oldest) from a full receive FIFO

    def lines(self) -> list[str]:
        out = [f"mode {self.mode}: {self.ticks} ticks, {self.frames_rx} frames in, {self.frames_tx} out, "
               f"{self.wall_s:.1f} s"]
        if self.mode == "realtime":
            out.append(f"tick lateness µs {_fmt(self.lateness_us)}; deadline misses {self.deadline_misses}")
            out.append(f"frame-to-estimate latency µs {_fmt(self.latency_us)}")
        faults = {k: v for k, v in self.counters.items() if v}
        out.append("faults: " + (", ".join(f"{k}={v}" for k, v in faults.items()) or "none"))
        chassis = {k: v for k, v in self.chassis_counters.items() if v}
        if chassis:
            out.append("chassis faults: " + ", ".join(f"{k}={v}" for k, v in chassis.items()))
        if self.rx_overrun:
            out.append(f"receive FIFO overrun: {self.rx_overrun} frames dropped (the oldest; the daemon fell "
                       f"{RX_FIFO} frames behind)")
        if self.rx_undecodable:
            out.append(f"undecodable input: {self.rx_undecodable} (not a CAN frame of the bus's transport; dropped)")
        if self.bus_outages:
            out.append(f"bus errors: {self.bus_outages} outage(s), {self.send_failures} failed sends, "
                       f"{self.recv_errors} receive errors, down {self.bus_down_s:.1f} s")
        else:
            out.append("bus errors: none")
        if len(self.buses) > 1:
            out.append("buses: " + "; ".join(f"{k} {v['rx']} in, {v['tx']} out" for k, v in self.buses.items()))
        health = ", ".join(f"{k}={v}" for k, v in self.health.items() if k not in self.not_heard) or "-"
        if self.not_heard:
            input_of = {e.name: e.input for e in Ecu.estimators()}
            inputs = dict.fromkeys(input_of[k] for k in self.not_heard)
            health += (f"; not heard (not configured or absent, not a fault): {', '.join(self.not_heard)} "
                       f"(no {' or '.join(inputs)} since start)")
        out.append("health: " + health)
        return out


def stop_process(proc: subprocess.Popen, timeout: float) -> str:
    """Stop an ECU daemon run as its own process (text pipes): SIGTERM (its clean shutdown), killed if it
    has not exited within `timeout` s; what it wrote to stderr."""
    if proc.poll() is None:
        proc.send_signal(signal.SIGTERM)
    try:
        _, err = proc.communicate(timeout=timeout)
    except subprocess.TimeoutExpired:
        proc.kill()
        _, err = proc.communicate()
    return err


def _fmt(p: dict) -> str:
    return " ".join(f"{k}={v:.0f}" for k, v in p.items() if k != "n") or "-"


class EcuDaemon:
    def __init__(self, bus: can.BusABC | dict[str, can.BusABC], ecu: Ecu | None = None, *,
                 log_writer: can.Listener | None = None, log_channel: str | None = "vcan0",
                 notifier: sdnotify.Notifier | None = None, routes: dict[int, str] | None = None,
                 rx_by_bus: dict[str, Callable[[can.Message], None]] | None = None):
        """`bus`: one bus, or {name: bus} for several (then logged with the bus's name as channel);
        `routes`: frame ID -> bus name of what the ECU sends (others go to the first bus);
        `rx_by_bus`: bus name -> what takes that bus's frames instead of the ECU's RX (XCP's own bus:
        its slave listens there only, and nothing heard there is the systems' input)."""
        self.buses = dict(bus) if isinstance(bus, dict) else {"": bus}
        if not self.buses:
            raise ValueError("the daemon needs a bus")
        self.bus = next(iter(self.buses.values()))
        self.routes = {i: n for i, n in (routes or {}).items() if n in self.buses}
        self.rx_by_bus = {n: f for n, f in (rx_by_bus or {}).items() if n in self.buses}
        self.notifier = notifier or sdnotify.Notifier()  # systemd's sd_notify; a no-op by default
        self.ecu = ecu or Ecu()
        self.log_writer = log_writer
        self.log_channel = log_channel
        self.stop_event = threading.Event()
        self._dls_id = frame_id("DLS_Sensors")
        self._own = sent_by({"VEHEST"})
        self.stats = DaemonStats("idle")
        self._down_since: float | None = None  # perf_counter() of an open outage's first error
        self._down_send = False                # a send failed in the open outage

    # -- shared -------------------------------------------------------------------------------
    def _log(self, msg: can.Message, timestamp: float, bus: str = "") -> None:
        if self.log_writer is not None:
            msg.timestamp = timestamp
            msg.channel = bus if len(self.buses) > 1 else self.log_channel
            self.log_writer.on_message_received(msg)

    def _route(self, msg: can.Message) -> str:
        return self.routes.get(msg.arbitration_id, next(iter(self.buses)))

    def _send(self, msg: can.Message, timestamp: float, bus: str | None = None) -> bool:
        """Send and log one frame (on its bus); a bus error is counted and the frame dropped (returns False)."""
        name = self._route(msg) if bus is None else bus
        try:
            self.buses[name].send(msg)
        except (can.CanError, OSError) as exc:
            self.stats.send_failures += 1
            self._bus_error("send", exc)
            return False
        self._bus_ok("send")
        self._log(msg, timestamp, name)
        self._count(name, "tx")
        return True

    def _count(self, bus: str, what: str) -> None:
        self.stats.buses.setdefault(bus or "bus", {"rx": 0, "tx": 0})[what] += 1

    def _inbox(self, sink) -> list[can.Notifier]:
        """One python-can Notifier per bus, each frame (or receive error) handed to ``sink(bus, item)``.
        Only a bus failing again and again (no frame between) backs off, up to 50 ms: garbage between
        good frames must not stall the receive path."""
        stop_event = self.stop_event

        class Inbox(can.Listener):
            def __init__(self, name: str):
                self.name = name
                self.in_row = 0  # receive errors since the last frame

            def on_message_received(self, msg: can.Message) -> None:
                self.in_row = 0
                sink(self.name, msg)

            def on_error(self, exc: Exception) -> None:
                # The notifier goes on receiving after this; counted on the ticking thread.
                sink(self.name, exc)
                if not is_undecodable(exc):
                    self.in_row += 1
                    if self.in_row > 3:
                        stop_event.wait(0.001 * 2 ** min(self.in_row - 4, 5.6))  # up to 50 ms

        return [can.Notifier(b, [Inbox(name)], timeout=0.005) for name, b in self.buses.items()]

    def _rx_error(self, exc: Exception) -> bool:
        """Count a receive error. An undecodable datagram (garbage on a udp_multicast port, a
        truncated frame) is a counted fault of the input, not an outage: the bus is fine and the
        next frame may be good, so nothing waits. True if it was an outage-like error."""
        if is_undecodable(exc):
            self.stats.rx_undecodable += 1
            if self.stats.rx_undecodable in (1, 10, 100, 1000) or self.stats.rx_undecodable % 10000 == 0:
                log.warning("undecodable input on the bus (%d so far): %s", self.stats.rx_undecodable, exc)
            return False
        self.stats.recv_errors += 1
        self._bus_error("receive", exc)
        return True

    def _bus_error(self, what: str, exc: Exception) -> None:
        self._down_send |= what == "send"
        if self._down_since is None:
            self._down_since = time.perf_counter()
            self.stats.bus_outages += 1
            log.warning("bus error on %s (%s): keeping on ticking, counting failures until the bus is back",
                        what, exc)

    def _bus_ok(self, what: str) -> None:
        """A frame went out or came in: that ends an outage (once sending failed, only a send does)."""
        if self._down_since is not None and (what == "send" or not self._down_send):
            down = time.perf_counter() - self._down_since
            self.stats.bus_down_s += down
            self._down_since = None
            self._down_send = False
            log.warning("bus back after %.1f s (%d failed sends, %d receive errors so far)",
                        down, self.stats.send_failures, self.stats.recv_errors)

    def _finish(self, stats: DaemonStats, t0: float) -> DaemonStats:
        if self._down_since is not None:  # still down at exit
            stats.bus_down_s += time.perf_counter() - self._down_since
            self._down_since = None
        stats.wall_s = time.perf_counter() - t0
        stats.counters = self.ecu.counters()
        stats.chassis_counters = self.ecu.chassis_counters()
        stats.health = self.ecu.health()
        stats.not_heard = self.ecu.not_heard()
        self.notifier.stopping(sdnotify.status_line(f"{stats.mode} stopping", stats.ticks, stats.counters))
        log.info("ECU daemon stopped: %s", stats.lines()[0])
        return stats

    def _start(self, stats: DaemonStats) -> sdnotify.Watchdog:
        """READY=1 (the bus is open, the loop starts) and the loop's keep-alive (WATCHDOG=1, STATUS=)."""
        where = ", ".join((f"{name}: " if name else "") + (b.channel_info if b.channel_info != "unknown"
                                                             else type(b).__name__) for name, b in self.buses.items())
        log.info("ECU daemon serving in %s mode on %s", stats.mode, where)
        self.notifier.ready(f"{stats.mode}: serving on {where}")
        return sdnotify.Watchdog(self.notifier, stats.mode, lambda: stats.ticks, self.ecu.counters, logger=log)

    # -- lockstep -----------------------------------------------------------------------------
    def serve_lockstep(self, *, exit_on_end: bool = False, idle_timeout: float | None = None,
                       duration: float | None = None) -> DaemonStats:
        """Answer SIM_Sync frames until stopped (or END with exit_on_end, idle_timeout s of silence, or
        duration s of wall time)."""
        stats = self.stats = DaemonStats("lockstep")
        t0 = last = time.perf_counter()
        watchdog = self._start(stats)
        recv, notifiers = self._lockstep_receiver()
        try:
            while not self.stop_event.is_set():
                if duration is not None and time.perf_counter() - t0 >= duration:
                    break
                name, msg = recv(0.05)
                if isinstance(msg, Exception):
                    if self._rx_error(msg):
                        self.stop_event.wait(0.05)  # a bus that fails at once must not make us spin
                    msg = None
                watchdog.tick()
                if msg is None:
                    if idle_timeout is not None and time.perf_counter() - last > idle_timeout:
                        log.warning("no frame for %.1f s, stopping", idle_timeout)
                        break
                    continue
                last = time.perf_counter()
                self._bus_ok("receive")
                if msg.is_error_frame or msg.is_remote_frame or is_own(msg, self._own):
                    continue
                stats.frames_rx += 1
                self._count(name, "rx")
                now = self.ecu.tick * TICK_S
                self._log(msg, now, name)
                if name in self.rx_by_bus:
                    self.rx_by_bus[name](msg)
                    continue
                if not lockstep.is_sync(msg):
                    self.ecu.rx(msg)
                    continue
                tick, cmd = lockstep.decode_sync(msg)
                if cmd == lockstep.RESET:
                    self.ecu.reset()
                    stats.sessions += 1
                    self._send(lockstep.ack_message(tick, 0), 0.0, name)
                elif cmd == lockstep.STEP:
                    out = self.ecu.step()
                    here = 0
                    for m in out:
                        to = self._route(m)
                        sent = self._send(m, now, to)
                        stats.frames_tx += sent
                        here += to == name  # the ack counts what was sent on the sync's bus
                    stats.ticks += 1
                    self._send(lockstep.ack_message(tick, here), now, name)
                elif cmd == lockstep.END:
                    self._send(lockstep.ack_message(tick, 0), now, name)
                    if exit_on_end:
                        break
        finally:
            for n in notifiers:
                n.stop()
        return self._finish(stats, t0)

    def _snapshot(self, stats: DaemonStats, now: float, ticker: Ticker, latency: Durations,
                  lateness: Durations) -> dict:
        """A real-time run's report: totals since start, percentiles of the window since the last one."""
        return {"t_s": now, "ticks": stats.ticks, "frames_rx": stats.frames_rx, "frames_tx": stats.frames_tx,
                "deadline_misses": ticker.misses, "rx_undecodable": stats.rx_undecodable,
                "recv_errors": stats.recv_errors, "send_failures": stats.send_failures, "rx_overrun": stats.rx_overrun,
                "counters": self.ecu.counters(), "chassis_counters": self.ecu.chassis_counters(),
                "latency_us": latency.percentiles_us(), "lateness_us": lateness.percentiles_us()}

    def _lockstep_receiver(self):
        """recv(timeout) -> (bus, frame, receive error or None). One bus: its own recv() in this
        thread (no hand-over: the lockstep round trip is the demo's speed); several: their notifiers."""
        if len(self.buses) == 1:
            (name, bus), = self.buses.items()

            def recv_one(timeout: float):
                try:
                    return name, bus.recv(timeout=timeout)
                except (can.CanError, OSError) as exc:
                    return name, exc
            return recv_one, []
        # unbounded, but bounded by the protocol: the master has at most its window of ticks in flight
        inbox: queue.SimpleQueue = queue.SimpleQueue()
        notifiers = self._inbox(lambda bus, item: inbox.put((bus, item)))

        def recv_any(timeout: float):
            try:
                return inbox.get(timeout=timeout)
            except queue.Empty:
                return "", None
        return recv_any, notifiers

    # -- real time ----------------------------------------------------------------------------
    def serve_realtime(self, *, duration: float | None = None, report=None, report_every: float = 60.0) -> DaemonStats:
        """Tick at 2 kHz of wall clock until stopped or for duration seconds. `report(dict)`, if given,
        is called every `report_every` s with the totals so far and the window's latency and
        lateness percentiles (fixed memory: one histogram per quantity, emptied after each report)."""
        stats = self.stats = DaemonStats("realtime")
        # A receive FIFO of fixed size, like a CAN controller's: a daemon descheduled for a second must
        # not queue thousands of frames (memory that Python keeps); on overrun the oldest go, counted.
        inbox: collections.deque = collections.deque(maxlen=RX_FIFO)

        def sink(bus: str, item) -> None:
            if len(inbox) == RX_FIFO:
                stats.rx_overrun += 1
            inbox.append((time.perf_counter(), bus, item))

        notifiers = self._inbox(sink)
        ticker = Ticker(TICK_S)
        latencies = Durations()  # fixed memory: the daemon may run for weeks
        window_latency, window_lateness = Durations(), Durations()
        t0 = time.perf_counter()
        last_at = float("-inf")
        next_report = report_every
        watchdog = self._start(stats)
        ticker.start()
        try:
            while not self.stop_event.is_set():
                if duration is not None and time.perf_counter() - t0 >= duration:
                    break
                missed = ticker.wait()
                if missed:
                    self.ecu.note_deadline_miss(missed)
                now = time.perf_counter() - t0
                if report is not None:
                    window_lateness.add(ticker.late)
                    if now >= next_report:
                        next_report += report_every
                        report(self._snapshot(stats, now, ticker, window_latency, window_lateness))
                        window_latency.clear()
                        window_lateness.clear()
                pending = []
                while True:
                    try:
                        t_rx, name, msg = inbox.popleft()
                    except IndexError:
                        break
                    if isinstance(msg, Exception):
                        self._rx_error(msg)
                        continue
                    self._bus_ok("receive")
                    if msg.is_error_frame or msg.is_remote_frame or is_own(msg, self._own):
                        continue
                    stats.frames_rx += 1
                    self._count(name, "rx")
                    # when it came off the bus, not the tick's time; never before the frame logged last
                    last_at = max(t_rx - t0, last_at)
                    self._log(msg, last_at, name)
                    self.rx_by_bus.get(name, self.ecu.rx)(msg)
                    if msg.arbitration_id == self._dls_id:
                        pending.append(t_rx)
                out = self.ecu.step()
                last_at = time.perf_counter() - t0  # logged as sent
                sent = sum(self._send(m, last_at) for m in out)
                t_tx = time.perf_counter()
                if sent:
                    latencies.extend(t_tx - t for t in pending)
                    if report is not None:
                        window_latency.extend(t_tx - t for t in pending)
                stats.frames_tx += sent
                stats.ticks += 1
                watchdog.tick()
        finally:
            for n in notifiers:
                n.stop()
        stats.lateness_us = percentiles_us(ticker.lateness)
        stats.latency_us = percentiles_us(latencies)
        stats.deadline_misses = ticker.misses
        return self._finish(stats, t0)
