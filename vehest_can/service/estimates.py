"""The ECU's estimates of a replay as a decoded table (``vehest-can replay LOG --table FILE``).

One row per ECU frame the replay produced, decoded through the DBCs (cantools, raw numbers for
enumerated signals): its time on the log's clock (the SIM_Sync frame that stepped it, or the tick
of a timestamp-paced log), the ECU tick, bus, frame ID and message, then one column per signal of
every message the ECU sends, named ``Message.Signal`` (empty where the row is another message).
The format is the file's extension:

* ``.csv``: one header line, then the rows (empty cells for other messages' signals);
* ``.parquet``: the same columns (nulls for other messages' signals, signal units as field
  metadata), through pyarrow, written batch by batch;
* ``.mf4``: ASAM MDF 4 through asammdf (the ``mf4`` extra): one channel group per message with
  its own time base (seconds since the header's start time, the log time of the first frame of
  the replay), channels ``Message.Signal`` with their DBC units and ``Message.tick``.

All three are written as the replay goes, so memory stays bounded (asammdf keeps appended
samples in a temporary file until it saves).
"""
from __future__ import annotations

import csv
from datetime import UTC, datetime
from pathlib import Path

import numpy as np

from ..bus.formats import TABLE_FORMATS
from ..bus.frames import BUSES, database
from ..bus.log import check_output_path

KEYS = ("time", "tick", "bus", "frame_id", "message")


def check_table_path(path: str | Path) -> Path:
    """A path --table can write, the library of its format installed."""
    return check_output_path(path, TABLE_FORMATS, "table", {
        ".parquet": ("pyarrow", "pip install pyarrow"), ".mf4": ("asammdf", "pip install 'vehest-can[mf4]'")})


class EstimateTable:
    """Rows in with :meth:`write` (ECU frames, their ticks and log times), the file done by :meth:`close`."""

    def __init__(self, path: str | Path, frame_ids):
        self.path = check_table_path(path)
        self.kind = self.path.suffix.lower()
        self.messages = {}  # frame ID -> (bus, cantools message)
        for fid in sorted(frame_ids):
            for bus in BUSES:
                try:
                    self.messages[fid] = (bus, database(bus).get_message_by_frame_id(fid))
                    break
                except KeyError:
                    continue
        self._ids = np.array(sorted(self.messages), dtype=np.uint32)
        self.columns = [f"{m.name}.{s.name}" for _, m in self.messages.values() for s in m.signals]
        self._col = {c: j for j, c in enumerate(self.columns)}
        self.rows = 0
        self.start: float | None = None
        if self.kind == ".csv":
            self._file = self.path.open("w", newline="")
            self._csv = csv.writer(self._file)
            self._csv.writerow([*KEYS, *self.columns])
        elif self.kind == ".parquet":
            import pyarrow as pa
            import pyarrow.parquet as pq

            units = {f"{m.name}.{s.name}": s.unit or "" for _, m in self.messages.values() for s in m.signals}
            self._schema = pa.schema(
                [pa.field("time", pa.float64()), pa.field("tick", pa.int64()), pa.field("bus", pa.string()),
                 pa.field("frame_id", pa.uint32()), pa.field("message", pa.string())]
                + [pa.field(c, pa.float64(), metadata={"unit": units[c]}) for c in self.columns])
            self._parquet = pq.ParquetWriter(str(self.path), self._schema)
        else:
            from asammdf import MDF

            self._mdf = MDF(version="4.10")
            self._groups: dict[int, int] = {}  # frame ID -> channel group index

    def write(self, frames: np.ndarray, ticks: np.ndarray, times: np.ndarray) -> None:
        """ECU frames (FRAME_DTYPE) with their ticks and log times, in the order the ECU sent them;
        frames of other IDs are not rows."""
        keep = np.flatnonzero(np.isin(frames["id"], self._ids))
        if not len(keep):
            return
        frames, ticks, times = frames.take(keep), np.asarray(ticks)[keep], np.asarray(times, np.float64)[keep]
        if self.start is None:
            self.start = float(times[0])
        ids = frames["id"]
        n = len(frames)
        self.rows += n
        value = np.zeros((n, len(self.columns)))
        present = np.zeros((n, len(self.columns)), dtype=bool)
        for fid in np.unique(ids):
            fid = int(fid)
            _, msg = self.messages[fid]
            at = np.flatnonzero(ids == fid)
            names = [s.name for s in msg.signals]
            values = np.empty((len(at), len(names)))
            for i, f in enumerate(frames.take(at)):
                d = msg.decode(bytes(f["data"][: f["len"]]), decode_choices=False)
                assert isinstance(d, dict)  # one message, not a container
                values[i] = np.array([d[n] for n in names], dtype=np.float64)
            if self.kind == ".mf4":
                self._write_mf4(fid, msg, values, ticks[at], times[at])
                continue
            cols = np.array([self._col[f"{msg.name}.{n}"] for n in names])
            value[np.ix_(at, cols)] = values
            present[np.ix_(at, cols)] = True
        if self.kind == ".csv":
            for i in range(n):
                fid = int(ids[i])
                bus, msg = self.messages[fid]
                cells = [repr(float(v)) if p else "" for v, p in zip(value[i], present[i])]
                self._csv.writerow([repr(float(times[i])), int(ticks[i]), bus, f"0x{fid:03X}", msg.name, *cells])
        elif self.kind == ".parquet":
            import pyarrow as pa

            data = [pa.array(times, pa.float64()), pa.array(np.asarray(ticks).astype(np.int64)),
                    pa.array([self.messages[int(i)][0] for i in ids]), pa.array(ids.astype(np.uint32)),
                    pa.array([self.messages[int(i)][1].name for i in ids])]
            data += [pa.array(value[:, j], pa.float64(), mask=~present[:, j]) for j in range(len(self.columns))]
            self._parquet.write_batch(pa.record_batch(data, schema=self._schema))

    def _write_mf4(self, fid: int, msg, values: np.ndarray, ticks: np.ndarray, times: np.ndarray) -> None:
        from asammdf import Signal

        assert self.start is not None
        rel = np.asarray(times, np.float64) - self.start
        if fid in self._groups:
            self._mdf.extend(self._groups[fid], [(rel, None), *((values[:, j], None) for j in range(values.shape[1])),
                                                 (ticks.astype(np.int64), None)])
            return
        sigs = [Signal(values[:, j], rel, name=f"{msg.name}.{s.name}", unit=s.unit or "")
                for j, s in enumerate(msg.signals)]
        sigs.append(Signal(ticks.astype(np.int64), rel, name=f"{msg.name}.tick"))
        self._groups[fid] = self._mdf.append(sigs, acq_name=msg.name, comment=f"{msg.name} (0x{fid:03X})")

    def close(self) -> None:
        if self.kind == ".csv":
            self._file.close()
        elif self.kind == ".parquet":
            self._parquet.close()
        else:
            if self.start is not None:
                self._mdf.header.start_time = datetime.fromtimestamp(self.start, UTC)
            self._mdf.save(str(self.path), overwrite=True)
            self._mdf.close()
