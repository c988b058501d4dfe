"""Thin layer over the compiled C core (``vehest_can._native``): one place for status codes."""
from __future__ import annotations

import dataclasses
import enum
from collections.abc import Callable, Mapping
from typing import Any

from ._native import ffi, lib
from .errors import ConfigError, NativeError

_STATUS = {lib.VH_EINVAL: "invalid configuration value", lib.VH_ENOSPC: "buffer too small"}


def check(status: int, what: str) -> int:
    """Turn a C status code into NativeError; returns the status when it is VH_OK or positive."""
    if status < 0:
        raise NativeError(f"{what}: {_STATUS.get(status, f'status {status}')}")
    return status


_KINDS = {"double": "f8", "float": "f4", "int": "i4", "int8_t": "i1", "uint8_t": "u1", "int16_t": "i2",
          "uint16_t": "u2", "int32_t": "i4", "uint32_t": "u4", "int64_t": "i8", "uint64_t": "u8"}


def struct_dtype(ctype: str):
    """numpy dtype laid out exactly like a C struct of scalars, scalar arrays and such structs (offsets
    from the compiler, through cffi), so C arrays of it can be viewed without copying."""
    import numpy as np

    fields = ffi.typeof(ctype).fields
    formats = []
    for _, f in fields:
        t = f.type
        if t.kind == "struct":
            formats.append(struct_dtype(t.cname))
        else:
            formats.append((_KINDS[t.item.cname], t.length) if t.kind == "array" else _KINDS[t.cname])
    return np.dtype({"names": [name for name, _ in fields], "formats": formats,
                     "offsets": [f.offset for _, f in fields], "itemsize": ffi.sizeof(ctype)})


def struct_array(ctype: str, cdata, n: int):
    """A numpy copy of the first n elements of a cffi array of ``ctype``, laid out by struct_dtype."""
    import numpy as np

    return np.frombuffer(ffi.buffer(cdata, n * ffi.sizeof(ctype)), dtype=struct_dtype(ctype)).copy()


_INTEGER = ("int", "unsigned", "int8_t", "uint8_t", "int16_t", "uint16_t", "int32_t", "uint32_t", "int64_t",
            "uint64_t", "size_t")


def c_enum(ctype: str, name: str, prefix: str, doc: str = "") -> Any:
    """An IntEnum of a C enum type: its members are the C enumerators without ``prefix``, in value
    order, so the Python side cannot drift from the header."""
    members = sorted(ffi.typeof(ctype).relements.items(), key=lambda kv: kv[1])
    cls = enum.IntEnum(name, [(k.removeprefix(prefix), v) for k, v in members])  # type: ignore[misc]
    cls.__doc__ = doc or f"{ctype}, from the C."
    return cls


def config_class(ctype: str, name: str, *, defaults: Callable[[Any], object] | None = None,
                 enums: Mapping[str, tuple[str, Mapping[str, int]]] | None = None, flags: tuple[str, ...] = (),
                 frozen: bool = False, doc: str = "") -> Any:
    """A dataclass that mirrors a C configuration struct, derived from it rather than copied by hand:
    its fields are the struct's (names, order and array lengths from the cffi type), their defaults
    what the C defaults function writes (``defaults(c)`` on a fresh struct; None: no defaults), with
    ``from_c(c)`` and ``to_c(c=None)``. Scalars become float or int as in C, arrays tuples, the
    fields in `flags` bool, and those in `enums` (field: (what it is, {name: C value})) names.

    ``to_c`` refuses, as ConfigError, what C could not hold (an unknown name, an array of another
    length, a non-number); the C init function checks the values themselves. Subclass the result
    to add a system's own constructors and checks."""
    enums = dict(enums or {})
    fields = ffi.typeof(ctype).fields
    c0 = ffi.new(f"{ctype} *")
    if defaults is not None:
        defaults(c0)

    def py(fname: str, value) -> Any:
        if fname in enums:
            label, names = enums[fname]
            return {v: k for k, v in names.items()}.get(value, value)
        if fname in flags:
            return bool(value)
        return tuple(value) if isinstance(value, ffi.CData) else value

    spec = []
    for fname, f in fields:
        t = f.type.item if f.type.kind == "array" else f.type
        kind: Any = str if fname in enums else bool if fname in flags else int if t.cname in _INTEGER else float
        if f.type.kind == "array":
            kind = tuple
        default = py(fname, getattr(c0, fname))
        spec.append((fname, kind, dataclasses.field(default=default) if defaults is not None else dataclasses.field()))

    def from_c(cls, c):
        return cls(**{fname: py(fname, getattr(c, fname)) for fname, _ in fields})

    def to_c(self, c=None):
        """Fill (or allocate) a ``{ctype}``."""
        c = c if c is not None else ffi.new(f"{ctype} *")
        for fname, f in fields:
            value = getattr(self, fname)
            if fname in enums:
                label, names = enums[fname]
                if value not in names:
                    raise ConfigError(f"{label} {value!r}: expected one of {sorted(names)}")
                value = names[value]
            elif fname in flags:
                value = int(bool(value))
            elif f.type.kind == "array":
                value = tuple(value)
                if len(value) != f.type.length:
                    raise ConfigError(f"{fname}: expected {f.type.length} values, got {len(value)}")
            try:
                setattr(c, fname, value)
            except (TypeError, OverflowError) as exc:
                raise ConfigError(f"{fname}: {value!r} does not fit the C field ({f.type.cname}): {exc}") from None
        return c

    to_c.__doc__ = f"Fill (or allocate) a ``{ctype}``."
    cls = dataclasses.make_dataclass(name, spec, frozen=frozen,
                                     namespace={"from_c": classmethod(from_c), "to_c": to_c, "C_TYPE": ctype})
    cls.__doc__ = doc or f"``{ctype}`` as a dataclass (derived from the C struct)."
    return cls


def from_c_default(cls, fill: Callable[[Any], object], overrides: Mapping[str, Any], what: str,
                   convert: Callable[[str, Any], Any] = lambda key, value: value):
    """A :func:`config_class` dataclass from a fresh C struct that ``fill(c)`` (a C defaults function)
    wrote, with `overrides` (field: value, each through ``convert(field, value)``) set on it in order;
    a name that is not a field is ConfigError ``unknown <what> 'name'``."""
    c = ffi.new(f"{cls.C_TYPE} *")
    fill(c)
    cfg = cls.from_c(c)
    names = {f.name for f in dataclasses.fields(cfg)}
    for key, value in overrides.items():
        if key not in names:
            raise ConfigError(f"unknown {what} {key!r}")
        setattr(cfg, key, convert(key, value))
    return cfg


__all__ = ["ffi", "lib", "check", "struct_dtype", "struct_array", "config_class", "from_c_default"]
