"""The embedded default bus stays on this host: no CAN frame leaves through a network interface.

python-can's own ``udp_multicast`` joins its group on INADDR_ANY (the default route's interface)
and sends with TTL 1, i.e. onto the local network segment. Every udp_multicast bus vehest-can
opens is joined on loopback and sends with TTL 0 unless the user names an interface and a TTL.
"""
import argparse
import os
import shutil
import socket
import struct
import subprocess
import sys
import time
from pathlib import Path

import can
import numpy as np
import pytest

from vehest_can.bus import bus as busmod
from vehest_can.bus.frames import database
from vehest_can.cli import main
from vehest_can.sim.powertrain import powertrain_car
from vehest_can.sim.session import run_inprocess
from vehest_can.systems.driveline.scenario import load_driveline_scenario
from vehest_can.systems.ecu import Ecu

CI = os.environ.get("CI", "").lower() in ("true", "1")
HERE = Path(__file__).resolve().parent  # tests/bus/
ECU_IDS = {m.frame_id for m in database("pt").messages if "VEHEST" in m.senders}  # the SyncAck is vehest_sim.dbc's


def loopback_only_namespace() -> list[str]:
    """The command prefix that runs a command in a new network namespace with only `lo` (up), or a
    skip (a failure under CI=true) with the reason it cannot be made here."""
    prefix = ["unshare", "--net"] if os.geteuid() == 0 else ["unshare", "--map-root-user", "--net"]
    reason = None
    if shutil.which("unshare") is None or shutil.which("ip") is None:
        reason = "unshare (util-linux) and ip (iproute2) are needed"
    else:
        r = subprocess.run([*prefix, "ip", "link", "set", "lo", "up"], capture_output=True, text=True)
        if r.returncode != 0:
            reason = f"{' '.join(prefix)} failed: {r.stderr.strip()}"
    if reason:
        message = f"no network namespace can be made here: {reason}"
        if CI:
            pytest.fail(f"{message} (CI=true: this test must run)", pytrace=False)
        pytest.skip(message)
    return prefix


def non_loopback_interfaces() -> list[str]:
    return [name for _, name in socket.if_nameindex() if not busmod._is_loopback(name)]


def tx_packets() -> dict[str, int]:
    """Transmit packet counters of every interface, from /proc/net/dev."""
    out = {}
    for line in Path("/proc/net/dev").read_text().splitlines()[2:]:
        name, fields = line.split(":", 1)
        out[name.strip()] = int(fields.split()[9])
    return out


def igmp_devices(group: str) -> set[str]:
    """The interfaces on which this host (namespace) has joined IPv4 `group` (/proc/net/igmp)."""
    want = f"{struct.unpack('<I', socket.inet_aton(group))[0]:08X}"
    devices, device = set(), None
    for line in Path("/proc/net/igmp").read_text().splitlines()[1:]:
        if not line[:1].isspace():
            device = line.split()[1]
        elif line.split()[0].upper() == want:
            devices.add(device)
    return devices


def ecu_frames(frames, ticks):
    sel = np.isin(frames["id"], list(ECU_IDS))
    return frames[sel], ticks[sel]


@pytest.mark.multicast
def test_lockstep_two_processes_on_the_default_bus_in_a_loopback_only_namespace(tmp_path):
    """The daemon and the simulator as two processes over the default bus, in a network namespace
    where loopback is the only interface: with python-can's INADDR_ANY join the bus cannot even
    open there (no route, no interface); host-only, it runs and equals the in-process run."""
    prefix = loopback_only_namespace()
    seconds = 1.0
    script = f"ip link set lo up && exec {sys.executable} {HERE / 'netns' / 'lockstep_default_bus.py'} {tmp_path} {seconds}"
    env = {k: v for k, v in os.environ.items() if not k.startswith("CAN_")}
    r = subprocess.run([*prefix, "sh", "-c", script], capture_output=True, text=True, timeout=300, env=env,
                       cwd=tmp_path)  # no can.ini / .canrc of the checkout's
    assert r.returncode == 0, r.stderr
    got = np.load(tmp_path / "session.npz")
    assert int(got["rc"]) == 0, (tmp_path / "daemon.err").read_text()
    err = (tmp_path / "daemon.err").read_text()
    assert "udp_multicast 239.74.163.2 port 43113 on 127.0.0.1, TTL 0: this host only" in err
    assert "faults: none" in err
    local = run_inprocess(powertrain_car(load_driveline_scenario("launch_2nd"), seconds), Ecu())
    a, b = ecu_frames(got["frames"], got["frame_tick"]), ecu_frames(local.frames, local.frame_tick)
    assert len(a[0]) == len(b[0]) > 1500
    assert np.array_equal(a[0], b[0]) and np.array_equal(a[1], b[1])


def capture_socket() -> socket.socket | None:
    """A packet socket on every interface (root only): each IPv4 datagram in or out, link header off."""
    try:
        s = socket.socket(socket.AF_PACKET, socket.SOCK_DGRAM, socket.htons(0x0800))  # ETH_P_IP
    except (PermissionError, AttributeError, OSError):
        return None
    s.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 16 << 20)  # every datagram of the test, kept
    s.setblocking(False)
    return s


def captured(sock: socket.socket, group: str, port: int) -> dict[str, int]:
    """UDP datagrams to group:port seen so far, per interface."""
    seen: dict[str, int] = {}
    while True:
        try:
            ip, addr = sock.recvfrom(65535)
        except BlockingIOError:
            return seen
        ihl = (ip[0] & 0xF) * 4
        if len(ip) >= ihl + 4 and ip[9] == 17 and socket.inet_ntoa(ip[16:20]) == group \
                and struct.unpack("!H", ip[ihl + 2:ihl + 4])[0] == port:
            seen[addr[0]] = seen.get(addr[0], 0) + 1


@pytest.mark.hostnet
def test_default_bus_sends_nothing_through_a_network_interface():
    """A few hundred frames on the default bus: /proc/net/igmp shows the group joined on `lo`
    only, no other interface's transmit counter moved by them, and (as root) a packet capture on
    every interface sees each frame on loopback and none anywhere else."""
    others = non_loopback_interfaces()
    if not others:
        pytest.skip("this namespace has no interface but loopback: nothing to leak to (run it in the host's)")
    config = busmod.private_multicast()
    group, port, n = config["channel"], config["port"], 400
    sock = capture_socket()
    if sock is None and CI:
        pytest.fail("CI=true runs as root: the packet capture must be available", pytrace=False)
    tx, rx = busmod.open_bus(config), busmod.open_bus(config)
    try:
        joined = igmp_devices(group)
        before = tx_packets()
        for i in range(n):
            tx.send(can.Message(arbitration_id=0x100 + i % 16, data=i.to_bytes(8, "little"),
                                is_extended_id=False, is_fd=True))
        got = 0
        while got < n and rx.recv(2.0) is not None:
            got += 1
        time.sleep(0.2)
        after = tx_packets()
    finally:
        tx.shutdown()
        rx.shutdown()
    assert got == n  # they did travel, on this host
    assert joined == {"lo"}, f"group {group} joined on {sorted(joined)}"
    moved = {name: after.get(name, 0) - before.get(name, 0) for name in others}
    # other traffic of the machine may move a counter a little; n leaked frames would move it by n
    assert all(d < n // 4 for d in moved.values()), moved
    if sock is not None:
        seen = captured(sock, group, port)
        sock.close()
        assert seen.get("lo", 0) >= n, seen           # the capture does see our frames...
        assert {k: v for k, v in seen.items() if k != "lo"} == {}, seen  # ...and only on loopback


def test_default_config_is_the_host_only_multicast_bus(monkeypatch, tmp_path):
    for var in ("CAN_INTERFACE", "CAN_CHANNEL", "CAN_BITRATE", "CAN_CONFIG"):
        monkeypatch.delenv(var, raising=False)
    monkeypatch.chdir(tmp_path)
    monkeypatch.setenv("HOME", str(tmp_path))
    config = busmod.bus_config(argparse.Namespace())
    assert config == {"interface": "udp_multicast", "channel": "239.74.163.2", "fd": True}
    bus = busmod.open_bus(busmod.private_multicast())
    try:
        assert isinstance(bus, busmod.HostMulticastBus) and bus.host_only
        assert "on 127.0.0.1, TTL 0: this host only" in busmod.describe_bus(bus, config)
    finally:
        bus.shutdown()


@pytest.mark.parametrize("kwargs, problem", [
    ({"channel": "ff15:7079:7468:6f6e:6465:6d6f:6d63:6173"}, "Linux's loopback carries no IPv6 multicast"),
    ({"hop_limit": 256}, "hop_limit must be an integer 0..255, not 256"),
    ({"hop_limit": "one"}, "hop_limit must be an integer 0..255, not 'one'"),
    ({"channel": "vcan0"}, "channel 'vcan0' is not an IP multicast group"),
    ({"multicast_interface": "nosuchif0", "hop_limit": 1}, "interface nosuchif0"),
])
def test_bad_multicast_settings_are_clear_errors(kwargs, problem):
    with pytest.raises(busmod.BusError, match="cannot open bus") as err:
        busmod.open_bus({**busmod.private_multicast(), **kwargs})
    assert problem in str(err.value)


def test_a_network_interface_without_a_ttl_is_refused_before_anything_is_sent():
    """Asking for another machine's reach takes both an interface and a TTL >= 1; the refusal
    comes before a socket joins anything (so this test sends nothing off the host)."""
    iface = next(iter(non_loopback_interfaces()), "eth0")
    with pytest.raises(busmod.BusError, match="hop_limit=0 would hear other machines but send them nothing"):
        busmod.open_bus({**busmod.private_multicast(), "multicast_interface": iface})


def test_hop_limit_from_a_config_file_string(tmp_path):
    ini = tmp_path / "can.ini"
    port = busmod.private_multicast()["port"]
    ini.write_text(f"[default]\ninterface = udp_multicast\nchannel = 239.74.163.9\nport = {port}\nhop_limit = 0\n")
    config = busmod.bus_config(argparse.Namespace(bus_config=str(ini)))
    bus = busmod.open_bus(config)
    try:
        assert bus.channel_info == f"udp_multicast 239.74.163.9 port {port} on 127.0.0.1, TTL 0: this host only"
    finally:
        bus.shutdown()


def test_daemon_with_bad_bus_kwargs_is_an_error_not_a_traceback(capsys):
    rc = main(["daemon", "--duration", "0.1", "-i", "udp_multicast", "-c", "239.74.163.2",
               "--bus-kwargs", "hop_limit=999"])
    err = capsys.readouterr().err
    assert rc == 1 and "error:" in err and "hop_limit must be an integer 0..255" in err
    assert "Traceback" not in err


@pytest.mark.parametrize("kwargs, problem", [
    (["bogus_kw=1"], "bus keyword argument bogus_kw=1: python-can's udp_multicast interface takes no argument "
                     "'bogus_kw' (it takes: can_filters, channel, fd, hop_limit, multicast_interface, port, "
                     "receive_own_messages)"),
    (["fd=maybe"], "bus keyword argument fd=maybe: python-can's udp_multicast interface takes fd as bool "
                   "(true or false), not 'maybe'"),
    (["port=1.5"], "bus keyword argument port=1.5: python-can's udp_multicast interface takes port as int, not 1.5"),
    (["port=50000", "hop_limt=1"], "takes no argument 'hop_limt' (did you mean 'hop_limit'?"),
])
@pytest.mark.parametrize("verb", [["monitor", "--duration", "0.1"], ["daemon", "--duration", "0.1"],
                                  ["sim", "launch_2nd", "--duration", "0.1"]])
def test_unknown_or_mistyped_bus_kwargs_are_refused_with_what_the_interface_takes(capsys, verb, kwargs, problem):
    """Once accepted and ignored: python-can hands unknown keyword arguments to BusABC, which drops them."""
    rc = main([*verb, "--bus-kwargs", *kwargs])
    err = capsys.readouterr().err
    assert rc == 1 and err.startswith("error: ") and problem in err and "Traceback" not in err, err


def test_bus_kwargs_are_checked_against_each_interfaces_signature():
    """python-can's own classes, introspected: what each takes and the simple types of its values."""
    ok = {"virtual": {"rx_queue_size": 10, "preserve_timestamps": True, "receive_own_messages": 1},
          "socketcan": {"local_loopback": False, "fd": True, "ignore_rx_error_frames": True},
          "udp_multicast": {"port": 50000, "hop_limit": 1, "multicast_interface": "eth0", "fd": False,
                            "can_filters": [1]}}
    for interface, kwargs in ok.items():
        assert busmod.check_bus_kwargs(interface, kwargs) == ([], "")
    problems, _ = busmod.check_bus_kwargs("virtual", {"rx_queue_size": 1.5, "protocol": "x", "bogus": 1})
    assert [k for k, _ in problems] == ["rx_queue_size", "bogus"]  # protocol is an enum: not checked
    assert "takes rx_queue_size as int, not 1.5" in problems[0][1]
    args, _ = busmod.interface_arguments("socketcan")
    assert args is not None and args["fd"] == (bool,) and args["can_filters"] is None and "kwargs" not in args


@pytest.mark.parametrize("where", ["env", "file"])
def test_a_bogus_interface_named_outside_the_flags_is_an_error_not_the_default_bus(tmp_path, monkeypatch, capsys, where):
    """python-can refuses an unknown interface; so does vehest-can, wherever it was named (a bench
    that silently ran on the default bus would be on the wrong bus without knowing it)."""
    for var in ("CAN_INTERFACE", "CAN_CHANNEL", "CAN_CONFIG"):
        monkeypatch.delenv(var, raising=False)
    monkeypatch.setenv("HOME", str(tmp_path))
    if where == "env":
        monkeypatch.setenv("CAN_INTERFACE", "bogus")
    else:
        (tmp_path / ".canrc").write_text("[default]\ninterface = bogus\n")
    assert main(["daemon", "--duration", "0.1"]) == 1
    err = capsys.readouterr().err
    assert 'Unknown interface type "bogus"' in err
    assert ("CAN_INTERFACE" in err) if where == "env" else ("configuration file" in err)
