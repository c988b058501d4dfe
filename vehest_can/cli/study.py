"""``vehest-can study TOPIC [ARGS...]``: the design and validation studies behind the docs' tables,
each a system's (``SYSTEM.NAME``, from its registration's ``studies``) or the house's (campaign
throughput, the firmware's cost per tick). ``vehest-can study`` lists them; ``vehest-can study TOPIC
--help`` shows a study's own flags."""
from __future__ import annotations

import argparse
import importlib

from ..errors import ConfigError

#: the verb's one line in `vehest-can --help` (read without building its parser)
HELP = "the studies behind the docs' tables (list them: vehest-can study)"

#: studies of no one system: (topic, module:function, help)
HOUSE = (
    ("campaign.throughput", "vehest_can.campaign.bench:main",
     "a campaign on 1 and N local workers and on Dask, runs per minute side by side (docs/campaigns.md)"),
    ("firmware.cost", "vehest_can.tools.pil_bench:main",
     "instructions and cycles per tick per system on the emulated Cortex-M4F or Cortex-M7 (docs/firmware.md)"),
)


def add_subparser(subparsers) -> None:
    p = subparsers.add_parser("study", help=HELP, description=__doc__.split("\n\n")[0].replace("``", ""))
    p.add_argument("topic", nargs="?", metavar="TOPIC", help="the study (none: list them)")
    p.add_argument("args", nargs=argparse.REMAINDER, metavar="ARGS", help="the study's own arguments")
    p.set_defaults(func=run)


def topics() -> dict[str, tuple[str, str]]:
    """Every study: topic -> (module:function, help)."""
    from ..systems import registered

    found = {f"{s.name}.{st.name}": (st.main, st.help) for s in registered() for st in getattr(s, "studies", ())}
    found.update((t, (m, h)) for t, m, h in HOUSE)
    return found


def run(args) -> int:
    known = topics()
    if args.topic is None:
        for topic, (_, text) in sorted(known.items()):
            print(f"{topic:<22} {text}")
        return 0
    if args.topic not in known:
        raise ConfigError(f"no study {args.topic!r}; the studies: {', '.join(sorted(known))}")
    module, _, function = known[args.topic][0].partition(":")
    main = getattr(importlib.import_module(module), function)
    return int(main(args.args, f"vehest-can study {args.topic}") or 0)
