"""The ECU's XCP description: its measurements and characteristics by their C names.

``ecu.toml`` says which members of ``vh_ecu_t`` are measurements and which members of
``vh_ecu_cal_t`` are characteristics, with units, physical limits and conversions; their C
types, shapes and addresses come from the structs through a cffi ``FFI`` (the build's parsed
headers, or the compiled ``vehest_can._native``: one layout, cffi checks it when compiling).
From the one ``Description`` come the firmware's limit table (``c_table``: what the slave
checks a DOWNLOAD against), the A2L (``a2l.generate``) and the XCP bus's DBC for the bus budget
(``dbc_text``), so none of them can disagree with the C or with each other.

Pure Python on purpose: ``c_core/vehest_build.py`` runs it before the extension exists.
"""
from __future__ import annotations

import re
import tomllib
from pathlib import Path

from . import a2l
from .args import ECU_TOML
from .description import C_TYPES, SAFETY_CLASSES, Description, DescriptionError, Event, Item, raw_limits_for_c

A2L_NAME = "VEHEST_ECU"
SHIPPED_A2L = Path(__file__).with_name(f"{A2L_NAME}.a2l")
MEAS_STRUCT, CAL_STRUCT = "vh_ecu_t", "vh_ecu_cal_t"
CAL_PREFIX = "cal."  # characteristic names: "cal." + the member path in vh_ecu_cal_t
_VH_XCP_TYPE = {"uint8_t": "VH_XCP_U8", "int8_t": "VH_XCP_I8", "uint16_t": "VH_XCP_U16",
                "int16_t": "VH_XCP_I16", "uint32_t": "VH_XCP_U32", "int32_t": "VH_XCP_I32",
                "float": "VH_XCP_F32", "double": "VH_XCP_F64"}
_TOKEN = re.compile(r"\.?([A-Za-z_]\w*)|\[(\d+)\]")
_ROW_KEYS = {"c", "elements", "unit", "units", "min", "max", "factor", "offset", "comment", "class"}


def _parse_path(path: str) -> list[str | int]:
    out: list[str | int] = []
    pos = 0
    while pos < len(path):
        m = _TOKEN.match(path, pos)
        if m is None or (pos == 0 and path.startswith(".")):
            raise DescriptionError(f"{path!r} is not a C member path such as dkf[0].x")
        out.append(m.group(1) if m.group(1) else int(m.group(2)))
        pos = m.end()
    return out


def _member(ffi, struct_name: str, path: str):
    """(ctype, offset) of a member path in a struct, checked against the C declarations."""
    t = ffi.typeof(struct_name)
    for tok in _parse_path(path):
        if isinstance(tok, str):
            fields = dict(t.fields or []) if t.kind == "struct" else {}
            if tok not in fields:
                raise DescriptionError(f"{struct_name} has no member {path!r} ({tok!r})")
            t = fields[tok].type
        else:
            if t.kind != "array" or not 0 <= tok < t.length:
                raise DescriptionError(f"{path!r}: index {tok} outside the C array")
            t = t.item
    return t, ffi.offsetof(struct_name, *_parse_path(path))


def _primitive(t, path: str) -> str:
    if t.kind != "primitive" or t.cname not in C_TYPES:
        raise DescriptionError(f"{path!r} is {t.cname}, not one of the A2L's scalar types")
    return t.cname


def _rows(doc: dict, kind: str) -> list[dict]:
    rows = doc.get(kind, [])
    for row in rows:
        if "c" not in row or set(row) - _ROW_KEYS:
            raise DescriptionError(f"{kind} row {row!r}: needs 'c', may have {', '.join(sorted(_ROW_KEYS - {'c'}))}")
    return rows


def _common(row: dict) -> dict:
    return {k: row[k] for k in ("unit", "min", "max", "factor", "offset") if k in row}


def _measurements(ffi, rows: list[dict], base: int) -> list[Item]:
    items = []
    for row in rows:
        path, comment = row["c"], row.get("comment", "")
        if "class" in row:
            raise DescriptionError(f"measurement {path!r}: a class is a characteristic's (measurements are read-only)")
        if path.endswith(".*"):
            t, _ = _member(ffi, MEAS_STRUCT, path[:-2])
            if t.kind != "struct":
                raise DescriptionError(f"{path!r}: '.*' takes the fields of a struct")
            leaves = [f"{path[:-2]}.{name}" for name, _ in t.fields]
        else:
            t, _ = _member(ffi, MEAS_STRUCT, path)
            if t.kind == "array":
                picks = row.get("elements", range(t.length))
                leaves = [f"{path}[{i}]" for i in picks]
            else:
                leaves = [path]
        # `units`: one per measurement the row makes (an array's elements differ: a state vector)
        units = row.get("units")
        if units is not None and ("unit" in row or len(units) != len(leaves)):
            raise DescriptionError(f"measurement {path!r}: units takes one unit per element ({len(leaves)}), "
                                   "instead of unit")
        for k, leaf in enumerate(leaves):
            lt, off = _member(ffi, MEAS_STRUCT, leaf)
            common = _common(row) if units is None else {**_common(row), "unit": units[k]}
            items.append(Item(name=leaf, ctype=_primitive(lt, leaf), kind="measurement", address=base + off,
                              comment=comment, **common))
    return items


def _characteristics(ffi, rows: list[dict], base: int) -> list[Item]:
    items = []
    for row in rows:
        path = row["c"]
        t, off = _member(ffi, CAL_STRUCT, path)
        shape: tuple[int, ...] = ()
        if t.kind == "array":
            shape, t = (t.length,), t.item
        if "min" not in row or "max" not in row:
            raise DescriptionError(f"characteristic {path!r}: writes are range-checked, give min and max")
        if "units" in row:
            raise DescriptionError(f"characteristic {path!r}: one unit for the whole block (an A2L VAL_BLK has one)")
        if row.get("class") not in SAFETY_CLASSES:
            raise DescriptionError(f"characteristic {path!r}: give its class, one of {', '.join(SAFETY_CLASSES)}")
        items.append(Item(name=CAL_PREFIX + path, ctype=_primitive(t, path), kind="characteristic",
                          address=base + off, shape=shape, comment=row.get("comment", ""),
                          safety_class=row["class"], **_common(row)))
    return items


def describe(ffi, path: Path = ECU_TOML) -> Description:
    """The ECU's Description, laid out by the C structs `ffi` declares."""
    with Path(path).open("rb") as f:
        doc = tomllib.load(f)
    x = doc.get("xcp", {})
    meas_base = int(x.get("measurement_address", 0x10000000))
    cal_base = int(x.get("calibration_address", 0x20000000))
    events = tuple(Event(e["name"], int(e["cycle_us"])) for e in doc.get("event", []))
    for ev in events:
        ev.xcp_cycle_unit()
    meas = _measurements(ffi, _rows(doc, "measurement"), meas_base)
    chars = _characteristics(ffi, _rows(doc, "characteristic"), cal_base)
    names = [it.name for it in meas + chars]
    if len(set(names)) != len(names):
        raise DescriptionError("a C member is described twice")
    desc = Description(
        name=x.get("name", A2L_NAME), cro_id=int(x["cro_id"]), dto_id=int(x["dto_id"]),
        max_cto=int(x["max_cto"]), max_dto=int(x["max_dto"]), fd=bool(x["fd"]),
        measurement_address=meas_base, calibration_address=cal_base, events=events,
        measurements=tuple(meas), characteristics=tuple(chars), bitrate=int(x.get("bitrate", 500000)),
        data_bitrate=int(x.get("data_bitrate", 4000000)),
        tick_us=int(x.get("tick_us", 500)), comment=x.get("comment", ""))
    if not desc.fd and (desc.max_cto > 8 or desc.max_dto > 8):
        raise DescriptionError("MAX_CTO/MAX_DTO above 8 need CAN FD (fd = true)")
    return desc


def data_bitrate(path: Path = ECU_TOML) -> int:
    with Path(path).open("rb") as f:
        return int(tomllib.load(f).get("xcp", {}).get("data_bitrate", 4000000))


def _c_double(v: float) -> str:
    return repr(float(v))  # shortest repr round-trips: the C compiler reads the same double


def regions(desc: Description) -> list[tuple[Item, int]]:
    """The readable measurement memory: (first item, size) per run of adjacent measurements, in
    address order. Only described bytes: a gap between two items (padding, a pointer, a member
    not described) ends a region."""
    out: list[list] = []
    for it in sorted(desc.measurements, key=lambda m: m.address):
        if out and it.address <= out[-1][0].address + out[-1][1]:
            out[-1][1] = max(out[-1][1], it.address + it.size - out[-1][0].address)
        else:
            out.append([it, it.size])
    return [(it, size) for it, size in out]


def c_table(desc: Description) -> str:
    """c_core/ecu/vh_ecu_xcp_table.inc: the characteristics with the A2L's limits and safety classes
    and the readable measurement regions, by offsetof (included by vh_ecu_xcp.c only; not a header,
    so the cdef never reads it)."""
    regs = regions(desc)
    lines = [
        "/* vh_ecu_xcp_table.inc - GENERATED from vehest_can/xcp/ecu.toml by vehest_can/xcp/ecu_desc.py",
        " * (c_core/vehest_build.py); do not edit. The characteristics of the ECU's calibration segment",
        " * with the raw limits of the A2L (the slave refuses a DOWNLOAD outside them) and their safety",
        " * class; the measurement regions: the described members of vh_ecu_t, adjacent ones merged, the",
        " * only memory UPLOAD and DAQ read. */",
        "#include <stddef.h>", "",
        f'#define VH_ECU_XCP_A2L_NAME "{desc.name}"',
        f"#define VH_ECU_XCP_N_CHARS {len(desc.characteristics)}u",
        f"#define VH_ECU_XCP_N_REGIONS {len(regs)}u", "",
        "static const vh_xcp_char_t VH_ECU_XCP_CHARS[] = {",
    ]
    for it in desc.characteristics:
        lo, hi = raw_limits_for_c(it)
        member = it.name[len(CAL_PREFIX):]
        flags = "VH_XCP_CHAR_SAFETY" if it.safety_class == "safety" else "0u"
        lines.append(f"    {{VH_ECU_XCP_CAL_ADDRESS + offsetof({CAL_STRUCT}, {member}), {it.count}u, "
                     f"{_VH_XCP_TYPE[it.ctype]}, {flags}, {_c_double(lo)}, {_c_double(hi)}}},")
    lines += ["};", "", "static const struct {", "    uint32_t offset, size;", "} VH_ECU_XCP_REGIONS[] = {"]
    for it, size in regs:
        lines.append(f"    {{(uint32_t)offsetof({MEAS_STRUCT}, {it.name}), {size}u}},")
    lines += ["};", ""]
    return "\n".join(lines)


def dbc_text(desc: Description, data_rate: int) -> str:
    """The XCP bus's DBC for ``vehest-can busload``: the slave's frame (a RES or a DTO, at most one per
    tick: VH_ECU_XCP_MAX_TX) is cyclic at the tick with the longer of MAX_CTO and MAX_DTO; the master's
    CRO is an event frame. A master in standard mode sends its next CRO only after the RES, and the
    RES takes the tick's one slave frame, so per tick the bus carries a CRO and its RES or a DTO:
    ``worst_case_frames`` (the budget test holds it to 60 %)."""
    fmt = 14 if desc.fd else 0
    ext = 0x80000000
    def frame_id(i: int) -> int:
        return (i & 0x1FFFFFFF) | ext if i & ext else i
    cro, dto = frame_id(desc.cro_id), frame_id(desc.dto_id)
    if desc.cro_id & ext or desc.dto_id & ext:
        fmt += 1
    slave_len = max(desc.max_cto, desc.max_dto)
    return "\n".join([
        'VERSION ""', "", "NS_ :", "", "BS_:", "", "BU_: XCP_MASTER VEHEST", "",
        f"BO_ {cro} XCP_CRO: {desc.max_cto} XCP_MASTER", "",
        f"BO_ {dto} XCP_DTO: {slave_len} VEHEST", "",
        f'CM_ "GENERATED from vehest_can/xcp/ecu.toml: the XCP-on-CAN bus of the vehest ECU. The ECU sends at '
        f'most one XCP frame per {desc.tick_us} us tick (VH_ECU_XCP_MAX_TX: a RES of up to MAX_CTO or a DTO of up '
        f'to MAX_DTO bytes), cyclic here; a master in standard mode sends a CRO (event frame) only after the '
        f'RES of the one before, so per tick the worst case is a CRO and its RES, or one DTO.";',
        'BA_DEF_ "Baudrate" INT 10000 1000000;', 'BA_DEF_ "BaudrateCANFD" INT 500000 10000000;',
        'BA_DEF_ BO_ "GenMsgCycleTime" FLOAT 0 65535;', 'BA_DEF_ BO_ "CycleTimeUs" INT 0 100000000;',
        'BA_DEF_ BO_ "GenMsgSendType" ENUM "Cyclic","Event";',
        'BA_DEF_ BO_ "VFrameFormat" ENUM "StandardCAN","ExtendedCAN","reserved","reserved","reserved",'
        '"reserved","reserved","reserved","reserved","reserved","reserved","reserved","reserved","reserved",'
        '"StandardCAN_FD","ExtendedCAN_FD";',
        'BA_DEF_DEF_ "Baudrate" 500000;', 'BA_DEF_DEF_ "BaudrateCANFD" 4000000;', 'BA_DEF_DEF_ "CycleTimeUs" 0;',
        'BA_DEF_DEF_ "GenMsgCycleTime" 0;', 'BA_DEF_DEF_ "GenMsgSendType" "Event";',
        'BA_DEF_DEF_ "VFrameFormat" "StandardCAN";',
        f'BA_ "Baudrate" {desc.bitrate};', f'BA_ "BaudrateCANFD" {data_rate};',
        f'BA_ "VFrameFormat" BO_ {cro} {fmt};',
        f'BA_ "GenMsgCycleTime" BO_ {dto} {desc.tick_us / 1000:g};',  # ms, as the bus DBCs (docs/busload.md)
        f'BA_ "CycleTimeUs" BO_ {dto} {desc.tick_us};', f'BA_ "GenMsgSendType" BO_ {dto} 0;',
        f'BA_ "VFrameFormat" BO_ {dto} {fmt};', "",
    ])


def worst_case_frames(desc: Description) -> list[tuple[int, ...]]:
    """The payload lengths on the XCP bus in one tick, for each case the firmware allows: a CRO and
    its RES (each up to MAX_CTO), or one DTO (MAX_DTO). The bus budget is the longest of them."""
    return [(desc.max_cto, desc.max_cto), (desc.max_dto,)]


TABLE = Path(__file__).resolve().parents[2] / "c_core" / "ecu" / "vh_ecu_xcp_table.inc"
SHIPPED_DBC = Path(__file__).with_name("vehest_xcp.dbc")


def outputs(desc: Description, path: Path = ECU_TOML) -> dict[Path, str]:
    """Every file made from the description: the firmware's limit table, the A2L, the DBC."""
    return {TABLE: c_table(desc), SHIPPED_A2L: a2l.generate(desc), SHIPPED_DBC: dbc_text(desc, data_bitrate(path))}


def generate(ffi, path: Path = ECU_TOML) -> Description:
    """Write the outputs where they are changed (the build does this before compiling)."""
    desc = describe(ffi, path)
    for target, text in outputs(desc, path).items():
        if target.parent.is_dir() and (not target.exists() or target.read_text() != text):
            target.write_text(text)
    return desc
