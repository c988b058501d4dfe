"""Fault injection at a sending node: drop, corrupt, freeze or skip counters, wrong DLC, silence, flood,
latency and jitter. Pure and seeded: the same configuration, seed and input give the same output.

A :class:`FaultConfig` is a list of :class:`FaultSpec` (kind, target, time window, amounts) and a seed.
It comes from a ``[faults]`` table in a TOML file (:func:`load_faults`) or from command-line strings
(:func:`parse_fault`, syntax ``KIND[:TARGET][:KEY=VALUE...][:START-END]``). The schema, the fault table
and how to wrap a bus are in ``docs/faults.md``.

:class:`FaultInjector` transforms the frames one node sends at one time ``t_s`` (seconds since the
run started): frames in, ``(frame, delay_s)`` out. The delay (latency + jitter) is for the wire model
(:mod:`vehest_can.faultbus`), which also produces the flood frames. Frames of one ID keep their order
however they are delayed: a controller's transmit queue does not overtake itself.

Sync frames (SIM_Sync, VEHEST_SyncAck) belong to the test bench, not the car: node targets and ``*``
leave them alone; only naming them as the target hits them.
"""
from __future__ import annotations

import math
import re
import tomllib
from dataclasses import dataclass, fields
from pathlib import Path
from typing import NamedTuple

import can
import numpy as np

from .busload import FD_LENGTHS
from .errors import ConfigError
from .frames import database, e2e_data_id
from .native import ffi, lib

#: Fault kinds and the amounts each takes (besides target, start_s, end_s).
KINDS: dict[str, tuple[str, ...]] = {
    "drop": ("p",),
    "corrupt_crc": ("p",),
    "freeze_counter": ("p",),
    "skip_counter": ("p", "by"),
    "wrong_dlc": ("p", "length"),
    "silence": (),
    "flood": ("id", "length", "load"),
    "latency": ("us",),
    "jitter": ("max_us",),
}
#: What each kind does, for help texts and the docs.
DESCRIPTIONS = {
    "drop": "each frame of the target is lost with probability p",
    "corrupt_crc": "one random payload bit of a frame flips (probability p): the E2E CRC no longer matches",
    "freeze_counter": "the sender repeats its previous payload (probability p): same counter, stale data",
    "skip_counter": "the sender's alive counter jumps by `by` instead of 1 (probability p), CRC recomputed",
    "wrong_dlc": "a frame goes out with `length` bytes (probability p; default the next shorter length)",
    "silence": "the target sends nothing (node off the bus)",
    "flood": "a babbling node sends frame `id` (`length` bytes, classic CAN) taking `load` of the bus",
    "latency": "every frame of the target leaves `us` microseconds late",
    "jitter": "every frame of the target leaves a uniform random 0..`max_us` microseconds late",
}
_DEFAULTS = {"p": 1.0, "by": 2, "length": None, "id": 0x001, "load": 1.0, "us": 0.0, "max_us": 0.0}
_SYNC = ("SIM_Sync", "VEHEST_SyncAck")
_NO_TARGET = ("flood",)


@dataclass(frozen=True)
class FaultSpec:
    """One fault: what, on which frames (message name, node name or ``*``), when, how much."""

    kind: str
    target: str | None = None
    start_s: float = 0.0
    end_s: float = math.inf
    p: float = 1.0
    by: int = 2
    length: int | None = None
    id: int = 0x001
    load: float = 1.0
    us: float = 0.0
    max_us: float = 0.0

    def active(self, t_s: float) -> bool:
        return self.start_s <= t_s < self.end_s

    def text(self) -> str:
        """The command-line form of this fault (round-trips through :func:`parse_fault`)."""
        parts = [self.kind] + ([self.target] if self.target else [])
        for key in KINDS[self.kind]:
            value = getattr(self, key)
            if value != _DEFAULTS[key]:
                parts.append(f"{key}=0x{value:03X}" if key == "id" else f"{key}={_num(value)}")
        if self.start_s > 0 or math.isfinite(self.end_s):
            end = _num(self.end_s) if math.isfinite(self.end_s) else ""
            parts.append(f"{_num(self.start_s)}-{end}")
        return ":".join(parts)


def _num(value) -> str:
    """Short but exact: 2 rather than 2.0, 0.1 as 0.1."""
    short = f"{value:g}"
    return short if float(short) == value else repr(float(value))


@dataclass(frozen=True)
class FaultConfig:
    """The faults of one run and the seed of their random draws."""

    faults: tuple[FaultSpec, ...] = ()
    seed: int = 0

    def __post_init__(self):
        if isinstance(self.seed, bool) or not isinstance(self.seed, int) or not 0 <= self.seed < 2**64:
            raise ConfigError(f"fault seed: must be an integer in [0, 2^64), not {self.seed!r}")
        for spec in self.faults:
            _validate(spec, f"fault {spec.kind!r}")

    @property
    def floods(self) -> tuple[FaultSpec, ...]:
        return tuple(f for f in self.faults if f.kind == "flood")


class Injected(NamedTuple):
    msg: can.Message
    delay_s: float


# ---- validation --------------------------------------------------------------------------------

def _names(bus: str = "pt") -> tuple[set[str], set[str]]:
    db = database(bus)
    return {m.name for m in db.messages}, {n.name for n in db.nodes}


def _validate(spec: FaultSpec, where: str, bus: str = "pt") -> None:
    """ConfigError naming `where` and the key for anything a run could not use."""
    def fail(key, problem):
        raise ConfigError(f"{where}: {key}: {problem}")

    if spec.kind not in KINDS:
        fail("kind", f"unknown fault kind {spec.kind!r} (expected one of: {', '.join(KINDS)})")
    messages, nodes = _names(bus)
    if spec.kind in _NO_TARGET:
        if spec.target is not None:
            fail("target", "a flood comes from its own babbling node: give no target")
    elif spec.target is None:
        fail("target", f"missing: name a message ({', '.join(sorted(messages))}), "
                       f"a node ({', '.join(sorted(nodes))}) or *")
    elif spec.target != "*" and spec.target not in messages and spec.target not in nodes:
        fail("target", f"{spec.target!r} is neither a message ({', '.join(sorted(messages))}) "
                       f"nor a node ({', '.join(sorted(nodes))}) of the DBC, nor *")
    for key in ("start_s", "end_s", "p", "load", "us", "max_us"):
        value = getattr(spec, key)
        if isinstance(value, bool) or not isinstance(value, (int, float)) or math.isnan(value):
            fail(key, f"must be a number, not {value!r}")
    if not (0.0 <= spec.start_s < math.inf):
        fail("start_s", f"must be a time >= 0 s, not {spec.start_s!r}")
    if not spec.end_s > spec.start_s:
        fail("end_s", f"{spec.end_s:g} s must come after start_s {spec.start_s:g} s")
    if not 0.0 <= spec.p <= 1.0:
        fail("p", f"is a probability in [0, 1], not {spec.p!r}")
    if not 0.0 < spec.load <= 1.0:
        fail("load", f"is the flood's share of the bus in (0, 1], not {spec.load!r}")
    for key in ("us", "max_us"):
        if not 0.0 <= getattr(spec, key) <= 10e6:
            fail(key, f"must be a delay in [0, 1e7] µs, not {getattr(spec, key)!r}")
    if isinstance(spec.by, bool) or not isinstance(spec.by, int) or not 2 <= spec.by <= 14:
        fail("by", f"is the counter jump, an integer in [2, 14] (1 is no skip, 15 wraps to a repeat), "
                   f"not {spec.by!r}")
    if isinstance(spec.id, bool) or not isinstance(spec.id, int) or not 0 <= spec.id <= 0x7FF:
        fail("id", f"is an 11-bit frame ID in [0x000, 0x7FF], not {spec.id!r}")
    if spec.length is not None:
        if isinstance(spec.length, bool) or not isinstance(spec.length, int) or spec.length not in FD_LENGTHS:
            fail("length", f"must be a CAN (FD) payload length ({', '.join(map(str, FD_LENGTHS))}), "
                           f"not {spec.length!r}")
        if spec.kind == "flood" and spec.length > 8:
            fail("length", f"a flood frame is classic CAN: 0..8 bytes, not {spec.length}")
    if spec.kind == "skip_counter" and spec.target != "*":
        ids = _target_ids(spec.target, bus)
        if not any(e2e_data_id(database(bus).get_message_by_frame_id(i)) for i in ids):
            fail("target", f"{spec.target} sends no E2E-protected frame: there is no counter to skip")


def _target_ids(target: str, bus: str = "pt") -> frozenset[int]:
    db = database(bus)
    if target in {m.name for m in db.messages}:
        return frozenset({db.get_message_by_name(target).frame_id})
    return frozenset(m.frame_id for m in db.messages
                     if target in m.senders and m.name not in _SYNC and not m.is_extended_frame)


# ---- parsing: TOML and command line ------------------------------------------------------------

_WINDOW = re.compile(r"^(\d+(?:\.\d*)?)?-(\d+(?:\.\d*)?)?$")
_INT_KEYS = ("by", "length", "id")


def parse_fault(text: str) -> FaultSpec:
    """``KIND[:TARGET][:KEY=VALUE...][:START-END]``, e.g. ``drop:DLS_Sensors:p=0.1:2.0-3.0``.

    START-END in seconds; either side may be left out (``2-`` from 2 s on, ``-3`` until 3 s).
    Integers may be hex (``id=0x001``). ConfigError names the option and the part that is wrong.
    """
    where = f"--fault {text!r}"
    parts = text.split(":")
    kind = parts[0].strip()
    if kind not in KINDS:
        raise ConfigError(f"{where}: unknown fault kind {kind!r} (expected one of: {', '.join(KINDS)})")
    values: dict = {"kind": kind}
    for part in parts[1:]:
        part = part.strip()
        window = _WINDOW.match(part)
        if "=" in part:
            key, _, raw = part.partition("=")
            key = key.strip()
            if key not in KINDS[kind]:
                allowed = ", ".join(KINDS[kind]) or "none"
                raise ConfigError(f"{where}: {key!r} is not an amount of {kind} (it takes: {allowed})")
            if key in values:
                raise ConfigError(f"{where}: {key} given twice")
            values[key] = _number(raw.strip(), key, where)
        elif window and part != "-":
            if "start_s" in values:
                raise ConfigError(f"{where}: two time windows")
            values["start_s"] = float(window.group(1)) if window.group(1) else 0.0
            values["end_s"] = float(window.group(2)) if window.group(2) else math.inf
        elif part:
            if "target" in values:
                raise ConfigError(f"{where}: {part!r}: a second target (or a malformed KEY=VALUE / START-END)")
            values["target"] = part
        else:
            raise ConfigError(f"{where}: empty field between ':'")
    spec = FaultSpec(**values)
    _validate(spec, where)
    return spec


def _number(raw: str, key: str, where: str):
    try:
        return int(raw, 0) if key in _INT_KEYS else float(raw)
    except ValueError:
        kind = "an integer" if key in _INT_KEYS else "a number"
        raise ConfigError(f"{where}: {key}={raw!r} is not {kind}") from None


def faults_from_cli(texts: list[str] | None, seed: int = 0) -> FaultConfig:
    return FaultConfig(tuple(parse_fault(t) for t in texts or ()), seed)


def faults_from_dict(table: dict, where: str = "<faults>") -> FaultConfig:
    """The ``[faults]`` table of a parsed TOML document (``where`` names the file in errors)::

        [faults]
        seed = 7
        [[faults.fault]]
        kind = "drop"
        target = "DLS_Sensors"
        p = 0.1
        start_s = 2.0
        end_s = 3.0
    """
    def fail(key, problem):
        raise ConfigError(f"{where}: {key}: {problem}")

    if not isinstance(table, dict):
        fail("faults", "must be a table ([faults])")
    for key in table:
        if key not in ("seed", "fault"):
            fail(f"faults.{key}", "unknown key (expected: seed, fault)")
    seed = table.get("seed", 0)
    if isinstance(seed, bool) or not isinstance(seed, int) or not 0 <= seed < 2**64:
        fail("faults.seed", f"must be an integer in [0, 2^64), not {seed!r}")
    entries = table.get("fault", [])
    if not isinstance(entries, list):
        fail("faults.fault", "must be an array of tables ([[faults.fault]])")
    specs = []
    names = {f.name for f in fields(FaultSpec)}
    for i, entry in enumerate(entries):
        key = f"faults.fault[{i}]"
        if not isinstance(entry, dict):
            fail(key, "must be a table")
        if "kind" not in entry:
            fail(f"{key}.kind", f"missing (one of: {', '.join(KINDS)})")
        kind = entry["kind"]
        if kind not in KINDS:
            fail(f"{key}.kind", f"unknown fault kind {kind!r} (expected one of: {', '.join(KINDS)})")
        allowed = {"kind", "start_s", "end_s", *KINDS[kind]} | (set() if kind in _NO_TARGET else {"target"})
        for k in entry:
            if k not in allowed:
                fail(f"{key}.{k}", f"not a key of a {kind} fault (expected: {', '.join(sorted(allowed))})")
        values = {k: v for k, v in entry.items() if k in names}
        for k, v in values.items():
            if k in _INT_KEYS and (isinstance(v, bool) or not isinstance(v, int)):
                fail(f"{key}.{k}", f"must be an integer, not {v!r}")
            if k == "target" and not isinstance(v, str):
                fail(f"{key}.{k}", f"must be a string, not {v!r}")
        spec = FaultSpec(**values)
        try:
            _validate(spec, key)
        except ConfigError as exc:
            raise ConfigError(f"{where}: {exc}") from None
        specs.append(spec)
    return FaultConfig(tuple(specs), seed)


def load_faults(path: str | Path) -> FaultConfig:
    """The ``[faults]`` table of a TOML file (a scenario file or a file of its own)."""
    path = Path(path)
    try:
        with open(path, "rb") as fh:
            doc = tomllib.load(fh)
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"{path}: (TOML syntax): {exc}") from None
    except OSError as exc:
        raise ConfigError(f"{path}: cannot read: {exc.strerror or exc}") from None
    if "faults" not in doc:
        raise ConfigError(f"{path}: faults: missing (the file has no [faults] table)")
    return faults_from_dict(doc["faults"], str(path))


# ---- the injector ------------------------------------------------------------------------------

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
        self._sync_ids = frozenset(self.db.get_message_by_name(n).frame_id for n in _SYNC)
        self._data_ids: dict[int, int] = {}
        self.reset()

    def reset(self) -> None:
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

    def _data_id(self, msg: can.Message) -> int:
        if msg.is_extended_id:
            return 0
        data_id = self._data_ids.get(msg.arbitration_id)
        if data_id is None:
            try:
                data_id = e2e_data_id(self.db.get_message_by_frame_id(msg.arbitration_id))
            except KeyError:
                data_id = 0
            self._data_ids[msg.arbitration_id] = data_id
        return data_id

    def _reprotect(self, data: bytearray, data_id: int, counter: int) -> bytearray:
        """E2E P01 protect with the given counter (the firmware's own C)."""
        n = len(data)
        ffi.memmove(self._buf, bytes(data), n)
        self._counter[0] = counter
        lib.vh_e2e_p01_protect(self._buf, n, data_id, self._counter)
        return bytearray(ffi.buffer(self._buf, n))

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
            data_id = self._data_id(original)
            # the sender: its counter and its payload
            if data_id and len(data) >= 2:
                for i, spec in enumerate(faults):
                    if spec.kind == "skip_counter" and self._hits(i, spec, original, t_s):
                        state.counter_offset += spec.by - 1
                if state.counter_offset:
                    data = self._reprotect(data, data_id, ((data[1] & 0x0F) + state.counter_offset) % 15)
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


# ---- in-process runs: car -> injector -> wire model -> ECU, in simulated time ----------------------

@dataclass
class FaultRun:
    """One drive with faults, tick by tick. ``est`` holds the raw VEHEST_DrivelineEst payload of every
    tick; the methods decode its health and valid bits."""

    config: FaultConfig
    est: np.ndarray            # (n, 16) uint8
    counters: np.ndarray       # (n, len(ecu.COUNTERS)) after each step
    sample_age: np.ndarray     # (n,) s from the making of the newest sample the ECU accepted to its step
    truth_to: np.ndarray       # (n,) plant output-shaft torque [Nm]
    rx: list                   # per tick: the frames the ECU received before its step
    tx: list                   # (tick, can.Message) of every ECU frame
    applied: list              # frames each fault changed
    overflow: dict             # transmit-queue overflows per node
    load: float                # bus load the wire carried over the run (0..1)

    @property
    def n(self) -> int:
        return len(self.est)

    def health(self, which: str) -> np.ndarray:
        """Health of filter "T" (speeds + torque) or "S" (speeds only) per tick: 0 INIT .. 3 FAULT."""
        return (self.est[:, 1] >> (4 if which == "T" else 6)) & 3

    def valid(self, which: str) -> np.ndarray:
        return ((self.est[:, 14] >> (0 if which == "T" else 1)) & 1).astype(bool)

    @property
    def turbine_valid(self) -> np.ndarray:
        return ((self.est[:, 14] >> 2) & 1).astype(bool)

    def shaft_torque(self, which: str) -> np.ndarray:
        col = 2 if which == "T" else 6
        return self.est[:, col:col + 2].copy().view("<i2")[:, 0] * 0.25

    def counter(self, name: str) -> np.ndarray:
        from .ecu import COUNTERS
        return self.counters[:, COUNTERS.index(name)]


def run_with_faults(drive, config: FaultConfig | None = None, *, bitrate: int = 500_000,
                    data_bitrate: int | None = 4_000_000, stuffing: str = "worst", tx_queue: int = 10,
                    tx_policy: str = "fifo") -> FaultRun:
    """The drive in simulated time with the car's and the ECU's frames through injectors and one wire.

    Tick k: the car's frames (and the ECU's frames of step k-1) are ready at k * 500 µs plus their
    delay; what the wire completes by (k + 1) * 500 µs reaches the ECU before its step k. Without
    faults this equals ``run_inprocess`` frame for frame (a load of 47 % leaves every frame inside
    its tick). Floods come from a node of their own.
    """
    from .ecu import COUNTERS, Ecu
    from .faultbus import WireModel
    from .frames import TICK_S, frame_id, to_message
    from .sim import Car

    config = config or FaultConfig()
    wire = WireModel(bitrate, data_bitrate, stuffing=stuffing, tx_queue=tx_queue, tx_policy=tx_policy)
    for spec in config.floods:
        wire.add_flood(spec, "FLOOD")
    car, ecu = Car(drive), Ecu()
    sensors, vehest = FaultInjector(config, stream=0), FaultInjector(config, stream=1)
    est_id, dls_id = frame_id("VEHEST_DrivelineEst"), frame_id("DLS_Sensors")
    cnt = ecu.c.cnt
    n = drive.n
    est = np.zeros((n, 16), dtype=np.uint8)
    counters = np.zeros((n, len(COUNTERS)), dtype=np.int64)
    sample_age = np.full(n, np.nan)
    truth_to = np.zeros(n)
    rx, tx = [], []
    out: list[can.Message] = []
    sample_t = math.nan
    for k in range(n):
        t = k * TICK_S
        for msg, delay in sensors.apply([to_message(f, timestamp=t) for f in car.tick(k)], t):
            wire.submit(msg, t + delay, "DLS")
        for msg, delay in vehest.apply(out, t):
            wire.submit(msg, t + delay, "VEHEST")
        got = [tr.msg for tr in wire.advance(t + TICK_S) if tr.node != "VEHEST"]
        for msg in got:
            refused = cnt.crc_error + cnt.counter_repeat + cnt.dlc_error
            ecu.rx(msg)
            if msg.arbitration_id == dls_id and not msg.is_extended_id and \
                    cnt.crc_error + cnt.counter_repeat + cnt.dlc_error == refused:
                sample_t = msg.timestamp   # when the sensor node made it
        out = ecu.step(timestamp=t + TICK_S)
        rx.append(got)
        for msg in out:
            tx.append((k, msg))
            if msg.arbitration_id == est_id:
                est[k] = np.frombuffer(bytes(msg.data), dtype=np.uint8)
        counters[k] = [getattr(cnt, name) for name in COUNTERS]
        sample_age[k] = t + TICK_S - sample_t
        truth_to[k] = car.c.plant.truth.to
    for msg, delay in vehest.apply(out, n * TICK_S):   # the last step's frames, sent as the run ends
        wire.submit(msg, n * TICK_S + delay, "VEHEST")
    wire.advance((n + 1) * TICK_S)
    load = sum(wire.busy_s.values()) / (n * TICK_S)    # the frames of the run's n ticks, over n ticks
    applied = [a + b for a, b in zip(sensors.applied, vehest.applied)]
    return FaultRun(config, est, counters, sample_age, truth_to, rx, tx, applied, dict(wire.overflow), load)


# ---- the fault table: each fault run, what the ECU detects, its health response, recovery -----------

class Case(NamedTuple):
    """One row of the fault table: a fault (command-line form), the counters it must raise, wire options."""

    label: str
    fault: str
    expect: tuple[str, ...] = ()
    wire: dict = {}


#: The rows of ``vehest-can faults``. Windows are 2.0-2.5 s of the launch scenario: both filters are OK
#: well before.
CATALOGUE: tuple[Case, ...] = (
    Case("none (reference)", ""),
    Case("random frame loss", "drop:DLS_Sensors:p=0.2:2-2.5", ("counter_skip",)),
    Case("bit errors, some frames", "corrupt_crc:DLS_Sensors:p=0.2:2-2.5", ("crc_error",)),
    Case("bit errors, every frame", "corrupt_crc:DLS_Sensors:2-2.5", ("crc_error", "timeout")),
    Case("frozen sender (repeats its frame)", "freeze_counter:DLS_Sensors:2-2.5", ("counter_repeat", "timeout")),
    Case("counter jumps", "skip_counter:DLS_Sensors:p=0.1:2-2.5", ("counter_skip",)),
    Case("wrong length", "wrong_dlc:DLS_Sensors:p=0.2:2-2.5", ("dlc_error",)),
    Case("sensor node silent", "silence:DLS:2-2.5", ("timeout",)),
    Case("flood at ID 0x001, whole bus", "flood:2-2.5", ("unknown_id", "timeout")),
    Case("same, sender keeps only its newest frame", "flood:2-2.5", ("unknown_id", "timeout"),
         {"tx_policy": "latest"}),
    Case("flood at ID 0x001, half the bus", "flood:load=0.5:2-2.5", ("unknown_id",)),
    Case("constant latency 1.5 ms", "latency:DLS_Sensors:us=1500:2-2.5"),
    Case("jitter 0..1 ms", "jitter:DLS_Sensors:max_us=1000:2-2.5"),
    Case("jitter 0..2.5 ms", "jitter:DLS_Sensors:max_us=2500:2-2.5", ("timeout",)),
)
_HEALTH = ("INIT", "OK", "DEGRADED", "FAULT")


@dataclass
class FaultRow:
    label: str
    fault: str                    # command-line form ("" for the reference run), plus wire options
    expect: tuple[str, ...]
    window: tuple[int, int]       # ticks [first, end) of the fault
    detected: dict                # counter -> rise from the fault's start to the end of the run
    first_detect: int | None      # ticks from the fault's start to the first rise of an expected counter
    health: dict                  # "T"/"S" -> health states during the fault, in order of appearance
    valid_pct: dict               # "T"/"S" -> % of the fault's ticks with the estimate marked valid
    recovery: int | None          # ticks after the fault until both valid; 0: never lost; None: not again
    oldest_ms: float              # oldest sample behind an estimate marked valid, fault to run end [ms]
    rms_nm: float                 # DkfT torque error vs the plant while valid during the fault [Nm]; nan: < 10 ticks
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
        t, s = ("→".join(self.health[w]) for w in "TS")
        vt, vs = self.valid_pct["T"], self.valid_pct["S"]
        if t == s and abs(vt - vs) < 0.05:
            return f"T, S: {t}; valid {vt:.1f} %"
        return f"T: {t}, valid {vt:.1f} %; S: {s}, valid {vs:.1f} %"

    def recovery_text(self) -> str:
        if self.recovery == 0:
            return "never lost"
        if self.recovery is None:
            return "not within the run"
        return f"valid at tick {self.recovery} after the fault"


def analyse(run: FaultRun, label: str, fault: str, expect: tuple[str, ...],
            window_s: tuple[float, float]) -> FaultRow:
    """One row of the fault table from a run; window_s = the fault's [start, end) in seconds."""
    from .ecu import COUNTERS
    from .frames import TICK_S

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
    health, valid_pct = {}, {}
    for w in "TS":
        states = []
        for h in run.health(w)[a:b]:
            if _HEALTH[h] not in states:
                states.append(_HEALTH[h])
        health[w] = states
        valid_pct[w] = 100.0 * float(run.valid(w)[a:b].mean()) if b > a else 100.0
    both = run.valid("T") & run.valid("S")
    if both[a:b].all():
        recovery = 0
    else:
        again = np.flatnonzero(both[b:])
        recovery = int(again[0]) + 1 if again.size else None
    vt = run.valid("T")
    ages = run.sample_age[a:][vt[a:]]
    oldest = 1e3 * float(np.nanmax(ages)) if ages.size else math.nan
    sel = np.flatnonzero(vt[a:b]) + a
    err = run.shaft_torque("T")[sel] - run.truth_to[sel]
    rms = float(np.sqrt(np.mean(err ** 2))) if sel.size >= 10 else math.nan   # too few valid ticks to say
    applied = sum(run.applied)
    return FaultRow(label, fault, expect, (a, b), detected, first, health, valid_pct, recovery, oldest, rms,
                    applied, run)


def fault_table(drive, catalogue=CATALOGUE, *, seed: int = 1, keep_runs: bool = False, progress=None,
                **wire) -> list[FaultRow]:
    """Run every case on the drive and analyse it (``wire``: bit rates, stuffing, queue for every case)."""
    rows = []
    for i, case in enumerate(catalogue):
        config = faults_from_cli([case.fault] if case.fault else [], seed=seed)
        window = (config.faults[0].start_s, config.faults[0].end_s) if config.faults else (2.0, 2.5)
        run = run_with_faults(drive, config, **{**wire, **case.wire})
        text = " ".join([case.fault, *(f"{k}={v}" for k, v in case.wire.items())])
        row = analyse(run, case.label, text, case.expect, window)
        if not keep_runs:
            row.run = None
        rows.append(row)
        if progress:
            progress(i + 1, len(catalogue))
    return rows


def format_table(rows: list[FaultRow], *, markdown: bool = False) -> list[str]:
    head = ("fault", "injected as", "ECU detects (counter rise)", "health during the fault", "recovery",
            "oldest sample, valid est.", "DkfT error while valid")
    body = [(r.label, r.fault or "-", r.detect_text(), r.health_text(), r.recovery_text(),
             f"{r.oldest_ms:.1f} ms", "-" if math.isnan(r.rms_nm) else f"{r.rms_nm:.1f} Nm RMS") for r in rows]
    if markdown:
        def cell(x):
            return x.replace("|", "\\|")
        lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
        lines += ["| " + " | ".join(cell(c) if j != 1 or c == "-" else f"`{c}`" for j, c in enumerate(row)) + " |"
                  for row in body]
        return lines
    widths = [max(len(r[i]) for r in (head, *body)) for i in range(len(head))]
    return ["  ".join(c.ljust(w) for c, w in zip(row, widths)).rstrip() for row in (head, *body)]


__all__ = ["KINDS", "DESCRIPTIONS", "FaultSpec", "FaultConfig", "FaultInjector", "Injected", "parse_fault",
           "faults_from_cli", "faults_from_dict", "load_faults", "flood_message", "FaultRun", "run_with_faults",
           "Case", "CATALOGUE", "FaultRow", "analyse", "fault_table", "format_table"]
