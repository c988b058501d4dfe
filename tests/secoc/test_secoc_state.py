"""SecOC freshness that survives restarts by default (docs/secoc.md, "Restarts"): the state file
(mode 600 in a 700 folder, written atomically, every bad file a clear error), and the real daemon
started twice on the host-only bus with default flags: frames recorded in its first run and replayed
in its second are all rejected, after a clean stop and after a kill -9, and its first sync frame is
never the same twice. A control run with `--secoc-state none` accepts the same replay."""
from __future__ import annotations

import json
import os
import signal
import stat
import subprocess
import sys
import threading
import time

import can
import pytest
from daemonproc import start_daemon, stop_daemon

from vehest_can.bus.bus import open_bus, private_multicast
from vehest_can.bus.frames import database, to_message
from vehest_can.bus.secoc import (
    RESERVE_BLOCK,
    BusSecoc,
    FreshnessStore,
    crash_margin,
    default_state_path,
    secured_messages,
    state_dir,
    write_dev_keys,
)
from vehest_can.errors import ConfigError
from vehest_can.systems.roll.scenario import RollCar, load_roll_scenario

CH = database("ch")
SYNC_CH = CH.get_message_by_name("VEHEST_SecOCSyncCh").frame_id
SECURED = secured_messages()


@pytest.fixture(scope="module")
def keyfile(tmp_path_factory):
    from vehest_can.cli.secoc import sending_nodes

    path = tmp_path_factory.mktemp("keys") / "keys.toml"
    return path, write_dev_keys(path, sending_nodes())


# ---- the state file --------------------------------------------------------------------------------

def test_default_state_file_is_private_and_written_atomically(keyfile, tmp_path, monkeypatch):
    _, keys = keyfile
    monkeypatch.setenv("XDG_STATE_HOME", str(tmp_path / "xdg"))
    path = default_state_path(keys, ("VEHEST",))
    assert path.parent == tmp_path / "xdg" / "vehest-can" == state_dir()
    assert path.name.startswith("secoc-VEHEST-") and keys["VEHEST"].raw.hex() not in path.name
    s = BusSecoc("VEHEST", keys, store=FreshnessStore(path))
    assert stat.S_IMODE(path.stat().st_mode) == 0o600 and stat.S_IMODE(path.parent.stat().st_mode) == 0o700
    doc = json.loads(path.read_text())
    assert doc["nodes"]["VEHEST"] == {"reserved": 1 + RESERVE_BLOCK, "latest": {}, "clean": False}
    # atomic: a write that fails half way leaves the previous file whole (the half one is a temp file)
    store = s.store
    store.node("VEHEST").reserved = 10**9
    real_dump = json.dump

    def dies(obj, f, **kw):
        f.write('{"format": "vehest-can secoc fresh')  # half a file ...
        raise OSError(28, "No space left on device")  # ... then the disk is full

    monkeypatch.setattr(json, "dump", dies)
    with pytest.raises(ConfigError, match="cannot write the SecOC freshness state file: No space left"):
        store.save()
    monkeypatch.setattr(json, "dump", real_dump)
    assert json.loads(path.read_text()) == doc
    assert {p.name for p in path.parent.iterdir()} == {path.name, f".{path.name}.tmp"}
    store.save()  # the next write replaces the stale temp file
    assert {p.name for p in path.parent.iterdir()} == {path.name}
    s.close()
    assert json.loads(path.read_text())["nodes"]["VEHEST"] == {"reserved": 1, "latest": {}, "clean": True}


def test_bad_state_files_are_clear_errors(keyfile, tmp_path):
    _, keys = keyfile
    p = tmp_path / "s.json"
    good = {"format": "vehest-can secoc freshness", "version": 1,
            "nodes": {"VEHEST": {"reserved": 5, "latest": {"ROLL": 3}, "clean": True}}}
    cases = [("{", "corrupt"), ("[]", "not a JSON object"), (b"\xff\xfe", "corrupt"),
             ('{"reserved": "x"}', "not a SecOC freshness state file"),
             ('{"latest": {}}', "not a SecOC freshness state file"),
             ('{"reserved": -4}', "must be positive"),
             (json.dumps({**good, "format": "other"}), "format is 'other'"),
             (json.dumps({**good, "nodes": {"VEHEST": {"reserved": 2**64}}}), "64-bit")]
    for text, words in cases:
        p.unlink(missing_ok=True)
        (p.write_bytes if isinstance(text, bytes) else p.write_text)(text)
        p.chmod(0o600)
        with pytest.raises(ConfigError, match=words):
            FreshnessStore(p)
    p.write_text(json.dumps(good))
    for mode in (0o644, 0o660, 0o602):  # a state others may write could be rewound: refused as a key file is
        p.chmod(mode)
        with pytest.raises(ConfigError, match=f"permissions {mode:04o} are too open"):
            FreshnessStore(p)
    p.chmod(0o600)
    assert FreshnessStore(p).node("VEHEST").latest == {"ROLL": 3}
    os.chown(p, 4242, -1)  # someone else's (the tests run as root on this machine; skip otherwise)
    if os.stat(p).st_uid == 4242:
        with pytest.raises(ConfigError, match="belongs to uid 4242"):
            FreshnessStore(p)
    with pytest.raises(ConfigError, match="not a regular file"):
        FreshnessStore(tmp_path)
    loose = tmp_path / "loose"
    loose.mkdir(mode=0o777)
    loose.chmod(0o777)
    with pytest.raises(ConfigError, match="writable by others"):
        BusSecoc("VEHEST", keys, store=FreshnessStore(loose / "s.json"))


@pytest.mark.multicast
def test_daemon_state_file_errors_are_one_line(keyfile, tmp_path):
    path, _ = keyfile
    bad = tmp_path / "bad.json"
    bad.write_text("{ not json")
    bad.chmod(0o600)
    open_ = tmp_path / "open.json"
    open_.write_text("{}")
    open_.chmod(0o644)
    for state, words in ((bad, "corrupt"), (open_, "too open"), (tmp_path, "not a regular file")):
        r = subprocess.run([sys.executable, "-m", "vehest_can.cli", "daemon", "--duration", "0.1",
                            "--secoc-keys", str(path), "--secoc-state", str(state)],
                           capture_output=True, text=True, timeout=120)
        assert r.returncode != 0 and "Traceback" not in r.stderr, r.stderr
        assert r.stderr.strip().splitlines()[-1].startswith("error: ") and words in r.stderr, r.stderr


@pytest.mark.multicast
def test_no_state_is_explicit_and_warned(keyfile, tmp_path):
    path, _ = keyfile
    r = subprocess.run([sys.executable, "-m", "vehest_can.cli", "daemon", "--duration", "0.2",
                        "--secoc-keys", str(path), "--secoc-state", "none"],
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    warn = [ln for ln in r.stderr.splitlines() if ln.startswith("warning: --secoc-state none")]
    assert len(warn) == 1 and "replayed" in warn[0]
    assert not any(state_dir().glob("*.json"))  # nothing persisted


# ---- the crash margin, in process ------------------------------------------------------------------

def test_a_crashed_receiver_resumes_above_what_it_may_have_accepted(keyfile, tmp_path):
    _, keys = keyfile
    margin = crash_margin("ROLL")
    assert 1000 < margin < 5000  # about 3 s of the roll node's 611 secured frames a second
    store = FreshnessStore(tmp_path / "ecu.json")
    ecu = BusSecoc("VEHEST", keys, store=store)
    ecu.c.rx[ecu._idx["ROLL"]].latest = 700  # as if it had accepted the roll node up to FV 700 ...
    ecu.maintain()                         # ... and written that; then it dies (no close)
    again = BusSecoc("VEHEST", keys, store=FreshnessStore(tmp_path / "ecu.json"))
    assert again.c.rx[again._idx["ROLL"]].latest == 700 + margin  # frames after the last write: stale too
    assert again.c.tx.fv == 1 + RESERVE_BLOCK  # and it sends above every FV it may have used
    again.close()  # a clean end stores the exact state: no margin on the next start
    third = BusSecoc("VEHEST", keys, store=FreshnessStore(tmp_path / "ecu.json"))
    assert third.c.rx[third._idx["ROLL"]].latest == 700 + margin and third.c.tx.fv == 1 + RESERVE_BLOCK


# ---- the daemon started twice ----------------------------------------------------------------------

class Recorder(can.Listener):
    def __init__(self):
        self.frames: list[can.Message] = []
        self.lock = threading.Lock()

    def on_message_received(self, msg):
        with self.lock:
            self.frames.append(msg)

    def first(self, frame_id: int, timeout: float = 20.0) -> can.Message:
        t0 = time.monotonic()
        while time.monotonic() - t0 < timeout:
            with self.lock:
                for m in self.frames:
                    if m.arbitration_id == frame_id:
                        return m
            time.sleep(0.05)
        raise AssertionError(f"no frame {frame_id:#x} within {timeout} s")


def _car_frames(keys, ticks: int) -> list[can.Message]:
    """The roll car's frames (its CHS and ROLL nodes secured, FVs from 1), as a sender records them."""
    car = RollCar(load_roll_scenario("roll_paper_72kph_active"), 1.0)
    car.enable_secoc(keys)
    return [to_message(f) for k in range(ticks) for f in car.tick(k)]


def _send(bus, msgs) -> None:
    for i, m in enumerate(msgs):
        bus.send(m)
        if i % 4 == 3:
            time.sleep(0.001)  # paced like the car's 2 kHz (the loopback multicast keeps every frame)


def _run(config, keyfile, tmp_path, name, *extra, send=(), stop=signal.SIGTERM):
    """One daemon run on the bus: its frames as heard, its --stats (None after a kill -9)."""
    rec = Recorder()
    bus = open_bus(config)
    notifier = can.Notifier(bus, [rec])
    (tmp_path / name).mkdir()
    stats = tmp_path / name / "stats.json"
    proc = start_daemon(config, "--mode", "realtime", "--secoc-keys", str(keyfile), "--stats", str(stats), *extra,
                        tmp_path=tmp_path / name)
    try:
        rec.first(SYNC_CH)
        _send(bus, send)
        time.sleep(0.3)
    finally:
        rc, err = stop_daemon(proc, stop)
        notifier.stop()
        bus.shutdown()
    assert rc in (0, -signal.SIGKILL), err
    return rec.frames, (json.loads(stats.read_text())["secoc"] if stats.exists() else None), err


def _fv_of_sync(msg) -> int:
    return int.from_bytes(bytes(msg.data)[:8], "big")


@pytest.mark.multicast
@pytest.mark.parametrize("stop", [signal.SIGTERM, signal.SIGKILL], ids=["clean-stop", "kill-9"])
def test_daemon_restarted_with_default_flags_rejects_every_replayed_frame(keyfile, tmp_path, stop):
    path, keys = keyfile
    config = private_multicast()
    car = _car_frames(keys, 400)  # 0.2 s of the roll car: CHS_Sensors, the roll node's frames, both sync frames
    n_secured = sum(1 for m in car if m.arbitration_id in SECURED)
    assert n_secured == len(car) > 500

    run1, stats1, err1 = _run(config, path, tmp_path, "run1", send=car, stop=stop)
    assert "SecOC freshness state" in err1 and str(state_dir()) in err1
    if stats1 is not None:  # the first run took the car's frames: all verified
        assert stats1["accepted"] >= 0.95 * (n_secured - 2) and stats1["rejected"] == 0, stats1
    syncs1 = [m for m in run1 if m.arbitration_id == SYNC_CH]
    vehest1 = [m for m in run1 if m.arbitration_id in SECURED and SECURED[m.arbitration_id][0] == "VEHEST"]

    # the second run: the recorded frames replayed, the old sync frames first
    run2, stats2, _ = _run(config, path, tmp_path, "run2", send=car)
    assert stats2["accepted"] == 0, stats2
    assert stats2["rejected"] >= 0.95 * n_secured, stats2
    # its own first sync frame is new, above every FV the first run may have sent
    first2 = next(m for m in run2 if m.arbitration_id == SYNC_CH)
    assert bytes(first2.data) != bytes(syncs1[0].data)
    last = max(i for i, m in enumerate(vehest1) if m.arbitration_id == SYNC_CH)
    last_fv = _fv_of_sync(vehest1[last]) + len(vehest1) - last - 1  # one FV per VEHEST frame after it
    # (how far run 1 got depends on the machine's speed: it must only have moved on from its first sync)
    assert last_fv > _fv_of_sync(syncs1[0]) and _fv_of_sync(first2) > last_fv
    if stop == signal.SIGKILL:  # after a crash: at the persisted reservation bound, a block ahead
        assert _fv_of_sync(first2) >= 1 + RESERVE_BLOCK

    if stop == signal.SIGTERM:  # the control: without persistence the same replay is accepted
        _, stats3, err3 = _run(config, path, tmp_path, "run3", "--secoc-state", "none", send=car)
        assert "warning: --secoc-state none" in err3
        assert stats3["accepted"] >= 0.95 * (n_secured - 2), stats3
