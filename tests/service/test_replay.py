"""The batched replay (candump -L parsed in C, the ECU fed in batches, compared as it goes) gives
what the message-by-message replay gave, on lockstep and timestamp-paced logs; a time gap is not
stepped through; the C candump reader reads what python-can's reader reads."""
import random
import resource

import can
import numpy as np
import pytest
from frames_oracle import same_frame

from vehest_can.bus import lockstep
from vehest_can.bus.frames import TICK_S, to_message
from vehest_can.bus.frames import frame_id as frame_id_of
from vehest_can.bus.log import SessionLog, iter_log_arrays, read_log
from vehest_can.errors import ConfigError
from vehest_can.service.replay import ECU_TX, Replayer, replay, replay_file
from vehest_can.sim.powertrain import powertrain_car
from vehest_can.sim.session import run_inprocess
from vehest_can.systems.driveline.scenario import load_driveline_scenario
from vehest_can.systems.ecu import Ecu


def reference_replay(messages):
    """The replay as it was, one python-can message at a time (the independent reference)."""
    ecu = Ecu()
    produced = []
    logged = [m for m in messages if m.arbitration_id in ECU_TX and not m.is_extended_id]
    inputs = [m for m in messages if not (m.arbitration_id in ECU_TX and not m.is_extended_id)]
    if any(lockstep.is_sync(m) for m in inputs):
        for m in inputs:
            if not lockstep.is_sync(m):
                ecu.rx(m)
                continue
            tick, cmd = lockstep.decode_sync(m)
            if cmd == lockstep.RESET:
                ecu.reset()
            elif cmd == lockstep.STEP:
                produced += ecu.step(timestamp=tick * TICK_S)
    else:
        inputs.sort(key=lambda m: m.timestamp)
        t0 = inputs[0].timestamp if inputs else 0.0
        k = 0
        for m in inputs:
            while t0 + k * TICK_S < m.timestamp - 1e-7:
                produced += ecu.step(timestamp=k * TICK_S)
                k += 1
            ecu.rx(m)
        if inputs:
            produced += ecu.step(timestamp=k * TICK_S)
    return produced, logged, ecu.counters()


def wire(msgs):
    return [(m.arbitration_id, m.is_extended_id, m.is_fd, bytes(m.data)) for m in msgs]


@pytest.fixture(scope="module")
def session():
    return run_inprocess(powertrain_car(load_driveline_scenario("launch_2nd"), duration_s=1.0), Ecu())


def lockstep_messages(session):
    """The session as a lockstep log: RESET, then per tick the car's frames, SIM_Sync, the ECU's."""
    out = [lockstep.sync_message(lockstep.RESET_TICK_BASE, lockstep.RESET)]
    msgs = list(session.messages())
    i = 0
    for k in range(len(session.truth)):
        while i < len(msgs) and session.frame_tick[i] == k and msgs[i].arbitration_id not in ECU_TX:
            out.append(msgs[i])
            i += 1
        sync = lockstep.sync_message(k)
        sync.timestamp = k * TICK_S
        out.append(sync)
        while i < len(msgs) and session.frame_tick[i] == k:
            out.append(msgs[i])
            i += 1
    return out


def write(path, msgs, nodes=("SIM", "DLS")):
    with SessionLog(path, set(nodes), epoch=1764620000.0) as log:
        for m in msgs:
            log.on_message_received(m)


def test_lockstep_log_replays_identically_to_the_reference(session, tmp_path):
    msgs = lockstep_messages(session)
    write(tmp_path / "ls.log", msgs)
    ref_prod, ref_logged, ref_counters = reference_replay(read_log(tmp_path / "ls.log"))
    assert len(ref_prod) == len(ref_logged) > 1000 and wire(ref_prod) == wire(ref_logged)
    listed = replay(read_log(tmp_path / "ls.log"))
    assert wire(listed.produced) == wire(ref_prod) and listed.identical and listed.paced_by == "sync"
    assert [m.timestamp for m in listed.produced] == [m.timestamp for m in ref_prod]
    streamed = replay_file(tmp_path / "ls.log")
    assert streamed.identical is True and streamed.n_produced == len(ref_prod) and streamed.counters == ref_counters
    # an old log (simulated time from 0, every frame on vcan0, all Rx) replays the same
    with can.Logger(str(tmp_path / "old.log")) as w:
        for m in msgs:
            m.channel = "vcan0"
            w.on_message_received(m)
    assert replay_file(tmp_path / "old.log").identical is True


def test_a_changed_ecu_frame_is_found(session, tmp_path):
    msgs = lockstep_messages(session)
    ecu_at = [i for i, m in enumerate(msgs) if m.arbitration_id in ECU_TX]
    bad = msgs[ecu_at[777]]
    bad.data = bytes([bad.data[0] ^ 1]) + bytes(bad.data[1:])
    write(tmp_path / "bad.log", msgs)
    r = replay_file(tmp_path / "bad.log")
    assert r.identical is False and r.first_difference() == 777


@pytest.mark.parametrize("chunk, swapped", [(100, False), (1 << 18, True)])
def test_timestamp_paced_log_equals_the_reference(session, tmp_path, chunk, swapped):
    """A capture without SIM_Sync (real-time-like jitter; with `swapped`, neighbours out of order in
    the file), in batches small and large: the same ECU frames, counters and tick times as the
    reference. (Out-of-order frames are sorted within a batch; one older than the batch before it
    is handed in at once and counted: loggers write in time order, so that is the rare case.)"""
    rng = random.Random(4)
    msgs = [m for m in session.messages() if m.arbitration_id not in ECU_TX]
    for m in msgs:
        m.timestamp += rng.uniform(0, 0.0004)
    if swapped:
        for i in range(5, len(msgs) - 1, 97):
            msgs[i], msgs[i + 1] = msgs[i + 1], msgs[i]
    else:
        msgs.sort(key=lambda m: m.timestamp)
    write(tmp_path / "ts.log", msgs)
    ref_prod, _, ref_counters = reference_replay(read_log(tmp_path / "ts.log"))
    r = Replayer(keep=True)
    for frames, ts in iter_log_arrays(tmp_path / "ts.log", chunk=chunk):
        r.feed(frames, ts)
    res = r.finish()
    assert res.paced_by == "timestamps" and res.identical is None and res.out_of_order == 0
    assert len(ref_prod) > 1000 and wire(res.produced) == wire(ref_prod) and res.counters == ref_counters
    assert [round(m.timestamp, 9) for m in res.produced] == [round(m.timestamp, 9) for m in ref_prod]


def test_a_frame_older_than_the_batch_before_is_counted(tmp_path):
    msgs = [can.Message(timestamp=t, arbitration_id=0x100, is_extended_id=False, data=b"\0" * 16, is_fd=True)
            for t in (0.0, 0.01, 0.02, 0.005)]
    write(tmp_path / "ooo.log", msgs)
    r = Replayer()
    for frames, ts in iter_log_arrays(tmp_path / "ooo.log", chunk=3):
        r.feed(frames, ts)
    assert r.finish().out_of_order == 1


def test_an_hour_gap_is_not_stepped_tick_by_tick(tmp_path):
    """#15: 1,001 frames with a 1 h gap took 50 s and 2.4 GB. Now: 1 s of idle ticks, then a jump."""
    sensors = [m for m in run_inprocess(powertrain_car(load_driveline_scenario("launch_2nd"), duration_s=0.5),
                                        Ecu()).messages() if m.arbitration_id not in ECU_TX][:1001]
    for m in sensors[500:]:
        m.timestamp += 3600.0
    write(tmp_path / "gap.log", sensors)
    rss0 = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    r = replay_file(tmp_path / "gap.log")
    assert r.gaps == 1 and r.idle_ticks_skipped == pytest.approx(3600 / TICK_S - 2000, abs=600)
    assert r.ticks < 2000 + 2 * len(sensors)  # the ECU stepped 1 s of the gap, not an hour
    assert resource.getrusage(resource.RUSAGE_SELF).ru_maxrss - rss0 < 200_000  # kB
    listed = replay(read_log(tmp_path / "gap.log"))
    assert listed.gaps == 1 and len(listed.produced) == listed.n_produced < 20_000
    # the ECU timed its inputs out in the gap, as it would have
    assert r.counters["timeout"] > 0


CANDUMP = """\
(1764620000.000000) pt 100#0102 R
(1764620000.000500) pt 1ABCDEF0#DEADBEEF T

(1764620000.001000) ch 110##1CB00B0FFC4FFCAFF2A00FFFFE618DD18E918EC180600FBFFF5FFFAFFFF1F0000 R
(1764620000.001500)   can0  7FF##0 T
(1764620000.002000) can0 123#R
(1764620000.002500) can0 20000080#0000000000000000
(1764620000.003000) can0 00000123#
  (1764620000.0035) vcan0 180#11223344556677
(1764620000.004000) can0 124#R R
(1764620000.004500)\tcan0\t125#00
"""


def test_the_c_candump_reader_reads_what_python_can_reads(tmp_path):
    (tmp_path / "mix.log").write_text(CANDUMP)
    ref = read_log(tmp_path / "mix.log")  # python-can: remote and error frames dropped
    (frames, ts), = list(iter_log_arrays(tmp_path / "mix.log"))
    got = [to_message(f, timestamp=float(t)) for f, t in zip(frames, ts)]
    assert len(got) == len(ref) == 7
    assert all(same_frame(a, b) and a.timestamp == b.timestamp and a.bitrate_switch == b.bitrate_switch
               for a, b in zip(got, ref))


@pytest.mark.parametrize("line, where", [
    ("(1.0) can0 123456789#00", "line 2"),          # an ID beyond 29 bits
    ("(1.0) can0 FFF#00", "line 2"),                # an 11-bit ID above 0x7FF
    ("(1.0) can0 123#0", "line 2"),                 # half a byte
    ("(1.0) can0 123#" + "00" * 65, "line 2"),      # more than 64 bytes
    ("(nan) can0 123#00", "line 2"),
    ("1.0 can0 123#00", "line 2"),
    ("(1.0) can0 123", "line 2"),
    ("\xff\xfe garbage", "line 2"),
    # the field count, as python-can counts it (its reader raises on each of these)
    ("(1.0) can0 R", "line 2"),
    ("(1.0) 123#00 R", "line 2"),
    ("(1.0) can0 123#00 xyz", "line 2"),
    ("(1.0) can0 123#00 extra R", "line 2"),
    ("(1.0) a b 123#00 R", "line 2"),
    ("(1.0) can0 123#R junk", "line 2"),
    ("(1.0) can0 12 3#00", "line 2"),
    ("(1.0) can0 123#00\tR", "line 2"),
])
def test_malformed_candump_lines_are_errors_with_the_line(tmp_path, line, where):
    (tmp_path / "bad.log").write_bytes(("(0.5) can0 100#00\n" + line + "\n").encode("latin-1"))
    with pytest.raises(ConfigError, match=where):
        replay_file(tmp_path / "bad.log")


def test_replay_memory_is_bounded_by_the_batch(tmp_path, session):
    """The streamed replay holds a batch, not the log: its result keeps no frames."""
    write(tmp_path / "ls.log", lockstep_messages(session))
    r = replay_file(tmp_path / "ls.log")
    assert r.produced == [] and r.logged == [] and r.n_logged == r.n_produced > 0
    assert np.isfinite(r.ticks)


def test_streams_far_apart_are_not_compared(session, tmp_path, monkeypatch):
    """A log whose ECU frames cannot line up with the replay's (here: one ECU frame in a sensor
    capture): once one side is COMPARE_WINDOW frames ahead, the replay stops holding frames and
    says DIFFERENT, where the comparison stopped."""
    from vehest_can.service import replay as replay_mod

    monkeypatch.setattr(replay_mod, "COMPARE_WINDOW", 50)
    msgs = [m for m in session.messages() if m.arbitration_id not in ECU_TX]
    ecu_frame = next(m for m in session.messages() if m.arbitration_id in ECU_TX)
    ecu_frame.timestamp = msgs[-1].timestamp
    write(tmp_path / "far.log", msgs + [ecu_frame])
    r = replay_file(tmp_path / "far.log")
    assert r.n_logged == 1 and r.n_produced > 1000
    assert r.identical is False and r.first_difference() in (0, 1)


def test_the_c_reader_rounds_timestamps_as_python_does(tmp_path):
    """The C reader's fast path for plain decimals (Clinger's: one exact division) and its strtod
    fallback give the double python-can's float() gives, for every shape of timestamp."""
    rng = random.Random(7)
    stamps = ["0", "1.", ".5", "0.1", "1764620000.000500", "1764620000.123456789", "9007199254740993.5",
              "123456789012345678", "1e3", "1.5E-3", "+2.5", "-0.25", "0.30000000000000004",
              "4.35" + "0" * 30, "0." + "0" * 21 + "1"]
    stamps += [f"{rng.randrange(10**10)}.{rng.randrange(10**6):06d}" for _ in range(300)]
    stamps += [f"{rng.random() * 10 ** rng.randrange(-5, 17):.{rng.randrange(0, 20)}f}" for _ in range(300)]
    (tmp_path / "ts.log").write_text("".join(f"({s}) can0 100#00\n" for s in stamps))
    (_, ts), = list(iter_log_arrays(tmp_path / "ts.log"))
    assert [float(t) for t in ts] == [float(s) for s in stamps] == [m.timestamp for m in read_log(tmp_path / "ts.log")]


# -- the estimates as a table (--table), read back with other libraries ----------------------------

def logged_estimates(path):
    """The ECU frames of a session log, decoded with cantools from the DBC files (the reference)."""
    import cantools

    from vehest_can.paths import dbc_path

    dbs = {b: cantools.database.load_file(str(dbc_path(b))) for b in ("pt", "ch")}
    out = []
    for m in read_log(path):
        if m.arbitration_id in ECU_TX and not m.is_extended_id:
            db = dbs["pt"] if m.arbitration_id in {x.frame_id for x in dbs["pt"].messages} else dbs["ch"]
            msg = db.get_message_by_frame_id(m.arbitration_id)
            out.append((m.timestamp, msg.name, msg.decode(bytes(m.data), decode_choices=False)))
    return out


@pytest.fixture(scope="module")
def lockstep_log(session, tmp_path_factory):
    path = tmp_path_factory.mktemp("table") / "ls.log"
    write(path, lockstep_messages(session))
    return path, logged_estimates(path)


@pytest.mark.parametrize("ext", [".csv", ".parquet"])
def test_the_table_holds_the_logged_estimates(lockstep_log, tmp_path, ext, capsys):
    """CSV and Parquet read back with pandas: a row per ECU frame of the log, in order, at the log's
    time, with the signals cantools decodes from the logged frame and nothing in other messages'."""
    pd = pytest.importorskip("pandas")
    from vehest_can.cli import main

    log, ref = lockstep_log
    assert main(["replay", str(log), "--table", str(tmp_path / f"est{ext}")]) == 0
    assert f"estimates: {len(ref)} rows written" in capsys.readouterr().out
    df = pd.read_csv(tmp_path / f"est{ext}") if ext == ".csv" else pd.read_parquet(tmp_path / f"est{ext}")
    assert len(df) == len(ref) > 1000 and len({name for _, name, _ in ref}) >= 2
    assert list(df["message"]) == [name for _, name, _ in ref]
    assert np.allclose(df["time"], [t for t, _, _ in ref], rtol=0, atol=1e-6)
    assert df["time"].iloc[0] > 1.7e9 and (np.diff(df["tick"]) >= 0).all()
    for i, (_, name, sig) in enumerate(ref):
        row = df.iloc[i]
        assert all(row[f"{name}.{k}"] == pytest.approx(v, abs=0) for k, v in sig.items()), (i, name)
        others = [c for c in df.columns if "." in c and not c.startswith(name + ".")]
        assert row[others].isna().all()
    if ext == ".parquet":
        import pyarrow.parquet as pq

        field = pq.read_schema(tmp_path / "est.parquet").field("VEHEST_DrivelineEst.DkfT_ShaftTorque")
        assert field.metadata == {b"unit": b"Nm"}


def test_the_mf4_table_holds_the_logged_estimates(lockstep_log, tmp_path):
    """MF4 read back with asammdf: a channel group per message, each signal's samples and times
    those of the logged frames, on the log's absolute time (the header's start time + t)."""
    asammdf = pytest.importorskip("asammdf")
    from vehest_can.cli import main

    log, ref = lockstep_log
    assert main(["replay", str(log), "--table", str(tmp_path / "est.mf4")]) == 0
    mdf = asammdf.MDF(str(tmp_path / "est.mf4"))
    start = mdf.header.start_time.timestamp()
    names = sorted({name for _, name, _ in ref})
    assert len(names) >= 2
    for name in names:
        rows = [(t, sig) for t, n, sig in ref if n == name]
        for key in rows[0][1]:
            s = mdf.get(f"{name}.{key}")
            assert len(s.samples) == len(rows)
            assert np.array_equal(s.samples.astype(float), [sig[key] for _, sig in rows]), (name, key)
            assert np.allclose(start + s.timestamps, [t for t, _ in rows], rtol=0, atol=2e-6)
    assert mdf.get("VEHEST_DrivelineEst.DkfT_ShaftTorque").unit == "Nm"
    mdf.close()


@pytest.mark.parametrize("args, problem", [
    (["--table", "{tmp}/x.xyz"], "unknown table format '.xyz'"),
    (["--table", "{tmp}"], "is a folder"),
    (["--table", "{tmp}/missing/x.csv"], "does not exist"),
    (["--table", "/proc/vehest-x.csv"], "error: "),   # a folder nobody can write in
    (["-o", "{tmp}/x.xyz"], "unknown log format"),
    (["-c", "x"], "apply to --play only"),
    (["--play", "--table", "{tmp}/x.csv"], "--play only sends the log"),
    (["--max-gap", "nan"], "--max-gap must be a finite number of seconds in 0.0005..3600, not nan"),
])
def test_bad_replay_arguments_are_clear_errors(lockstep_log, tmp_path, capsys, args, problem):
    from vehest_can.cli import main

    log, _ = lockstep_log
    assert main(["replay", str(log), *(a.format(tmp=tmp_path) for a in args)]) == 1
    err = capsys.readouterr().err
    assert err.startswith("error: ") and problem in err and "Traceback" not in err, err


@pytest.mark.parametrize("ext, module", [(".parquet", "pyarrow"), (".mf4", "asammdf")])
def test_a_table_without_its_library_says_which(lockstep_log, tmp_path, capsys, monkeypatch, ext, module):
    import sys

    from vehest_can.cli import main

    monkeypatch.setitem(sys.modules, module, None)  # import fails, as when it is not installed
    log, _ = lockstep_log
    assert main(["replay", str(log), "--table", str(tmp_path / f"x{ext}")]) == 1
    err = capsys.readouterr().err
    assert f"tables need {module}: pip install" in err and "Traceback" not in err, err
    assert not (tmp_path / f"x{ext}").exists()


# -- the log played onto a bus (--play) -----------------------------------------------------------

@pytest.mark.multicast
def test_played_onto_a_bus_a_daemon_estimates_as_the_log_did(lockstep_log, tmp_path, capsys):
    """`replay --play` on a host-only udp_multicast bus (a port of its own): a lockstep daemon in
    its own process steps on the played SIM_Sync frames and sends, frame for frame, the ECU
    frames the log holds (those are not played). Its own log shows them."""
    from daemonproc import start_daemon, stop_daemon

    from vehest_can.bus.bus import cli_args, private_multicast
    from vehest_can.cli import main

    log, ref = lockstep_log
    config = private_multicast()
    daemon = start_daemon(config, "--mode", "lockstep", "--idle-timeout", "3", "--log", str(tmp_path / "d.log"),
                          tmp_path=tmp_path)
    try:
        assert main(["replay", str(log), "--play", *cli_args(config)]) == 0
        _, err = daemon.communicate(timeout=120)  # it stops 3 s after the last frame (a loaded host: it lags)
        rc = daemon.returncode
    finally:
        if daemon.poll() is None:
            stop_daemon(daemon)
    out = capsys.readouterr().out
    n_in = sum(1 for m in read_log(log) if m.arbitration_id not in ECU_TX)
    assert f"sent {n_in} frames" in out and f"{len(ref)} ECU frames of the log not sent" in out, out
    assert rc == 0, err
    logged = [m for m in read_log(log) if m.arbitration_id in ECU_TX]
    got = [m for m in read_log(tmp_path / "d.log") if m.arbitration_id in ECU_TX]
    assert all(not m.is_rx for m in got) and len(got) == len(logged) > 1000
    assert all(same_frame(a, b) for a, b in zip(got, logged))


def test_play_keeps_the_recorded_pace_and_shortens_long_gaps(tmp_path):
    """Frames 0.2 s apart arrive 0.2 s apart (the schedule is absolute: lateness does not add up);
    a 5 s gap is shortened to --max-gap; the ECU's own frames are not sent."""
    from vehest_can.service.replay import play

    sensor = frame_id_of("DLS_Sensors")
    ecu = sorted(ECU_TX)[0]
    times = [0.0, 0.2, 0.4, 0.6, 5.6, 5.8]
    msgs = [can.Message(timestamp=1764620000.0 + t, arbitration_id=sensor, is_extended_id=False, is_fd=True,
                        data=bytes([i]) * 16) for i, t in enumerate(times)]
    msgs.insert(2, can.Message(timestamp=1764620000.25, arbitration_id=ecu, is_extended_id=False, is_fd=True,
                               data=bytes(16)))
    write(tmp_path / "pace.log", msgs)
    channel = f"pace{random.random()}"
    with can.Bus(interface="virtual", channel=channel, receive_own_messages=False) as tx, \
            can.Bus(interface="virtual", channel=channel) as rx:
        r = play(tmp_path / "pace.log", tx, max_gap_s=0.3)
        got = []
        while (m := rx.recv(0.5)) is not None:
            got.append(m)
    assert r.sent == 6 and r.not_sent == 1 and r.gaps == 1 and r.send_failures == 0
    assert [m.data[0] for m in got] == list(range(6))
    dt = np.diff([m.timestamp for m in got])
    assert np.allclose(dt, [0.2, 0.2, 0.2, 0.3, 0.2], atol=0.08), dt


def test_the_table_of_a_timestamp_paced_log_is_on_its_clock(session, tmp_path):
    """Without SIM_Sync a row's time is the tick of the log's clock that sent it: the first input's
    time + k * 500 us, k as the message-by-message reference counts it."""
    pd = pytest.importorskip("pandas")
    from vehest_can.service.estimates import EstimateTable

    msgs = [m for m in session.messages() if m.arbitration_id not in ECU_TX]
    write(tmp_path / "ts.log", msgs)
    inputs = read_log(tmp_path / "ts.log")
    ref_prod, _, _ = reference_replay(inputs)
    table = EstimateTable(tmp_path / "est.csv", ECU_TX)
    replay_file(tmp_path / "ts.log", table=table)
    table.close()
    df = pd.read_csv(tmp_path / "est.csv")
    assert len(df) == len(ref_prod) > 1000
    assert np.allclose(df["time"] - inputs[0].timestamp, [m.timestamp for m in ref_prod], rtol=0, atol=1e-6)
    assert np.allclose(df["tick"] * TICK_S, [m.timestamp for m in ref_prod], rtol=0, atol=1e-9)
    assert [int(x, 16) for x in df["frame_id"]] == [m.arbitration_id for m in ref_prod]


# -- logs that hold nothing, and time that goes backwards --------------------------------------------

@pytest.mark.parametrize("name, content, problem", [
    ("empty.asc", b"", "no CAN data frames in this log (the file is empty)"),
    ("empty.log", b"", "no CAN data frames in this log (the file is empty)"),
    ("words.asc", b"hello\nnot a log at all\n", "no CAN data frames in this log (nothing in it reads as a .asc frame)"),
    ("blank.log", b"\n\n", "no CAN data frames in this log (nothing in it reads as a .log frame)"),
    ("noise.asc", bytes(range(128, 256)) * 8, "not a readable CAN log"),
    ("noise.blf", bytes(range(256)) * 8, "not a readable CAN log"),
    ("noise.log", b"garbage\n", "line 1: not a candump -L frame|not a readable CAN log"),  # C reader | --play's
])
@pytest.mark.parametrize("play", [False, True])
def test_an_empty_or_unreadable_log_is_an_error(tmp_path, capsys, name, content, problem, play):
    """Once these replayed '100 %' with exit status 0 (python-can's readers skip what they do not know)."""
    from vehest_can.bus.bus import cli_args, private_multicast
    from vehest_can.cli import main

    path = tmp_path / name
    path.write_bytes(content)
    assert main(["replay", str(path), *(["--play", *cli_args(private_multicast())] if play else [])]) == 1
    captured = capsys.readouterr()
    problem = problem.split("|")[play if "|" in problem else 0]
    assert captured.err.startswith(f"error: {path}: ") and problem in captured.err, captured.err
    assert "Traceback" not in captured.err and captured.out == ""
    assert captured.err.count("\n") == 1


def candump_lines(msgs, times) -> str:
    """candump -L text with the given times (s, or whole µs as ints): python-can's writer would clamp a
    time that goes back."""
    def stamp(t):
        return f"{t // 1_000_000}.{t % 1_000_000:06d}" if isinstance(t, (int, np.integer)) else f"{t:.6f}"
    return "".join(f"({stamp(t)}) pt {m.arbitration_id:03X}##{int(m.bitrate_switch)}{bytes(m.data).hex().upper()}\n"
                   for m, t in zip(msgs, times))


def test_a_jump_back_in_time_is_counted_not_stepped_as_a_gap(session, tmp_path, capsys):
    """A timestamp-paced log whose clock is set back 100 s halfway: once sorted into a 100 s forward
    gap without a word (the second half handed in first, then 200,000 idle ticks). Now counted, and
    the clock goes on from the frame before: the replay is that of the log without the jump."""
    from vehest_can.cli import main

    msgs = [m for m in session.messages() if m.arbitration_id not in ECU_TX]
    # whole µs, every frame but the first 200 µs into its tick (a µs of rounding moves none to another)
    t = np.array([1764620000_000000 + round(m.timestamp * 1e6) + (200 if i else 0) for i, m in enumerate(msgs)])
    j = len(t) // 2
    jumped = t.copy()
    jumped[j:] -= 100_000_000
    joined = t.copy()                   # the same log, its second half on from the frame before the jump
    joined[j:] += t[j - 1] - t[j]
    (tmp_path / "jump.log").write_text(candump_lines(msgs, jumped))
    (tmp_path / "joined.log").write_text(candump_lines(msgs, joined))

    r = replay_file(tmp_path / "jump.log")
    assert (r.backwards, r.jumps_back, r.gaps, r.idle_ticks_skipped) == (1, 1, 0, 0)
    assert r.backward_max_s == pytest.approx(100.0 - (t[j] - t[j - 1]) * 1e-6, abs=1e-6)
    ref = replay(read_log(tmp_path / "joined.log"))
    got = replay(read_log(tmp_path / "jump.log"))
    assert got.jumps_back == 1 and ref.backwards == 0 and len(ref.produced) > 1000
    assert wire(got.produced) == wire(ref.produced) and got.counters == ref.counters
    assert r.ticks == ref.ticks and r.counters == ref.counters and r.counters["timeout"] == 0

    assert main(["replay", str(tmp_path / "jump.log")]) == 0
    out = capsys.readouterr().out
    assert "backwards in time: 1 frames earlier than the frame before them (largest step back 99.9995 s); " \
           "1 more than 1 s back: the log's clock went on from the frame before" in out, out
    assert "gaps:" not in out


def test_small_steps_back_are_counted_and_sorted(session, tmp_path):
    """Neighbours swapped in the file (merged channels): counted, and replayed in time order as before."""
    msgs = [m for m in session.messages() if m.arbitration_id not in ECU_TX]
    t = [1764620000.0 + m.timestamp + 0.0001 * (i % 2) for i, m in enumerate(msgs)]
    for i in range(5, len(msgs) - 1, 97):
        t[i], t[i + 1] = t[i + 1], t[i]
    (tmp_path / "swapped.log").write_text(candump_lines(msgs, t))
    r = replay_file(tmp_path / "swapped.log")
    assert r.backwards == len(range(5, len(msgs) - 1, 97)) > 5 and r.jumps_back == 0 and r.gaps == 0
    ref_prod, _, ref_counters = reference_replay(read_log(tmp_path / "swapped.log"))
    assert r.n_produced == len(ref_prod) and r.counters == ref_counters


def test_play_goes_on_from_the_frame_before_a_jump_back(tmp_path):
    """Played onto a bus, a jump back is counted and the pace goes on (no burst of 'late' frames)."""
    from vehest_can.service.replay import play

    sensor = frame_id_of("DLS_Sensors")
    times = [1764620100.0, 1764620100.2, 1764620000.0, 1764620000.2, 1764620000.15]
    msgs = [can.Message(arbitration_id=sensor, is_extended_id=False, is_fd=True, data=bytes([i]) * 16)
            for i in range(len(times))]
    (tmp_path / "back.log").write_text(candump_lines(msgs, times))
    channel = f"back{random.random()}"
    with can.Bus(interface="virtual", channel=channel, receive_own_messages=False) as tx, \
            can.Bus(interface="virtual", channel=channel) as rx:
        r = play(tmp_path / "back.log", tx, max_gap_s=1.0)
        got = []
        while (m := rx.recv(0.5)) is not None:
            got.append(m)
    assert (r.sent, r.backwards, r.jumps_back, r.gaps) == (5, 2, 1, 0)
    assert r.backward_max_s == pytest.approx(100.2, abs=1e-6)
    dt = np.diff([m.timestamp for m in got])
    assert np.allclose(dt, [0.2, 0.0, 0.2, 0.0], atol=0.08), dt
