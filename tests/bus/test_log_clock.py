"""Which clock a session log keeps: real-time nodes log when a frame was on the bus (wall clock), so a
run that the machine stretched shows its true length; lockstep logs keep simulated time (covered by
tests/bus/test_log.py and the replay tests, which map lockstep logs back to ticks)."""
import threading
import time
import uuid

import can

from vehest_can.bus.frames import TICK_S, unused_frame_id
from vehest_can.bus.log import SessionLog, read_log
from vehest_can.service.daemon import EcuDaemon
from vehest_can.sim.powertrain import powertrain_car
from vehest_can.sim.session import CAR_NODES, SimMaster
from vehest_can.systems.driveline.scenario import load_driveline_scenario
from vehest_can.systems.ecu import Ecu

OTHER = unused_frame_id()


class SlowCar:
    """A car that takes 1 ms a tick: twice the 500 µs a tick has, as on a machine too busy for 2 kHz."""

    def __init__(self, car):
        self._car = car

    def __getattr__(self, name):
        return getattr(self._car, name)

    def tick(self, k):
        time.sleep(0.001)
        return self._car.tick(k)


def other_node(channel: str, stop: threading.Event) -> threading.Thread:
    """Another node on the bus: a frame every 5 ms, which the logging node receives (Rx)."""
    def run() -> None:
        with can.Bus(interface="virtual", channel=channel) as bus:
            while not stop.wait(0.005):
                bus.send(can.Message(arbitration_id=OTHER, is_extended_id=False, data=b"\x01"))
    t = threading.Thread(target=run, daemon=True)
    t.start()
    return t


def check_wall_clock(msgs: list[can.Message], wall_s: float, simulated_s: float) -> None:
    times = [m.timestamp for m in msgs]
    assert times == sorted(times)  # in time order: sent and received frames interleaved as on the bus
    span = times[-1] - times[0]
    assert span > 1.5 * simulated_s, (span, simulated_s)  # not the tick count's time
    assert abs(span - wall_s) < 0.15 + 0.05 * wall_s, (span, wall_s)
    assert any(m.is_rx and m.arbitration_id == OTHER for m in msgs)


def test_the_realtime_simulator_logs_wall_clock_time(tmp_path):
    channel = f"clock-{uuid.uuid4().hex}"
    stop = threading.Event()
    sender = other_node(channel, stop)
    car = SlowCar(powertrain_car(load_driveline_scenario("launch_2nd"), duration_s=0.25))
    try:
        with can.Bus(interface="virtual", channel=channel) as bus, SessionLog(tmp_path / "car.log", CAR_NODES) as log:
            t0 = time.time()
            session = SimMaster(bus, car, log_writer=log, keep=False).run_realtime(settle_s=0.05)
    finally:
        stop.set()
        sender.join(timeout=5)
    msgs = read_log(tmp_path / "car.log")
    check_wall_clock(msgs, session.stats["wall_s"], session.stats["ticks"] * TICK_S)
    assert abs(msgs[0].timestamp - t0) < 0.5  # absolute: the epoch is the wall clock's


def test_the_realtime_daemon_logs_when_frames_were_on_the_bus(tmp_path):
    channel = f"clock-{uuid.uuid4().hex}"
    stop = threading.Event()
    sender = other_node(channel, stop)
    try:
        with can.Bus(interface="virtual", channel=channel) as bus, SessionLog(tmp_path / "ecu.log", {"VEHEST"}) as log:
            daemon = EcuDaemon(bus, Ecu(), log_writer=log)
            t0 = time.perf_counter()
            daemon.serve_realtime(duration=0.6)
            wall = time.perf_counter() - t0
    finally:
        stop.set()
        sender.join(timeout=5)
    msgs = read_log(tmp_path / "ecu.log")
    check_wall_clock(msgs, wall, 0.0)
    assert any(not m.is_rx for m in msgs)  # the ECU's own frames, Tx
