"""The ECU tick under good and hostile input: every fault is counted, flagged, survived."""
import math
from dataclasses import replace

import can
import numpy as np
import pytest
from ecurun import run_ecu
from frames_oracle import E2ESender

from vehest_can.bus.frames import database
from vehest_can.errors import ConfigError
from vehest_can.systems.ecu import Ecu, EcuConfig

DB = database("pt")
EST = DB.get_message_by_name("VEHEST_DrivelineEst")
STATUS = DB.get_message_by_name("VEHEST_Status")

GOOD = dict(OutShaftSpeed=200.0, WheelSpeedL=51.0, WheelSpeedR=51.0, ShaftTorque=1500.0,
            EngineSpeed=500.0, TurbineSpeed=200.0 / 0.43, GearEngaged=2,
            Qf_OutShaftSpeed=1, Qf_WheelSpeedL=1, Qf_WheelSpeedR=1, Qf_ShaftTorque=1,
            Qf_EngineSpeed=1, Qf_TurbineSpeed=1)


def run(ecu, frames_per_tick):
    """The estimates and the status the ECU sent, decoded (tests/ecurun.py)."""
    return run_ecu(ecu, frames_per_tick, (EST.name, STATUS.name))


def good_ticks(tx, n, **override):
    return [[tx.message("DLS_Sensors", {**GOOD, **override})] for _ in range(n)]


@pytest.fixture
def warm():
    """An ECU after 2.5 s of good input: both filters OK."""
    ecu, tx = Ecu(), E2ESender()
    est, _ = run(ecu, good_ticks(tx, 5000))
    assert est[-1]["DkfT_Health"] == 1 and est[-1]["DkfS_Health"] == 1
    assert est[-1]["DkfT_Valid"] == 1 and est[-1]["DkfS_Valid"] == 1
    assert all(v == 0 for v in ecu.counters().values())
    return ecu, tx


def test_clean_input_gives_no_fault_and_status_every_10_ms(warm):
    ecu, tx = warm
    est, status = run(ecu, good_ticks(tx, 200))
    assert len(est) == 200 and len(status) == 10
    assert all(s["RxFaultActive"] == 0 for s in status)
    assert est[-1]["DkfT_ShaftTorque"] == pytest.approx(1500.0, abs=30)


def counters_after(warm, frames, ticks_after=40):
    ecu, tx = warm
    est, status = run(ecu, [frames] + good_ticks(tx, ticks_after))
    return ecu, est, status


def test_wrong_dlc_is_counted_and_not_used(warm):
    ecu, tx = warm
    good = tx.message("DLS_Sensors", GOOD)
    short = can.Message(arbitration_id=good.arbitration_id, is_extended_id=False, is_fd=True, data=good.data[:12])
    ecu, _, status = counters_after(warm, [short])
    assert ecu.counters()["dlc_error"] == 1
    assert status[-1]["CntDlcError"] == 1


def test_bad_crc_is_counted_and_flags_estimates_invalid_until_good_again(warm):
    ecu, tx = warm
    ticks = []
    for _ in range(25):
        bad = tx.message("DLS_Sensors", GOOD)
        data = bytearray(bad.data)
        data[0] ^= 0xFF
        bad.data = data
        ticks.append([bad])
    est, status = run(ecu, ticks)
    assert ecu.counters()["crc_error"] == 25
    assert ecu.counters()["timeout"] == 1  # 25 ticks without a good frame > 4-cycle timeout
    assert est[-1]["DkfT_Valid"] == 0 and est[-1]["DkfT_Health"] == 2  # DEGRADED, not valid
    assert status[-1]["RxFaultActive"] & 1
    est, status = run(ecu, good_ticks(tx, 100))
    assert est[-1]["DkfT_Valid"] == 1 and status[-1]["RxFaultActive"] == 0


def test_repeated_counter_is_not_used_and_skipped_counter_is_counted(warm):
    ecu, tx = warm
    f = tx.message("DLS_Sensors", GOOD)
    run(ecu, [[f], [f]])  # the same frame twice: the second is stale
    assert ecu.counters()["counter_repeat"] == 1
    tx.message("DLS_Sensors", GOOD)  # one frame lost on the way
    run(ecu, good_ticks(tx, 1))
    assert ecu.counters()["counter_skip"] == 1


def test_unknown_ids_are_counted_known_foreign_ids_are_not(warm):
    ecu, tx = warm
    frames = [can.Message(arbitration_id=0x555, is_extended_id=False, data=b"\x01"),
              can.Message(arbitration_id=0x100, is_extended_id=True, data=bytes(16)),  # 29-bit 0x100 is not ours
              tx.message("VEHEST_Status", {})]
    ecu.rx(frames[0])
    ecu.rx(frames[2])
    assert ecu.counters()["unknown_id"] == 1
    ecu.rx(frames[1])
    assert ecu.counters()["dlc_error"] + ecu.counters()["unknown_id"] == 2


def test_silent_sensor_times_out_after_four_cycles_and_recovers(warm):
    ecu, tx = warm
    est, status = run(ecu, [[]] * 3)
    assert ecu.counters()["timeout"] == 0
    assert est[-1]["DkfT_Health"] == 1  # predicting through 3 missing samples is fine (ZOH input)
    est, status = run(ecu, [[]] * 40)
    assert ecu.counters()["timeout"] == 1
    assert est[-1]["DkfT_Valid"] == 0 and est[-1]["TurbineTorque_Valid"] == 0
    est, _ = run(ecu, good_ticks(tx, 10))
    assert est[-1]["DkfT_Valid"] == 1


def test_sna_and_qualifier_make_signals_invalid(warm):
    ecu, tx = warm
    est, _ = run(ecu, good_ticks(tx, 5, Qf_ShaftTorque=0))
    assert ecu.counters()["signal_invalid"] == 5
    assert est[-1]["DkfT_Valid"] == 0 and est[-1]["DkfS_Valid"] == 1  # only T uses the torque sensor
    est, _ = run(ecu, good_ticks(tx, 5, OutShaftSpeed=1310.7))  # raw 65535 = SNA
    assert ecu.counters()["signal_invalid"] == 10
    assert est[-1]["DkfS_Valid"] == 0


def test_nan_producing_input_engine_stalled(warm):
    """Engine speed 0: eq. 9's speed ratio would divide by zero. Counted, input held, no NaN out."""
    ecu, tx = warm
    est, _ = run(ecu, good_ticks(tx, 10, EngineSpeed=0.0))
    assert ecu.counters()["input_invalid"] == 10
    assert est[-1]["TurbineTorque_Valid"] == 0 and est[-1]["DkfT_Valid"] == 0
    assert all(math.isfinite(v) for v in est[-1].values())
    assert ecu.counters()["filter_reset"] == 0


def test_extreme_values_reset_the_filter_and_are_reported(warm):
    """Torque at the end of its range, speeds zero: the filters are pushed hard; never NaN, never a crash."""
    ecu, tx = warm
    rng = np.random.default_rng(0)
    hostile = [[tx.message("DLS_Sensors", {**GOOD, "ShaftTorque": float(rng.choice([-8191.75, 8191.75])),
                                            "OutShaftSpeed": 1310.68 * rng.random(), "WheelSpeedL": 0.0})]
               for _ in range(2000)]
    est, status = run(ecu, hostile)
    assert all(math.isfinite(v) for e in est for v in e.values())
    est, status = run(ecu, good_ticks(tx, 6000))
    assert est[-1]["DkfT_Valid"] == 1 and est[-1]["DkfS_Valid"] == 1


def test_random_garbage_never_crashes(warm):
    ecu, tx = warm
    rng = np.random.default_rng(7)
    known = {m.frame_id for bus in ("pt", "ch", "sim") for m in database(bus).messages}  # the ECU knows the lockstep IDs too
    to_sensor = foreign = 0
    for _ in range(3000):
        n = int(rng.choice([16, int(rng.integers(0, 65))]))
        fid = int(rng.choice([0x100, 0x180, 0x7F0, int(rng.integers(0, 0x800))]))
        to_sensor += fid == 0x100
        foreign += fid not in known
        ecu.rx(can.Message(arbitration_id=fid, is_extended_id=False, is_fd=n > 8,
                           data=rng.integers(0, 256, n, dtype=np.uint8).tobytes()))
        ecu.step()
    c = ecu.counters()
    assert c["unknown_id"] == foreign
    # E2E lets about 1 in 256 random payloads of the right length through; everything else is refused
    assert c["crc_error"] + c["dlc_error"] >= 0.97 * to_sensor


def test_a_burst_of_queued_frames_is_not_used_until_the_message_is_regular_again(warm):
    """After a blocked bus a sender's queue drains: good CRC, good counters, old samples. More
    than two frames of a message in one tick is a burst: counted, estimates invalid, and valid
    again only after the message has been regular for its 4-cycle timeout."""
    ecu, tx = warm
    burst = [tx.message("DLS_Sensors", GOOD) for _ in range(6)]
    est, status = run(ecu, [burst[:4], burst[4:]])  # the queue drains over two ticks
    assert ecu.counters()["rx_burst"] == 1
    assert [e["DkfT_Valid"] for e in est] == [0, 0]
    est, status = run(ecu, good_ticks(tx, 40))
    valid = [e["DkfT_Valid"] for e in est]
    assert valid[:2] == [0, 0] and all(valid[3:])  # 4 regular ticks, the burst's tail included
    assert ecu.counters()["counter_repeat"] == ecu.counters()["crc_error"] == 0
    assert status[-1]["CntRxBurst"] == 1
    # one late frame plus the on-time one is ordinary jitter, not a burst
    run(ecu, [good_ticks(tx, 2)[0] + good_ticks(tx, 1)[0]])
    assert ecu.counters()["rx_burst"] == 1


@pytest.mark.parametrize("limit, bursts", [(0, 0), (2, 1), (5, 0), (3, 1)])
def test_the_burst_limit_is_configurable_and_zero_switches_it_off(limit, bursts):
    """A transport that batches (UML's 100 Hz timer: 20 frames per wake-up) needs the check off
    or relaxed; the limit is the ECU's configuration, `daemon --rx-burst-limit N`."""
    ecu, tx = Ecu(replace(EcuConfig.default(), rx_burst_frames=limit)), E2ESender()
    run(ecu, good_ticks(tx, 100))
    frames = [f for tick in good_ticks(tx, 4) for f in tick]
    est, _ = run(ecu, [frames] + good_ticks(tx, 1))
    assert ecu.counters()["rx_burst"] == bursts
    assert est[-1]["DkfT_Valid"] == (1 if bursts == 0 else 0)


def test_a_burst_limit_out_of_range_is_refused():
    for bad in (-1, 256):
        with pytest.raises(ConfigError, match="rx_burst_frames"):
            Ecu(replace(EcuConfig.default(), rx_burst_frames=bad))


def test_a_system_registered_from_outside_is_reported_with_no_edit_to_the_ecu():
    """The ECU's health and not-heard lists come from the registered systems' estimators: a toy
    system (its estimator reads the ECU's tick: OK once the ECU has stepped, heard likewise) is
    reported beside the shipped ones, and gone again when unregistered."""
    from vehest_can.systems import EcuEstimator, Registration, register, unregister

    class Toy(Registration):
        name = "toy"
        estimators = (EcuEstimator("toy_est", "TOY_Sensors", lambda c: 1 if c.tick else 0, lambda c: c.tick > 0),)

    toy = Toy()
    register(toy)
    try:
        ecu = Ecu()
        assert ecu.health()["toy_est"] == "INIT" and "toy_est" in ecu.not_heard()
        ecu.step()
        assert ecu.health()["toy_est"] == "OK" and "toy_est" not in ecu.not_heard()
        assert {"dkf_t", "skfmec_q", "skfmec_a", "roll_ukf"} <= set(ecu.health())
    finally:
        unregister(toy)
    assert "toy_est" not in Ecu().health()
