"""XCP on CAN: the ECU's C slave (``c_core/xcp``, in its tick) seen from Python.

``description`` says what a master may see and change (the ECU's: ``ecu_desc``, from the C structs);
``ecu`` reads and writes the running ECU's items and counters; ``a2l`` writes the matching A2L file;
``calfile`` saves and loads the working page; ``master`` is a small master for the CLI; ``keys`` the
seed & key key files.
"""
from .description import Description, DescriptionError, load
from .keys import key_for

__all__ = ["Description", "DescriptionError", "key_for", "load"]
