"""SecOC on the bus, end to end (issue 15, point 3): the DBCs' secured layout within the bus-load
budget; the ECU verifying every secured frame in its one RX hook (vh_ecu_rx) and securing its own
in its one TX hook (vh_ecu_step); the roll node verifying the ECU's commands before it applies
them. Spoofed, replayed and bit-flipped frames are all rejected, counted and flagged, and change no
estimate and no actuator; restarts of either side resynchronise; a secured session log is checked
by an independent verifier written here from the spec with `cryptography`'s CMAC; lockstep over
udp_multicast is bit-exact with in-process, SecOC on."""
from __future__ import annotations

import random

import can
import numpy as np
import pytest
from secoc_bus_helpers import authentic, daemon_lockstep, dev_keys

from vehest_can.bus.busload import bus_load
from vehest_can.bus.frames import authentic_data, database, to_frame, to_message
from vehest_can.bus.log import read_log
from vehest_can.bus.secoc import FreshnessStore, Key, secured_messages
from vehest_can.native import ffi
from vehest_can.paths import dbc_path
from vehest_can.sim.session import run_inprocess
from vehest_can.systems.ecu import Ecu
from vehest_can.systems.roll.scenario import RollCar, load_roll_scenario

CH, PT = database("ch"), database("pt")
CMD = CH.get_message_by_name("VEHEST_RollCmd")
MODE = CH.get_message_by_name("ROLL_ModeCmd")
SENS = CH.get_message_by_name("ROLL_Sensors")
STATUS = PT.get_message_by_name("VEHEST_Status")
ACT = CH.get_message_by_name("ROLL_ActuatorStatus")
CHS = CH.get_message_by_name("CHS_Sensors")
RIDE = CH.get_message_by_name("CHS_RideHeight")
SCENARIO = "roll_paper_72kph_active"
#: the roll node's secured frames (its sync frame aside)
ROLL_SECURED = {fid for fid, (node, _, _, sync) in secured_messages().items() if node == "ROLL" and not sync}


@pytest.fixture(scope="module")
def keys(tmp_path_factory):
    return dev_keys(tmp_path_factory)


def secured_ecu(keys, store=None) -> Ecu:
    ecu = Ecu()
    ecu.enable_secoc(keys, store)
    return ecu


def secured_car(keys, duration_s: float, store=None) -> RollCar:
    car = RollCar(load_roll_scenario(SCENARIO), duration_s)
    car.enable_secoc(keys, store)
    return car


# ---- the layout ----------------------------------------------------------------------------------

def test_dbc_carries_the_secured_layout_within_the_bus_load_budget():
    sec = secured_messages()
    names = {CH.get_message_by_frame_id(i).name if i in {m.frame_id for m in CH.messages}
             else PT.get_message_by_frame_id(i).name for i in sec}
    assert {"VEHEST_RollCmd", "ROLL_ModeCmd", "ROLL_Sensors", "VEHEST_RollEst", "VEHEST_DrivelineEst",
            "VEHEST_Status", "VEHEST_SecOCSyncPt", "VEHEST_SecOCSyncCh", "ROLL_SecOCSync"} <= names
    for db in (CH, PT):
        for m in db.messages:
            if m.frame_id not in sec:
                continue
            sender, data_id, authentic, sync = sec[m.frame_id]
            sig = {s.name: s for s in m.signals}
            fv = next(s for n, s in sig.items() if n.endswith("_FV") or n.endswith("FV_Low"))
            mac = next(s for n, s in sig.items() if n.endswith("MAC"))
            assert authentic == m.length - 4 and fv.start == 8 * authentic and fv.length == 8, m.name
            assert mac.length == 24 and mac.byte_order == "big_endian", m.name
            # nothing of the authentic part reaches into the tail
            assert all(s.start + s.length <= 8 * authentic for s in m.signals
                       if s is not fv and s is not mac and s.byte_order == "little_endian"), m.name
            # the big-endian MAC signal reads the three bytes after the FV byte, MSB first
            data = bytes(authentic + 1) + b"\x12\x34\x56"
            assert m.decode(data, decode_choices=False, scaling=False)[mac.name] == 0x123456, m.name
    for bus in ("pt", "ch"):
        assert bus_load(dbc_path(bus)).worst_pct <= 60.0, bus


# ---- genuine traffic in process ------------------------------------------------------------------

def run_roll(keys, duration_s=1.0, attack=None, car_rx=None):
    """The roll car and the ECU tick by tick (as run_inprocess), SecOC on with keys (None: off).
    attack(k, frames) -> extra frames for the ECU before the car's; car_rx(k, frame) -> the frames
    the car gets for one of the ECU's. Returns (ECU frames by tick, truth, car, ecu)."""
    car = secured_car(keys, duration_s) if keys else RollCar(load_roll_scenario(SCENARIO), duration_s)
    ecu = secured_ecu(keys) if keys else Ecu()
    car.reset()
    out, truth = [], []
    for k in range(car.n):
        frames = [to_message(f) for f in car.tick(k)]
        for m in (attack(k, frames) if attack else []) + frames:
            ecu.rx(m)
        sent = ecu.step()
        for m in sent:
            for got in (car_rx(k, m) if car_rx else [m]):
                car.rx(got)
        out.append(sent)
        truth.append(car.truth())
    return out, np.array(truth), car, ecu


def test_genuine_traffic_zero_rejections_and_same_estimates_as_off(keys):
    on, truth_on, car, ecu = run_roll(keys)
    off, truth_off, _, _ = run_roll(None)
    c = ecu.secoc.counters()
    # every frame of 1 s of the roll node (610) and of the chassis sensor node (2000 CHS_Sensors), each
    # node's sync frame
    assert c["rejected"] == 0 and c["accepted"] == 3 * 200 + 10 + 2000 and c["syncs"] == 2
    assert car.secoc["ROLL"].counters()["rejected"] == 0 and car.node.cnt_rejected == 0
    assert car.secoc["ROLL"].counters()["accepted"] == 200          # every VEHEST_RollCmd of 1 s, verified
    assert ecu.counters()["secoc_reject"] == 0
    assert authentic(on) == authentic(off)                  # SecOC changes no estimate, no command
    assert np.array_equal(truth_on, truth_off)              # ... and nothing the actuators did
    cmds = [m for tick in on for m in tick if m.arbitration_id == CMD.frame_id]
    assert len(cmds) == 200 and all(len(m.data) == CMD.length and any(m.data[-3:]) for m in cmds[:5])


# ---- attacks: spoofed, replayed, flipped -----------------------------------------------------------

def test_spoofed_replayed_and_flipped_frames_are_all_rejected_and_change_nothing(keys):
    """At every 5 ms sensor tick after 0.1 s, three hostile frames reach the ECU before the genuine
    ones: a forged ROLL_Sensors (random MAC and FV), a replay of an earlier genuine frame of the roll
    node, and a copy of this tick's genuine ROLL_Sensors with one payload bit flipped. The same for
    the roll node: forged, replayed and flipped VEHEST_RollCmd frames beside the genuine ones."""
    rng = random.Random(15)
    seen: list[can.Message] = []
    sent = {"spoof": 0, "replay": 0, "flip": 0}
    so_far = {}  # tick -> hostile frames up to and including it

    def attack(k, frames):
        so_far[k] = sum(sent.values())
        genuine = [m for m in frames if m.arbitration_id in ROLL_SECURED]
        seen.extend(genuine)
        if k < 200 or not genuine:
            return []
        sens = next((m for m in genuine if m.arbitration_id == SENS.frame_id), None)
        out = [can.Message(arbitration_id=SENS.frame_id, is_extended_id=False, is_fd=True,
                           data=bytes(rng.randrange(256) for _ in range(SENS.length)))]
        out.append(seen[rng.randrange(len(seen) - len(genuine))])
        sent["spoof"] += 1
        sent["replay"] += 1
        if sens is not None:
            d = bytearray(sens.data)
            bit = rng.randrange(8 * (SENS.length - 4))
            d[bit // 8] ^= 1 << (bit % 8)
            out.append(can.Message(arbitration_id=SENS.frame_id, is_extended_id=False, is_fd=True, data=bytes(d)))
            sent["flip"] += 1
        so_far[k] = sum(sent.values())
        return out

    old_cmds: list[can.Message] = []

    def car_rx(k, m):
        if m.arbitration_id != CMD.frame_id or k < 200:
            old_cmds.append(m) if m.arbitration_id == CMD.frame_id else None
            return [m]
        d = bytearray(m.data)
        d[rng.randrange(CMD.length - 4)] ^= 1 << rng.randrange(8)
        forged = bytes(rng.randrange(256) for _ in range(CMD.length))
        hostile = [to_message(to_frame(can.Message(arbitration_id=CMD.frame_id, is_extended_id=False,
                                                   is_fd=True, data=x))) for x in (bytes(d), forged)]
        out = hostile + [old_cmds[rng.randrange(len(old_cmds))], m]
        old_cmds.append(m)
        return out

    on, truth, car, ecu = run_roll(keys, attack=attack, car_rx=car_rx)
    ref, truth_ref, _, _ = run_roll(keys)
    c = ecu.secoc.counters()
    n_attacks = sum(sent.values())
    assert n_attacks > 500 and sent["flip"] == sent["spoof"]
    assert c["rejected"] == n_attacks                              # 100 % rejected, each counted
    assert c["bad_mac"] + c["replayed"] == n_attacks and c["replayed"] >= sent["replay"] // 2
    assert ecu.counters()["secoc_reject"] == n_attacks
    # flagged in health: VEHEST_Status counts them and raises RxFaultActive bit 3
    st = {k: STATUS.decode(authentic_data(m.arbitration_id, bytes(m.data)), decode_choices=False)
          for k, tick in enumerate(on) for m in tick if m.arbitration_id == STATUS.frame_id}
    assert all(d["CntSecocReject"] == so_far[k] for k, d in st.items())
    assert all(bool(d["RxFaultActive"] & 8) == (k >= 200) for k, d in st.items())  # flagged from the attack on
    # no estimate affected: every frame but the status identical to the run without the attack
    strip = [[f for f in tick if f[0] != STATUS.frame_id] for tick in authentic(on)]
    assert strip == [[f for f in tick if f[0] != STATUS.frame_id] for tick in authentic(ref)]
    # no actuator affected: the roll node rejected every hostile command, the plant moved alike
    n_cmd_attacks = 3 * sum(1 for tick in on[200:] for m in tick if m.arbitration_id == CMD.frame_id)
    assert car.node.cnt_rejected == n_cmd_attacks > 400
    assert car.secoc["ROLL"].counters()["rejected"] == n_cmd_attacks
    assert np.array_equal(truth["m_applied"], truth_ref["m_applied"])
    assert np.array_equal(truth["phi"], truth_ref["phi"]) if "phi" in truth.dtype.names else True


def test_a_rejected_command_is_a_lost_one_hold_then_fail_safe(keys):
    """From 0.5 s every command reaches the actuators with one payload bit flipped: each is rejected
    by the roll node's SecOC check, so after the command timeout the actuators hold, then fail safe."""
    def car_rx(k, m):
        if m.arbitration_id != CMD.frame_id or k < 1000:
            return [m]
        d = bytearray(m.data)
        d[2] ^= 0x01
        return [can.Message(arbitration_id=m.arbitration_id, is_extended_id=False, is_fd=True, data=bytes(d))]

    on, truth, car, ecu = run_roll(keys, duration_s=1.0, car_rx=car_rx)
    assert car.node.cnt_rejected == 100 and car.node.cnt_timeout == 1
    assert truth["arc_state"][990] == 1 and truth["arc_state"][1045] == 2 and truth["arc_state"][-1] == 3


# ---- restarts ------------------------------------------------------------------------------------

def test_resync_after_a_restart_of_either_side(keys, tmp_path):
    """Each side with a freshness state file: the ECU restarted mid-run resumes above every FV it sent
    and its sync frame (its first frame) resynchronises the roll node at once; the roll node restarted
    likewise; a receiver restarted without state is unsynchronised only until the next sync frame."""
    ecu_store, car_store = FreshnessStore(tmp_path / "ecu.json"), FreshnessStore(tmp_path / "roll.json")
    car = secured_car(keys, 3.0, car_store)
    ecu = secured_ecu(keys, ecu_store)

    def run(ticks, ecu, car, k0):
        for k in range(k0, k0 + ticks):
            for f in car.tick(k):
                ecu.rx_frame(ffi.addressof(f))
            for f in ecu.step_frames():
                car.rx(ffi.addressof(f))
        return k0 + ticks

    k = run(2000, ecu, car, 0)
    fv_before = int(ecu.secoc.c.tx.fv)
    ecu.secoc.close()  # a clean stop: the exact state (a crash's margin: test_secoc_state.py)
    rej0 = car.node.cnt_rejected
    ecu2 = secured_ecu(keys, FreshnessStore(tmp_path / "ecu.json"))  # the ECU process restarted
    assert int(ecu2.secoc.c.tx.fv) >= fv_before                      # above every FV it ever sent
    k = run(400, ecu2, car, k)
    assert car.node.cnt_rejected == rej0 and car.secoc["ROLL"].counters()["syncs"] >= 2
    assert ecu2.secoc.counters()["rejected"] == 0                    # it remembered the roll node
    for s in car.secoc_hooks():
        s.close()
    car2 = RollCar(load_roll_scenario(SCENARIO), 3.0)                 # the roll node restarted
    car2.enable_secoc(keys, FreshnessStore(tmp_path / "roll.json"))
    before = ecu2.secoc.counters()
    for kk in range(k, k + 400):   # car2's first tick carries its sync frame: the ECU follows at once
        for f in car2.tick(kk - k):
            ecu2.rx_frame(ffi.addressof(f))
        for f in ecu2.step_frames():
            car2.rx(ffi.addressof(f))
    after = ecu2.secoc.counters()
    assert after["rejected"] == before["rejected"] and after["syncs"] == before["syncs"] + 2
    assert after["accepted"] - before["accepted"] == 3 * 40 + 2 + 400  # every frame of car2's 200 ms
    assert car2.secoc["ROLL"].counters()["rejected"] == 0 and car2.node.cnt_rejected == 0  # restored: in sync
    # a receiver without state (a new ECU, no state file): unsynced until the roll node's next sync
    ecu3 = Ecu()
    ecu3.enable_secoc(keys)
    for kk in range(2000):
        for f in car2.tick(400 + kk):
            ecu3.rx_frame(ffi.addressof(f))
        ecu3.step_frames()
    c3 = ecu3.secoc.counters()
    assert c3["syncs"] == 2 and c3["unsynced"] == c3["rejected"] > 0 and c3["accepted"] > 0


# ---- an independent verifier on a secured log ---------------------------------------------------------

def independent_check(messages, keys: dict[str, Key]):
    """From the spec, with `cryptography`'s CMAC only: per sending node the freshness is rebuilt
    from its sync frames (the full FV in bytes 0..7) and the low FV byte of each frame; each frame's
    MAC = the 3 most significant bytes of CMAC-AES-128(key, data ID BE16 | authentic | FV BE64).
    Returns (verified, failed) counts."""
    cmac = pytest.importorskip("cryptography.hazmat.primitives.cmac")
    from cryptography.hazmat.primitives.ciphers import algorithms

    def mac(key, data_id, authentic, fv):
        c = cmac.CMAC(algorithms.AES128(key))
        c.update(data_id.to_bytes(2, "big") + authentic + fv.to_bytes(8, "big"))
        return c.finalize()[:3]

    sec = secured_messages()
    latest: dict[str, int] = {}
    ok = bad = 0
    for m in messages:
        if m.arbitration_id not in sec or m.is_extended_id:
            continue
        node, data_id, n, sync = sec[m.arbitration_id]
        data = bytes(m.data)
        if sync:
            fv = int.from_bytes(data[:8], "big")
        elif node in latest:
            fv = (latest[node] & ~0xFF) | data[n]
            fv += 0x100 if fv <= latest[node] else 0
        else:
            continue  # before the sender's first sync frame
        if data[n] == fv & 0xFF and mac(keys[node].raw, data_id, data[:n], fv) == data[n + 1:n + 4] \
                and fv > latest.get(node, 0):
            latest[node] = fv
            ok += 1
        else:
            bad += 1
    return ok, bad


def test_secured_session_log_verified_independently(keys, tmp_path):
    session = run_inprocess(secured_car(keys, 0.5), secured_ecu(keys))
    with can.Logger(str(tmp_path / "secured.log")) as w:
        for m in session.messages():
            w.on_message_received(m)
    msgs = list(read_log(tmp_path / "secured.log"))
    ok, bad = independent_check(msgs, keys)
    n_secured = sum(1 for m in msgs if m.arbitration_id in secured_messages())
    assert bad == 0 and ok == n_secured > 2500          # every secured frame of 0.5 s, all three nodes
    assert sum(1 for m in msgs if m.arbitration_id == CHS.frame_id) == 1000  # CHS_Sensors among them
    # one flipped bit anywhere in a secured frame and the independent check refuses it
    i = next(j for j, m in enumerate(msgs) if m.arbitration_id == CMD.frame_id)
    d = bytearray(msgs[i].data)
    d[3] ^= 0x10
    msgs[i] = can.Message(arbitration_id=CMD.frame_id, is_extended_id=False, is_fd=True, data=bytes(d))
    assert independent_check(msgs, keys)[1] == 1


@pytest.mark.slow
def test_chassis_sensor_frames_secured_and_verified_independently(keys):
    """The tyre-force car (the chassis sensor node with ride heights, the inputs of the tyre-force,
    mass and friction estimation): CHS_Sensors and CHS_RideHeight secured, every MAC verified by the
    independent verifier, none rejected by the ECU, every estimate as with SecOC off; a tampered
    CHS_Sensors is rejected and changes nothing."""
    from vehest_can.sim.veh14 import Veh14Car
    from vehest_can.systems.tireforce.scenario import load_tireforce_scenario

    sc = load_tireforce_scenario("chassis_paper_mu_drop")
    car = Veh14Car(sc, 0.5)
    car.enable_secoc(keys)
    ecu = secured_ecu(keys)
    on = run_inprocess(car, ecu)
    msgs = list(on.messages())
    ok, bad = independent_check(msgs, keys)
    n = {fid: sum(1 for m in msgs if m.arbitration_id == fid) for fid in (CHS.frame_id, RIDE.frame_id)}
    assert bad == 0 and ok == sum(1 for m in msgs if m.arbitration_id in secured_messages())
    assert n == {CHS.frame_id: 1000, RIDE.frame_id: 50}
    c = ecu.secoc.counters()
    assert c["rejected"] == 0 and c["accepted"] == 1050 and c["syncs"] == 1
    off = run_inprocess(Veh14Car(sc, 0.5), Ecu())
    by_tick = lambda s: [[m for m, k in zip(s.messages(), s.frame_tick) if k == t] for t in range(s.frame_tick[-1] + 1)]  # noqa: E731
    assert authentic(by_tick(on)) == authentic(by_tick(off))  # SecOC changes no estimate
    # tampered: one bit of the payload of a genuine CHS_Sensors
    i = next(j for j, m in enumerate(msgs) if m.arbitration_id == CHS.frame_id)
    d = bytearray(msgs[i].data)
    d[5] ^= 0x04
    msgs[i] = can.Message(arbitration_id=CHS.frame_id, is_extended_id=False, is_fd=True, data=bytes(d))
    assert independent_check(msgs, keys)[1] == 1
    ecu2 = secured_ecu(keys)
    for m in msgs[:i + 1]:
        if m.arbitration_id in {CHS.frame_id, RIDE.frame_id} or secured_messages().get(m.arbitration_id, ("",))[0] == "CHS":
            ecu2.rx(m)
    assert ecu2.secoc.counters()["bad_mac"] == 1


# ---- lockstep over the bus -----------------------------------------------------------------------

@pytest.mark.multicast
def test_lockstep_over_multicast_equals_inprocess_with_secoc_on(keys, tmp_path):
    session, rc, err = daemon_lockstep(keys, secured_car(keys, 1.0), tmp_path)
    assert rc == 0, err
    assert "SecOC: accepted" in err and "rejected 0," in err
    local = run_inprocess(secured_car(keys, 1.0), secured_ecu(keys))
    assert len(session.frames) == len(local.frames) > 4000
    assert np.array_equal(session.frames, local.frames)
    assert np.array_equal(session.truth, local.truth)
    cmds = session.frames[session.frames["id"] == CMD.frame_id]
    assert len(cmds) == 200 and all(cmds["len"] == CMD.length)


@pytest.mark.multicast
def test_daemon_secoc_flags_give_clear_errors(tmp_path):
    import subprocess
    import sys

    def daemon(*args):
        return subprocess.run([sys.executable, "-m", "vehest_can.cli", "daemon", "--duration", "0.1", *args],
                              capture_output=True, text=True, timeout=60)

    loose = tmp_path / "loose.toml"
    loose.write_text('[keys]\nVEHEST = "00112233445566778899aabbccddeeff"\n')
    loose.chmod(0o644)
    for args, words in ((("--secoc-keys", str(loose)), "too open"),
                        (("--secoc-state", str(tmp_path / "s.json")), "--secoc-state needs --secoc-keys"),
                        (("--secoc-keys", str(tmp_path / "none.toml")), "cannot read key file")):
        r = daemon(*args)
        assert r.returncode != 0 and words in r.stderr and "Traceback" not in r.stderr, (args, r.stderr)
        assert "0011223344" not in r.stderr + r.stdout
