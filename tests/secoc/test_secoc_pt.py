"""SecOC for the powertrain sensor frames (issue 15): DLS_Sensors (node DLS, 2 kHz) and CIS_Accel
(the camber inspection devices, node CIS, 100 Hz) secured by their nodes in the car
(vh_dlsim_set_secoc) and verified by the ECU in its one RX hook, as ROLL_Sensors is on the chassis
bus (tests/secoc/test_secoc_bus.py). Genuine traffic: 0 rejections, every frame verified, the ECU's
estimates those of the run with SecOC off; spoofed, replayed and bit-flipped frames: all rejected,
counted, flagged, and changing no estimate; in-process lockstep (one C loop) == tick by tick ==
lockstep over udp_multicast with the daemon, SecOC on."""
from __future__ import annotations

import random

import can
import numpy as np
import pytest
from secoc_bus_helpers import authentic, daemon_lockstep, dev_keys

from vehest_can.bus.busload import bus_load
from vehest_can.bus.frames import authentic_data, database, to_message
from vehest_can.bus.secoc import secured_messages
from vehest_can.paths import dbc_path
from vehest_can.sim.powertrain import powertrain_car
from vehest_can.sim.session import run_inprocess
from vehest_can.systems.camber.scenario import load_camber_scenario
from vehest_can.systems.ecu import Ecu

PT = database("pt")
DLS = PT.get_message_by_name("DLS_Sensors")
CIS = PT.get_message_by_name("CIS_Accel")
STATUS = PT.get_message_by_name("VEHEST_Status")
SC = load_camber_scenario("camber_inspection")
DURATION = 0.5  # s: 1000 DLS_Sensors, 50 CIS_Accel
SECURED = {fid for fid, (node, _, _, sync) in secured_messages().items() if node in ("DLS", "CIS") and not sync}


@pytest.fixture(scope="module")
def keys(tmp_path_factory):
    return dev_keys(tmp_path_factory)


def drive(keys=None, duration_s=DURATION):
    d = powertrain_car(SC, duration_s)
    return d.enable_secoc(keys) if keys else d


def ecu_for(keys=None) -> Ecu:
    ecu = Ecu()
    if keys:
        ecu.enable_secoc(keys)
    return ecu


def test_dbc_secures_both_sensor_frames_within_the_bus_load_budget():
    sec = secured_messages()
    assert sec[DLS.frame_id][0] == "DLS" and sec[CIS.frame_id][0] == "CIS"
    assert (DLS.length, CIS.length) == (20, 48)  # 16 + 4; 32 + 4 -> the 48-byte DLC
    syncs = {PT.get_message_by_frame_id(i).name for i, v in sec.items() if v[3] and v[0] in ("DLS", "CIS")}
    assert syncs == {"DLS_SecOCSync", "CIS_SecOCSync"}
    assert bus_load(dbc_path("pt")).worst_pct <= 60.0


def run_car(keys, attack=None, duration_s=DURATION):
    """The camber-inspection car and the ECU tick by tick (as the bus lockstep), SecOC on with keys
    (None: off). attack(k, frames) -> hostile frames for the ECU before the car's. Returns (ECU frames
    by tick, car frames by tick, car, ecu)."""
    car, ecu = drive(keys, duration_s), ecu_for(keys)
    out, sent = [], []
    for k in range(car.n):
        frames = [to_message(f) for f in car.tick(k)]
        for m in (attack(k, frames) if attack else []) + frames:
            ecu.rx(m)
        out.append(ecu.step())
        sent.append(frames)
    return out, sent, car, ecu


def test_genuine_traffic_zero_rejections_and_same_estimates_as_off(keys):
    on, car_on, car, ecu = run_car(keys)
    off, car_off, _, _ = run_car(None)
    c = ecu.secoc.counters()
    n_dls, n_cis = int(DURATION * 2000), int(DURATION * 100)
    assert c["rejected"] == 0 and c["accepted"] == n_dls + n_cis and c["syncs"] == 2  # DLS's and CIS's
    assert car.secoc["DLS"].counters()["secured"] == n_dls and car.secoc["CIS"].counters()["secured"] == n_cis
    assert ecu.counters()["secoc_reject"] == 0
    assert authentic(car_on) == authentic(car_off)  # the nodes' payloads: SecOC adds only the tails
    assert authentic(on) == authentic(off)          # ... and changes no estimate
    dls = [m for tick in car_on for m in tick if m.arbitration_id == DLS.frame_id]
    assert len(dls) == n_dls and all(len(m.data) == DLS.length and any(m.data[-3:]) for m in dls[:5])


def test_spoofed_replayed_and_flipped_frames_are_all_rejected_and_change_nothing(keys):
    """From 0.1 s, before the car's frames of every tick: a forged DLS_Sensors (random payload, MAC and
    FV), a replay of an earlier genuine DLS or CIS frame, a copy of the tick's DLS_Sensors with one
    payload bit flipped; at each CIS tick the same three for CIS_Accel."""
    rng = random.Random(15)
    seen: list[can.Message] = []
    sent = {"spoof": 0, "replay": 0, "flip": 0}
    so_far = {}

    def hostile(msg, genuine):
        forged = can.Message(arbitration_id=msg.frame_id, is_extended_id=False, is_fd=True,
                             data=bytes(rng.randrange(256) for _ in range(msg.length)))
        d = bytearray(genuine.data)
        bit = rng.randrange(8 * (msg.length - 4))
        d[bit // 8] ^= 1 << (bit % 8)
        flipped = can.Message(arbitration_id=msg.frame_id, is_extended_id=False, is_fd=True, data=bytes(d))
        old = [m for m in seen if m.arbitration_id == msg.frame_id][:-1]
        sent["spoof"] += 1
        sent["flip"] += 1
        sent["replay"] += 1
        return [forged, old[rng.randrange(len(old))], flipped]

    def attack(k, frames):
        genuine = {m.arbitration_id: m for m in frames if m.arbitration_id in SECURED}
        seen.extend(genuine.values())
        out = []
        if k >= 200:
            for msg in (DLS, CIS):
                if msg.frame_id in genuine:
                    out += hostile(msg, genuine[msg.frame_id])
        so_far[k] = sum(sent.values())
        return out

    on, _, _, ecu = run_car(keys, attack=attack)
    ref, _, _, _ = run_car(keys)
    c = ecu.secoc.counters()
    n_attacks = sum(sent.values())
    assert n_attacks == 3 * (int(DURATION * 2000) - 200 + int(DURATION * 100) - 10)
    assert c["rejected"] == n_attacks and c["bad_mac"] + c["replayed"] == n_attacks  # 100 %, by reason
    assert c["accepted"] == int(DURATION * 2100)                                      # genuine all through
    assert ecu.counters()["secoc_reject"] == n_attacks
    st = {k: STATUS.decode(authentic_data(m.arbitration_id, bytes(m.data)), decode_choices=False)
          for k, tick in enumerate(on) for m in tick if m.arbitration_id == STATUS.frame_id}
    assert all(d["CntSecocReject"] == so_far[k] % 65536 for k, d in st.items())
    assert all(bool(d["RxFaultActive"] & 8) == (k >= 200) for k, d in st.items())
    strip = [[f for f in tick if f[0] != STATUS.frame_id] for tick in authentic(on)]
    assert strip == [[f for f in tick if f[0] != STATUS.frame_id] for tick in authentic(ref)]


def test_a_car_without_keys_is_refused_by_a_secured_ecu(keys):
    """Fail closed: the sensor frames of a car without SecOC (zero tails) never reach the estimator."""
    car, ecu = drive(None, 0.05), ecu_for(keys)
    for k in range(car.n):
        for f in car.tick(k):
            ecu.rx(to_message(f))
        ecu.step()
    c = ecu.secoc.counters()
    assert c["accepted"] == 0 and c["rejected"] == c["unsynced"] == 100 + 5


def test_inprocess_lockstep_equals_tick_by_tick_and_bus_lockstep_with_secoc_on(keys, tmp_path):
    session, rc, err = daemon_lockstep(keys, drive(keys), tmp_path)
    assert rc == 0, err
    assert "SecOC: accepted" in err and "rejected 0," in err
    local = run_inprocess(drive(keys), ecu_for(keys))
    assert len(session.frames) == len(local.frames) > 2000
    assert np.array_equal(session.frames, local.frames)
    assert np.array_equal(session.truth, local.truth)
    on, car_frames, _, _ = run_car(keys)  # tick by tick from Python: the same frames, tails included
    flat = [(m.arbitration_id, bytes(m.data)) for k in range(len(on)) for m in car_frames[k] + on[k]]
    assert flat == [(int(f["id"]), bytes(f["data"][:f["len"]])) for f in local.frames]
    dls = local.frames[local.frames["id"] == DLS.frame_id]
    assert len(dls) == int(DURATION * 2000) and all(dls["len"] == DLS.length)
