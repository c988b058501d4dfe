"""What several verbs share: the session-log flags (``--log`` is always an output)."""
from __future__ import annotations

import argparse

from ..bus.log import FORMATS, SessionLog, check_log_path

LOG_HELP = ("log every frame to FILE, in the format of its extension: "
            + ", ".join(f"{k} {v}" for k, v in FORMATS.items())
            + "; absolute time, Tx/Rx, one channel per bus (pt, ch)")


def add_log_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--log", metavar="FILE", help=LOG_HELP)
    parser.add_argument("--log-per-bus", action="store_true",
                        help="one log per bus (FILE-pt.log, FILE-ch.log) instead of one with a channel per bus")


def check_log_arguments(args) -> None:
    """Before anything starts: a bad --log is an error now, not after the run."""
    if getattr(args, "log", None):
        check_log_path(args.log)


def open_session_log(args, nodes) -> SessionLog | None:
    return SessionLog(args.log, nodes, per_bus=args.log_per_bus) if args.log else None
