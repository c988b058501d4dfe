import pytest

from vehest_can.systems.roll import api as rn
from vehest_can.systems.roll import evaluate as ev


@pytest.fixture(scope="session")
def case72():
    """3 s of the paper's 72 km/h steer ramp on the 14-DOF plant, measurements synthesised."""
    truth = ev.run_plant(ev.paper_case(72.0, duration_s=3.0, t_ramp=(0.3, 1.3)))
    prm = rn.default_params()
    u, z, idx = ev.synthesise(truth, prm=prm)
    return truth, u, z, idx
