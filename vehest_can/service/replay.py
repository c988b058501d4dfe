"""Run a recorded log (candump -L, or anything python-can's LogReader reads) through the ECU offline.

Ticks come from the log's SIM_Sync frames when it has them (a lockstep session: the replay then
reproduces the ECU's frames bit for bit), otherwise from its timestamps: a tick every 500 µs from
the first frame, each frame handed in before the first tick at or after its timestamp.
"""
from __future__ import annotations

from dataclasses import dataclass

import can

from ..bus import lockstep
from ..bus.frames import TICK_S, same_frame, sent_by
from ..systems.ecu import Ecu

# What the ECU core transmits (the lockstep acknowledge is the daemon's, not the core's)
ECU_TX = sent_by({"VEHEST"}) - {lockstep.ACK.frame_id}


@dataclass
class ReplayResult:
    frames_in: int
    ticks: int
    produced: list[can.Message]
    logged: list[can.Message]
    counters: dict
    paced_by: str

    @property
    def identical(self) -> bool | None:
        """Equal to the ECU frames in the log (None when the log has none to compare)."""
        if not self.logged:
            return None
        return len(self.logged) == len(self.produced) and all(map(same_frame, self.logged, self.produced))

    def first_difference(self) -> int | None:
        for i, (a, b) in enumerate(zip(self.logged, self.produced)):
            if not same_frame(a, b):
                return i
        return None if len(self.logged) == len(self.produced) else min(len(self.logged), len(self.produced))


def replay(messages: list[can.Message], ecu: Ecu | None = None) -> ReplayResult:
    ecu = ecu or Ecu()
    produced: list[can.Message] = []
    logged = [m for m in messages if m.arbitration_id in ECU_TX and not m.is_extended_id]
    inputs = [m for m in messages if not (m.arbitration_id in ECU_TX and not m.is_extended_id)]
    if any(lockstep.is_sync(m) for m in inputs):
        paced_by = "sync"
        for m in inputs:
            if not lockstep.is_sync(m):
                ecu.rx(m)
                continue
            tick, cmd = lockstep.decode_sync(m)
            if cmd == lockstep.RESET:
                ecu.reset()
            elif cmd == lockstep.STEP:
                produced += ecu.step(timestamp=tick * TICK_S)
    else:
        paced_by = "timestamps"
        inputs.sort(key=lambda m: m.timestamp)
        t0 = inputs[0].timestamp if inputs else 0.0
        k = 0
        for m in inputs:
            while t0 + k * TICK_S < m.timestamp - 1e-7:
                produced += ecu.step(timestamp=k * TICK_S)
                k += 1
            ecu.rx(m)
        if inputs:
            produced += ecu.step(timestamp=k * TICK_S)
    return ReplayResult(len(messages), ecu.tick, produced, logged, ecu.counters(), paced_by)
