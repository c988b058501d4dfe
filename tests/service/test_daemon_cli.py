"""The daemon's arguments and counters (issue 15): every bad duration is a clear error, lockstep honours
--duration, 16-bit counters become true totals on the host, and a bus never heard reads as such."""
from __future__ import annotations

import random
import threading
import time

import can
import pytest

from vehest_can.bus.frames import frame_id, message, unused_frame_id
from vehest_can.cli import main
from vehest_can.service.daemon import RX_FIFO, DaemonStats, EcuDaemon
from vehest_can.sim.session import run_inprocess
from vehest_can.systems import load_any_scenario
from vehest_can.systems.ecu import Ecu


@pytest.mark.parametrize("args, problem", [
    (["--duration", "nan"], "--duration must be a finite number of seconds > 0, not nan"),
    (["--duration", "inf"], "--duration must be a finite number of seconds > 0, not inf"),
    (["--duration", "-1"], "--duration must be a finite number of seconds > 0"),
    (["--mode", "lockstep", "--idle-timeout", "nan"], "--idle-timeout must be a finite number of seconds > 0, not nan"),
    (["--mode", "lockstep", "--idle-timeout", "-1"], "--idle-timeout must be a finite number of seconds > 0, not -1.0"),
    (["--idle-timeout", "5"], "--idle-timeout only applies to --mode lockstep"),
    (["--exit-on-end"], "--exit-on-end only applies to --mode lockstep"),
])
def test_bad_durations_are_clear_errors(capsys, args, problem):
    assert main(["daemon", *args, "-i", "virtual", "-c", "unused"]) == 1
    err = capsys.readouterr().err
    assert err.startswith("error: ") and problem in err and "Traceback" not in err, err


def test_lockstep_honours_duration(capsys):
    t0 = time.perf_counter()
    assert main(["daemon", "--mode", "lockstep", "--duration", "0.5", "-i", "virtual",
                 "-c", f"dur{random.random()}"]) == 0
    assert 0.5 <= time.perf_counter() - t0 < 10
    assert "mode lockstep: 0 ticks" in capsys.readouterr().err


def test_counters_are_true_totals_past_65535():
    """The C counters are uint32 and saturate, never wrap; VEHEST_Status carries each saturated at
    65535 with CntSaturated set (tests/test_counters.py drives the C directly)."""
    ecu = Ecu()
    ecu.note_deadline_miss(200_000)  # one stall longer than 65535 ticks
    assert ecu.counters()["deadline_miss"] == 200_000
    bad = bytearray(message("DLS_Sensors").length)  # a DLS_Sensors frame with a wrong CRC, 70 000 times
    bad[0] = 0x55
    msg = can.Message(arbitration_id=frame_id("DLS_Sensors"), is_extended_id=False, is_fd=True, data=bytes(bad))
    status = []
    for k in range(70_000):
        ecu.rx(msg)
        if k % 3 == 0:
            status += [m for m in ecu.step() if m.arbitration_id == frame_id("VEHEST_Status")]
    assert ecu.counters()["crc_error"] == 70_000
    last = message("VEHEST_Status").decode(status[-1].data)
    assert (last["CntCrcError"], last["CntDeadlineMiss"], last["CntSaturated"]) == (65535, 65535, 1)
    ecu.reset()
    assert ecu.counters()["crc_error"] == 0 and ecu.counters()["deadline_miss"] == 0


def test_a_bus_never_heard_is_not_a_fault():
    """A chassis-only run: the powertrain bus is never heard. No input_invalid every tick (it was
    20 000 in the demo's chassis run), and the summary says the driveline filters were not heard
    rather than showing them at INIT as if they had failed."""
    system, sc = load_any_scenario("chassis_relation_70kph")
    ecu = Ecu()
    session = run_inprocess(system.car(sc, 2.0), ecu)
    assert session.stats["counters"]["input_invalid"] == 0
    assert ecu.not_heard() == ["dkf_t", "dkf_s", "roll_ukf"]  # every system's estimators, roll's and SKFMEC-A's too
    stats = DaemonStats("lockstep", counters=ecu.counters(), health=ecu.health(), not_heard=ecu.not_heard())
    health = stats.lines()[-1]
    assert health.startswith("health: skfmec_q=OK, skfmec_a=OK; not heard (not configured or absent, not a fault): "
                             "dkf_t, dkf_s, roll_ukf (no DLS_Sensors or ROLL_Sensors since start)"), health
    assert "INIT" not in health


class StallingEcu(Ecu):
    """The real ECU, whose 20th step takes 0.5 s: the daemon descheduled, as on a loaded host."""

    def step(self, timestamp: float = 0.0):
        if self.tick == 20:
            time.sleep(0.5)
        return super().step(timestamp)


def test_realtime_receive_fifo_is_bounded_and_its_overruns_counted():
    """Frames that arrive while the daemon cannot tick wait in a receive FIFO of fixed size (RX_FIFO),
    not in a queue that grows with the stall; the oldest are dropped and counted."""
    channel = f"fifo{random.random()}"
    ecu_bus, sender = can.Bus(interface="virtual", channel=channel), can.Bus(interface="virtual", channel=channel)
    daemon = EcuDaemon(ecu_bus, StallingEcu())
    out = {}
    thread = threading.Thread(target=lambda: out.update(stats=daemon.serve_realtime(duration=1.5)))
    thread.start()
    try:
        time.sleep(0.2)  # inside the stall
        n = 3 * RX_FIFO
        for _ in range(n):
            sender.send(can.Message(arbitration_id=unused_frame_id(), is_extended_id=False, data=bytes(8)))
        thread.join(10)
    finally:
        sender.shutdown()
        ecu_bus.shutdown()
    st = out["stats"]
    assert st.rx_overrun >= n - RX_FIFO - 50, st.rx_overrun
    assert st.frames_rx + st.rx_overrun == n and st.counters["unknown_id"] == st.frames_rx
    assert any(line.startswith("receive FIFO overrun: ") for line in st.lines())
