"""The three ways to drive a simulated car (:class:`vehest_can.sim.car.Car`) against the ECU.

1. ``run_inprocess``: car and ECU stepped together in one C loop, frames passed in memory. Fastest;
   for tests, batch runs and benchmarks.
2. ``SimMaster.run_lockstep``: the car here, the ECU daemon elsewhere on a bus; the tick's frames,
   then SIM_Sync, then wait for the ECU's frames and VEHEST_SyncAck. Identical results on any bus.
3. ``SimMaster.run_realtime``: the car on its own 2 kHz wall clock; the ECU daemon runs its own.

All three produce a ``Session``: the plant's truth per tick and every frame with its tick. On a bus
a session is kept compactly (a frame is 76 bytes: FRAME_DTYPE and its tick), or not at all
(``SimMaster(keep=False)``: counts only, for a long run whose frames go to a log file, so its memory
stays flat).
"""
from __future__ import annotations

import logging
import queue
import sys
import threading
import time
from dataclasses import dataclass, field, replace
from typing import Any

import can
import numpy as np

from ..bus import lockstep
from ..bus.bus import is_undecodable
from ..bus.frames import BUSES, FRAME_DTYPE, TICK_S, database, is_own, sent_by, to_frame, to_message
from ..bus.rt import Ticker, percentiles_us
from ..errors import BusError, VehestError
from ..native import ffi, lib
from .car import Car

log = logging.getLogger(__name__)


#: ticks per C call of run_inprocess: one second, so SecOC's upkeep runs at the rate a car on a bus keeps
INPROCESS_CHUNK = 2000
#: DBC nodes the simulated car plays (everything but the ECU)
CAR_NODES = frozenset(n.name for b in BUSES for n in database(b).nodes) - {"VEHEST"}


#: body roll beyond which a run counts as a rollover (Session.diverged_s) [rad]: 30 deg
ROLLOVER_RAD = float(np.radians(30.0))


@dataclass
class Session:
    name: str
    mode: str
    truth: np.ndarray             # (n,) the car's truth_dtype
    frames: np.ndarray            # (m,) FRAME_DTYPE, in bus order
    frame_tick: np.ndarray        # (m,) tick of each frame
    stats: dict = field(default_factory=dict)

    def diverged_s(self) -> float | None:
        """When the car left the range its plant's model holds, in seconds of simulated time (None: it
        never did): the state not finite, or a body rolled past ROLLOVER_RAD (the car is rolling over;
        no chassis model here describes that, and a multi-body one may go on integrating nonsense). The
        figures of such a run are not the estimators' alone."""
        k = left_range(self.truth)
        return None if k is None else float(k) * TICK_S

    def until(self, t_s: float) -> Session:
        """The session's first t_s seconds: its truth and the frames of those ticks."""
        k = int(round(t_s / TICK_S))
        keep = self.frame_tick < k
        return replace(self, truth=self.truth[:k], frames=self.frames[keep], frame_tick=self.frame_tick[keep])

    def messages(self):
        """The session as python-can messages, timestamped with simulated time (a SessionLog
        writes them with absolute time, direction and bus)."""
        for f, k in zip(self.frames, self.frame_tick):
            yield to_message(f, timestamp=float(k) * TICK_S)


def left_range(truth: np.ndarray) -> int | None:
    """The first tick of a truth record at which the car left the range its plant's model holds (None:
    it never did): the state not finite, or the body rolled past ROLLOVER_RAD."""
    ok = _finite_rows(truth)
    if truth.dtype.names and "phi" in truth.dtype.names:
        ok &= np.abs(truth["phi"]) <= ROLLOVER_RAD
    bad = np.flatnonzero(~ok)
    return int(bad[0]) if bad.size else None


def _finite_rows(a: np.ndarray) -> np.ndarray:
    """(n,) bool: every floating-point field of each record finite (nested records included)."""
    ok = np.ones(len(a), dtype=bool)
    for name in a.dtype.names or ():
        v = a[name]
        if v.dtype.names:
            ok &= _finite_rows(v.reshape(-1)).reshape(len(a), -1).all(axis=1)
        elif v.dtype.kind == "f":
            ok &= np.isfinite(v.reshape(len(a), -1)).all(axis=1)
    return ok


def run_inprocess(car: Car, ecu) -> Session:
    """Mode 1: car and ECU in one C loop (vh_lockstep_run), a second of the drive per call; between
    calls the ECU's counters are polled (a remote ECU refreshes its mirror) and the car's SecOC upkeep
    runs. `ecu` is a
    :class:`vehest_can.systems.ecu.Ecu` (the firmware with every system's app)."""
    car.reset()
    n = car.n
    raw = np.zeros(n, dtype=car.c_truth_dtype)
    per_tick = car.c.max_tx + lib.VH_ECU_MAX_TX
    buf = np.zeros(INPROCESS_CHUNK * per_tick, dtype=FRAME_DTYPE)
    buf_ticks = np.zeros(len(buf), dtype=np.uint32)
    c_buf = ffi.cast("vh_frame_t *", ffi.from_buffer(buf))
    c_ticks = ffi.cast("uint32_t *", ffi.from_buffer(buf_ticks))
    frames, ticks = [], []
    t0 = time.perf_counter()
    for k0 in range(0, n, INPROCESS_CHUNK):
        m = min(INPROCESS_CHUNK, n - k0)
        got = lib.vh_lockstep_run(car.c, ecu.c, k0, m, ffi.from_buffer(raw[k0:]), c_buf, c_ticks, len(buf))
        frames.append(buf[:got].copy())
        ticks.append(buf_ticks[:got].copy())
        ecu.poll_counters()
        if k0 + m < n:
            car.maintain()
    wall = time.perf_counter() - t0
    return Session(car.name, "inprocess", car.truths(raw), np.concatenate(frames), np.concatenate(ticks),
                   stats={"wall_s": wall, "realtime_factor": n * TICK_S / wall if wall else float("inf"),
                          "counters": ecu.counters(), "chassis_counters": ecu.chassis_counters(),
                          "health": ecu.health()})


class Recording:
    """A session's frames and their ticks, in chunks of FRAME_DTYPE: 76 bytes a frame where a kept
    ``can.Message`` and its list entry took ~300, and no copy at the end."""

    CHUNK = 1 << 14

    def __init__(self) -> None:
        self._frames: list[np.ndarray] = []
        self._ticks: list[np.ndarray] = []
        self._c: Any = None  # the last chunk as vh_frame_t[]
        self._i = self.CHUNK
        self.n = 0

    def add(self, msg: can.Message, tick: int) -> None:
        if self._i == self.CHUNK:
            self._frames.append(np.zeros(self.CHUNK, FRAME_DTYPE))
            self._ticks.append(np.zeros(self.CHUNK, np.uint32))
            self._c = ffi.from_buffer("vh_frame_t[]", self._frames[-1])
            self._i = 0
        to_frame(msg, self._c[self._i])
        self._ticks[-1][self._i] = tick
        self._i += 1
        self.n += 1

    def arrays(self) -> tuple[np.ndarray, np.ndarray]:
        """(frames, ticks) so far."""
        if not self._frames:
            return np.zeros(0, FRAME_DTYPE), np.zeros(0, np.uint32)
        last = slice(0, self._i)
        return (np.concatenate([*self._frames[:-1], self._frames[-1][last]]),
                np.concatenate([*self._ticks[:-1], self._ticks[-1][last]]))


class SimMaster:
    """The car on a bus: lockstep master or real-time node. Records every frame it sees or sends
    (with ``keep=False`` it counts them: a long run's memory stays flat, its frames go to the log)."""

    def __init__(self, bus: can.BusABC, car: Car, *, log_writer: can.Listener | None = None,
                 ack_timeout: float = 2.0, progress=None, keep: bool = True, peer=None):
        """`car`: a :class:`vehest_can.sim.car.Car`.
        `peer`: None, or a callable that says why the ECU cannot answer (its process ended: a text with
        its last lines) or None while it can; a wait for the ECU then ends as soon as it cannot.
        `log_writer` gets every frame with its session time in ``timestamp`` (lockstep: the tick's
        simulated time, tick * TICK_S; real time: the wall clock since the start, when the frame was
        sent or received): a :class:`vehest_can.bus.log.SessionLog` turns that into absolute time,
        direction and bus.
        `keep`: the session holds the plant's truth and every frame; without, it holds neither
        (empty arrays; ``stats`` has the counts ``ticks`` and ``frames``)."""
        self.bus = bus
        self.car = car
        self.log_writer = log_writer
        self.ack_timeout = ack_timeout
        self.progress = progress
        self.keep = keep
        self.peer = peer
        self.stop_event = threading.Event()
        self._recording = Recording()
        self._frames_seen = 0
        self._own = sent_by(CAR_NODES)
        self._ecu = sent_by({"VEHEST"})
        self.foreign = 0  # frames from neither the car nor the ECU: not part of the session
        self._last_at = float("-inf")

    def _record(self, msg: can.Message, tick: int, at: float | None = None) -> None:
        self._frames_seen += 1
        if self.keep:
            self._recording.add(msg, tick)
        self._log(msg, tick, at)

    def _log(self, msg: can.Message, tick: int, at: float | None = None) -> None:
        """Into the log only (sync frames: on the bus, but not part of the car/ECU session), at session
        time `at` (real time: seconds of wall clock since the start), else at the tick's simulated time."""
        if self.log_writer is not None:
            if at is not None:  # never before the frame logged last: a frame that arrived while this
                at = self._last_at = max(at, self._last_at)  # node sent is logged after, at the send's time
            msg.timestamp = tick * TICK_S if at is None else at
            self.log_writer.on_message_received(msg)

    def _session(self, mode: str, truth: np.ndarray, ticks: int, stats: dict) -> Session:
        frames, frame_ticks = self._recording.arrays()
        return Session(self.car.name, mode, truth, frames, frame_ticks,
                       {"ticks": ticks, "frames": self._frames_seen, **stats})

    def _truth(self, n: int) -> np.ndarray:
        """The plant's truth per tick, to fill (none when the session is not kept)."""
        return np.zeros(n if self.keep else 0, dtype=self.car.truth_dtype)

    def _await_ack(self, tick: int, deadline_s: float) -> list[can.Message]:
        """ECU frames of this tick, up to and excluding its ack."""
        got: list[can.Message] = []
        end = time.monotonic() + deadline_s
        while True:
            left = end - time.monotonic()
            # in slices of at most 1 s, to notice an ECU process that ended
            msg = self.bus.recv(timeout=max(0.0, min(left, 1.0))) if left > 0 else None
            if msg is None:
                why = self.peer() if self.peer is not None else None
                if why:
                    raise BusError(f"lockstep: tick {tick}: {why}")
                if time.monotonic() < end:
                    continue
                raise BusError(f"lockstep: no VEHEST_SyncAck for tick {tick} within {deadline_s:.1f} s "
                               f"(is the ECU daemon running on this bus?)")
            if is_own(msg, self._own):
                continue
            if not is_own(msg, self._ecu):
                self.foreign += 1
                continue
            if lockstep.is_ack(msg):
                ack_tick, count = lockstep.decode_ack(msg)
                if ack_tick != tick:
                    continue  # a late ack of an earlier handshake
                if count != len(got):
                    raise BusError(f"lockstep: tick {tick}: ECU sent {count} frames, {len(got)} arrived")
                return got
            got.append(msg)

    def connect(self, timeout_s: float = 10.0) -> None:
        """RESET handshake: the ECU starts from scratch; retried every 0.2 s for up to `timeout_s` while
        the daemon is starting (a line on stderr says so after the first second).

        Each attempt carries its own tick number, above any STEP tick, so a late answer to an
        earlier attempt is never taken for the answer to a later one (or to tick 0)."""
        t0 = time.monotonic()
        said = False
        attempt = 0
        while True:
            nonce = lockstep.RESET_TICK_BASE + attempt
            reset = lockstep.sync_message(nonce, lockstep.RESET)
            self.bus.send(reset)
            try:
                self._await_ack(nonce, 0.2)
                self._log(reset, 0)
                return
            except BusError as exc:
                if self.peer is not None and (why := self.peer()):
                    raise BusError(f"lockstep: {why}") from exc
            attempt += 1
            waited = time.monotonic() - t0
            if waited >= timeout_s:
                raise BusError(f"lockstep: the ECU daemon did not answer RESET within {timeout_s:g} s "
                               "(is it running on this bus?)")
            if waited >= 1.0 and not said:
                print(f"waiting for the ECU daemon to answer (up to {timeout_s:g} s) ...", file=sys.stderr, flush=True)
                said = True

    def run_lockstep(self, *, end: bool = True, window: int = 16, connect_timeout_s: float = 10.0) -> Session:
        """Mode 2. Deterministic: the ECU sees exactly each tick's frames, whatever the bus.

        Up to `window` ticks are in flight: the ECU steps on each SIM_Sync in the order the
        frames were sent, so its output does not depend on the window; the window only saves
        round trips (and bounds what a lossy bus like udp_multicast has to buffer)."""
        self.car.reset()
        self.connect(connect_timeout_s)
        n = self.car.n
        closed = self.car.closed
        if closed:  # the car acts on the ECU's frames of each tick before its next: one tick in flight
            window = 1
        truth = self._truth(n)
        sent: dict[int, list] = {}
        t0 = time.perf_counter()
        k_sent = k_done = 0
        while k_done < n:
            while k_sent < n and k_sent - k_done < max(1, window) and not self.stop_event.is_set():
                sent[k_sent] = [to_message(f) for f in self.car.tick(k_sent)]
                for msg in sent[k_sent]:
                    self.bus.send(msg)
                self.bus.send(lockstep.sync_message(k_sent))
                if self.keep:
                    truth[k_sent] = self.car.truth()
                k_sent += 1
            if k_done == k_sent:  # stopped
                break
            answer = self._await_ack(k_done, self.ack_timeout)
            for msg in sent.pop(k_done):  # recorded in tick order: car frames, then the ECU's
                self._record(msg, k_done)
            self._log(lockstep.sync_message(k_done), k_done)
            for msg in answer:
                self._record(msg, k_done)
                if closed:
                    self.car.rx(msg)
            k_done += 1
            if self.progress and k_done % 200 == 0:
                self.progress(k_done, n)
        if end:
            self.bus.send(lockstep.sync_message(n, lockstep.END))
        wall = time.perf_counter() - t0
        return self._session("lockstep", truth[:k_done], k_done,
                             {"wall_s": wall, "realtime_factor": k_done * TICK_S / wall})

    def run_realtime(self, *, settle_s: float = 0.2) -> Session:
        """Mode 3: send the car's frames on a 2 kHz wall clock; record what the ECU publishes. The log
        has wall-clock times (when a frame was sent, or taken off the bus), not the tick's: a machine
        too slow for 2 kHz stretches the run, and the log shows how long it really took."""
        self.car.reset()
        n = self.car.n
        truth = self._truth(n)
        inbox: queue.SimpleQueue = queue.SimpleQueue()

        errors = {"rx_undecodable": 0, "recv_errors": 0}
        stop_event = self.stop_event

        class Inbox(can.Listener):
            def on_message_received(inner, msg: can.Message) -> None:  # noqa: N805
                if not is_own(msg, self._own):
                    inbox.put((time.perf_counter() - t0, msg))

            def on_error(inner, exc: Exception) -> None:  # noqa: N805
                # Counted; the notifier goes on receiving (without this its thread would die and
                # the car would stop hearing the ECU). A failing bus backs off a little.
                if is_undecodable(exc):
                    errors["rx_undecodable"] += 1
                else:
                    errors["recv_errors"] += 1
                    stop_event.wait(0.005)

        def take(k: int, into: list) -> None:
            while not inbox.empty():
                at, msg = inbox.get_nowait()
                self._record(msg, k, at)
                into.append(msg)

        closed = self.car.closed
        t0 = time.perf_counter()
        notifier = can.Notifier(self.bus, [Inbox()], timeout=0.005)
        ticker = Ticker(TICK_S)
        sent = done = 0
        ticker.start()
        try:
            for k in range(n):
                if self.stop_event.is_set():
                    break
                ticker.wait()
                # what arrived before each of this tick's frames is logged before it (a log in time
                # order); it is applied after this tick, with what arrives while it is sent, as always
                arrived: list[can.Message] = []
                for f in self.car.tick(k):
                    take(k, arrived)
                    msg = to_message(f)
                    try:
                        self.bus.send(msg)
                    except can.CanError as exc:
                        raise BusError(f"send failed at tick {k}: {exc}") from exc
                    sent += 1
                    self._record(msg, k, time.perf_counter() - t0)
                if self.keep:
                    truth[k] = self.car.truth()
                done = k + 1
                take(k, arrived)
                if closed:  # applied from the car's next tick (zero-order hold)
                    for msg in arrived:
                        self.car.rx(msg)
                if self.progress and k % 200 == 0:
                    self.progress(k, n)
            time.sleep(settle_s)  # the ECU's answers to the last ticks
            take(max(done - 1, 0), [])
        finally:
            notifier.stop()
        wall = time.perf_counter() - t0
        return self._session("realtime", truth[:done], done, {
            "wall_s": wall, "frames_sent": sent, "deadline_misses": ticker.misses,
            "lateness_us": percentiles_us(ticker.lateness), **errors,
        })


__all__ = ["Session", "run_inprocess", "SimMaster", "VehestError"]
