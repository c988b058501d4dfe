"""The slave on a python-can bus: CRO frames in, RES/ERR and DTO frames out, DAQ events per tick.

A python-can ``Notifier`` hands every CRO to the slave as it arrives and sends the answer at
once (a master waits for it). Ticks come from the caller (``advance``: lockstep, tests, the
ECU's own tick later) or from a wall-clock thread (``start_clock``). Within a tick the order is
the ECU's: tick boundary (calibration writes reach the ECU page), the ECU's step (``on_tick``,
which reads calibration and writes measurements), then the event channels due this tick, then
the frames go out.
"""
from __future__ import annotations

import threading
import time
from collections.abc import Callable

import can
from xcp_demo import EXTENDED, Slave


class XcpBridge:
    def __init__(self, bus: can.BusABC, slave: Slave, *, tick_us: int | None = None,
                 on_tick: Callable[[int], None] | None = None):
        self.bus = bus
        self.slave = slave
        self.tick_us = slave.desc.tick_us if tick_us is None else tick_us
        self.on_tick = on_tick
        self.tick = 0
        d = slave.desc
        self._cro_id = d.cro_id & 0x1FFFFFFF
        self._cro_ext = bool(d.cro_id & EXTENDED)
        # event channel -> period in ticks (every tick, 1 ms, 10 ms for the ECU's channels)
        self.periods = [max(1, ev.cycle_us // self.tick_us) for ev in d.events]
        self.sent = 0
        self.tx_errors = 0
        self._lock = threading.Lock()
        self._notifier: can.Notifier | None = None
        self._clock: threading.Thread | None = None
        self._stop = threading.Event()

    # -- receive: called by the Notifier's thread ---------------------------------------------------
    def on_message(self, msg: can.Message) -> None:
        if msg.arbitration_id != self._cro_id or msg.is_extended_id != self._cro_ext or msg.is_error_frame:
            return
        with self._lock:
            self.slave.rx(bytes(msg.data), self.tick)
            self._send()

    def _send(self) -> None:
        for f in self.slave.frames():
            try:
                self.bus.send(can.Message(arbitration_id=f.arbitration_id, is_extended_id=f.is_extended_id,
                                          is_fd=f.is_fd, bitrate_switch=f.is_fd, data=f.data))
                self.sent += 1
            except can.CanError:
                self.tx_errors += 1  # a full TX buffer: counted, the master sees a lost DTO or a timeout

    # -- ticks ------------------------------------------------------------------------------------
    def advance(self, n: int = 1) -> None:
        """Run n ECU ticks now."""
        for _ in range(n):
            with self._lock:
                self.tick += 1
                self.slave.tick(self.tick)
                if self.on_tick is not None:
                    self.on_tick(self.tick)
                for ch, period in enumerate(self.periods):
                    if self.tick % period == 0:
                        self.slave.event(ch)
                self._send()

    def start(self) -> XcpBridge:
        self._notifier = can.Notifier(self.bus, [self.on_message], timeout=0.01)
        return self

    def start_clock(self) -> None:
        """Ticks on the wall clock (late ticks are caught up, in order)."""
        self._stop.clear()

        def run():
            period = self.tick_us * 1e-6
            t0 = time.perf_counter()
            done = 0
            while not self._stop.is_set():
                due = int((time.perf_counter() - t0) / period)
                if due > done:
                    self.advance(due - done)
                    done = due
                else:
                    time.sleep(period / 2)

        self._clock = threading.Thread(target=run, name="xcp-clock", daemon=True)
        self._clock.start()

    def stop(self) -> None:
        self._stop.set()
        if self._clock is not None:
            self._clock.join()
            self._clock = None
        if self._notifier is not None:
            self._notifier.stop()
            self._notifier = None

    def __enter__(self) -> XcpBridge:
        return self.start()

    def __exit__(self, *exc) -> None:
        self.stop()
