"""The roll loop closed over a real vcan0 inside user-mode Linux (issue 11 section 4): the ECU daemon
and the roll car as two processes on SocketCAN in lockstep give the same frames and truth as the
in-process run, bit for bit."""
import json
import shlex
import sys
from pathlib import Path

import numpy as np
import pytest

from vehest_can.sim.session import run_inprocess
from vehest_can.systems.ecu import Ecu
from vehest_can.systems.roll.scenario import RollCar, load_roll_scenario

REPO = Path(__file__).resolve().parents[2]
GUEST = REPO / "tests" / "vcan_guest"
SECONDS = 1.2   # the controller acts from ~0.5 s (the steer ramp starts, the estimate has been OK 0.5 s)


@pytest.mark.uml
def test_lockstep_over_vcan_equals_inprocess(uml, tmp_path):
    out = tmp_path / "vcan"
    cmd = (f"{shlex.quote(sys.executable)} {shlex.quote(str(GUEST / 'lockstep_sessions.py'))} "
           f"{shlex.quote(str(out))} --duration {SECONDS} roll_paper_72kph_active")
    result = uml.run(cmd, timeout=900, cwd=REPO, workdir=tmp_path / "uml", interfaces=("vcan0",))
    doc = json.loads(result.stdout[result.stdout.index("{"):])
    assert doc["interface"] == "socketcan" and doc["sessions"]["roll_paper_72kph_active"]["ticks"] == 2400
    with np.load(out / "roll_paper_72kph_active.session.npz") as z:
        frames, ticks, truth = z["frames"], z["frame_tick"], z["truth"]
    local = run_inprocess(RollCar(load_roll_scenario("roll_paper_72kph_active"), SECONDS), Ecu())
    assert len(frames) == len(local.frames) > 5000
    assert np.array_equal(frames, local.frames) and np.array_equal(ticks, local.frame_tick)
    assert np.array_equal(truth, local.truth)
    assert np.abs(local.truth["m_applied"]).max() > 50.0   # the loop acted on the car
