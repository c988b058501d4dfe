"""Generate the firmware's CAN codec from the DBC files (run at every build).

For each ``dbc/vehest_<bus>.dbc`` this writes into the output folder:

* ``vh_<bus>.h`` / ``vh_<bus>.c``: pack/unpack code from ``cantools generate_c_source``
  (never edited by hand, never committed: regenerated on every build, so never stale);
* ``vh_<bus>_meta.h``: per message the E2E data ID, the cycle time in microseconds and the
  RX timeout in cycles, read from the DBC's attributes (one source of truth for the frames);
* ``vh_<bus>_enc.h``: per scaled signal a rounding encoder ``..._encode_round(double)``: raw =
  round half up(value / scale), clamped to the DBC's [minimum, maximum], NaN -> the SNA value
  (0 without one). cantools' own ``_encode`` truncates toward zero, does not clamp and is
  undefined for NaN, so the firmware transmits through these; either way the scale is the DBC's;
* ``vh_<bus>_q.h``: for the fixed-point path, ``..._decode_q(raw, frac, sat)`` /
  ``..._encode_q(v, frac)``: raw to Q.frac and back with the scale as the exact fraction num/den
  (integer only, vh_fix.h), and ``..._encode_qs(v, frac, s_num, s_den)`` for a value carried
  scaled by an exact fraction s_num/s_den (a filter's scaling S), so the scale factor between the
  Q format and the DBC raw unit is always the DBC's fraction times the filter's;
* ``vh_<bus>.cdef``: cffi declarations of the generated structs and functions, so Python
  tests can call the generated C directly;
* ``vh_secoc_table.h`` (one for all buses): the SecOC-secured messages (attribute ``SecOCDataID``;
  ``SecOCSync`` marks a node's sync frame) with their data ID, authentic length (the DBC length less
  the 4-byte tail) and sending node, and the sending nodes' indices (``VH_SECOC_NODE_*``, the
  senders of every DBC in name order; c_core/secoc/vh_secoc_bus.h).

A cycle time that is not a whole number of ECU ticks cannot build: the meta header asserts it
against ``VH_TICK_US`` at compile time. A frame the DBC marks cyclic without a cycle time does not
generate (vehest_can/bus/cyclic.py, loaded alone: the build does not import the package).
"""
from __future__ import annotations

import importlib.util
import re
import sys
from fractions import Fraction
from pathlib import Path

import cantools
from cantools.database.can.c_source import camel_to_snake_case, generate

ROOT = Path(__file__).resolve().parent.parent
DBC_DIR = ROOT / "dbc"
# which frames must have a cycle time: the rule `vehest-can busload` applies, from its file alone
_spec = importlib.util.spec_from_file_location("vh_cyclic", ROOT / "vehest_can" / "bus" / "cyclic.py")
cyclic = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(cyclic)


def db_name(dbc_path: Path) -> str:
    """``vehest_pt.dbc`` -> ``vh_pt``."""
    return "vh_" + dbc_path.stem.removeprefix("vehest_")


def cycle_time_us(message) -> int:
    """Cycle time in µs: ``CycleTimeUs`` where given (sub-ms frames), else ``GenMsgCycleTime`` ms."""
    attrs = message.dbc.attributes if message.dbc else {}
    if "CycleTimeUs" in attrs and attrs["CycleTimeUs"].value:
        return int(attrs["CycleTimeUs"].value)
    return int(message.cycle_time or 0) * 1000


def _attr(message, name, default):
    attrs = message.dbc.attributes if message.dbc else {}
    return attrs[name].value if name in attrs else default


def meta_header(db, name: str) -> str:
    up = name.upper()
    lines = [
        f"/* {name}_meta.h - generated from the DBC by c_core/dbcgen.py: do not edit. */",
        f"#ifndef {up}_META_H",
        f"#define {up}_META_H",
        "",
        '#include "vh_types.h" /* VH_TICK_US */',
        "",
    ]
    for m in db.messages:
        if error := cyclic.zero_cycle_error(m, cycle_time_us(m)):
            raise ValueError(f"{name}: {error}")
        pre = f"{up}_{camel_to_snake_case(m.name).upper()}"
        lines.append(f"#define {pre}_CYCLE_TIME_US ({cycle_time_us(m)}u)")
        lines.append(f"#define {pre}_E2E_DATA_ID ({int(_attr(m, 'E2EDataID', 0))}u)")
        lines.append(f"#define {pre}_RX_TIMEOUT_CYCLES ({int(_attr(m, 'RxTimeoutCycles', 0))}u)")
        lines.append(f"#define {pre}_IS_FD ({1 if m.is_fd else 0}u)")
        lines.append(f"#define {pre}_SECOC_DATA_ID ({int(_attr(m, 'SecOCDataID', 0))}u)")
        # a cycle the tick cannot hit would run early or late every period: refuse to build
        lines.append(f"typedef char {pre.lower()}_cycle_is_whole_ticks[({pre}_CYCLE_TIME_US % VH_TICK_US) == 0u ? 1 : -1];")
    ids = sorted(m.frame_id for m in db.messages if not m.is_extended_frame)
    lines += ["", "/* a standard frame ID this bus's DBC knows */",
              f"#define {up}_KNOWN_ID(id) (" + " || ".join(f"(id) == 0x{i:X}u" for i in ids) + ")"]
    lines += ["", f"#endif /* {up}_META_H */", ""]
    return "\n".join(lines)


def _raw_bounds(sig) -> tuple[int, int, int | None]:
    """The raw range the encoder clamps to (the DBC's minimum/maximum in raw units, else the
    signal's bit range without its SNA value) and the SNA raw value, if the DBC names one."""
    lo, hi = (-(1 << (sig.length - 1)), (1 << (sig.length - 1)) - 1) if sig.is_signed else (0, (1 << sig.length) - 1)
    sna = next((int(k) for k, v in (sig.choices or {}).items() if str(v) == "SNA"), None)
    if sna == lo:
        lo += 1
    if sna == hi:
        hi -= 1
    if sig.minimum is not None:
        lo = max(lo, round((sig.minimum - sig.offset) / sig.scale))
    if sig.maximum is not None:
        hi = min(hi, round((sig.maximum - sig.offset) / sig.scale))
    return lo, hi, sna


def _ctype(sig) -> str:
    bits = next(b for b in (8, 16, 32, 64) if sig.length <= b)
    return f"{'' if sig.is_signed else 'u'}int{bits}_t"


def _scaled(db, name: str):
    """(C name prefix of the signal, signal, raw lo, raw hi, SNA, C type) of every scaled signal."""
    for m in db.messages:
        for s in m.signals:
            if not s.is_float and (s.scale != 1 or s.offset != 0):
                lo, hi, sna = _raw_bounds(s)
                yield f"{name}_{camel_to_snake_case(m.name)}_{camel_to_snake_case(s.name)}", s, lo, hi, sna, _ctype(s)


def _header(name: str, suffix: str, doc: str, includes: list[str], body: list[str]) -> str:
    guard = f"{name.upper()}_{suffix.upper()}_H"
    return "\n".join([f"/* {name}_{suffix}.h - generated from the DBC by c_core/dbcgen.py: do not edit.", f" * {doc} */",
                      f"#ifndef {guard}", f"#define {guard}", "", *includes, "", *body,
                      f"#endif /* {guard} */", ""])


def encoders_header(db, name: str) -> str:
    """Rounding, clamping, NaN-safe encoders for every scaled signal (see the module docstring)."""
    body = []
    for base, s, lo, hi, sna, ct in _scaled(db, name):
        val = "value" if s.offset == 0 else f"(value - {float(s.offset)!r})"
        body += [
            f"static inline {ct} {base}_encode_round(double value)",
            "{",
            "    double r;",
            "    if (value != value) {",
            f"        return ({ct})({sna if sna is not None else 0});",
            "    }",
            f"    r = floor({val} / {float(s.scale)!r} + 0.5);",
            f"    return r > {float(hi)!r} ? ({ct})({hi}) : (r < {float(lo)!r} ? ({ct})({lo}) : ({ct})r);",
            "}",
            "",
        ]
    return _header(name, "enc", "raw = floor(value / scale + 0.5) clamped to the DBC range; NaN -> SNA (0 without one).",
                   ["#include <math.h>", "#include <stdint.h>"], body)


def fixed_header(db, name: str) -> str:
    """Integer-only raw <-> Q.frac conversions for every scaled signal (see the module docstring)."""
    body = []
    for base, s, lo, hi, _, ct in _scaled(db, name):
        q = Fraction(repr(float(s.scale)))
        if s.offset != 0 or s.length > 16 or q.numerator > 1 << 15 or q.denominator > 1 << 30:
            continue
        body += [
            f"/* raw * {float(s.scale)!r} in Q.frac (round half up, saturating): exact, integer only */",
            f"static inline int32_t {base}_decode_q({ct} raw, int frac, uint32_t *sat)",
            "{",
            f"    return vh_fix_from_raw((int32_t)raw, {q.numerator}, {q.denominator}, frac, sat);",
            "}",
            "",
            "/* a Q.frac value in raw units (round half up), clamped to the DBC range: integer only */",
            f"static inline {ct} {base}_encode_q(int32_t v, int frac)",
            "{",
            f"    const int64_t r = vh_fix_to_raw(v, frac, {q.numerator}, {q.denominator});",
            f"    return r > {hi} ? ({ct})({hi}) : (r < {lo} ? ({ct})({lo}) : ({ct})r);",
            "}",
            "",
        ]
        body += [
            "/* a value v 2^-frac = s x in the signal's units times s = s_num / s_den, in raw units of x",
            " * (round half up), clamped to the DBC range: integer only. The fraction (s_num / s_den) /",
            f" * scale must have numerator <= 2^31 - 1 and denominator <= 2^30 ({base}_qs_ok), else 0. */",
            f"static inline int {base}_qs_ok(int32_t s_num, int32_t s_den)",
            "{",
            f"    return s_num > 0 && s_den > 0 && (int64_t)s_num * {q.numerator} <= INT32_MAX &&",
            f"           (int64_t)s_den * {q.denominator} <= ((int64_t)1 << 30);",
            "}",
            "",
            f"static inline {ct} {base}_encode_qs(int32_t v, int frac, int32_t s_num, int32_t s_den)",
            "{",
            f"    const int64_t r = {base}_qs_ok(s_num, s_den) ?",
            f"        vh_fix_to_raw(v, frac, s_num * {q.numerator}, s_den * {q.denominator}) : 0;",
            f"    return r > {hi} ? ({ct})({hi}) : (r < {lo} ? ({ct})({lo}) : ({ct})r);",
            "}",
            "",
        ]
    return _header(name, "q", "Raw signals to and from fixed point with the DBC scale as an exact fraction: integer only.",
                   ["#include <stdint.h>", "", '#include "vh_fix.h" /* vh_fix_from_raw, vh_fix_to_raw */'], body)


_STRUCT_RE = re.compile(r"^struct (\w+) \{(.*?)^\};", re.S | re.M)
_FIELD_RE = re.compile(r"^\s+((?:u?int(?:8|16|32|64)_t)) (\w+);", re.M)
_FUNC_RE = re.compile(r"^(int|bool|double|u?int(?:8|16|32|64)_t) (\w+)\(\s*([^;]*?)\);", re.M | re.S)


def cdef_from_header(header: str) -> str:
    """cffi declarations for the generated structs and pack/unpack/init functions."""
    out = []
    for sname, body in _STRUCT_RE.findall(header):
        fields = _FIELD_RE.findall(body)
        out.append(f"struct {sname} {{")
        out += [f"    {t} {f};" for t, f in fields]
        out.append("};")
    for ret, fname, args in _FUNC_RE.findall(header):
        if fname.endswith(("_pack", "_unpack", "_init")):
            out.append(f"{ret} {fname}({' '.join(args.split())});")
    return "\n".join(out) + "\n"


SECOC_TAIL_BYTES = 4  # VH_SECOC_TAIL_BYTES


def secoc_table_header(dbs: list) -> str:
    """The secured messages of every DBC and the sending nodes' indices (see the module docstring)."""
    nodes = sorted({n for db in dbs for m in db.messages for n in m.senders})
    lines = ["/* vh_secoc_table.h - generated from the DBCs by c_core/dbcgen.py: do not edit. */",
             "#ifndef VH_SECOC_TABLE_H", "#define VH_SECOC_TABLE_H", "",
             '#include "vh_secoc_bus.h"', ""]
    lines += [f"#define VH_SECOC_NODE_{n.upper()} {i}u" for i, n in enumerate(nodes)]
    lines += [f"#define VH_SECOC_N_NODES {len(nodes)}", "",
              "static const char *const VH_SECOC_NODE_NAMES[VH_SECOC_N_NODES] = {"
              + ", ".join(f'"{n}"' for n in nodes) + "};", "",
              "static const vh_secoc_msg_t VH_SECOC_MSGS[] = {"]
    for db in dbs:
        for m in db.messages:
            data_id = int(_attr(m, "SecOCDataID", 0))
            if not data_id:
                continue
            if len(m.senders) != 1 or m.length <= SECOC_TAIL_BYTES:
                raise ValueError(f"{m.name}: a SecOC message needs one sender and room for the tail")
            sync = int(_attr(m, "SecOCSync", 0))
            lines.append(f"    {{0x{m.frame_id:X}u, {data_id}u, {m.length - SECOC_TAIL_BYTES}u, "
                         f"VH_SECOC_NODE_{m.senders[0].upper()}, {sync}u}}, /* {m.name} */")
    lines += ["};", "", "#endif /* VH_SECOC_TABLE_H */", ""]
    return "\n".join(lines)


def generate_all(out_dir: Path, dbc_dir: Path = DBC_DIR) -> list[str]:
    """Regenerate everything for every DBC; returns the bus database names."""
    out_dir.mkdir(parents=True, exist_ok=True)
    names, dbs = [], []
    for dbc_path in sorted(dbc_dir.glob("vehest_*.dbc")):
        name = db_name(dbc_path)
        db = cantools.database.load_file(str(dbc_path), strict=True)
        header, source, _, _ = generate(db, name, f"{name}.h", f"{name}.c", f"{name}_fuzzer.c")
        _write(out_dir / f"{name}.h", header)
        _write(out_dir / f"{name}.c", source)
        _write(out_dir / f"{name}_meta.h", meta_header(db, name))
        _write(out_dir / f"{name}_enc.h", encoders_header(db, name))
        _write(out_dir / f"{name}_q.h", fixed_header(db, name))
        _write(out_dir / f"{name}.cdef", cdef_from_header(header))
        names.append(name)
        dbs.append(db)
    _write(out_dir / "vh_secoc_table.h", secoc_table_header(dbs))
    return names


def _write(path: Path, text: str) -> None:
    """Write only on change, so make and setuptools do not rebuild for nothing.

    cantools stamps the generation time into its banner; it is dropped for reproducible builds.
    """
    text = re.sub(r"(generated by cantools version \S+) [^\n]*?\.\n", r"\1.\n", text)
    if not path.exists() or path.read_text() != text:
        path.write_text(text)


if __name__ == "__main__":
    print(" ".join(generate_all(Path(sys.argv[1]) if len(sys.argv) > 1 else ROOT / "build" / "generated")))
