"""Bus faults, one way: ``spec`` (what a fault is, from TOML or the command line) -> ``injector`` (a node's
frames with faults, seeded, no clock) -> ``wire`` (arbitration and bit-time serialisation, a python-can
bus wrapper) -> ``campaign`` (fault runs, the fault table, the real-time bus run)."""
