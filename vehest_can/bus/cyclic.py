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

A frame that gives both ``GenMsgCycleTime`` (ms, what cantools and canmatrix read) and ``CycleTimeUs`` (µs,
what the firmware is generated from) non-zero must give the same time in both: otherwise the DBC tools show
one schedule and the ECU runs another.

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


def cycle_mismatch_error(message) -> str | None:
    """The error of a `message` whose own non-zero GenMsgCycleTime (ms) and CycleTimeUs (µs) differ, else None."""
    attrs = {k.lower(): a.value for k, a in ((message.dbc.attributes or {}).items() if message.dbc else ())}
    if not set(_CYCLE_ATTRIBUTES) <= set(attrs):
        return None
    try:
        ms, us = float(attrs["genmsgcycletime"] or 0), float(attrs["cycletimeus"] or 0)
    except (TypeError, ValueError):
        return None  # not numbers: the readers say so
    if not ms or not us or round(ms * 1000) == round(us):  # 0: not given (tools write 0 for "none")
        return None
    return (f"{message.name} (0x{message.frame_id:X}): GenMsgCycleTime = {ms:g} ms and CycleTimeUs = {us:g} us "
            f"disagree: give both the same cycle time")


def zero_cycle_error(message, cycle_us: float | None) -> str | None:
    """The error of a cyclic `message` whose cycle time (µs; 0 or None: none) is missing, else None."""
    if cycle_us:
        return None
    why = cyclic_because(message)
    if not why:
        return None
    return (f"{message.name} (0x{message.frame_id:X}) is cyclic ({'; '.join(why)}) but has no cycle time: "
            f"give it a CycleTimeUs (µs) or GenMsgCycleTime (ms), or make it an event frame")
