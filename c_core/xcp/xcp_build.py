"""cffi build script (out-of-line API mode) for ``vehest_can._xcp``: the XCP slave alone.

Its own extension, so the slave builds and is tested apart from the ECU firmware (and the
shared ``vehest_build.py`` stays untouched). The cdef is the public headers themselves
(``cbuild.headers_cdef``). Seed & key is CMAC-AES-128: the slave links SecOC's CMAC
(c_core/secoc/vh_cmac.c) and, like SecOC, OpenSSL's libcrypto for the AES.
"""
from __future__ import annotations

import sys
from pathlib import Path

from cffi import FFI

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent))
from cbuild import ROOT, STRICT_FLAGS, compile_strict, headers_cdef, libcrypto  # noqa: E402,F401  (c_core/cbuild.py)

SECOC = HERE.parent / "secoc"
HEADER = HERE / "vh_xcp.h"
HEADERS = [SECOC / "vh_aes128.h", SECOC / "vh_cmac.h", HEADER]
SOURCES = [HERE / "vh_xcp.c", SECOC / "vh_cmac.c", SECOC / "vh_aes128_host.c"]


def cdef_text(headers: list[Path] = HEADERS) -> str:
    return headers_cdef(headers)


def compile_objects(out_dir: Path = ROOT / "build" / "xcp_obj", extra_flags: list[str] | None = None, *,
                    dry: bool = False) -> list[str]:
    """The slave (and the CMAC it keys with) compiled with the strict flags, apart from cffi's glue."""
    return compile_strict(SOURCES, [HERE, SECOC], out_dir, extra_flags=extra_flags, dry=dry)


def make_ffi() -> FFI:
    """The builder of ``vehest_can._xcp`` (its objects compiled by compile_objects, not here)."""
    ffi = FFI()
    ffi.cdef(cdef_text())
    ffi.set_source("vehest_can._xcp", f'#include "{HEADER.name}"', include_dirs=[str(HERE), str(SECOC)],
                   extra_objects=compile_objects(dry=True), extra_link_args=[libcrypto()])
    return ffi


if __name__ == "__main__":
    compile_objects()
    make_ffi().compile(tmpdir=str(ROOT / "build" / "cffi_xcp"), verbose=True)
