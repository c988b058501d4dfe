"""Session logs that other tools read correctly: absolute time, Tx/Rx, one channel per bus, every
format python-can writes for CAN FD; checked with can-utils' log2asc, cantools and asammdf."""
import json
import shutil
import subprocess
import sys

import can
import pytest

from vehest_can.bus.frames import TICK_S, database, sent_by
from vehest_can.bus.log import FORMATS, SessionLog, check_log_path, read_log
from vehest_can.errors import ConfigError
from vehest_can.paths import dbc_path
from vehest_can.sim.session import run_inprocess
from vehest_can.systems import registered
from vehest_can.systems.ecu import Ecu

EPOCH = 1764620000.25  # 2025-12-01 20:13:20.25 UTC
ECU_IDS = sent_by({"VEHEST"})


@pytest.fixture(scope="module")
def session():
    """A chassis session in process: frames of both buses (CHS on ch; the ECU on pt and ch)."""
    tf = next(s for s in registered() if s.name == "tireforce")
    sc = tf.load(sorted(tf.scenario_dir().glob("*.toml"))[0])
    return run_inprocess(tf.car(sc, 0.3), Ecu())


def write(session, path, **kw):
    with SessionLog(path, {"VEHEST"}, epoch=EPOCH, **kw) as log:
        for m in session.messages():
            log.on_message_received(m)
    return log


def bus_ids(bus):
    return {m.frame_id for m in database(bus).messages}


def test_candump_log_absolute_time_direction_channels(session, tmp_path):
    write(session, tmp_path / "s.log")
    msgs = read_log(tmp_path / "s.log")
    assert len(msgs) == len(session.frames)
    assert msgs[0].timestamp == pytest.approx(EPOCH + session.frame_tick[0] * TICK_S, abs=1e-6)
    assert msgs[-1].timestamp == pytest.approx(EPOCH + session.frame_tick[-1] * TICK_S, abs=1e-6)
    assert {m.channel for m in msgs} == {"pt", "ch"}
    for m in msgs:
        assert m.is_rx == (m.arbitration_id not in ECU_IDS)   # the logging node's own frames are Tx
        assert m.arbitration_id in bus_ids(m.channel)          # each frame on its own bus
    meta = json.loads((tmp_path / "s.log.json").read_text())
    assert meta["epoch"] == EPOCH and meta["tick_s"] == TICK_S and meta["tx_nodes"] == ["VEHEST"]


@pytest.mark.skipif(shutil.which("log2asc") is None, reason="log2asc (can-utils) not installed here; "
                    ".ci/apt-packages.txt installs it in CI")
def test_log2asc_gives_one_header_and_the_right_times(session, tmp_path):
    write(session, tmp_path / "s.log")
    subprocess.run(["log2asc", "-I", str(tmp_path / "s.log"), "-O", str(tmp_path / "s.asc"), "pt", "ch"], check=True)
    text = (tmp_path / "s.asc").read_text()
    assert text.count("date ") == 1 and text.count("base hex") == 1
    # log2asc's date line has whole seconds, and its times count from the first frame
    msgs = list(can.ASCReader(str(tmp_path / "s.asc"), relative_timestamp=False))
    assert len(msgs) == len(session.frames)
    assert msgs[0].timestamp == int(EPOCH)
    span = (session.frame_tick[-1] - session.frame_tick[0]) * TICK_S
    assert msgs[-1].timestamp - msgs[0].timestamp == pytest.approx(span, abs=1e-6)
    assert {m.channel for m in msgs} == {0, 1}  # pt, ch: log2asc numbers the interfaces as given
    assert all(m.is_rx == (m.arbitration_id not in ECU_IDS) for m in msgs)


def test_cantools_decodes_each_bus_with_its_dbc(session, tmp_path):
    log = write(session, tmp_path / "s.log", per_bus=True)
    for bus in ("pt", "ch"):
        path = log.paths[bus]
        assert path.name == f"s-{bus}.log"
        lines = path.read_text().splitlines()
        assert lines and all(f" {bus} " in line for line in lines)
        out = subprocess.run([sys.executable, "-m", "cantools", "decode", "--single-line", str(dbc_path(bus))],
                             input="\n".join(lines) + "\n", capture_output=True, text=True, check=True).stdout
        decoded = out.splitlines()
        assert len(decoded) == len(lines)
        assert not [d for d in decoded if "Unknown frame id" in d]
        assert all(" :: " in d for d in decoded)


@pytest.mark.parametrize("ext", [".asc", ".blf", ".mf4"])
def test_every_format_reads_back_with_time_direction_channel(session, tmp_path, ext):
    if ext == ".mf4":
        pytest.importorskip("asammdf", reason="MF4 needs the mf4 extra (asammdf)")
    write(session, tmp_path / f"s{ext}")
    kw = {"relative_timestamp": False} if ext == ".asc" else {}
    reader = can.ASCReader(str(tmp_path / "s.asc"), **kw) if ext == ".asc" else can.LogReader(str(tmp_path / f"s{ext}"))
    msgs = sorted(reader, key=lambda m: m.timestamp)
    assert len(msgs) == len(session.frames)
    assert msgs[0].timestamp == pytest.approx(EPOCH, abs=1e-3)
    assert msgs[-1].timestamp == pytest.approx(EPOCH + session.frame_tick[-1] * TICK_S, abs=1e-3)
    first = {"pt": 1, "ch": 2} if ext == ".mf4" else {"pt": 0, "ch": 1}  # python-can's numbering
    for m in msgs:
        assert m.is_fd and m.is_rx == (m.arbitration_id not in ECU_IDS)
        assert m.arbitration_id in bus_ids("pt" if m.channel == first["pt"] else "ch")


def test_asammdf_decodes_the_mf4_with_both_dbcs(session, tmp_path):
    asammdf = pytest.importorskip("asammdf", reason="MF4 needs the mf4 extra (asammdf)")
    write(session, tmp_path / "s.mf4")
    mdf = asammdf.MDF(str(tmp_path / "s.mf4"))
    decoded = mdf.extract_bus_logging({"CAN": [(str(dbc_path("pt")), 1), (str(dbc_path("ch")), 2)]})
    names = {ch.name for g in decoded.groups for ch in g.channels}
    assert {"SkfmecQ_Valid", "DkfT_ShaftTorque"} <= names  # a ch and a pt signal
    sig = decoded.get("SkfmecQ_Valid")
    start = decoded.header.start_time.timestamp()
    assert start + sig.timestamps[0] == pytest.approx(EPOCH, abs=0.01)  # a sane time base
    assert start + sig.timestamps[-1] == pytest.approx(EPOCH + session.frame_tick[-1] * TICK_S, abs=0.01)


@pytest.mark.parametrize("per_bus", [False, True])
def test_mf4_sources_are_the_buses_and_the_first_frame_is_at_the_start_time(session, tmp_path, per_bus):
    """asammdf lists each bus as the source of its frames (python-can's writer leaves the source name empty),
    and the header's start time is the first frame's time (python-can's: when the file was opened)."""
    asammdf = pytest.importorskip("asammdf", reason="MF4 needs the mf4 extra (asammdf)")
    log = write(session, tmp_path / "s.mf4", per_bus=per_bus)
    frames = 0
    for path in dict.fromkeys(log.paths.values()):
        mdf = asammdf.MDF(str(path))
        groups = [g for g in mdf.groups if g.channel_group.acq_source is not None]
        assert groups and all(g.channel_group.acq_source.name in ("pt", "ch") for g in groups)
        for i, g in enumerate(mdf.groups):
            if "CAN_DataFrame" not in [c.name for c in g.channels]:
                continue
            bus = g.channel_group.acq_source.name
            assert mdf.get("CAN_DataFrame", i).source.name == bus
            channel = mdf.get("CAN_DataFrame.BusChannel", i).samples
            ids = mdf.get("CAN_DataFrame.ID", i).samples
            assert set(channel) <= {("pt", "ch").index(bus) + 1} and set(ids) <= bus_ids(bus)
            frames += len(ids)
        first = [m for m in session.messages() if per_bus is False or m.arbitration_id in bus_ids(path.stem[-2:])][0]
        start = mdf.header.start_time.timestamp()
        assert start == pytest.approx(EPOCH + first.timestamp, abs=1e-6)
        decoded = mdf.extract_bus_logging({"CAN": [(str(dbc_path("pt")), 1), (str(dbc_path("ch")), 2)]})
        msg = database("pt" if first.arbitration_id in bus_ids("pt") else "ch").get_message_by_frame_id(
            first.arbitration_id)
        assert decoded.get(msg.signals[0].name).timestamps[0] == pytest.approx(0.0, abs=1e-6)  # at the start
        assert decoded.header.start_time.timestamp() == pytest.approx(start, abs=1e-6)
    assert frames == len(session.frames)


def test_bad_log_paths_are_clear_errors(tmp_path):
    with pytest.raises(ConfigError, match="unknown log format '.xyz'"):
        check_log_path(tmp_path / "x.xyz")
    with pytest.raises(ConfigError, match="unknown log format"):
        check_log_path(tmp_path / "x.trc")  # python-can's TRC writer drops CAN FD frames
    (tmp_path / "d.log").mkdir()
    with pytest.raises(ConfigError, match="is a folder"):
        check_log_path(tmp_path / "d.log")
    with pytest.raises(ConfigError, match="does not exist"):
        check_log_path(tmp_path / "nope" / "x.log")
    assert set(FORMATS) == {".log", ".asc", ".blf", ".mf4"}
