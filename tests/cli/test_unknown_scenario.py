"""An unknown scenario (or campaign) name, in every verb that takes one: an error that lists the valid
names, exit 1, no traceback (`hil`'s configuration: tests/service/test_hil.py)."""
import subprocess
import sys

import pytest

from vehest_can.campaign.spec import CAMPAIGNS
from vehest_can.systems import shipped_scenarios

SCENARIOS = sorted({p.stem for p in shipped_scenarios()})


def run(*args, cwd=None):
    return subprocess.run([sys.executable, "-m", "vehest_can.cli", *args], capture_output=True, text=True,
                          timeout=120, cwd=cwd)


@pytest.mark.parametrize("args", [
    ["sim", "no_such_scenario"],
    ["demo", "no_such_scenario"],
    ["faults", "--scenario", "no_such_scenario"],
    ["soak", "--scenario", "no_such_scenario", "--duration", "100"],
], ids=lambda a: a[0])
def test_an_unknown_scenario_lists_the_shipped_ones(args, tmp_path):
    out = run(*args, cwd=tmp_path)
    assert out.returncode == 1 and "Traceback" not in out.stderr, out.stderr
    assert "no_such_scenario" in out.stderr and all(name in out.stderr for name in SCENARIOS), out.stderr


def test_an_unknown_campaign_base_lists_the_shipped_scenarios(tmp_path):
    (tmp_path / "c.toml").write_text('[campaign]\nbase = "no_such_scenario"\nruns = 2\n')
    out = run("campaign", str(tmp_path / "c.toml"), "-o", str(tmp_path / "out"))
    assert out.returncode == 1 and "Traceback" not in out.stderr, out.stderr
    assert "campaign.base" in out.stderr and all(name in out.stderr for name in SCENARIOS), out.stderr


def test_an_unknown_campaign_lists_the_shipped_ones(tmp_path):
    out = run("campaign", "no_such_campaign", cwd=tmp_path)
    assert out.returncode == 1 and "Traceback" not in out.stderr, out.stderr
    assert all(name in out.stderr for name in CAMPAIGNS.names()), out.stderr
