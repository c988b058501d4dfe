"""The roll system (seed 003: float32 UKF + sliding-mode control) through the ECU's XCP slave: its
tuning on the calibration page, its internals as measurements, by their C names; a gain written
over XCP drives the commanded moment exactly as a start with it would; out-of-range writes refused.

Raw CRO frames into the firmware (as test_xcp_ecu.py); pyxcp against the daemon: test_xcp_daemon.py."""
from __future__ import annotations

import struct

import numpy as np
import pytest
from test_xcp_ecu import ERR, ERR_OUT_OF_RANGE, KEY, Cro

from vehest_can.bus.frames import database
from vehest_can.native import check, ffi, lib
from vehest_can.sim.session import run_inprocess
from vehest_can.systems.ecu import Ecu
from vehest_can.systems.roll.scenario import RollCar, load_roll_scenario
from vehest_can.xcp import ecu as xcp_ecu

CMD = database("ch").get_message_by_name("VEHEST_RollCmd")
ACTIVE = "roll_paper_72kph_active"


def test_roll_tuning_and_internals_are_described_by_their_c_names():
    desc = xcp_ecu.description()
    chars = {it.name for it in desc.characteristics}
    assert {f"cal.app.roll.ukf.{m}" for m in ("q", "r", "p0", "reg_eps", "nis_max", "phi_max")} <= chars
    assert {f"cal.app.roll.smc.{m}" for m in ("lambda", "k", "p", "ref_frac", "ref_tau", "ay_tau", "front_share",
                                          "m_max_f", "m_max_r", "rate_max_f", "rate_max_r", "fade_time",
                                          "recover_time", "not_ok_debounce")} <= chars
    meas = {it.name for it in desc.measurements}
    assert {"app.roll.ukf.x[4]", "app.roll.ukf.x[5]", "app.roll.ukf.P[88]", "app.roll.ukf.P[440]", "app.roll.ukf.nu[13]",
            "app.roll.ukf.health", "app.roll.ukf.resets", "app.roll.smc.m_f", "app.roll.smc.m_r", "app.roll.smc.s",
            "app.roll.smc.fade", "app.roll.smc.health", "app.roll.cnt.crc_error", "app.roll.cnt.timeout"} <= meas
    assert desc.item("cal.app.roll.smc.k").address - desc.calibration_address == \
        ffi.offsetof("vh_ecu_cal_t", "app", "roll", "smc", "k")
    assert desc.item("app.roll.smc.m_f").address - desc.measurement_address == \
        ffi.offsetof("vh_ecu_t", "app", "roll", "smc", "m_f")
    assert desc.item("cal.app.roll.ukf.r").shape == (lib.VH_ROLL_NZ,)
    # the reference page is the configured tuning
    ecu = Ecu()
    xcp_ecu.enable(ecu, KEY)
    assert xcp_ecu.read(ecu, "cal.app.roll.ukf.r", "ref") == list(ecu.c.app.roll.cfg.ukf.r)
    assert xcp_ecu.read(ecu, "cal.app.roll.smc.k", "ref") == ecu.c.app.roll.cfg.smc.k == 5.0


def _commands(session) -> np.ndarray:
    f = session.frames
    return f[f["id"] == CMD.frame_id]


def _moments(cmds) -> np.ndarray:
    return np.array([[CMD.decode(bytes(d))[s] for s in ("MomentCmdF", "MomentCmdR")] for d in cmds["data"]])


def _started_with(**smc) -> Ecu:
    """An ECU configured (vh_ecu_init) with these controller values: the run to compare against."""
    ecu = Ecu()
    cfg = ffi.new("vh_ecu_config_t *")
    cfg[0] = ecu._c_config[0]
    for k, v in smc.items():
        setattr(cfg.app.roll.smc, k, v)
    check(lib.vh_ecu_init(ecu.c, cfg), "roll configuration")
    return ecu


def test_a_roll_gain_written_over_xcp_commands_the_moment_a_start_with_it_would():
    """Lockstep: the switching gain k written through XCP gives the same VEHEST_RollCmd frames, bit
    for bit, as an ECU configured with it; and not the default's: the commanded moment changes."""
    k = 4.0 * Ecu().c.app.roll.cfg.smc.k
    started = _started_with(k=k)
    calibrated = Ecu()
    cro = Cro(calibrated)
    cro.connect_unlocked()
    assert cro.download(cro.desc.item("cal.app.roll.smc.k").address, struct.pack("<d", k))[0] == 0xFF
    assert calibrated.c.app.roll.smc.k == k == calibrated.c.app.roll.cfg.smc.k  # at the tick boundary, in both
    calibrated.reset()  # the session's reset: the calibration stays
    a, b, default = (_commands(run_inprocess(RollCar(load_roll_scenario(ACTIVE)), e))
                     for e in (started, calibrated, Ecu()))
    assert len(a) == len(b) == len(default) > 1000
    assert np.array_equal(a, b)
    ma, md = _moments(a), _moments(default)
    diff = np.max(np.abs(ma - md))
    print(f"k {k / 4} -> {k}: VEHEST_RollCmd bit-exact with a start at k = {k}; peak |M| front/rear "
          f"{np.max(np.abs(md), axis=0)} -> {np.max(np.abs(ma), axis=0)} Nm, largest change {diff:.0f} Nm")
    assert diff > 50.0


@pytest.mark.parametrize("name, bad", [
    ("cal.app.roll.smc.k", 0.0), ("cal.app.roll.smc.k", float("nan")), ("cal.app.roll.smc.lambda", -1.0),
    ("cal.app.roll.smc.m_max_f", 5000.0),    # above the actuator's 4800 Nm
    ("cal.app.roll.smc.rate_max_r", 15000.0),  # the fade could outrun the rate limit
    ("cal.app.roll.smc.fade_time", 0.2), ("cal.app.roll.ukf.r", 0.0), ("cal.app.roll.ukf.q", float("inf")),
])
def test_out_of_range_roll_writes_are_refused_counted_and_never_reach_the_controller(name, bad):
    ecu = Ecu()
    cro = Cro(ecu)
    cro.connect_unlocked()
    it = cro.desc.item(name)
    before = xcp_ecu.read(ecu, name)
    assert cro.download(it.address, struct.pack("<d", bad))[:2] == bytes([ERR, ERR_OUT_OF_RANGE])
    for _ in range(250):  # past open_ticks: nothing left open to commit
        ecu.step()
    assert xcp_ecu.read(ecu, name) == before and xcp_ecu.read(ecu, name, "work") == before
    assert xcp_ecu.counters(ecu)["err_range"] == 1
    assert lib.vh_roll_app_check(ffi.addressof(ecu.c.app.roll, "cfg")) == lib.VH_OK


def test_a_stuck_check_cannot_be_switched_off_over_xcp():
    ecu = Ecu()
    cro = Cro(ecu)
    cro.connect_unlocked()
    a = cro.desc.item("cal.app.roll.stuck_samples").address
    for bad in (0, 1):
        assert cro.download(a, bytes([bad]))[:2] == bytes([ERR, ERR_OUT_OF_RANGE])
    assert cro.download(a, bytes([20]))[0] == 0xFF
    ecu.step()
    assert ecu.c.app.roll.cfg.stuck_samples == 20


def test_every_roll_characteristic_at_its_limits_keeps_the_configuration_valid():
    """The limits hold for every combination (the slave checks element by element): both corners of
    the box reach the controller, and the roll app's own check accepts them."""
    for corner in (0, 1):
        ecu = Ecu()
        xcp_ecu.enable(ecu, KEY)
        cro = Cro.__new__(Cro)
        cro.ecu, cro.desc, cro.other = ecu, xcp_ecu.description(), []
        cro.connect_unlocked()
        for it in cro.desc.characteristics:
            if not it.name.startswith("cal.app.roll."):
                continue
            raw = it.raw_limits()[corner]
            fmt = "<" + ("B" if it.ctype == "uint8_t" else "d") * it.count
            assert cro.download(it.address, struct.pack(fmt, *[int(raw) if it.ctype == "uint8_t" else raw] * it.count))[0] == 0xFF
        for _ in range(3):
            ecu.step()
        assert ecu.c.app.roll.cfg.smc.m_max_f == (1.0, 4800.0)[corner]
        assert lib.vh_roll_app_check(ffi.addressof(ecu.c.app.roll, "cfg")) == lib.VH_OK, corner
