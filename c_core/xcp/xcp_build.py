"""cffi build script (out-of-line API mode) for ``vehest_can._xcp``: the XCP slave alone.

Its own extension, so the slave builds and is tested apart from the ECU firmware (and the
shared ``vehest_build.py`` stays untouched). The cdef is the public header itself: only its
preprocessor lines are dropped (cffi parses declarations and integer ``#define`` constants, not
include guards or ``#include``).
"""
from __future__ import annotations

import re
from pathlib import Path

from cffi import FFI

HERE = Path(__file__).resolve().parent
HEADER = HERE / "vh_xcp.h"
SOURCES = [HERE / "vh_xcp.c"]
STRICT_FLAGS = ["-std=c99", "-Wall", "-Wextra", "-Werror", "-pedantic"]
OPT_FLAGS = ["-O2"]
# An integer constant cffi can take as it stands; every other preprocessor line goes.
_CONSTANT = re.compile(r"#define\s+\w+\s+\d+\b")


def cdef_text(header: Path = HEADER) -> str:
    lines = []
    for line in header.read_text().splitlines():
        stripped = line.strip()
        if stripped.startswith("#") and not _CONSTANT.match(stripped):
            continue
        lines.append(line)
    return "\n".join(lines)


def compile_slave(out_dir: Path = HERE.parent.parent / "build" / "xcp_obj", extra_flags: list[str] | None = None) -> list[str]:
    """The slave compiled with the strict flags, apart from cffi's glue (which -pedantic rejects)."""
    from setuptools._distutils.ccompiler import new_compiler
    from setuptools._distutils.sysconfig import customize_compiler

    cc = new_compiler()
    customize_compiler(cc)
    return cc.compile([str(s) for s in SOURCES], output_dir=str(out_dir), include_dirs=[str(HERE)],
                      extra_postargs=STRICT_FLAGS + OPT_FLAGS + ["-fPIC"] + (extra_flags or []))


def make_ffi() -> FFI:
    ffi = FFI()
    ffi.cdef(cdef_text())
    ffi.set_source("vehest_can._xcp", '#include "vh_xcp.h"', include_dirs=[str(HERE)],
                   extra_objects=compile_slave())
    return ffi


ffibuilder = make_ffi()

if __name__ == "__main__":
    ffibuilder.compile(tmpdir=str(HERE.parent.parent / "build" / "cffi_xcp"), verbose=True)
