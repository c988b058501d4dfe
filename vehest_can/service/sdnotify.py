"""A tiny sd_notify(3) client: tell systemd a daemon is ready, alive, busy with what, or stopping.

No dependency: one ``AF_UNIX`` ``SOCK_DGRAM`` datagram per message to ``$NOTIFY_SOCKET`` (a path,
or ``@name`` for the abstract namespace). Without ``$NOTIFY_SOCKET`` (not started by systemd with
``Type=notify``) every call is a cheap no-op.

``Watchdog`` hooks it into a daemon loop: call ``tick()`` every iteration; at most every interval
(half ``WatchdogSec=``, as sd_watchdog_enabled(3) recommends, and at least once a second) it sends
``WATCHDOG=1`` plus a ``STATUS=`` line with the tick count and fault counters, and logs a WARNING
when a fault counter starts rising (INFO once it has settled), whether or not systemd listens.
"""
from __future__ import annotations

import logging
import math
import os
import socket
import sys
import time
from collections.abc import Callable, Mapping
from typing import cast

log = logging.getLogger(__name__)

#: Longest gap between two STATUS lines, s (also the ping interval without a systemd watchdog).
STATUS_INTERVAL_S = 1.0
#: A rising fault counter counts as settled after this long without a new fault, s.
QUIET_S = 10.0


def socket_address(value: str | None) -> str | bytes | None:
    """``$NOTIFY_SOCKET`` as an AF_UNIX address: a path as is, ``@name`` as the abstract ``\\0name``."""
    if not value:
        return None
    if value.startswith("@"):
        return b"\0" + value[1:].encode()
    if value.startswith("/"):
        return value
    return None  # vsock:... and other transports are not supported here


def watchdog_interval(env: Mapping[str, str] | None = None, pid: int | None = None) -> float | None:
    """Seconds between WATCHDOG=1 pings: half of ``$WATCHDOG_USEC``; None when no watchdog is asked for.

    ``$WATCHDOG_PID``, when set, must be this process's PID (the watchdog is meant for that process only).
    """
    env = os.environ if env is None else env
    try:
        usec = int(env.get("WATCHDOG_USEC", ""))
    except ValueError:
        return None
    if usec <= 0:
        return None
    wanted_pid = env.get("WATCHDOG_PID")
    if wanted_pid:
        try:
            if int(wanted_pid) != (os.getpid() if pid is None else pid):
                return None
        except ValueError:
            return None
    return usec / 2e6


class Notifier:
    """Sends sd_notify messages; a no-op without an address."""

    def __init__(self, address: str | bytes | None = None):
        self.address = address
        self._sock: socket.socket | None = None
        self._failed = False
        self.dropped = 0  # messages dropped because the receiver's queue was full

    @classmethod
    def from_env(cls, env: Mapping[str, str] | None = None) -> Notifier:
        env = os.environ if env is None else env
        raw = env.get("NOTIFY_SOCKET")
        address = socket_address(raw)
        if raw and address is None:
            log.warning("NOTIFY_SOCKET=%r: unsupported address, sd_notify disabled", raw)
        return cls(address)

    @property
    def enabled(self) -> bool:
        return self.address is not None and not self._failed

    def notify(self, *assignments: str) -> bool:
        """Send ``KEY=value`` lines as one datagram; False when disabled or the send failed."""
        if not self.enabled:
            return False
        payload = "\n".join(assignments).encode()
        try:
            if self._sock is None:
                self._sock = socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM | socket.SOCK_CLOEXEC)
            # Never block the caller's loop: a full receive queue (systemd busy) drops this message.
            self._sock.sendto(payload, socket.MSG_DONTWAIT | socket.MSG_NOSIGNAL, cast("str | bytes", self.address))
        except BlockingIOError:
            self.dropped += 1
            return False
        except OSError as exc:
            # systemd gone or the socket path wrong: say it once, then stay quiet (never crash the daemon).
            log.warning("sd_notify to %r failed: %s; further notifications dropped", self.address, exc)
            self._failed = True
            self.close()
            return False
        return True

    def ready(self, status: str | None = None) -> bool:
        return self.notify("READY=1", *([f"STATUS={status}"] if status else []))

    def status(self, text: str) -> bool:
        return self.notify(f"STATUS={text}")

    def watchdog(self, status: str | None = None) -> bool:
        return self.notify("WATCHDOG=1", *([f"STATUS={status}"] if status else []))

    def stopping(self, status: str | None = None) -> bool:
        return self.notify("STOPPING=1", *([f"STATUS={status}"] if status else []))

    def close(self) -> None:
        if self._sock is not None:
            self._sock.close()
            self._sock = None


def status_line(label: str, ticks: int, counters: Mapping[str, int]) -> str:
    """``realtime: 12000 ticks; faults: crc_error=2`` (only the non-zero counters)."""
    faults = ", ".join(f"{k}={v}" for k, v in counters.items() if v) or "none"
    return f"{label}: {ticks} ticks; faults: {faults}"


class Watchdog:
    """Periodic keep-alive of a daemon loop (see the module docstring). ``tick`` is cheap between beats."""

    def __init__(self, notifier: Notifier, label: str, ticks: Callable[[], int],
                 counters: Callable[[], Mapping[str, int]], *, interval: float | None = None,
                 clock: Callable[[], float] = time.monotonic, logger: logging.Logger = log):
        self.notifier = notifier
        self.log = logger
        self.label = label
        self._ticks = ticks
        self._counters = counters
        wd = watchdog_interval() if interval is None else interval
        self.interval = min(wd, STATUS_INTERVAL_S) if wd else STATUS_INTERVAL_S
        self._clock = clock
        self._due = -math.inf
        self._last: dict[str, int] = {}
        self._rising: dict[str, float] = {}  # counter -> when it last rose
        self.beats = 0

    def tick(self, now: float | None = None) -> bool:
        """Beat if due: WATCHDOG=1 + STATUS=..., fault logging. True when it beat."""
        now = self._clock() if now is None else now
        if now < self._due:
            return False
        self._due = now + self.interval
        self.beats += 1
        counters = dict(self._counters())
        self._log_faults(counters, now)
        self.notifier.watchdog(status_line(self.label, self._ticks(), counters))
        return True

    def _log_faults(self, counters: dict[str, int], now: float) -> None:
        """WARNING when a fault counter starts rising, INFO once it has been quiet for QUIET_S: a line per
        change, not per beat."""
        rose = {k: v - self._last.get(k, 0) for k, v in counters.items() if v > self._last.get(k, 0)}
        started = {k: d for k, d in rose.items() if k not in self._rising}
        self._rising.update(dict.fromkeys(rose, now))
        quiet = sorted(k for k, t in self._rising.items() if now - t >= QUIET_S)
        for k in quiet:
            del self._rising[k]
        if started:
            self.log.warning("%s: faults rising: %s", self.label,
                             ", ".join(f"{k} +{d} (total {counters[k]})" for k, d in started.items()))
        if quiet:
            self.log.info("%s: no new faults for %g s: %s", self.label, QUIET_S,
                          ", ".join(f"{k}={counters[k]}" for k in quiet))
        self._last = counters


class _JournalFormatter(logging.Formatter):
    """Prefixes ``<N>`` (syslog priority) so journald files each line at its level (SyslogLevelPrefix=)."""

    PRIORITY = {logging.DEBUG: 7, logging.INFO: 6, logging.WARNING: 4, logging.ERROR: 3, logging.CRITICAL: 2}

    def format(self, record: logging.LogRecord) -> str:
        level = max((lv for lv in self.PRIORITY if lv <= record.levelno), default=logging.DEBUG)
        return f"<{self.PRIORITY[level]}>{super().format(record)}"


def stderr_is_journal(env: Mapping[str, str] | None = None) -> bool:
    """True when stderr is the journal stream systemd named in ``$JOURNAL_STREAM`` (device:inode)."""
    env = os.environ if env is None else env
    try:
        dev, ino = (int(x) for x in env.get("JOURNAL_STREAM", "").split(":"))
        st = os.fstat(sys.stderr.fileno())
    except (ValueError, OSError, AttributeError):
        return False
    return (st.st_dev, st.st_ino) == (dev, ino)


def use_journal_levels() -> bool:
    """Under systemd with stderr to the journal, prefix log lines with their syslog priority."""
    if not stderr_is_journal():
        return False
    for handler in logging.getLogger().handlers:
        if isinstance(handler, logging.StreamHandler) and handler.stream is sys.stderr:
            handler.setFormatter(_JournalFormatter("%(name)s: %(message)s"))
    return True


LOG_LEVELS = ("debug", "info", "warning", "error")


def add_log_level(parser) -> None:
    """``--log-level`` for a daemon verb."""
    parser.add_argument("--log-level", choices=LOG_LEVELS,
                        help="log level on stderr (default: warning, or as -v says); under systemd the "
                             "journal files each line at its level")


def apply_log_level(level: str | None) -> None:
    """Set the root log level (None: leave it), and use syslog-priority prefixes if stderr is the journal."""
    if level:
        logging.getLogger().setLevel(level.upper())
    use_journal_levels()
