"""pyxcp, the independent master, against the C slave alone (``xcp_demo``) on python-can's virtual bus."""
from __future__ import annotations

import itertools
import logging
import struct

import can
import pytest
from xcp_demo import DEMO, Slave  # noqa: E402 - tests/xcp is on sys.path (rootdir-relative test imports)
from xcp_demo_bridge import XcpBridge  # noqa: E402

from vehest_can.xcp import load
from vehest_can.xcp.keys import seed_n_key

_channels = itertools.count()
#: RFC 4493's published AES-128 test key: the tests' seed & key key (a test vector, not a secret)
KEY = bytes.fromhex("2b7e151628aed2a6abf7158809cf4f3c")


def make_master(channel: str, desc, *, key: bytes | None = KEY, timeout: float = 1.0, bus=None):
    """A pyxcp master (skips the test when pyxcp is not installed: the C-only tests still run)."""
    pytest.importorskip("pyxcp")
    from pyxcp.config import General, PyXCP, Transport
    from pyxcp.master import Master
    from traitlets.config import Config  # pyxcp's configuration system

    c = Config()
    c.Transport.layer = "CAN"
    c.Transport.timeout = timeout
    c.Transport.Can.interface = "virtual" if bus is None else "custom"
    c.Transport.Can.channel = channel
    c.Transport.Can.can_id_master = desc.cro_id
    c.Transport.Can.can_id_slave = desc.dto_id
    c.Transport.Can.fd = desc.fd
    c.General.connect_retries = 0
    c.General.disable_error_handling = True  # an ERR response raises at once instead of retrying
    app = PyXCP(config=c)
    app.log_level = logging.WARNING
    app._setup_logger()
    app.general = General(config=c, parent=app)
    app.transport = Transport(config=c, parent=app)
    if key is not None:
        app.general.seed_n_key_function = seed_n_key(key)  # the key file's key, computed by `cryptography`
    logging.getLogger("pyxcp").setLevel(logging.WARNING)
    return Master("can", config=app, transport_layer_interface=bus)


class Rig:
    """A slave on its bridge and a pyxcp master, on one fresh virtual channel."""

    def __init__(self, desc=None, **slave_kw):
        self.desc = desc or load(DEMO)
        self.channel = f"xcp-test-{next(_channels)}"
        self.slave = Slave(self.desc, key=KEY, **slave_kw)
        self.bus = can.Bus(interface="virtual", channel=self.channel, receive_own_messages=False)
        self.bridge = XcpBridge(self.bus, self.slave).start()
        self.master = make_master(self.channel, self.desc)
        self.master.__enter__()

    def connect(self):
        """CONNECT, then GET_COMM_MODE_INFO (pyxcp's block transfers need MAX_BS/MIN_ST)."""
        r = self.master.connect()
        self.master.getCommModeInfo()
        return r

    def close(self):
        try:
            self.master.close()
        finally:
            self.bridge.stop()
            self.bus.shutdown()

    def download(self, name: str, values, fmt: str | None = None):
        item = self.desc.item(name)
        from vehest_can.xcp.description import C_TYPES
        fmt = fmt or "<" + C_TYPES[item.ctype][4] * len(values)
        blob = struct.pack(fmt, *values)
        # one DOWNLOAD per MAX_CTO - 2 bytes, each waiting for its RES: pyxcp's push() sends all
        # but the last chunk without waiting (block_request), which races the tick in a test
        self.master.setMta(item.address)
        step = self.desc.max_cto - 2
        for i in range(0, len(blob), step):
            self.master.download(blob[i:i + step])


@pytest.fixture
def rig():
    r = Rig()
    yield r
    r.close()


@pytest.fixture
def make_rig():
    rigs = []

    def make(desc=None, **kw):
        rigs.append(Rig(desc, **kw))
        return rigs[-1]
    yield make
    for r in rigs:
        r.close()


@pytest.fixture
def pyxcp_master():
    """make_master(channel, desc) as a fixture (test modules cannot import this conftest by name:
    tests/conftest.py is a "conftest" too)."""
    return make_master
