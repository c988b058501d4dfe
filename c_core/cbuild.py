"""The one owner of how C is built here (``vehest_build.py``; the tests and tools that compile the
firmware take its flags through it): the C compiler, the strict flags and the optimisation level, compiling sources with
them apart from cffi's glue (which -pedantic rejects), a public header as cffi declarations, and
how to link OpenSSL's libcrypto (the host's AES backend, vh_aes128_host.c). Importing it compiles
nothing."""
from __future__ import annotations

import ctypes.util
import os
import re
import shlex
import subprocess
from pathlib import Path

STRICT_FLAGS = ["-std=c99", "-Wall", "-Wextra", "-Werror", "-pedantic"]
# -O3: lets the compiler vectorise the 4x4 products of the filter step (~25% faster than -O2); no
# -ffast-math. -ffp-contract=off on the host and the target alike (-std=c99 implies it, said here so
# that no other mode brings it back): a*b+c fused into one FMA rounds once, so a Cortex-M4F
# (VFMA.F32) or an x86-64 with FMA would give other float bits than the plain build
FP_FLAGS = ["-ffp-contract=off"]
OPT_FLAGS = ["-O3", *FP_FLAGS]

#: the cores the firmware image is built for (firmware_image.py): the Cortex-M4F it is written for
#: (single-precision FPU) and a Cortex-M7 with the double-precision FPU (fpv5-d16), the next part up
TARGET_CC = "arm-none-eabi-gcc"
CORES = {
    "cortex-m4f": ["-mcpu=cortex-m4", "-mthumb", "-mfloat-abi=hard", "-mfpu=fpv4-sp-d16", *FP_FLAGS],
    "cortex-m7": ["-mcpu=cortex-m7", "-mthumb", "-mfloat-abi=hard", "-mfpu=fpv5-d16", *FP_FLAGS],
}
DEFAULT_CORE = "cortex-m4f"
#: the Cortex-M4F's flags (firmware_size.py)
TARGET_FLAGS = CORES[DEFAULT_CORE]


def cc() -> list[str]:
    """The C compiler as a command (``$CC``, else the one Python was built with, else ``cc``)."""
    from setuptools._distutils.sysconfig import get_config_var

    return shlex.split(os.environ.get("CC") or get_config_var("CC") or "cc")


_COMMENT = re.compile(r"/\*.*?\*/|//[^\n]*", re.S)
_INT_LITERAL = re.compile(r"^-?(0x[0-9a-fA-F]+|\d+)[uUlL]*$")
_FLOAT_LITERAL = re.compile(r"^-?(\d+\.\d*|\.\d+|\d+)([eE][-+]?\d+)?$")


def _inline_prototypes(text: str) -> str:
    """``static inline T f(args) { ... }`` -> ``T f(args);`` (cffi wraps the inline function)."""
    out, i = [], 0
    for m in re.finditer(r"static inline ([^;{]*?\))\s*\{", text):
        if m.start() < i:
            continue
        depth, j = 1, m.end()
        while depth:
            depth += {"{": 1, "}": -1}.get(text[j], 0)
            j += 1
        out.append(text[i:m.start()] + m.group(1) + ";")
        i = j
    return "".join(out) + text[i:]


def header_cdef(text: str) -> str:
    """The cffi declarations of one public header, from the header itself."""
    # a macro continued over several lines is one line to the reader below (a function-like one is skipped)
    text = _inline_prototypes(_COMMENT.sub("", text).replace("\\\n", " "))
    lines = []
    for line in text.splitlines():
        s = line.strip()
        if s.startswith("#"):
            m = re.match(r"#define\s+(\w+)\s+(.+)$", s)
            if not m or m.group(1).endswith("_H"):
                continue  # include guards, includes, function-like macros
            name, value = m.group(1), m.group(2).strip()
            if _INT_LITERAL.match(value):
                lines.append(f"#define {name} {value}")
            elif _FLOAT_LITERAL.match(value):
                lines.append(f"static const double {name};")
            elif re.fullmatch(r"\(\s*-?\d+[uUlL]*\s*\)", value):
                lines.append(f"#define {name} ...")
            continue
        if re.match(r"typedef char \w+\[", s):
            continue  # compile-time checks
        if s:
            lines.append(line.rstrip())
    return "\n".join(lines) + "\n"


def expanded_cdef(path: Path) -> str:
    """A header that includes a template (``*.inc``, e.g. vh_roll.h: one declaration per precision):
    its integer macros, then the header through the C preprocessor with ``<NAME>_CDEF`` set (the
    header leaves out its system includes then)."""
    out = subprocess.run(cc() + ["-E", "-P", f"-D{path.stem.upper()}_CDEF", "-I", str(path.parent), "-x", "c", str(path)],
                         check=True, capture_output=True, text=True).stdout
    defines = [ln for ln in header_cdef(path.read_text()).splitlines() if ln.startswith(("#define", "static const"))]
    return "\n".join(defines) + "\n" + out


def cdef_of(path: Path) -> str:
    """The cffi declarations of one public header (expanded through the preprocessor when it
    includes a template)."""
    text = path.read_text()
    return expanded_cdef(path) if re.search(r'#include\s+"[^"]+\.inc"', text) else header_cdef(text)


def headers_cdef(headers: list[Path]) -> str:
    """The cffi declarations of public headers, in the order given."""
    return "\n".join(cdef_of(h) for h in headers)


def compile_strict(sources: list[Path], include_dirs: list[Path], out_dir: Path,
                   extra_flags: list[str] | None = None) -> list[str]:
    """Object files of ``sources`` built with the strict flags and OPT_FLAGS (and ``extra_flags``)
    by the compiler Python's extensions are built with (``$CC`` honoured)."""
    from setuptools._distutils.ccompiler import new_compiler
    from setuptools._distutils.sysconfig import customize_compiler

    compiler = new_compiler()
    customize_compiler(compiler)
    return compiler.compile([str(s) for s in sources], output_dir=str(out_dir), include_dirs=[str(d) for d in include_dirs],
                            extra_postargs=STRICT_FLAGS + OPT_FLAGS + ["-fPIC"] + (extra_flags or []))


def libcrypto() -> str:
    """The linker argument for OpenSSL's libcrypto (``-l:libcrypto.so.3``), or a clear error: linked
    by its file name, so no development headers are needed."""
    name = ctypes.util.find_library("crypto")
    if not name:
        raise SystemExit("vehest-can needs OpenSSL's libcrypto (the library Python's ssl module uses) "
                         "for SecOC's AES; none was found by ctypes.util.find_library('crypto')")
    return f"-l:{name}"
