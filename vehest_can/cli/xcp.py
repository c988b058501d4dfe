"""``vehest-can xcp``: the ECU's XCP description, its A2L, and a small master for named items.

    vehest-can xcp keygen FILE            a new seed & key key file (mode 600) for the daemon and its masters
    vehest-can xcp a2l [-o FILE]          the A2L of the ECU (the build's, from the C structs)
    vehest-can xcp list [PATTERN]         measurements and characteristics: type, unit, limits
    vehest-can xcp get NAME...            read them from a running daemon (its bus: python-can flags)
    vehest-can xcp set NAME VALUE...      calibrate one (seed & key with --key FILE), read it back
    vehest-can xcp save FILE              the running ECU's working page as a calibration file
    vehest-can xcp load FILE              a calibration file (checked whole first) into the running ECU
(`vehest-can daemon --xcp-cal FILE` starts the ECU on one.)
"""
from __future__ import annotations

import fnmatch
import math
import sys
from contextlib import contextmanager
from pathlib import Path

from ..bus import bus as busmod
from ..errors import ConfigError

#: the verb's one line in `vehest-can --help` (read without building its parser)
HELP = "the ECU's XCP: its A2L, its items, read and calibrate them on a bus"


def add_subparser(subparsers) -> None:
    p = subparsers.add_parser("xcp", help=HELP,
                              description="The ECU's XCP-on-CAN slave (docs/xcp.md): write its A2L, list what it "
                                          "measures and calibrates, read or write an item by its C name on the "
                                          "bus of a running `vehest-can daemon`.")
    sub = p.add_subparsers(dest="action", metavar="ACTION")
    sub.required = True
    kg = sub.add_parser("keygen", help="write a new seed & key key file (mode 600; never overwrites)")
    kg.add_argument("file", metavar="FILE")
    kg.set_defaults(func=run_keygen)
    a = sub.add_parser("a2l", help="write the ECU's A2L")
    a.add_argument("-o", "--output", metavar="FILE", help="where (default: print it)")
    a.add_argument("--description", metavar="TOML",
                   help="the A2L of this XCP description (docs/xcp.md) instead of the ECU's")
    a.set_defaults(func=run_a2l)
    ls = sub.add_parser("list", help="list the measurements and characteristics")
    ls.add_argument("pattern", nargs="?", default="*", help="shell pattern on the names, e.g. 'cal.app.drv.dkf*'")
    ls.set_defaults(func=run_list)
    for name, hlp, func in (("get", "read items from the running ECU", run_get),
                            ("set", "write a characteristic of the running ECU and read it back", run_set),
                            ("save", "save the running ECU's working page as a calibration file", run_save),
                            ("load", "write a calibration file into the running ECU's working page", run_load)):
        q = sub.add_parser(name, help=hlp)
        if name == "get":
            q.add_argument("names", nargs="+", metavar="NAME")
        elif name in ("save", "load"):
            q.add_argument("file", metavar="FILE")
        else:
            q.add_argument("name", metavar="NAME")
            q.add_argument("values", nargs="+", metavar="VALUE", help="physical value(s), from element --index on")
            q.add_argument("--index", type=int, default=0, help="first element to write (default 0)")
        q.add_argument("--cro-id", metavar="ID", help="master->slave identifier (default: the A2L's)")
        q.add_argument("--dto-id", metavar="ID", help="slave->master identifier (default: the A2L's)")
        q.add_argument("--timeout", type=float, default=1.0, metavar="S", help="per answer (default 1 s)")
        if name in ("set", "load"):
            k = q.add_mutually_exclusive_group(required=True)
            k.add_argument("--key", metavar="FILE", help="the daemon's seed & key key file (--xcp-key)")
            k.add_argument("--dev", action="store_true", help="the public development key (a daemon with --xcp-dev)")
        busmod.add_arguments(q)
        q.set_defaults(func=func)


def _description():
    from ..xcp import ecu as xcp_ecu
    return xcp_ecu.description()


def _item(desc, name: str):
    try:
        return desc.item(name)
    except KeyError:
        close = [n for n in (i.name for i in desc.measurements + desc.characteristics) if name in n][:5]
        hint = f" (did you mean {', '.join(close)}?)" if close else " (`vehest-can xcp list` shows them)"
        raise ConfigError(f"no XCP item named {name!r}{hint}") from None


def run_keygen(args) -> int:
    from ..xcp.keys import write_key

    write_key(args.file)
    print(f"{args.file}: XCP seed & key key written (mode 600); start the daemon with --xcp on --xcp-key {args.file}",
          file=sys.stderr)
    return 0


def run_a2l(args) -> int:
    from ..xcp import a2l, description, ecu_desc

    if args.description:
        try:  # a DescriptionError and a TOML syntax error are ValueErrors
            text = a2l.generate(description.load(args.description))
        except (ValueError, OSError) as exc:
            raise ConfigError(f"--description {args.description}: {exc}") from None
    else:
        text = ecu_desc.SHIPPED_A2L.read_text()
    if args.output:
        Path(args.output).write_text(text)
        print(f"wrote {args.output}", file=sys.stderr)
    else:
        sys.stdout.write(text)
    return 0


def run_list(args) -> int:
    desc = _description()
    for it in desc.measurements + desc.characteristics:
        if fnmatch.fnmatchcase(it.name, args.pattern):
            lo, hi = it.phys_limits()
            shape = f"[{it.count}]" if it.shape else ""
            limits = f"  [{lo:g}, {hi:g}]" if it.kind == "characteristic" else ""
            print(f"{it.kind[:4]}  {it.name:28s} {it.ctype}{shape:5s} {it.unit:10s}{limits}  {it.comment}")
    return 0


def _master(args):
    from dataclasses import replace

    from ..xcp.master import Master

    desc = _description()
    ids = {}
    for key in ("cro_id", "dto_id"):
        text = getattr(args, key)
        if text is not None:
            try:
                ids[key] = int(text, 0)
            except ValueError:
                raise ConfigError(f"--{key.replace('_', '-')} {text!r} is not a number (decimal or 0x hex)") from None
    if args.timeout <= 0 or not math.isfinite(args.timeout):
        raise ConfigError("--timeout must be a positive number of seconds")
    desc = replace(desc, **ids)
    config = busmod.bus_config(args)
    return Master(busmod.open_bus(config), desc, timeout=args.timeout), desc


@contextmanager
def _connected(args, unlock: bool = False):
    """A master connected to the daemon of the bus flags (seed & key done when `unlock`, for writes);
    disconnected after the body, its bus shut down in any case."""
    m, _ = _master(args)
    try:
        if unlock:
            from ..xcp.keys import DEV_KEY, load_key

            m.connect(DEV_KEY if args.dev else load_key(args.key))
        else:
            m.connect()
        yield m
        m.disconnect()
    finally:
        m.bus.shutdown()


def _show(item, values) -> str:
    text = ", ".join(f"{v:g}" for v in values)
    return f"{item.name} = {'[' + text + ']' if item.shape else text} {item.unit}".rstrip()


def run_get(args) -> int:
    desc = _description()
    items = [_item(desc, n) for n in args.names]
    with _connected(args) as m:
        for it in items:
            print(_show(it, m.read(it)))
    return 0


def run_set(args) -> int:
    from ..xcp.master import XcpError

    desc = _description()
    it = _item(desc, args.name)
    if it.kind != "characteristic":
        raise ConfigError(f"{it.name} is a measurement; only characteristics (cal.*) can be written")
    try:
        values = [float(v) for v in args.values]
    except ValueError:
        raise ConfigError(f"values must be numbers, got {' '.join(args.values)}") from None
    if not 0 <= args.index or args.index + len(values) > it.count:
        raise ConfigError(f"{it.name} has {it.count} element(s): {len(values)} value(s) from --index {args.index} do not fit")
    with _connected(args, unlock=True) as m:
        try:
            m.write(it, values, args.index)
        except XcpError as exc:
            if "OUT_OF_RANGE" in str(exc):
                lo, hi = it.phys_limits()
                raise XcpError(f"{exc}: {it.name} takes [{lo:g}, {hi:g}] {it.unit}".rstrip() + "; nothing written") from None
            raise
        print(_show(it, m.read(it)))
    return 0


def run_save(args) -> int:
    from ..xcp import calfile

    desc = _description()
    with _connected(args) as m:
        raw = {it.name: m.read_raw(it) for it in desc.characteristics}
    calfile.save_values(desc, calfile.values_of(desc, lambda n: raw[n] if desc.item(n).shape else raw[n][0]), args.file)
    print(f"wrote {args.file}: {len(raw)} characteristics of {desc.name}", file=sys.stderr)
    return 0


def run_load(args) -> int:
    from ..xcp import calfile

    desc = _description()
    try:  # every check of the file before anything goes on the bus
        _, vals = calfile.load_image(desc, args.file, bytes(desc.calibration_size))
    except calfile.CalFileError as exc:
        raise ConfigError(str(exc)) from None
    with _connected(args, unlock=True) as m:
        for it in desc.characteristics:
            v = vals[it.name]
            m.write(it, [x for row in v for x in (row if isinstance(row, list) else [row])] if it.shape else [v])
    print(f"loaded {args.file}: {len(vals)} characteristics into the running ECU", file=sys.stderr)
    return 0
