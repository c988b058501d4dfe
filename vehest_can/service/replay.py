"""Run a recorded log (candump -L, or anything python-can's LogReader reads) through the ECU offline.

Ticks come from the log's SIM_Sync frames when it has them (a lockstep session: the replay then
reproduces the ECU's frames bit for bit), otherwise from its timestamps: a tick every 500 µs from
the first frame, each frame handed in before the first tick at or after its timestamp. A gap of
more than `max_gap_s` (1 s) between frames is not stepped through tick by tick: the ECU steps
`max_gap_s` of idle ticks (every input times out, as it would), then the log's clock jumps to the
next frame (counted in ``idle_ticks_skipped``). Time that goes backwards in the file is counted
(``backwards``, the largest step ``backward_max_s``); a step back longer than `max_gap_s` (a logger's
clock set back, files joined) is a jump (``jumps_back``): the log's clock goes on from the frame
before it, instead of sorting the later frames before the earlier ones and stepping the difference
as a forward gap.

The log is read and handed to the C ECU in batches (:func:`vehest_can.bus.log.iter_log_arrays`:
candump -L parsed in C; ``vh_replay_run``: a batch of frames and ticks per call), and the ECU's
frames are compared with the ones in the log as they come, so a file of any length replays in
bounded memory. :func:`replay` takes python-can messages and keeps every frame (for tests and
small logs); :func:`replay_file` streams a file.
"""
from __future__ import annotations

import queue
import threading
import time
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path

import can
import numpy as np

from ..bus import lockstep
from ..bus.formats import MAX_GAP_S
from ..bus.frames import FRAME_DTYPE, TICK_S, sent_by, to_message
from ..bus.log import SessionLog, iter_log, iter_log_arrays, messages_to_arrays
from ..native import ffi, lib
from ..systems.ecu import Ecu
from .estimates import EstimateTable

# What the ECU core transmits (the lockstep acknowledge is the daemon's, not the core's)
ECU_SENT = sent_by({"VEHEST"})
ECU_TX = ECU_SENT - {lockstep.ACK.frame_id}
#: standard ID -> sent by the ECU core (a table lookup: np.isin sorts each batch)
_IS_ECU_TX = np.zeros(0x800, dtype=bool)
_IS_ECU_TX[sorted(ECU_TX)] = True
#: ECU frames held for comparison on the side that is ahead; beyond this the two streams are not
#: aligned (e.g. a log that has none of the ECU's frames) and are not compared further
COMPARE_WINDOW = 1 << 20
_OUT_CAP = 1 << 16
_EXT = lib.VH_FRAME_EXT


@dataclass
class ReplayResult:
    frames_in: int
    ticks: int
    produced: list[can.Message]   # every ECU frame of the replay: kept by replay(), not by replay_file()
    logged: list[can.Message]     # the ECU frames in the log: likewise
    counters: dict
    paced_by: str
    n_produced: int = 0
    n_logged: int = 0
    first_mismatch: int | None = None
    idle_ticks_skipped: int = 0
    gaps: int = 0
    out_of_order: int = 0         # frames older than one before them across batches (handed in late)
    backwards: int = 0            # frames with an earlier timestamp than the frame before them in the file
    backward_max_s: float = 0.0   # ... the largest such step back
    jumps_back: int = 0           # steps back longer than max_gap_s: the clock went on from the frame before
    stats: dict = field(default_factory=dict)

    @property
    def identical(self) -> bool | None:
        """Equal to the ECU frames in the log (None when the log has none to compare)."""
        if not self.n_logged:
            return None
        return self.n_logged == self.n_produced and self.first_mismatch is None

    def first_difference(self) -> int | None:
        if self.first_mismatch is not None:
            return self.first_mismatch
        return None if self.n_logged == self.n_produced else min(self.n_logged, self.n_produced)


# FRAME_DTYPE as 9 words: id, len, flags and data[0:2] in the first, data[2:64] and the struct's
# padding in the rest; what same_frame compares is every byte but the BRS flag and the padding
# (payload bytes past len are zero on both sides: the C reader's, messages_to_arrays', the ECU's)
_MASK = np.array([~np.uint64(lib.VH_FRAME_BRS << 40)] + [np.uint64(0xFFFFFFFFFFFFFFFF)] * 7
                 + [np.uint64(0x0000FFFFFFFFFFFF)], dtype=np.uint64)
assert FRAME_DTYPE.itemsize == 72 and FRAME_DTYPE.fields["flags"][1] == 5 and FRAME_DTYPE.fields["data"][1] == 6


def _same(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Element-wise same_frame of two FRAME_DTYPE arrays (ID, ID type, FD, payload)."""
    wa = np.ascontiguousarray(a).view(np.uint64).reshape(-1, 9)
    wb = np.ascontiguousarray(b).view(np.uint64).reshape(-1, 9)
    return np.logical_not(((wa ^ wb) & _MASK).any(axis=1))


class Replayer:
    """Batches of a log in (:meth:`feed`), the result out (:meth:`finish`)."""

    def __init__(self, ecu: Ecu | None = None, *, keep: bool = False, writer: can.Listener | None = None,
                 table: EstimateTable | None = None, max_gap_s: float = MAX_GAP_S):
        self.ecu = ecu or Ecu()
        self.keep = keep
        self.writer = writer
        self.table = table
        self.max_gap_s = max_gap_s
        self.max_idle = max(1, int(round(max_gap_s / TICK_S)))
        self.paced_by: str | None = None
        self.frames_in = 0
        self.first_ts: float | None = None
        self.t0: float | None = None  # timestamps: the log's clock starts at its first input
        self.k = 0                    # timestamps: ticks of the log's clock so far
        self.inputs = 0
        self.skipped = self.gaps = self.out_of_order = 0
        self.backwards = self.jumps_back = 0
        self.backward_max_s = 0.0
        self._last_ts: float | None = None  # the log's last timestamp, in file order
        self._shift = 0.0             # s added to the log's time after jumps back
        self.n_logged = self.n_produced = self._compared = 0
        self.first_mismatch: int | None = None
        self._aligned = True          # False once one side ran COMPARE_WINDOW frames ahead
        self._compared_until = 0      # ... and how far the comparison got then
        self._qlog = np.zeros(0, FRAME_DTYPE)
        self._qprod = np.zeros(0, FRAME_DTYPE)
        self.produced: list[can.Message] = []
        self.logged: list[can.Message] = []
        self._out = np.zeros(_OUT_CAP, FRAME_DTYPE)
        self._out_event = np.zeros(_OUT_CAP, np.uint32)
        self._out_step = np.zeros(_OUT_CAP, np.uint32)
        self._c_out = (ffi.cast("vh_frame_t *", ffi.from_buffer(self._out)),
                       ffi.cast("uint32_t *", ffi.from_buffer(self._out_event)),
                       ffi.cast("uint32_t *", ffi.from_buffer(self._out_step)))
        self._pos = ffi.new("vh_replay_pos_t *")

    # -- comparison ---------------------------------------------------------------------------
    def _compare(self, logged: np.ndarray | None = None, produced: np.ndarray | None = None) -> None:
        if logged is not None:
            self.n_logged += len(logged)
            if self._aligned:
                self._qlog = np.concatenate((self._qlog, logged)) if len(self._qlog) else logged
        if produced is not None:
            self.n_produced += len(produced)
            if self._aligned:
                self._qprod = np.concatenate((self._qprod, produced)) if len(self._qprod) else produced
        if not self._aligned:
            return
        m = min(len(self._qlog), len(self._qprod))
        if m:
            if self.first_mismatch is None:
                eq = _same(self._qlog[:m], self._qprod[:m])
                if not eq.all():
                    self.first_mismatch = self._compared + int(np.argmin(eq))
            self._compared += m
            self._qlog, self._qprod = self._qlog[m:], self._qprod[m:]
        if max(len(self._qlog), len(self._qprod)) > COMPARE_WINDOW:
            self._aligned = False  # one side ran far ahead: nothing more to compare
            self._compared_until = self._compared
            self._qlog = self._qprod = np.zeros(0, FRAME_DTYPE)

    # -- the ECU ------------------------------------------------------------------------------
    def _run(self, frames: np.ndarray, op: np.ndarray, steps: np.ndarray, when) -> None:
        """Events through the C ECU; `when(event, step)` gives the tick and the log time of its frames."""
        n = len(op)
        frames = np.ascontiguousarray(frames)
        op = np.ascontiguousarray(op, dtype=np.uint8)
        steps = np.ascontiguousarray(steps, dtype=np.uint32)
        c_in = ffi.cast("vh_frame_t *", ffi.from_buffer(frames)) if len(frames) else ffi.NULL
        pos = self._pos
        pos.event, pos.step = 0, 0
        # an ECU that is not this process's C (the emulated one, vehest_can.service.pil) runs the batch itself
        own = getattr(self.ecu, "replay_run", None)
        while pos.event < n:
            if own is not None:
                got = own(frames, op, steps, n, pos, self._out, self._out_event, self._out_step, _OUT_CAP)
            else:
                got = lib.vh_replay_run(self.ecu.c, c_in, ffi.cast("uint8_t *", ffi.from_buffer(op)),
                                        ffi.cast("uint32_t *", ffi.from_buffer(steps)), n, pos, *self._c_out, _OUT_CAP)
            if got:
                out = self._out[:got].copy()
                self._produced(out, *when(self._out_event[:got], self._out_step[:got]))

    def _produced(self, out: np.ndarray, ticks: np.ndarray, times: np.ndarray) -> None:
        self._compare(produced=out)
        if self.table is not None:
            self.table.write(out, ticks, times)
        if self.keep or self.writer is not None:
            for f, k in zip(out, ticks):
                msg = to_message(f, timestamp=float(k) * TICK_S)
                if self.keep:
                    self.produced.append(msg)
                if self.writer is not None:
                    self.writer.on_message_received(msg)

    # -- a batch of the log -------------------------------------------------------------------
    def feed(self, frames: np.ndarray, ts: np.ndarray) -> None:
        self.frames_in += len(frames)
        if not len(frames):
            return
        if self.first_ts is None:
            self.first_ts = float(ts[0])
            if isinstance(self.writer, SessionLog) and self.writer.epoch is None:
                self.writer.epoch = self.first_ts  # the replay's frames on the log's own time base
        clock = self._clock(ts)
        ids = frames["id"]
        ext = (frames["flags"] & _EXT) != 0
        is_ecu = _IS_ECU_TX[ids & 0x7FF] & ~ext  # a standard frame's ID is <= 0x7FF
        if is_ecu.any():
            at = np.flatnonzero(is_ecu)
            logged = frames.take(at)  # take, not a boolean index: ~20x faster on a structured array
            self._compare(logged=logged)
            if self.keep:
                self.logged += [to_message(f, timestamp=float(t)) for f, t in zip(logged, ts[at])]
        if is_ecu.all():
            return
        self.inputs += int(len(frames) - np.count_nonzero(is_ecu))
        sync = ((ids == lockstep.SYNC.frame_id) & ~ext & (frames["len"] == lockstep.SYNC.length))
        if self.paced_by is None:
            self.paced_by = "sync" if sync.any() else "timestamps"
        if self.paced_by == "sync":
            self._feed_sync(frames, ts, sync, is_ecu)
        else:
            at = np.flatnonzero(~is_ecu)
            self._feed_timestamps(frames.take(at), clock[at])

    def _clock(self, ts: np.ndarray) -> np.ndarray:
        """The log's time, steps back counted (in file order, every frame); after a step back longer
        than max_gap_s the time goes on from the frame before it (what timestamp pacing uses)."""
        prev = np.empty_like(ts)
        prev[0] = ts[0] if self._last_ts is None else self._last_ts
        prev[1:] = ts[:-1]
        step = ts - prev
        self._last_ts = float(ts[-1])
        back = step < 0
        if not back.any():
            return ts + self._shift if self._shift else ts
        self.backwards += int(np.count_nonzero(back))
        self.backward_max_s = max(self.backward_max_s, float(-step.min()))
        jump = step < -self.max_gap_s
        self.jumps_back += int(np.count_nonzero(jump))
        shift = self._shift + np.cumsum(np.where(jump, -step, 0.0))
        self._shift = float(shift[-1])
        return ts + shift

    def _feed_sync(self, frames: np.ndarray, ts: np.ndarray, sync: np.ndarray, is_ecu: np.ndarray) -> None:
        """In log order; the ECU frames of the log are events that do nothing. The log time of a
        tick's frames is that of the SIM_Sync frame that stepped it."""
        tick = np.ascontiguousarray(frames["data"][:, :4]).view("<u4").ravel()
        cmd = frames["data"][:, 4]
        op = np.where(sync, np.where(cmd == lockstep.RESET, lib.VH_REPLAY_RESET, lib.VH_REPLAY_NONE),
                      np.where(is_ecu, lib.VH_REPLAY_NONE, lib.VH_REPLAY_RX)).astype(np.uint8)
        steps = (sync & (cmd == lockstep.STEP)).astype(np.uint32)
        self._run(frames, op, steps, lambda ev, _st: (tick[ev].astype(np.float64), ts[ev]))

    def _feed_timestamps(self, inp: np.ndarray, its: np.ndarray) -> None:
        order = np.argsort(its, kind="stable")
        inp, its = inp.take(order), its[order]
        if self.t0 is None:
            self.t0 = float(its[0])
        t0 = self.t0
        # the first tick k with t0 + k * TICK_S >= t - 1e-7, in the very float operations of the loop
        # `while t0 + k * TICK_S < t - 1e-7: step; k += 1`
        x = its - 1e-7
        k = np.maximum(np.ceil((x - t0) / TICK_S), 0).astype(np.int64)
        k += (t0 + k * TICK_S < x)
        k -= (k > 0) & (t0 + (k - 1) * TICK_S >= x)
        self.out_of_order += int(np.count_nonzero(k < self.k))
        k = np.maximum.accumulate(np.maximum(k, self.k))
        before = np.concatenate(([self.k], k[:-1]))
        full = k - before
        steps = np.minimum(full, self.max_idle)
        self.gaps += int(np.count_nonzero(full > self.max_idle))
        self.skipped += int((full - steps).sum())
        self.k = int(k[-1])
        op = np.full(len(inp), lib.VH_REPLAY_RX, dtype=np.uint8)
        self._run(inp, op, steps, lambda ev, st: self._ticks_and_times(before[ev] + st))

    def _ticks_and_times(self, k: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Ticks of the log's clock and their times on it (a timestamp-paced log)."""
        assert self.t0 is not None
        k = np.asarray(k, dtype=np.float64)
        return k, self.t0 + k * TICK_S

    def finish(self) -> ReplayResult:
        if self.paced_by == "timestamps":  # the tick of the last frame
            k = self.k
            self._run(np.zeros(1, FRAME_DTYPE), np.zeros(1, np.uint8), np.ones(1, np.uint32),
                      lambda ev, st: self._ticks_and_times(np.full(len(ev), k)))
        if self._aligned:
            self._compare()
        elif self.first_mismatch is None:
            self.first_mismatch = self._compared_until
        return ReplayResult(
            self.frames_in, self.ecu.tick, self.produced, self.logged, self.ecu.counters(), self.paced_by or "timestamps",
            n_produced=self.n_produced, n_logged=self.n_logged, first_mismatch=self.first_mismatch,
            idle_ticks_skipped=self.skipped, gaps=self.gaps, out_of_order=self.out_of_order,
            backwards=self.backwards, backward_max_s=self.backward_max_s, jumps_back=self.jumps_back,
        )


def replay(messages: list[can.Message], ecu: Ecu | None = None, *, max_gap_s: float = MAX_GAP_S) -> ReplayResult:
    """Replay python-can messages; the result keeps every ECU frame produced and logged."""
    r = Replayer(ecu, keep=True, max_gap_s=max_gap_s)
    r.feed(*messages_to_arrays(messages))
    r.frames_in = len(messages)
    return r.finish()


def _read_ahead(batches: Iterator, depth: int = 2) -> Iterator:
    """`batches` read by a thread of its own, up to `depth` batches ahead: the C parser (which, like
    every cffi call, releases the GIL) reads the next batch while the ECU runs this one. A reader's
    error is raised here."""
    q: queue.Queue = queue.Queue(maxsize=depth)
    stop = threading.Event()
    end = object()

    def put(item) -> bool:
        while not stop.is_set():
            try:
                q.put(item, timeout=0.1)
                return True
            except queue.Full:
                continue
        return False

    def read() -> None:
        try:
            for item in batches:
                if not put(item):
                    return
            put(end)
        except BaseException as exc:  # noqa: BLE001 - handed to the consumer, which raises it
            put(exc)
        finally:
            close = getattr(batches, "close", None)
            if close is not None:
                close()

    reader = threading.Thread(target=read, name="replay-reader", daemon=True)
    reader.start()
    try:
        while True:
            item = q.get()
            if item is end:
                return
            if isinstance(item, BaseException):
                raise item
            yield item
    finally:
        stop.set()
        reader.join()


def replay_file(path: str | Path, ecu: Ecu | None = None, *, writer: can.Listener | None = None,
                table: EstimateTable | None = None, max_gap_s: float = MAX_GAP_S, progress=None) -> ReplayResult:
    """Replay a log file in bounded memory (the result keeps counts, not frames); `writer` gets
    the ECU's frames with their session time, `table` their decoded signals with the log's time.
    The log is read up to two batches ahead by a thread of its own (three batches in memory more)."""
    r = Replayer(ecu, writer=writer, table=table, max_gap_s=max_gap_s)
    depth = 2  # batches read ahead; buffers: those, the one being read and the one being replayed
    for frames, ts in _read_ahead(iter_log_arrays(path, progress=progress, copy=False, buffers=depth + 2), depth):
        r.feed(frames, ts)
    return r.finish()


@dataclass
class PlayResult:
    sent: int
    not_sent: int        # the ECU's own frames in the log (the ECU on the bus sends its own)
    send_failures: int   # frames the bus refused (counted, not retried)
    gaps: int            # gaps longer than max_gap_s, shortened to it
    late_max_s: float    # the furthest behind its recorded time a frame was sent
    seconds: float
    backwards: int = 0   # frames with an earlier timestamp than the frame before them in the file
    backward_max_s: float = 0.0  # ... the largest such step back
    jumps_back: int = 0  # steps back longer than max_gap_s: the pace went on from the frame before


def play(path: str | Path, bus: can.BusABC, *, max_gap_s: float = MAX_GAP_S, stop: threading.Event | None = None,
         clock=time.perf_counter, sleep=time.sleep) -> PlayResult:
    """Send a log's frames onto `bus` at their recorded pace, like can-utils' canplayer or
    python-can's ``can.player``, so that an ECU on that bus runs on them. The ECU's own frames
    (VEHEST_*) are not sent: the ECU on the bus sends its own. The schedule is absolute (the
    start plus the frame's time in the log), so one late frame does not delay the rest; a gap
    longer than `max_gap_s` is shortened to it, as the offline replay does not step it either; a
    step back in time longer than `max_gap_s` is counted and the pace goes on from the frame before
    (a shorter one: the frame goes at once), as the offline replay's clock does."""
    sent = not_sent = failures = gaps = backwards = jumps_back = 0
    late = back_max = 0.0
    start = t0 = last = prev = shift = 0.0
    first = True
    t_start = clock()
    for m in iter_log(path):
        if stop is not None and stop.is_set():
            break
        if first:
            start, t0, last, prev, first = clock(), m.timestamp, m.timestamp, m.timestamp, False
        if m.timestamp < prev:  # counted over every frame in file order, as the offline replay does
            backwards += 1
            back_max = max(back_max, prev - m.timestamp)
            if prev - m.timestamp > max_gap_s:  # the log's clock set back: go on from the frame before
                jumps_back += 1
                shift -= prev - m.timestamp
                last = m.timestamp
        prev = m.timestamp
        if not m.is_extended_id and m.arbitration_id in ECU_SENT:
            not_sent += 1
            continue
        if m.timestamp - last > max_gap_s:
            shift += m.timestamp - last - max_gap_s
            gaps += 1
        last = max(last, m.timestamp)  # a frame older than the one before goes at once
        delay = start + (m.timestamp - t0 - shift) - clock()
        if delay > 0:
            sleep(delay)
        else:
            late = max(late, -delay)
        m.channel = None  # the log's bus name is not the bus it is played on
        try:
            bus.send(m)
            sent += 1
        except can.CanError:
            failures += 1
    return PlayResult(sent, not_sent, failures, gaps, late, clock() - t_start, backwards, back_max, jumps_back)
