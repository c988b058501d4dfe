"""The monitor on a terminal: curses, with ``cantools monitor``'s keys (q, p, f or /, r, the arrows and
pages) and a raw view; the screen is drawn from :class:`vehest_can.service.monitor.Monitor`.

Frames keep being counted while the screen is paused; the paused screen is a copy of the monitor
taken at that moment, so it can still be filtered, scrolled and switched to raw."""
from __future__ import annotations

import curses
import time
from collections.abc import Callable

import can

from .monitor import Monitor, compile_filter

KEYS = "q quit  p pause  f filter  x raw/decoded  r reset  arrows/PgUp/PgDn/Home/End scroll"


class Screen:
    def __init__(self, stdscr, mon: Monitor, *, refresh: float = 0.25, filter_text: str = "", raw: bool = False):
        self.scr = stdscr
        self.mon = mon
        self.refresh = refresh
        self.filter = filter_text
        self.pattern = compile_filter(filter_text)
        self.raw = raw
        self.frozen: Monitor | None = None  # the paused screen's monitor
        self.frozen_at = 0.0
        self.top = 0
        self.editing: str | None = None  # the filter being typed
        self.quit = False
        self.dirty = True
        try:
            curses.curs_set(0)
        except curses.error:
            pass  # a terminal without cursor control
        stdscr.nodelay(True)
        stdscr.keypad(True)

    # -- keys -------------------------------------------------------------------------------------
    def keys(self) -> None:
        while True:
            try:
                key = self.scr.get_wch()
            except curses.error:
                return  # none waiting
            self.dirty = True
            if self.editing is not None:
                self._edit(key)
            else:
                self._command(key)

    def _command(self, key) -> None:
        rows = self._rows()
        if key in ("q", "Q"):
            self.quit = True
        elif key in ("p", " "):
            if self.frozen is None:
                self.frozen, self.frozen_at = self.mon.snapshot(), time.monotonic()
            else:
                self.frozen = None
        elif key in ("f", "/"):
            self.editing = self.filter
        elif key in ("x", "X"):
            self.raw = not self.raw
            self.top = 0
        elif key == "r":
            self.mon.reset()
            self.frozen = None
            self.top = 0
        elif key in (curses.KEY_DOWN, "j"):
            self.top += 1
        elif key in (curses.KEY_UP, "k"):
            self.top -= 1
        elif key == curses.KEY_NPAGE:
            self.top += rows
        elif key == curses.KEY_PPAGE:
            self.top -= rows
        elif key in (curses.KEY_HOME, "g"):
            self.top = 0
        elif key in (curses.KEY_END, "G"):
            self.top = 1 << 30  # clamped when drawn
        self.top = max(0, self.top)

    def _edit(self, key) -> None:
        assert self.editing is not None
        if key in ("\n", "\r", curses.KEY_ENTER):
            self.filter, self.pattern, self.editing = self.editing, compile_filter(self.editing), None
            self.top = 0
        elif key == "\x1b":  # Esc: the filter as it was
            self.editing = None
        elif key in (curses.KEY_BACKSPACE, "\x7f", "\b"):
            self.editing = self.editing[:-1]
        elif key == "\x15":  # Ctrl-U, as in a shell: the whole line
            self.editing = ""
        elif isinstance(key, str) and key.isprintable():
            self.editing += key
        if self.editing is not None:  # as typed, like cantools
            self.pattern = compile_filter(self.editing)
            self.top = 0

    # -- drawing ----------------------------------------------------------------------------------
    def _rows(self) -> int:
        return max(1, self.scr.getmaxyx()[0] - 2)  # a status line on top, the keys at the bottom

    def draw(self) -> None:
        height, width = self.scr.getmaxyx()
        mon = self.frozen or self.mon
        now = self.frozen_at if self.frozen is not None else time.monotonic()
        status = mon.header(width)
        flags = [s for s, on in (("PAUSED", self.frozen is not None), ("raw", self.raw)) if on]
        if self.filter and self.editing is None:
            flags.append(f"filter /{self.filter}/")
        body = mon.body(width - 1, now, pattern=self.pattern, raw=self.raw)
        rows = self._rows()
        self.top = max(0, min(self.top, len(body) - rows))
        self.scr.erase()
        self._put(0, status, curses.A_BOLD)
        for i, line in enumerate(body[self.top:self.top + rows]):
            self._put(1 + i, line)
        if self.editing is not None:
            bottom = f"Filter (regex; Enter keeps, Esc cancels): {self.editing}_"
        else:
            where = f"lines {self.top + 1}-{min(len(body), self.top + rows)} of {len(body)}" if body else "no line"
            bottom = "  ".join([*flags, where, KEYS])
        self._put(height - 1, bottom.ljust(width), curses.A_REVERSE)
        self.scr.refresh()
        self.dirty = False

    def _put(self, row: int, text: str, attr: int = 0) -> None:
        height, width = self.scr.getmaxyx()
        if 0 <= row < height:
            try:  # the bottom right cell cannot be written without scrolling: one column short
                self.scr.addnstr(row, 0, text, width - 1, attr)
            except curses.error:
                pass


def run(bus: can.BusABC, mon: Monitor, *, duration: float | None, refresh: float, stopped: Callable[[], bool],
        filter_text: str = "", raw: bool = False) -> None:
    """The screen until q, Ctrl-C (`stopped`) or `duration` s."""
    curses.set_escdelay(25)  # Esc alone cancels the filter at once (curses waits 1 s for a sequence)

    def main(stdscr) -> None:
        screen = Screen(stdscr, mon, refresh=refresh, filter_text=filter_text, raw=raw)
        t0 = time.monotonic()
        next_draw = t0
        while not (screen.quit or stopped()) and (duration is None or time.monotonic() - t0 < duration):
            msg = bus.recv(timeout=0.02)
            while msg is not None:  # what the bus has now, then the keys and the screen
                mon.feed(msg)
                if time.monotonic() >= next_draw:
                    break
                msg = bus.recv(timeout=0)
            screen.keys()
            if screen.dirty or time.monotonic() >= next_draw:
                screen.draw()
                next_draw = time.monotonic() + refresh

    curses.wrapper(main)
