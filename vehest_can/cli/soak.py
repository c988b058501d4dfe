"""``vehest-can soak``: the real-time daemon and a simulated car on udp_multicast with a bounded hostile
sender, for a given time; RSS, open fds, latency percentiles and fault rates per window (docs/hil.md)."""
from __future__ import annotations

import json
import math
from dataclasses import asdict
from pathlib import Path

from ..bus import bus as busmod
from ..errors import ConfigError
from ._common import check_seconds

#: the verb's one line in `vehest-can --help` (read without building its parser)
HELP = "long real-time run (daemon + car + hostile sender): memory, fds, latency, fault rates"


def add_subparser(subparsers) -> None:
    p = subparsers.add_parser(
        "soak", help=HELP,
        description="Run the real-time ECU daemon (its own process) against a simulated car on udp_multicast "
                    "(this host only), with a bounded hostile sender, and report the daemon's RSS, open fds, "
                    "frame-to-estimate latency p50/p99/p99.9 and fault rates per window.")
    p.add_argument("--duration", type=float, default=300.0, metavar="S", help="seconds to run (default 300)")
    p.add_argument("--interval", type=float, default=60.0, metavar="S",
                   help="seconds per reported window (default 60: per minute)")
    p.add_argument("--warmup", type=float, default=60.0, metavar="S",
                   help="memory and fds are judged after this many seconds (default 60)")
    p.add_argument("--hostile-rate", type=float, default=500.0, metavar="N",
                   help="hostile frames per second (bad CRC, unknown ID, wrong length, undecodable; default 500)")
    p.add_argument("--scenario", default="tip_in_tip_out", help="the car's drive, looped (default tip_in_tip_out)")
    p.add_argument("--check", action="store_true",
                   help="exit 1 unless RSS grows <= 1 MB after the warm-up, fds stay flat and no counter saturates")
    p.add_argument("--json", metavar="FILE", help="write every sample, report and check as JSON")
    p.set_defaults(func=run)


def run(args) -> int:
    from ..progress import Progress
    from ..service.soak import Soak, SoakConfig, format_result

    check_seconds(args.duration, "--duration", maximum=30 * 86400)
    check_seconds(args.interval, "--interval", maximum=86400)
    if not (math.isfinite(args.hostile_rate) and 0 < args.hostile_rate <= 20_000):
        raise ConfigError(f"--hostile-rate must be a number of frames per second in (0, 20000], not {args.hostile_rate}")
    if not (math.isfinite(args.warmup) and 0 <= args.warmup < args.duration):
        raise ConfigError(f"--warmup must be a number of seconds in [0, --duration), not {args.warmup}")
    if args.interval > args.duration:
        raise ConfigError("--interval must not be longer than --duration")
    cfg = SoakConfig(duration_s=args.duration, interval_s=args.interval, warmup_s=args.warmup,
                     hostile_rate=args.hostile_rate, scenario=args.scenario)
    progress = Progress("soak (real time)")
    soak = Soak(cfg, progress=progress)
    with busmod.stop_on_signals(soak.stop):
        result = soak.run()
    progress.done()
    print("\n".join(format_result(result)))
    checks = result.checks()
    if args.json:
        Path(args.json).write_text(json.dumps({
            "config": asdict(cfg), "bus": result.bus, "samples": result.samples, "reports": result.reports,
            "windows": result.windows(), "hostile_sent": result.hostile_sent, "daemon": result.daemon_stats,
            "checks": [{"what": w, "passed": ok, "figures": f} for w, ok, f in checks]}, indent=1) + "\n")
    return 1 if args.check and not all(ok for _, ok, _ in checks) else 0
