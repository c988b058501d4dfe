"""cffi build script (out-of-line API mode) for ``vehest_can._roll``: the roll system's C
(``c_core/roll``), its own extension so it builds apart from ``vehest_can._native``.

The cdef is the header itself: ``vh_roll.h`` run through the C preprocessor with
``VH_ROLL_CDEF`` set (no system headers; the float32 and double declarations expanded from
``vh_roll_decl.inc``), never a Python copy of the declarations.

The sources are compiled here with the strict flags (C99, -Wall -Wextra -Werror -pedantic,
and -Wdouble-promotion so the float32 build stays single precision), apart from cffi's glue.
"""
from __future__ import annotations

import os
import shlex
import subprocess
import sys
from pathlib import Path

from cffi import FFI

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent))
import cbuild  # noqa: E402  (c_core/cbuild.py)

ROOT = cbuild.ROOT
STRICT_FLAGS = cbuild.STRICT_FLAGS + ["-Wdouble-promotion"]
OPT_FLAGS = cbuild.OPT_FLAGS
SOURCES = ["vh_roll_f32.c", "vh_roll_f64_host.c", "vh_roll_params.c"]


def _cc() -> list[str]:
    from setuptools._distutils.sysconfig import get_config_var

    return shlex.split(os.environ.get("CC") or get_config_var("CC") or "cc")


def cdef_text() -> str:
    """The declarations of vh_roll.h, preprocessed (both precisions expanded)."""
    out = subprocess.run(
        _cc() + ["-E", "-P", "-DVH_ROLL_CDEF", "-I", str(HERE), "-x", "c", str(HERE / "vh_roll.h")],
        check=True, capture_output=True, text=True,
    ).stdout
    return out


def compile_roll(out_dir: Path = ROOT / "build" / "obj_roll", extra_flags: list[str] | None = None) -> list[str]:
    return cbuild.compile_strict([HERE / s for s in SOURCES], [HERE], out_dir, STRICT_FLAGS + OPT_FLAGS, extra_flags)


def make_ffi() -> FFI:
    objects = compile_roll()
    ffi = FFI()
    ffi.cdef(cdef_text())
    ffi.set_source("vehest_can._roll", '#include "vh_roll.h"', include_dirs=[str(HERE)],
                   extra_objects=objects, libraries=["m"])
    return ffi


ffibuilder = make_ffi()

if __name__ == "__main__":
    ffibuilder.compile(tmpdir=str(ROOT / "build" / "cffi_roll"), verbose=True)
