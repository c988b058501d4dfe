"""Generate the firmware's CAN codec from the DBC files (run at every build).

For each ``dbc/vehest_<bus>.dbc`` this writes into the output folder:

* ``vh_<bus>.h`` / ``vh_<bus>.c``: pack/unpack code from ``cantools generate_c_source``
  (never edited by hand, never committed: regenerated on every build, so never stale);
* ``vh_<bus>_meta.h``: per message the E2E data ID, the cycle time in microseconds and the
  RX timeout in cycles, read from the DBC's attributes (one source of truth for the frames);
* ``vh_<bus>.cdef``: cffi declarations of the generated structs and functions, so Python
  tests can call the generated C directly.
"""
from __future__ import annotations

import re
import sys
from pathlib import Path

import cantools
from cantools.database.can.c_source import camel_to_snake_case, generate

ROOT = Path(__file__).resolve().parent.parent
DBC_DIR = ROOT / "dbc"


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
    ]
    for m in db.messages:
        pre = f"{up}_{camel_to_snake_case(m.name).upper()}"
        lines.append(f"#define {pre}_CYCLE_TIME_US ({cycle_time_us(m)}u)")
        lines.append(f"#define {pre}_E2E_DATA_ID ({int(_attr(m, 'E2EDataID', 0))}u)")
        lines.append(f"#define {pre}_RX_TIMEOUT_CYCLES ({int(_attr(m, 'RxTimeoutCycles', 0))}u)")
        lines.append(f"#define {pre}_IS_FD ({1 if m.is_fd else 0}u)")
    lines += ["", f"#endif /* {up}_META_H */", ""]
    return "\n".join(lines)


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


def generate_all(out_dir: Path, dbc_dir: Path = DBC_DIR) -> list[str]:
    """Regenerate everything for every DBC; returns the bus database names."""
    out_dir.mkdir(parents=True, exist_ok=True)
    names = []
    for dbc_path in sorted(dbc_dir.glob("vehest_*.dbc")):
        name = db_name(dbc_path)
        db = cantools.database.load_file(str(dbc_path), strict=True)
        header, source, _, _ = generate(db, name, f"{name}.h", f"{name}.c", f"{name}_fuzzer.c")
        _write(out_dir / f"{name}.h", header)
        _write(out_dir / f"{name}.c", source)
        _write(out_dir / f"{name}_meta.h", meta_header(db, name))
        _write(out_dir / f"{name}.cdef", cdef_from_header(header))
        names.append(name)
    return names


def _write(path: Path, text: str) -> None:
    """Write only on change, so make and setuptools do not rebuild for nothing."""
    if not path.exists() or path.read_text() != text:
        path.write_text(text)


if __name__ == "__main__":
    print(" ".join(generate_all(Path(sys.argv[1]) if len(sys.argv) > 1 else ROOT / "build" / "generated")))
