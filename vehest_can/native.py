"""Thin layer over the compiled C core (``vehest_can._native``): one place for status codes."""
from __future__ import annotations

from ._native import ffi, lib
from .errors import NativeError

_STATUS = {lib.VH_EINVAL: "invalid configuration value", lib.VH_ENOSPC: "buffer too small"}


def check(status: int, what: str) -> int:
    """Turn a C status code into NativeError; returns the status when it is VH_OK or positive."""
    if status < 0:
        raise NativeError(f"{what}: {_STATUS.get(status, f'status {status}')}")
    return status


_KINDS = {"double": "f8", "float": "f4", "int": "i4", "int8_t": "i1", "uint8_t": "u1", "int16_t": "i2",
          "uint16_t": "u2", "int32_t": "i4", "uint32_t": "u4", "int64_t": "i8", "uint64_t": "u8"}


def struct_dtype(ctype: str):
    """numpy dtype laid out exactly like a C struct of scalars and scalar arrays (offsets from
    the compiler, through cffi), so C arrays of it can be viewed without copying."""
    import numpy as np

    fields = ffi.typeof(ctype).fields
    formats = []
    for _, f in fields:
        t = f.type
        formats.append((_KINDS[t.item.cname], t.length) if t.kind == "array" else _KINDS[t.cname])
    return np.dtype({"names": [name for name, _ in fields], "formats": formats,
                     "offsets": [f.offset for _, f in fields], "itemsize": ffi.sizeof(ctype)})


def struct_array(ctype: str, cdata, n: int):
    """A numpy copy of the first n elements of a cffi array of ``ctype``, laid out by struct_dtype."""
    import numpy as np

    return np.frombuffer(ffi.buffer(cdata, n * ffi.sizeof(ctype)), dtype=struct_dtype(ctype)).copy()


__all__ = ["ffi", "lib", "check", "struct_dtype", "struct_array"]
