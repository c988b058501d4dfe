"""XCP on CAN: the C slave (in ``vehest_can._native``), its python-can bridge and the A2L generator.

``description`` says what the master may see and change; ``slave.Slave`` is the C slave over a
memory image laid out by it; ``bridge.XcpBridge`` runs it on a python-can bus; ``a2l`` writes
the matching A2L file and ``calfile`` saves and loads the working page.

The slave and the bridge load on first use, so the A2L generator runs before the C is built.
"""
from .description import DEMO, Description, DescriptionError, load
from .keys import key_for

_LAZY = {"Slave": "slave", "XcpConfigError": "slave", "XcpBridge": "bridge"}

__all__ = ["DEMO", "Description", "DescriptionError", "Slave", "XcpBridge", "XcpConfigError", "key_for", "load"]


def __getattr__(name):
    if name in _LAZY:
        import importlib
        return getattr(importlib.import_module(f".{_LAZY[name]}", __name__), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
