"""``--target``: where the ECU firmware runs — this process (the host build, through cffi) or QEMU's
emulated Cortex-M4F (processor in the loop, vehest_can.service.pil), or the Cortex-M7 beside it.
Nothing heavy at import."""
from __future__ import annotations

from ..errors import ConfigError

#: --target -> the emulated core (None: the host build)
TARGETS = {"host": None, "qemu": "cortex-m4f", "qemu-m7": "cortex-m7"}


def add_target_argument(p) -> None:
    p.add_argument("--target", choices=tuple(TARGETS), default="host",
                   help="where the ECU firmware runs: host (this process, default) or qemu (the image cross-compiled "
                        "for a Cortex-M4F in qemu-system-arm's mps2-an386, in lockstep over its UART: processor in "
                        "the loop; the same frames bit for bit, not real time; docs/firmware.md); qemu-m7: the same "
                        "on a Cortex-M7 (mps2-an500)")


def on_qemu(args) -> bool:
    """The ECU runs in the emulator (either core)."""
    return TARGETS[getattr(args, "target", "host")] is not None


def refuse_on_qemu(args, **flags) -> None:
    """A ConfigError naming the first given flag the emulated ECU does not take (flag name -> why)."""
    if not on_qemu(args):
        return
    for flag, why in flags.items():
        if getattr(args, flag.lstrip("-").replace("-", "_"), None) not in (None, False, "off"):
            raise ConfigError(f"{flag} with --target {args.target}: {why}")


def make_ecu(args, config):
    """The ECU for ``config`` on the chosen target (a PilEcu: close it when done)."""
    if on_qemu(args):
        from ..service.pil import PilEcu, missing_tools

        why = missing_tools()
        if why:
            raise ConfigError(f"--target {args.target}: processor-in-the-loop unavailable here: {why}")
        return PilEcu(config, core=TARGETS[args.target])
    from ..systems.ecu import Ecu

    return Ecu(config)
