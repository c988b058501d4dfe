"""cffi build script (out-of-line API mode) for ``vehest_can._secoc``: SecOC-style frame
authentication (CMAC-AES-128, RFC 4493) and its freshness manager, built and tested apart from
the ECU firmware like the XCP slave.

AES itself is OpenSSL's (libcrypto, the library CPython's ssl module already loads): the build
links the shared library by its file name, so no development headers are needed.
"""
from __future__ import annotations

import re
import sys
from pathlib import Path

from cffi import FFI

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
from crypto_link import libcrypto  # noqa: E402  (sits beside this file)

HEADERS = [HERE / "vh_aes128.h", HERE / "vh_cmac.h", HERE / "vh_secoc.h"]
SOURCES = [HERE / "vh_cmac.c", HERE / "vh_secoc.c", HERE / "vh_aes128_host.c"]
STRICT_FLAGS = ["-std=c99", "-Wall", "-Wextra", "-Werror", "-pedantic"]
OPT_FLAGS = ["-O2"]
_CONSTANT = re.compile(r"#define\s+\w+\s+\d+\b")


def cdef_text() -> str:
    """The public headers as cffi declarations: every preprocessor line but integer constants goes."""
    lines = []
    for header in HEADERS:
        for line in header.read_text().splitlines():
            stripped = line.strip()
            if stripped.startswith("#") and not _CONSTANT.match(stripped):
                continue
            lines.append(line)
    return "\n".join(lines)


def compile_objects(out_dir: Path = HERE.parent.parent / "build" / "secoc_obj",
                    extra_flags: list[str] | None = None) -> list[str]:
    """The C compiled with the strict flags, apart from cffi's glue (which -pedantic rejects)."""
    from setuptools._distutils.ccompiler import new_compiler
    from setuptools._distutils.sysconfig import customize_compiler

    cc = new_compiler()
    customize_compiler(cc)
    return cc.compile([str(s) for s in SOURCES], output_dir=str(out_dir), include_dirs=[str(HERE)],
                      extra_postargs=STRICT_FLAGS + OPT_FLAGS + ["-fPIC"] + (extra_flags or []))


def make_ffi() -> FFI:
    ffi = FFI()
    ffi.cdef(cdef_text())
    ffi.set_source("vehest_can._secoc", '#include "vh_secoc.h"', include_dirs=[str(HERE)],
                   extra_objects=compile_objects(), extra_link_args=[libcrypto()])
    return ffi


ffibuilder = make_ffi()

if __name__ == "__main__":
    ffibuilder.compile(tmpdir=str(HERE.parent.parent / "build" / "cffi_secoc"), verbose=True)
