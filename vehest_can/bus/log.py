"""CAN log files, written and read.

Written (:class:`SessionLog`): a session's frames as other tools expect them, in the format of the
file's extension through python-can's writers (``.log`` candump -L, ``.asc``, ``.blf``;
``.mf4`` through asammdf, the ``mf4`` extra: :class:`Mf4Log`). Not ``.trc``: python-can's TRC writer drops CAN FD
frames, and both buses are CAN FD; not ``.csv``: it keeps no channel, direction or FD flag.

* absolute time: the session starts at a wall-clock epoch (``time.time()`` when its first frame
  is logged, minus that frame's session time) and advances by the session's own clock (simulated
  time in lockstep; in real time the wall clock, when the node sent or received the frame), like
  ``candump -l``; the epoch and the tick are recorded beside the log (``<log>.json``), so a
  lockstep log still maps back to ticks;
* direction: the frames the logging node sent are Tx (``is_rx=False``), the rest Rx;
* one channel per bus, named as the bus configuration names it (``pt``, ``ch``: the DBC a frame's
  ID belongs to); formats whose channels are numbers (ASC, BLF, MF4) write ``pt`` as 1 and
  ``ch`` as 2. One log with both channels, or one log per bus (``per_bus``: ``x.log`` becomes
  ``x-pt.log`` and ``x-ch.log``).

Read (:func:`read_log`): whatever python-can's ``LogReader`` reads; any reader's failure on a
malformed file is a :class:`ConfigError` naming the file, and so is a log without a data frame (an
empty file, or one whose lines the reader skips: python-can's text readers skip what they do not
recognise).
"""
from __future__ import annotations

import json
import mmap
import time
from collections.abc import Generator, Iterable, Iterator
from pathlib import Path
from typing import Any

import can
import numpy as np

from ..errors import ConfigError
from ..native import ffi, lib
from .formats import FORMATS  # what --log writes, by extension
from .frames import BUSES, FRAME_DTYPE, TICK_S, database, sent_by

#: formats whose channels are numbers: python-can counts those from 0 and writes 1, 2 ... (MF4
#: writes the number as given, so it gets the 1-based one itself)
_NUMBERED = {".asc": 0, ".blf": 0, ".mf4": 1}
MAX_EXT_ID = 0x1FFFFFFF


def bus_of_id() -> dict[int, str]:
    """Standard frame ID -> the bus (DBC) it belongs to; IDs are unique across the buses."""
    return {m.frame_id: b for b in BUSES for m in database(b).messages if not m.is_extended_frame}


def check_output_path(path: str | Path, formats: dict[str, str], what: str,
                      needs: dict[str, tuple[str, str]] | None = None) -> Path:
    """A path a verb can write a ``what`` (log, table) to: an extension of ``formats``, not a folder,
    in a folder that exists, and the library its format ``needs`` (extension -> module, how) installed."""
    path = Path(path)
    suffix = path.suffix.lower()
    if path.is_dir():
        raise ConfigError(f"{path}: is a folder, not a {what} file")
    if suffix not in formats:
        known = ", ".join(f"{k} ({v})" for k, v in formats.items())
        raise ConfigError(f"{path}: unknown {what} format {suffix or '(no extension)'!r}; the extension chooses one of "
                          f"{known}")
    if not path.parent.is_dir():
        raise ConfigError(f"{path}: folder {path.parent} does not exist")
    if suffix in (needs or {}):
        module, how = (needs or {})[suffix]
        try:
            __import__(module)
        except ImportError:
            raise ConfigError(f"{path}: {formats[suffix].split(' (')[0]} {what}s need {module}: {how}") from None
    return path


def check_log_path(path: str | Path) -> Path:
    """A path --log can write."""
    return check_output_path(path, FORMATS, "log", {".mf4": ("asammdf", "pip install 'vehest-can[mf4]'")})


def bus_log_path(path: Path, bus: str) -> Path:
    return path.with_name(f"{path.stem}-{bus}{path.suffix}")


class SessionLog(can.Listener):
    """A log of one node's view of a session (see the module). Messages come in with their session
    time in ``timestamp`` (seconds from the session's start); they are written with absolute time,
    their direction and their bus's channel."""

    def __init__(self, path: str | Path, nodes: Iterable[str], *, per_bus: bool = False,
                 epoch: float | None = None, default_bus: str = BUSES[0]):
        """`nodes`: the DBC nodes the logging process plays (their frames are Tx). Frames of an ID
        in no bus's DBC (the simulator's lockstep frames, unknown IDs) are logged on `default_bus`."""
        self.path = check_log_path(path)
        self.nodes = sorted(nodes)
        self.per_bus = per_bus
        self.epoch = epoch
        self.default_bus = default_bus
        self._sent = sent_by(frozenset(self.nodes))
        self._bus = bus_of_id()
        self._base = _NUMBERED.get(self.path.suffix.lower())
        self.paths = {b: bus_log_path(self.path, b) for b in BUSES} if per_bus else {b: self.path for b in BUSES}
        self._writers: dict[Path, can.Listener] = {}
        try:
            for p in dict.fromkeys(self.paths.values()):
                if p.suffix.lower() == ".mf4":
                    on = [b for b in BUSES if self.paths[b] == p]
                    self._writers[p] = Mf4Log(p, {BUSES.index(b) + (self._base or 0): b for b in on})
                else:
                    self._writers[p] = can.Logger(str(p))
        except (OSError, ValueError, ImportError) as exc:
            self.stop()
            raise ConfigError(f"{self.path}: cannot write the log ({exc})") from exc
        self.frames = 0

    def on_message_received(self, msg: can.Message) -> None:
        if self.epoch is None:
            self.epoch = time.time() - (msg.timestamp or 0.0)
        bus = self._bus.get(msg.arbitration_id, self.default_bus) if not msg.is_extended_id else self.default_bus
        out = can.Message(
            timestamp=self.epoch + (msg.timestamp or 0.0), arbitration_id=msg.arbitration_id,
            is_extended_id=msg.is_extended_id, is_remote_frame=msg.is_remote_frame, is_error_frame=msg.is_error_frame,
            is_fd=msg.is_fd, bitrate_switch=msg.bitrate_switch, error_state_indicator=msg.error_state_indicator,
            dlc=msg.dlc, data=msg.data, check=False,
            is_rx=msg.is_extended_id or msg.arbitration_id not in self._sent,
            channel=bus if self._base is None else BUSES.index(bus) + self._base,
        )
        self._writers[self.paths[bus]].on_message_received(out)
        self.frames += 1

    def metadata(self) -> dict:
        return {
            "format": FORMATS[self.path.suffix.lower()],
            "epoch": self.epoch,
            "epoch_utc": time.strftime("%Y-%m-%dT%H:%M:%S", time.gmtime(self.epoch)) if self.epoch else None,
            "time": "epoch + session time (simulated time in lockstep, the wall clock in real time)",
            "tick_s": TICK_S,
            "tx_nodes": self.nodes,
            "channels": {b: (b if self._base is None else BUSES.index(b) + self._base) for b in BUSES},
            "files": {b: str(p) for b, p in self.paths.items()},
            "frames": self.frames,
        }

    def stop(self) -> None:
        for w in self._writers.values():
            w.stop()
        if self._writers and self.epoch is not None:
            self.path.with_name(self.path.name + ".json").write_text(json.dumps(self.metadata(), indent=2) + "\n")
        self._writers = {}

    def __enter__(self) -> SessionLog:
        return self

    def __exit__(self, *exc) -> None:
        self.stop()


class Mf4Log(can.Listener):
    """A CAN bus log in ASAM MDF 4, read by python-can's MF4Reader and asammdf's ``extract_bus_logging``:
    python-can's layout (channel groups ``CAN_DataFrame``, ``CAN_ErrorFrame``, ``CAN_RemoteFrame``, its
    record types), but one set of groups per bus, each with the bus's name as its acquisition source
    (``pt``, ``ch``: tools list signals by source), and the header's start time at the first frame's
    time, so the signals start at 0 (python-can's writer takes the moment the file is opened).
    Frames are appended in batches, not one ``extend`` per frame."""

    BATCH = 4096

    def __init__(self, path: str | Path, channels: dict[int, str]):
        """`channels`: BusChannel number -> bus name, the buses this file holds."""
        from can.io.mf4 import ERR_DTYPE, RTR_DTYPE, STD_DTYPE

        self.path = Path(path)
        self.channels = channels
        self._dtypes = (STD_DTYPE, ERR_DTYPE, RTR_DTYPE)
        self._mdf: Any = None  # asammdf's MDF, made at the first frame
        self._start = 0.0
        self._last = 0.0
        self._group = {ch: 3 * i for i, ch in enumerate(channels)}  # a bus's data group; error, remote next
        self._batch = {ch: (np.zeros(self.BATCH, STD_DTYPE), np.zeros(self.BATCH)) for ch in channels}
        self._n = dict.fromkeys(channels, 0)
        self._saved = False

    def _open(self, start: float) -> None:
        from datetime import UTC, datetime

        from asammdf import MDF, Signal, Source

        self._mdf = mdf = MDF(version="4.10")
        mdf.header.start_time = datetime.fromtimestamp(start, UTC)
        self._start = self._last = start
        for ch, bus in self.channels.items():
            source = Source(name=bus, path=f"CAN{ch}", comment=f"CAN FD bus {bus} (BusChannel {ch})",
                            source_type=Source.SOURCE_BUS, bus_type=Source.BUS_TYPE_CAN)
            for name, dtype in zip(("CAN_DataFrame", "CAN_ErrorFrame", "CAN_RemoteFrame"), self._dtypes):
                mdf.append(Signal(name=name, samples=np.array([], dtype=dtype), timestamps=np.array([], dtype="<f8"),
                                  source=source), acq_name=bus, acq_source=source)

    def on_message_received(self, msg: can.Message) -> None:
        ts = msg.timestamp or 0.0
        if self._mdf is None:
            self._open(ts)
        self._last = max(self._last, ts)  # a master channel never goes back (python-can's writer does the same)
        t = self._last - self._start
        ch = msg.channel if msg.channel in self._group else next(iter(self._group))
        if msg.is_error_frame or msg.is_remote_frame:
            kind = 1 if msg.is_error_frame else 2
            rec = np.zeros(1, self._dtypes[kind])
            self._fill(rec[0], "CAN_ErrorFrame" if kind == 1 else "CAN_RemoteFrame", msg, ch)
            self._mdf.extend(self._group[ch] + kind, [(np.array([t]), None), (rec, None)])
            return
        records, times = self._batch[ch]
        i = self._n[ch]
        records[i] = 0
        self._fill(records[i], "CAN_DataFrame", msg, ch)
        times[i] = t
        self._n[ch] = i + 1
        if i + 1 == self.BATCH:
            self._flush(ch)

    @staticmethod
    def _fill(rec, kind: str, msg: can.Message, ch: int) -> None:
        from can.util import len2dlc

        rec[f"{kind}.BusChannel"] = ch
        rec[f"{kind}.ID"] = msg.arbitration_id
        rec[f"{kind}.IDE"] = int(msg.is_extended_id)
        rec[f"{kind}.Dir"] = 0 if msg.is_rx else 1
        if kind == "CAN_RemoteFrame":
            rec[f"{kind}.DLC"] = msg.dlc
            return
        data = bytes(msg.data or b"")[:64]
        rec[f"{kind}.DataLength"] = len(data)
        rec[f"{kind}.DataBytes"][: len(data)] = np.frombuffer(data, np.uint8)
        rec[f"{kind}.DLC"] = len2dlc(len(data)) if msg.is_fd else msg.dlc
        rec[f"{kind}.EDL"] = int(msg.is_fd)
        rec[f"{kind}.BRS"] = int(msg.is_fd and msg.bitrate_switch)
        rec[f"{kind}.ESI"] = int(msg.is_fd and msg.error_state_indicator)

    def _flush(self, ch: int) -> None:
        n = self._n[ch]
        if n and self._mdf is not None:
            records, times = self._batch[ch]
            self._mdf.extend(self._group[ch], [(times[:n].copy(), None), (records[:n].copy(), None)])
        self._n[ch] = 0

    def stop(self) -> None:
        if self._saved:
            return
        self._saved = True
        if self._mdf is None:  # no frame: an empty log, starting now
            self._open(time.time())
        for ch in self._group:
            self._flush(ch)
        assert self._mdf is not None
        self._mdf.save(self.path, overwrite=True, compression=2)
        self._mdf.close()
        self._mdf = None


def check_log_file(path: str | Path) -> Path:
    """A log to read: an existing regular file (a folder or a missing path is a ConfigError)."""
    path = Path(path)
    if path.is_dir():
        raise ConfigError(f"{path}: is a folder, not a log file")
    if not path.is_file():
        raise ConfigError(f"{path}: no such log file")
    return path


def no_frames(path: Path) -> ConfigError:
    """The error of a log without a data frame."""
    what = "the file is empty" if path.stat().st_size == 0 else f"nothing in it reads as a {path.suffix or 'CAN'} frame"
    return ConfigError(f"{path}: no CAN data frames in this log ({what})")


def iter_log(path: str | Path) -> Generator[can.Message, None, None]:
    """The data frames of a log, one by one (error and remote frames skipped); a malformed file,
    a log without a data frame or an ID beyond 29 bits is a ConfigError."""
    path = check_log_file(path)
    data_frames = 0
    try:
        for i, m in enumerate(can.LogReader(str(path))):
            if m.is_error_frame or m.is_remote_frame:
                continue
            if not 0 <= m.arbitration_id <= (MAX_EXT_ID if m.is_extended_id else 0x7FF) or len(m.data) > 64:
                raise ConfigError(f"{path}: frame {i + 1}: ID 0x{m.arbitration_id:X} or length {len(m.data)} "
                                  f"does not fit a CAN frame ({'29' if m.is_extended_id else '11'}-bit ID, <= 64 bytes)")
            data_frames += 1
            yield m
        if not data_frames:
            raise no_frames(path)
    except ConfigError:
        raise
    except Exception as exc:  # noqa: BLE001 - third-party readers of an untrusted file raise anything
        # (BLFParseError, sqlite3.DatabaseError, asammdf's MdfException, struct.error, zlib.error ...);
        # the cause stays chained for --debug
        raise ConfigError(f"{path}: not a readable CAN log ({type(exc).__name__}: {exc})") from exc


def check_log_frames(path: str | Path) -> Path:
    """A log to read that holds a data frame (:func:`iter_log`'s errors, found before a run starts)."""
    frames = iter_log(path)
    next(frames)
    frames.close()
    return Path(path)


def read_log(path: str | Path) -> list[can.Message]:
    return list(iter_log(path))


#: frames per batch of :func:`iter_log_arrays` (18 MB of frames)
CHUNK_FRAMES = 1 << 18
_BLOCK_BYTES = 16 << 20


def iter_log_arrays(path: str | Path, chunk: int = CHUNK_FRAMES, progress=None,
                    copy: bool = True, buffers: int = 1) -> Iterator[tuple[np.ndarray, np.ndarray]]:
    """The data frames of a log in batches of up to `chunk`: (FRAME_DTYPE array, timestamps),
    in file order, in bounded memory. candump -L (``.log``) is parsed in C (``vh_candump_parse``,
    the rules of python-can's reader); other formats go through python-can's readers.
    `progress(done, total)` is called with bytes read. With copy=False a batch is valid only until
    the next one is asked for (no copy of each batch); with `buffers` > 1, until `buffers` - 1 more
    are (candump -L: the batches rotate through that many buffers; other formats make new arrays)."""
    path = check_log_file(path)
    total = path.stat().st_size
    if path.suffix.lower() != ".log":
        batch: list[can.Message] = []
        for m in iter_log(path):
            batch.append(m)
            if len(batch) == chunk:
                yield messages_to_arrays(batch)
                batch = []
        if batch:
            yield messages_to_arrays(batch)
        if progress:
            progress(total, total)
        return
    ring = [(np.zeros(chunk, dtype=FRAME_DTYPE), np.zeros(chunk, dtype=np.float64)) for _ in range(max(1, buffers))]
    c_ring = [(ffi.cast("vh_frame_t *", ffi.from_buffer(fr)), ffi.cast("double *", ffi.from_buffer(t))) for fr, t in ring]
    turn = 0
    n_out, used, lines, skipped = (ffi.new("size_t *") for _ in range(4))
    if total == 0:
        raise no_frames(path)
    line_no = 0  # lines before `pos`
    data_frames = 0
    pos = dropped = 0
    # The file mapped, not read: the C parser reads the page cache in place (no copies into bytes
    # objects, no fresh pages to fault in), and the pages behind it are dropped from this
    # process's resident set as it goes (they stay in the page cache), so memory stays a batch.
    with path.open("rb") as f, mmap.mmap(f.fileno(), 0, access=mmap.ACCESS_READ) as mm:
        mm.madvise(mmap.MADV_SEQUENTIAL)
        view = ffi.from_buffer(mm)
        try:
            while True:
                frames, ts = ring[turn]
                c_frames, c_ts = c_ring[turn]
                rc = lib.vh_candump_parse(view + pos, total - pos, 1, c_frames, c_ts, chunk, n_out, used, lines, skipped)
                line_no += lines[0]
                if rc != lib.VH_OK:
                    bad = mm[pos + used[0]:pos + used[0] + 200].split(b"\n", 1)[0][:80]
                    raise ConfigError(f"{path}: line {line_no + 1}: not a candump -L frame: "
                                      f"{bad.decode('utf-8', 'replace')!r}")
                pos += used[0]
                data_frames += n_out[0]
                if not data_frames and n_out[0] < chunk:  # the whole file parsed: nothing in it
                    raise no_frames(path)
                if pos - dropped >= _BLOCK_BYTES or pos == total:
                    end = pos - pos % mmap.PAGESIZE
                    if end > dropped:
                        mm.madvise(mmap.MADV_DONTNEED, dropped, end - dropped)
                        dropped = end
                if progress:
                    progress(pos, total)
                if n_out[0]:
                    yield ((frames[: n_out[0]].copy(), ts[: n_out[0]].copy()) if copy
                           else (frames[: n_out[0]], ts[: n_out[0]]))
                    turn = (turn + 1) % len(ring)
                if n_out[0] < chunk:  # the rest of the file parsed
                    return
        finally:
            ffi.release(view)  # before the map closes


def messages_to_arrays(messages: list[can.Message]) -> tuple[np.ndarray, np.ndarray]:
    """Data frames (error and remote frames dropped) as a FRAME_DTYPE array and their timestamps."""
    msgs = [m for m in messages if not (m.is_error_frame or m.is_remote_frame)]
    out = np.zeros(len(msgs), dtype=FRAME_DTYPE)
    if not msgs:
        return out, np.zeros(0)
    data = [bytes(m.data or b"")[:64] for m in msgs]
    out["id"] = np.fromiter((m.arbitration_id for m in msgs), dtype=np.uint32, count=len(msgs))
    out["len"] = np.fromiter(map(len, data), dtype=np.uint8, count=len(msgs))
    out["flags"] = np.fromiter(((lib.VH_FRAME_EXT if m.is_extended_id else 0) | (lib.VH_FRAME_FD if m.is_fd else 0)
                                | (lib.VH_FRAME_BRS if m.bitrate_switch else 0) for m in msgs),
                               dtype=np.uint8, count=len(msgs))
    out["data"] = np.frombuffer(b"".join(d.ljust(64, b"\0") for d in data), dtype=np.uint8).reshape(-1, 64)
    return out, np.fromiter((m.timestamp for m in msgs), dtype=np.float64, count=len(msgs))
