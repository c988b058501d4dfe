"""What the master may see and change: a small table of measurements and characteristics.

One description drives both the slave's memory tables (regions, characteristic limits) and the
A2L file (``a2l.py``), so the two cannot disagree. It is a TOML file (or the same dicts in
Python)::

    [xcp]                       # transport and layout
    cro_id = 0x7F0              # master -> slave (add 0x80000000 for a 29-bit identifier)
    dto_id = 0x7F1
    max_cto = 8
    max_dto = 8
    fd = false
    measurement_address = 0x10000000
    calibration_address = 0x20000000

    [[event]]                   # the ECU's DAQ event channels, in channel order
    name = "tick"
    cycle_us = 500

    [[measurement]]
    name = "dkf_x0"             # the C name
    type = "float"              # C type
    unit = "Nm"
    min = -2000.0               # physical range
    max = 2000.0
    factor = 1.0                # physical = factor * raw + offset (COMPU_METHOD LINEAR)
    offset = 0.0
    comment = "..."

    [[characteristic]]
    name = "dkf_r_torque"
    type = "float"
    shape = [4, 4]              # optional: VAL_BLK of 16 elements
    ...

Addresses are given (``address``) or laid out in order with C alignment (each item at the next
multiple of its element size), which is what a C struct of the same members does.
"""
from __future__ import annotations

import math
import struct
import tomllib
from dataclasses import dataclass
from pathlib import Path

# C type -> (vh_xcp_type_t value, size, A2L datatype, pyxcp DAQ type, struct format, raw limits)
C_TYPES = {
    "uint8_t": (0, 1, "UBYTE", "U8", "B", (0, 255)),
    "int8_t": (1, 1, "SBYTE", "I8", "b", (-128, 127)),
    "uint16_t": (2, 2, "UWORD", "U16", "H", (0, 65535)),
    "int16_t": (3, 2, "SWORD", "I16", "h", (-32768, 32767)),
    "uint32_t": (4, 4, "ULONG", "U32", "I", (0, 2**32 - 1)),
    "int32_t": (5, 4, "SLONG", "I32", "i", (-(2**31), 2**31 - 1)),
    "float": (6, 4, "FLOAT32_IEEE", "F32", "f", (-3.4028234663852886e38, 3.4028234663852886e38)),
    "double": (7, 8, "FLOAT64_IEEE", "F64", "d", (-1.7976931348623157e308, 1.7976931348623157e308)),
}


#: a characteristic's safety class: "tuning" any value in range at any time; "safety" (monitors,
#: health thresholds, controller gains and limits) written only in the ECU's safe state
SAFETY_CLASSES = ("tuning", "safety")


class DescriptionError(ValueError):
    """The description cannot be laid out or is inconsistent."""


@dataclass(frozen=True)
class Item:
    """One measurement or characteristic."""

    name: str
    ctype: str
    kind: str  # "measurement" | "characteristic"
    address: int
    unit: str = ""
    min: float | None = None  # physical limits; None: the C type's range
    max: float | None = None
    factor: float = 1.0
    offset: float = 0.0
    shape: tuple[int, ...] = ()
    comment: str = ""
    initial: tuple[float, ...] = ()  # characteristic: raw reference-page value(s)
    safety_class: str = "tuning"  # characteristic: SAFETY_CLASSES

    @property
    def type_code(self) -> int:
        return C_TYPES[self.ctype][0]

    @property
    def element_size(self) -> int:
        return C_TYPES[self.ctype][1]

    @property
    def count(self) -> int:
        return math.prod(self.shape) if self.shape else 1

    @property
    def size(self) -> int:
        return self.count * self.element_size

    @property
    def compu_name(self) -> str:
        if self.factor == 1.0 and self.offset == 0.0:
            return "CM_IDENTICAL"
        return f"CM_{self.name}"

    def phys_limits(self) -> tuple[float, float]:
        lo, hi = (self.raw_to_phys(v) for v in C_TYPES[self.ctype][5])
        lo, hi = min(lo, hi), max(lo, hi)
        return (lo if self.min is None else self.min, hi if self.max is None else self.max)

    def raw_limits(self) -> tuple[float, float]:
        """The limits the slave checks: physical limits through the inverse conversion."""
        a, b = (self.phys_to_raw(v) for v in self.phys_limits())
        return (min(a, b), max(a, b))

    def raw_to_phys(self, raw: float) -> float:
        return self.factor * raw + self.offset

    def phys_to_raw(self, phys: float) -> float:
        return (phys - self.offset) / self.factor


@dataclass(frozen=True)
class Event:
    name: str
    cycle_us: int

    def xcp_cycle_unit(self) -> tuple[int, int]:
        """EVENT_CHANNEL_TIME_CYCLE (one byte) and EVENT_CHANNEL_TIME_UNIT (3 = 1 us ... 6 = 1 ms)."""
        cycle, unit = self.cycle_us, 3
        while cycle > 255:
            if cycle % 10:
                raise DescriptionError(f"event {self.name}: {self.cycle_us} us has no exact XCP cycle/unit")
            cycle, unit = cycle // 10, unit + 1
        return cycle, unit


@dataclass(frozen=True)
class Description:
    name: str
    cro_id: int
    dto_id: int
    max_cto: int
    max_dto: int
    fd: bool
    measurement_address: int
    calibration_address: int
    events: tuple[Event, ...]
    measurements: tuple[Item, ...]
    characteristics: tuple[Item, ...]
    bitrate: int = 500000
    data_bitrate: int = 0  # CAN FD data phase (bit rate switch); 0: not given
    tick_us: int = 500  # the ECU tick: one DAQ timestamp tick
    comment: str = ""

    @property
    def measurement_size(self) -> int:
        return max((m.address + m.size for m in self.measurements), default=self.measurement_address) - self.measurement_address

    @property
    def calibration_size(self) -> int:
        end = max((c.address + c.size for c in self.characteristics), default=self.calibration_address)
        return end - self.calibration_address

    def item(self, name: str) -> Item:
        for it in self.measurements + self.characteristics:
            if it.name == name:
                return it
        raise KeyError(name)


def _layout(rows: list[dict], kind: str, base: int) -> tuple[Item, ...]:
    items, pos, names = [], base, set()
    for row in rows:
        row = dict(row)
        name = row.pop("name")
        ctype = row.pop("type")
        if ctype not in C_TYPES:
            raise DescriptionError(f"{name}: unknown C type {ctype!r} (one of {', '.join(C_TYPES)})")
        if name in names or not name.isidentifier():
            raise DescriptionError(f"{name!r}: names must be unique C identifiers")
        names.add(name)
        size = C_TYPES[ctype][1]
        shape = tuple(row.pop("shape", ()))
        if kind == "measurement" and shape:
            raise DescriptionError(f"{name}: measurements are scalars (one DAQ entry each)")
        address = row.pop("address", None)
        if address is None:
            address = -(-pos // size) * size  # next multiple of the element size
        if address < pos:
            raise DescriptionError(f"{name}: address 0x{address:X} overlaps the item before it")
        initial = row.pop("initial", 0.0)
        initial = tuple(initial) if isinstance(initial, (list, tuple)) else (initial,) * (math.prod(shape) if shape else 1)
        if "class" in row:
            row["safety_class"] = row.pop("class")
            if kind != "characteristic" or row["safety_class"] not in SAFETY_CLASSES:
                raise DescriptionError(f"{name}: class is a characteristic's, one of {', '.join(SAFETY_CLASSES)}")
        unknown = set(row) - {"unit", "min", "max", "factor", "offset", "comment", "safety_class"}
        if unknown:
            raise DescriptionError(f"{name}: unknown keys {', '.join(sorted(unknown))}")
        item = Item(name=name, ctype=ctype, kind=kind, address=address, shape=shape, initial=initial, **row)
        if item.factor == 0.0:
            raise DescriptionError(f"{name}: factor 0 has no inverse")
        if len(item.initial) != item.count:
            raise DescriptionError(f"{name}: {len(item.initial)} initial values for {item.count} elements")
        lo, hi = item.raw_limits()
        if kind == "characteristic" and not all(lo <= v <= hi for v in item.initial):
            raise DescriptionError(f"{name}: an initial value is outside [{item.min}, {item.max}]")
        items.append(item)
        pos = address + item.size
    return tuple(items)


def from_dict(d: dict, name: str = "VEHEST") -> Description:
    x = d.get("xcp", {})
    events = tuple(Event(e["name"], int(e["cycle_us"])) for e in d.get("event", []))
    for ev in events:
        ev.xcp_cycle_unit()
    desc = Description(
        name=x.get("name", name),
        cro_id=int(x.get("cro_id", 0x7F0)),
        dto_id=int(x.get("dto_id", 0x7F1)),
        max_cto=int(x.get("max_cto", 8)),
        max_dto=int(x.get("max_dto", 8)),
        fd=bool(x.get("fd", False)),
        bitrate=int(x.get("bitrate", 500000)),
        data_bitrate=int(x.get("data_bitrate", 0)),
        tick_us=int(x.get("tick_us", 500)),
        measurement_address=int(x.get("measurement_address", 0x10000000)),
        calibration_address=int(x.get("calibration_address", 0x20000000)),
        events=events,
        measurements=_layout(d.get("measurement", []), "measurement", int(x.get("measurement_address", 0x10000000))),
        characteristics=_layout(d.get("characteristic", []), "characteristic",
                                int(x.get("calibration_address", 0x20000000))),
        comment=x.get("comment", ""),
    )
    if not desc.fd and (desc.max_cto > 8 or desc.max_dto > 8):
        raise DescriptionError("MAX_CTO/MAX_DTO above 8 need CAN FD (fd = true)")
    return desc


def load(path: str | Path) -> Description:
    path = Path(path)
    with path.open("rb") as f:
        return from_dict(tomllib.load(f), name=path.stem.upper())


def raw_limits_for_c(item: Item) -> tuple[float, float]:
    """Raw limits as the C slave compares them: a float32 limit is rounded to float32, so the value a
    master writes for a limit (itself rounded to float32) is accepted."""
    lo, hi = item.raw_limits()
    if item.ctype != "float":
        return lo, hi
    return tuple(struct.unpack("<2f", struct.pack("<2f", lo, hi)))
