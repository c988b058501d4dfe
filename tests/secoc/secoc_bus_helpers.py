"""What the SecOC-on-the-bus tests share (test_secoc_bus.py: the chassis bus and the roll node;
test_secoc_pt.py: the powertrain sensor frames): development keys for every sending node, the
frames' authentic parts, and a lockstep session with the ECU daemon over udp_multicast, SecOC on."""
from __future__ import annotations

from daemonproc import start_daemon, stop_daemon

from vehest_can.bus.bus import open_bus, private_multicast
from vehest_can.bus.frames import authentic_data
from vehest_can.bus.secoc import secured_messages, write_dev_keys
from vehest_can.sim.session import SimMaster


def dev_keys(tmp_path_factory) -> dict:
    from vehest_can.cli.secoc import sending_nodes

    return write_dev_keys(tmp_path_factory.mktemp("keys") / "keys.toml", sending_nodes())


def authentic(frames):
    """Frames by tick without their SecOC tails and without the sync frames."""
    sync = {i for i, v in secured_messages().items() if v[3]}
    return [[(m.arbitration_id, authentic_data(m.arbitration_id, bytes(m.data))) for m in tick
             if m.arbitration_id not in sync] for tick in frames]


def daemon_lockstep(keys: dict, car, tmp_path):
    """car (or a Drive) in lockstep with `vehest-can daemon --secoc-keys` (these keys) over a private
    udp_multicast bus. Returns (the session, the daemon's exit status, its stderr)."""
    keyfile = tmp_path / "keys.toml"
    write_dev_keys(keyfile, [])  # a fresh file, then the keys into it (mode 600 kept)
    keyfile.write_text("[keys]\n" + "".join(f'{k.node} = "{k.raw.hex()}"\n' for k in keys.values()))
    config = private_multicast()
    # keys made for this test, so no persisted freshness: both sides start at FV 1, as in-process
    proc = start_daemon(config, "--mode", "lockstep", "--idle-timeout", "60", "--secoc-keys", str(keyfile),
                        "--secoc-state", "none", tmp_path=tmp_path)
    try:
        bus = open_bus(config)
        try:
            session = SimMaster(bus, car).run_lockstep()
        finally:
            bus.shutdown()
    finally:
        rc, err = stop_daemon(proc)
    return session, rc, err
