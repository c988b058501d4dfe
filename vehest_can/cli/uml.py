"""``vehest-can uml [--fetch] [-- COMMAND]``: a shell command in user-mode Linux with a real SocketCAN
vcan0 (CAN FD), for hosts whose kernel has no CAN (docs/uml.md)."""
from __future__ import annotations

import shlex
import sys

from ..errors import ConfigError

#: the verb's one line in `vehest-can --help` (read without building its parser)
HELP = "run a command in user-mode Linux with a real SocketCAN vcan0 (hosts without kernel CAN)"


def add_subparser(subparsers) -> None:
    p = subparsers.add_parser("uml", help=HELP, description=__doc__.split("\n\n")[0].replace("``", ""))
    p.add_argument("--fetch", action="store_true", help="download a UML kernel that works on this CPU (docs/uml.md)")
    p.add_argument("--force", action="store_true", help="with --fetch: download again")
    p.add_argument("--check", action="store_true", help="say whether UML runs here, and which kernel; exit 1 if not")
    p.add_argument("--timeout", type=float, default=300.0, help="seconds for the whole guest run (default: 300)")
    p.add_argument("--iface", action="append", metavar="NAME", help="a vcan interface (repeatable; default: vcan0)")
    p.add_argument("command", nargs="*", help="after --: the command line to run in the guest")
    p.set_defaults(func=run)


def run(args) -> int:
    from ..tools import uml

    if not 0 < args.timeout < 86400:
        raise ConfigError("--timeout must be a number of seconds between 0 and 86400")
    if args.fetch:
        uml.fetch_kernel(force=args.force)
        if not args.command:
            return 0
    if args.check or not args.command:
        ok, reason = uml.available()
        print(("available: " if ok else "unavailable: ") + reason)
        return 0 if ok else 1
    line = args.command[0] if len(args.command) == 1 else shlex.join(args.command)
    result = uml.run(line, timeout=args.timeout, interfaces=tuple(args.iface or ("vcan0",)))  # UmlError: the CLI's error
    sys.stdout.write(result.stdout)
    sys.stderr.write(result.stderr)
    print(f"[uml] exit {result.returncode}, command started {result.boot_seconds:.2f} s after "
          f"launch, {result.total_seconds:.2f} s in all", file=sys.stderr)
    return result.returncode
