"""How a build links OpenSSL's libcrypto, the host's AES backend (vh_aes128_host.c): by its file
name, so no development headers are needed. Shared by the ECU extension and vehest_can._secoc."""
from __future__ import annotations

import ctypes.util


def libcrypto() -> str:
    """The linker argument for OpenSSL's libcrypto (``-l:libcrypto.so.3``), or a clear error."""
    name = ctypes.util.find_library("crypto")
    if not name:
        raise SystemExit("vehest-can needs OpenSSL's libcrypto (the library Python's ssl module uses) "
                         "for SecOC's AES; none was found by ctypes.util.find_library('crypto')")
    return f"-l:{name}"
