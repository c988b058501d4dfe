"""The file formats of logs (``--log``, python-can's writers) and estimate tables (``--table``), by
extension, and the replay's gap limit: data only, so a verb's parser can name them without loading
the machinery that writes them (vehest_can.bus.log, vehest_can.service.estimates, .replay)."""

FORMATS = {
    ".log": "candump -L (can-utils)",
    ".asc": "Vector ASC",
    ".blf": "Vector BLF",
    ".mf4": "ASAM MDF 4 (needs the mf4 extra: asammdf)",
}
TABLE_FORMATS = {
    ".csv": "CSV",
    ".parquet": "Apache Parquet (pyarrow)",
    ".mf4": "ASAM MDF 4, a channel group per message (needs the mf4 extra: asammdf)",
}
#: a replayed gap between frames longer than this [s] is not stepped through tick by tick
MAX_GAP_S = 1.0
