"""CAN log files: whatever python-can's LogReader reads (candump -L, .asc, .blf, .csv, .trc ...)."""
from __future__ import annotations

from pathlib import Path

import can

from ..errors import ConfigError


def read_log(path: str | Path) -> list[can.Message]:
    path = Path(path)
    if not path.is_file():
        raise ConfigError(f"{path}: no such log file")
    try:
        return [m for m in can.LogReader(str(path)) if not (m.is_error_frame or m.is_remote_frame)]
    except (ValueError, KeyError, IndexError, UnicodeDecodeError) as exc:
        raise ConfigError(f"{path}: not a readable CAN log ({exc})") from exc
