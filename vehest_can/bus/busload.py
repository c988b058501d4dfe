"""Bus load of a CAN / CAN FD bus from its DBC: bits per frame, time on the wire, load per bus.

Works on any DBC cantools can read (not only ours). One DBC file = one bus.

Frame length in bits (upper bound "worst case" with bit stuffing, and "nominal" without dynamic stuff bits):

* Classic CAN (Davis, Burns, Bril, Lukkien 2007, "Controller Area Network (CAN) schedulability analysis:
  refuted, revisited and revised", Real-Time Systems 35(3), eq. (2)), n data bytes:

      11-bit ID: 8n + 47 + floor((34 + 8n - 1) / 4)      (8 bytes: 135 bits; 111 without stuff bits)
      29-bit ID: 8n + 67 + floor((54 + 8n - 1) / 4)      (8 bytes: 160 bits; 131 without stuff bits)

  47 = SOF 1, ID 11, RTR 1, IDE 1, r0 1, DLC 4, CRC 15 (= the 34 stuffable bits) plus CRC delimiter 1,
  ACK slot 1, ACK delimiter 1, EOF 7, intermission 3 (= 13 fixed-form bits). 29-bit IDs add SRR 1, ID 18,
  r1 1 to the stuffable part (54). A stuff bit follows 5 equal bits and itself starts the next run, so g
  stuffable bits carry at most floor((g - 1) / 4) stuff bits.

* CAN FD (ISO 11898-1:2015, FD base/extended format), n = payload bytes (a valid FD length):

      arbitration phase, nominal rate:  SOF 1, ID 11, RRS 1, IDE 1, FDF 1, res 1, BRS 1           = 17
                          29-bit ID:    SOF 1, ID 11, SRR 1, IDE 1, ID 18, RRS 1, FDF 1, res 1, BRS 1 = 36
      data phase, data rate if BRS:     ESI 1, DLC 4, data 8n,
                                        stuff count 4 (3-bit Gray code + parity), CRC 17 (n <= 16) or 21,
                                        fixed stuff bits ceil((4 + CRC) / 4) = 6 or 7 (one before the stuff
                                        count, then one after every 4th bit of stuff count + CRC)
      back at the nominal rate:         CRC delimiter 1, ACK slot 1, ACK delimiter 1, EOF 7, intermission 3 = 13

  Dynamic stuffing covers SOF .. end of data (arbitration + ESI + DLC + data = g bits): at most
  floor((g - 1) / 4) stuff bits. With BRS, the stuff bits that fall before the BRS bit (after bits 5, 9, 13,
  ... of the arbitration field; floor((A - 2) / 4) of them for an A-bit arbitration field: 3 for 11-bit, 8 for
  29-bit IDs) are sent at the nominal rate, the rest at the data rate; the worst-case pattern maximises both
  at once. BRS itself and the CRC delimiter are counted whole at the nominal rate (the rate switches at their
  sample points; counting them slow is the conservative choice). Without BRS every bit is at the nominal rate.
  The bound may count one dynamic stuff bit after the last data bit where ISO lets the first fixed stuff
  bit serve instead; it is an upper bound, by at most one bit.

"Nominal" load leaves out the dynamic stuff bits (fixed stuff bits stay: they are always sent).

Cycle time of a frame: the message attribute ``CycleTimeUs`` (project convention, in microseconds, exact)
when present and non-zero, else cantools' ``message.cycle_time`` (GenMsgCycleTime, ms; a FLOAT attribute
gives sub-millisecond cycles, 0.5 for 2 kHz). A frame that gives both must give the same time. Frames
with neither are event frames: listed, but not part of the cyclic load. A frame the DBC marks cyclic
(``vehest_can.bus.cyclic``: GenMsgSendType, a cycle attribute set to 0, RxTimeoutCycles) without a cycle
time is a ConfigError, not an event frame.
"""
from __future__ import annotations

import math
import os
from dataclasses import dataclass
from pathlib import Path

import cantools

from ..errors import ConfigError
from .cyclic import cycle_mismatch_error, zero_cycle_error

#: Payload lengths a CAN FD frame can have (DLC 0..15).
FD_LENGTHS = (0, 1, 2, 3, 4, 5, 6, 7, 8, 12, 16, 20, 24, 32, 48, 64)

# Fixed-form bits after the CRC: CRC delimiter, ACK slot, ACK delimiter, EOF 7, intermission 3.
_TAIL_BITS = 1 + 1 + 1 + 7 + 3


def stuff_bits_worst(stuffable_bits: int) -> int:
    """Most stuff bits `stuffable_bits` bits can need: one after the first 5, then one per 4 (Davis 2007)."""
    return max(0, (stuffable_bits - 1) // 4)


def fd_length(length: int) -> int:
    """The smallest valid CAN FD payload length >= `length` (ConfigError above 64 bytes)."""
    for valid in FD_LENGTHS:
        if valid >= length:
            return valid
    raise ConfigError(f"a CAN FD frame carries at most 64 bytes, not {length}")


def frame_bits(length: int, *, extended: bool = False, fd: bool = False, brs: bool = False,
               worst_case: bool = True) -> tuple[int, int]:
    """Bits of one data frame with `length` payload bytes: ``(nominal_rate_bits, data_rate_bits)``.

    `worst_case` adds the most dynamic stuff bits the frame can need; without it, none (fixed stuff bits of
    CAN FD are always counted). `data_rate_bits` is 0 unless `fd` and `brs`. Field-by-field accounting is in
    the module docstring.
    """
    if not fd:
        if brs:
            raise ConfigError("bit rate switching (BRS) exists only in CAN FD frames")
        if not 0 <= length <= 8:
            raise ConfigError(f"a classic CAN frame carries 0..8 bytes, not {length}")
        stuffable = (54 if extended else 34) + 8 * length          # SOF .. CRC sequence
        stuff = stuff_bits_worst(stuffable) if worst_case else 0
        return stuffable + _TAIL_BITS + stuff, 0                     # Davis 2007: 8n + 47 (67) + stuff

    if length not in FD_LENGTHS:
        raise ConfigError(f"{length} is not a CAN FD payload length (valid: {', '.join(map(str, FD_LENGTHS))})")
    arbitration = 36 if extended else 17                             # SOF .. BRS
    crc = 17 if length <= 16 else 21
    crc_field = 4 + crc + math.ceil((4 + crc) / 4)                   # stuff count, CRC, fixed stuff bits
    data_phase = 1 + 4 + 8 * length + crc_field                      # ESI, DLC, data, CRC field
    if worst_case:
        stuff_total = stuff_bits_worst(arbitration + 1 + 4 + 8 * length)   # SOF .. end of data
        stuff_arbitration = (arbitration - 2) // 4                   # stuff bits sent before BRS
    else:
        stuff_total = stuff_arbitration = 0
    if brs:
        return (arbitration + stuff_arbitration + _TAIL_BITS,
                data_phase + stuff_total - stuff_arbitration)
    return arbitration + data_phase + _TAIL_BITS + stuff_total, 0


def wire_time_us(bits: tuple[int, int], bitrate: float, data_bitrate: float | None = None) -> float:
    """Time on the wire in microseconds of ``(nominal_rate_bits, data_rate_bits)`` at the given rates."""
    nominal_bits, data_bits = bits
    if bitrate <= 0:
        raise ConfigError(f"bit rate must be positive, not {bitrate}")
    if data_bits and (data_bitrate is None or data_bitrate <= 0):
        raise ConfigError("data-phase bits need a positive data bit rate")
    return 1e6 * (nominal_bits / bitrate + (data_bits / data_bitrate if data_bits and data_bitrate else 0.0))


@dataclass(frozen=True)
class FrameLoad:
    """One frame of a bus: its bits, its time on the wire and its share of the bus."""

    name: str
    frame_id: int
    extended: bool
    length: int                      # payload bytes as the DBC says
    wire_length: int                 # payload bytes on the wire (DBC length rounded up to a valid FD length)
    fd: bool
    brs: bool
    cycle_us: float | None           # None: event frame (no cycle time in the DBC)
    cycle_source: str                # "CycleTimeUs", "GenMsgCycleTime" or "" for event frames
    bits_worst: tuple[int, int]      # (nominal-rate bits, data-rate bits), with worst-case stuff bits
    bits_nominal: tuple[int, int]    # the same without dynamic stuff bits
    wire_us_worst: float
    wire_us_nominal: float
    worst_pct: float                 # share of the bus, % (0 for event frames)
    nominal_pct: float
    notes: tuple[str, ...] = ()

    @property
    def event(self) -> bool:
        return self.cycle_us is None


@dataclass(frozen=True)
class BusLoad:
    """Load of one bus (one DBC file) at the given bit rates."""

    bus: str
    source: str
    bitrate: int
    data_bitrate: int | None
    frames: tuple[FrameLoad, ...]
    worst_pct: float                 # cyclic frames only
    nominal_pct: float
    notes: tuple[str, ...] = ()

    @property
    def cyclic_frames(self) -> int:
        return sum(not f.event for f in self.frames)

    @property
    def event_frames(self) -> int:
        return sum(f.event for f in self.frames)


def load_dbc(path: str | os.PathLike[str]) -> cantools.database.can.Database:
    """Read a DBC (or any format cantools reads) leniently: bus load does not care about signal overlaps."""
    path = Path(path)
    try:
        db = cantools.database.load_file(path, strict=False)
    except OSError as exc:
        raise ConfigError(f"cannot read {path}: {exc.strerror or exc}") from exc
    except Exception as exc:  # cantools raises many kinds on malformed input; the file is what is wrong
        # cantools quotes the offending line; of a binary file that is noise, so keep the location only.
        text = " ".join(str(exc).split(': ">>!<<')[0].replace('"', '').split())
        text = "".join(c if c.isascii() and c.isprintable() else "?" for c in text)
        raise ConfigError(f"{path} is not a readable DBC file: {text[:160]}") from exc
    if not isinstance(db, cantools.database.can.Database):
        raise ConfigError(f"{path} is not a CAN database")
    return db


def _dbc_attribute(db, names: tuple[str, ...], obj_attributes=None):
    """Value of a DBC attribute (first of `names`, any case): explicit value, else its BA_DEF_DEF_ default."""
    if db.dbc is None:
        return None, None
    wanted = {n.lower() for n in names}
    explicit = obj_attributes if obj_attributes is not None else db.dbc.attributes
    for key, attr in (explicit or {}).items():
        if key.lower() in wanted:
            return attr.value, key
    for key, definition in (db.dbc.attribute_definitions or {}).items():
        # Message attributes are kind BO_, network attributes have no kind.
        kind = "BO_" if obj_attributes is not None else None
        if key.lower() in wanted and (definition.kind or None) == kind:
            return definition.default_value, key
    return None, None


def _rate(value, what: str, source: str) -> int | None:
    """A bit rate from the CLI or a DBC attribute as a positive int; 0 / missing in a DBC means not set."""
    if value is None:
        return None
    try:
        number = float(value)
    except (TypeError, ValueError):
        raise ConfigError(f"{what} {value!r} ({source}) is not a number") from None
    if not math.isfinite(number) or number < 0 or number != int(number):
        raise ConfigError(f"{what} {value!r} ({source}) is not a positive whole number of bit/s")
    return int(number) or None


def _cycle_us(db, message, source: str) -> tuple[float | None, str]:
    """Cycle time in µs and where it came from; (None, "") for an event frame. A frame the DBC marks
    cyclic without a cycle time, or with two that disagree (GenMsgCycleTime, CycleTimeUs), is a ConfigError."""
    if error := cycle_mismatch_error(message):
        raise ConfigError(f"{source}: {error}")
    if message.dbc is not None:
        value, _ = _dbc_attribute(db, ("CycleTimeUs",), message.dbc.attributes or {})
        try:
            us = float(value) if value is not None else 0.0
        except (TypeError, ValueError):
            raise ConfigError(f"{source}: CycleTimeUs {value!r} of {message.name} is not a number") from None
        if math.isfinite(us) and us > 0:
            return us, "CycleTimeUs"
    if message.cycle_time and message.cycle_time > 0:
        return 1000.0 * message.cycle_time, "GenMsgCycleTime"
    error = zero_cycle_error(message, None)
    if error:
        raise ConfigError(f"{source}: {error}")
    return None, ""


def check_cycles(db, source: str = "<database>") -> None:
    """ConfigError when a frame of `db` is cyclic without a cycle time (see ``_cycle_us``)."""
    for message in db.messages:
        _cycle_us(db, message, source)


def bus_load(dbc, bitrate: int | None = None, data_bitrate: int | None = None, *,
             name: str | None = None) -> BusLoad:
    """Worst-case and nominal load of the bus described by `dbc` (a path or a loaded cantools Database).

    `bitrate` / `data_bitrate` (bit/s) override the DBC's ``Baudrate`` / ``BaudrateCANFD`` network
    attributes. FD frames use bit rate switching when a data bit rate is known. Raises ConfigError when the
    file is unusable or no nominal bit rate is known.
    """
    if isinstance(dbc, (str, os.PathLike)):
        source = str(dbc)
        bus = name or Path(dbc).stem
        db = load_dbc(dbc)
    else:
        db, source, bus = dbc, "<database>", name or "bus"

    notes: list[str] = []

    def rate(given, what: str, keys: tuple[str, str], required: bool) -> int | None:
        """A bit rate given, else from the DBC's network attribute (noted)."""
        if given is not None:
            value = _rate(given, what, "given")
            if value is None:
                raise ConfigError(f"{what} must be positive, not {given}")
            return value
        attr, key = _dbc_attribute(db, keys)
        value = _rate(attr, what, f"{key} in {source}")
        if value is None and required:
            raise ConfigError(f"{source} gives no {what} (no {keys[0]} attribute, or 0): give it with --bitrate")
        if value is not None:
            notes.append(f"{what} from the DBC attribute {key}")
        return value

    nominal = rate(bitrate, "bit rate", ("Baudrate", "BaudRate"), required=True)
    assert nominal is not None  # required
    data = rate(data_bitrate, "data bit rate", ("BaudrateCANFD", "BaudRateCANFD"), required=False)
    if data is not None and data < nominal:
        raise ConfigError(f"data bit rate {data} is lower than the nominal bit rate {nominal} ({source})")

    frames = []
    for message in db.messages:
        frame_notes = []
        fd = bool(message.is_fd)
        if message.length > 64:
            raise ConfigError(f"{source}: {message.name} has {message.length} bytes; CAN FD carries at most 64")
        if not fd and message.length > 8:
            fd = True
            frame_notes.append(f"{message.length} bytes need CAN FD; counted as an FD frame")
        wire_length = fd_length(message.length) if fd else message.length
        if wire_length != message.length:
            frame_notes.append(f"length {message.length} is no valid FD length; counted as {wire_length}")
        brs = fd and data is not None
        if fd and data is None:
            frame_notes.append("no data bit rate: FD frame counted without bit rate switching")
        kind = dict(extended=bool(message.is_extended_frame), fd=fd, brs=brs)
        worst = frame_bits(wire_length, worst_case=True, **kind)
        typical = frame_bits(wire_length, worst_case=False, **kind)
        wire_worst = wire_time_us(worst, nominal, data)
        wire_typical = wire_time_us(typical, nominal, data)
        cycle_us, cycle_source = _cycle_us(db, message, source)
        if cycle_us is None:
            frame_notes.append("event frame (no cycle time): not in the cyclic load")
        frames.append(FrameLoad(
            name=message.name, frame_id=message.frame_id, extended=kind["extended"],
            length=message.length, wire_length=wire_length, fd=fd, brs=brs,
            cycle_us=cycle_us, cycle_source=cycle_source, bits_worst=worst, bits_nominal=typical,
            wire_us_worst=wire_worst, wire_us_nominal=wire_typical,
            worst_pct=100.0 * wire_worst / cycle_us if cycle_us else 0.0,
            nominal_pct=100.0 * wire_typical / cycle_us if cycle_us else 0.0,
            notes=tuple(frame_notes)))
    frames.sort(key=lambda f: (f.frame_id, f.extended))
    return BusLoad(bus=bus, source=source, bitrate=nominal, data_bitrate=data, frames=tuple(frames),
                   worst_pct=sum(f.worst_pct for f in frames),
                   nominal_pct=sum(f.nominal_pct for f in frames), notes=tuple(notes))
