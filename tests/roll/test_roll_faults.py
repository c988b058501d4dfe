"""The roll system's faults: a dead suspension-deflection sensor, a stuck vertical accelerometer, a missing
yaw-rate frame and lost actuator command frames, each injected on the bus (the FaultStudy protocol, as
`vehest-can faults --scenario roll_paper_72kph_active` runs them): detected, flagged in health, the
controller fades to passive, the actuators end at zero moment (for lost commands: the plant's actuators
fail safe and say so). A sensor the robust UKF does not use (a wheel's vertical accelerometer) is
detected and said on the bus without degrading the loop."""
import numpy as np
import pytest

from vehest_can.bus.frames import database
from vehest_can.faults.campaign import analyse, run_with_faults
from vehest_can.faults.spec import faults_from_cli
from vehest_can.systems.roll.faults import FAULTS
from vehest_can.systems.roll.scenario import RollCar, load_roll_scenario

DB = database("ch")
STATUS = DB.get_message_by_name("ROLL_ActuatorStatus")
EST = DB.get_message_by_name("VEHEST_RollEst")
CASES = {c.label: c for c in FAULTS.catalogue}
START, END = 4000, 5000   # ticks of the catalogue's 2.0-2.5 s window
MISSING = {"dead suspension-deflection sensor (FL)": 1 << 9, "missing yaw-rate frame": 1 << 13}
#: faults of a sensor the robust UKF does not use (the unsprung accelerations): detected and said, not degrading
UNUSED = {"stuck vertical accelerometer (FL wheel)": 1 << 1}


def fault_run(label: str):
    case = CASES[label]
    car = RollCar(load_roll_scenario("roll_paper_72kph_active"), 2.6)
    return run_with_faults(car, faults_from_cli([case.fault] if case.fault else [], seed=1), study=FAULTS)


def status_at(run, k):
    for tick in range(k, k - 20, -1):
        for m in run.rx[tick]:
            if m.arbitration_id == STATUS.frame_id:
                return STATUS.decode(bytes(m.data), decode_choices=False)
    raise AssertionError(f"no ROLL_ActuatorStatus near tick {k}")


@pytest.mark.parametrize("label", list(MISSING) + ["lost actuator command frames"])
def test_fault_detected_flagged_faded_and_zero_moment(label):
    run = fault_run(label)
    row = analyse(run, label, CASES[label].fault, CASES[label].expect, (2.0, 2.5))
    assert all(row.detected.get(c, 0) > 0 for c in CASES[label].expect), row.detected
    est = FAULTS._decoded(run.est)
    before, late = START - 10, END - 10
    assert est["RollFade"][before] == 1.0 and est["RollSmc_Health"][before] == 0   # active, full moment before
    if label in UNUSED:
        assert int(est["RollMeasMissing"][late]) & UNUSED[label]                     # said on the bus
        assert est["RollUkf_Health"][late] == 1 and est["RollFade"][late] == 1.0     # the loop carries on
        return
    assert est["RollFade"][late] == 0.0                                             # faded to passive
    assert int(est["RollSmc_Health"][late]) & 64                                     # tripped, says why:
    if label in MISSING:
        assert int(est["RollMeasMissing"][late]) & MISSING[label]                    # the measurement removed
        assert est["RollUkf_Health"][late] == 2 and not run.valid("UKF")[late]      # the UKF DEGRADED
    else:
        assert int(est["RollRxFault"][late]) & 16                                    # actuators HOLD / FAILSAFE
        assert status_at(run, START + 45)["ArcState"] == 2                           # holding after 20 ms
        assert status_at(run, late)["ArcState"] == 3                                 # then failed safe
    s = status_at(run, late)
    assert abs(s["AppliedMomentF"]) < 50.0 and abs(s["AppliedMomentR"]) < 50.0      # no moment left
    assert abs(status_at(run, before)["AppliedMomentF"]) > 500.0                      # acting before


def test_reference_run_keeps_everything_ok():
    run = fault_run("none (reference)")
    est = FAULTS._decoded(run.est)
    sel = slice(START, END)
    assert np.all(est["RollUkf_Health"][sel] == 1) and np.all(est["RollFade"][sel] == 1.0)
    assert status_at(run, END - 10)["ArcState"] == 1


def test_signal_faults_parse_validate_and_round_trip():
    from vehest_can.errors import ConfigError
    from vehest_can.faults.spec import parse_fault

    spec = parse_fault("sna:ROLL_Sensors:signal=SuspDeflFL:2-2.5")
    assert parse_fault(spec.text()) == spec and spec.signal == "SuspDeflFL"
    for bad, why in (("sna:ROLL_Sensors:signal=Nope", "not a signal"), ("stuck:ROLL:signal=SuspDeflFL", "one message"),
                     ("drop:ROLL_Sensors:signal=SuspDeflFL", "not an amount"),
                     ("sna:ROLL_Sensors:signal=Qf_SuspDeflFL", "no SNA")):
        with pytest.raises(ConfigError, match=why):
            parse_fault(bad)


def outage_run(ms: int):
    """Every frame on the bus lost for `ms` from 2.0 s (both nodes and the ECU's commands: what a
    stalled host does to a real-time run)."""
    car = RollCar(load_roll_scenario("roll_paper_72kph_active"), 2.6)
    return run_with_faults(car, faults_from_cli([f"silence:*:2-{2 + ms / 1000:g}"], seed=1), study=FAULTS)


def test_a_short_total_outage_is_ridden_through_a_long_one_trips():
    """Ride-through (docs/roll.md): the controller holds its fade while the estimate is not OK for up to
    not_ok_debounce (60 ms = 12 sensor frames), acting on the UKF's prediction; a 40 ms outage of
    every frame (the estimate DEGRADED, the actuators time out: HOLD, FAILSAFE at 40 ms, until commands
    return) does not trip it,
    a 200 ms one does, and fades it out."""
    short, long_ = outage_run(40), outage_run(200)
    for run in (short, long_):
        est = FAULTS._decoded(run.est)
        assert est["RollFade"][START - 10] == 1.0 and est["RollSmc_Health"][START - 10] == 0
        assert np.any(est["RollUkf_Health"][START:START + 200] == 2)       # seen: the estimate DEGRADED
    est = FAULTS._decoded(short.est)
    sel = slice(START, END)
    assert not np.any(est["RollSmc_Health"][sel].astype(int) & 64)           # never tripped
    assert np.all(est["RollFade"][sel] == 1.0)
    states = {int(STATUS.decode(bytes(m.data), decode_choices=False)["ArcState"])
              for k in range(START, START + 200) for m in short.rx[k] if m.arbitration_id == STATUS.frame_id}
    assert states & {2, 3} and status_at(short, START + 400)["ArcState"] == 1   # timed out, then active again
    est = FAULTS._decoded(long_.est)
    assert int(est["RollSmc_Health"][START + 300]) & 64 and est["RollFade"][END - 10] == 0.0
