"""A2L (ASAM MCD-2 MC, ASAP2 1.7.1) from a description: the same table that configures the slave.

Generated, never edited: ``python -m vehest_can.xcp.a2l [DESCRIPTION.toml] -o FILE.a2l`` (default:
the demo description to ``vehest_can/xcp/<NAME>.a2l``, the shipped file). The output is deterministic (no dates, sorted
where order is not meaningful), so a test regenerates it and compares with the shipped file.

What it writes: PROJECT/HEADER/MODULE; MOD_PAR with the two MEMORY_SEGMENTs (measurement RAM and
the calibration segment with its working and reference pages in IF_DATA XCP SEGMENT/PAGE);
MOD_COMMON (byte order, alignment); IF_DATA XCP (PROTOCOL_LAYER with MAX_CTO/MAX_DTO and the
optional commands the slave has, DAQ with the event channels, PAG, XCP_ON_CAN with the
identifiers and, on CAN FD, MAX_DLC); one COMPU_METHOD per scaled item (LINEAR: phys = a * raw +
b, COEFFS_LINEAR a b) and CM_IDENTICAL for the rest; one RECORD_LAYOUT per datatype; MEASUREMENT
and CHARACTERISTIC (VALUE, or VAL_BLK with MATRIX_DIM) by their C names, each characteristic with
its safety class in an ANNOTATION (label "safety class": "tuning" or "safety").
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

from .description import C_TYPES, DEMO, Description, Item, load

# The shipped build output sits beside the description it comes from.
SHIPPED_DIR = Path(__file__).resolve().parent

# The optional commands the C slave implements (c_core/xcp/vh_xcp.c), as the A2L names them.
OPTIONAL_CMDS = [
    "GET_COMM_MODE_INFO", "GET_ID", "GET_SEED", "UNLOCK", "SET_MTA", "UPLOAD", "SHORT_UPLOAD",
    "DOWNLOAD", "SHORT_DOWNLOAD", "SET_CAL_PAGE", "GET_CAL_PAGE", "GET_PAG_PROCESSOR_INFO",
    "CLEAR_DAQ_LIST", "SET_DAQ_PTR", "WRITE_DAQ", "SET_DAQ_LIST_MODE", "GET_DAQ_LIST_MODE",
    "START_STOP_DAQ_LIST", "START_STOP_SYNCH", "GET_DAQ_CLOCK", "GET_DAQ_PROCESSOR_INFO",
    "GET_DAQ_RESOLUTION_INFO", "GET_DAQ_EVENT_INFO", "FREE_DAQ", "ALLOC_DAQ", "ALLOC_ODT",
    "ALLOC_ODT_ENTRY",
]
MAX_DAQ = 8  # VH_XCP_MAX_DAQ
#: each characteristic's safety class as an ANNOTATION (label "safety class", text: the class and its rule)
SAFETY_TEXT = {
    "tuning": "tuning: any value within the limits, at any time",
    "safety": "safety: written only in the ECU's safe state (roll control passive and the car at standstill, "
              "or calibration mode); otherwise ERR_WRITE_PROTECTED",
}
TIME_UNITS = {3: "UNIT_1US", 4: "UNIT_10US", 5: "UNIT_100US", 6: "UNIT_1MS", 7: "UNIT_10MS", 8: "UNIT_100MS"}


# The A2ML that lets a parser read the IF_DATA XCP blocks: the part of the ASAM XCP 1.x AML
# (XCP_common, XCP_on_CAN) that this file uses, with the standard's keywords and value order.
A2ML = """\
/begin A2ML
  struct Protocol_Layer {
    uint; uint; uint; uint; uint; uint; uint; uint;  /* version, T1..T7 [ms] */
    uchar;                                          /* MAX_CTO */
    uint;                                           /* MAX_DTO */
    enum { "BYTE_ORDER_MSB_LAST" = 0, "BYTE_ORDER_MSB_FIRST" = 1 };
    enum { "ADDRESS_GRANULARITY_BYTE" = 1, "ADDRESS_GRANULARITY_WORD" = 2, "ADDRESS_GRANULARITY_DWORD" = 4 };
    taggedstruct {
      ("OPTIONAL_CMD" enum {
        "GET_COMM_MODE_INFO" = 0xFB, "GET_ID" = 0xFA, "GET_SEED" = 0xF8, "UNLOCK" = 0xF7,
        "SET_MTA" = 0xF6, "UPLOAD" = 0xF5, "SHORT_UPLOAD" = 0xF4, "DOWNLOAD" = 0xF0,
        "SHORT_DOWNLOAD" = 0xED, "SET_CAL_PAGE" = 0xEB, "GET_CAL_PAGE" = 0xEA,
        "GET_PAG_PROCESSOR_INFO" = 0xE9, "CLEAR_DAQ_LIST" = 0xE3, "SET_DAQ_PTR" = 0xE2,
        "WRITE_DAQ" = 0xE1, "SET_DAQ_LIST_MODE" = 0xE0, "GET_DAQ_LIST_MODE" = 0xDF,
        "START_STOP_DAQ_LIST" = 0xDE, "START_STOP_SYNCH" = 0xDD, "GET_DAQ_CLOCK" = 0xDC,
        "GET_DAQ_PROCESSOR_INFO" = 0xDA, "GET_DAQ_RESOLUTION_INFO" = 0xD9,
        "GET_DAQ_EVENT_INFO" = 0xD7, "FREE_DAQ" = 0xD6, "ALLOC_DAQ" = 0xD5, "ALLOC_ODT" = 0xD4,
        "ALLOC_ODT_ENTRY" = 0xD3
      })*;
    };
  };
  struct Daq {
    enum { "STATIC" = 0, "DYNAMIC" = 1 };
    uint;   /* MAX_DAQ */
    uint;   /* MAX_EVENT_CHANNEL */
    uchar;  /* MIN_DAQ */
    enum { "OPTIMISATION_TYPE_DEFAULT" = 0 };
    enum { "ADDRESS_EXTENSION_FREE" = 0, "ADDRESS_EXTENSION_ODT" = 1, "ADDRESS_EXTENSION_DAQ" = 3 };
    enum { "IDENTIFICATION_FIELD_TYPE_ABSOLUTE" = 0, "IDENTIFICATION_FIELD_TYPE_RELATIVE_BYTE" = 1,
           "IDENTIFICATION_FIELD_TYPE_RELATIVE_WORD" = 2, "IDENTIFICATION_FIELD_TYPE_RELATIVE_WORD_ALIGNED" = 3 };
    enum { "GRANULARITY_ODT_ENTRY_SIZE_DAQ_BYTE" = 1, "GRANULARITY_ODT_ENTRY_SIZE_DAQ_WORD" = 2,
           "GRANULARITY_ODT_ENTRY_SIZE_DAQ_DWORD" = 4, "GRANULARITY_ODT_ENTRY_SIZE_DAQ_DLONG" = 8 };
    uchar;  /* MAX_ODT_ENTRY_SIZE_DAQ */
    enum { "NO_OVERLOAD_INDICATION" = 0, "OVERLOAD_INDICATION_PID" = 1, "OVERLOAD_INDICATION_EVENT" = 2 };
    taggedstruct {
      "PRESCALER_SUPPORTED";
      block "TIMESTAMP_SUPPORTED" struct {
        uint;  /* TIMESTAMP_TICKS */
        enum { "NO_TIME_STAMP" = 0, "SIZE_BYTE" = 1, "SIZE_WORD" = 2, "SIZE_DWORD" = 4 };
        enum { "UNIT_1NS" = 0, "UNIT_10NS" = 1, "UNIT_100NS" = 2, "UNIT_1US" = 3, "UNIT_10US" = 4,
               "UNIT_100US" = 5, "UNIT_1MS" = 6, "UNIT_10MS" = 7, "UNIT_100MS" = 8, "UNIT_1S" = 9 };
        taggedstruct { "TIMESTAMP_FIXED"; };
      };
      (block "EVENT" struct {
        char[101];  /* EVENT_CHANNEL_NAME */
        char[9];    /* EVENT_CHANNEL_SHORT_NAME */
        uint;       /* EVENT_CHANNEL_NUMBER */
        enum { "DAQ" = 1, "STIM" = 2, "DAQ_STIM" = 3 };
        uchar;      /* MAX_DAQ_LIST */
        uchar;      /* EVENT_CHANNEL_TIME_CYCLE */
        uchar;      /* EVENT_CHANNEL_TIME_UNIT */
        uchar;      /* EVENT_CHANNEL_PRIORITY */
      })*;
    };
  };
  struct Pag {
    uchar;  /* MAX_SEGMENTS */
    taggedstruct { "FREEZE_SUPPORTED"; };
  };
  struct Segment {
    uchar; uchar; uchar; uchar; uchar;  /* SEGMENT_NUMBER, pages, address extension, compression, encryption */
    taggedstruct {
      (block "PAGE" struct {
        uchar;  /* PAGE_NUMBER */
        enum { "ECU_ACCESS_NOT_ALLOWED" = 0, "ECU_ACCESS_WITHOUT_XCP_ONLY" = 1,
               "ECU_ACCESS_WITH_XCP_ONLY" = 2, "ECU_ACCESS_DONT_CARE" = 3 };
        enum { "XCP_READ_ACCESS_NOT_ALLOWED" = 0, "XCP_READ_ACCESS_WITHOUT_ECU_ONLY" = 1,
               "XCP_READ_ACCESS_WITH_ECU_ONLY" = 2, "XCP_READ_ACCESS_DONT_CARE" = 3 };
        enum { "XCP_WRITE_ACCESS_NOT_ALLOWED" = 0, "XCP_WRITE_ACCESS_WITHOUT_ECU_ONLY" = 1,
               "XCP_WRITE_ACCESS_WITH_ECU_ONLY" = 2, "XCP_WRITE_ACCESS_DONT_CARE" = 3 };
        taggedstruct { "INIT_SEGMENT" uchar; };
      })*;
    };
  };
  taggedstruct Common_Parameters {
    block "PROTOCOL_LAYER" struct Protocol_Layer;
    block "SEGMENT" struct Segment;
    block "DAQ" struct Daq;
    block "PAG" struct Pag;
  };
  struct CAN_Parameters {
    uint;  /* XCP on CAN version */
    taggedstruct {
      "CAN_ID_MASTER" ulong;  /* bit 31 set: 29-bit identifier */
      "CAN_ID_SLAVE" ulong;
      "BAUDRATE" ulong;
      block "CAN_FD" struct {
        taggedstruct { "MAX_DLC" uint; "CAN_FD_DATA_TRANSFER_BAUDRATE" ulong; };
      };
    };
  };
  block "IF_DATA" taggedunion if_data {
    "XCP" struct {
      taggedstruct Common_Parameters;
      taggedstruct {
        block "XCP_ON_CAN" struct {
          struct CAN_Parameters;
          taggedstruct Common_Parameters;
        };
      };
    };
  };
/end A2ML"""


def _q(s: str) -> str:
    return '"' + s.replace("\\", "\\\\").replace('"', '\\"') + '"'


def _num(v: float) -> str:
    """Shortest exact text of a limit (repr round-trips a double)."""
    if float(v).is_integer() and abs(v) < 1e15:
        return str(int(v))
    return repr(float(v))


def _hex(v: int) -> str:
    return f"0x{v:X}"


def _layout_name(ctype: str) -> str:
    return f"RL_{C_TYPES[ctype][2]}"


def _compu(item: Item) -> list[str]:
    # ASAP2 display format "%Length.Layout" (total width, decimals), no type letter
    fmt = '"%12.6"' if item.ctype in ("float", "double") else '"%10.3"' if item.factor != 1.0 else '"%10.0"'
    return [
        f"/begin COMPU_METHOD {item.compu_name} {_q(item.name + ' conversion')}",
        f"  LINEAR {fmt} {_q(item.unit)}",
        f"  COEFFS_LINEAR {_num(item.factor)} {_num(item.offset)}",
        "/end COMPU_METHOD",
    ]


def _measurement(item: Item) -> list[str]:
    lo, hi = item.phys_limits()
    out = [
        f"/begin MEASUREMENT {item.name} {_q(item.comment)}",
        f"  {C_TYPES[item.ctype][2]} {item.compu_name} 0 0 {_num(lo)} {_num(hi)}",
        f"  ECU_ADDRESS {_hex(item.address)}",
    ]
    if item.unit:
        out.append(f"  PHYS_UNIT {_q(item.unit)}")
    out.append("/end MEASUREMENT")
    return out


def _characteristic(item: Item) -> list[str]:
    lo, hi = item.phys_limits()
    kind = "VAL_BLK" if item.shape else "VALUE"
    out = [
        f"/begin CHARACTERISTIC {item.name} {_q(item.comment)}",
        f"  {kind} {_hex(item.address)} {_layout_name(item.ctype)} 0 {item.compu_name} {_num(lo)} {_num(hi)}",
    ]
    if item.shape:
        dims = list(item.shape) + [1] * (3 - len(item.shape))  # x y z, as ASAP2 1.6 wants all three
        out.append("  MATRIX_DIM " + " ".join(str(n) for n in dims))
    if item.unit:
        out.append(f"  PHYS_UNIT {_q(item.unit)}")
    out += ["  /begin ANNOTATION", f"    ANNOTATION_LABEL {_q('safety class')}",
            f"    ANNOTATION_ORIGIN {_q('vehest-can')}", "    /begin ANNOTATION_TEXT",
            f"      {_q(SAFETY_TEXT[item.safety_class])}", "    /end ANNOTATION_TEXT", "  /end ANNOTATION"]
    out.append("/end CHARACTERISTIC")
    return out


def _if_data_xcp(d: Description) -> list[str]:
    out = [
        "/begin IF_DATA XCP",
        # version, T1..T7 timeouts (ms), MAX_CTO, MAX_DTO, byte order, address granularity
        f"  /begin PROTOCOL_LAYER 0x0100 1000 2000 0 0 0 0 0 {d.max_cto} {d.max_dto} "
        "BYTE_ORDER_MSB_LAST ADDRESS_GRANULARITY_BYTE",
    ]
    out += [f"    OPTIONAL_CMD {c}" for c in OPTIONAL_CMDS]
    out += [
        "  /end PROTOCOL_LAYER",
        # DAQ: dynamic, MAX_DAQ, MAX_EVENT_CHANNEL, MIN_DAQ, absolute ODT numbers, MAX_ODT_ENTRY_SIZE
        f"  /begin DAQ DYNAMIC {MAX_DAQ} {len(d.events)} 0 OPTIMISATION_TYPE_DEFAULT ADDRESS_EXTENSION_FREE "
        f"IDENTIFICATION_FIELD_TYPE_ABSOLUTE GRANULARITY_ODT_ENTRY_SIZE_DAQ_BYTE {d.max_dto - 1} NO_OVERLOAD_INDICATION",
        "    PRESCALER_SUPPORTED",
        # one timestamp tick per ECU tick (TIMESTAMP_TICKS in 1 us), 4 bytes: the tick count
        f"    /begin TIMESTAMP_SUPPORTED {d.tick_us} SIZE_DWORD UNIT_1US",
        "    /end TIMESTAMP_SUPPORTED",
    ]
    for ch, ev in enumerate(d.events):
        cycle, unit = ev.xcp_cycle_unit()
        # name, short name, channel number, DAQ, MAX_DAQ_LIST, cycle, unit, priority
        out += [f"    /begin EVENT {_q(ev.name)} {_q(ev.name[:8])} {ch} DAQ 0xFF {cycle} {unit} 0",
                "    /end EVENT"]
    out += [
        "  /end DAQ",
        "  /begin PAG 1",  # one segment
        "  /end PAG",
        "  /begin XCP_ON_CAN 0x0100",
        f"    CAN_ID_MASTER {_hex(d.cro_id)}",
        f"    CAN_ID_SLAVE {_hex(d.dto_id)}",
        f"    BAUDRATE {d.bitrate}",
    ]
    if d.fd:
        out += ["    /begin CAN_FD", f"      MAX_DLC {max(d.max_cto, d.max_dto)}", "    /end CAN_FD"]
    out += ["  /end XCP_ON_CAN", "/end IF_DATA"]
    return out


def _mod_par(d: Description) -> list[str]:
    return [
        f"/begin MOD_PAR {_q(d.comment)}",
        f"  ECU {_q(d.name)}",
        f"  /begin MEMORY_SEGMENT Measurements {_q('ECU RAM: measurements')} VARIABLES RAM INTERN "
        f"{_hex(d.measurement_address)} {_hex(d.measurement_size)} -1 -1 -1 -1 -1",
        "  /end MEMORY_SEGMENT",
        f"  /begin MEMORY_SEGMENT Calibration {_q('calibration segment: page 0 working (RAM), page 1 reference')} "
        f"DATA FLASH INTERN {_hex(d.calibration_address)} {_hex(d.calibration_size)} -1 -1 -1 -1 -1",
        "    /begin IF_DATA XCP",
        # segment 0, 2 pages, address extension 0, compression and encryption none
        "      /begin SEGMENT 0 2 0 0 0",
        "        /begin PAGE 0 ECU_ACCESS_DONT_CARE XCP_READ_ACCESS_DONT_CARE XCP_WRITE_ACCESS_DONT_CARE",
        "        /end PAGE",
        "        /begin PAGE 1 ECU_ACCESS_DONT_CARE XCP_READ_ACCESS_DONT_CARE XCP_WRITE_ACCESS_NOT_ALLOWED",
        "        /end PAGE",
        "      /end SEGMENT",
        "    /end IF_DATA",
        "  /end MEMORY_SEGMENT",
        "/end MOD_PAR",
    ]


def generate(d: Description) -> str:
    items = list(d.measurements) + list(d.characteristics)
    body: list[str] = A2ML.splitlines()
    body += _mod_par(d)
    body += [
        f"/begin MOD_COMMON {_q('')}",
        "  BYTE_ORDER MSB_LAST",  # little endian (Intel), what CONNECT reports
        "  ALIGNMENT_BYTE 1", "  ALIGNMENT_WORD 2", "  ALIGNMENT_LONG 4",
        "  ALIGNMENT_FLOAT32_IEEE 4", "  ALIGNMENT_FLOAT64_IEEE 8",
        "/end MOD_COMMON",
    ]
    body += _if_data_xcp(d)
    body += [
        "/begin COMPU_METHOD CM_IDENTICAL \"no conversion\"",
        "  IDENTICAL \"%12.6\" \"\"",
        "/end COMPU_METHOD",
    ]
    for item in sorted((i for i in items if i.compu_name != "CM_IDENTICAL"), key=lambda i: i.name):
        body += _compu(item)
    for ctype in sorted({c.ctype for c in d.characteristics}, key=lambda t: C_TYPES[t][0]):
        body += [f"/begin RECORD_LAYOUT {_layout_name(ctype)}",
                 f"  FNC_VALUES 1 {C_TYPES[ctype][2]} ROW_DIR DIRECT",
                 "/end RECORD_LAYOUT"]
    for m in d.measurements:
        body += _measurement(m)
    for c in d.characteristics:
        body += _characteristic(c)
    lines = [
        "/* Generated by vehest_can.xcp.a2l from the XCP description; do not edit. */",
        "ASAP2_VERSION 1 71",
        f"/begin PROJECT {d.name} {_q(d.comment)}",
        "  /begin HEADER \"vehest-can\"",
        "    VERSION \"1\"",
        "  /end HEADER",
        f"  /begin MODULE {d.name} {_q(d.comment)}",
    ]
    lines += ["    " + b for b in body]
    lines += ["  /end MODULE", "/end PROJECT", ""]
    return "\n".join(lines)


def write(d: Description, path: Path | None = None) -> Path:
    path = Path(path) if path is not None else SHIPPED_DIR / f"{d.name}.a2l"
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(generate(d))
    return path


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m vehest_can.xcp.a2l", description=__doc__.splitlines()[0])
    ap.add_argument("description", nargs="?", default=str(DEMO), help="TOML description (default: the demo)")
    ap.add_argument("-o", "--output", help="A2L file (default: vehest_can/xcp/<NAME>.a2l)")
    args = ap.parse_args(argv)
    print(write(load(args.description), args.output))
    return 0


if __name__ == "__main__":
    sys.exit(main())
