"""XCP seed & key: the user's key file and the key a master answers a seed with.

The slave (``vh_xcp.h``) keys with CMAC-AES-128: its seed is the first 6 bytes of CMAC(K, "XCPS" |
salt | count | tick), the key it wants the first 6 bytes of CMAC(K, "XCPK" | resource | seed).
K is the user's: ``vehest-can xcp keygen FILE`` writes a random one (mode 600)::

    # vehest-can XCP seed & key ...
    [xcp]
    key = "9f0c…"      # 32 hex digits, AES-128

A file that others may read is refused (as ssh refuses a private key). ``key_for`` is the
master's side, computed with ``cryptography`` (not the C): an independent implementation of the
same function. The development key (``--xcp-dev``) is public and fixed: for a bench, never a car.
"""
from __future__ import annotations

import re
import secrets
from pathlib import Path

from ..bus.secoc import check_private, write_private
from ..errors import ConfigError
from ..schema import Checker, read_toml

KEY_LEN = SEED_LEN = 6  # VH_XCP_KEY_LEN, VH_XCP_SEED_LEN
#: the development mode's key: fixed and published here, so anyone has it (bench only, never a car)
DEV_KEY = b"vehest-can XCPdv"
_HEX_KEY = re.compile(r"[0-9a-fA-F]{32}")


def load_key(path: Path | str) -> bytes:
    """The key file's AES-128 key; every problem a clear ConfigError (never the key's value)."""
    path = Path(path)
    check_private(path)
    doc = read_toml(path, ConfigError)
    ck = Checker(path, ConfigError)
    ck.table(doc, "", {"xcp"})
    xcp = doc.get("xcp")
    if not isinstance(xcp, dict):
        ck.fail("xcp", "missing: the file needs an [xcp] table with key = \"<32 hex digits>\" "
                       "(`vehest-can xcp keygen FILE` writes one)")
    ck.table(xcp, "xcp", {"key"})
    value = xcp.get("key")
    if not isinstance(value, str) or not _HEX_KEY.fullmatch(value):
        ck.fail("xcp.key", "must be 32 hexadecimal digits (an AES-128 key)")
    return bytes.fromhex(value)


def write_key(path: Path | str) -> bytes:
    """A new key file with a random key (mode 600, never overwrites an existing file)."""
    key = secrets.token_bytes(16)
    write_private(path, "# vehest-can XCP seed & key: the AES-128 key of the ECU's XCP slave (CMAC).\n"
                        "# The daemon (--xcp-key) and every master that unlocks it need this file.\n"
                        "# Keep it out of the repository, readable by its owner only.\n"
                        f'[xcp]\nkey = "{key.hex()}"\n')
    return key


def key_for(seed: bytes, resource: int, key: bytes) -> bytes:
    """The key the slave wants for `seed` of `resource` (1 CAL/PAG, 4 DAQ): CMAC-AES-128 by
    ``cryptography``, independent of the C."""
    from cryptography.hazmat.primitives.ciphers import algorithms
    from cryptography.hazmat.primitives.cmac import CMAC

    if len(seed) != SEED_LEN:
        raise ConfigError(f"an XCP seed is {SEED_LEN} bytes, not {len(seed)}")
    c = CMAC(algorithms.AES(key))
    c.update(b"XCPK" + bytes([resource]) + bytes(seed))
    return c.finalize()[:KEY_LEN]


def seed_n_key(key: bytes):
    """pyxcp's ``seed_n_key_function`` (resource, seed) -> key for this key."""
    return lambda resource, seed: key_for(bytes(seed), int(resource), key)
