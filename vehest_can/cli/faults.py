"""``vehest-can faults``: run each bus fault against the ECU and print what it detects, how its health
responds and how it recovers; ``--bus-run S`` measures the bus load of a real-time run through the wire
model instead."""
from __future__ import annotations

import sys
from pathlib import Path
from typing import TYPE_CHECKING

from ..bus import bus as busmod
from ..errors import ConfigError
from ._common import check_range, check_seconds

if TYPE_CHECKING:  # annotations only: the verb's parser loads none of it
    from ..faults.spec import FaultConfig


#: the verb's one line in `vehest-can --help` (read without building its parser)
HELP = "inject bus faults; table of what the ECU detects, its health response and recovery"


def add_subparser(subparsers) -> None:
    from ..faults.spec import DESCRIPTIONS

    kinds = "; ".join(f"{k}: {v}" for k, v in DESCRIPTIONS.items())
    p = subparsers.add_parser(
        "faults", help=HELP,
        description="Run the launch scenario in simulated time with the sensor node's and the ECU's frames "
                    "through a fault injector and a bit-rate-limited wire model, once per fault, and tabulate "
                    "the ECU's fault counters, the health and valid flags of the scenario's filters during the fault and the "
                    "ticks until the estimates are valid again. With --fault / --faults-file: those faults "
                    "instead of the built-in table. With --bus-run S: a real-time run of S seconds on a "
                    "python-can bus (default: virtual) through the wire model, measuring the bus load.",
        epilog=f"Fault syntax: KIND[:TARGET][:KEY=VALUE...][:START-END], e.g. drop:DLS_Sensors:p=0.1:2.0-3.0, "
               f"flood:load=0.5:2-2.5. TARGET is a message or node of the DBC or *. Kinds: {kinds}. "
               "See docs/faults.md.")
    p.add_argument("--scenario", default="launch_2nd", metavar="NAME|FILE",
                   help="scenario to drive (default: launch_2nd)")
    p.add_argument("--duration", type=float, default=3.5, metavar="S",
                   help="seconds of the scenario to run (default: 3.5; the built-in faults act at 2.0-2.5 s; "
                        "--bus-run gives its own)")
    p.add_argument("--fault", action="append", metavar="SPEC", help="a fault to inject (repeatable)")
    p.add_argument("--faults-file", metavar="FILE", help="TOML file with a [faults] table")
    p.add_argument("--seed", type=int, default=None, help="seed of the random draws (default: the file's, else 1)")
    p.add_argument("--markdown", metavar="FILE", help="also write the table as Markdown ('-': stdout)")
    p.add_argument("--stuffing", choices=("worst", "nominal"), default="worst",
                   help="stuff bits per frame on the wire: worst case (default) or none (busload's nominal)")
    p.add_argument("--tx-queue", type=int, default=10, metavar="N",
                   help="frames a node's transmit queue holds (default: 10, Linux's CAN txqueuelen)")
    p.add_argument("--tx-policy", choices=("fifo", "latest"), default="fifo",
                   help="fifo: queued frames wait their turn (Linux); latest: a new frame replaces its "
                        "waiting predecessor of the same ID (AUTOSAR CanIf)")
    p.add_argument("--bus-run", type=float, metavar="S",
                   help="instead: S seconds in real time on a bus (ECU daemon thread + simulator, both through "
                        "one wire model), then the measured bus load beside `vehest-can busload`")
    busmod.add_arguments(p)
    p.set_defaults(func=run)


def _config(args) -> FaultConfig | None:
    from ..faults.spec import FaultConfig, faults_from_cli, load_faults

    given = None
    if args.faults_file:
        given = load_faults(args.faults_file)
    if args.fault:
        cli = faults_from_cli(args.fault)
        given = FaultConfig((given.faults if given else ()) + cli.faults, given.seed if given else 1)
    if args.seed is not None:
        if not 0 <= args.seed < 2**64:
            raise ConfigError(f"--seed {args.seed}: must be in [0, 2^64)")
        given = FaultConfig(given.faults if given else (), args.seed)
    return given


def run(args) -> int:
    from ..bus.busload import bus_load
    from ..faults.campaign import analyse, fault_table, format_table, run_with_faults
    from ..paths import dbc_path
    from ..progress import Progress
    from ..systems import load_any_scenario

    check_seconds(args.duration, "--duration")
    check_seconds(args.bus_run, "--bus-run")
    check_range(args.tx_queue, "--tx-queue", 1, 10_000, "frames")  # a CAN controller holds a few dozen
    system, scenario = load_any_scenario(args.scenario)
    study = system.faults
    if study is None:
        raise ConfigError(f"{args.scenario}: a {system.name} scenario; that system has no fault table")
    drive = system.car(scenario, args.duration)
    # bit rates: the flags, else the DBC's
    dbc = bus_load(dbc_path("pt"), getattr(args, "bitrate", None), getattr(args, "data_bitrate", None))
    wire = dict(bitrate=dbc.bitrate, data_bitrate=dbc.data_bitrate, stuffing=args.stuffing)
    config = _config(args)

    if args.bus_run is not None:
        return _bus_run(args, system.car(scenario, args.bus_run), config, wire)

    seed = config.seed if config is not None else 1
    options = dict(tx_queue=args.tx_queue, tx_policy=args.tx_policy, **wire)
    progress = Progress("faults")
    if config is not None and config.faults:
        late = [f.text() for f in config.faults if f.start_s >= args.duration]
        if late:
            raise ConfigError(f"{', '.join(late)}: starts after the run's {args.duration:g} s (see --duration)")
        rows = fault_table(drive, study.catalogue[:1], seed=seed, study=study, **options)
        window = (min(f.start_s for f in config.faults), min(max(f.end_s for f in config.faults), args.duration))
        row = analyse(run_with_faults(drive, config, study=study, **options), f"given faults ({window[0]:g}-{window[1]:g} s)",
                      " ".join(f.text() for f in config.faults), (), window)
        row.run = None
        rows.append(row)
    else:
        rows = fault_table(drive, seed=seed, progress=progress, study=study, **options)
    progress.done()
    print(f"{scenario.name}, {args.duration:g} s; wire {dbc.bitrate}/{dbc.data_bitrate} bit/s, "
          f"{args.stuffing}-case stuffing, transmit queue {args.tx_queue} ({args.tx_policy}); seed {seed}")
    print("\n".join(format_table(rows, study=study)))
    if args.markdown:
        text = "\n".join(format_table(rows, markdown=True, study=study)) + "\n"
        if args.markdown == "-":
            sys.stdout.write(text)
        else:
            Path(args.markdown).write_text(text)
    return 0


def _bus_run(args, car, config, wire) -> int:
    from ..faults.campaign import bus_run

    if not args.bus_run > 1.2:
        raise ConfigError(f"--bus-run {args.bus_run}: needs more than 1.2 s (0.5 s settle at each end)")
    bus_config = busmod.bus_config(args) if getattr(args, "interface", None) or args.bus_config else None
    result = bus_run(car, config, bus_config=bus_config,
                     tx_queue=args.tx_queue, tx_policy=args.tx_policy, **wire)
    print("\n".join(result.lines()))
    return 0
