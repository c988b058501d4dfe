"""When a DBC frame must have a cycle time: the one rule `vehest-can busload`, `vehest-can hil --check`
and the firmware build (c_core/dbcgen.py) apply.

A frame is cyclic when its DBC says so in any of three ways:

* ``GenMsgSendType`` is a cyclic send type (``Cyclic``, ``CyclicIfActive``, ... : any value that starts
  with "Cyclic", any case; the message's own value, else the attribute's default);
* the message sets ``CycleTimeUs`` or ``GenMsgCycleTime`` itself (a ``BA_`` line, even one that gives 0),
  unless it also sets a non-cyclic ``GenMsgSendType`` itself (tools that write every attribute give event
  frames ``GenMsgSendType Event`` with ``GenMsgCycleTime 0``);
* the message has ``RxTimeoutCycles`` > 0: its receiver times it out, so it must arrive periodically.

A cyclic frame whose cycle time is 0 is an error, not an event frame: counted as an event frame it would
drop out of the bus load (a 2 kHz frame is half a 500 kbit/s bus) and out of the ECU's schedule.

This file imports nothing: dbcgen loads it alone, without the vehest_can package.
"""
from __future__ import annotations

_CYCLE_ATTRIBUTES = ("cycletimeus", "genmsgcycletime")


def cyclic_because(message) -> list[str]:
    """Why the DBC says the cantools `message` is sent periodically (empty: it does not)."""
    why = []
    send_type = getattr(message, "send_type", None)
    cyclic_type = isinstance(send_type, str) and send_type.lower().startswith("cyclic")
    if cyclic_type:
        why.append(f"GenMsgSendType = {send_type}")
    attrs = {k.lower(): (k, a.value) for k, a in ((message.dbc.attributes or {}).items() if message.dbc else ())}
    if cyclic_type or "genmsgsendtype" not in attrs:
        why += [f"{attrs[k][0]} = {attrs[k][1]!r}" for k in _CYCLE_ATTRIBUTES if k in attrs]
    timeout = attrs.get("rxtimeoutcycles", (None, 0))[1]
    if isinstance(timeout, (int, float)) and timeout > 0:
        why.append(f"RxTimeoutCycles = {timeout:g}: received with a timeout")
    return why


def zero_cycle_error(message, cycle_us: float | None) -> str | None:
    """The error of a cyclic `message` whose cycle time (µs; 0 or None: none) is missing, else None."""
    if cycle_us:
        return None
    why = cyclic_because(message)
    if not why:
        return None
    return (f"{message.name} (0x{message.frame_id:X}) is cyclic ({'; '.join(why)}) but has no cycle time: "
            f"give it a CycleTimeUs (µs) or GenMsgCycleTime (ms), or make it an event frame")
