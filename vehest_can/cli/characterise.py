"""``vehest-can characterise``: the two plants' handling figures side by side for the same car."""
from __future__ import annotations

import json
from pathlib import Path

from ..errors import ConfigError
from ..sim import PLANTS
from ._common import check_range

#: the verb's one line in `vehest-can --help` (read without building its parser)
HELP = "the plants' roll and understeer gradients and load transfer, side by side"


def add_subparser(subparsers) -> None:
    parser = subparsers.add_parser(
        "characterise",
        help=HELP,
        description="Drive each plant of the 14-DOF car (veh14: ours; commonroad_mb: CommonRoad's multi-body "
                    "model) with the same car data through a quasi-steady-state manoeuvre: constant speed "
                    "(a speed controller sets the front wheels' drive torque), the road-wheel angle ramped slowly "
                    "from 0, friction 1. Fitted by least squares where |a_y| <= --ay-max (R^2 reported): roll "
                    "gradient (roll against a_y), understeer gradient (steer minus the Ackermann angle L r/v_x "
                    "against a_y), lateral load transfer per axle ((F_z,outer - F_z,inner)/2 against a_y), "
                    "each axle's as a fraction of a rigid car's (its static mass share m l/L at the whole "
                    "car's CG height h_cg: m_axle h_cg g/(2 t)), and the front share of the load transfer. "
                    "The car is the paper's, with the [vehicle] table of --scenario over it; each payload "
                    "is one run per plant. Exit status 0, or 1 on an error.",
    )
    parser.add_argument("--plant", nargs="+", choices=PLANTS, default=list(PLANTS), metavar="PLANT",
                        help=f"plants to run, of {', '.join(PLANTS)} (default: both)")
    parser.add_argument("--mass-delta-kg", nargs="+", type=float, default=[0.0, 200.0], metavar="KG",
                        help="payloads at the sprung CG, one run each (default: 0 200)")
    parser.add_argument("--car", nargs="+", metavar="FILE_OR_NAME",
                        help="cars to run, each a car file (docs/car.md) or a shipped car's name: paper, "
                             "commonroad_vehicle1 .. 3 (default: the paper's)")
    parser.add_argument("--scenario", metavar="FILE",
                        help="a scenario-like TOML file whose [vehicle] table overrides the paper car "
                             "(only that table is read; its mass_delta_kg is refused: use --mass-delta-kg)")
    parser.add_argument("--speed-kmh", type=float, default=80.0, help="speed held (default: 80)")
    parser.add_argument("--steer-deg", type=float, default=4.0,
                        help="road-wheel angle at the end of the ramp (default: 4)")
    parser.add_argument("--ramp-s", type=float, default=20.0, help="duration of the steer ramp (default: 20)")
    parser.add_argument("--ay-max", type=float, default=4.0,
                        help="the linear range fitted: |a_y| up to this, m/s^2 (default: 4)")
    parser.add_argument("--json", metavar="FILE", help="also write the figures, the fits' R^2 and the car to FILE")
    parser.set_defaults(func=run)


def run(args) -> int:
    for value in args.mass_delta_kg:
        check_range(value, "--mass-delta-kg", -500.0, 2000.0, "kg")
    check_range(args.speed_kmh, "--speed-kmh", 20.0, 200.0, "km/h")
    check_range(args.steer_deg, "--steer-deg", -30.0, 30.0, "degrees")
    if args.steer_deg == 0.0:
        raise ConfigError("--steer-deg must not be 0: the manoeuvre needs a steer ramp")
    check_range(args.ramp_s, "--ramp-s", 2.0, 600.0, "seconds")
    check_range(args.ay_max, "--ay-max", 0.5, 15.0, "m/s^2")
    if args.json and not Path(args.json).parent.is_dir():
        raise ConfigError(f"--json {args.json}: folder {Path(args.json).parent} does not exist")

    from ..sim import characteristics as ch

    vehicle, source = None, "<characterise>"
    if args.scenario:
        vehicle, source = ch.vehicle_from_toml(args.scenario), args.scenario
    m = ch.Manoeuvre(speed_kmh=args.speed_kmh, steer_deg=args.steer_deg, ramp_s=args.ramp_s, ay_max=args.ay_max)
    plants = list(dict.fromkeys(args.plant))
    cars = tuple(dict.fromkeys(args.car)) if args.car else (None,)
    rows = ch.characterise_all(plants, list(dict.fromkeys(args.mass_delta_kg)), vehicle, m, source, cars)
    print("\n".join(ch.table(rows)))
    if args.json:
        Path(args.json).write_text(json.dumps(ch.to_json(rows, m, vehicle), indent=2) + "\n")
    return 0
