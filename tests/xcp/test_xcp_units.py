"""The shipped ECU A2L as a calibration tool reads it: pya2l (an independent parser) finds a unit on
every measurement and characteristic (the COMPU_METHOD's unit or PHYS_UNIT) and the counts that
docs/xcp.md states; an item that mirrors a DBC signal has the signal's unit; a2ltool --check
--strict passes, and its IF_DATA parse by the file's A2ML (the standard XCP one) with the CAN FD
block's data-phase bit rate."""
from __future__ import annotations

import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from vehest_can.bus.frames import database
from vehest_can.xcp import ecu as xcp_ecu
from vehest_can.xcp import ecu_desc

A2L = ecu_desc.SHIPPED_A2L
DOCS = Path(__file__).resolve().parents[2] / "docs" / "xcp.md"
#: A2L item -> (DBC, message, signal) it mirrors
MIRRORS = {
    "app.drv.dkf[0].x[1]": ("pt", "VEHEST_DrivelineEst", "DkfT_WheelSpeed"),
    "app.drv.dkf[0].x[2]": ("pt", "VEHEST_DrivelineEst", "DkfT_ShaftTorque"),
    "app.drv.dkf[0].x[3]": ("pt", "VEHEST_DrivelineEst", "DkfT_RoadLoadErr"),
    "app.drv.dkf[1].x[2]": ("pt", "VEHEST_DrivelineEst", "DkfS_ShaftTorque"),
    "app.drv.dkf[1].x[3]": ("pt", "VEHEST_DrivelineEst", "DkfS_RoadLoadErr"),
    "app.roll.ukf.x[4]": ("ch", "VEHEST_RollEst", "RollEstAngle"),
    "app.roll.ukf.x[5]": ("ch", "VEHEST_RollEst", "RollEstRate"),
    "app.roll.ukf.ay_post": ("ch", "VEHEST_RollEst", "RollEstLatAccel"),
    "app.roll.smc.m_f": ("ch", "VEHEST_RollCmd", "MomentCmdF"),
    "app.roll.smc.m_r": ("ch", "VEHEST_RollCmd", "MomentCmdR"),
}


def pya2l_units() -> tuple[dict[str, str], dict[str, str]]:
    """{name: unit} of the A2L's measurements and characteristics, as pya2l reads them."""
    parser = pytest.importorskip("pya2l.parser")
    with parser.A2lParser() as p:
        module = p.tree_from_a2l(A2L.read_bytes()).PROJECT.MODULE[0]
        assert all("may be used at most once" in w for w in p.warnings), p.warnings  # its IF_DATA quirk
        compu = {c.Name.Value: c.Unit.Value for c in module.COMPU_METHOD}

        def unit(x) -> str:
            return x.PHYS_UNIT.Unit.Value or compu[x.Conversion.Value]
        return ({x.Name.Value: unit(x) for x in module.MEASUREMENT},
                {x.Name.Value: unit(x) for x in module.CHARACTERISTIC})


def test_pya2l_finds_a_unit_on_every_item_and_the_counts_the_docs_state():
    meas, chars = pya2l_units()
    desc = xcp_ecu.description()
    assert (len(meas), len(chars)) == (len(desc.measurements), len(desc.characteristics))
    without = sorted(n for n, u in {**meas, **chars}.items() if not u.strip())
    assert without == [], without
    stated = re.search(r"<!-- counts: written by c_core/ecu_gen.py -->\*\*(\d+) measurements and (\d+) "
                       r"characteristics, each with its unit\*\*<!-- /counts -->", DOCS.read_text())
    assert stated, "run: python c_core/ecu_gen.py"
    assert (int(stated.group(1)), int(stated.group(2))) == (len(meas), len(chars))
    print(f"pya2l: {len(meas)} measurements, {len(chars)} characteristics, {len(meas) + len(chars) - len(without)} "
          "with a unit")


def test_an_item_that_mirrors_a_dbc_signal_has_its_unit():
    meas, _ = pya2l_units()
    for name, (bus, message, signal) in MIRRORS.items():
        sig = database(bus).get_message_by_name(message).get_signal_by_name(signal)
        assert sig.unit and meas[name] == sig.unit, (name, meas[name], sig.unit)


a2ltool = shutil.which("a2ltool") or str(Path(sys.executable).with_name("a2ltool"))


@pytest.mark.skipif(not Path(a2ltool).exists(), reason="a2ltool (PyPI) not installed")
def test_a2ltool_strict_and_the_standard_xcp_if_data(tmp_path):
    r = subprocess.run([a2ltool, "--check", "--strict", str(A2L)], capture_output=True, text=True)
    assert r.returncode == 0 and "No problems found" in r.stdout, r.stdout + r.stderr
    clean = tmp_path / "clean.a2l"  # --ifdata-cleanup drops every IF_DATA the A2ML cannot parse
    r = subprocess.run([a2ltool, "--strict", "--ifdata-cleanup", "-o", str(clean), str(A2L)], capture_output=True,
                       text=True)
    assert r.returncode == 0, r.stderr
    assert clean.read_text().count("/begin IF_DATA XCP") == A2L.read_text().count("/begin IF_DATA XCP") == 2
    desc = xcp_ecu.description()
    shown = subprocess.run([a2ltool, "--show-xcp", str(A2L)], capture_output=True, text=True).stdout
    assert f"CAN-FD data baudrate: {desc.data_bitrate // 1000} kbps" in shown, shown
    assert f"CAN-FD max DLC: {max(desc.max_cto, desc.max_dto)}" in shown, shown
    # the standard's grammar, not an own one: its keywords for the other XCP features are declared too
    for keyword in ('"MAX_DLC_REQUIRED"', '"SAMPLE_POINT"', '"CAN_FD_DATA_TRANSFER_BAUDRATE"', '"DAQ_EVENT"',
                    '"COMMUNICATION_MODE_SUPPORTED"', '"PGM"'):
        assert keyword in A2L.read_text(), keyword
