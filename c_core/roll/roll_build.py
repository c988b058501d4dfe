"""cffi build script (out-of-line API mode) for ``vehest_can._roll``: the roll system's C
(``c_core/roll``), its own extension so it builds apart from ``vehest_can._native``.

The cdef is the header itself: ``vh_roll.h`` run through the C preprocessor with
``VH_ROLL_CDEF`` set (no system headers; the float32 and double declarations expanded from
``vh_roll_decl.inc``), never a Python copy of the declarations.

The sources are compiled here with the strict flags (C99, -Wall -Wextra -Werror -pedantic,
and -Wdouble-promotion so the float32 build stays single precision), apart from cffi's glue.
"""
from __future__ import annotations

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


def cdef_text() -> str:
    """The declarations of vh_roll.h, preprocessed (both precisions expanded)."""
    return cbuild.cdef_of(HERE / "vh_roll.h")


def compile_objects(out_dir: Path = ROOT / "build" / "obj_roll", extra_flags: list[str] | None = None, *,
                    dry: bool = False) -> list[str]:
    return cbuild.compile_strict([HERE / s for s in SOURCES], [HERE], out_dir, STRICT_FLAGS + OPT_FLAGS, extra_flags,
                                 dry=dry)


def make_ffi() -> FFI:
    """The builder of ``vehest_can._roll`` (its objects compiled by compile_objects, not here)."""
    objects = compile_objects(dry=True)
    ffi = FFI()
    ffi.cdef(cdef_text())
    ffi.set_source("vehest_can._roll", '#include "vh_roll.h"', include_dirs=[str(HERE)],
                   extra_objects=objects, libraries=["m"])
    return ffi


if __name__ == "__main__":
    compile_objects()
    make_ffi().compile(tmpdir=str(ROOT / "build" / "cffi_roll"), verbose=True)
