"""The firmware-size command (c_core/firmware_size.py, `make firmware-size`) on a Cortex-M4F."""
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "c_core"))
import firmware_size  # noqa: E402
import vehest_build  # noqa: E402

pytestmark = [pytest.mark.rebuild, pytest.mark.skipif(firmware_size.missing_toolchain() is not None,
                                                      reason=str(firmware_size.missing_toolchain()))]


@pytest.fixture(scope="module")
def measured(tmp_path_factory):
    return firmware_size.measure(tmp_path_factory.mktemp("fw"))


@pytest.fixture(scope="module")
def figures(measured):
    return measured[0]


def test_the_flashed_firmware_calls_no_host_code(measured):
    """*_host.c are left out of the image, so nothing flashed may call into them."""
    import re

    host = {name for d in vehest_build.FIRMWARE_DIRS for p in d.glob(vehest_build.HOST_ONLY_GLOB)
            for name in re.findall(r"^[a-z][\w ]*?\b(vh_\w+)\(", p.read_text(), re.M)}
    assert {"vh_skfq_params_from_config", "vh_skfq_quantise_inputs", "vh_ecu_init"} <= host
    # but a driver interface the target implements itself: SecOC's AES (vh_aes128.h: its HSM/SHE
    # driver on a target, OpenSSL in vh_aes128_host.c here)
    driver = set(re.findall(r"\b(vh_aes128_\w+)\(", vehest_build.firmware_path("vh_aes128.h").read_text()))
    assert driver == {"vh_aes128_setkey", "vh_aes128_encrypt"}
    called = {c for callees in measured[1].values() for c in callees}
    assert not (host - driver) & called


def test_a_row_per_firmware_folder_and_the_codec(figures):
    rows = figures["folders"]
    assert list(rows) == [d.name for d in vehest_build.FIRMWARE_DIRS] + ["codec (generated)"]
    assert all(r["text"] > 0 for r in rows.values())
    assert not any(f.endswith("_host.c") for r in rows.values() for f in r["files"])  # not flashed


def test_no_state_in_globals(figures):
    """No heap and no globals that hold state: the flashed image has no .data and no .bss."""
    assert all(r["data"] == 0 and r["bss"] == 0 for r in figures["folders"].values())


def test_stack_depth_of_the_entry_points(figures):
    """Every frame is static (no VLA, no alloca), and the tick's worst chain is the fixed-point
    SKFMEC step: well inside the few KB a Cortex-M4 task stack has; init holds the matrix exponential."""
    assert all(not r["dynamic"] for r in figures["folders"].values())
    e = figures["entries"]
    assert set(e) == {"vh_ecu_init_params", "vh_ecu_rx", "vh_ecu_step"}
    assert "vh_skfq_step" in e["vh_ecu_step"]["chain"] and e["vh_ecu_step"]["stack"] < 2048
    assert "vh_mat_expm" in e["vh_ecu_init_params"]["chain"] and "vh_mat_expm" not in e["vh_ecu_step"]["chain"]


def test_cli_prints_the_table(capsys):
    assert firmware_size.main([]) == 0
    out = capsys.readouterr().out
    assert "tireforce" in out and "vh_ecu_step" in out and "total" in out
