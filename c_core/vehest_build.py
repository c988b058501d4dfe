"""cffi build script (out-of-line API mode) for ``vehest_can._native``.

One extension holds the ECU firmware (``c_core/src``), the simulated car and sensor nodes
(``firmware_sim/src``) and the codec generated from ``dbc/`` at build time. The firmware
sources never include firmware_sim headers (a test checks it), so ``c_core`` stays a
portable, self-contained firmware; sharing one extension lets the C lockstep harness pass
instances between plant and ECU without copies.

The cdef is read from declaration files (``c_core/cdef/*.h``, ``firmware_sim/cdef/*.h`` and
the generated ``*.cdef``), not written as Python strings.
"""
from __future__ import annotations

import sys
from pathlib import Path

from cffi import FFI

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
sys.path.insert(0, str(HERE))
import dbcgen  # noqa: E402  (sits beside this file)

GEN_DIR = ROOT / "build" / "generated"
# The warnings that make the build fail; the same set the Makefile's strict build uses.
STRICT_FLAGS = ["-std=c99", "-Wall", "-Wextra", "-Werror", "-pedantic"]
# -O3: lets the compiler vectorise the 4x4 products of the filter step (~25% faster than -O2).
OPT_FLAGS = ["-O3"]
SOURCE_DIRS = [ROOT / "c_core" / "src", ROOT / "firmware_sim" / "src"]
INCLUDE_DIRS = [ROOT / "c_core" / "include", ROOT / "firmware_sim" / "include", GEN_DIR]
CDEF_DIRS = [ROOT / "c_core" / "cdef", ROOT / "firmware_sim" / "cdef"]
# Declarations other cdef files use by value go first (cffi needs a type before a struct embeds it).
CDEF_FIRST = ("vh_e2e.h", "vh_rng.h", "vh_dkf.h", "vh_skf.h")


def firmware_sources(gen_dir: Path = GEN_DIR) -> list[Path]:
    """Every C source of the extension, generated codec included (after generating it)."""
    names = dbcgen.generate_all(gen_dir)
    srcs = [p for d in SOURCE_DIRS for p in sorted(d.glob("*.c"))]
    return srcs + [gen_dir / f"{n}.c" for n in names]


def cdef_text(gen_dir: Path = GEN_DIR) -> str:
    files = sorted((p for d in CDEF_DIRS for p in d.glob("*.h")),
                   key=lambda p: (p.name not in CDEF_FIRST, str(p.parent) != str(CDEF_DIRS[0]), p.name))
    parts = [p.read_text() for p in files]
    parts += [p.read_text() for p in sorted(gen_dir.glob("*.cdef"))]
    return "\n".join(parts)


def include_text(gen_dir: Path = GEN_DIR) -> str:
    headers = [p.name for d in INCLUDE_DIRS[:2] for p in sorted(d.glob("*.h"))]
    headers += [p.name for p in sorted(gen_dir.glob("*.h"))]
    return "\n".join(f'#include "{h}"' for h in headers)


def compile_firmware(out_dir: Path = ROOT / "build" / "obj", extra_flags: list[str] | None = None) -> list[str]:
    """Compile every firmware source with the strict flags; returns the object files.

    The firmware is compiled here, apart from cffi's own glue: the glue casts object pointers
    to function pointers, which ``-pedantic`` rejects, and it is not our code to hold to C99.
    """
    from setuptools._distutils.ccompiler import new_compiler
    from setuptools._distutils.sysconfig import customize_compiler

    cc = new_compiler()
    customize_compiler(cc)
    flags = STRICT_FLAGS + OPT_FLAGS + ["-fPIC"] + (extra_flags or [])
    return cc.compile(
        [str(s) for s in firmware_sources()],
        output_dir=str(out_dir),
        include_dirs=[str(d) for d in INCLUDE_DIRS],
        extra_postargs=flags,
    )


def make_ffi() -> FFI:
    objects = compile_firmware()
    ffi = FFI()
    ffi.cdef(cdef_text())
    ffi.set_source(
        "vehest_can._native",
        include_text(),
        include_dirs=[str(d) for d in INCLUDE_DIRS],
        extra_objects=objects,
        libraries=["m"],
    )
    return ffi


ffibuilder = make_ffi()

if __name__ == "__main__":
    ffibuilder.compile(tmpdir=str(ROOT / "build" / "cffi"), verbose=True)
