"""``vehest-can camber calibrate|measure|bound``: camber inspection (seed 002) for the user."""
from __future__ import annotations

import json
import sys
from typing import TYPE_CHECKING

from ..bus import bus as busmod
from ..errors import ConfigError
from ._common import DeprecatedAlias, check_plot_path, check_range, check_seconds

if TYPE_CHECKING:  # annotations only: the verb's parser loads none of it
    from ..systems.camber import inspection

#: accelerometer resolution per axis, mg: a 24-bit part at +-2 g counts 0.00024 mg; 500 mg is a 2-bit sensor
LSB_MG_RANGE = (1e-4, 500.0)
SAMPLES_RANGE = (2, 1_000_000)   # per pose: a mean needs two; a million at 100 Hz is almost three hours
MAX_LISTEN_S = 3600.0            # a live capture or measurement waits at most an hour


#: the verb's one line in `vehest-can --help` (read without building its parser)
HELP = "camber inspection: calibrate devices, measure, error bound"


def add_subparser(subparsers) -> None:
    from ..systems.camber.api import WHEELS

    p = subparsers.add_parser("camber", help=HELP,
                              description="Camber angle inspection with wheel-mounted 3-axis accelerometers "
                                          "(seed 002).")
    sub = p.add_subparsers(dest="camber_verb", metavar="ACTION")
    sub.required = True

    c = sub.add_parser("calibrate", help="chip-in-device calibration from an x-down and a z-down capture",
                       description="Calibrate the inspection devices (eq. 7-19). Give two logs, or capture live "
                                   "from the bus: you are asked to put the devices in each fixture pose.")
    c.add_argument("-o", "--output", required=True, metavar="FILE", help="calibration file to write (JSON)")
    c.add_argument("--x-down", metavar="LOG", help="log of CIS_Accel frames with each device's x axis down")
    c.add_argument("--z-down", metavar="LOG", help="log of CIS_Accel frames with each device's z axis down")
    c.add_argument("--wheel", action="append", choices=WHEELS, help="only these wheels (default: every device seen)")
    c.add_argument("--samples", type=int, default=512, metavar="N", help="live capture: samples per pose (512; 2..1000000)")
    c.add_argument("--timeout", type=float, default=30.0, metavar="S", help="live capture: give up after S s (30; at most 3600)")
    c.add_argument("--yes", action="store_true", help="live capture: do not wait for Enter between poses")
    busmod.add_arguments(c)
    c.set_defaults(func=calibrate_cmd)

    m = sub.add_parser("measure", help="per-wheel camber, misalignment and error bound from the ECU",
                       description="Print the ECU's camber results (VEHEST_Camber) from a log or the live bus.")
    m.add_argument("--from-log", metavar="LOG", help="read a recorded log instead of the bus")
    m.add_argument("--log", dest="from_log", metavar="LOG", action=DeprecatedAlias, new="--from-log",
                   help="deprecated name of --from-log")
    m.add_argument("--timeout", type=float, default=5.0, metavar="S", help="live: listen for S seconds (5; at most 3600)")
    m.add_argument("--json", action="store_true", help="print JSON")
    busmod.add_arguments(m)
    m.set_defaults(func=measure_cmd)

    b = sub.add_parser("bound", help="the worst-case camber error of eq. 22 (and the paper's Fig. 5)")
    b.add_argument("--lsb-mg", type=float, default=4.0, help="accelerometer resolution per axis, mg (4; 0.0001..500)")
    b.add_argument("--plot", metavar="PNG", help="write the error map over camber and misalignment")
    b.set_defaults(func=bound_cmd)


def _live_capture(args, pose: str) -> inspection.Capture:
    from ..systems.camber import inspection

    if not args.yes:
        print(f"Put every inspection device in its fixture with its {pose[0]} axis straight down, "
              f"hold still, then press Enter.", file=sys.stderr)
        sys.stdin.readline()
    bus = busmod.open_bus(busmod.bus_config(args))
    try:
        print(f"capturing {args.samples} samples ({pose})...", file=sys.stderr)
        return inspection.capture_bus(bus, args.samples, args.timeout)
    finally:
        bus.shutdown()


def calibrate_cmd(args) -> int:
    from ..bus.log import read_log
    from ..systems.camber import inspection
    from ..systems.camber.api import save_calibrations

    if bool(args.x_down) != bool(args.z_down):
        raise ConfigError("give both --x-down and --z-down logs, or neither (live capture)")
    check_range(args.samples, "--samples", *SAMPLES_RANGE, "samples per pose")
    check_seconds(args.timeout, "--timeout", maximum=MAX_LISTEN_S)
    if args.x_down:
        x = inspection.capture_messages(read_log(args.x_down))
        z = inspection.capture_messages(read_log(args.z_down))
    else:
        x = _live_capture(args, "x-down")
        z = _live_capture(args, "z-down")
    cals = inspection.calibrate_wheels(x, z, args.wheel)
    save_calibrations(args.output, cals)
    for w, cal in cals.items():
        cap = cal.capture
        print(f"{w}: {cap['n'][0]} + {cap['n'][1]} samples, x.z = {cap['x_dot_z']:+.5f}, "
              f"spread {max(cap['std_g']):.4f} g")
    refused = x.refused + z.refused
    print(f"wrote {args.output} ({len(cals)} wheels){f'; {refused} frames refused (E2E)' if refused else ''}")
    return 0


def measure_cmd(args) -> int:
    from ..bus.log import read_log
    from ..systems.camber import inspection

    check_seconds(args.timeout, "--timeout", maximum=MAX_LISTEN_S)
    if args.from_log:
        messages = read_log(args.from_log)
    else:
        import time

        bus = busmod.open_bus(busmod.bus_config(args))
        messages, end = [], time.monotonic() + args.timeout
        try:
            while time.monotonic() < end:
                msg = bus.recv(timeout=0.1)
                if msg is not None:
                    messages.append(msg)
        finally:
            bus.shutdown()
    results = inspection.ecu_results(messages)
    if results is None:
        raise ConfigError("no VEHEST_Camber frame: is the ECU running, with the inspection devices on the bus?")
    if args.json:
        print(json.dumps(results, indent=2))
    else:
        print(inspection.results_table(results))
    return 0 if all(r["reason"] == "OK" for r in results.values()) else 3


def bound_cmd(args) -> int:
    from ..systems.camber import inspection

    if args.plot:
        check_plot_path(args.plot)
    check_range(args.lsb_mg, "--lsb-mg", *LSB_MG_RANGE, "mg")
    print(f"worst-case camber error at camber 0 with {args.lsb_mg:g} mg per axis: "
          f"{inspection.min_worst_case_deg(args.lsb_mg):.4g} deg (paper, 4 mg: 0.2292 deg)")
    if args.plot:
        print(f"plot: {inspection.bound_plot(check_plot_path(args.plot), args.lsb_mg)}")
    return 0
