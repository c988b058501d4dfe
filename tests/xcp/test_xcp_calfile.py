"""Calibration files: round trip, validation, and what a master wrote survives a save/load."""
import json

import pytest
from xcp_demo import DEMO, Slave, cal_values, load_cal, save_cal  # noqa: E402

from vehest_can.xcp import calfile, load


def test_round_trip_of_what_the_master_wrote(rig, tmp_path):
    rig.connect()
    rig.master.cond_unlock("calpag")
    rig.download("torque_offset", [-37])  # -9.25 Nm
    rig.download("skf_gain", [float(i) / 8 for i in range(16)])
    rig.bridge.advance(1)
    path = tmp_path / "cal.json"
    save_cal(rig.slave, path)
    doc = json.loads(path.read_text())
    assert doc["format"] == calfile.FORMAT and doc["version"] == 1
    assert doc["values"]["torque_offset"] == -9.25 and doc["values"]["skf_gain"][1][0] == 0.5
    fresh = Slave(load(DEMO), key=bytes(16))
    assert fresh.read("torque_offset") == 0
    load_cal(fresh, path)
    for c in fresh.desc.characteristics:
        assert fresh.read(c.name) == rig.slave.read(c.name) == fresh.read(c.name, "work")
    assert fresh.read("dkf_r_torque", "ref") == 64.0  # the reference page stays


@pytest.mark.parametrize("edit, msg", [
    (lambda d: d.update(format="x"), "not an XCP calibration"),
    (lambda d: d.update(version=2), "unsupported version"),
    (lambda d: d.update(description="OTHER"), "written for"),
    (lambda d: d["values"].pop("dkf_r_torque"), "missing"),
    (lambda d: d["values"].update(nope=1.0), "unknown"),
    (lambda d: d["values"].update(dkf_r_torque=-1.0), "outside"),
    (lambda d: d["values"].update(dkf_r_torque="64"), "not a number"),
    (lambda d: d["values"].update(torque_offset=0.1), "resolution"),
    (lambda d: d["values"].update(skf_gain=[1.0] * 16), "shape"),
    (lambda d: d["values"].update(rx_timeout_ticks=1), "outside"),
])
def test_invalid_files_are_refused_and_change_nothing(tmp_path, edit, msg):
    s = Slave(load(DEMO), key=bytes(16))
    path = tmp_path / "cal.json"
    save_cal(s, path)
    doc = json.loads(path.read_text())
    edit(doc)
    path.write_text(json.dumps(doc))
    before = cal_values(s, "work")
    with pytest.raises(calfile.CalFileError, match=msg):
        load_cal(s, path)
    assert cal_values(s, "work") == before == cal_values(s, "ecu")
