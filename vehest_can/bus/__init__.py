"""Buses and frames: opening python-can buses (``bus``: HostMulticastBus, the host-only default), the
DBC codec and E2E (``frames``), the lockstep protocol, bus load, the real-time clock (``rt``), CAN log files."""
