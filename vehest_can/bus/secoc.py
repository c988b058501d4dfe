"""SecOC-style authenticated frames on the host: key files, persisted freshness, and the C
protector/verifier (``c_core/secoc/``, in ``vehest_can._native``) over python-can messages.

A secured frame is its authentic part followed by a 4-byte tail: the freshness value's 8 least
significant bits and the 24 most significant bits of CMAC-AES-128(key, data ID | authentic part |
full 64-bit FV) — AUTOSAR SecOC's profile-1 layout. docs/secoc.md has the whole design.

Key file (TOML, outside the repository, readable by its owner only; ``vehest-can secoc keygen``
writes one)::

    [keys]            # one AES-128 key per sending node of the DBCs, 32 hex digits
    DLS = "9f0c…"
    VEHEST = "…"

Keys are never logged or printed: :class:`Key` shows only its node name and a fingerprint.
"""
from __future__ import annotations

import hashlib
import json
import os
import re
import secrets
import stat
from dataclasses import dataclass, field
from pathlib import Path

from ..errors import ConfigError
from ..schema import Checker, read_toml

TAIL_BYTES = 4
SYNC_AUTHENTIC = 8
# A sender persists its next FV this far ahead, so a restart resumes above every FV it sent
# (one state-file write per block, not per frame: 65536 frames is 33 s of a 2 kHz frame).
RESERVE_BLOCK = 1 << 16
_HEX_KEY = re.compile(r"[0-9a-fA-F]{32}")

RESULTS = {0: "ok", 1: "bad_mac", 2: "replayed", 3: "unsynced", 4: "length", 5: "exhausted"}


def _lib():
    from ..native import ffi, lib  # on first use: key files need no C

    return ffi, lib


@dataclass(frozen=True)
class Key:
    node: str
    raw: bytes = field(repr=False)

    @property
    def fingerprint(self) -> str:
        """What logs and status may show: 8 hex digits of SHA-256 of the key, not the key."""
        return hashlib.sha256(b"vehest-can secoc key\0" + self.raw).hexdigest()[:8]

    def __repr__(self) -> str:
        return f"Key({self.node}, fp={self.fingerprint})"


def check_private(path: Path) -> None:
    """Refuses a key file that others may read or write (as ssh does with a private key)."""
    try:
        st = path.stat()
    except OSError as e:
        raise ConfigError(f"{path}: cannot read key file: {e.strerror}") from None
    if not stat.S_ISREG(st.st_mode):
        raise ConfigError(f"{path}: key file is not a regular file")
    if st.st_mode & 0o077:
        raise ConfigError(f"{path}: key file permissions {stat.S_IMODE(st.st_mode):04o} are too open "
                          f"(others can read it); chmod 600 {path}")


def write_private(path: Path | str, text: str) -> None:
    """A new key file with `text`, mode 600, never over an existing file."""
    path = Path(path)
    try:
        fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600)
    except FileExistsError:
        raise ConfigError(f"{path}: exists; not overwritten (remove it to make new keys)") from None
    except OSError as e:
        raise ConfigError(f"{path}: cannot create: {e.strerror}") from None
    with os.fdopen(fd, "w") as f:
        f.write(text)


def load_keys(path: Path | str) -> dict[str, Key]:
    """The key file's keys by node name; every problem a clear ConfigError naming the key, never its value."""
    path = Path(path)
    check_private(path)
    doc = read_toml(path, ConfigError)
    ck = Checker(path, ConfigError)
    ck.table(doc, "", {"keys"})
    keys = doc.get("keys", {})
    if not isinstance(keys, dict):
        ck.fail("keys", "must be a table ([keys])")
    if not keys:
        ck.fail("keys", "no keys")
    out = {}
    for node, value in keys.items():
        if not isinstance(value, str) or not _HEX_KEY.fullmatch(value):
            ck.fail(f"keys.{node}", "must be 32 hexadecimal digits (an AES-128 key)")
        out[node] = Key(node, bytes.fromhex(value))
    return out


def write_dev_keys(path: Path | str, nodes: list[str]) -> dict[str, Key]:
    """A new key file of random keys (mode 600, never overwrites): the development keys of a bench."""
    keys = {n: Key(n, secrets.token_bytes(16)) for n in nodes}
    write_private(path, "# vehest-can SecOC development keys: one AES-128 key per sending node.\n"
                        "# Keep this file out of the repository, readable by its owner only.\n[keys]\n"
                  + "".join(f'{k.node} = "{k.raw.hex()}"\n' for k in keys.values()))
    return keys


def state_dir() -> Path:
    """Where SecOC state files go by default: $XDG_STATE_HOME/vehest-can, else ~/.local/state/vehest-can."""
    base = os.environ.get("XDG_STATE_HOME") or ""
    root = Path(base) if base and Path(base).is_absolute() else Path.home() / ".local" / "state"
    return root / "vehest-can"


def keyset_id(keys: dict[str, Key]) -> str:
    """12 hex digits naming a key set (a SHA-256 of its keys, never the keys): new keys, new state."""
    h = hashlib.sha256(b"vehest-can secoc keyset\0")
    for node in sorted(keys):
        h.update(node.encode() + b"\0" + keys[node].raw)
    return h.hexdigest()[:12]


def default_state_path(keys: dict[str, Key], nodes) -> Path:
    """The default state file of a process playing `nodes` with this key set: one per key set and role."""
    return state_dir() / f"secoc-{'+'.join(sorted(nodes))}-{keyset_id(keys)}.json"


@dataclass
class NodeState:
    """One node's persisted freshness: its sender's reservation bound (it resumes there), the latest
    FV it accepted from each sender, and whether its process ended cleanly (else its receivers resume
    a crash margin above the stored latest: frames accepted after the last write are unknown)."""
    reserved: int = 1  # senders start at FV 1 (a receiver without state has latest 0)
    latest: dict[str, int] = field(default_factory=dict)
    clean: bool = True


_FORMAT = "vehest-can secoc freshness"


def _state_error(path: Path, why: str) -> ConfigError:
    return ConfigError(f"{path}: {why}")


class FreshnessStore:
    """The persisted freshness state of one process: a :class:`NodeState` per node it plays (JSON,
    mode 600 in a folder only its owner may write, written whole: temp file, fsync, rename).
    A file that is not one, unreadable, too open or someone else's is a clear ConfigError."""

    def __init__(self, path: Path | str):
        self.path = Path(path)
        self.nodes: dict[str, NodeState] = {}
        self._legacy: NodeState | None = None
        try:
            st = self.path.lstat()
        except FileNotFoundError:
            return
        except OSError as e:
            raise _state_error(self.path, f"cannot read the SecOC freshness state file: {e.strerror}") from None
        self._check(st)
        try:
            doc = json.loads(self.path.read_text())
        except OSError as e:
            raise _state_error(self.path, f"cannot read the SecOC freshness state file: {e.strerror}") from None
        except (ValueError, UnicodeDecodeError) as e:
            raise _state_error(self.path, f"not a SecOC freshness state file (corrupt: {e})") from None
        self._parse(doc)

    def _check(self, st: os.stat_result) -> None:
        if not stat.S_ISREG(st.st_mode):
            raise _state_error(self.path, "SecOC freshness state file is not a regular file")
        if st.st_uid != os.getuid():
            raise _state_error(self.path, f"SecOC freshness state file belongs to uid {st.st_uid}, not to you")
        if st.st_mode & 0o077:
            raise _state_error(self.path, f"SecOC freshness state file permissions {stat.S_IMODE(st.st_mode):04o} "
                                          f"are too open (others could rewind it); chmod 600 {self.path}")

    def _parse(self, doc) -> None:
        def node_state(d, clean_default: bool) -> NodeState:
            ns = NodeState(int(d["reserved"]), {str(k): int(v) for k, v in d.get("latest", {}).items()},
                           bool(d.get("clean", clean_default)))
            if ns.reserved < 1 or any(v < 0 for v in ns.latest.values()) or ns.reserved >= 2**64 \
                    or any(v >= 2**64 for v in ns.latest.values()):
                raise ValueError("freshness values must be positive 64-bit integers")
            return ns

        try:
            if not isinstance(doc, dict):
                raise TypeError("not a JSON object")
            if "nodes" in doc:
                if doc.get("format") != _FORMAT:
                    raise ValueError(f"format is {doc.get('format')!r}, not {_FORMAT!r}")
                self.nodes = {str(n): node_state(d, True) for n, d in doc["nodes"].items()}
            else:  # the single-node layout of earlier versions; whether it ended cleanly is unknown
                self._legacy = node_state(doc, False)
        except (ValueError, KeyError, TypeError, AttributeError) as e:
            raise _state_error(self.path, f"not a SecOC freshness state file ({e})") from None

    def node(self, name: str) -> NodeState:
        """The state of node `name` (a new one if the file has none; an earlier version's single-node
        file is the first node asked for)."""
        if name not in self.nodes:
            legacy, self._legacy = self._legacy, None
            self.nodes[name] = legacy or NodeState()
        return self.nodes[name]

    def save(self) -> None:
        """Atomically: a temp file (mode 600) in the same folder, fsync, rename, fsync of the folder."""
        folder = self.path.parent
        try:
            folder.mkdir(mode=0o700, parents=True, exist_ok=True)
            st = folder.stat()
            if st.st_mode & 0o022:
                raise _state_error(folder, f"folder of the SecOC freshness state is writable by others "
                                           f"({stat.S_IMODE(st.st_mode):04o}); chmod 700 {folder}")
            tmp = folder / f".{self.path.name}.tmp"
            tmp.unlink(missing_ok=True)
            fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL | getattr(os, "O_NOFOLLOW", 0), 0o600)
            with os.fdopen(fd, "w") as f:
                json.dump({"format": _FORMAT, "version": 1,
                           "nodes": {n: {"reserved": ns.reserved, "latest": ns.latest, "clean": ns.clean}
                                     for n, ns in sorted(self.nodes.items())}}, f, indent=1)
                f.write("\n")
                f.flush()
                os.fsync(f.fileno())
            os.replace(tmp, self.path)
            dfd = os.open(folder, os.O_RDONLY)
            try:
                os.fsync(dfd)
            finally:
                os.close(dfd)
        except OSError as e:
            raise _state_error(self.path, f"cannot write the SecOC freshness state file: {e.strerror}") from None


def cmac(key: bytes, msg: bytes) -> bytes:
    """The full AES-CMAC of msg (RFC 4493) through the C, for checks and tools."""
    ffi, lib = _lib()
    k = ffi.new("vh_cmac_key_t *")
    if lib.vh_cmac_init(k, key) != 0:
        raise ConfigError("SecOC: the AES backend refused the key")
    tag = ffi.new("uint8_t[16]")
    lib.vh_cmac(k, msg, len(msg), tag)
    lib.vh_cmac_wipe(k)
    return bytes(tag)


# ---- SecOC on the bus: a node's vh_secoc_bus_t (c_core/secoc/vh_secoc_bus.h) in the ECU or a plant node ----

#: the widest reservation bound: a node without a state file persists nothing (every start is FV 1)
_NO_BOUND = 2**64 - 1
#: what a node's hook counts (vh_secoc_bus_counters_t); "rejected" is the sum of the five reasons
BUS_COUNTERS = ("accepted", "bad_mac", "replayed", "unsynced", "malformed", "no_key", "rejected",
                "syncs", "secured", "tx_dropped", "sync_sent")
#: a node's state is written once a second (maintain); after a crash its receivers treat what each
#: sender can send in this long as already used (frames accepted after the last write are unknown)
CRASH_MARGIN_S = 3.0


def secured_messages() -> dict[int, tuple[str, int, int, bool]]:
    """The DBCs' secured messages: frame ID -> (sender, SecOC data ID, authentic bytes, is a sync frame)."""
    from .frames import BUSES, database

    out = {}
    for bus in BUSES:
        for m in database(bus).messages:
            attrs = m.dbc.attributes if m.dbc else {}
            if "SecOCDataID" in attrs and attrs["SecOCDataID"].value:
                sync = bool("SecOCSync" in attrs and attrs["SecOCSync"].value)
                out[m.frame_id] = (m.senders[0], int(attrs["SecOCDataID"].value), m.length - TAIL_BYTES, sync)
    return out


def crash_margin(sender: str) -> int:
    """FVs `sender` may use in CRASH_MARGIN_S: its secured frames' rates from the DBCs' cycle times."""
    from .frames import BUSES, database

    rate = 0.0
    secured = secured_messages()
    for bus in BUSES:
        for m in database(bus).messages:
            if m.frame_id in secured and secured[m.frame_id][0] == sender:
                attrs = m.dbc.attributes if m.dbc else {}
                us = float(attrs["CycleTimeUs"].value if "CycleTimeUs" in attrs else (m.cycle_time or 0) * 1000)
                rate += 1e6 / us if us else 2000.0  # an event frame: at most one per tick
    return int(rate * CRASH_MARGIN_S) + 1


class BusSecoc:
    """One node's SecOC hook in the C (``vh_secoc_bus_t``, handed to the ECU or a plant node), keyed
    from a key file and started; the host's part is the freshness store (None: ephemeral, every
    start at FV 1 — for sessions that must be a pure function of their inputs, and keys made for
    one run): :meth:`maintain` moves the reservation bound ahead (stored first) and remembers the
    receivers' latest FVs; :meth:`close` stores the exact state of a clean end. Keys are set in the
    C and never kept here beyond the :class:`Key` objects."""

    def __init__(self, node: str, keys: dict[str, Key], *, store: FreshnessStore | None = None):
        from ..native import ffi, lib

        self.ffi, self.lib = ffi, lib
        self.node = node
        self.store = store
        self.c = ffi.new("vh_secoc_bus_t *")  # handed to the node's C (vh_ecu_set_secoc, vh_rln_set_secoc)
        self._idx = {}
        self_idx = lib.vh_secoc_bus_node(node.encode())
        if self_idx < 0:
            raise ConfigError(f"SecOC: {node} sends nothing in the DBCs")
        lib.vh_secoc_bus_init(self.c, self_idx)
        for name, key in keys.items():
            i = lib.vh_secoc_bus_node(name.encode())
            if i < 0:
                continue  # a key of a node these DBCs do not have: unused
            if lib.vh_secoc_bus_set_key(self.c, i, key.raw) != lib.VH_OK:
                raise ConfigError(f"SecOC: the AES backend refused the key of {name}")
            self._idx[name] = i
        if node not in keys:
            raise ConfigError(f"SecOC: the key file has no key for {node}, the node that sends here")
        self.restart()

    def restart(self) -> None:
        """As a restarted process: from the state (above every FV sent, receivers where they were),
        or without one from FV 1 with every receiver unsynchronised until its sender's sync frame.
        A new session of the simulation (the lockstep RESET, a new car) is such a restart; a running
        node's state is taken into the store first, so a restart never goes back."""
        lib, store = self.lib, self.store
        if store is None:
            for i in self._idx.values():
                lib.vh_secoc_bus_restore_rx(self.c, i, 0)
            start, bound = 1, _NO_BOUND
        else:
            ns = store.node(self.node)
            if self.c.on:
                self._capture(ns)
            crashed = not ns.clean and not self.c.on  # the process before this one did not end cleanly
            for name, i in self._idx.items():
                latest = ns.latest.get(name, 0)
                if crashed and name != self.node:
                    latest = min(latest + crash_margin(name), 2**63)  # a fresh sync frame is still above
                lib.vh_secoc_bus_restore_rx(self.c, i, latest)
            start = bound = ns.reserved
        if lib.vh_secoc_bus_start(self.c, start, bound) != lib.VH_OK:
            raise ConfigError(f"SecOC: cannot start {self.node}")
        self.maintain()

    def _capture(self, ns: NodeState) -> None:
        ns.latest = {n: int(self.c.rx[i].latest) for n, i in self._idx.items() if self.c.rx[i].latest}

    def maintain(self) -> None:
        """Keep the reservation a block ahead (stored before use) and store the receivers' state;
        call it at least every RESERVE_BLOCK // 2 frames sent (e.g. once a second)."""
        if self.store is None:
            return
        ns = self.store.node(self.node)
        tx = self.c.tx
        if tx.reserved_until - tx.fv <= RESERVE_BLOCK // 2:
            ns.reserved = int(tx.fv) + RESERVE_BLOCK
        self._capture(ns)
        ns.clean = False  # until close(): a crash from here on leaves a state older than the C's
        self.store.save()
        self.lib.vh_secoc_tx_reserve(self.ffi.addressof(self.c, "tx"), ns.reserved)

    def close(self) -> None:
        """A clean end: the exact state stored (the next start resumes at the next FV, its receivers
        exactly where these are). Sending after this is refused until restart()."""
        if self.store is None or not self.c.on:
            return
        ns = self.store.node(self.node)
        self._capture(ns)
        ns.reserved = int(self.c.tx.fv)
        self.c.tx.reserved_until = self.c.tx.fv  # nothing more may be sent under the stored state
        ns.clean = True
        self.store.save()

    def counters(self) -> dict[str, int]:
        return {k: int(getattr(self.c.cnt, k)) for k in BUS_COUNTERS}

    def wipe(self) -> None:
        self.lib.vh_secoc_bus_wipe(self.c)
