"""The UML harness gives a real SocketCAN vcan0: kernel, python-can and can-utils inside a guest.

Each guest boot costs one to a few seconds, so checks that share a boot are batched into one
guest script that prints JSON for the host to judge. Nothing here measures time: the guest
kernel ticks at 100 Hz.
"""

import json
import os
import shlex
import sys
import time
from pathlib import Path

import can
import pytest

from vehest_can.tools import uml as vuml

PY = shlex.quote(sys.executable)

# One boot: the vcan links as ip(8) sees them, python-can's socketcan bus on vcan0/vcan1, and
# python-can's udp_multicast inside the guest.
GUEST_SOCKETCAN = r'''
import json, subprocess, sys
import can, can.interfaces.udp_multicast

def frames(bus, first=2.0, more=0.3):
    got, timeout = [], first
    while (m := bus.recv(timeout=timeout)) is not None:
        got.append({"id": m.arbitration_id, "ext": m.is_extended_id, "fd": m.is_fd,
                    "brs": m.bitrate_switch, "rtr": m.is_remote_frame, "dlc": m.dlc,
                    "data": m.data.hex(), "rx": m.is_rx, "channel": m.channel})
        timeout = more
    return got

out = {"argv0": sys.executable}
out["ip_text"] = subprocess.run(["ip", "-details", "link", "show", "vcan0"],
                                capture_output=True, text=True, check=True).stdout
out["ip_json"] = json.loads(subprocess.run(["ip", "-details", "-json", "link", "show"],
                                           capture_output=True, text=True, check=True).stdout)

tx = can.Bus(interface="socketcan", channel="vcan0", fd=True)  # receive_own_messages=False
rx = can.Bus(interface="socketcan", channel="vcan0", fd=True)
own = can.Bus(interface="socketcan", channel="vcan0", fd=True, receive_own_messages=True)
classic_only = can.Bus(interface="socketcan", channel="vcan0", fd=False)
other_channel = can.Bus(interface="socketcan", channel="vcan1", fd=True)

tx.send(can.Message(arbitration_id=0x123, is_extended_id=False,
                    data=bytes([0xDE, 0xAD, 0xBE, 0xEF, 1, 2, 3, 4])))
tx.send(can.Message(arbitration_id=0x18DAF110, is_extended_id=True, is_fd=True,
                    bitrate_switch=True, data=bytes(range(64))))
out["rx"] = frames(rx)
out["tx_self"] = frames(tx, first=0.5)
out["classic_only"] = frames(classic_only)
out["vcan1"] = frames(other_channel, first=0.5)
own.send(can.Message(arbitration_id=0x7FF, is_extended_id=False, is_fd=True,
                     data=bytes([0xA5] * 12)))
out["own"] = frames(own)
out["rx_after_own"] = frames(rx)
for bus in (tx, rx, own, classic_only, other_channel):
    bus.shutdown()

for name, group in (("udp6", can.interfaces.udp_multicast.UdpMulticastBus.DEFAULT_GROUP_IPv6),
                    ("udp4", can.interfaces.udp_multicast.UdpMulticastBus.DEFAULT_GROUP_IPv4)):
    a = can.Bus(interface="udp_multicast", channel=group, fd=True)
    b = can.Bus(interface="udp_multicast", channel=group, fd=True)
    a.send(can.Message(arbitration_id=0x42, is_extended_id=False, is_fd=True,
                       data=bytes(range(16))))
    out[name] = frames(b)
    a.shutdown()
    b.shutdown()
print(json.dumps(out))
'''

# One boot: candump -L records what cansend and a python-can sender put on vcan0.
GUEST_INTEROP = r'''
set -e
out=$1
timeout 60 candump -L -n 6 vcan0 > "$out/candump.log" &
dump=$!
i=0
until grep -q ' vcan0 .* raw$' /proc/net/can/rcvlist_all; do  # candump has bound its socket
    i=$((i + 1)); [ "$i" -lt 3000 ] || { echo "candump never listened" >&2; exit 90; }
    sleep 0.01
done
cansend vcan0 123#DEADBEEF
cansend vcan0 1ABCDEF0#0102030405060708
cansend vcan0 321##1$(i=0; while [ $i -lt 64 ]; do printf '%02X' $((255 - i)); i=$((i + 1)); done)
cansend vcan0 456#R
"$PY" "$out/sender.py"
wait "$dump"
'''

GUEST_SENDER = r'''
import can
with can.Bus(interface="socketcan", channel="vcan0", fd=True) as bus:
    bus.send(can.Message(arbitration_id=0x0AB, is_extended_id=False, data=b"\x01\x02\x03"))
    bus.send(can.Message(arbitration_id=0x1F000001, is_extended_id=True, is_fd=True,
                         bitrate_switch=True, data=bytes(range(100, 148))))
'''


def _frame(id_, ext, data, *, fd=False, brs=False, rtr=False, rx=False, channel="vcan0"):
    data = bytes(data)
    return {"id": id_, "ext": ext, "fd": fd, "brs": brs, "rtr": rtr,
            "dlc": len(data), "data": data.hex(), "rx": rx, "channel": channel}


CLASSIC = _frame(0x123, False, [0xDE, 0xAD, 0xBE, 0xEF, 1, 2, 3, 4])
FD64 = _frame(0x18DAF110, True, range(64), fd=True, brs=True)


# --------------------------------------------------------------------------- no boot needed


def test_available_reports_a_reason():
    ok, reason = vuml.available()
    assert isinstance(ok, bool)
    assert reason


@pytest.mark.parametrize("kwargs, match", [
    ({"cmd": ""}, "non-empty"),
    ({"cmd": "true", "interfaces": ("vcan0; reboot",)}, "bad interface"),
    ({"cmd": "true", "timeout": 0}, "timeout"),
    ({"cmd": "true", "mem": "lots"}, "mem"),
    ({"cmd": "true", "workdir": "/tmp/a b"}, "whitespace"),
])
def test_run_rejects_bad_arguments_before_booting(kwargs, match):
    with pytest.raises(vuml.UmlError, match=match):
        vuml.run(**kwargs)


def test_module_plan_follows_modules_dep(tmp_path):
    """Dependencies load first, built-in modules are skipped, a missing one is named."""
    mods = tmp_path / "6.99.0"
    rel = {
        "can": "kernel/net/can/can.ko",
        "can-raw": "kernel/net/can/can-raw.ko",
        "can-bcm": "kernel/net/can/can-bcm.ko",
        "can-dev": "kernel/drivers/net/can/dev/can-dev.ko",
        "vcan": "kernel/drivers/net/can/vcan.ko",
    }
    for path in rel.values():
        (mods / path).parent.mkdir(parents=True, exist_ok=True)
        (mods / path).write_bytes(b"")
    (mods / "modules.dep").write_text(
        f"{rel['vcan']}: {rel['can-dev']}\n{rel['can-raw']}: {rel['can']}\n"
        f"{rel['can-bcm']}: {rel['can']}\n{rel['can-dev']}:\n")
    (mods / "modules.builtin").write_text("kernel/net/can/can.ko\n")
    kernel = vuml.UmlKernel(binary=Path("/nonexistent"), modules=mods, version="6.99.0",
                            origin="test")
    plan = [p.relative_to(mods).as_posix() for p in vuml._module_plan(kernel)]
    assert plan == [rel["can-raw"], rel["can-bcm"], rel["can-dev"], rel["vcan"]]

    (mods / "modules.builtin").write_text("")
    with pytest.raises(vuml.UmlError, match="no module can"):
        vuml._module_plan(kernel)


# --------------------------------------------------------------------------- in the guest


@pytest.mark.uml
def test_socketcan_vcan_python_can_in_guest(uml, tmp_path):
    script = tmp_path / "guest_socketcan.py"
    script.write_text(GUEST_SOCKETCAN)
    result = uml.run(f"{PY} {shlex.quote(str(script))}", timeout=180,
                     interfaces=("vcan0", "vcan1"), workdir=tmp_path / "uml")
    assert result.returncode == 0, result.stderr
    out = json.loads(result.stdout)
    assert out["argv0"] == sys.executable  # the host's venv interpreter runs in the guest

    # ip(8): real vcan links with the CAN FD MTU.
    assert "vcan" in out["ip_text"].split() and "mtu 72" in out["ip_text"]
    links = {link["ifname"]: link for link in out["ip_json"]}
    for name in ("vcan0", "vcan1"):
        assert links[name]["linkinfo"]["info_kind"] == "vcan"
        assert links[name]["mtu"] == 72
        assert links[name]["link_type"] == "can"
        assert "UP" in links[name]["flags"]

    # Another socket on vcan0 receives both frames, flags intact.
    assert out["rx"] == [CLASSIC, FD64]
    # The sender does not see its own frames without receive_own_messages ...
    assert out["tx_self"] == []
    # ... a socket without CAN_RAW_FD_FRAMES gets the classic frame only ...
    assert out["classic_only"] == [CLASSIC]
    # ... and vcan1 is a separate bus.
    assert out["vcan1"] == []
    # With receive_own_messages the bus gets the others' frames and its own echo.
    own = _frame(0x7FF, False, [0xA5] * 12, fd=True)
    assert out["own"] == [CLASSIC, FD64, own]
    assert out["rx_after_own"] == [own]
    # python-can derives is_rx from MSG_DONTROUTE ("created on this host"), which every frame
    # on a vcan has: is_rx is False for all of them, so it cannot tell an echo from a peer's.
    assert not any(f["rx"] for key in ("rx", "own", "classic_only") for f in out[key])

    # python-can's udp_multicast also works inside (IPv6 and IPv4 groups).
    for name in ("udp6", "udp4"):
        assert len(out[name]) == 1, name
        got = out[name][0]
        assert (got["id"], got["fd"], got["data"]) == (0x42, True, bytes(range(16)).hex())


@pytest.mark.uml
def test_candump_records_cansend_and_python_can(uml, tmp_path):
    (tmp_path / "interop.sh").write_text(GUEST_INTEROP)
    (tmp_path / "sender.py").write_text(GUEST_SENDER)
    result = uml.run(f"sh interop.sh {shlex.quote(str(tmp_path))}", timeout=180,
                     cwd=tmp_path, env={"PY": sys.executable}, workdir=tmp_path / "uml")
    assert result.returncode == 0, result.stderr

    log = tmp_path / "candump.log"
    lines = log.read_text().splitlines()
    assert len(lines) == 6 and lines[0].endswith(" vcan0 123#DEADBEEF"), lines

    with can.LogReader(log) as reader:  # .log -> can.CanutilsLogReader
        assert isinstance(reader, can.CanutilsLogReader)
        got = [(m.arbitration_id, m.is_extended_id, m.is_remote_frame, m.is_fd,
                m.bitrate_switch, bytes(m.data), m.channel) for m in reader]
    assert got == [
        (0x123, False, False, False, False, bytes.fromhex("DEADBEEF"), "vcan0"),
        (0x1ABCDEF0, True, False, False, False, bytes(range(1, 9)), "vcan0"),
        (0x321, False, False, True, True, bytes(255 - i for i in range(64)), "vcan0"),
        (0x456, False, True, False, False, b"", "vcan0"),
        (0x0AB, False, False, False, False, b"\x01\x02\x03", "vcan0"),
        (0x1F000001, True, False, True, True, bytes(range(100, 148)), "vcan0"),
    ]


@pytest.mark.uml
def test_exit_code_output_cwd_and_env_cross_over(uml, tmp_path):
    cwd = tmp_path / "a dir"
    cwd.mkdir()
    result = uml.run('echo "out:$VEHEST_PROBE"; pwd; id -u; echo "venv:$VIRTUAL_ENV"; '
                     'echo oops >&2; exit 7',
                     timeout=120, cwd=cwd, env={"VEHEST_PROBE": "it's here", "VIRTUAL_ENV": "v"},
                     workdir=tmp_path / "uml")
    assert result.returncode == 7
    assert result.stdout.splitlines() == ["out:it's here", str(cwd), "0", "venv:v"]
    assert result.stderr == "oops\n"
    assert result.console_log == tmp_path / "uml" / "console.log"
    assert "vcan: Virtual CAN interface driver" in result.console


@pytest.mark.uml
def test_guest_setup_failure_raises_with_the_setup_log(uml, tmp_path):
    # "lo" exists already, so `ip link add dev lo type vcan` fails in the guest's setup.
    with pytest.raises(vuml.UmlError, match="(?s)Guest setup failed.*File exists") as err:
        uml.run("true", timeout=120, interfaces=("lo",), workdir=tmp_path / "uml")
    assert err.value.workdir == tmp_path / "uml"
    assert "vcan: Virtual CAN interface driver" in err.value.console_tail


@pytest.mark.uml
def test_timeout_kills_the_guest(uml, tmp_path):
    work = tmp_path / "uml"
    start = time.monotonic()
    with pytest.raises(vuml.UmlTimeout, match="timed out"):
        uml.run("sleep 600", timeout=5, workdir=work)
    assert time.monotonic() - start < 60
    # No process of that guest (the UML kernel or its guest-process helpers) survives.
    survivors = []
    for pid in os.listdir("/proc"):
        try:
            cmdline = Path("/proc", pid, "cmdline").read_bytes()
        except OSError:
            continue
        if str(work).encode() in cmdline:
            survivors.append(pid)
    assert survivors == []
