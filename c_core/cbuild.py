"""What the cffi build scripts share (``vehest_build.py`` and the standalone extensions in
``xcp/``, ``secoc/``, ``roll/``): the strict C flags, compiling sources with them apart from
cffi's glue (which -pedantic rejects), a public header as cffi declarations, the builder of a
standalone extension, and how to link OpenSSL's libcrypto (the host's AES backend,
vh_aes128_host.c)."""
from __future__ import annotations

import ctypes.util
import re
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parent.parent
STRICT_FLAGS = ["-std=c99", "-Wall", "-Wextra", "-Werror", "-pedantic"]
OPT_FLAGS = ["-O2"]
# An integer constant cffi can take as it stands; every other preprocessor line goes.
_CONSTANT = re.compile(r"#define\s+\w+\s+\d+\b")


def header_cdef(headers: list[Path]) -> str:
    """Public headers as cffi declarations: every preprocessor line but integer constants goes
    (cffi parses declarations and integer ``#define`` constants, not guards or ``#include``)."""
    lines = []
    for header in headers:
        for line in header.read_text().splitlines():
            stripped = line.strip()
            if stripped.startswith("#") and not _CONSTANT.match(stripped):
                continue
            lines.append(line)
    return "\n".join(lines)


def compile_strict(sources: list[Path], include_dirs: list[Path], out_dir: Path,
                   flags: list[str] | None = None, extra_flags: list[str] | None = None) -> list[str]:
    """Object files of ``sources`` built with ``flags`` (default: the strict flags and -O2)."""
    from setuptools._distutils.ccompiler import new_compiler
    from setuptools._distutils.sysconfig import customize_compiler

    cc = new_compiler()
    customize_compiler(cc)
    return cc.compile([str(s) for s in sources], output_dir=str(out_dir), include_dirs=[str(d) for d in include_dirs],
                      extra_postargs=(flags or STRICT_FLAGS + OPT_FLAGS) + ["-fPIC"] + (extra_flags or []))


def extension(module: str, header: Path, cdef: str, objects: list[str], **link: Any) -> Any:
    """The cffi builder of a standalone extension: ``cdef`` declared, its glue including ``header``
    (from the header's folder), linked with ``objects`` (built by compile_strict) and ``link``
    (``set_source``'s link arguments)."""
    from cffi import FFI

    ffi = FFI()
    ffi.cdef(cdef)
    ffi.set_source(module, f'#include "{header.name}"', include_dirs=[str(header.parent)],
                   extra_objects=objects, **link)
    return ffi


def libcrypto() -> str:
    """The linker argument for OpenSSL's libcrypto (``-l:libcrypto.so.3``), or a clear error: linked
    by its file name, so no development headers are needed."""
    name = ctypes.util.find_library("crypto")
    if not name:
        raise SystemExit("vehest-can needs OpenSSL's libcrypto (the library Python's ssl module uses) "
                         "for SecOC's AES; none was found by ctypes.util.find_library('crypto')")
    return f"-l:{name}"
