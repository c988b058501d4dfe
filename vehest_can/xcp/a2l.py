"""A2L (ASAM MCD-2 MC, ASAP2 1.7.1) from a description: the same table that configures the slave.

Generated, never edited: ``vehest-can xcp a2l --description DESCRIPTION.toml -o FILE.a2l``; :func:`write`
with no path writes the shipped file ``vehest_can/xcp/<NAME>.a2l``. The output is deterministic (no dates, sorted
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

from pathlib import Path

from .description import C_TYPES, Description, Item

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


# The ASAM MCD-1 XCP A2ML (the XCP_common part and XCP_on_CAN with its CAN_FD block, as the tools
# ship it), so CANape/INCA-style tools read the IF_DATA XCP blocks by the standard's own grammar.
# Transcribed from the XCP A2ML that a2ltool checks IF_DATA against (github.com/DanielT/a2ltool,
# src/ifdata.rs, its "A2mlVector" specification: Vector's XCP AML), keywords, value order and
# enum values unchanged; only the other transport layers (SxI, TCP/UDP, USB, FlexRay) and the
# tool-specific CANAPE_* blocks are left out.
A2ML = """\
/begin A2ML
  struct Protocol_Layer {
    uint;  /* XCP protocol layer version, current 0x100 */
    uint;  /* T1 [ms] */
    uint;  /* T2 [ms] */
    uint;  /* T3 [ms] */
    uint;  /* T4 [ms] */
    uint;  /* T5 [ms] */
    uint;  /* T6 [ms] */
    uint;  /* T7 [ms] */
    uchar;  /* MAX_CTO */
    uint;  /* MAX_DTO */
    enum {
      "BYTE_ORDER_MSB_LAST" = 0,
      "BYTE_ORDER_MSB_FIRST" = 1
    };
    enum {
      "ADDRESS_GRANULARITY_BYTE" = 1,
      "ADDRESS_GRANULARITY_WORD" = 2,
      "ADDRESS_GRANULARITY_DWORD" = 4
    };
    taggedstruct {
      ("OPTIONAL_CMD" enum {
        "GET_COMM_MODE_INFO" = 251,
        "GET_ID" = 250,
        "SET_REQUEST" = 249,
        "GET_SEED" = 248,
        "UNLOCK" = 247,
        "SET_MTA" = 246,
        "UPLOAD" = 245,
        "SHORT_UPLOAD" = 244,
        "BUILD_CHECKSUM" = 243,
        "TRANSPORT_LAYER_CMD" = 242,
        "USER_CMD" = 241,
        "DOWNLOAD" = 240,
        "DOWNLOAD_NEXT" = 239,
        "DOWNLOAD_MAX" = 238,
        "SHORT_DOWNLOAD" = 237,
        "MODIFY_BITS" = 236,
        "SET_CAL_PAGE" = 235,
        "GET_CAL_PAGE" = 234,
        "GET_PAG_PROCESSOR_INFO" = 233,
        "GET_SEGMENT_INFO" = 232,
        "GET_PAGE_INFO" = 231,
        "SET_SEGMENT_MODE" = 230,
        "GET_SEGMENT_MODE" = 229,
        "COPY_CAL_PAGE" = 228,
        "CLEAR_DAQ_LIST" = 227,
        "SET_DAQ_PTR" = 226,
        "WRITE_DAQ" = 225,
        "SET_DAQ_LIST_MODE" = 224,
        "GET_DAQ_LIST_MODE" = 223,
        "START_STOP_DAQ_LIST" = 222,
        "START_STOP_SYNCH" = 221,
        "GET_DAQ_CLOCK" = 220,
        "READ_DAQ" = 219,
        "GET_DAQ_PROCESSOR_INFO" = 218,
        "GET_DAQ_RESOLUTION_INFO" = 217,
        "GET_DAQ_LIST_INFO" = 216,
        "GET_DAQ_EVENT_INFO" = 215,
        "FREE_DAQ" = 214,
        "ALLOC_DAQ" = 213,
        "ALLOC_ODT" = 212,
        "ALLOC_ODT_ENTRY" = 211,
        "PROGRAM_START" = 210,
        "PROGRAM_CLEAR" = 209,
        "PROGRAM" = 208,
        "PROGRAM_RESET" = 207,
        "GET_PGM_PROCESSOR_INFO" = 206,
        "GET_SECTOR_INFO" = 205,
        "PROGRAM_PREPARE" = 204,
        "PROGRAM_FORMAT" = 203,
        "PROGRAM_NEXT" = 202,
        "PROGRAM_MAX" = 201,
        "PROGRAM_VERIFY" = 200,
        "WRITE_DAQ_MULTIPLE" = 199
      })*;
      "COMMUNICATION_MODE_SUPPORTED" taggedunion {
        "BLOCK" taggedstruct {
          "SLAVE";
          "MASTER" struct {
            uchar;  /* MAX_BS */
            uchar;  /* MIN_ST */
          };
        };
        "INTERLEAVED" uchar;  /* QUEUE_SIZE */
      };
      "SEED_AND_KEY_EXTERNAL_FUNCTION" char[256];  /* name of the seed & key function */
      "MAX_DTO_STIM" uint;  /* overrules MAX_DTO for STIM */
    };
  };
  struct Daq {
    enum {
      "STATIC" = 0,
      "DYNAMIC" = 1
    };
    uint;  /* MAX_DAQ */
    uint;  /* MAX_EVENT_CHANNEL */
    uchar;  /* MIN_DAQ */
    enum {
      "OPTIMISATION_TYPE_DEFAULT" = 0,
      "OPTIMISATION_TYPE_ODT_TYPE_16" = 1,
      "OPTIMISATION_TYPE_ODT_TYPE_32" = 2,
      "OPTIMISATION_TYPE_ODT_TYPE_64" = 3,
      "OPTIMISATION_TYPE_ODT_TYPE_ALIGNMENT" = 4,
      "OPTIMISATION_TYPE_MAX_ENTRY_SIZE" = 5
    };
    enum {
      "ADDRESS_EXTENSION_FREE" = 0,
      "ADDRESS_EXTENSION_ODT" = 1,
      "ADDRESS_EXTENSION_DAQ" = 3
    };
    enum {
      "IDENTIFICATION_FIELD_TYPE_ABSOLUTE" = 0,
      "IDENTIFICATION_FIELD_TYPE_RELATIVE_BYTE" = 1,
      "IDENTIFICATION_FIELD_TYPE_RELATIVE_WORD" = 2,
      "IDENTIFICATION_FIELD_TYPE_RELATIVE_WORD_ALIGNED" = 3
    };
    enum {
      "GRANULARITY_ODT_ENTRY_SIZE_DAQ_BYTE" = 1,
      "GRANULARITY_ODT_ENTRY_SIZE_DAQ_WORD" = 2,
      "GRANULARITY_ODT_ENTRY_SIZE_DAQ_DWORD" = 4,
      "GRANULARITY_ODT_ENTRY_SIZE_DAQ_DLONG" = 8
    };
    uchar;  /* MAX_ODT_ENTRY_SIZE_DAQ */
    enum {
      "NO_OVERLOAD_INDICATION" = 0,
      "OVERLOAD_INDICATION_PID" = 1,
      "OVERLOAD_INDICATION_EVENT" = 2
    };
    taggedstruct {
      "DAQ_ALTERNATING_SUPPORTED" uint;
      "PRESCALER_SUPPORTED";
      "RESUME_SUPPORTED";
      "STORE_DAQ_SUPPORTED";
      block "STIM" struct {
        enum {
          "GRANULARITY_ODT_ENTRY_SIZE_STIM_BYTE" = 1,
          "GRANULARITY_ODT_ENTRY_SIZE_STIM_WORD" = 2,
          "GRANULARITY_ODT_ENTRY_SIZE_STIM_DWORD" = 4,
          "GRANULARITY_ODT_ENTRY_SIZE_STIM_DLONG" = 8
        };
        uchar;  /* MAX_ODT_ENTRY_SIZE_STIM */
        taggedstruct {
          "BIT_STIM_SUPPORTED";
          "MIN_ST_STIM" uchar;
        };
      };
      block "TIMESTAMP_SUPPORTED" struct {
        uint;  /* TIMESTAMP_TICKS */
        enum {
          "NO_TIME_STAMP" = 0,
          "SIZE_BYTE" = 1,
          "SIZE_WORD" = 2,
          "SIZE_DWORD" = 4
        };
        enum {
          "UNIT_1NS" = 0,
          "UNIT_10NS" = 1,
          "UNIT_100NS" = 2,
          "UNIT_1US" = 3,
          "UNIT_10US" = 4,
          "UNIT_100US" = 5,
          "UNIT_1MS" = 6,
          "UNIT_10MS" = 7,
          "UNIT_100MS" = 8,
          "UNIT_1S" = 9,
          "UNIT_1PS" = 10,
          "UNIT_10PS" = 11,
          "UNIT_100PS" = 12
        };
        taggedstruct {
          "TIMESTAMP_FIXED";
        };
      };
      "PID_OFF_SUPPORTED";
      "MAX_DAQ_TOTAL" uint;
      "MAX_ODT_TOTAL" uint;
      "MAX_ODT_DAQ_TOTAL" uint;
      "MAX_ODT_STIM_TOTAL" uint;
      "MAX_ODT_ENTRIES_TOTAL" uint;
      "MAX_ODT_ENTRIES_DAQ_TOTAL" uint;
      "MAX_ODT_ENTRIES_STIM_TOTAL" uint;
      "CPU_LOAD_MAX_TOTAL" float;
      block "DAQ_MEMORY_CONSUMPTION" struct {
        ulong;  /* DAQ_MEMORY_LIMIT */
        uint;  /* DAQ_SIZE */
        uint;  /* ODT_SIZE */
        uint;  /* ODT_ENTRY_SIZE */
        uint;  /* ODT_DAQ_BUFFER_FACTOR */
        uint;  /* ODT_STIM_BUFFER_FACTOR */
      };
      (block "DAQ_LIST" struct {
        uint;  /* DAQ_LIST_NUMBER */
        taggedstruct {
          "DAQ_LIST_TYPE" enum {
            "DAQ" = 1,
            "STIM" = 2,
            "DAQ_STIM" = 3
          };
          "MAX_ODT" uchar;
          "MAX_ODT_ENTRIES" uchar;
          "FIRST_PID" uchar;
          "EVENT_FIXED" uint;
          block "PREDEFINED" taggedstruct {
            (block "ODT" struct {
              uchar;  /* ODT number */
              taggedstruct {
                ("ODT_ENTRY" struct {
                  uchar;  /* ODT_ENTRY number */
                  ulong;  /* address of element */
                  uchar;  /* address extension of element */
                  uchar;  /* size of element [AG] */
                  uchar;  /* BIT_OFFSET */
                })*;
              };
            })*;
          };
        };
      })*;
      (block "EVENT" struct {
        char[101];  /* EVENT_CHANNEL_NAME */
        char[9];  /* EVENT_CHANNEL_SHORT_NAME */
        uint;  /* EVENT_CHANNEL_NUMBER */
        enum {
          "DAQ" = 1,
          "STIM" = 2,
          "DAQ_STIM" = 3
        };
        uchar;  /* MAX_DAQ_LIST */
        uchar;  /* TIME_CYCLE */
        uchar;  /* TIME_UNIT */
        uchar;  /* PRIORITY */
        taggedstruct {
          "COMPLEMENTARY_BYPASS_EVENT_CHANNEL_NUMBER" uint;
          "CONSISTENCY" enum {
            "DAQ" = 0,
            "EVENT" = 1
          };
          block "MIN_CYCLE_TIME" struct {
            uchar;  /* EVENT_CHANNEL_TIME_CYCLE */
            uchar;  /* EVENT_CHANNEL_TIME_UNIT */
          };
          "CPU_LOAD_MAX" float;
          block "CPU_LOAD_CONSUMPTION_DAQ" struct {
            float;  /* DAQ_FACTOR */
            float;  /* ODT_FACTOR */
            float;  /* ODT_ENTRY_FACTOR */
            taggedstruct {
              (block "ODT_ENTRY_SIZE_FACTOR_TABLE" struct {
                uint;  /* SIZE */
                float;  /* SIZE_FACTOR */
              })*;
            };
          };
          block "CPU_LOAD_CONSUMPTION_STIM" struct {
            float;  /* DAQ_FACTOR */
            float;  /* ODT_FACTOR */
            float;  /* ODT_ENTRY_FACTOR */
            taggedstruct {
              (block "ODT_ENTRY_SIZE_FACTOR_TABLE" struct {
                uint;  /* SIZE */
                float;  /* SIZE_FACTOR */
              })*;
            };
          };
          block "CPU_LOAD_CONSUMPTION_QUEUE" struct {
            float;  /* ODT_FACTOR */
            float;  /* ODT_LENGTH_FACTOR */
          };
        };
      })*;
    };
  };
  taggedunion Daq_Event {
    "FIXED_EVENT_LIST" taggedstruct {
      ("EVENT" uint)*;
    };
    "VARIABLE" taggedstruct {
      block "AVAILABLE_EVENT_LIST" taggedstruct {
        ("EVENT" uint)*;
      };
      block "DEFAULT_EVENT_LIST" taggedstruct {
        ("EVENT" uint)*;
      };
    };
  };
  struct Pag {
    uchar;  /* MAX_SEGMENTS */
    taggedstruct {
      "FREEZE_SUPPORTED";
    };
  };
  struct Pgm {
    enum {
      "PGM_MODE_ABSOLUTE" = 1,
      "PGM_MODE_FUNCTIONAL" = 2,
      "PGM_MODE_ABSOLUTE_AND_FUNCTIONAL" = 3
    };
    uchar;  /* MAX_SECTORS */
    uchar;  /* MAX_CTO_PGM */
    taggedstruct {
      (block "SECTOR" struct {
        char[101];  /* SECTOR_NAME */
        uchar;  /* SECTOR_NUMBER */
        ulong;  /* address */
        ulong;  /* length */
        uchar;  /* CLEAR_SEQUENCE_NUMBER */
        uchar;  /* PROGRAM_SEQUENCE_NUMBER */
        uchar;  /* PROGRAM_METHOD */
      })*;
      "COMMUNICATION_MODE_SUPPORTED" taggedunion {
        "BLOCK" taggedstruct {
          "SLAVE";
          "MASTER" struct {
            uchar;  /* MAX_BS_PGM */
            uchar;  /* MIN_ST_PGM */
          };
        };
        "INTERLEAVED" uchar;  /* QUEUE_SIZE_PGM */
      };
    };
  };
  struct Segment {
    uchar;  /* SEGMENT_NUMBER */
    uchar;  /* number of pages */
    uchar;  /* ADDRESS_EXTENSION */
    uchar;  /* COMPRESSION_METHOD */
    uchar;  /* ENCRYPTION_METHOD */
    taggedstruct {
      block "CHECKSUM" struct {
        enum {
          "XCP_ADD_11" = 1,
          "XCP_ADD_12" = 2,
          "XCP_ADD_14" = 3,
          "XCP_ADD_22" = 4,
          "XCP_ADD_24" = 5,
          "XCP_ADD_44" = 6,
          "XCP_CRC_16" = 7,
          "XCP_CRC_16_CITT" = 8,
          "XCP_CRC_32" = 9,
          "XCP_USER_DEFINED" = 255
        };
        taggedstruct {
          "MAX_BLOCK_SIZE" ulong;
          "EXTERNAL_FUNCTION" char[256];  /* name of the checksum library */
        };
      };
      (block "PAGE" struct {
        uchar;  /* PAGE_NUMBER */
        enum {
          "ECU_ACCESS_NOT_ALLOWED" = 0,
          "ECU_ACCESS_WITHOUT_XCP_ONLY" = 1,
          "ECU_ACCESS_WITH_XCP_ONLY" = 2,
          "ECU_ACCESS_DONT_CARE" = 3
        };
        enum {
          "XCP_READ_ACCESS_NOT_ALLOWED" = 0,
          "XCP_READ_ACCESS_WITHOUT_ECU_ONLY" = 1,
          "XCP_READ_ACCESS_WITH_ECU_ONLY" = 2,
          "XCP_READ_ACCESS_DONT_CARE" = 3
        };
        enum {
          "XCP_WRITE_ACCESS_NOT_ALLOWED" = 0,
          "XCP_WRITE_ACCESS_WITHOUT_ECU_ONLY" = 1,
          "XCP_WRITE_ACCESS_WITH_ECU_ONLY" = 2,
          "XCP_WRITE_ACCESS_DONT_CARE" = 3
        };
        taggedstruct {
          "INIT_SEGMENT" uchar;  /* the segment that initialises this page */
        };
      })*;
      (block "ADDRESS_MAPPING" struct {
        ulong;  /* source address */
        ulong;  /* destination address */
        ulong;  /* length */
      })*;
      "PGM_VERIFY" ulong;  /* verification value for PGM */
    };
  };
  taggedstruct Common_Parameters {
    block "PROTOCOL_LAYER" struct Protocol_Layer;
    block "SEGMENT" struct Segment;
    block "DAQ" struct Daq;
    block "PAG" struct Pag;
    block "PGM" struct Pgm;
    block "DAQ_EVENT" taggedunion Daq_Event;
  };
  struct CAN_Parameters {
    uint;  /* XCP on CAN version, currently 0x0100 */
    taggedstruct {
      "CAN_ID_BROADCAST" ulong;  /* auto-detection CAN-ID */
      "CAN_ID_MASTER" ulong;  /* CMD/STIM CAN-ID */
      "CAN_ID_MASTER_INCREMENTAL";  /* master uses a range of CAN-IDs, starting at CAN_ID_MASTER */
      "CAN_ID_SLAVE" ulong;  /* RES/ERR/EV/SERV/DAQ CAN-ID */
      "BAUDRATE" ulong;  /* BAUDRATE [Hz] */
      "SAMPLE_POINT" uchar;  /* sample point [% of the bit time] */
      "SAMPLE_RATE" enum {
        "SINGLE" = 1,
        "TRIPLE" = 3
      };
      "BTL_CYCLES" uchar;  /* slots per bit time */
      "SJW" uchar;  /* length of the synchronisation segment [BTL_CYCLES] */
      "SYNC_EDGE" enum {
        "SINGLE" = 1,
        "DUAL" = 2
      };
      "MAX_DLC_REQUIRED";  /* master to slave frames always with DLC = MAX_DLC = 8 */
      (block "DAQ_LIST_CAN_ID" struct {
        uint;  /* reference to DAQ_LIST_NUMBER */
        taggedstruct {
          "VARIABLE";
          "FIXED" ulong;  /* this DAQ list always on this CAN-ID */
        };
      })*;
      (block "EVENT_CAN_ID_LIST" struct {
        uint;  /* reference to EVENT_NUMBER */
        taggedstruct {
          ("FIXED" ulong)*;  /* this event always on these CAN-IDs */
        };
      })*;
      "MAX_BUS_LOAD" ulong;  /* maximum available bus load [bit/s] */
      block "CAN_FD" struct {
        taggedstruct {
          "MAX_DLC" uint;  /* 8, 12, 16, 20, 24, 32, 48 or 64 */
          "CAN_FD_DATA_TRANSFER_BAUDRATE" ulong;  /* data phase BAUDRATE [Hz] */
          "SAMPLE_POINT" uchar;  /* receiver sample point [% of the bit time] */
          "BTL_CYCLES" uchar;  /* slots per bit time */
          "SJW" uchar;  /* length of the synchronisation segment [BTL_CYCLES] */
          "SYNC_EDGE" enum {
            "SINGLE" = 1,
            "DUAL" = 2
          };
          "MAX_DLC_REQUIRED";  /* master to slave frames always with DLC = MAX_DLC */
          "SECONDARY_SAMPLE_POINT" uchar;  /* sender sample point [% of the bit time] */
          "TRANSCEIVER_DELAY_COMPENSATION" enum {
            "OFF" = 0,
            "ON" = 1
          };
        };
      };
    };
  };
  block "IF_DATA" taggedunion if_data {
    "XCP" struct {
      taggedstruct Common_Parameters;  /* default parameters */
      taggedstruct {
        block "XCP_ON_CAN" struct {
          struct CAN_Parameters;  /* specific for CAN */
          taggedstruct Common_Parameters;  /* overruling of the defaults */
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
        # the longest frame either way; frames shorter than it are padded to the next CAN FD length
        # (no MAX_DLC_REQUIRED: the slave takes a CRO of any length)
        out += ["    /begin CAN_FD", f"      MAX_DLC {max(d.max_cto, d.max_dto)}"]
        if d.data_bitrate:
            out.append(f"      CAN_FD_DATA_TRANSFER_BAUDRATE {d.data_bitrate}")
        out.append("    /end CAN_FD")
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

