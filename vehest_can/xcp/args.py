"""The daemon's XCP flags: a module of their own, so that building the daemon's parser needs neither
the C core nor the XCP description (vehest_can.xcp.ecu sets the slave up from them)."""
from __future__ import annotations

import tomllib
from pathlib import Path

#: which members of vh_ecu_t are XCP items, and the slave's transport (vehest_can.xcp.ecu_desc)
ECU_TOML = Path(__file__).with_name("ecu.toml")


def add_arguments(parser) -> None:
    """The daemon's XCP flags: the slave is off unless --xcp on with the user's key (--xcp-key, or
    --xcp-dev's public one); identifiers, sizes and CAN FD are configuration (defaults:
    vehest_can/xcp/ecu.toml, the A2L's)."""
    with ECU_TOML.open("rb") as f:  # the defaults the help names, from the configuration (no C needed)
        d = tomllib.load(f).get("xcp", {})
    g = parser.add_argument_group("XCP on CAN (the ECU's measurement and calibration slave, docs/xcp.md)")
    g.add_argument("--xcp", choices=("on", "off"), default="off",
                   help="serve XCP (default off); on its own bus when --xcp-interface/--xcp-channel name one, "
                        "else on the ECU's bus")
    g.add_argument("--xcp-key", metavar="FILE", help="seed & key key file (mode 600; `vehest-can xcp keygen FILE`)")
    g.add_argument("--xcp-dev", action="store_true",
                   help="development mode: seed & key with the fixed, public development key (a bench, never a car)")
    g.add_argument("--xcp-cal-mode", action="store_true",
                   help="calibration mode: the roll actuators held passive for the whole run, so safety-relevant "
                        "characteristics may be written without standstill")
    g.add_argument("--xcp-cro-id", metavar="ID", help=f"master->slave identifier (default 0x{d['cro_id']:X}; "
                   "add 0x80000000 for a 29-bit one)")
    g.add_argument("--xcp-dto-id", metavar="ID", help=f"slave->master identifier (default 0x{d['dto_id']:X})")
    g.add_argument("--xcp-max-cto", metavar="N", help=f"MAX_CTO 8..64 (default {d['max_cto']})")
    g.add_argument("--xcp-max-dto", metavar="N", help=f"MAX_DTO 8..64 (default {d['max_dto']}; above 8 needs CAN FD)")
    g.add_argument("--xcp-fd", choices=("on", "off"), help=f"XCP frames as CAN FD (default {'on' if d['fd'] else 'off'})")
    g.add_argument("--xcp-cal", metavar="FILE", help="start on this calibration file (`vehest-can xcp save` writes one)")
    _add_bus_arguments(g)


def _add_bus_arguments(group) -> None:
    """The XCP bus's own python-can flags (python-can's prefixed bus arguments: --xcp-interface,
    --xcp-channel, --xcp-bitrate, --xcp-data-bitrate, --xcp-timing, --xcp-bus-kwargs; its --xcp-fd
    is ours above: the slave's frames and the bus are CAN FD together)."""
    import argparse

    from can.cli import add_bus_arguments

    from ..bus.bus import parse_bitrate
    from ..errors import BusError

    def bitrate(text: str) -> int:
        try:
            return int(parse_bitrate(text) or 0)
        except BusError as exc:
            raise argparse.ArgumentTypeError(str(exc).removeprefix("bitrate ")) from None

    donor = argparse.ArgumentParser(add_help=False)
    add_bus_arguments(donor, prefix="xcp")
    for action in donor._actions:
        if action.dest in ("xcp_fd", "help"):
            continue
        if action.dest in ("xcp_bitrate", "xcp_data_bitrate"):
            action.type = bitrate
            action.help = (action.help or "") + " (bit/s: 500000, 500k, 2M)"
        action.help = (action.help or "") + " [the XCP bus]"
        group._add_action(action)
    group.add_argument("--xcp-bus-context", metavar="SECTION",
                       help="the XCP bus from this section of the python-can configuration file (--bus-config, "
                            "~/.canrc); its flags win")
