"""The fault injector: a :class:`~.spec.FaultConfig` applied to the frames one node sends, seeded, with
no clock and no I/O: frames in, ``(frame, delay_s)`` out (the delay is for the wire model, :mod:`.wire`)."""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import NamedTuple

import can
import numpy as np

from ..bus.busload import FD_LENGTHS
from ..bus.frames import database, e2e_config, message, message_by_id
from ..native import ffi, lib
from .spec import _SYNC, FaultConfig, FaultSpec, _target_ids


class Injected(NamedTuple):
    msg: can.Message
    delay_s: float


def _shorter_length(n: int) -> int:
    """The next shorter valid length: what a sender with a wrong DLC table would send."""
    shorter = [x for x in FD_LENGTHS if x < n]
    return shorter[-1] if shorter else 1


@dataclass
class _State:
    """What the sender remembers per frame ID."""

    last_payload: bytes | None = None
    counter_offset: int = 0
    last_release: float = -math.inf


class FaultInjector:
    """Applies a :class:`FaultConfig` to the frames one node sends. Seeded, no clock, no I/O.

    ``applied[i]`` counts the frames fault ``i`` changed (dropped, corrupted, delayed, ...).
    """

    def __init__(self, config: FaultConfig | None = None, *, stream: int = 0, bus: str = "pt"):
        self.config = config or FaultConfig()
        self.stream = stream   # several nodes with one config: give each its own stream of draws
        self.db = database(bus)
        self._targets = [None if f.target in (None, "*") else _target_ids(f.target, bus)
                         for f in self.config.faults]
        self._sync_ids = frozenset(message(n).frame_id for n in _SYNC)
        self._e2e: dict[int, object] = {}
        self.reset()

    def reset(self) -> None:
        self._held: dict[int, int] = {}   # stuck faults: the raw value each holds
        seed = self.config.seed
        self._rng = [np.random.default_rng([seed, i, self.stream]) for i in range(len(self.config.faults))]
        self._state: dict[tuple[int, bool], _State] = {}
        self.applied = [0] * len(self.config.faults)
        self._counter = ffi.new("uint8_t *")
        self._buf = ffi.new("uint8_t[64]")

    @property
    def floods(self) -> tuple[FaultSpec, ...]:
        return self.config.floods

    def _hits(self, i: int, spec: FaultSpec, msg: can.Message, t_s: float) -> bool:
        """Fault i is active for this frame now (a random draw for p < 1 from its own stream)."""
        if not spec.active(t_s):
            return False
        targets = self._targets[i]
        if targets is None:
            if not msg.is_extended_id and msg.arbitration_id in self._sync_ids:
                return False
        elif msg.is_extended_id or msg.arbitration_id not in targets:
            return False
        if spec.p < 1.0 and not self._rng[i].random() < spec.p:
            return False
        self.applied[i] += 1
        return True

    def _e2e_config(self, msg: can.Message):
        """The frame's E2E configuration (``vh_e2e_cfg_t *``), None if it is not E2E-protected."""
        if msg.is_extended_id:
            return None
        if msg.arbitration_id not in self._e2e:
            try:
                self._e2e[msg.arbitration_id] = e2e_config(message_by_id(msg.arbitration_id))
            except KeyError:
                self._e2e[msg.arbitration_id] = None
        return self._e2e[msg.arbitration_id]

    def _reprotect(self, data: bytearray, cfg, offset: int = 0) -> bytearray:
        """Protect again with the frame's own counter moved on by `offset` (the firmware's own C)."""
        n = len(data)
        ffi.memmove(self._buf, bytes(data), n)
        self._counter[0] = (lib.vh_e2e_counter(cfg, self._buf) + offset) % lib.vh_e2e_counter_range(cfg)
        lib.vh_e2e_protect(cfg, self._buf, n, self._counter)
        return bytearray(ffi.buffer(self._buf, n))

    def _signal_fault(self, i: int, spec: FaultSpec, data: bytearray, cfg) -> bytearray:
        """A sensor's fault inside its node: the signal's raw value replaced (SNA and its qualifier
        INVALID, or the value held since the fault began), the frame re-protected with its own counter."""
        msg = message(str(spec.target))
        raw = msg.decode(bytes(data), decode_choices=False, scaling=False)
        sig = msg.get_signal_by_name(str(spec.signal))
        if spec.kind == "sna":
            raw[spec.signal] = next(int(k) for k, v in (sig.choices or {}).items() if str(v) == "SNA")
            if f"Qf_{spec.signal}" in raw:
                raw[f"Qf_{spec.signal}"] = 0
        else:
            raw[spec.signal] = self._held.setdefault(i, int(raw[spec.signal]))
        out = bytearray(msg.encode(raw, scaling=False, strict=False, padding=False))
        out += bytearray(max(0, len(data) - len(out)))
        return self._reprotect(out, cfg) if cfg is not None else out

    def apply(self, frames: list[can.Message], t_s: float) -> list[Injected]:
        """The frames as they leave the node at time t_s (s since the run started), each with its delay."""
        out = []
        faults = self.config.faults
        quiet = not any(spec.active(t_s) for spec in faults)
        for original in frames:
            key = (original.arbitration_id, bool(original.is_extended_id))
            state = self._state.get(key)
            if state is None:
                state = self._state[key] = _State()
            if quiet and not state.counter_offset:   # nothing to do but remember
                state.last_payload = bytes(original.data)
                release = max(t_s, state.last_release)
                state.last_release = release
                out.append(Injected(original, release - t_s))
                continue
            data = bytearray(original.data)
            cfg = self._e2e_config(original)
            # the sender: its counter and its payload
            if cfg is not None:
                for i, spec in enumerate(faults):
                    if spec.kind == "skip_counter" and self._hits(i, spec, original, t_s):
                        state.counter_offset += spec.by - 1
                if state.counter_offset:
                    data = self._reprotect(data, cfg, state.counter_offset)
            for i, spec in enumerate(faults):
                if spec.kind in ("sna", "stuck") and self._hits(i, spec, original, t_s):
                    data = self._signal_fault(i, spec, data, cfg)
            for i, spec in enumerate(faults):
                if spec.kind == "freeze_counter" and state.last_payload is not None and \
                        self._hits(i, spec, original, t_s):
                    data = bytearray(state.last_payload)
            state.last_payload = bytes(data)
            # on the way out: length, bit errors, loss
            is_fd = bool(original.is_fd)
            lost = False
            for i, spec in enumerate(faults):
                if spec.kind == "wrong_dlc" and self._hits(i, spec, original, t_s):
                    n = spec.length if spec.length is not None else _shorter_length(len(data))
                    data = data[:n] + bytearray(max(0, n - len(data)))
                    is_fd = is_fd or n > 8
                elif spec.kind == "corrupt_crc" and data and self._hits(i, spec, original, t_s):
                    bit = int(self._rng[i].integers(0, 8 * len(data)))
                    data[bit // 8] ^= 1 << (bit % 8)
                elif spec.kind in ("drop", "silence") and self._hits(i, spec, original, t_s):
                    lost = True
            if lost:
                continue
            delay = 0.0
            for i, spec in enumerate(faults):
                if spec.kind == "latency" and self._hits(i, spec, original, t_s):
                    delay += spec.us * 1e-6
                elif spec.kind == "jitter" and self._hits(i, spec, original, t_s):
                    delay += float(self._rng[i].uniform(0.0, spec.max_us)) * 1e-6
            release = max(t_s + delay, state.last_release)   # one ID never overtakes itself
            state.last_release = release
            msg = can.Message(timestamp=original.timestamp, arbitration_id=original.arbitration_id,
                              is_extended_id=original.is_extended_id, is_fd=is_fd,
                              bitrate_switch=original.bitrate_switch and is_fd, data=bytes(data),
                              channel=original.channel, is_rx=False)
            out.append(Injected(msg, release - t_s))
        return out


def flood_message(spec: FaultSpec, n: int) -> can.Message:
    """The n-th frame of a flood: classic CAN, `length` bytes (default 8) of a running count."""
    length = 8 if spec.length is None else spec.length
    return can.Message(arbitration_id=spec.id, is_extended_id=False, is_fd=False,
                       data=(n % 2**64).to_bytes(8, "little")[:length])
