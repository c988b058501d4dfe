"""A bus that behaves like a wire: bit-rate-limited serialisation, arbitration, latency, jitter, faults.

vcan, ``virtual`` and ``udp_multicast`` deliver a frame the moment it is sent. :class:`FaultBus` wraps any
python-can bus and puts a model of the wire between ``send()`` and the inner bus:

* each frame passes the node's :class:`~vehest_can.faults.injector.FaultInjector` (drop, corrupt, delay, ...);
* it waits in the node's transmit queue (at most ``tx_queue`` frames, the Linux default ``txqueuelen`` of
  a CAN device is 10; a full queue discards the new frame and counts it) until it is ready (latency, jitter);
* frames leave one after another, each occupying the wire for its time from
  :func:`vehest_can.bus.busload.frame_bits` at the nominal / data bit rate. ``stuffing="worst"`` (default)
  counts the most stuff bits the frame can need, as ``vehest-can busload`` does for its worst case;
  ``"nominal"`` counts none (busload's nominal figure). The worst case is the default because a schedule
  that fits with it fits on a real bus whatever the payload;
* when the wire falls idle and several frames are ready, the lowest arbitration ID goes first (a
  standard ID before an extended one with the same 11 base bits), as CAN arbitration decides;
* at the end of its wire time a frame is handed to the inner bus.

Several FaultBus instances in one process may share a :class:`Wire`: then they arbitrate against each
other like nodes on one cable. A wire measures what it carried (busy time per frame ID), so the bus
load a run produced can be compared with ``vehest-can busload``.

:class:`WireModel` is the same wire without a clock: the in-process fault runs drive it in simulated
time. ``recv()`` passes straight through to the inner bus: faults act where frames are sent.
"""
from __future__ import annotations

import logging
import threading
import time
from collections.abc import Hashable
from dataclasses import dataclass
from typing import Any, NamedTuple

import can

from ..bus.busload import fd_length, frame_bits, wire_time_us
from ..errors import ConfigError
from .injector import FaultInjector, flood_message
from .spec import FaultSpec

log = logging.getLogger(__name__)

EXT_FLAG = 0x8000_0000  # key of an extended ID in the statistics (SocketCAN's CAN_EFF_FLAG)


def frame_key(msg: can.Message) -> int:
    return msg.arbitration_id | (EXT_FLAG if msg.is_extended_id else 0)


def arbitration_key(msg: can.Message) -> tuple[int, int, int]:
    """Order of winning arbitration: base ID, then standard (dominant RTR/IDE) before extended."""
    if msg.is_extended_id:
        return msg.arbitration_id >> 18, 1, msg.arbitration_id & 0x3FFFF
    return msg.arbitration_id, 0, 0


class Transmission(NamedTuple):
    start: float
    end: float
    node: Any                     # the sender: a node name, or the FaultBus that delivers it
    msg: can.Message


class WireModel:
    """The wire in any time base (seconds): submit frames with their ready times, ``advance`` the clock.

    Deterministic: the same submissions give the same transmissions.
    """

    def __init__(self, bitrate: int = 500_000, data_bitrate: int | None = 4_000_000, *,
                 stuffing: str = "worst", tx_queue: int = 10, tx_policy: str = "fifo"):
        if tx_policy not in ("fifo", "latest"):
            raise ConfigError(f"tx_policy must be 'fifo' or 'latest', not {tx_policy!r}")
        if stuffing not in ("worst", "nominal"):
            raise ConfigError(f"stuffing must be 'worst' or 'nominal', not {stuffing!r}")
        if not bitrate or bitrate <= 0:
            raise ConfigError(f"bit rate must be positive, not {bitrate}")
        if data_bitrate is not None and data_bitrate < bitrate:
            raise ConfigError(f"data bit rate {data_bitrate} is lower than the bit rate {bitrate}")
        if tx_queue < 1:
            raise ConfigError(f"tx_queue must be at least 1 frame, not {tx_queue}")
        self.bitrate = bitrate
        self.data_bitrate = data_bitrate
        self.stuffing = stuffing
        self.tx_queue = tx_queue
        self.tx_policy = tx_policy
        self._times: dict[tuple, float] = {}
        self._pending: list[tuple[float, int, Hashable, can.Message]] = []  # ready, seq, node, msg
        self._queued: dict[Hashable, int] = {}
        self._floods: list[list] = []  # [spec, node, t_end, next_ready, n, period]
        self._seq = 0
        self._current: Transmission | None = None
        self.bus_free = 0.0
        self.busy_s: dict[int, float] = {}
        self.frames: dict[int, int] = {}
        self.overflow: dict[Hashable, int] = {}
        self.replaced: dict[Hashable, int] = {}

    def wire_time(self, msg: can.Message) -> float:
        """Seconds the frame occupies the wire."""
        n = len(msg.data or b"")
        fd = bool(msg.is_fd)
        if not fd and n > 8:
            raise can.CanOperationError(f"a classic CAN frame carries 0..8 bytes, not {n} "
                                        f"(ID 0x{msg.arbitration_id:X})")
        key = (n, bool(msg.is_extended_id), fd, bool(msg.bitrate_switch))
        t = self._times.get(key)
        if t is None:
            brs = fd and key[3] and self.data_bitrate is not None
            bits = frame_bits(fd_length(n) if fd else n, extended=key[1], fd=fd, brs=brs,
                              worst_case=self.stuffing == "worst")
            t = self._times[key] = wire_time_us(bits, self.bitrate, self.data_bitrate) * 1e-6
        return t

    def submit(self, msg: can.Message, ready: float, node: Hashable = None) -> bool:
        """Queue a frame of `node`, ready to go at time `ready`. False: the node's queue was full, discarded.

        ``tx_policy="fifo"`` keeps every frame in order (Linux's qdisc); ``"latest"`` lets a frame replace
        the node's frame of the same ID still waiting (an AUTOSAR CanIf transmit buffer keeps the newest).
        """
        self.wire_time(msg)  # refuse an impossible frame now, not in the middle of the schedule
        if self.tx_policy == "latest":
            key = frame_key(msg)
            for i, p in enumerate(self._pending):
                if p[2] == node and frame_key(p[3]) == key:
                    self._pending[i] = (ready, p[1], node, msg)
                    self.replaced[node] = self.replaced.get(node, 0) + 1
                    return True
        queued = self._queued.get(node, 0)
        if queued >= self.tx_queue:
            self.overflow[node] = self.overflow.get(node, 0) + 1
            return False
        self._queued[node] = queued + 1
        self._pending.append((ready, self._seq, node, msg))
        self._seq += 1
        return True

    def add_flood(self, spec: FaultSpec, node: Hashable = None, t0: float = 0.0) -> None:
        """A babbling node: `spec.id` frames from t0 + start_s to t0 + end_s taking `spec.load` of the wire."""
        period = self.wire_time(flood_message(spec, 0)) / spec.load
        self._floods.append([spec, node, t0 + spec.end_s, t0 + spec.start_s, 0, period])

    def remove_node(self, node: Hashable) -> None:
        self._pending = [p for p in self._pending if p[2] != node]
        self._queued.pop(node, None)
        self._floods = [f for f in self._floods if f[1] != node]

    def pending(self, node: Hashable = None) -> int:
        return self._queued.get(node, 0)

    def _earliest(self) -> float | None:
        times = [p[0] for p in self._pending] + [f[3] for f in self._floods if f[3] < f[2]]
        return min(times) if times else None

    def next_event(self) -> float | None:
        """When something happens next: the end of the frame on the wire, or the next start."""
        if self._current is not None:
            return self._current.end
        earliest = self._earliest()
        return None if earliest is None else max(self.bus_free, earliest)

    def advance(self, t: float) -> list[Transmission]:
        """Run the wire up to time t: the frames completed by t, in wire order.

        Arbitration is decided only for starts before t, so frames submitted later with ready times
        >= t are never too late to compete.
        """
        done = []
        while True:
            if self._current is not None:
                if self._current.end > t:
                    break
                done.append(self._current)
                key = frame_key(self._current.msg)
                self.busy_s[key] = self.busy_s.get(key, 0.0) + self._current.end - self._current.start
                self.frames[key] = self.frames.get(key, 0) + 1
                self.bus_free = self._current.end
                self._current = None
            earliest = self._earliest()
            if earliest is None:
                break
            start = max(self.bus_free, earliest)
            if start >= t:
                break
            best = None  # (arbitration key, ready, seq, where)
            for i, (ready, seq, _node, msg) in enumerate(self._pending):
                if ready <= start:
                    cand = (arbitration_key(msg), ready, seq, ("q", i))
                    best = cand if best is None or cand[:3] < best[:3] else best
            for j, fl in enumerate(self._floods):
                if fl[3] <= start and fl[3] < fl[2]:
                    cand = (arbitration_key(flood_message(fl[0], fl[4])), fl[3], -1, ("f", j))
                    best = cand if best is None or cand[:3] < best[:3] else best
            assert best is not None  # the loop above ran while something was ready
            kind, idx = best[3]
            if kind == "q":
                _, _, node, msg = self._pending.pop(idx)
                self._queued[node] -= 1
            else:
                fl = self._floods[idx]
                node, msg = fl[1], flood_message(fl[0], fl[4])
                fl[4] += 1
                fl[3] += fl[5]
            self._current = Transmission(start, start + self.wire_time(msg), node, msg)
        return done


@dataclass(frozen=True)
class WireSnapshot:
    """What a wire had carried by time t (s on its clock)."""

    t: float
    busy_s: dict
    frames: dict

    def load_since(self, earlier: WireSnapshot, keys=None) -> float:
        """Bus load between two snapshots (0..1), of the frame keys given (default: everything)."""
        keys = self.busy_s.keys() if keys is None else keys
        busy = sum(self.busy_s.get(k, 0.0) - earlier.busy_s.get(k, 0.0) for k in keys)
        return busy / (self.t - earlier.t)

    def frames_since(self, earlier: WireSnapshot, key: int) -> int:
        return self.frames.get(key, 0) - earlier.frames.get(key, 0)


class Wire:
    """A :class:`WireModel` on the wall clock, shared by the FaultBus nodes of one process.

    One thread hands each frame to its node's inner bus at the end of its wire time. Times are seconds
    since the wire was made (fault windows count from then). A wire given to FaultBus instances is
    theirs to use, not to close: ``close()`` it after shutting them down.
    """

    def __init__(self, bitrate: int = 500_000, data_bitrate: int | None = 4_000_000, *,
                 stuffing: str = "worst", tx_queue: int = 10, tx_policy: str = "fifo"):
        self.model = WireModel(bitrate, data_bitrate, stuffing=stuffing, tx_queue=tx_queue, tx_policy=tx_policy)
        self.cond = threading.Condition()
        self.t0 = time.perf_counter()
        self.t0_epoch = time.time()    # the same instant on the clock python-can stamps messages with
        self.send_errors = 0
        self.late_s = 0.0          # worst delivery lateness behind the modelled end of a frame
        self._outbox: list[Transmission] = []
        self._running = True
        self._thread = threading.Thread(target=self._run, name="vehest-wire", daemon=True)
        self._thread.start()

    def now(self) -> float:
        return time.perf_counter() - self.t0

    def submit(self, node, injected, t: float) -> None:
        """Queue injected frames (from ``FaultInjector.apply`` at time t); call with ``cond`` held.

        The model is first brought up to t, so a late wire thread never makes a queue look fuller than
        the modelled wire would have it.
        """
        self._outbox.extend(self.model.advance(t))
        for msg, delay in injected:
            self.model.submit(msg, t + delay, node)
        self.cond.notify()

    def _run(self) -> None:
        while True:
            with self.cond:
                if not self._running:
                    return
                now = self.now()
                self._outbox.extend(self.model.advance(now))
                if not self._outbox:
                    nxt = self.model.next_event()
                    self.cond.wait(None if nxt is None else max(0.0, nxt - now))
                    continue
                done, self._outbox = self._outbox, []
            for tr in done:
                self.late_s = max(self.late_s, self.now() - tr.end)
                try:
                    tr.node._deliver(tr.msg)
                except (can.CanError, OSError, ValueError) as exc:  # the wire keeps running whatever a bus does
                    self.send_errors += 1
                    log.warning("wire: inner bus refused 0x%X: %s", tr.msg.arbitration_id, exc)

    def snapshot(self) -> WireSnapshot:
        with self.cond:
            return WireSnapshot(self.now(), dict(self.model.busy_s), dict(self.model.frames))

    def close(self) -> None:
        with self.cond:
            self._running = False
            self.cond.notify()
        if threading.current_thread() is not self._thread:
            self._thread.join(5)


class FaultBus(can.BusABC):
    """Any python-can bus behind a wire model and a fault injector (see the module docstring).

    `wire`: share one :class:`Wire` between the nodes of one process; without it the bus makes its own
    from `bitrate`, `data_bitrate`, `stuffing`, `tx_queue` and `tx_policy`. Shutting the bus down shuts the inner
    bus down too (and its own wire).
    """

    def __init__(self, inner: can.BusABC, injector: FaultInjector | None = None, *, wire: Wire | None = None,
                 bitrate: int = 500_000, data_bitrate: int | None = 4_000_000, stuffing: str = "worst",
                 tx_queue: int = 10, tx_policy: str = "fifo", **kwargs):
        self.inner = inner
        self.injector = injector or FaultInjector()
        self._own_wire = wire is None
        self.wire = wire or Wire(bitrate, data_bitrate, stuffing=stuffing, tx_queue=tx_queue, tx_policy=tx_policy)
        self.sent = 0
        super().__init__(channel=getattr(inner, "channel_info", "faultbus"), **kwargs)
        self.channel_info = f"faultbus({getattr(inner, 'channel_info', inner)})"
        self._can_protocol = getattr(inner, "protocol", can.CanProtocol.CAN_FD)
        with self.wire.cond:
            for spec in self.injector.floods:
                self.wire.model.add_flood(spec, self, 0.0)
            self.wire.cond.notify()

    def send(self, msg: can.Message, timeout: float | None = None) -> None:
        if self._is_shutdown:
            raise can.CanOperationError("the FaultBus is shut down")
        with self.wire.cond:
            t = self.wire.now()
            self.wire.submit(self, self.injector.apply([msg], t), t)
            self.sent += 1

    def _deliver(self, msg: can.Message) -> None:
        if not self._is_shutdown:
            self.inner.send(msg)

    def _recv_internal(self, timeout: float | None):
        return self.inner.recv(timeout), False

    @property
    def overflow(self) -> int:
        """Frames discarded because this node's transmit queue was full."""
        return self.wire.model.overflow.get(self, 0)

    def shutdown(self) -> None:
        if self._is_shutdown:
            return
        with self.wire.cond:
            self.wire.model.remove_node(self)
        if self._own_wire:
            self.wire.close()
        super().shutdown()
        self.inner.shutdown()
