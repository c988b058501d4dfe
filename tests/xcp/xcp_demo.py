"""The tests' XCP rig: the ECU's C XCP slave (``vh_xcp``, in ``vehest_can._native``) on its own, over
a memory image laid out by a small description (``data/demo.toml``), so that the protocol is
tested command by command against pyxcp without an ECU around it.

The memory it serves is an image owned here: one buffer of measurements (``measurements``, written
by the test) and the three calibration buffers (reference page, working page, the ECU's view). The
slave only ever sees them as caller-owned memory, exactly as it sees the ECU's own structs.
"""
from __future__ import annotations

import struct
from dataclasses import dataclass
from pathlib import Path

from vehest_can.native import ffi, lib
from vehest_can.xcp import calfile
from vehest_can.xcp.description import C_TYPES, Description, Item, raw_limits_for_c

XCP_ERRORS = {
    0x00: "ERR_CMD_SYNCH", 0x10: "ERR_CMD_BUSY", 0x11: "ERR_DAQ_ACTIVE", 0x12: "ERR_PGM_ACTIVE",
    0x20: "ERR_CMD_UNKNOWN", 0x21: "ERR_CMD_SYNTAX", 0x22: "ERR_OUT_OF_RANGE",
    0x23: "ERR_WRITE_PROTECTED", 0x24: "ERR_ACCESS_DENIED", 0x25: "ERR_ACCESS_LOCKED",
    0x26: "ERR_PAGE_NOT_VALID", 0x27: "ERR_MODE_NOT_VALID", 0x28: "ERR_SEGMENT_NOT_VALID",
    0x29: "ERR_SEQUENCE", 0x2A: "ERR_DAQ_CONFIG", 0x30: "ERR_MEMORY_OVERFLOW", 0x31: "ERR_GENERIC",
    0x32: "ERR_VERIFY", 0x33: "ERR_RESOURCE_TEMPORARY_NOT_ACCESSIBLE",
}
DEMO = Path(__file__).with_name("data") / "demo.toml"
EXTENDED = 0x80000000  # XCP-on-CAN convention: bit 31 of an identifier marks a 29-bit one
COUNTERS = [f[0] for f in ffi.typeof("vh_xcp_counters_t").fields]


class XcpConfigError(ValueError):
    """The C slave refused its configuration."""


@dataclass(frozen=True)
class Frame:
    arbitration_id: int
    is_extended_id: bool
    is_fd: bool
    data: bytes




class Slave:
    """One C slave instance and the memory it serves (all kept alive by this object)."""

    def __init__(self, desc: Description, *, key: bytes, protect: int = 0x05,
                 tick_us: int | None = None, open_ticks: int = 200, pad8: bool = False,
                 ident: str = "vehest-can ECU XCP slave", salt: bytes = bytes(8),
                 unlock_delay_ticks: int = 1000, unlock_attempts: int = 5, safe: bool | None = None):
        """`key`: the 16-byte seed & key key; `safe`: None (no safe state: every class writable), or
        the initial value of a safe-state flag the caller sets with ``set_safe``."""
        self.desc = desc
        self.key = key
        self._keep = []
        self._cmac = ffi.new("vh_cmac_key_t *")
        if len(key) != 16 or lib.vh_cmac_init(self._cmac, key) != 0:
            raise XcpConfigError("the seed & key key must be 16 bytes (AES-128)")
        self._safe = ffi.new("uint8_t *", int(bool(safe)))
        self.measurements = ffi.new("uint8_t[]", max(desc.measurement_size, 1))
        cal = max(desc.calibration_size, 1)
        self.cal_ref = ffi.new("uint8_t[]", self._reference_image(cal))
        self.cal_work = ffi.new("uint8_t[]", cal)
        self.cal_ecu = ffi.new("uint8_t[]", cal)
        regions = ffi.new("vh_xcp_region_t[]", 1)
        regions[0].address = desc.measurement_address
        regions[0].size = max(desc.measurement_size, 1)
        regions[0].access = lib.VH_XCP_ACC_READ | lib.VH_XCP_ACC_DAQ
        regions[0].mem = self.measurements
        chars = ffi.new("vh_xcp_char_t[]", max(len(desc.characteristics), 1))
        for i, c in enumerate(desc.characteristics):
            chars[i].address = c.address
            chars[i].count = c.count
            chars[i].type = c.type_code
            chars[i].flags = lib.VH_XCP_CHAR_SAFETY if c.safety_class == "safety" else 0
            chars[i].min, chars[i].max = raw_limits_for_c(c)
        events = ffi.new("vh_xcp_event_t[]", max(len(desc.events), 1))
        for i, ev in enumerate(desc.events):
            events[i].cycle, events[i].unit = ev.xcp_cycle_unit()
            self._keep.append(ffi.new("char[]", ev.name.encode()))
            events[i].name = self._keep[-1]
        id_ascii = ffi.new("char[]", ident.encode())
        id_a2l = ffi.new("char[]", desc.name.encode())
        self._keep += [regions, chars, events, id_ascii, id_a2l]
        cfg = ffi.new("vh_xcp_config_t *")
        cfg.cro_id, cfg.dto_id = desc.cro_id, desc.dto_id
        cfg.max_cto, cfg.max_dto, cfg.fd, cfg.pad8 = desc.max_cto, desc.max_dto, desc.fd, pad8
        cfg.protect, cfg.key, cfg.salt, cfg.open_ticks = protect, self._cmac, salt, open_ticks
        cfg.unlock_delay_ticks, cfg.unlock_attempts = unlock_delay_ticks, unlock_attempts
        cfg.safe = ffi.NULL if safe is None else self._safe
        cfg.tick_us = desc.tick_us if tick_us is None else tick_us
        cfg.regions, cfg.n_regions = regions, 1
        cfg.cal_address, cfg.cal_size = desc.calibration_address, desc.calibration_size
        cfg.cal_ref, cfg.cal_work, cfg.cal_ecu = self.cal_ref, self.cal_work, self.cal_ecu
        cfg.chars, cfg.n_chars = chars, len(desc.characteristics)
        cfg.events, cfg.n_events = events, len(desc.events)
        cfg.id_ascii, cfg.id_a2l = id_ascii, id_a2l
        self.x = ffi.new("vh_xcp_t *")
        if lib.vh_xcp_init(self.x, cfg) != lib.VH_XCP_OK:
            raise XcpConfigError(f"vh_xcp_init refused the configuration of {desc.name}")
        self._out = ffi.new("vh_xcp_frame_t *")

    def _reference_image(self, size: int) -> bytes:
        img = bytearray(size)
        for c in self.desc.characteristics:
            fmt = "<" + C_TYPES[c.ctype][4] * c.count
            vals = [int(v) if c.ctype not in ("float", "double") else v for v in c.initial]
            struct.pack_into(fmt, img, c.address - self.desc.calibration_address, *vals)
        return bytes(img)

    # -- the C API, one call each ---------------------------------------------------------------
    def reset(self) -> None:
        lib.vh_xcp_reset(self.x)

    def tick(self, tick: int) -> None:
        lib.vh_xcp_tick(self.x, tick & 0xFFFFFFFF)

    def rx(self, cro: bytes, tick: int = 0) -> None:
        lib.vh_xcp_rx(self.x, cro, len(cro), tick & 0xFFFFFFFF)

    def event(self, channel: int) -> None:
        lib.vh_xcp_event(self.x, channel)

    def frames(self) -> list[Frame]:
        out = []
        while lib.vh_xcp_tx_pop(self.x, self._out):
            f = self._out
            out.append(Frame(f.id, bool(f.ext), bool(f.fd), bytes(f.data[0:f.len])))
        return out

    def counters(self) -> dict[str, int]:
        return {name: getattr(self.x.n, name) for name in COUNTERS}

    def set_safe(self, safe: bool) -> None:
        """The caller's safe state (given `safe` at construction)."""
        self._safe[0] = int(bool(safe))

    # -- the memory image -----------------------------------------------------------------------
    def _buf(self, item: Item, which: str):
        if item.kind == "measurement":
            return self.measurements, item.address - self.desc.measurement_address
        buf = {"ecu": self.cal_ecu, "work": self.cal_work, "ref": self.cal_ref}[which]
        return buf, item.address - self.desc.calibration_address

    def read(self, name: str, page: str = "ecu"):
        """Raw value(s) of an item: for a characteristic, what the ECU sees (``ecu``), the working
        page (``work``) or the reference page (``ref``)."""
        item = self.desc.item(name)
        buf, off = self._buf(item, page)
        vals = struct.unpack("<" + C_TYPES[item.ctype][4] * item.count, bytes(ffi.buffer(buf)[off:off + item.size]))
        return vals[0] if item.count == 1 and not item.shape else list(vals)

    def write_measurement(self, name: str, raw) -> None:
        item = self.desc.item(name)
        if item.kind != "measurement":
            raise KeyError(f"{name} is a characteristic: the master writes those")
        buf, off = self._buf(item, "ecu")
        ffi.buffer(buf)[off:off + item.size] = struct.pack("<" + C_TYPES[item.ctype][4], raw)


def cal_values(slave: Slave, page: str = "work") -> dict:
    """Physical values of every characteristic on a page (``work``, ``ecu`` or ``ref``)."""
    return calfile.values_of(slave.desc, lambda name: slave.read(name, page))


def save_cal(slave: Slave, path, page: str = "work") -> None:
    calfile.save_values(slave.desc, cal_values(slave, page), path)


def load_cal(slave: Slave, path) -> dict:
    """Validates the file against the slave's description and applies it; returns the values."""
    image, vals = calfile.load_image(slave.desc, path, bytes(ffi.buffer(slave.cal_work)))
    ffi.buffer(slave.cal_work)[:] = image
    ffi.buffer(slave.cal_ecu)[:] = image
    return vals

