"""cffi build script (out-of-line API mode) for ``vehest_can._native``.

One extension holds the ECU firmware (``c_core/<folder>/``: ``common``, one folder per system,
``ecu``), the simulated car and sensor nodes (``firmware_sim/src``) and the codec generated from
``dbc/`` at build time. Two include paths keep the boundary: the firmware and the codec compile
with the firmware folders only, so a firmware source that includes a simulator header does not
build; the simulator compiles with both. Sharing one extension lets the C lockstep harness pass
instances between plant and ECU without copies.

The cdef is generated from the public headers themselves (``header_cdef``): comments, include
guards and includes dropped, ``static inline`` bodies turned into prototypes, integer macros kept,
floating ones declared ``static const double``. Nothing is written twice.
"""
from __future__ import annotations

import re
import sys
from pathlib import Path

from cffi import FFI

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
sys.path.insert(0, str(HERE))
import dbcgen  # noqa: E402  (sits beside this file)
from cbuild import STRICT_FLAGS, libcrypto  # noqa: E402  (the strict flags; SecOC's AES on the host: OpenSSL)

GEN_DIR = ROOT / "build" / "generated"
# -O3: lets the compiler vectorise the 4x4 products of the filter step (~25% faster than -O2).
OPT_FLAGS = ["-O3"]
#: the systems of the firmware, one folder each (sources, headers, the system's ECU application)
SYSTEMS = ("driveline", "tireforce", "camber", "roll")
#: every folder of the firmware: what it shares, the systems, the XCP slave, SecOC, the scheduler
FIRMWARE_DIRS = [HERE / "common", *(HERE / s for s in SYSTEMS), HERE / "xcp", HERE / "secoc", HERE / "ecu"]
#: what a program built from the firmware's sources links: libm, and OpenSSL's libcrypto for SecOC's
#: AES on the host (vh_aes128_host.c; a target links its HSM driver instead)
LINK_FLAGS = ["-lm", libcrypto()]
SIM_SRC_DIR = ROOT / "firmware_sim" / "src"
SIM_INCLUDE_DIR = ROOT / "firmware_sim" / "include"
#: built into the extension but never flashed (host-side calibration helpers)
HOST_ONLY_GLOB = "*_host.c"


def firmware_include_dirs(gen_dir: Path = GEN_DIR) -> list[Path]:
    """The include path of a firmware build: the firmware folders and the generated codec."""
    return [*FIRMWARE_DIRS, gen_dir]


def sim_include_dirs(gen_dir: Path = GEN_DIR) -> list[Path]:
    """The include path of the simulator, and of the benches and test drivers that run it (the
    one declared way from ``c_core/bench`` and ``tests/c`` into ``firmware_sim``)."""
    return [*FIRMWARE_DIRS, SIM_INCLUDE_DIR, gen_dir]


#: the include path of c_core/bench (the simulated car drives the ECU benches)
bench_include_dirs = sim_include_dirs


def firmware_path(name: str) -> Path:
    """Where a firmware source or header lives, by file name (e.g. ``vh_skfq.c``)."""
    for d in FIRMWARE_DIRS:
        if (d / name).exists():
            return d / name
    raise FileNotFoundError(name)


def ecu_sources(gen_dir: Path = GEN_DIR, host: bool = True) -> list[Path]:
    """The firmware's C sources (host-only helpers unless host=False), without the codec."""
    srcs = [p for d in FIRMWARE_DIRS for p in sorted(d.glob("*.c"))]
    return srcs if host else [p for p in srcs if not p.match(HOST_ONLY_GLOB)]


def firmware_sources(gen_dir: Path = GEN_DIR) -> list[Path]:
    """Every C source of the extension, generated codec included (after generating it)."""
    names = dbcgen.generate_all(gen_dir)
    return ecu_sources(gen_dir) + sorted(SIM_SRC_DIR.glob("*.c")) + [gen_dir / f"{n}.c" for n in names]


# ---- cdef from the headers ----------------------------------------------------------------

_COMMENT = re.compile(r"/\*.*?\*/|//[^\n]*", re.S)
_INT_LITERAL = re.compile(r"^-?(0x[0-9a-fA-F]+|\d+)[uUlL]*$")
_FLOAT_LITERAL = re.compile(r"^-?(\d+\.\d*|\.\d+|\d+)([eE][-+]?\d+)?$")
_INCLUDE = re.compile(r'^#include\s+"([^"]+)"', re.M)


def _inline_prototypes(text: str) -> str:
    """``static inline T f(args) { ... }`` -> ``T f(args);`` (cffi wraps the inline function)."""
    out, i = [], 0
    for m in re.finditer(r"static inline ([^;{]*?\))\s*\{", text):
        if m.start() < i:
            continue
        depth, j = 1, m.end()
        while depth:
            depth += {"{": 1, "}": -1}.get(text[j], 0)
            j += 1
        out.append(text[i:m.start()] + m.group(1) + ";")
        i = j
    return "".join(out) + text[i:]


def header_cdef(text: str) -> str:
    """The cffi declarations of one public header, from the header itself."""
    # a macro continued over several lines is one line to the reader below (a function-like one is skipped)
    text = _inline_prototypes(_COMMENT.sub("", text).replace("\\\n", " "))
    lines = []
    for line in text.splitlines():
        s = line.strip()
        if s.startswith("#"):
            m = re.match(r"#define\s+(\w+)\s+(.+)$", s)
            if not m or m.group(1).endswith("_H"):
                continue  # include guards, includes, function-like macros
            name, value = m.group(1), m.group(2).strip()
            if _INT_LITERAL.match(value):
                lines.append(f"#define {name} {value}")
            elif _FLOAT_LITERAL.match(value):
                lines.append(f"static const double {name};")
            elif re.fullmatch(r"\(\s*-?\d+[uUlL]*\s*\)", value):
                lines.append(f"#define {name} ...")
            continue
        if re.match(r"typedef char \w+\[", s):
            continue  # compile-time checks
        if s:
            lines.append(line.rstrip())
    return "\n".join(lines) + "\n"


def public_headers(gen_dir: Path = GEN_DIR) -> list[Path]:
    """Every public header of the extension, each after the headers it includes."""
    by_name = {p.name: p for d in (*FIRMWARE_DIRS, SIM_INCLUDE_DIR) for p in sorted(d.glob("*.h"))}
    by_name.update({p.name: p for p in sorted(gen_dir.glob("vh_*_enc.h")) + sorted(gen_dir.glob("vh_*_q.h"))
                    + sorted(gen_dir.glob("vh_*_e2e.h"))})
    order: list[Path] = []

    def visit(name: str) -> None:
        p = by_name.get(name)
        if p is None or p in order:
            return
        for dep in _INCLUDE.findall(p.read_text()):
            visit(dep)
        if p not in order:
            order.append(p)

    for name in sorted(by_name):
        visit(name)
    return order


def _expanded_cdef(path: Path) -> str:
    """A header that includes a template (``*.inc``, e.g. vh_roll.h: one declaration per precision):
    its integer macros, then the header through the C preprocessor with ``<NAME>_CDEF`` set (the
    header leaves out its system includes then)."""
    import os
    import shlex
    import subprocess

    from setuptools._distutils.sysconfig import get_config_var

    cc = shlex.split(os.environ.get("CC") or get_config_var("CC") or "cc")
    out = subprocess.run(cc + ["-E", "-P", f"-D{path.stem.upper()}_CDEF", "-I", str(path.parent), "-x", "c", str(path)],
                         check=True, capture_output=True, text=True).stdout
    defines = [ln for ln in header_cdef(path.read_text()).splitlines() if ln.startswith(("#define", "static const"))]
    return "\n".join(defines) + "\n" + out


def _cdef_of(path: Path) -> str:
    text = path.read_text()
    return _expanded_cdef(path) if re.search(r'#include\s+"[^"]+\.inc"', text) else header_cdef(text)


def cdef_text(gen_dir: Path = GEN_DIR) -> str:
    dbcgen.generate_all(gen_dir)
    parts = [p.read_text() for p in sorted(gen_dir.glob("*.cdef"))]  # the generated codec
    parts += [f"/* {p.name} */\n" + _cdef_of(p) for p in public_headers(gen_dir)]
    return "\n".join(parts)


def include_text(gen_dir: Path = GEN_DIR) -> str:
    headers = [p.name for p in public_headers(gen_dir)]
    headers += [p.name for p in sorted(gen_dir.glob("vh_*.h"))
                if p.name not in headers and "_meta" not in p.name and p.name != "vh_secoc_table.h"]
    return "\n".join(f'#include "{h}"' for h in headers)


def xcp_generate(gen_dir: Path = GEN_DIR):
    """The ECU's XCP limit table (c_core/ecu/vh_ecu_xcp_table.inc), A2L and XCP-bus DBC
    (vehest_can/xcp/) from vehest_can/xcp/ecu.toml, laid out by the structs of the headers
    (cffi's layout, which the compiled extension is checked against). Written into the source
    tree only when they change; tests/xcp/test_xcp_ecu.py regenerates them and compares."""
    sys.path.insert(0, str(ROOT))
    from vehest_can.xcp import ecu_desc

    ffi = FFI()
    ffi.cdef(cdef_text(gen_dir))
    return ecu_desc.generate(ffi)


def compile_firmware(out_dir: Path = ROOT / "build" / "obj", extra_flags: list[str] | None = None,
                     gen_dir: Path = GEN_DIR) -> list[str]:
    """Compile every source with the strict flags; returns the object files.

    The firmware and the codec see only the firmware's include path; the simulator sees both.
    The firmware is compiled here, apart from cffi's own glue: the glue casts object pointers
    to function pointers, which ``-pedantic`` rejects, and it is not our code to hold to C99.
    """
    from setuptools._distutils.ccompiler import new_compiler
    from setuptools._distutils.sysconfig import customize_compiler

    cc = new_compiler()
    customize_compiler(cc)
    flags = STRICT_FLAGS + OPT_FLAGS + ["-fPIC"] + (extra_flags or [])
    srcs = firmware_sources(gen_dir)
    sim = [s for s in srcs if s.parent == SIM_SRC_DIR]
    fw = [s for s in srcs if s.parent != SIM_SRC_DIR]
    objs = cc.compile([str(s) for s in fw], output_dir=str(out_dir / "firmware"),
                      include_dirs=[str(d) for d in firmware_include_dirs(gen_dir)], extra_postargs=flags)
    objs += cc.compile([str(s) for s in sim], output_dir=str(out_dir / "sim"),
                       include_dirs=[str(d) for d in sim_include_dirs(gen_dir)], extra_postargs=flags)
    return objs


def make_ffi() -> FFI:
    xcp_generate()  # before compiling: vh_ecu_xcp.c includes the limit table
    objects = compile_firmware()
    ffi = FFI()
    ffi.cdef(cdef_text())
    ffi.set_source(
        "vehest_can._native",
        include_text(),
        include_dirs=[str(d) for d in sim_include_dirs()],
        extra_objects=objects,
        libraries=["m"],
        extra_link_args=LINK_FLAGS[1:],
    )
    return ffi


ffibuilder = make_ffi()

if __name__ == "__main__":
    ffibuilder.compile(tmpdir=str(ROOT / "build" / "cffi"), verbose=True)
