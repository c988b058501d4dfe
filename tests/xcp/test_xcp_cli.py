"""``vehest-can xcp``: the A2L, the item list, and get/set against a running daemon on the
project's default bus (a private udp_multicast port)."""
from __future__ import annotations

import threading
import time

import pytest

from vehest_can.bus import bus as busmod
from vehest_can.cli import main
from vehest_can.errors import ConfigError
from vehest_can.service.daemon import EcuDaemon
from vehest_can.systems.ecu import Ecu
from vehest_can.xcp import ecu as xcp_ecu
from vehest_can.xcp import ecu_desc
from vehest_can.xcp.keys import DEV_KEY


def test_a2l_is_written_and_items_listed(tmp_path, capsys):
    out = tmp_path / "ecu.a2l"
    assert main(["xcp", "a2l", "-o", str(out)]) == 0
    assert out.read_text() == ecu_desc.SHIPPED_A2L.read_text()
    assert main(["xcp", "list", "cal.app.drv.dkf[[]0].*"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert [ln.split()[1] for ln in lines] == ["cal.app.drv.dkf[0].q", "cal.app.drv.dkf[0].r", "cal.app.drv.dkf[0].p_max"]


@pytest.fixture
def daemon_bus():
    config = busmod.private_multicast()
    bus = busmod.open_bus(config)
    ecu = Ecu()
    xcp_ecu.enable(ecu, DEV_KEY)
    daemon = EcuDaemon(bus, ecu)
    t = threading.Thread(target=daemon.serve_realtime, daemon=True)
    t.start()
    time.sleep(0.2)
    yield ecu, ["-i", "udp_multicast", "-c", config["channel"], "--fd", "--bus-kwargs", f"port={config['port']}"]
    daemon.stop_event.set()
    t.join(10)
    bus.shutdown()


@pytest.mark.multicast
def test_get_and_set_against_the_running_daemon(daemon_bus, capsys):
    ecu, flags = daemon_bus
    with pytest.raises(SystemExit):  # a write needs the key: argparse's error
        main(["xcp", "set", "cal.app.drv.dkf[0].r", "3000", "--index", "2", *flags])
    capsys.readouterr()
    assert main(["xcp", "set", "cal.app.drv.dkf[0].r", "3000", "--index", "2", *flags, "--dev"]) == 0
    # a block whose elements differ in unit names each element's
    assert capsys.readouterr().out.strip() == "cal.app.drv.dkf[0].r = [415, 27, 3000] (rad/s)^2 [0, 1], Nm^2 [2]"
    assert ecu.c.app.drv.dkf[0].cfg.r[2] == 3000.0  # in the running filter
    assert main(["xcp", "get", "tick", "app.drv.dkf[0].health", *flags]) == 0
    out = capsys.readouterr().out.splitlines()
    assert out[0].startswith("tick = ") and out[0].endswith(" tick") and int(out[0].split()[-2]) > 0
    assert main(["xcp", "set", "cal.app.drv.we_min", "500", *flags, "--dev"]) == 1
    err = capsys.readouterr().err
    assert "ERR_OUT_OF_RANGE" in err and "[0, 200] rad/s" in err and "nothing written" in err
    assert ecu.c.app.drv.cfg.we_min == 40.0


def test_bad_arguments_are_clear_errors(capsys):
    flags = ["-i", "virtual", "-c", "xcp-cli-nobody", "--timeout", "0.2"]
    assert main(["xcp", "get", "no_such", *flags]) == 1
    assert "no XCP item named 'no_such'" in capsys.readouterr().err
    assert main(["xcp", "set", "tick", "1", *flags, "--dev"]) == 1
    assert "is a measurement" in capsys.readouterr().err
    assert main(["xcp", "set", "cal.app.drv.we_min", "fast", *flags, "--dev"]) == 1
    assert "values must be numbers" in capsys.readouterr().err
    assert main(["xcp", "set", "cal.app.drv.we_min", "1", "2", *flags, "--dev"]) == 1
    assert "do not fit" in capsys.readouterr().err
    assert main(["xcp", "get", "tick", "--cro-id", "0xZZ", *flags]) == 1
    assert "--cro-id" in capsys.readouterr().err
    assert main(["xcp", "get", "tick", *flags]) == 1  # nobody on that bus
    assert "no XCP answer to CONNECT" in capsys.readouterr().err


@pytest.mark.multicast
def test_save_and_load_a_calibration_file_of_the_running_daemon(daemon_bus, tmp_path, capsys):
    import json

    ecu, flags = daemon_bus
    assert main(["xcp", "set", "cal.app.drv.we_min", "55", *flags, "--dev"]) == 0
    f = tmp_path / "ecu_cal.json"
    assert main(["xcp", "save", str(f), *flags]) == 0
    doc = json.loads(f.read_text())
    assert doc["description"] == "VEHEST_ECU" and doc["values"]["cal.app.drv.we_min"] == 55.0
    assert doc["values"]["cal.app.tf.skf.r"] == [v * 2.0 ** -24 for v in ecu.c.app.tf.skf.prm.r]  # Q7.24 -> physical
    doc["values"]["cal.app.drv.dkf[0].r"][2] = 12345.0
    f.write_text(json.dumps(doc))
    assert main(["xcp", "load", str(f), *flags, "--dev"]) == 0
    assert ecu.c.app.drv.dkf[0].cfg.r[2] == 12345.0 and ecu.c.app.drv.cfg.we_min == 55.0
    doc["values"]["cal.app.drv.dkf[0].r"][2] = -1.0
    f.write_text(json.dumps(doc))
    capsys.readouterr()
    assert main(["xcp", "load", str(f), *flags, "--dev"]) == 1  # checked whole before the bus: nothing written
    assert "cal.app.drv.dkf[0].r: -1.0 outside" in capsys.readouterr().err
    assert ecu.c.app.drv.dkf[0].cfg.r[2] == 12345.0


def test_the_daemon_starts_on_a_calibration_file(tmp_path):
    import argparse
    import json

    ecu = Ecu()
    xcp_ecu.enable(ecu, DEV_KEY)
    f = tmp_path / "cal.json"
    xcp_ecu.save_calibration(ecu, f)
    doc = json.loads(f.read_text())
    doc["values"]["cal.app.drv.dkf[0].r"][2] = 999.0
    f.write_text(json.dumps(doc))
    parser = argparse.ArgumentParser()
    xcp_ecu.add_arguments(parser)
    fresh = Ecu()
    xcp_ecu.from_args(parser.parse_args(["--xcp", "on", "--xcp-dev", "--xcp-cal", str(f)]), fresh)
    assert fresh.c.app.drv.dkf[0].cfg.r[2] == 999.0 == xcp_ecu.read(fresh, "cal.app.drv.dkf[0].r", "ref")[2]  # as if flashed
    f.write_text("{}")
    with pytest.raises(ConfigError, match="not an XCP calibration file"):
        xcp_ecu.from_args(parser.parse_args(["--xcp", "on", "--xcp-dev", "--xcp-cal", str(f)]), Ecu())
    with pytest.raises(ConfigError, match="needs the XCP slave"):
        xcp_ecu.from_args(parser.parse_args(["--xcp", "off", "--xcp-cal", str(f)]), Ecu())


def test_the_xcp_bus_flags_are_python_cans_and_checked(capsys):
    """--xcp-interface/--xcp-channel/--xcp-bus-kwargs name the XCP bus (resolved like the ECU's bus);
    without them the slave stays on the ECU's bus; a lone rate or an XCP bus without the slave is an error."""
    import argparse

    parser = argparse.ArgumentParser()
    xcp_ecu.add_arguments(parser)
    desc = xcp_ecu.description()
    assert xcp_ecu.bus_config(parser.parse_args([]), desc) is None
    config = xcp_ecu.bus_config(parser.parse_args(["--xcp-interface", "udp_multicast", "--xcp-channel", "239.74.163.9",
                                                   "--xcp-bitrate", "500k", "--xcp-bus-kwargs", "port=50999"]), desc)
    assert config == {"interface": "udp_multicast", "channel": "239.74.163.9", "bitrate": 500000, "port": 50999,
                      "fd": True}
    assert main(["daemon", "--xcp", "on", "--xcp-dev", "--xcp-data-bitrate", "4M", "--duration", "1"]) == 1
    assert "--xcp-data-bitrate configures a separate XCP bus" in capsys.readouterr().err
    assert main(["daemon", "--xcp", "off", "--xcp-channel", "239.74.163.9", "--duration", "1"]) == 1
    assert "needs the XCP slave" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        main(["daemon", "--xcp", "on", "--xcp-dev", "--xcp-interface", "udp_multicast", "--xcp-bitrate", "fast",
              "--duration", "1"])
    assert "argument --xcp-bitrate: 'fast': expected a positive number of bit/s" in capsys.readouterr().err
