"""XCP on CAN: the C slave (``vehest_can._xcp``), its python-can bridge and the A2L generator.

``description`` says what the master may see and change; ``slave.Slave`` is the C slave over a
memory image laid out by it; ``bridge.XcpBridge`` runs it on a python-can bus; ``a2l`` writes
the matching A2L file.
"""
from .bridge import XcpBridge
from .description import DEMO, Description, DescriptionError, load
from .slave import Slave, XcpConfigError, key_for

__all__ = ["DEMO", "Description", "DescriptionError", "Slave", "XcpBridge", "XcpConfigError", "key_for", "load"]
