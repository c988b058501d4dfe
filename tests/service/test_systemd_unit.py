"""The shipped systemd unit is sandboxed: `systemd-analyze security` exposure <= 3.0."""
import os
import re
import shutil
import subprocess
from pathlib import Path

import pytest

UNIT = Path(__file__).resolve().parents[2] / "examples" / "systemd" / "vehest-ecu.service"


def test_systemd_unit_exposure_is_at_most_3():
    if shutil.which("systemd-analyze") is None:
        if os.environ.get("CI", "").lower() in ("true", "1"):
            pytest.fail("systemd-analyze (Debian's systemd) is needed on CI", pytrace=False)
        pytest.skip("systemd-analyze not installed")
    r = subprocess.run(["systemd-analyze", "security", "--offline=true", str(UNIT)],
                       capture_output=True, text=True, cwd=UNIT.parent)
    m = re.search(r"Overall exposure level for \S+: (\d+\.\d+)", r.stdout)
    assert m, r.stdout + r.stderr
    assert float(m[1]) <= 3.0, r.stdout


def test_the_unit_keeps_what_the_daemon_needs():
    text = UNIT.read_text()
    fams = re.search(r"^RestrictAddressFamilies=(.*)$", text, re.M)[1].split()
    assert {"AF_CAN", "AF_UNIX"} <= set(fams)  # SocketCAN and sd_notify
    assert re.search(r"^Type=notify$", text, re.M) and re.search(r"^WatchdogSec=", text, re.M)
