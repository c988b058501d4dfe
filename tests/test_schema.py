"""One schema reader (vehest_can.schema) for every user file kind: the same reading, the same
``FILE: dotted.key: problem`` errors, each kind's own error class."""
import pytest

from vehest_can.errors import ConfigError, ScenarioError
from vehest_can.faults.spec import load_faults
from vehest_can.schema import Checker, Num
from vehest_can.service.hil import load_hil_config
from vehest_can.systems.driveline.scenario import load_driveline_scenario
from vehest_can.systems.tireforce.scenario import load_tireforce_scenario

LOADERS = [(load_driveline_scenario, ScenarioError), (load_tireforce_scenario, ScenarioError),
           (load_hil_config, ConfigError), (load_faults, ConfigError)]


@pytest.mark.parametrize("load, error", LOADERS, ids=lambda x: getattr(x, "__name__", ""))
def test_every_kind_reports_broken_toml_the_same_way(tmp_path, load, error):
    path = tmp_path / "broken.toml"
    path.write_text("name = [1\n")
    with pytest.raises(error, match=rf"^{path}: \(TOML syntax\): "):
        load(path)


@pytest.mark.parametrize("load, error", LOADERS, ids=lambda x: getattr(x, "__name__", ""))
def test_every_kind_reports_a_missing_file_the_same_way(tmp_path, load, error):
    with pytest.raises(error, match=rf"^{tmp_path / 'none.toml'}: cannot read: "):
        load(tmp_path / "none.toml")


def test_checker_names_the_dotted_key_and_raises_the_kind_s_error():
    c = Checker("f.toml", ConfigError)
    with pytest.raises(ConfigError, match=r"^f.toml: a.b: 7 is out of range: must be a number in \[0, 1\]$"):
        c.number(7, "a.b", Num(0.0, 1.0))
    with pytest.raises(ScenarioError, match=r"^g.toml: t.x: unknown key \(expected one of: y\)$"):
        Checker("g.toml").table({"x": 1}, "t", {"y"})
