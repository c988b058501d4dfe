"""A small XCP master for the command line: read and write the ECU's named items by their C
names (``vehest-can xcp get/set``). Polling only (CONNECT, GET_SEED/UNLOCK, SET_MTA, UPLOAD,
SHORT_UPLOAD, DOWNLOAD, DISCONNECT; codes of ASAM MCD-1 XCP Part 2); DAQ and anything larger
is what pyxcp or a calibration tool is for (docs/xcp.md has the pyxcp configuration).
"""
from __future__ import annotations

import struct
import time

import can

from ..errors import VehestError
from .description import C_TYPES, Description, Item
from .keys import key_for

ERRORS = {0x10: "ERR_CMD_BUSY", 0x11: "ERR_DAQ_ACTIVE", 0x20: "ERR_CMD_UNKNOWN", 0x21: "ERR_CMD_SYNTAX",
          0x22: "ERR_OUT_OF_RANGE", 0x23: "ERR_WRITE_PROTECTED", 0x24: "ERR_ACCESS_DENIED",
          0x25: "ERR_ACCESS_LOCKED", 0x26: "ERR_PAGE_NOT_VALID", 0x29: "ERR_SEQUENCE", 0x31: "ERR_GENERIC",
          0x33: "ERR_RESOURCE_TEMPORARY_NOT_ACCESSIBLE"}
EXT = 0x80000000
RES_CALPAG = 0x01


class XcpError(VehestError):
    """The slave answered with an ERR packet, or did not answer."""


class Master:
    def __init__(self, bus: can.BusABC, desc: Description, *, timeout: float = 1.0):
        self.bus, self.desc, self.timeout = bus, desc, timeout

    def _cmd(self, name: str, *data: int) -> bytes:
        d = self.desc
        self.bus.send(can.Message(arbitration_id=d.cro_id & ~EXT, is_extended_id=bool(d.cro_id & EXT),
                                  is_fd=d.fd, data=bytes(data)))
        end = time.monotonic() + self.timeout
        while (left := end - time.monotonic()) > 0:
            m = self.bus.recv(left)
            if m is None or m.arbitration_id != d.dto_id & ~EXT or not m.data or m.data[0] < 0xFE:
                continue  # other traffic, DTOs
            if m.data[0] == 0xFE:
                code = m.data[1] if len(m.data) > 1 else 0
                raise XcpError(f"XCP {ERRORS.get(code, 'error')} (0x{code:02X}) for {name}")
            return bytes(m.data)
        raise XcpError(f"no XCP answer to {name} on CRO 0x{d.cro_id:X} within {self.timeout:g} s: is the "
                       "ECU daemon running on this bus, with --xcp on and the same identifiers?")

    def connect(self, key: bytes | None = None) -> None:
        """CONNECT and, with the seed & key `key` (keys.load_key), unlock calibration."""
        self._cmd("CONNECT", 0xFF, 0x00)
        if key is not None:
            seed = self._cmd("GET_SEED", 0xF8, 0x00, RES_CALPAG)
            if seed[1] == 0:
                return  # unlocked already
            answer = key_for(seed[2:2 + seed[1]], RES_CALPAG, key)
            self._cmd("UNLOCK", 0xF7, len(answer), *answer)

    def disconnect(self) -> None:
        self._cmd("DISCONNECT", 0xFE)

    def _mta(self, address: int) -> None:
        self._cmd("SET_MTA", 0xF6, 0, 0, 0, *struct.pack("<I", address))

    def upload(self, address: int, n: int) -> bytes:
        self._mta(address)
        out = b""
        while len(out) < n:
            k = min(n - len(out), self.desc.max_cto - 1)
            out += self._cmd("UPLOAD", 0xF5, k)[1:1 + k]
        return out

    def download(self, address: int, blob: bytes) -> None:
        self._mta(address)
        step = self.desc.max_cto - 2
        for i in range(0, len(blob), step):
            chunk = blob[i:i + step]
            self._cmd("DOWNLOAD", 0xF0, len(chunk), *chunk)

    # -- named items ----------------------------------------------------------------------------
    def read_raw(self, item: Item) -> list:
        return list(struct.unpack("<" + C_TYPES[item.ctype][4] * item.count, self.upload(item.address, item.size)))

    def read(self, item: Item) -> list[float]:
        return [item.raw_to_phys(v) for v in self.read_raw(item)]

    def write(self, item: Item, values: list[float], index: int = 0) -> None:
        """Physical values from element `index` on, converted to raw (rounded for integer types)."""
        fmt = C_TYPES[item.ctype][4]
        raw = [item.phys_to_raw(v) for v in values]
        if item.ctype not in ("float", "double"):
            raw = [int(round(v)) for v in raw]
        try:
            blob = struct.pack("<" + fmt * len(raw), *raw)
        except struct.error as exc:
            raise XcpError(f"{item.name}: a value does not fit its C type {item.ctype}: {exc}") from None
        self.download(item.address + index * item.element_size, blob)
