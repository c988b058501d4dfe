"""Fault injection at a sending node: drop, corrupt, freeze or skip counters, wrong DLC, silence, flood,
latency and jitter. Pure and seeded: the same configuration, seed and input give the same output.

A :class:`FaultConfig` is a list of :class:`FaultSpec` (kind, target, time window, amounts) and a seed.
It comes from a ``[faults]`` table in a TOML file (:func:`load_faults`) or from command-line strings
(:func:`parse_fault`, syntax ``KIND[:TARGET][:KEY=VALUE...][:START-END]``). The schema, the fault table
and how to wrap a bus are in ``docs/faults.md``.

:class:`FaultInjector` transforms the frames one node sends at one time ``t_s`` (seconds since the
run started): frames in, ``(frame, delay_s)`` out. The delay (latency + jitter) is for the wire model
(:mod:`vehest_can.faults.wire`), which also produces the flood frames. Frames of one ID keep their order
however they are delayed: a controller's transmit queue does not overtake itself.

Sync frames (SIM_Sync, VEHEST_SyncAck) belong to the test bench, not the car: node targets and ``*``
leave them alone; only naming them as the target hits them.
"""
from __future__ import annotations

import math
import re
from dataclasses import dataclass, fields
from pathlib import Path
from typing import cast

from ..bus.busload import FD_LENGTHS
from ..bus.frames import DBCS, database, e2e_config, message, message_by_id
from ..errors import ConfigError
from ..schema import Checker, read_toml

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
    "sna": ("signal",),
    "stuck": ("signal",),
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
    "sna": "the target message's `signal` is sent as not available (its SNA value, its Qf_ qualifier INVALID): "
           "a dead sensor; CRC recomputed",
    "stuck": "the target message's `signal` keeps the value it had when the fault began (qualifier untouched): "
             "a stuck sensor; CRC recomputed",
}
_DEFAULTS = {"p": 1.0, "by": 2, "length": None, "id": 0x001, "load": 1.0, "us": 0.0, "max_us": 0.0,
             "signal": None}
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
    signal: str | None = None

    def active(self, t_s: float) -> bool:
        return self.start_s <= t_s < self.end_s

    def text(self) -> str:
        """The command-line form of this fault (round-trips through :func:`parse_fault`)."""
        parts = [self.kind] + ([self.target] if self.target else [])
        for key in KINDS[self.kind]:
            value = getattr(self, key)
            if value != _DEFAULTS[key]:
                parts.append(f"{key}=0x{value:03X}" if key == "id" else
                             f"{key}={value}" if key == "signal" else f"{key}={_num(value)}")
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



# ---- validation --------------------------------------------------------------------------------

def _names(bus: str = "pt") -> tuple[set[str], set[str]]:
    """Messages and nodes of every DBC (names are unique across them; `bus` is kept for callers)."""
    dbs = [database(b) for b in DBCS]
    return {m.name for db in dbs for m in db.messages}, {n.name for db in dbs for n in db.nodes}


def _validate(spec: FaultSpec, where: str, bus: str = "pt") -> None:
    """ConfigError naming `where` and the key for anything a run could not use."""
    fail = Checker(where, ConfigError).fail

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
    if spec.kind in ("sna", "stuck"):
        if spec.target not in messages:
            fail("target", f"a {spec.kind} fault names one message, not {spec.target!r}")
        sig = {s.name: s for s in message(spec.target).signals}.get(spec.signal or "")
        if sig is None:
            names = sorted(s.name for s in message(spec.target).signals)
            fail("signal", f"{spec.signal!r} is not a signal of {spec.target} ({', '.join(names)})")
        if spec.kind == "sna" and not any(str(v) == "SNA" for v in (sig.choices or {}).values()):
            fail("signal", f"{spec.signal} has no SNA value in the DBC")
    elif spec.signal is not None:
        fail("signal", f"only sna and stuck faults take a signal, not {spec.kind}")
    if spec.kind == "skip_counter" and spec.target != "*":
        ids = _target_ids(cast(str, spec.target), bus)   # _validate: every kind but flood has one
        if not any(e2e_config(message_by_id(i)) is not None for i in ids):
            fail("target", f"{spec.target} sends no E2E-protected frame: there is no counter to skip")


def _target_ids(target: str, bus: str = "pt") -> frozenset[int]:
    """The standard IDs a target names, in every DBC (`bus` is kept for callers)."""
    msgs = [m for b in DBCS for m in database(b).messages]
    if target in {m.name for m in msgs}:
        return frozenset({message(target).frame_id})
    return frozenset(m.frame_id for m in msgs
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
            values[key] = raw.strip() if key == "signal" else _number(raw.strip(), key, where)
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
    fail = Checker(where, ConfigError).fail

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
            if k in ("target", "signal") and not isinstance(v, str):
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
    doc = read_toml(path, ConfigError)
    if "faults" not in doc:
        raise ConfigError(f"{path}: faults: missing (the file has no [faults] table)")
    return faults_from_dict(doc["faults"], str(path))
