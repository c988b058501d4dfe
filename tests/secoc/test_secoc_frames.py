"""SecOC-style secured frames: genuine traffic passes, spoofed, replayed and corrupted frames are
all rejected and counted, freshness survives restarts of either side (with its state) and comes
back through a sync frame (without it). The layout is checked by an independent decoder written
here from the spec with `cryptography`'s CMAC."""
from __future__ import annotations

import os
import random
import stat

import pytest
from secoc_peers import Receiver, Sender

from vehest_can.bus.secoc import RESERVE_BLOCK, FreshnessStore, Key, load_keys, write_dev_keys
from vehest_can.errors import ConfigError

KEY = Key("CHS", bytes(range(16)))
DATA_ID = 0x110


def frames(n, seed=1, length=28):
    rng = random.Random(seed)
    return [bytes(rng.randrange(256) for _ in range(length)) for _ in range(n)]


def independent_verify(key: bytes, data_id: int, data: bytes, latest: int) -> int | None:
    """The spec, once more: DataToAuthenticator = data ID (2 bytes BE) | authentic | FV (8 bytes BE),
    MAC truncated to its 3 most significant bytes, FV to its least significant byte; the smallest FV
    above `latest` with the received low byte. Returns the FV, or None."""
    cr = pytest.importorskip("cryptography.hazmat.primitives.cmac")
    from cryptography.hazmat.primitives.ciphers import algorithms

    authentic, t, mac = data[:-4], data[-4], data[-3:]
    fv = (latest & ~0xFF) | t
    if fv <= latest:
        fv += 0x100
    c = cr.CMAC(algorithms.AES128(key))
    c.update(data_id.to_bytes(2, "big") + authentic + fv.to_bytes(8, "big"))
    return fv if c.finalize()[:3] == mac else None


def test_genuine_traffic_all_accepted_and_decoded_independently():
    tx, rx = Sender(KEY), Receiver(KEY)
    rx_sync = tx.sync_frame(DATA_ID)
    assert rx.accept_sync(DATA_ID, rx_sync) == "ok"
    latest = int.from_bytes(rx_sync[:8], "big")
    for payload in frames(2000):
        data = tx.protect(DATA_ID, payload)
        assert len(data) == len(payload) + 4 and data[:-4] == payload  # the authentic part is in clear
        verdict, out = rx.verify(DATA_ID, data)
        assert verdict == "ok" and out == payload
        fv = independent_verify(KEY.raw, DATA_ID, data, latest)
        assert fv == latest + 1
        latest = fv
    assert rx.counts == {"accepted": 2001, "bad_mac": 0, "replayed": 0, "unsynced": 0, "resyncs": 1}


def synced_pair(store_tx=None, store_rx=None):
    tx, rx = Sender(KEY, store_tx), Receiver(KEY, store_rx)
    assert rx.accept_sync(0x7F0, tx.sync_frame(0x7F0)) == "ok"
    return tx, rx


def test_spoofed_flipped_replayed_and_foreign_frames_rejected():
    tx, rx = synced_pair()
    rng = random.Random(7)
    sent = [tx.protect(DATA_ID, p) for p in frames(300)]
    for d in sent[:100]:
        assert rx.verify(DATA_ID, d)[0] == "ok"
    spoofed = [d[:-3] + bytes(rng.randrange(256) for _ in range(3)) for d in sent[100:200]]
    flipped = []
    for d in sent[100:200]:
        b = bytearray(d)
        bit = rng.randrange(8 * (len(d) - 4))
        b[bit // 8] ^= 1 << (bit % 8)
        flipped.append(bytes(b))
    verdicts = [rx.verify(DATA_ID, d)[0] for d in spoofed + flipped]
    assert verdicts.count("ok") == 0 and set(verdicts) == {"bad_mac"}
    replays = [rx.verify(DATA_ID, d) for d in sent[:100]]
    assert all(v == ("replayed", None) for v in replays)
    other_id = [rx.verify(DATA_ID + 1, d)[0] for d in sent[100:110]]  # a frame moved to another ID
    assert set(other_id) == {"bad_mac"}
    c = rx.counts
    assert c["bad_mac"] == 210 and c["replayed"] == 100
    # genuine traffic still passes after the attack: failures do not unsynchronise the receiver
    assert [rx.verify(DATA_ID, d)[0] for d in sent[100:]] == ["ok"] * 200


def test_lost_frames_up_to_four_wraps_then_a_sync_frame():
    tx, rx = synced_pair()
    for lost in (1, 255, 256, 1000):
        for p in frames(lost):
            tx.protect(DATA_ID, p)
        assert rx.verify(DATA_ID, tx.protect(DATA_ID, b"x" * 8))[0] == "ok", lost
    for p in frames(1100):  # more than 4 wraps of the 8-bit FV: cannot be reconstructed
        tx.protect(DATA_ID, p)
    assert rx.verify(DATA_ID, tx.protect(DATA_ID, b"x" * 8))[0] == "bad_mac"
    assert rx.accept_sync(0x7F0, tx.sync_frame(0x7F0)) == "ok"
    assert rx.verify(DATA_ID, tx.protect(DATA_ID, b"x" * 8))[0] == "ok"


def test_sender_restart_resumes_above_every_fv_it_sent(tmp_path):
    store = FreshnessStore(tmp_path / "chs.json")
    tx, rx = synced_pair(store_tx=store)
    for p in frames(50):
        rx.verify(DATA_ID, tx.protect(DATA_ID, p))
    tx2 = Sender(KEY, FreshnessStore(tmp_path / "chs.json"))  # restart: state read back
    assert tx2.fv > tx.fv and tx2.fv == RESERVE_BLOCK + 1
    assert rx.verify(DATA_ID, tx2.protect(DATA_ID, b"after restart"))[0] == "bad_mac"  # > 4 wraps ahead
    assert rx.accept_sync(0x7F0, tx2.sync_frame(0x7F0)) == "ok"  # the periodic sync frame
    assert rx.verify(DATA_ID, tx2.protect(DATA_ID, b"after restart"))[0] == "ok"
    old = Sender(KEY)  # a sender that lost its state restarts at 1: everything it sends is stale
    assert rx.verify(DATA_ID, old.protect(DATA_ID, b"stale"))[0] in ("replayed", "bad_mac")
    assert rx.accept_sync(0x7F0, old.sync_frame(0x7F0)) == "replayed"


def test_receiver_restart_with_and_without_its_state(tmp_path):
    tx, rx = synced_pair(store_rx=FreshnessStore(tmp_path / "ecu.json"))
    sent = [tx.protect(DATA_ID, p) for p in frames(20)]
    for d in sent:
        rx.verify(DATA_ID, d)
    rx.remember()
    rx2 = Receiver(KEY, FreshnessStore(tmp_path / "ecu.json"))
    assert rx2.synced
    assert [rx2.verify(DATA_ID, d)[0] for d in sent] == ["replayed"] * 20  # old frames stay old
    assert rx2.verify(DATA_ID, tx.protect(DATA_ID, b"new"))[0] == "ok"
    bare = Receiver(KEY)  # no state: nothing accepted until a sync frame
    assert bare.verify(DATA_ID, tx.protect(DATA_ID, b"new"))[0] == "unsynced"
    assert bare.accept_sync(0x7F0, tx.sync_frame(0x7F0)) == "ok"
    assert bare.verify(DATA_ID, tx.protect(DATA_ID, b"new"))[0] == "ok"


def test_forged_and_replayed_sync_frames_rejected():
    tx, rx = synced_pair()
    old_sync = tx.sync_frame(0x7F0)
    assert rx.accept_sync(0x7F0, old_sync) == "ok"
    assert rx.accept_sync(0x7F0, old_sync) == "replayed"
    forged = (10**12).to_bytes(8, "big") + old_sync[8:]  # a far-ahead FV with someone else's MAC
    assert rx.accept_sync(0x7F0, forged) == "bad_mac"
    assert rx.accept_sync(0x7F0, b"short") == "length"
    assert rx.verify(DATA_ID, b"abc")[0] == "length"


def test_key_file_format_and_permissions(tmp_path):
    path = tmp_path / "keys.toml"
    keys = write_dev_keys(path, ["DLS", "CHS", "VEHEST"])
    assert stat.S_IMODE(path.stat().st_mode) == 0o600
    assert load_keys(path) == keys
    with pytest.raises(ConfigError, match="exists; not overwritten"):
        write_dev_keys(path, ["DLS"])
    for k in keys.values():  # a key never shows in its repr (logs, tracebacks)
        assert k.raw.hex() not in repr(k) and k.fingerprint in repr(k)
    os.chmod(path, 0o644)
    with pytest.raises(ConfigError, match="too open"):
        load_keys(path)
    bad = tmp_path / "bad.toml"
    for text, message in [('[keys]\nDLS = "00"\n', "keys.DLS: must be 32 hexadecimal digits"),
                          ("[keys]\n", "keys: no keys"), ('[other]\nx = 1\n', "unknown key"),
                          ("[keys\n", "TOML syntax")]:
        bad.write_text(text)
        os.chmod(bad, 0o600)
        with pytest.raises(ConfigError, match=message):
            load_keys(bad)
    with pytest.raises(ConfigError, match="cannot read key file"):
        load_keys(tmp_path / "missing.toml")


def test_bad_freshness_state_file_is_a_clear_error(tmp_path):
    p = tmp_path / "s.json"
    for text in ["{", '{"reserved": "x"}', '{"latest": {}}', '{"reserved": -4}']:
        p.write_text(text)
        p.chmod(0o600)  # (a readable-by-others one is refused before it is read: test_secoc_state.py)
        with pytest.raises(ConfigError, match="not a SecOC freshness state file|must be positive"):
            FreshnessStore(p)
