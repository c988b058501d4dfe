"""The real-time simulator's memory stays flat over a long run (`vehest-can sim` keeps nothing: its
frames go to --log as they come): measured as bytes retained per frame sent, not as a timed figure.

Once every frame stayed in a list as a ``can.Message`` and the truth of every tick in an array:
`vehest-can sim --duration 600` grew by about 0.8 MB per simulated second (docs/hil.md, "Memory over a
long run")."""
import threading
import tracemalloc

import numpy as np
import pytest

from vehest_can.bus.bus import open_bus, private_multicast
from vehest_can.bus.log import SessionLog
from vehest_can.sim import session as session_mod
from vehest_can.sim.powertrain import powertrain_car
from vehest_can.sim.session import CAR_NODES, SimMaster
from vehest_can.systems.driveline.scenario import load_driveline_scenario


def retained_bytes_per_frame(tmp_path, keep: bool, seconds: float = 3.0) -> tuple[float, SimMaster, object]:
    """Python-traced memory (tracemalloc: numpy's arrays included) against frames sent, sampled every
    0.1 s while the car runs on a bus of its own with a log file; the slope of a least-squares line
    over the samples after the first second (the start-up's allocations are not growth)."""
    drive = powertrain_car(load_driveline_scenario("tip_in_tip_out"), duration_s=seconds)
    bus = open_bus(private_multicast())
    writer = SessionLog(tmp_path / f"sim-{keep}.log", CAR_NODES)
    master = SimMaster(bus, drive, log_writer=writer, keep=keep)
    samples: list[tuple[int, int]] = []
    done = threading.Event()

    def sample():
        while not done.wait(0.1):
            samples.append((master._frames_seen, tracemalloc.get_traced_memory()[0]))

    tracemalloc.start()
    sampler = threading.Thread(target=sample, daemon=True)
    sampler.start()
    try:
        session = master.run_realtime(settle_s=0.0)
    finally:
        done.set()
        sampler.join()
        tracemalloc.stop()
        writer.stop()
        bus.shutdown()
    frames, mem = np.array([s for s in samples if s[0] > 2000], dtype=float).T  # after the first second
    assert len(frames) > 5 and frames[-1] - frames[0] > 2000, samples
    return float(np.polyfit(frames, mem, 1)[0]), master, session


@pytest.mark.slow
def test_a_realtime_run_that_keeps_nothing_stays_flat(tmp_path, monkeypatch):
    slope, master, session = retained_bytes_per_frame(tmp_path, keep=False)
    st = session.stats
    assert st["ticks"] == 6000 and st["frames"] >= 6000 and master._recording.n == 0
    assert len(session.truth) == 0 and len(session.frames) == 0
    assert slope < 16, f"{slope:.1f} bytes retained per frame"
    assert (tmp_path / "sim-False.log").stat().st_size > 6000 * 40  # the frames went to the log instead

    # The same measurement sees a kept session grow (76 bytes a frame; small chunks so it shows in 3 s).
    monkeypatch.setattr(session_mod.Recording, "CHUNK", 256)
    slope, master, session = retained_bytes_per_frame(tmp_path, keep=True)
    assert 60 < slope < 200, f"{slope:.1f} bytes retained per frame"
    assert len(session.frames) == session.stats["frames"] == master._recording.n and len(session.truth) == 6000
