"""``vehest-can examples``: where the shipped examples are (HIL bench configurations, the systemd
unit), and a copy of them to edit."""
from __future__ import annotations

import shutil
from pathlib import Path

from ..errors import ConfigError

#: the verb's one line in `vehest-can --help` (read without building its parser)
HELP = "list the shipped examples (HIL configurations, systemd unit) or copy them"


def add_subparser(subparsers) -> None:
    p = subparsers.add_parser("examples", help=HELP,
                              description="List the examples shipped with the package, or copy them to a folder "
                                          "to edit (existing files are kept unless --force).")
    p.add_argument("--copy", metavar="DIR", help="copy every example into DIR (hil/, systemd/)")
    p.add_argument("--force", action="store_true", help="with --copy: overwrite files that exist")
    p.set_defaults(func=run)


def run(args) -> int:
    from ..paths import examples_dir

    root = examples_dir()
    files = sorted(p for p in root.glob("*/*") if p.is_file())
    if not files:
        raise ConfigError(f"no examples found in {root}")
    if not args.copy:
        print(f"examples in {root}:")
        for f in files:
            print(f"  {f.relative_to(root)}")
        return 0
    dest = Path(args.copy)
    if dest.exists() and not dest.is_dir():
        raise ConfigError(f"{dest}: exists and is not a folder")
    for f in files:
        target = dest / f.relative_to(root)
        if target.exists() and not args.force:
            print(f"kept {target} (exists; --force overwrites)")
            continue
        target.parent.mkdir(parents=True, exist_ok=True)
        shutil.copy2(f, target)
        print(f"wrote {target}")
    return 0
