"""``vehest-can secoc keygen|check``: keys for every sending node, never printed, clear errors."""
import os
import subprocess
import sys


def vc(*args, cwd):
    return subprocess.run([sys.executable, "-m", "vehest_can.cli", "secoc", *args], capture_output=True,
                          text=True, cwd=cwd, timeout=60)


def test_keygen_then_check(tmp_path):
    r = vc("keygen", "k.toml", cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    for node in ("CHS", "CIS", "DLS", "VEHEST"):
        assert node in r.stdout
    text = (tmp_path / "k.toml").read_text()
    for line in text.splitlines():
        if "=" in line:
            assert line.split('"')[1] not in r.stdout  # the key itself is never printed
    assert vc("check", "k.toml", cwd=tmp_path).returncode == 0
    again = vc("keygen", "k.toml", cwd=tmp_path)
    assert again.returncode == 1 and "not overwritten" in again.stderr and "Traceback" not in again.stderr
    os.chmod(tmp_path / "k.toml", 0o640)
    loose = vc("check", "k.toml", cwd=tmp_path)
    assert loose.returncode == 1 and "too open" in loose.stderr and "Traceback" not in loose.stderr
    bad = vc("frobnicate", "k.toml", cwd=tmp_path)
    assert bad.returncode == 2 and "invalid choice" in bad.stderr
