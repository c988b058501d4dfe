"""Fault injection and the wire model: every row of the fault table, checked against an independent
reading of the frames the ECU received; configuration errors; the serialiser's timing and arbitration;
bus load in real time against ``vehest-can busload``."""
import math
import random
import time

import can
import e2e.p01
import numpy as np
import pytest
from frames_oracle import E2ESender

from vehest_can.bus.bus import open_bus, private_multicast
from vehest_can.bus.busload import bus_load
from vehest_can.bus.frames import TICK_S, database
from vehest_can.cli import main
from vehest_can.errors import ConfigError
from vehest_can.faults.campaign import bus_run, fault_table, run_with_faults
from vehest_can.faults.injector import FaultInjector
from vehest_can.faults.spec import KINDS, FaultSpec, faults_from_cli, load_faults, parse_fault
from vehest_can.faults.wire import FaultBus, WireModel
from vehest_can.paths import dbc_path
from vehest_can.sim.powertrain import powertrain_car
from vehest_can.sim.session import run_inprocess
from vehest_can.systems.driveline.faults import FAULTS
from vehest_can.systems.driveline.scenario import driveline_scenario_dir, load_driveline_scenario
from vehest_can.systems.ecu import Ecu

CATALOGUE = FAULTS.catalogue
DB = database("pt")
DLS = DB.get_message_by_name("DLS_Sensors")
LAUNCH = load_driveline_scenario(driveline_scenario_dir() / "launch_2nd.toml")
TICK = 0.0005
# Wire time of a 16-byte FD frame with BRS at 500 kbit/s / 4 Mbit/s, worst-case stuffing, by hand:
# 33 bits at the nominal rate (17 arbitration + 3 stuff + 13 tail) = 66 µs, 194 at the data rate
# (ESI 1, DLC 4, 128 data, stuff count 4, CRC 17, 6 fixed stuff, 34 dynamic stuff) = 48.5 µs.
DLS_WIRE_S = 66e-6 + 48.5e-6


def drive(seconds=3.5):
    return powertrain_car(LAUNCH, seconds)


# ---- an independent reading of what the ECU received ------------------------------------------------

def p01_ok(data: bytes, data_id: int) -> bool:
    """AUTOSAR E2E P01 (data ID mode BOTH) as the independent autosar-e2e library checks it."""
    return len(data) >= 2 and (data[1] & 0x0F) <= 14 and e2e.p01.e2e_p01_check(bytearray(data), data_id)


DLS_DATA_ID = int(DLS.dbc.attributes["E2EDataID"].value)
SNA = {"OutShaftSpeed": 65535, "WheelSpeedL": 65535, "WheelSpeedR": 65535, "ShaftTorque": -32768,
       "EngineSpeed": 65535, "TurbineSpeed": 65535}


def inputs_valid(rx_per_tick, timeout_cycles=4, we_min=40.0):
    """Per tick: (filter T's inputs valid, filter S's inputs valid), from the frames alone.

    Necessary conditions only, read from the DBC and the E2E rules without the ECU's code: a DLS frame
    of the right length, correct CRC, a counter that does not repeat; then no more than 3 ticks without
    one; the needed signals with their qualifier set and not SNA; a gear 0..5; for the turbine torque
    input engine speed >= we_min and turbine speed <= 2 x engine speed.
    """
    last_counter, sample, age = None, None, timeout_cycles
    out_t, out_s = [], []
    for frames in rx_per_tick:
        fresh = False
        for m in frames:
            if m.arbitration_id != DLS.frame_id or m.is_extended_id or len(m.data) != DLS.length:
                continue
            data = bytes(m.data)
            if not p01_ok(data, DLS_DATA_ID):
                continue
            counter = data[1] & 0x0F
            if counter == last_counter:
                continue
            last_counter = counter
            sample = DLS.decode(data, decode_choices=False, scaling=False)
            fresh = True
        age = 0 if fresh else age + 1
        if sample is None or age >= timeout_cycles:
            out_t.append(False)
            out_s.append(False)
            continue
        ok = {name: sample[f"Qf_{name}"] == 1 and sample[name] != sna for name, sna in SNA.items()}
        gear = sample["GearEngaged"]
        we, wt = sample["EngineSpeed"] * 0.02, sample["TurbineSpeed"] * 0.02
        u = gear == 0 or (1 <= gear <= 5 and ok["EngineSpeed"] and ok["TurbineSpeed"] and we >= we_min
                          and wt <= 2 * we)
        s = u and ok["OutShaftSpeed"] and ok["WheelSpeedL"] and ok["WheelSpeedR"]
        out_s.append(s)
        out_t.append(s and ok["ShaftTorque"])
    return np.array(out_t), np.array(out_s)


# ---- every row of the table -------------------------------------------------------------------------

@pytest.fixture(scope="module")
def drive35():
    return drive()


@pytest.mark.parametrize("case", CATALOGUE, ids=[c.label for c in CATALOGUE])
def test_every_fault_row(case, drive35):
    row = fault_table(drive35, (case,), keep_runs=True)[0]
    run = row.run
    a, b = row.window
    assert (a, b) == (4000, 5000)
    rx_counters = ("crc_error", "counter_repeat", "counter_skip", "dlc_error", "timeout", "unknown_id")
    # what the ECU detects: the expected counters rise, nothing before the fault
    assert not run.counters[a - 1].any(), "a fault counter rose before the fault"
    for name in case.expect:
        assert row.detected.get(name, 0) > 0, f"{name} did not rise"
        assert run.counter(name)[b - 1] > 0, f"{name} rose only after the fault"
    if not case.expect:
        assert not any(row.detected.get(n) for n in rx_counters), row.detected
    # never valid from invalid inputs, whatever the fault
    ok_t, ok_s = inputs_valid(run.rx)
    assert not (run.valid("T") & ~ok_t).any(), np.flatnonzero(run.valid("T") & ~ok_t)[:10]
    assert not (run.valid("S") & ~ok_s).any(), np.flatnonzero(run.valid("S") & ~ok_s)[:10]
    assert not (run.valid("T") & (run.health("T") != 1)).any()
    # the reference reading is not vacuous: it accepts the good ticks, refuses the lost ones
    assert ok_t[3000:a].all() and run.valid("T")[3000:a].all() and run.valid("S")[3000:a].all()
    if case.expect and "timeout" in case.expect:
        assert not ok_t[a:b].all()
    # health response: a fault that takes every frame leaves the estimates invalid within 4 ticks
    if case.fault.split(":")[0] in ("silence", "freeze_counter") or case.fault.startswith("corrupt_crc:DLS_Sensors:2") \
            or case.fault.startswith("flood:2"):
        assert not run.valid("T")[a + 4:b].any() and not run.valid("S")[a + 4:b].any()
        assert set(row.health["T"]) == {"OK", "DEGRADED"} and row.valid_pct["T"] < 0.5
    if "timeout" in case.expect:
        assert "DEGRADED" in row.health["T"] and "DEGRADED" in row.health["S"]
    # recovery: valid again at the first tick after the fault, and to the end of the run; a fault
    # that ends with frames bunched up (a draining queue, delayed frames catching up) is a burst:
    # the ECU waits until the message has been regular for its timeout: 4 ticks after the last late
    # frame, which trails the fault by up to 2.5 ms = 5 ticks (the largest jitter of the table): 9
    burst = run.counter("rx_burst")[-1] > 0
    settle = 9 if burst else 0
    assert row.recovery <= (settle + 1)
    assert run.valid("T")[b + settle:].all() and run.valid("S")[b + settle:].all()
    assert not any(run.counters[-1, :6] - run.counters[b + 10, :6])  # quiet again after the fault
    assert np.isfinite(run.estimate("T")).all()


def test_flood_queue_policy_decides_how_stale_the_first_samples_are(drive35):
    """After a flood, a FIFO sender flushes its 10 waiting frames: up to 0.5 s old, CRC and counter fine.
    The ECU's burst check refuses them; a sender that keeps only its newest frame never sends them."""
    fifo = run_with_faults(drive35, faults_from_cli(["flood:2-2.5"]))
    latest = run_with_faults(drive35, faults_from_cli(["flood:2-2.5"]), tx_policy="latest")
    for run in (fifo, latest):
        assert run.counter("unknown_id")[-1] == math.floor(0.5 / 270e-6) + 1  # 8-byte classic, 270 µs each
    # the ECU sees the FIFO's queue drain as a burst of one message and uses none of it
    assert fifo.counter("rx_burst")[-1] >= 1
    assert not (fifo.valid("T") & (fifo.sample_age > 0.1)).any()
    assert (fifo.sample_age > 0.45).any()  # the stale samples were on the bus
    assert np.nanmax(latest.sample_age[5000:][latest.valid("T")[5000:]]) <= 0.0025


def test_without_faults_the_wire_changes_nothing_and_carries_the_busload_figure():
    d = drive(1.5)
    run = run_with_faults(d)
    ref = run_inprocess(drive(1.5), Ecu())
    sel = np.isin(ref.frames["id"], [0x180, 0x300])
    expected = [(int(k), bytes(f["data"][:f["len"]])) for f, k in zip(ref.frames[sel], ref.frame_tick[sel])]
    assert [(k, bytes(m.data)) for k, m in run.tx] == expected
    assert not run.counters.any()
    # the driveline drive sends the driveline frames; the camber frames are on the bus only during inspection
    on_bus = {"DLS_Sensors", "VEHEST_DrivelineEst", "VEHEST_Status"}
    for stuffing, figure in (("worst", "worst_pct"), ("nominal", "nominal_pct")):
        load = run_with_faults(d, stuffing=stuffing).load
        rows = [f for f in bus_load(dbc_path("pt")).frames if f.name in on_bus]
        assert len(rows) == len(on_bus)
        assert load == pytest.approx(sum(getattr(f, figure) for f in rows) / 100, rel=1e-9)


def test_same_seed_same_run_other_seed_other_run():
    d = drive(2.3)
    spec = ["drop:DLS_Sensors:p=0.2:2-2.3", "jitter:DLS_Sensors:max_us=800:2-2.3", "corrupt_crc:*:p=0.1:2-2.3"]
    one, two = (run_with_faults(d, faults_from_cli(spec, seed=5)) for _ in range(2))
    other = run_with_faults(d, faults_from_cli(spec, seed=6))
    assert np.array_equal(one.est, two.est) and np.array_equal(one.counters, two.counters)
    assert one.applied == two.applied
    assert not np.array_equal(one.counters, other.counters)


# ---- the injector, frame by frame -------------------------------------------------------------------

GOOD = dict(OutShaftSpeed=200.0, WheelSpeedL=51.0, WheelSpeedR=51.0, ShaftTorque=1500.0, EngineSpeed=500.0,
            TurbineSpeed=465.0, GearEngaged=2, Qf_OutShaftSpeed=1, Qf_WheelSpeedL=1, Qf_WheelSpeedR=1,
            Qf_ShaftTorque=1, Qf_EngineSpeed=1, Qf_TurbineSpeed=1)


def stream(n, start=0):
    tx = E2ESender()
    return [(start + i) * TICK for i in range(n)], [tx.message("DLS_Sensors", GOOD) for _ in range(n)]


def inject(texts, n=400, seed=3):
    inj = FaultInjector(faults_from_cli(texts, seed=seed))
    times, msgs = stream(n)
    return msgs, [inj.apply([m], t) for t, m in zip(times, msgs)], inj


def test_drop_rate_and_window():
    msgs, out, inj = inject(["drop:DLS_Sensors:p=0.3:0.05-0.15"])
    kept = [len(o) for o in out]
    assert all(kept[:100]) and all(kept[300:])
    lost = 200 - sum(kept[100:300])
    assert 35 <= lost <= 85 and inj.applied == [lost]  # binomial(200, 0.3): mean 60, sd 6.5
    assert all(o[0].msg.data == m.data for o, m in zip(out[:100], msgs) if o)


def test_corrupt_flips_exactly_one_bit_and_breaks_the_crc():
    msgs, out, _ = inject(["corrupt_crc:DLS:0.01-0.02"], n=60)
    for i, (m, o) in enumerate(zip(msgs, out)):
        got = bytes(o[0].msg.data)
        flipped = sum(bin(x ^ y).count("1") for x, y in zip(got, bytes(m.data)))
        assert flipped == (1 if 20 <= i < 40 else 0)
        assert p01_ok(got, DLS_DATA_ID) == (flipped == 0)


def test_skip_counter_jumps_and_keeps_the_crc_right():
    msgs, out, _ = inject(["skip_counter:DLS_Sensors:by=3:0.01-0.0125"], n=40)
    counters = [o[0].msg.data[1] & 0x0F for o in out]
    steps = [(b - a) % 15 for a, b in zip(counters, counters[1:])]
    assert steps == [1] * 19 + [3] * 5 + [1] * 15   # the sender's counter stays moved after the window
    for o, m in zip(out, msgs):
        assert p01_ok(bytes(o[0].msg.data), DLS_DATA_ID)
        assert bytes(o[0].msg.data)[2:] == bytes(m.data)[2:]


def test_freeze_repeats_the_last_payload_and_wrong_dlc_shortens():
    msgs, out, _ = inject(["freeze_counter:DLS_Sensors:0.01-0.012", "wrong_dlc:DLS_Sensors:p=1:0.02-0.021"], n=50)
    data = [bytes(o[0].msg.data) for o in out]
    assert data[19:24] == [bytes(msgs[19].data)] * 5 and data[24] == bytes(msgs[24].data)
    assert [len(d) for d in data[40:42]] == [16, 16] and len(data[42]) == 20 and data[40] == bytes(msgs[40].data)[:16]


def test_silence_a_node_spares_the_bench_sync_frames_unless_named():
    from vehest_can.bus import lockstep
    sync = lockstep.sync_message(5)
    _, dls = stream(1)
    for target, sync_kept in (("DLS", True), ("SIM", True), ("*", True), ("SIM_Sync", False)):
        inj = FaultInjector(faults_from_cli([f"silence:{target}"]))
        ids = [i.msg.arbitration_id for i in inj.apply([dls[0], sync], 0.0)]
        assert (sync.arbitration_id in ids) == sync_kept
        assert (DLS.frame_id in ids) == (target not in ("DLS", "*"))


def test_latency_and_jitter_delay_but_never_reorder_one_id():
    _, out, _ = inject(["latency:DLS_Sensors:us=300:0.05-", "jitter:DLS_Sensors:max_us=2000:0.1-0.15"], n=400)
    times = [i * TICK for i in range(400)]
    release = [t + o[0].delay_s for t, o in zip(times, out)]
    assert all(o[0].delay_s == 0 for o in out[:100])
    assert all(o[0].delay_s == pytest.approx(300e-6) for o in out[310:])
    assert all(b >= a for a, b in zip(release, release[1:]))
    jit = [o[0].delay_s - 300e-6 for o in out[200:300]]
    assert 0 <= min(jit) < 0.3e-3 and 1.5e-3 < max(jit) <= 2.0e-3 + TICK


# ---- configuration: command line and TOML -----------------------------------------------------------

@pytest.mark.parametrize("text", [
    "drop:DLS_Sensors:p=0.1:2-3", "corrupt_crc:*", "freeze_counter:DLS:1.5-", "skip_counter:DLS_Sensors:by=4:p=0.5",
    "wrong_dlc:VEHEST_DrivelineEst:length=8:-2", "silence:VEHEST:0.5-1", "flood:id=0x010:length=4:load=0.25:1-2",
    "latency:DLS:us=250", "jitter:*:max_us=100:0-1"])
def test_fault_syntax_round_trips(text):
    spec = parse_fault(text)
    assert parse_fault(spec.text()) == spec


def test_fault_syntax_fields():
    spec = parse_fault("flood:id=0x010:load=0.25:1-2")
    assert (spec.kind, spec.id, spec.load, spec.start_s, spec.end_s, spec.target) == ("flood", 16, 0.25, 1.0, 2.0, None)
    assert parse_fault("drop:DLS").end_s == math.inf and set(KINDS) >= {"drop", "flood", "jitter"}


@pytest.mark.parametrize("text, words", [
    ("explode:DLS", ["unknown fault kind 'explode'"]),
    ("drop", ["target", "missing"]),
    ("drop:Nope", ["'Nope'", "neither a message"]),
    ("drop:DLS:p=1.5", ["p:", "probability"]),
    ("drop:DLS:p=lots", ["p='lots'", "not a number"]),
    ("drop:DLS:by=2", ["'by' is not an amount of drop", "takes: p"]),
    ("drop:DLS:3-2", ["end_s", "must come after"]),
    ("drop:DLS:1-2:3-4", ["two time windows"]),
    ("drop:DLS:VEHEST", ["second target"]),
    ("flood:DLS", ["target", "give no target"]),
    ("flood:id=0x800", ["id:", "11-bit"]),
    ("flood:length=16", ["classic CAN"]),
    ("flood:load=0", ["load:", "(0, 1]"]),
    ("skip_counter:SIM_Sync", ["no E2E-protected frame"]),
    ("skip_counter:DLS:by=1", ["by:", "[2, 14]"]),
    ("wrong_dlc:DLS:length=13", ["length:", "payload length"]),
    ("jitter:DLS:max_us=-5", ["max_us:"]),
    ("drop::DLS", ["empty field"]),
])
def test_fault_syntax_errors_name_the_problem(text, words):
    with pytest.raises(ConfigError) as err:
        parse_fault(text)
    message = str(err.value)
    assert message.startswith(f"--fault {text!r}")
    for w in words:
        assert w in message, message


def test_faults_from_toml(tmp_path):
    path = tmp_path / "f.toml"
    path.write_text('name = "x"\n[faults]\nseed = 9\n'
                    '[[faults.fault]]\nkind = "drop"\ntarget = "DLS_Sensors"\np = 0.1\nstart_s = 2.0\nend_s = 3.0\n'
                    '[[faults.fault]]\nkind = "flood"\nid = 1\nload = 0.5\n')
    config = load_faults(path)
    assert config.seed == 9
    assert config.faults == (FaultSpec("drop", "DLS_Sensors", 2.0, 3.0, p=0.1), FaultSpec("flood", id=1, load=0.5))


@pytest.mark.parametrize("body, words", [
    ('name = "x"\n', ["faults: missing"]),
    ('[faults]\nsed = 1\n', ["faults.sed", "unknown key"]),
    ('[faults]\nseed = -1\n', ["faults.seed"]),
    ('[faults]\nfault = 3\n', ["faults.fault", "array of tables"]),
    ('[[faults.fault]]\ntarget = "DLS"\n', ["faults.fault[0].kind", "missing"]),
    ('[[faults.fault]]\nkind = "drop"\ntarget = "DLS"\npp = 1\n', ["faults.fault[0].pp", "not a key of a drop"]),
    ('[[faults.fault]]\nkind = "skip_counter"\ntarget = "DLS"\nby = "2"\n', ["faults.fault[0].by", "integer"]),
    ('[[faults.fault]]\nkind = "drop"\ntarget = "DLS"\np = 2\n', ["faults.fault[0]: p:", "probability"]),
    ('[[faults.fault]]\nkind = "drop"\ntarget = 5\n', ["faults.fault[0].target", "string"]),
    ('[faults\n', ["TOML syntax"]),
])
def test_faults_toml_errors_name_file_and_key(tmp_path, body, words):
    path = tmp_path / "bad.toml"
    path.write_text(body)
    with pytest.raises(ConfigError) as err:
        load_faults(path)
    assert str(err.value).startswith(str(path))
    for w in words:
        assert w in str(err.value), str(err.value)


def test_faults_command(tmp_path, capsys):
    md = tmp_path / "t.md"
    assert main(["faults", "--duration", "2.6", "--fault", "corrupt_crc:DLS_Sensors:p=0.5:2-2.5",
                 "--markdown", str(md)]) == 0
    out = capsys.readouterr().out
    assert "none (reference)" in out and "crc_error +" in out
    lines = md.read_text().splitlines()
    assert lines[0].startswith("| fault |") and len(lines) == 4 and "`corrupt_crc:DLS_Sensors:p=0.5:2-2.5`" in lines[3]
    assert main(["faults", "--fault", "drop:DLS:p=7"]) == 1
    assert "error: --fault 'drop:DLS:p=7': p:" in capsys.readouterr().err
    assert main(["faults", "--faults-file", str(tmp_path / "none.toml")]) == 1
    assert "cannot read" in capsys.readouterr().err


# ---- the wire model ---------------------------------------------------------------------------------

def frame(fid, n=16, ext=False, fd=True):
    return can.Message(arbitration_id=fid, is_extended_id=ext, is_fd=fd, bitrate_switch=fd, data=bytes(n))


def test_wire_serialises_back_to_back_at_the_frame_bit_time():
    wire = WireModel(tx_queue=100)
    for _ in range(20):
        wire.submit(frame(0x100), 0.0, "a")
    done = wire.advance(1.0)
    assert [round(t.end / DLS_WIRE_S, 9) for t in done] == list(range(1, 21))
    assert wire.busy_s[0x100] == pytest.approx(20 * DLS_WIRE_S)
    classic = WireModel(stuffing="nominal")
    classic.submit(frame(0x7F0, 8, fd=False), 0.0)
    assert classic.advance(1.0)[0].end == pytest.approx(111 / 500e3)  # Davis 2007: 8n + 47 bits, no stuffing


def test_wire_arbitration_lowest_id_first_and_never_preempts():
    wire = WireModel()
    for fid in (0x300, 0x180, 0x100):
        wire.submit(frame(fid), 0.0, fid)
    wire.submit(frame(0x100 << 18, ext=True), 0.0, "x")
    wire.submit(frame(0x001, 8, fd=False), 1e-6, "late")   # becomes ready while 0x100 is on the wire
    order = [t.msg.arbitration_id for t in wire.advance(1.0)]
    assert order == [0x100, 0x001, 0x100 << 18, 0x180, 0x300]


def test_flood_starves_lower_priority_frames_and_fills_the_wire():
    wire = WireModel()
    wire.add_flood(FaultSpec("flood", start_s=0.0, end_s=0.01), "babbler")
    wire.submit(frame(0x100), 0.0005, "dls")
    done = wire.advance(0.02)
    dls = [t for t in done if t.node == "dls"][0]
    assert dls.start >= 0.01 - 1e-12                       # waited for the whole flood
    flood = [t for t in done if t.node == "babbler"]
    assert sum(t.end - t.start for t in flood) == pytest.approx(0.01 + 270e-6 * (len(flood) - 0.01 / 270e-6))
    half = WireModel()
    half.add_flood(FaultSpec("flood", start_s=0.0, end_s=1.0, load=0.5))
    half.advance(2.0)
    assert half.busy_s[0x001] == pytest.approx(0.5, abs=300e-6)


def test_transmit_queue_fifo_discards_and_latest_replaces():
    fifo = WireModel(tx_queue=10)
    accepted = [fifo.submit(frame(0x100), 1.0, "n") for _ in range(12)]
    assert accepted == [True] * 10 + [False] * 2 and fifo.overflow == {"n": 2}
    latest = WireModel(tx_policy="latest")
    for i in range(5):
        msg = can.Message(arbitration_id=0x100, is_extended_id=False, is_fd=True, data=bytes([i]) * 16)
        latest.submit(msg, 1.0, "n")
    done = latest.advance(2.0)
    assert len(done) == 1 and done[0].msg.data[0] == 4 and latest.replaced == {"n": 4}
    with pytest.raises(ConfigError):
        WireModel(stuffing="some")
    with pytest.raises(can.CanOperationError):
        WireModel().submit(frame(0x100, 12, fd=False), 0.0)


# ---- real time: FaultBus on python-can buses --------------------------------------------------------

def test_faultbus_delivers_no_faster_than_the_wire_in_order():
    channel = f"fb{random.random()}"
    rx = can.Bus(interface="virtual", channel=channel)
    bus = FaultBus(can.Bus(interface="virtual", channel=channel), tx_queue=200)
    try:
        t0 = time.perf_counter()
        for i in range(100):
            bus.send(can.Message(arbitration_id=0x100, is_extended_id=False, is_fd=True, bitrate_switch=True,
                                 data=bytes([i]) * 16))
        got = []
        while len(got) < 100:
            m = rx.recv(2.0)
            assert m is not None, f"only {len(got)} of 100 frames arrived"
            got.append(m)
        elapsed = time.perf_counter() - t0
        assert [m.data[0] for m in got] == list(range(100))
        assert elapsed >= 100 * DLS_WIRE_S * 0.999
        snap = bus.wire.snapshot()
        assert snap.busy_s[0x100] == pytest.approx(100 * DLS_WIRE_S) and snap.frames[0x100] == 100
    finally:
        bus.shutdown()
        rx.shutdown()


@pytest.mark.multicast
def test_faultbus_on_udp_multicast_injects_faults():
    config = private_multicast()
    rx = open_bus(config)
    bus = FaultBus(open_bus(config),
                   FaultInjector(faults_from_cli(["corrupt_crc:DLS_Sensors"])))
    try:
        _, msgs = stream(5)
        for m in msgs:
            bus.send(m)
        sent = [bytes(m.data) for m in msgs]
        flips = {}
        end = time.monotonic() + 5
        while len(flips) < 5 and time.monotonic() < end:
            m = rx.recv(0.5)
            if m is None or m.arbitration_id != DLS.frame_id or len(m.data) != DLS.length:
                continue
            # Linux hands a socket bound to the port every group's datagrams: other runs' frames may
            # arrive too. Ours are the sent payloads with bits flipped.
            dist = [sum(bin(x ^ y).count("1") for x, y in zip(bytes(m.data), d)) for d in sent]
            i = int(np.argmin(dist))
            if dist[i] <= 4:
                flips[i] = (dist[i], p01_ok(bytes(m.data), DLS_DATA_ID))
        assert flips == {i: (1, False) for i in range(5)}
    finally:
        bus.shutdown()
        rx.shutdown()


@pytest.mark.slow
def test_realtime_bus_load_matches_busload():
    """Acceptance: real time through the wire at 500 k / 4 M, both nodes on one wire; the measured
    load (busy time of the frames sent over wall time, 2 s in the middle of a 3 s run) within 5 % of
    ``vehest-can busload``'s worst case (the wire counts worst-case stuffing). A run in which a 2 kHz
    loop lost more than 2 % of its ticks to the machine says nothing about the bus; up to three runs."""
    expected = bus_load(dbc_path("pt"))
    per_frame = {f.name: f.wire_us_worst for f in expected.frames}
    runs = []
    for _ in range(3):
        r = bus_run(drive(3.0))
        runs.append(r)
        print("\n".join(r.lines()))
        # the frames on the wire are the DBC's frames: same bits per frame, whatever the timing
        for name in ("DLS_Sensors", "VEHEST_DrivelineEst", "VEHEST_Status"):
            assert r.wire_us[name] == pytest.approx(per_frame[name], rel=1e-9)
        assert set(r.load) == {"DLS_Sensors", "VEHEST_DrivelineEst", "VEHEST_Status", "total"}
        assert r.overflow == 0 and r.send_errors == 0
        within = all(abs(r.load[k] / r.expected_worst[k] - 1) <= 0.05 for k in ("DLS_Sensors", "total"))
        if within:
            return
        assert not r.undisturbed(0.02), "an undisturbed real-time run is off busload by more than 5 %"
    pytest.skip("the machine kept neither 2 kHz loop on schedule in 3 runs: " + "; ".join(
        f"sim {r.sim['deadline_misses']} / ECU {r.daemon.deadline_misses} misses, "
        f"total {100 * r.load['total']:.1f} %" for r in runs))


@pytest.mark.slow
def test_realtime_daemon_survives_faults_and_counts_them():
    config = faults_from_cli(["corrupt_crc:DLS_Sensors:p=0.2:0.6-0.9", "wrong_dlc:DLS_Sensors:p=0.2:0.9-1.1",
                              "silence:DLS:1.2-1.5", "flood:load=0.6:1.6-1.9", "freeze_counter:DLS_Sensors:2.0-2.1",
                              "jitter:DLS_Sensors:max_us=1500:2.2-2.4"], seed=4)
    r = bus_run(drive(3.0), config)
    print("\n".join(r.lines()))
    stats = r.daemon
    assert stats is not None and stats.ticks > 2000        # the daemon ran to the end and returned
    c = stats.counters
    for name in ("crc_error", "dlc_error", "timeout", "unknown_id", "counter_repeat"):
        assert c[name] > 0, name
    # the flood is made by the wire itself: 0.3 s at 0.6 of the bus, whatever the machine's timing
    assert r.load["0x1"] * r.window_s == pytest.approx(0.3 * 0.6, abs=0.001)
    frames, ticks = r.session.frames, r.session.frame_tick
    est = frames["id"] == 0x180
    assert est.sum() > 2000
    est_msg = DB.get_message_by_frame_id(0x180)
    decoded = [est_msg.decode(bytes(f["data"][:est_msg.length]), decode_choices=False) for f in frames[est]]
    assert all(d["DkfT_Valid"] == 0 or d["DkfT_Health"] == 1 for d in decoded)
    # valid again after the faults: among the estimates the simulator received after the last fault's
    # window (its ticks, not the last frames: a 2-core CI machine may stall the final 0.1 s)
    after = ticks[est] > round(2.4 / TICK_S) + 100
    assert after.sum() > 200
    assert any(d["DkfT_Valid"] for d, a in zip(decoded, after) if a)
