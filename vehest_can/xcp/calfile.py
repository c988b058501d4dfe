"""Calibration files: the working page saved as physical values, loaded back with every check.

A versioned JSON document (like the camber calibration)::

    {"format": "vehest-can/xcp-calibration", "version": 1, "description": "VEHEST_ECU",
     "values": {"<characteristic>": <physical value, or nested lists for an array>, ...}}

Loading refuses another format or version, another description, unknown or missing names, a
wrong shape, a value outside the characteristic's limits or not representable in its C type; it
then writes the working page and the ECU page at once (as the ECU starts, before any tick).
"""
from __future__ import annotations

import json
import math
import os
import struct
import tempfile
from pathlib import Path

from .description import C_TYPES, Description, DescriptionError, Item, raw_limits_for_c

FORMAT = "vehest-can/xcp-calibration"
VERSION = 1


class CalFileError(DescriptionError):
    """A calibration file that cannot be applied."""


def _nest(flat: list, shape: tuple[int, ...]):
    if len(shape) <= 1:
        return list(flat)
    step = math.prod(shape[1:])
    return [_nest(flat[i * step:(i + 1) * step], shape[1:]) for i in range(shape[0])]


def _flatten(v) -> list:
    return [x for e in v for x in _flatten(e)] if isinstance(v, list) else [v]


def _shape_of(v) -> tuple[int, ...]:
    if not isinstance(v, list):
        return ()
    inner = {_shape_of(e) for e in v}
    if len(inner) != 1:
        raise ValueError("ragged")
    return (len(v),) + inner.pop()


def values_of(desc: Description, read_raw) -> dict:
    """{name: physical value(s)} of every characteristic, from `read_raw(name)` (raw value(s))."""
    out = {}
    for c in desc.characteristics:
        raw = read_raw(c.name)
        flat = [c.raw_to_phys(r) for r in (raw if isinstance(raw, list) else [raw])]
        out[c.name] = _nest(flat, c.shape) if c.shape else flat[0]
    return out


def save_values(desc: Description, vals: dict, path) -> None:
    doc = {"format": FORMAT, "version": VERSION, "description": desc.name, "values": vals}
    path = Path(path)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=path.name, suffix=".tmp")
    with os.fdopen(fd, "w") as f:
        json.dump(doc, f, indent=1)
        f.write("\n")
    os.replace(tmp, path)  # atomic: a crash leaves the old file


def _raw(item: Item, phys: float, path) -> float | int:
    if isinstance(phys, bool) or not isinstance(phys, (int, float)):
        raise CalFileError(f"{path}: {item.name}: {phys!r} is not a number")
    raw = item.phys_to_raw(float(phys))
    if item.ctype in ("float", "double"):
        if item.ctype == "float":
            raw = struct.unpack("<f", struct.pack("<f", raw))[0]
    else:
        r = round(raw)
        if abs(r - raw) > 1e-9 * max(1.0, abs(raw)):
            raise CalFileError(f"{path}: {item.name}: {phys} is not a multiple of its resolution {item.factor}")
        raw = int(r)
    lo, hi = raw_limits_for_c(item)
    if not (lo <= raw <= hi):
        lo_p, hi_p = item.phys_limits()
        raise CalFileError(f"{path}: {item.name}: {phys} outside [{lo_p}, {hi_p}]")
    return raw


def load_image(desc: Description, path, image: bytes) -> tuple[bytes, dict]:
    """The calibration segment `image` with the file's values, every check passed; and the values."""
    try:
        doc = json.loads(Path(path).read_text())
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as e:
        raise CalFileError(f"{path}: cannot read: {e}") from e
    if not isinstance(doc, dict) or doc.get("format") != FORMAT:
        raise CalFileError(f"{path}: not an XCP calibration file (format must be {FORMAT!r})")
    if doc.get("version") != VERSION:
        raise CalFileError(f"{path}: unsupported version {doc.get('version')!r}; this reads version {VERSION}")
    if doc.get("description") != desc.name:
        raise CalFileError(f"{path}: written for {doc.get('description')!r}, not {desc.name!r}")
    unknown = set(doc) - {"format", "version", "description", "values"}
    vals = doc.get("values")
    if unknown or not isinstance(vals, dict):
        raise CalFileError(f"{path}: unknown keys {sorted(unknown)} or no 'values' table")
    names = {c.name for c in desc.characteristics}
    if set(vals) != names:
        raise CalFileError(f"{path}: unknown {sorted(set(vals) - names)}, missing {sorted(names - set(vals))}")
    out = bytearray(image)
    for c in desc.characteristics:
        v = vals[c.name]
        try:
            shape = _shape_of(v)
        except ValueError:
            shape = None
        if shape != c.shape:
            raise CalFileError(f"{path}: {c.name}: shape {shape}, expected {c.shape}")
        raws = [_raw(c, p, path) for p in _flatten(v)]
        struct.pack_into("<" + C_TYPES[c.ctype][4] * c.count, out, c.address - desc.calibration_address, *raws)
    return bytes(out), vals
