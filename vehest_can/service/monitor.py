"""A live view of a bus (``vehest-can monitor``): every frame decoded through the bundled DBCs and
the user's own (``--dbc``), with each message's count, rate and age; the ECU's messages are listed
even before they are heard; frames of an ID in no DBC are shown raw. Two views of the same frames:
decoded (the latest value of each signal) and raw (the latest payload in hex, like cansniffer), and
a filter (a case-insensitive regular expression on message names, IDs, buses and signal names, as
``cantools monitor``'s).

Frames are only counted and kept as they come (:meth:`Monitor.feed`: a few hundred ns); decoding
happens when a screen is drawn, a few times a second, whatever the bus load."""
from __future__ import annotations

import copy
import re
import time
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import can
import cantools
from cantools.database.can import Message

from ..bus.frames import DBCS, database
from ..errors import ConfigError

#: signals left out of the decoded view unless the filter names them: they change every frame
_NOISE = ("_CRC", "_Counter")


@dataclass
class _Seen:
    count: int = 0
    first: float = 0.0
    last: float = 0.0
    data: bytes = b""
    fd: bool = False
    brs: bool = False
    bad_length: int = 0  # frames whose length is not the DBC's: not decodable


@dataclass(frozen=True)
class _Entry:
    bus: str       # the bus (bundled DBC) or the user DBC's file name
    message: Message


def load_dbc(path: str | Path):
    """A user's DBC (any format cantools reads, by extension), not strict: a monitor only decodes, so a
    database that cantools' strict checks refuse (overlapping signals, say) is still shown."""
    p = Path(path)
    if p.is_dir():
        raise ConfigError(f"--dbc {p}: is a folder, not a DBC file")
    if not p.is_file():
        raise ConfigError(f"--dbc {p}: no such file")
    try:
        return cantools.database.load_file(str(p), strict=False)
    except Exception as exc:  # noqa: BLE001 - cantools' parsers raise many kinds on a bad file
        raise ConfigError(f"--dbc {p}: not a database cantools reads ({type(exc).__name__}: {exc})") from exc


def compile_filter(text: str | None) -> re.Pattern | None:
    """The filter as a case-insensitive regular expression; text that is not one (``CntTime(``, half
    typed) is taken literally, so the view never empties on a typo. Empty: no filter."""
    if not text:
        return None
    try:
        return re.compile(text, re.IGNORECASE)
    except re.error:
        return re.compile(re.escape(text), re.IGNORECASE)


def _id_text(key: tuple[int, bool]) -> str:
    fid, ext = key
    return f"{fid:08X}" if ext else f"{fid:03X}"


class Monitor:
    """Frames in (:meth:`feed`), screens out (:meth:`render`, or :meth:`header` and :meth:`body`)."""

    def __init__(self, dbcs: Iterable[str | Path] = (), nodes: frozenset[str] = frozenset({"VEHEST"})):
        """`dbcs`: the user's databases, over the bundled ones (an ID in both is the user's: one's own
        DBC describes one's own bus). `nodes`: whose messages are listed before they are heard."""
        self.catalogue: dict[tuple[int, bool], _Entry] = {}
        for p in dbcs:
            db = load_dbc(p)
            for m in db.messages:
                self.catalogue.setdefault((m.frame_id, bool(m.is_extended_frame)), _Entry(Path(p).stem, m))
        for b in DBCS:
            for m in database(b).messages:
                self.catalogue.setdefault((m.frame_id, bool(m.is_extended_frame)), _Entry(b, m))
        self.listed = frozenset(k for k, e in self.catalogue.items() if set(e.message.senders) & nodes)
        self.reset()

    def reset(self) -> None:
        self.seen: dict[tuple[int, bool], _Seen] = {}
        self.frames = self.not_data = 0

    def snapshot(self) -> Monitor:
        """A copy that no later frame changes (a paused screen), sharing the databases."""
        frozen = copy.copy(self)
        frozen.seen = {k: copy.copy(s) for k, s in self.seen.items()}
        return frozen

    def feed(self, msg: can.Message, now: float | None = None) -> None:
        self.frames += 1
        if msg.is_error_frame or msg.is_remote_frame:
            self.not_data += 1
            return
        now = time.monotonic() if now is None else now
        key = (msg.arbitration_id, bool(msg.is_extended_id))
        s = self.seen.get(key)
        if s is None:
            s = self.seen[key] = _Seen(first=now)
        s.count += 1
        s.last = now
        s.data = bytes(msg.data)
        s.fd, s.brs = bool(msg.is_fd), bool(msg.bitrate_switch)
        entry = self.catalogue.get(key)
        if entry is not None and len(s.data) != entry.message.length:
            s.bad_length += 1

    # -- the screen -----------------------------------------------------------------------------
    @property
    def unknown(self) -> list[tuple[int, bool]]:
        """IDs heard that no database describes."""
        return sorted(k for k in self.seen if k not in self.catalogue)

    def header(self, width: int = 100) -> str:
        heard = [k for k in self.seen if k in self.catalogue]
        bad = sum(s.bad_length for s in self.seen.values())
        ecu = sum(k in self.seen for k in self.listed)
        text = (f"vehest-can monitor: {self.frames} frames, {len(heard)} messages heard ({ecu} of {len(self.listed)} "
                f"ECU), {len(self.unknown)} IDs in no DBC, {bad} undecodable")
        if self.not_data:
            text += f", {self.not_data} error/remote"
        return text[:width]

    def body(self, width: int = 100, now: float | None = None, *, pattern: re.Pattern | None = None,
             raw: bool = False) -> list[str]:
        """The message lines, bus by bus and ID by ID: the ECU's messages always, the others once heard,
        then the IDs in no DBC; only what `pattern` matches."""
        now = time.monotonic() if now is None else now
        keys = set(self.listed) | set(self.seen)
        label = max((len(self._bus(k)) for k in keys), default=2)
        order = {b: i for i, b in enumerate(DBCS)}
        lines: list[str] = []
        for key in sorted(keys, key=lambda k: (k not in self.catalogue, order.get(self._bus(k), -1), self._bus(k), k)):
            lines += self._lines(key, width, now, pattern, raw, label)
        return lines

    def render(self, width: int = 100, now: float | None = None, *, pattern: re.Pattern | None = None,
               raw: bool = False) -> list[str]:
        return [self.header(width), *self.body(width, now, pattern=pattern, raw=raw)]

    def _bus(self, key: tuple[int, bool]) -> str:
        e = self.catalogue.get(key)
        return e.bus if e is not None else "--"

    def _lines(self, key, width: int, now: float, pattern, raw: bool, label: int) -> list[str]:
        entry = self.catalogue.get(key)
        name = entry.message.name if entry is not None else "(in no DBC)"
        bus, ident = self._bus(key), _id_text(key)
        whole = pattern is None or any(pattern.search(t) for t in (name, ident, f"0x{ident}", bus))
        s = self.seen.get(key)
        signals = None
        if not whole:
            if raw or entry is None:
                return []
            signals = [sg.name for sg in entry.message.signals if pattern.search(sg.name)]
            if not signals:
                return []
        head = f"{bus:<{label}} {ident} {name}"
        if s is None:  # an ECU message: listed in the decoded view, the raw view has only what was heard
            return [] if raw else [f"{head}: not heard"[:width]]
        span = s.last - s.first
        rate = f"{(s.count - 1) / span:.0f}/s" if span > 0 else "-"
        age = f"{max(0.0, now - s.last):.1f} s"
        if raw:  # one line per ID, like cansniffer: the payload wraps under itself
            line = f"{bus:<{label}} {ident:<8} {name:<26} {s.count:>9} {rate:>7} {age:>7}  {_payload(s)}"
            return _wrap([line], width, " " * (label + 64), split=" ")
        lines = [f"{head}: {s.count} frame{'s' * (s.count != 1)}, {rate}, {age} ago"[:width]]
        if entry is None:
            return lines + _wrap(["    " + _payload(s)], width, "    ", split=" ")
        try:
            decoded = entry.message.decode(s.data, decode_choices=True)
            if not isinstance(decoded, dict):  # an AUTOSAR container message: its parts, not signals
                return lines + _wrap(["    " + _payload(s)], width, "    ", split=" ")
            values: dict[str, Any] = decoded
        except Exception as exc:  # noqa: BLE001 - cantools raises several kinds on a bad payload
            return lines + _wrap([f"undecodable ({type(exc).__name__}: {exc}): {_payload(s)}"], width, "    ", split=" ")
        shown = [k for k in values if (k in signals if signals is not None else not k.endswith(_NOISE))]
        cells = [f"{k}={_fmt(values[k], entry.message.get_signal_by_name(k).unit)}" for k in shown]
        return lines + _wrap(cells, width, "    ")


def _payload(s: _Seen) -> str:
    kind = ("FD BRS" if s.brs else "FD") if s.fd else "CAN"
    return f"{kind} [{len(s.data)}] {s.data.hex(' ').upper()}"


def _fmt(v, unit) -> str:
    text = f"{v:.4g}" if isinstance(v, float) else str(v)
    return f"{text} {unit}" if unit else text


def _wrap(cells: list[str], width: int, indent: str, split: str | None = None) -> list[str]:
    """Cells two spaces apart on lines of at most `width`, every line indented; with `split`, one text
    broken at that character (a long payload) onto lines indented by `indent` after its first."""
    if split is not None:
        text = cells[0]
        out, line = [], text[: len(text) - len(text.lstrip(split))]
        for word in text.lstrip(split).split(split):
            if line.strip() and len(line) + len(split) + len(word) > width:
                out.append(line)
                line = indent + word
            else:
                line = f"{line}{split}{word}" if line.strip() else line + word
        return [x[:width] for x in [*out, line] if x.strip()]
    out, line = [], indent
    for c in cells:
        if line.strip() and len(line) + len(c) + 2 > width:
            out.append(line.rstrip())
            line = indent
        line += c + "  "
    if line.strip():
        out.append(line.rstrip())
    return [x[:width] for x in out]
