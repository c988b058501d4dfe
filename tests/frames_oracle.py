"""Test helpers on the wire: a sender of E2E-protected frames from physical values, and frame
equality on the wire. Not shipped: the product decodes and checks frames, it does not forge them."""
import can

from vehest_can.bus.frames import database, e2e_config
from vehest_can.native import ffi, lib


class E2ESender:
    """Encode a DBC message from physical values and protect it (its DBC's E2E profile, the firmware's own C)."""

    def __init__(self, bus: str = "pt"):
        self.db = database(bus)
        self._counters: dict[str, object] = {}

    def message(self, name: str, values: dict, *, protect: bool = True) -> can.Message:
        m = self.db.get_message_by_name(name)
        signals = {s.name: 0 for s in m.signals}
        signals.update(values)
        payload = bytearray(m.encode(signals, scaling=True, strict=False, padding=False))
        cfg = e2e_config(m)
        if protect and cfg is not None:
            counter = self._counters.setdefault(name, ffi.new("uint8_t *", 0))
            buf = ffi.new("uint8_t[]", bytes(payload))
            lib.vh_e2e_protect(cfg, buf, len(payload), counter)
            payload = bytearray(ffi.buffer(buf, len(payload)))
        return can.Message(arbitration_id=m.frame_id, is_extended_id=False, is_fd=m.is_fd,
                           bitrate_switch=m.is_fd, data=bytes(payload))


def same_frame(a: can.Message, b: can.Message) -> bool:
    """Equal on the wire (ID, ID type, FD, payload); timestamps and channels aside."""
    return (a.arbitration_id, a.is_extended_id, a.is_fd, bytes(a.data)) == (
        b.arbitration_id, b.is_extended_id, b.is_fd, bytes(b.data))
