"""``vehest-can secoc keygen|check KEYFILE``: SecOC key files (docs/secoc.md)."""
from __future__ import annotations

from pathlib import Path

#: the verb's one line in `vehest-can --help` (read without building its parser)
HELP = "SecOC key files: make development keys, check a key file"


def add_subparser(subparsers) -> None:
    parser = subparsers.add_parser(
        "secoc", help=HELP,
        description="Key files for SecOC-style authenticated frames (CMAC-AES-128, one key per sending "
                    "node). 'keygen' writes random development keys for every sending node of the DBCs "
                    "(mode 600, never overwrites); 'check' validates a file and prints each key's "
                    "fingerprint (never the key).")
    parser.add_argument("action", choices=("keygen", "check"))
    parser.add_argument("keyfile", type=Path, metavar="KEYFILE", help="the key file (TOML, outside the repository)")
    parser.set_defaults(func=run)


def sending_nodes() -> list[str]:
    from ..bus.busload import load_dbc
    from ..paths import dbc_dir

    nodes: set[str] = set()
    for path in sorted(dbc_dir().glob("*.dbc")):
        for m in load_dbc(path).messages:
            nodes.update(m.senders)
    return sorted(nodes)


def run(args) -> int:
    from ..bus.secoc import load_keys, write_dev_keys

    keys = write_dev_keys(args.keyfile, sending_nodes()) if args.action == "keygen" else load_keys(args.keyfile)
    for k in keys.values():
        print(f"{k.node:<8} fingerprint {k.fingerprint}")
    print(f"{args.keyfile}: {len(keys)} keys" + (" written (mode 600)" if args.action == "keygen" else " ok"))
    return 0
