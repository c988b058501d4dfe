"""Generate the firmware's CAN codec from the DBC files (run at every build).

For each ``dbc/vehest_<bus>.dbc`` this writes into the output folder:

* ``vh_<bus>.h`` / ``vh_<bus>.c``: pack/unpack code from ``cantools generate_c_source``
  (never edited by hand, never committed: regenerated on every build, so never stale);
* ``vh_<bus>_meta.h``: per message the E2E data ID, the cycle time in microseconds and the
  RX timeout in cycles, read from the DBC's attributes (one source of truth for the frames);
  cantools' own ``*_CYCLE_TIME_MS`` defines are dropped from ``vh_<bus>.h`` (a 0.5 ms FLOAT has no
  C literal);
* ``vh_<bus>_e2e.h`` and a table appended to ``vh_<bus>.c``: per message its AUTOSAR E2E
  configuration (``vh_e2e_cfg_t``, c_core/common/vh_e2e.h) from the attributes ``E2EProfile``
  (P01, P02, P05 or empty), ``E2EDataID``, ``E2EDataIDMode`` (P01: BOTH, ALT, LOW, NIBBLE) and
  ``E2EDataIDList`` (P02: 16 data IDs, one per counter value), checked against the profile's
  layout (its CRC and counter signals); ``VH_<BUS>_<MSG>_E2E`` points at a message's entry and
  ``vh_<bus>_e2e_cfg(frame_id)`` looks one up (NULL: not protected);
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
    """Cycle time in µs: ``CycleTimeUs`` (exact) where given, else ``GenMsgCycleTime`` (ms, a FLOAT
    here: 0.5 for the 2 kHz frames). Where both are given they must agree, or the firmware would run a
    schedule that the DBC tools (cantools, canmatrix, the bus load) do not show."""
    if error := cyclic.cycle_mismatch_error(message):
        raise DbcError(error)
    attrs = message.dbc.attributes if message.dbc else {}
    if "CycleTimeUs" in attrs and attrs["CycleTimeUs"].value:
        return int(attrs["CycleTimeUs"].value)
    return round(float(message.cycle_time or 0) * 1000)


def _attr(message, name, default):
    """A message attribute's value (an ENUM's by its name: a DBC may give its index), else default."""
    attrs = message.dbc.attributes if message.dbc else {}
    if name not in attrs:
        return default
    attr = attrs[name]
    choices = getattr(attr.definition, "choices", None)
    if choices and isinstance(attr.value, int) and 0 <= attr.value < len(choices):
        return choices[attr.value]
    return attr.value


E2E_PROFILES = {"P01": 1, "P02": 2, "P05": 5}  # VH_E2E_P01 ...
E2E_ID_MODES = ("BOTH", "ALT", "LOW", "NIBBLE")  # VH_E2E_ID_BOTH ...
#: each profile's header, as (start bit, length) of its CRC and counter signals (little endian)
E2E_LAYOUT = {1: ((0, 8), (8, 4)), 2: ((0, 8), (8, 4)), 5: ((0, 16), (16, 8))}


class DbcError(ValueError):
    """A DBC the firmware cannot be built from; the message names the message and the attribute."""


def e2e_config(message) -> tuple[int, int, int, bytes] | None:
    """(profile, data ID mode, data ID, data ID list) of a message, None if it is not E2E-protected;
    DbcError when its attributes or its layout do not make a profile the firmware implements."""
    text = str(_attr(message, "E2EProfile", "") or "").strip().upper()
    if not text:
        return None
    where = f"{message.name} (0x{message.frame_id:X})"
    if text not in E2E_PROFILES:
        raise DbcError(f"{where}: E2EProfile {text!r} is not one of {', '.join(E2E_PROFILES)}")
    profile = E2E_PROFILES[text]
    data_id = int(_attr(message, "E2EDataID", 0))
    mode_text = str(_attr(message, "E2EDataIDMode", "BOTH") or "BOTH").upper()
    if mode_text not in E2E_ID_MODES:
        raise DbcError(f"{where}: E2EDataIDMode {mode_text!r} is not one of {', '.join(E2E_ID_MODES)}")
    mode = E2E_ID_MODES.index(mode_text)
    id_list = bytes(16)
    if profile == 2:
        words = str(_attr(message, "E2EDataIDList", "") or "").replace(",", " ").split()
        try:
            values = [int(w, 0) for w in words]
        except ValueError:
            values = []
        if len(values) != 16 or not all(0 <= v <= 255 for v in values):
            raise DbcError(f"{where}: P02 needs E2EDataIDList, 16 data IDs 0..255 (one per counter value), "
                           f"not {_attr(message, 'E2EDataIDList', '')!r}")
        id_list = bytes(values)
    elif not 0 <= data_id <= 0xFFFF or (mode == 3 and data_id > 0xFFF) or (mode == 2 and data_id > 0xFF):
        raise DbcError(f"{where}: E2EDataID {data_id} does not fit E2EDataIDMode {mode_text} "
                       "(BOTH/ALT 16 bits, NIBBLE 12, LOW 8)")
    have = {(s.start, s.length) for s in message.signals if s.byte_order == "little_endian" and not s.is_signed}
    crc, counter = E2E_LAYOUT[profile]
    if crc not in have or counter not in have:
        raise DbcError(f"{where}: {text} puts its CRC at bits {crc[0]}..{sum(crc) - 1} and its counter at bits "
                       f"{counter[0]}..{sum(counter) - 1} (unsigned, little endian signals): the DBC has no such signals")
    if message.length < sum(counter) // 8 + 1:
        raise DbcError(f"{where}: {message.length} bytes cannot carry {text}'s header and data")
    return profile, mode, data_id, id_list


def e2e_header(db, name: str) -> str:
    """The E2E configuration table's declarations and each message's pointer into it."""
    up = name.upper()
    protected = [m for m in db.messages if e2e_config(m) is not None]
    body = [f"extern const vh_e2e_cfg_t {name}_e2e_cfgs[{max(len(protected), 1)}];",
            "/* the configuration of a frame ID of this bus, NULL if it is not E2E-protected */",
            f"const vh_e2e_cfg_t *{name}_e2e_cfg(uint32_t frame_id);", ""]
    body += [f"#define {up}_{camel_to_snake_case(m.name).upper()}_E2E (&{name}_e2e_cfgs[{i}])"
             for i, m in enumerate(protected)]
    return _header(name, "e2e", "Each message's AUTOSAR E2E configuration (vh_e2e.h), from the DBC's attributes.",
                   ["#include <stdint.h>", "", '#include "vh_e2e.h"'], body + [""])


def e2e_source(db, name: str) -> str:
    """The table behind e2e_header, appended to the codec's source."""
    protected = [(m, e2e_config(m)) for m in db.messages]
    protected = [(m, c) for m, c in protected if c is not None]
    lines = ["", f"/* Appended by c_core/dbcgen.py: each message's E2E configuration ({name}_e2e.h). */",
             f'#include "{name}_e2e.h"', "", f"const vh_e2e_cfg_t {name}_e2e_cfgs[{max(len(protected), 1)}] = {{"]
    for m, (profile, mode, data_id, id_list) in protected:
        ids = ", ".join(f"{b}u" for b in id_list)
        lines.append(f"    {{{profile}u, {mode}u, {data_id}u, {{{ids}}}}}, /* {m.name} */")
    if not protected:
        lines.append("    {0u, 0u, 0u, {0u}}")
    lines += ["};", "", f"const vh_e2e_cfg_t *{name}_e2e_cfg(uint32_t frame_id)", "{", "    switch (frame_id) {"]
    for i, (m, _) in enumerate(protected):
        lines += [f"    case 0x{m.frame_id:X}u:", f"        return &{name}_e2e_cfgs[{i}];"]
    lines += ["    default:", "        return NULL;", "    }", "}", ""]
    return "\n".join(lines)


def meta_header(db, name: str) -> str:
    up = name.upper()
    lines = [
        f"/* {name}_meta.h - generated from the DBC by c_core/dbcgen.py: do not edit. */",
        f"#ifndef {up}_META_H",
        f"#define {up}_META_H",
        "",
        '#include "vh_types.h" /* VH_TICK_US */',
        f'#include "{name}_e2e.h" /* {up}_<MSG>_E2E */',
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


_CANTOOLS_CYCLE_MS = re.compile(r"^#define \w+_CYCLE_TIME_MS \([^)]*\)\n", re.M)
#: the simulator's lockstep frames (vehest_sim.dbc): the ECU core knows their IDs (VH_SIM_KNOWN_ID), the
#: daemon answers them; the firmware image never packs one, so it is built without this codec
SIM = "vh_sim"


def generate_all(out_dir: Path, dbc_dir: Path = DBC_DIR) -> list[str]:
    """Regenerate everything for every DBC; returns the bus database names."""
    out_dir.mkdir(parents=True, exist_ok=True)
    names, dbs = [], []
    for dbc_path in sorted(dbc_dir.glob("vehest_*.dbc")):
        name = db_name(dbc_path)
        db = cantools.database.load_file(str(dbc_path), strict=True)
        header, source, _, _ = generate(db, name, f"{name}.h", f"{name}.c", f"{name}_fuzzer.c")
        # cantools writes GenMsgCycleTime as "(<ms>u)": no C literal for a FLOAT (0.5u); the µs are in _meta.h
        header = _CANTOOLS_CYCLE_MS.sub("", header)
        _write(out_dir / f"{name}.h", header)
        _write(out_dir / f"{name}_e2e.h", e2e_header(db, name))
        _write(out_dir / f"{name}.c", source + e2e_source(db, name))
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
