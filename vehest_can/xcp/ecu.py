"""The XCP slave inside the ECU firmware (``c_core/ecu/vh_ecu_xcp.h``), seen from Python.

Off unless switched on: ``enable(ecu, key)`` with the user's key (``keys.load_key``) switches it
on in a :class:`vehest_can.systems.ecu.Ecu`: from then on the CRO frames handed to ``ecu.rx``
(or, with ``own_bus``, only those handed to ``rx_own``: the XCP bus) reach it through the ECU's
own dispatch and its RES/ERR/DTO frames come out of ``ecu.step`` with the systems' frames, so
every way of driving the ECU (in-process, lockstep, real time, the daemon) serves XCP without
more code. The layout is the C structs'; ``description()`` is the same Description the build
wrote the A2L and the limit table from.
"""
from __future__ import annotations

import os
import struct
import sys
import weakref
from functools import lru_cache

from ..bus.frames import to_frame
from ..errors import ConfigError
from ..native import ffi, lib
from ..systems.ecu import Ecu
from . import ecu_desc
from .args import add_arguments  # noqa: F401 - the daemon's XCP flags, kept beside the slave they set up
from .description import C_TYPES, Description
from .keys import DEV_KEY, load_key

COUNTERS = [f[0] for f in ffi.typeof("vh_xcp_counters_t").fields]
#: the key schedule each enabled ECU's slave reads: outside vh_ecu_t (never in XCP's memory), alive
#: as long as its ECU
_KEYS: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()
PAGES = ("page", "work", "ref")  # what the systems run on, the working page, the reference page


@lru_cache(maxsize=1)
def description() -> Description:
    """The ECU's XCP description, laid out by the compiled extension's structs."""
    return ecu_desc.describe(ffi)


def firmware_key_for(seed: bytes, resource: int, key: bytes) -> bytes:
    """The key as the firmware computes it (vh_xcp_key, the C); ``keys.key_for`` is the independent one."""
    k = ffi.new("vh_cmac_key_t *")
    if lib.vh_cmac_init(k, key) != 0:
        raise ConfigError("the AES backend refused the XCP key")
    out = ffi.new("uint8_t[]", lib.VH_XCP_KEY_LEN)
    lib.vh_xcp_key(k, resource, seed, out)
    lib.vh_cmac_wipe(k)
    return bytes(out)


def enable(ecu: Ecu, key: bytes, *, cro_id: int | None = None, dto_id: int | None = None,
           max_cto: int | None = None, max_dto: int | None = None, fd: bool | None = None,
           own_bus: bool = False, cal_mode: bool = False, salt: bytes | None = None) -> Description:
    """Switch the slave on with the user's 16-byte seed & key key (the ECU's tuning as configured
    now becomes the reference page). Identifiers, MAX_CTO/MAX_DTO and CAN FD default to the
    description's; ``own_bus``: the slave answers only CROs handed to ``rx_own`` (its own bus);
    ``cal_mode``: calibration mode (roll held passive); ``salt``: 8 bytes that make this start's
    seeds (default random). ConfigError if the firmware refuses them. Returns the description with
    the values in use."""
    from dataclasses import replace

    if not isinstance(key, (bytes, bytearray)) or len(key) != 16:
        raise ConfigError("XCP needs a 16-byte (AES-128) seed & key key: `vehest-can xcp keygen FILE`")
    salt = os.urandom(lib.VH_XCP_SALT_LEN) if salt is None else salt
    if len(salt) != lib.VH_XCP_SALT_LEN:
        raise ConfigError(f"the XCP seed salt is {lib.VH_XCP_SALT_LEN} bytes")
    k = ffi.new("vh_cmac_key_t *")
    if lib.vh_cmac_init(k, bytes(key)) != 0:
        raise ConfigError("the AES backend refused the XCP key")

    desc = description()
    desc = replace(desc, cro_id=desc.cro_id if cro_id is None else cro_id,
                   dto_id=desc.dto_id if dto_id is None else dto_id,
                   max_cto=desc.max_cto if max_cto is None else max_cto,
                   max_dto=desc.max_dto if max_dto is None else max_dto,
                   fd=desc.fd if fd is None else fd)
    c = ffi.new("vh_ecu_xcp_config_t *")
    c.cro_id, c.dto_id, c.max_cto, c.max_dto, c.fd = desc.cro_id, desc.dto_id, desc.max_cto, desc.max_dto, int(desc.fd)
    c.key, c.salt, c.own_bus, c.cal_mode = k, salt, int(own_bus), int(cal_mode)
    _KEYS[ecu] = k  # before the slave can read it; replaced (a new key) on a second enable
    if lib.vh_ecu_xcp_enable(ecu.c, c) != lib.VH_OK:
        raise ConfigError(f"XCP configuration refused by the ECU: CRO 0x{desc.cro_id:X}, DTO 0x{desc.dto_id:X}, "
                          f"MAX_CTO {desc.max_cto}, MAX_DTO {desc.max_dto}, fd={desc.fd} "
                          "(8..64, above 8 only with CAN FD, CRO and DTO apart)")
    return desc


def enabled(ecu: Ecu) -> bool:
    return bool(ecu.c.xcp.enabled)


def counters(ecu: Ecu) -> dict[str, int]:
    return {name: int(getattr(ecu.c.xcp.slave.n, name)) for name in COUNTERS}


def state(ecu: Ecu) -> dict[str, int]:
    """The slave's counters and its seed & key and safe-state flags (the daemon's --stats "xcp")."""
    x = ecu.c.xcp
    return counters(ecu) | {"fail_streak": int(x.slave.fail_streak), "locked_out": int(x.slave.locked_out),
                            "safe": int(x.safe), "cal_mode": int(x.cal_mode), "own_bus": int(x.own_bus)}


_RX_OWN = ffi.new("vh_frame_t *")  # the daemon's receive path is one thread


def rx_own(ecu: Ecu, msg) -> None:
    """A frame heard on XCP's own bus: its CRO reaches the slave; nothing there is the systems' input."""
    if not (msg.is_error_frame or msg.is_remote_frame):
        lib.vh_ecu_xcp_rx_own(ecu.c, to_frame(msg, _RX_OWN))


def read_raw(ecu: Ecu, name: str, page: str = "page"):
    """Raw value(s) of a measurement, or of a characteristic on one of the three pages."""
    desc = description()
    item = desc.item(name)
    if item.kind == "measurement":
        off = item.address - desc.measurement_address
        raw = bytes(ffi.buffer(ecu.c, ffi.sizeof("vh_ecu_t"))[off:off + item.size])
    else:
        if page not in PAGES:
            raise ConfigError(f"page must be one of {', '.join(PAGES)}, not {page!r}")
        off = item.address - desc.calibration_address
        raw = bytes(ffi.buffer(ffi.addressof(ecu.c.xcp, page), ffi.sizeof("vh_ecu_cal_t"))[off:off + item.size])
    vals = list(struct.unpack("<" + C_TYPES[item.ctype][4] * item.count, raw))
    return vals if item.shape else vals[0]


def read(ecu: Ecu, name: str, page: str = "page"):
    """Physical value(s) of a measurement, or of a characteristic on one of the three pages."""
    item = description().item(name)
    raw = read_raw(ecu, name, page)
    return [item.raw_to_phys(v) for v in raw] if item.shape else item.raw_to_phys(raw)


def save_calibration(ecu: Ecu, path, page: str = "work") -> None:
    """A page as a calibration file (calfile.py: versioned JSON, physical values, written atomically)."""
    from . import calfile

    desc = description()
    calfile.save_values(desc, calfile.values_of(desc, lambda name: read_raw(ecu, name, page)), path)


def load_calibration(ecu: Ecu, path) -> dict:
    """Start the ECU on a calibration file: every check of calfile.py (format, version, names,
    shapes, limits, resolution), then it is the reference, working and running page at once and
    in the filters, as if flashed. Before the first tick; CalFileError and nothing changed if bad."""
    from . import calfile

    if not enabled(ecu):
        raise ConfigError("enable XCP on the ECU before loading a calibration file")
    size = ffi.sizeof("vh_ecu_cal_t")
    try:
        image, vals = calfile.load_image(description(), path, bytes(ffi.buffer(ffi.addressof(ecu.c.xcp, "ref"), size)))
    except calfile.CalFileError as exc:
        raise ConfigError(str(exc)) from None
    for page in PAGES:
        ffi.buffer(ffi.addressof(ecu.c.xcp, page), size)[:] = image
    lib.vh_ecu_cal_apply(ecu.c, ffi.addressof(ecu.c.xcp, "page"))
    return vals


# ---- the daemon's configuration (vehest-can daemon) -------------------------------------------

def _int(text: str) -> int:
    try:
        return int(text, 0)
    except ValueError:
        raise ConfigError(f"{text!r} is not a number (decimal or 0x hex)") from None


def from_args(args, ecu: Ecu) -> Description | None:
    """Enable the slave on `ecu` as the flags say; None with --xcp off (the default)."""
    if getattr(args, "xcp", "off") != "on":
        for flag in ("xcp_cal", "xcp_key", "xcp_dev", "xcp_cal_mode"):
            if getattr(args, flag, None):
                raise ConfigError(f"--{flag.replace('_', '-')} needs the XCP slave (--xcp on)")
        return None
    if args.xcp_key and args.xcp_dev:
        raise ConfigError("--xcp-key and --xcp-dev exclude each other: the user's key, or the public development key")
    if not (args.xcp_key or args.xcp_dev):
        raise ConfigError("--xcp on needs a seed & key key: --xcp-key FILE (`vehest-can xcp keygen FILE` makes one), "
                          "or --xcp-dev for a bench")
    key = load_key(args.xcp_key) if args.xcp_key else DEV_KEY
    opt = {k: _int(v) for k, v in (("cro_id", args.xcp_cro_id), ("dto_id", args.xcp_dto_id),
                                   ("max_cto", args.xcp_max_cto), ("max_dto", args.xcp_max_dto)) if v is not None}
    for k in ("cro_id", "dto_id"):
        if k in opt and not 0 <= opt[k] & 0x7FFFFFFF <= (0x1FFFFFFF if opt[k] & 0x80000000 else 0x7FF):
            raise ConfigError(f"--xcp-{k.replace('_', '-')} 0x{opt[k]:X} is not a CAN identifier")
    fd = None if args.xcp_fd is None else args.xcp_fd == "on"
    desc = enable(ecu, key, cro_id=opt.get("cro_id"), dto_id=opt.get("dto_id"), max_cto=opt.get("max_cto"),
                  max_dto=opt.get("max_dto"), fd=fd, own_bus=own_bus(args), cal_mode=bool(args.xcp_cal_mode))
    if args.xcp_dev:
        print("vehest-can daemon: XCP development mode: seed & key with the fixed, public development key "
              "(anyone can unlock calibration: a bench, never a car)", file=sys.stderr, flush=True)
    if args.xcp_cal:
        load_calibration(ecu, args.xcp_cal)
    return desc


_BUS_KEYS = ("interface", "channel", "bitrate", "data_bitrate", "timing", "bus_kwargs")


def own_bus(args) -> bool:
    """XCP on a bus of its own: the flags name one (the slave then listens there only)."""
    return any(getattr(args, f"xcp_{k}", None) is not None for k in ("interface", "channel")) or \
        bool(getattr(args, "xcp_bus_context", None))


def bus_config(args, desc: Description | None) -> dict | None:
    """The XCP bus's python-can configuration when the flags name one (--xcp-interface,
    --xcp-channel or --xcp-bus-context; resolved as the main bus is: flags > configuration file >
    the embedded udp_multicast default), else None: XCP on the ECU's (first) bus."""
    from argparse import Namespace

    from ..bus import bus as busmod

    given = {k: getattr(args, f"xcp_{k}") for k in _BUS_KEYS if getattr(args, f"xcp_{k}", None) is not None}
    context = getattr(args, "xcp_bus_context", None)
    if not ({"interface", "channel"} & set(given) or context):
        if given:
            raise ConfigError(f"--xcp-{next(iter(given)).replace('_', '-')} configures a separate XCP bus: "
                              "name it with --xcp-interface/--xcp-channel (or --xcp-bus-context)")
        return None
    if desc is None:
        raise ConfigError("an XCP bus (--xcp-interface/--xcp-channel) needs the XCP slave (--xcp on)")
    ns = Namespace(**given, fd=desc.fd, bus_config=getattr(args, "bus_config", None), bus_context=context)
    return busmod.bus_config(ns)


def summary(ecu: Ecu) -> str:
    n = {k: v for k, v in counters(ecu).items() if v}
    text = "xcp: " + (", ".join(f"{k}={v}" for k, v in n.items()) if n else "no traffic")
    return text + ("; seed & key LOCKED OUT (too many wrong keys) until restart" if ecu.c.xcp.slave.locked_out else "")
