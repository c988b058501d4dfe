"""A node's SecOC sender and receiver in Python over the firmware's C (``vh_secoc_tx_t``,
``vh_secoc_rx_t``): the tests' peers for checking frames one by one. Not shipped: the ECU and the
simulated nodes secure and verify through ``BusSecoc``."""
from __future__ import annotations

from vehest_can.bus.secoc import RESERVE_BLOCK, RESULTS, SYNC_AUTHENTIC, TAIL_BYTES, FreshnessStore, Key, _lib
from vehest_can.errors import ConfigError


class Sender:
    """Secures one node's frames: one FV counter for all of them, persisted a block ahead."""

    def __init__(self, key: Key, store: FreshnessStore | None = None):
        self.ffi, self.lib = _lib()
        self.key = key
        self._cmac = self.ffi.new("vh_cmac_key_t *")
        if self.lib.vh_cmac_init(self._cmac, key.raw) != 0:
            raise ConfigError(f"SecOC: the AES backend refused the key of {key.node}")
        self.store = store
        self.tx = self.ffi.new("vh_secoc_tx_t *")
        start = store.node(key.node).reserved if store else 1
        self.lib.vh_secoc_tx_init(self.tx, start, start)
        self._reserve()

    def _reserve(self) -> None:
        until = self.tx.fv + RESERVE_BLOCK
        if self.store is not None:
            self.store.node(self.key.node).reserved = until
            self.store.save()  # stored before any FV below it is used
        self.lib.vh_secoc_tx_reserve(self.tx, until)

    def protect(self, data_id: int, authentic: bytes) -> bytes:
        """The secured frame's data: authentic part + tail."""
        if len(authentic) > self.lib.VH_SECOC_MAX_AUTHENTIC:
            raise ConfigError(f"SecOC: {len(authentic)} authentic bytes do not fit a CAN FD frame with the tail")
        if self.tx.reserved_until - self.tx.fv <= RESERVE_BLOCK // 2:
            self._reserve()
        buf = self.ffi.new("uint8_t[]", len(authentic) + TAIL_BYTES)
        self.ffi.memmove(buf, authentic, len(authentic))
        r = self.lib.vh_secoc_protect(self.tx, self._cmac, data_id & 0xFFFF, buf, len(authentic))
        if r != 0:
            raise ConfigError(f"SecOC: cannot protect: {RESULTS.get(r, r)}")
        return bytes(self.ffi.buffer(buf))

    def sync_frame(self, data_id: int) -> bytes:
        if self.tx.reserved_until - self.tx.fv <= RESERVE_BLOCK // 2:
            self._reserve()
        buf = self.ffi.new("uint8_t[]", SYNC_AUTHENTIC + TAIL_BYTES)
        r = self.lib.vh_secoc_sync_build(self.tx, self._cmac, data_id & 0xFFFF, buf)
        if r != 0:
            raise ConfigError(f"SecOC: cannot build a sync frame: {RESULTS.get(r, r)}")
        return bytes(self.ffi.buffer(buf))

    @property
    def fv(self) -> int:
        return int(self.tx.fv)


class Receiver:
    """Checks one sender's secured frames; counts every verdict. Nothing of a frame that is not ok
    may be used."""

    def __init__(self, key: Key, store: FreshnessStore | None = None, owner: str = "host"):
        self.ffi, self.lib = _lib()
        self.key = key
        self.store = store
        self.owner = owner  # the receiving node: its section of the store
        self._cmac = self.ffi.new("vh_cmac_key_t *")
        if self.lib.vh_cmac_init(self._cmac, key.raw) != 0:
            raise ConfigError(f"SecOC: the AES backend refused the key of {key.node}")
        self.rx = self.ffi.new("vh_secoc_rx_t *")
        latest = store.node(owner).latest.get(key.node) if store else None
        self.lib.vh_secoc_rx_init(self.rx, latest or 0, latest is not None)

    def verify(self, data_id: int, data: bytes) -> tuple[str, bytes | None]:
        """("ok", authentic part) or (the reason, None)."""
        n = len(data) - TAIL_BYTES
        if n < 0 or n > self.lib.VH_SECOC_MAX_AUTHENTIC:
            self.rx.bad_mac = min(self.rx.bad_mac + 1, 2**32 - 1)
            return "length", None
        r = self.lib.vh_secoc_verify(self.rx, self._cmac, data_id & 0xFFFF, data, n, self.ffi.NULL)
        return RESULTS[r], (bytes(data[:n]) if r == 0 else None)

    def accept_sync(self, data_id: int, data: bytes) -> str:
        if len(data) != SYNC_AUTHENTIC + TAIL_BYTES:
            self.rx.bad_mac = min(self.rx.bad_mac + 1, 2**32 - 1)
            return "length"
        return RESULTS[self.lib.vh_secoc_sync_accept(self.rx, self._cmac, data_id & 0xFFFF, data)]

    def remember(self) -> None:
        """Stores the latest accepted FV (a restart then resumes synchronised)."""
        if self.store is not None:
            self.store.node(self.owner).latest[self.key.node] = int(self.rx.latest)
            self.store.save()

    @property
    def counts(self) -> dict[str, int]:
        r = self.rx
        return {"accepted": r.accepted, "bad_mac": r.bad_mac, "replayed": r.replayed,
                "unsynced": r.unsynced, "resyncs": r.resyncs}

    @property
    def synced(self) -> bool:
        return bool(self.rx.synced)
