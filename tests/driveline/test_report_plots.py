"""The driveline report's plots: every axis of every figure is labelled, the y axis with its unit."""
import re

from vehest_can.plotting import Figures
from vehest_can.sim.powertrain import powertrain_car
from vehest_can.sim.session import run_inprocess
from vehest_can.systems.driveline import report
from vehest_can.systems.driveline.scenario import load_driveline_scenario
from vehest_can.systems.ecu import Ecu


def test_every_plot_has_a_y_label_with_its_unit(tmp_path, monkeypatch):
    labels: dict[str, list[str]] = {}
    save = Figures.save

    def spy(self, fig, name):
        labels[name] = [ax.get_ylabel() for ax in fig.axes]
        return save(self, fig, name)

    monkeypatch.setattr(Figures, "save", spy)
    session = run_inprocess(powertrain_car(load_driveline_scenario("launch_2nd"), duration_s=1.0), Ecu())
    report.plots(session, tmp_path)
    assert "gain.png" in labels and (tmp_path / "gain.png").is_file()
    for name, ys in labels.items():
        assert ys and all(re.search(r"\[.+\]", y) for y in ys), (name, ys)
