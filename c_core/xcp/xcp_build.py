"""cffi build script (out-of-line API mode) for ``vehest_can._xcp``: the XCP slave alone.

Its own extension, so the slave builds and is tested apart from the ECU firmware (and the
shared ``vehest_build.py`` stays untouched). The cdef is the public header itself: only its
preprocessor lines are dropped (cffi parses declarations and integer ``#define`` constants, not
include guards or ``#include``).
"""
from __future__ import annotations

import sys
from pathlib import Path

from cffi import FFI

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent))
from cbuild import ROOT, STRICT_FLAGS, compile_strict, extension, header_cdef  # noqa: E402,F401  (c_core/cbuild.py)

HEADER = HERE / "vh_xcp.h"
SOURCES = [HERE / "vh_xcp.c"]


def cdef_text(header: Path = HEADER) -> str:
    return header_cdef([header])


def compile_slave(out_dir: Path = ROOT / "build" / "xcp_obj", extra_flags: list[str] | None = None) -> list[str]:
    """The slave compiled with the strict flags, apart from cffi's glue."""
    return compile_strict(SOURCES, [HERE], out_dir, extra_flags=extra_flags)


def make_ffi() -> FFI:
    return extension("vehest_can._xcp", HEADER, cdef_text(), compile_slave())


ffibuilder = make_ffi()

if __name__ == "__main__":
    ffibuilder.compile(tmpdir=str(ROOT / "build" / "cffi_xcp"), verbose=True)
