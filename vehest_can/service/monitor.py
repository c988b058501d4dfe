"""A live view of the ECU (``vehest-can monitor``): the latest value of every signal the ECU
publishes (its estimates, their validity, the health states, the fault counters), decoded through
the DBCs, with each message's rate and age; frames that fail their decode are counted, not shown."""
from __future__ import annotations

import time
from dataclasses import dataclass, field

import can

from ..bus.frames import BUSES, database


@dataclass
class _Seen:
    count: int = 0
    first: float = 0.0
    last: float = 0.0
    values: dict = field(default_factory=dict)


class Monitor:
    """Frames in (:meth:`feed`), a screen out (:meth:`render`)."""

    def __init__(self, nodes: frozenset[str] = frozenset({"VEHEST"})):
        self.messages = {m.frame_id: (b, m) for b in BUSES for m in database(b).messages
                         if set(m.senders) & nodes and not m.is_extended_frame}
        self.seen: dict[int, _Seen] = {}
        self.frames = self.other = self.undecodable = 0

    def feed(self, msg: can.Message, now: float | None = None) -> None:
        self.frames += 1
        entry = self.messages.get(msg.arbitration_id) if not msg.is_extended_id else None
        if entry is None or msg.is_error_frame or msg.is_remote_frame:
            self.other += 1
            return
        now = time.monotonic() if now is None else now
        try:
            values = entry[1].decode(bytes(msg.data), decode_choices=True)
        except Exception:  # noqa: BLE001 - cantools raises several kinds on a bad payload
            self.undecodable += 1
            return
        s = self.seen.setdefault(msg.arbitration_id, _Seen(first=now))
        s.count += 1
        s.last = now
        s.values = dict(values)

    def render(self, width: int = 100, now: float | None = None) -> list[str]:
        now = time.monotonic() if now is None else now
        lines = [f"vehest-can monitor: {self.frames} frames, {len(self.seen)} of {len(self.messages)} ECU messages "
                 f"heard, {self.other} other, {self.undecodable} undecodable"[:width]]
        for fid, (bus, m) in sorted(self.messages.items(), key=lambda kv: (kv[1][0], kv[0])):
            s = self.seen.get(fid)
            if s is None:
                lines.append(f"{bus} {fid:03X} {m.name}: not heard"[:width])
                continue
            span = s.last - s.first
            rate = f"{(s.count - 1) / span:.0f}/s" if span > 0 else "-"
            lines.append(f"{bus} {fid:03X} {m.name}: {s.count} frames, {rate}, {now - s.last:.1f} s ago"[:width])
            cells = [f"{k}={_fmt(v, m.get_signal_by_name(k).unit)}" for k, v in s.values.items()
                     if not k.endswith(("_CRC", "_Counter"))]
            lines += _wrap(cells, width, "    ")
        return lines


def _fmt(v, unit) -> str:
    if isinstance(v, float):
        text = f"{v:.4g}"
    else:
        text = str(v)
    return f"{text} {unit}" if unit else text


def _wrap(cells: list[str], width: int, indent: str) -> list[str]:
    out, line = [], indent
    for c in cells:
        if len(line) + len(c) + 2 > width and line.strip():
            out.append(line.rstrip())
            line = indent
        line += c + "  "
    if line.strip():
        out.append(line.rstrip())
    return out
