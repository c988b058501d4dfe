"""cffi build script (out-of-line API mode) for ``vehest_can._native``.

One extension holds the ECU firmware (``c_core/<folder>/``: ``common``, one folder per system,
``xcp``, ``secoc``, ``ecu``), the simulated car and sensor nodes (``firmware_sim/src``) and the
codec generated from ``dbc/`` at build time; the XCP slave, SecOC and the roll filter (float32 and
double) are used from Python through it too, so every source is compiled once. Two include paths
keep the boundary: the firmware and the codec compile with the firmware folders only, so a firmware
source that includes a simulator header does not build; the simulator compiles with both. Sharing
one extension lets the C lockstep harness pass instances between plant and ECU without copies.

The cdef is generated from the public headers themselves (``cbuild.cdef_of``). Nothing is written
twice. Importing this compiles and generates nothing; setup.py's build_ext calls ``make_ffi`` with
its temporary directory, the only place the build writes to. The build does not import
``vehest_can``: the app list and XCP limit table it compiles (``c_core/ecu/``) are the committed
copies that ``c_core/ecu_gen.py`` writes from the systems' descriptors (a test holds them current).
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
from cbuild import OPT_FLAGS, STRICT_FLAGS, cdef_of, compile_strict, header_cdef, libcrypto  # noqa: E402,F401  (c_core/cbuild.py)

_INCLUDE = re.compile(r'^#include\s+"([^"]+)"', re.M)

#: the systems of the firmware, one folder each (sources, headers, the system's ECU application)
SYSTEMS = ("driveline", "tireforce", "camber", "roll")
#: every folder of the firmware: what it shares, the systems, the XCP slave, SecOC, the scheduler
FIRMWARE_DIRS = [HERE / "common", *(HERE / s for s in SYSTEMS), HERE / "xcp", HERE / "secoc", HERE / "ecu"]
#: what a program built from the firmware's sources links: libm, and OpenSSL's libcrypto for SecOC's
#: AES on the host (vh_aes128_host.c; a target links its HSM driver instead)
LINK_FLAGS = ["-lm", libcrypto()]
SIM_SRC_DIR = ROOT / "firmware_sim" / "src"
SIM_INCLUDE_DIR = ROOT / "firmware_sim" / "include"
#: the board support of the firmware image for an emulated Cortex-M4F (startup, linker script, the
#: frame link, main: c_core/firmware_image.py); never in the extension
TARGET_DIR = HERE / "target"
#: built into the extension but never flashed (host-side calibration helpers)
HOST_ONLY_GLOB = "*_host.c"


def firmware_include_dirs(gen_dir: Path) -> list[Path]:
    """The include path of a firmware build: the firmware folders and the generated codec."""
    return [*FIRMWARE_DIRS, gen_dir]


def sim_include_dirs(gen_dir: Path) -> list[Path]:
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


def ecu_sources(gen_dir: Path, host: bool = True) -> list[Path]:
    """The firmware's C sources (host-only helpers unless host=False), without the codec."""
    srcs = [p for d in FIRMWARE_DIRS for p in sorted(d.glob("*.c"))]
    return srcs if host else [p for p in srcs if not p.match(HOST_ONLY_GLOB)]


def firmware_sources(gen_dir: Path) -> list[Path]:
    """Every C source of the extension, generated codec included (after generating it)."""
    names = dbcgen.generate_all(gen_dir)
    return ecu_sources(gen_dir) + sorted(SIM_SRC_DIR.glob("*.c")) + [gen_dir / f"{n}.c" for n in names]


def public_headers(gen_dir: Path) -> list[Path]:
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


def cdef_text(gen_dir: Path) -> str:
    dbcgen.generate_all(gen_dir)
    parts = [p.read_text() for p in sorted(gen_dir.glob("*.cdef"))]  # the generated codec
    parts += [f"/* {p.name} */\n" + cdef_of(p) for p in public_headers(gen_dir)]
    return "\n".join(parts)


def include_text(gen_dir: Path) -> str:
    headers = [p.name for p in public_headers(gen_dir)]
    headers += [p.name for p in sorted(gen_dir.glob("vh_*.h"))
                if p.name not in headers and "_meta" not in p.name and p.name != "vh_secoc_table.h"]
    return "\n".join(f'#include "{h}"' for h in headers)


def compile_objects(out_dir: Path, gen_dir: Path, extra_flags: list[str] | None = None) -> list[str]:
    """Compile every source with the strict flags (the codec generated into ``gen_dir``); returns
    the object files.

    The firmware and the codec see only the firmware's include path; the simulator sees both.
    The firmware is compiled here, apart from cffi's own glue: the glue casts object pointers
    to function pointers, which ``-pedantic`` rejects, and it is not our code to hold to C99.
    """
    srcs = firmware_sources(gen_dir)
    sim = [s for s in srcs if s.parent == SIM_SRC_DIR]
    fw = [s for s in srcs if s.parent != SIM_SRC_DIR]
    return (compile_strict(fw, firmware_include_dirs(gen_dir), out_dir / "firmware", extra_flags)
            + compile_strict(sim, sim_include_dirs(gen_dir), out_dir / "sim", extra_flags))


def make_ffi(build_dir: Path) -> FFI:
    """The builder of ``vehest_can._native``, everything it needs made under ``build_dir`` (the
    build's temporary directory): the codec in ``generated/``, every source compiled once into
    ``obj/``; cffi's glue, compiled by the caller, links those objects."""
    gen_dir = build_dir / "generated"
    objects = compile_objects(build_dir / "obj", gen_dir)
    ffi = FFI()
    ffi.cdef(cdef_text(gen_dir))
    ffi.set_source(
        "vehest_can._native",
        include_text(gen_dir),
        include_dirs=[str(d) for d in sim_include_dirs(gen_dir)],
        extra_objects=objects,
        libraries=["m"],
        extra_link_args=LINK_FLAGS[1:],
    )
    return ffi
