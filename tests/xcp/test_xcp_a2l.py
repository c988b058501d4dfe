"""The generated A2L: equal to the shipped file, and read without errors by two independent parsers."""
from __future__ import annotations

import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
from xcp_demo import DEMO  # noqa: E402

from vehest_can.xcp import a2l, load

SHIPPED = DEMO.with_name("VEHEST_XCP_DEMO.a2l")


def test_regenerated_a2l_equals_the_shipped_file(tmp_path):
    out = a2l.write(load(DEMO), tmp_path / "x.a2l")
    assert out.read_text() == SHIPPED.read_text(), "regenerate: vehest-can xcp a2l --description DEMO -o SHIPPED"


def test_cli_writes_the_file(tmp_path):
    r = subprocess.run([sys.executable, "-m", "vehest_can.cli", "xcp", "a2l", "--description", str(DEMO),
                        "-o", str(tmp_path / "d.a2l")],
                       capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    assert (tmp_path / "d.a2l").read_text() == SHIPPED.read_text()


def test_every_item_is_there_by_its_c_name():
    text = SHIPPED.read_text()
    desc = load(DEMO)
    for m in desc.measurements:
        assert re.search(rf"/begin MEASUREMENT {m.name} .*\n.*\n  +ECU_ADDRESS 0x{m.address:X}\n", text), m.name
    for c in desc.characteristics:
        assert re.search(rf"/begin CHARACTERISTIC {c.name} .*\n +(VALUE|VAL_BLK) 0x{c.address:X} ", text), c.name
    assert "COEFFS_LINEAR 0.25 0" in text  # torque_offset: 0.25 Nm per LSB
    assert "CAN_ID_MASTER 0x7F0" in text and "CAN_ID_SLAVE 0x7F1" in text


a2ltool = shutil.which("a2ltool") or str(Path(sys.executable).with_name("a2ltool"))


@pytest.mark.skipif(not Path(a2ltool).exists(), reason="a2ltool (PyPI) not installed")
def test_a2ltool_strict_check_and_ifdata_match_the_a2ml(tmp_path):
    r = subprocess.run([a2ltool, "--check", "--strict", str(SHIPPED)], capture_output=True, text=True)
    assert r.returncode == 0 and "No problems found" in r.stdout, r.stdout + r.stderr
    # --ifdata-cleanup drops every IF_DATA that does not parse by the file's A2ML: none is dropped
    clean = tmp_path / "clean.a2l"
    r = subprocess.run([a2ltool, "--strict", "--ifdata-cleanup", "-o", str(clean), str(SHIPPED)],
                       capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    assert clean.read_text().count("/begin IF_DATA XCP") == SHIPPED.read_text().count("/begin IF_DATA XCP") == 2
    r = subprocess.run([a2ltool, "--show-xcp", str(SHIPPED)], capture_output=True, text=True)
    assert "CAN id master: 0x7F0" in r.stdout


def test_pya2l_parses_it():
    parser = pytest.importorskip("pya2l.parser")
    desc = load(DEMO)
    text = SHIPPED.read_bytes()
    with parser.A2lParser() as p:
        tree = p.tree_from_a2l(text)
        # pya2l 0.4 reads IF_DATA without its A2ML and warns "may be used at most once" for every
        # block inside one (a single PROTOCOL_LAYER too): its quirk, not a fault of the file
        assert all("may be used at most once" in w for w in p.warnings), p.warnings
        m = tree.PROJECT.MODULE[0]
        assert m.Name.Value == desc.name
        got = {x.Name.Value: x.ECU_ADDRESS.Address.Value for x in m.MEASUREMENT}
        assert got == {x.name: x.address for x in desc.measurements}
        assert {x.Name.Value for x in m.CHARACTERISTIC} == {x.name for x in desc.characteristics}
        # the rest of the file passes its strict ASAP2 1.71 version check
        no_if = re.sub(rb"/begin IF_DATA.*?/end IF_DATA", b"", text, flags=re.S)
        p.tree_from_a2l(no_if, enforce_version_check=True)
        assert p.warnings == []


def test_the_generator_does_not_need_the_c_extension():
    code = ("import sys; sys.modules['vehest_can._native'] = None\n"  # importing it would fail
            "from vehest_can.xcp import a2l, load\n"
            f"assert 'CHARACTERISTIC' in a2l.generate(load({str(DEMO)!r}))\n")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
