"""The real-time daemon under hostile input that is not a bus failure: garbage datagrams on a
udp_multicast port are counted and dropped without stalling the receive path; the statistics of
a long run live in fixed memory."""
import socket
import sys
import threading
import time

import numpy as np
import pytest

from vehest_can.bus import bus as busmod
from vehest_can.bus.rt import Durations, percentiles_us
from vehest_can.service.daemon import EcuDaemon
from vehest_can.sim.powertrain import powertrain_car
from vehest_can.sim.report import decode
from vehest_can.sim.session import SimMaster
from vehest_can.systems.driveline.scenario import load_driveline_scenario
from vehest_can.systems.ecu import Ecu


def junk_sender(group: str, port: int, rate_hz: float, stop: threading.Event, sent: list):
    s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    s.setsockopt(socket.IPPROTO_IP, socket.IP_MULTICAST_TTL, 0)  # host only, as every test
    s.setsockopt(socket.IPPROTO_IP, socket.IP_MULTICAST_IF, socket.inet_aton("127.0.0.1"))
    while not stop.wait(1 / rate_hz):
        s.sendto(b"\xc1 not msgpack \xff", (group, port))
        sent.append(1)
    s.close()


@pytest.mark.multicast
def test_garbage_datagrams_between_good_frames_are_counted_and_do_not_stall_the_ecu():
    config = busmod.private_multicast()
    ecu_bus, car_bus = busmod.open_bus(config), busmod.open_bus(config)
    daemon = EcuDaemon(ecu_bus, Ecu())
    result = {}
    t = threading.Thread(target=lambda: result.setdefault("stats", daemon.serve_realtime()), daemon=True)
    stop, sent = threading.Event(), []
    junk = threading.Thread(target=junk_sender, args=(config["channel"], config["port"], 20.0, stop, sent), daemon=True)
    t.start()
    time.sleep(0.2)
    junk.start()
    try:
        session = SimMaster(car_bus, powertrain_car(load_driveline_scenario("tip_in_tip_out"), 3.0)).run_realtime()
    finally:
        stop.set()
        junk.join(5)
        time.sleep(0.2)
        daemon.stop_event.set()
        t.join(10)
        ecu_bus.shutdown()
        car_bus.shutdown()
    stats = result["stats"]
    assert len(sent) >= 40
    assert stats.rx_undecodable == len(sent)      # each counted, none lost, none taken as a frame
    assert stats.bus_outages == 0 and stats.recv_errors == 0
    assert any("undecodable input" in line for line in stats.lines())
    # the car's receive path too (it stops listening a moment before the sender stops)
    assert len(sent) - 3 <= session.stats["rx_undecodable"] <= len(sent)
    est = decode(session, "VEHEST_DrivelineEst")
    valid = np.asarray(est["DkfT_Valid"], dtype=float)
    # Before: each garbage datagram stopped receiving for 50 ms; at 20/s the receive path was
    # stalled all the time and validity was 0.001. Functional, not timing: the bound sits far above
    # that and far below what a loaded machine gives (0.999 quiet, 0.67 once on a busy 2-core CI).
    assert np.nanmean(valid[len(valid) // 3:]) > 0.3


def test_durations_are_held_in_fixed_memory_and_agree_with_numpy():
    rng = np.random.default_rng(1)
    x = np.concatenate([rng.exponential(300e-6, 200_000), rng.uniform(0.01, 2.0, 500)])
    d = Durations()
    size = d.bins.nbytes
    d.extend(x)
    assert d.bins.nbytes == size and len(d) == x.size
    got, want = d.percentiles_us(), percentiles_us(x)
    assert got["n"] == want["n"] and got["max"] == pytest.approx(want["max"])
    for q in ("p50", "p99", "p99.9"):
        assert 0 <= got[q] - want[q] <= max(1.0, 0.011 * want[q]) + 1e-9, (q, got[q], want[q])
    d.add(float("nan"))
    assert len(d) == x.size  # a NaN duration is not a sample
    assert Durations().percentiles_us() == {}


def test_ticker_lateness_does_not_grow_with_ticks():
    from vehest_can.bus.rt import Ticker

    t = Ticker(1e-5)
    t.start()
    for _ in range(5000):
        t.wait()
    assert isinstance(t.lateness, Durations) and len(t.lateness) == 5000
    assert sys.getsizeof(t.lateness.bins) < 200_000
