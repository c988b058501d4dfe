"""The pyxcp recipe of docs/xcp.md, run as it stands against `vehest-can daemon` (its own process,
XCP on a bus of its own, both on private host-only udp_multicast ports), and the commands an 8-byte
value takes on the bus: one UPLOAD and one DOWNLOAD on CAN FD (MAX_CTO 24 or 64), two each on
classic CAN (MAX_CTO 8: 7 + 1 and 6 + 2 bytes)."""
from __future__ import annotations

import dataclasses
import re
import struct
import subprocess
import sys
from collections import Counter
from pathlib import Path

import can
import pytest
from daemonproc import start_daemon, stop_daemon

from vehest_can.bus import bus as busmod
from vehest_can.xcp import ecu as xcp_ecu
from vehest_can.xcp.keys import write_key

pytestmark = pytest.mark.multicast
pytest.importorskip("pyxcp")

DOCS = Path(__file__).resolve().parents[2] / "docs" / "xcp.md"
UPLOAD, DOWNLOAD = 0xF5, 0xF0


def recipe() -> str:
    text = DOCS.read_text()
    section = text[text.index("## Talking to it with pyxcp"):]
    return re.search(r"```python\n(.*?)```", section, re.S).group(1)


class XcpDaemon:
    """The daemon with XCP on its own bus, and a listener there counting the master's commands."""

    def __init__(self, tmp_path: Path, *xcp_flags: str):
        self.main, self.xcp = busmod.private_multicast(), busmod.private_multicast()
        self.key_file = tmp_path / "xcp.key"
        self.key = write_key(self.key_file)
        self.proc = start_daemon(self.main, "--mode", "realtime", "--xcp", "on", "--xcp-key", str(self.key_file),
                                 "--xcp-interface", "udp_multicast", "--xcp-channel", self.xcp["channel"],
                                 "--xcp-bus-kwargs", f"port={self.xcp['port']}", *xcp_flags, tmp_path=tmp_path)
        self.cros: Counter = Counter()
        self.listen = busmod.open_bus(self.xcp)
        cro_id = xcp_ecu.description().cro_id
        self.notifier = can.Notifier(self.listen, [lambda m: m.arbitration_id == cro_id and self.cros.update([m.data[0]])],
                                     timeout=0.01)

    def close(self) -> str:
        self.notifier.stop()
        self.listen.shutdown()
        return stop_daemon(self.proc)[1]


def test_the_documented_pyxcp_recipe_reads_and_writes_an_8_byte_value_in_one_command_each(tmp_path):
    script = tmp_path / "recipe.py"
    script.write_text(recipe())
    d = XcpDaemon(tmp_path)
    try:
        r = subprocess.run([sys.executable, str(script), str(d.xcp["port"]), str(d.key_file)],
                           capture_output=True, text=True, timeout=120)
    finally:
        err = d.close()
    assert r.returncode == 0, r.stdout + r.stderr + err
    desc = xcp_ecu.description()
    assert f"MAX_CTO {desc.max_cto} MAX_DTO {desc.max_dto}" in r.stdout
    assert "cal.app.drv.dkf[0].r[2] 30000.0" in r.stdout
    # two 8-byte reads (the torque, the value written back) and one 8-byte write
    assert (d.cros[UPLOAD], d.cros[DOWNLOAD]) == (2, 1), d.cros
    print(f"recipe: {r.stdout.strip()!r}; CROs on the XCP bus: {dict(d.cros)}")


@pytest.mark.parametrize("flags, fd, cto, dto, per_value", [
    (("--xcp-max-cto", "64", "--xcp-max-dto", "64"), True, 64, 64, 1),
    (("--xcp-fd", "off", "--xcp-max-cto", "8", "--xcp-max-dto", "8"), False, 8, 8, 2),
], ids=["fd64", "classic8"])
def test_an_8_byte_value_takes_one_upload_on_can_fd_and_two_on_classic_can(tmp_path, pyxcp_master, flags, fd, cto,
                                                                              dto, per_value):
    d = XcpDaemon(tmp_path, *flags)
    desc = dataclasses.replace(xcp_ecu.description(), fd=fd, max_cto=cto, max_dto=dto)
    bus = busmod.open_bus(dict(d.xcp, fd=fd))
    try:
        m = pyxcp_master(None, desc, bus=bus, key=d.key, timeout=2.0)
        m.__enter__()
        m.connect()
        assert (m.slaveProperties.maxCto, m.slaveProperties.maxDto) == (cto, dto)
        m.cond_unlock("calpag")
        r = desc.item("cal.app.drv.dkf[0].r")
        blob = struct.pack("<d", 12345.0)
        m.setMta(r.address + 2 * r.element_size)
        for i in range(0, len(blob), cto - 2):  # as pyxcp's push splits it, each DOWNLOAD waiting for its RES
            m.download(blob[i:i + cto - 2])
        m.setMta(r.address + 2 * r.element_size)
        assert struct.unpack("<d", m.fetch(8)[:8])[0] == 12345.0  # pyxcp splits by MAX_CTO - 1
        m.disconnect()
        m.__exit__(None, None, None)
    finally:
        bus.shutdown()
        d.close()
    assert (d.cros[UPLOAD], d.cros[DOWNLOAD]) == (per_value, per_value), d.cros
