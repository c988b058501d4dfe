"""Every E2E-protected frame on the project's buses as an AUTOSAR node sees it: the frames the car's
nodes and the ECU send in every system's shipped scenario pass the independent ``autosar-e2e``
library's check for the profile and data ID mode their DBC gives, and frames that library protects
are taken by the ECU. The E2E parameters are read here from the DBC attributes, not from the
firmware's generated table (c_core/dbcgen.py), so a wrong table fails too."""
import can
import e2e.p01
import e2e.p02
import e2e.p05
import numpy as np
import pytest

from vehest_can.bus.frames import BUSES, authentic_data, database, message_by_id
from vehest_can.bus.secoc import write_dev_keys
from vehest_can.cli.secoc import sending_nodes
from vehest_can.sim.session import run_inprocess
from vehest_can.systems import registered
from vehest_can.systems.ecu import Ecu

P01_MODES = {"BOTH": e2e.p01.E2E_P01_DATAID_BOTH, "ALT": e2e.p01.E2E_P01_DATAID_ALT,
             "LOW": e2e.p01.E2E_P01_DATAID_LOW, "NIBBLE": e2e.p01.E2E_P01_DATAID_NIBBLE}


def dbc_e2e(msg) -> tuple[str, dict] | None:
    """(profile, the library's keyword arguments) of a message, from its DBC attributes."""
    attrs = msg.dbc.attributes
    profile = str(attrs["E2EProfile"].value) if "E2EProfile" in attrs else ""
    if not profile:
        return None
    data_id = int(attrs["E2EDataID"].value)
    if profile == "P01":
        mode = str(attrs["E2EDataIDMode"].value) if "E2EDataIDMode" in attrs else "BOTH"
        return profile, {"data_id": data_id, "data_id_mode": P01_MODES[mode]}
    if profile == "P02":
        return profile, {"data_id_list": bytes(int(w, 0) for w in str(attrs["E2EDataIDList"].value).split())}
    return profile, {"data_id": data_id}


def library_check(profile: str, kw: dict, data: bytes) -> bool:
    fn = {"P01": e2e.p01.e2e_p01_check, "P02": e2e.p02.e2e_p02_check, "P05": e2e.p05.e2e_p05_check}[profile]
    return fn(bytearray(data), *kw.values()) if profile == "P02" else fn(bytearray(data), kw["data_id"],
                                                                           **{k: v for k, v in kw.items() if k != "data_id"})


def test_every_protected_message_has_a_profile_the_library_knows():
    protected = [m for b in BUSES for m in database(b).messages if dbc_e2e(m) is not None]
    assert len(protected) >= 15
    assert {dbc_e2e(m)[0] for m in protected} == {"P01"}  # the shipped buses: Profile 1, data ID mode BOTH


def _first_scenario(system):
    return system.load(sorted(system.scenario_dir().glob("*.toml"))[0])


@pytest.fixture(scope="module")
def sessions(tmp_path_factory):
    """One shipped scenario of every system, 1 s, in process, SecOC on as in the demo."""
    keys = write_dev_keys(tmp_path_factory.mktemp("keys") / "keys.toml", sending_nodes())
    out = {}
    for system in registered():
        car = system.car(_first_scenario(system), 1.0)
        if hasattr(car, "enable_secoc"):
            car.enable_secoc(keys)
        ecu = Ecu()
        ecu.enable_secoc(keys)
        out[system.name] = run_inprocess(car, ecu)
    return out


def test_the_library_accepts_every_frame_sent(sessions):
    seen = {}
    for s in sessions.values():
        for m in s.messages():
            try:
                msg = message_by_id(m.arbitration_id)
            except KeyError:
                continue
            cfg = dbc_e2e(msg)
            if cfg is None:
                continue
            ok = library_check(*cfg, authentic_data(m.arbitration_id, bytes(m.data)))
            good, total = seen.get(msg.name, (0, 0))
            seen[msg.name] = (good + ok, total + 1)
    bad = {k: v for k, v in seen.items() if v[0] != v[1]}
    assert not bad, bad
    # the sensor frames and the ECU's frames of every system were there
    assert {"DLS_Sensors", "VEHEST_DrivelineEst", "CHS_Sensors", "CHS_RideHeight", "VEHEST_TireForceEst",
            "ROLL_Sensors", "VEHEST_RollCmd", "VEHEST_RollEst"} <= set(seen), sorted(seen)


def test_the_ecu_takes_frames_the_library_protects(sessions):
    """The tyre-force run's sensor frames with their E2E header cleared and protected again by the
    library (its counter running on from 0): an ECU (SecOC off, the frames' tails zeroed) refuses none
    and estimates as from the originals."""
    s = sessions["tireforce"]
    counters: dict[int, int] = {}
    original, relabelled = [], []
    for m in s.messages():
        m = can.Message(arbitration_id=m.arbitration_id, is_extended_id=m.is_extended_id, is_fd=m.is_fd,
                        data=authentic_data(m.arbitration_id, bytes(m.data)))
        original.append(m)
        data = bytearray(m.data)
        try:
            cfg = dbc_e2e(message_by_id(m.arbitration_id)) if not m.is_extended_id else None
        except KeyError:
            cfg = None
        if cfg is not None and m.arbitration_id in (0x110, 0x111):  # CHS_Sensors, CHS_RideHeight
            k = counters.get(m.arbitration_id, -1)
            data[0] = 0
            data[1] = (data[1] & 0xF0) | (k % 15)  # the library advances the counter it finds
            e2e.p01.e2e_p01_protect(data, **cfg[1])
            counters[m.arbitration_id] = k + 1
        relabelled.append(can.Message(arbitration_id=m.arbitration_id, is_extended_id=m.is_extended_id,
                                      is_fd=m.is_fd, data=bytes(data)))
    assert min(counters.values()) >= 90  # 1 s: 2000 CHS_Sensors, 100 CHS_RideHeight
    estimates = {}
    for label, frames in (("original", original), ("library", relabelled)):
        ecu = Ecu()
        out = []
        sensor_ids = {0x110, 0x111}
        by_tick: dict[int, list] = {}
        for f, k in zip(frames, s.frame_tick):
            if f.arbitration_id in sensor_ids:
                by_tick.setdefault(int(k), []).append(f)
        for k in range(int(s.frame_tick.max()) + 1):
            for f in by_tick.get(k, []):
                ecu.rx(f)
            out += [bytes(m.data) for m in ecu.step() if m.arbitration_id == 0x190]  # VEHEST_TireForceEst
        c = ecu.chassis_counters()
        assert c["crc_error"] == 0 and c["counter_repeat"] == 0 and c["counter_skip"] == 0, (label, c)
        estimates[label] = out
    assert len(estimates["original"]) > 100
    assert estimates["original"] == estimates["library"]
    assert np.any([e != estimates["original"][0] for e in estimates["original"]])


def test_the_firmware_table_is_the_dbc():
    """c_core/dbcgen.py's table (what the ECU, the car's nodes and the host tools use) against the
    attributes read here, message by message; and a frame E2ESender protects passes the library."""
    from frames_oracle import E2ESender

    from vehest_can.bus.frames import e2e_config

    profiles = {"P01": 1, "P02": 2, "P05": 5}
    for bus in BUSES:
        sender = E2ESender(bus)
        for m in database(bus).messages:
            want, cfg = dbc_e2e(m), e2e_config(m)
            assert (cfg is None) == (want is None), m.name
            if want is None:
                continue
            assert (cfg.profile, cfg.data_id) == (profiles[want[0]], want[1].get("data_id", 0)), m.name
            for _ in range(3):
                frame = sender.message(m.name, {})
                assert library_check(*want, bytes(frame.data)), m.name
