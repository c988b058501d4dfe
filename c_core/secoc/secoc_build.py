"""cffi build script (out-of-line API mode) for ``vehest_can._secoc``: SecOC-style frame
authentication (CMAC-AES-128, RFC 4493) and its freshness manager, built and tested apart from
the ECU firmware like the XCP slave.

AES itself is OpenSSL's (libcrypto, the library CPython's ssl module already loads): the build
links the shared library by its file name, so no development headers are needed.
"""
from __future__ import annotations

import sys
from pathlib import Path

from cffi import FFI

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent))
from cbuild import ROOT, STRICT_FLAGS, compile_strict, extension, headers_cdef, libcrypto  # noqa: E402,F401  (c_core/cbuild.py)

HEADERS = [HERE / "vh_aes128.h", HERE / "vh_cmac.h", HERE / "vh_secoc.h"]
SOURCES = [HERE / "vh_cmac.c", HERE / "vh_secoc.c", HERE / "vh_aes128_host.c"]


def cdef_text() -> str:
    return headers_cdef(HEADERS)


def compile_objects(out_dir: Path = ROOT / "build" / "secoc_obj", extra_flags: list[str] | None = None, *,
                    dry: bool = False) -> list[str]:
    """The C compiled with the strict flags, apart from cffi's glue."""
    return compile_strict(SOURCES, [HERE], out_dir, extra_flags=extra_flags, dry=dry)


def make_ffi() -> FFI:
    """The builder of ``vehest_can._secoc`` (its objects compiled by compile_objects, not here)."""
    return extension("vehest_can._secoc", HERE / "vh_secoc.h", cdef_text(), compile_objects(dry=True),
                     extra_link_args=[libcrypto()])



if __name__ == "__main__":
    compile_objects()
    make_ffi().compile(tmpdir=str(ROOT / "build" / "cffi_secoc"), verbose=True)
