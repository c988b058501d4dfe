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


__all__ = ["ffi", "lib", "check"]
