"""Frames across the firmware boundary: ``vh_frame_t`` <-> ``can.Message``, and the DBC helpers."""
from __future__ import annotations

from collections.abc import Set as AbstractSet
from functools import cache
from typing import cast

import can
import cantools
import numpy as np

from ..native import ffi, lib, struct_dtype
from ..paths import dbc_path

TICK_S = lib.VH_TICK_US * 1e-6

#: numpy view of ``vh_frame_t`` (for bulk frame buffers filled by C loops)
FRAME_DTYPE = struct_dtype("vh_frame_t")


@cache
def database(bus: str = "pt") -> cantools.database.can.Database:
    return cast(cantools.database.can.Database, cantools.database.load_file(str(dbc_path(bus)), strict=True))


#: the ECU's buses: powertrain (driveline, camber) and chassis (tyre force, roll); IDs are unique across both
BUSES = ("pt", "ch")
#: the simulator's lockstep frames (SIM_Sync, VEHEST_SyncAck): no bus of the car, they ride on whichever
#: bus a lockstep session runs; their IDs are unique across every DBC too
SIM = "sim"
#: every bundled DBC
DBCS = (*BUSES, SIM)


@cache
def unused_frame_id(start: int = 0x123) -> int:
    """The first standard ID from `start` that no bundled DBC uses, nor the ECU's XCP identifiers
    (0x7E0/0x7E1): the "unknown frame" of hostile tests and the soak's sender, never a real one."""
    used = {m.frame_id for b in DBCS for m in database(b).messages} | {0x7E0, 0x7E1}
    return next(i for i in range(start, 0x800) if i not in used)


def sent_by(nodes: AbstractSet[str], bus: str | None = None) -> frozenset[int]:
    """Standard IDs the given DBC nodes transmit (in one DBC, or in every DBC, the simulator's too). A
    node ignores its own IDs on receive: some buses (python-can's udp_multicast) echo a sender's frames
    back to it."""
    return frozenset(m.frame_id for b in ((bus,) if bus else DBCS) for m in database(b).messages
                     if set(m.senders) & nodes and not m.is_extended_frame)


def message(name: str):
    """A message of any bundled DBC by name (names, like IDs, are unique across them)."""
    return _on_either_bus("get_message_by_name", name)


def message_by_id(frame_id: int):
    """The message of any bundled DBC with this standard ID (IDs are unique across them)."""
    return _on_either_bus("get_message_by_frame_id", frame_id)


def _on_either_bus(lookup: str, key):
    """``database(name).<lookup>(key)`` of the first DBC that has it; KeyError(key) when none does."""
    for bus in DBCS:
        try:
            return getattr(database(bus), lookup)(key)
        except KeyError:
            continue
    raise KeyError(key)


def is_own(msg: can.Message, own: frozenset[int]) -> bool:
    return not msg.is_extended_id and msg.arbitration_id in own


def frame_id(name: str, bus: str = "pt") -> int:
    return database(bus).get_message_by_name(name).frame_id


def to_message(frame, timestamp: float = 0.0, channel=None) -> can.Message:
    """``vh_frame_t`` (cdata or a FRAME_DTYPE record) -> ``can.Message`` (IDs always explicit)."""
    flags = int(frame["flags"] if isinstance(frame, np.void) else frame.flags)
    n = int(frame["len"] if isinstance(frame, np.void) else frame.len)
    data = bytes(frame["data"][:n]) if isinstance(frame, np.void) else bytes(ffi.buffer(frame.data)[:n])
    return can.Message(
        timestamp=timestamp,
        arbitration_id=int(frame["id"] if isinstance(frame, np.void) else frame.id),
        is_extended_id=bool(flags & lib.VH_FRAME_EXT),
        is_fd=bool(flags & lib.VH_FRAME_FD),
        bitrate_switch=bool(flags & lib.VH_FRAME_BRS),
        data=data,
        channel=channel,
    )


def to_frame(msg: can.Message, out=None):
    """``can.Message`` -> ``vh_frame_t`` cdata. Remote and error frames carry no payload."""
    out = out if out is not None else ffi.new("vh_frame_t *")
    data = bytes(msg.data or b"")[:64]
    out.id = msg.arbitration_id
    out.len = len(data)
    out.flags = (
        (lib.VH_FRAME_EXT if msg.is_extended_id else 0)
        | (lib.VH_FRAME_FD if msg.is_fd else 0)
        | (lib.VH_FRAME_BRS if msg.bitrate_switch else 0)
    )
    ffi.memmove(out.data, data.ljust(64, b"\0"), 64)
    return out


@cache
def _secoc_tails() -> dict[int, int]:
    """Frame ID -> authentic length, for the DBCs' SecOC-secured messages (attribute SecOCDataID)."""
    out = {}
    for bus in BUSES:
        for m in database(bus).messages:
            attrs = m.dbc.attributes if m.dbc else {}
            if "SecOCDataID" in attrs and attrs["SecOCDataID"].value:
                out[m.frame_id] = m.length - 4
    return out


def authentic_data(frame_id: int, data: bytes) -> bytes:
    """A frame's payload as its sender's application packed it: a SecOC-secured frame's tail (FV and
    MAC, docs/secoc.md) zeroed, which the E2E CRC covers as zeros. Verifying the tail is the SecOC
    receiver's job (vehest_can.bus.secoc); this is for tools that only decode."""
    n = _secoc_tails().get(frame_id)
    return data if n is None or len(data) <= n else data[:n] + bytes(len(data) - n)


def e2e_config(message):
    """The message's AUTOSAR E2E configuration (``vh_e2e_cfg_t *``, the firmware's own table generated
    from the DBC's E2E attributes by c_core/dbcgen.py), or None when it is not E2E-protected."""
    for bus in BUSES:
        cfg = getattr(lib, f"vh_{bus}_e2e_cfg")(message.frame_id)
        if cfg != ffi.NULL:
            return cfg
    return None


def e2e_check(cfg, rx, data: bytes) -> int:
    """One received frame through the firmware's E2E check (``vh_e2e_check``): a VH_E2E_* status."""
    return lib.vh_e2e_check(cfg, rx, data, len(data))


#: E2E statuses whose data may be used (a frame lost before this one does not spoil it)
E2E_USABLE = (lib.VH_E2E_OK, lib.VH_E2E_INITIAL, lib.VH_E2E_SKIPPED)
