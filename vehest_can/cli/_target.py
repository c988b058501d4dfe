"""``--target``: where the ECU firmware runs — this process (the host build, through cffi) or QEMU's
emulated Cortex-M4F (processor in the loop, vehest_can.service.pil). Nothing heavy at import."""
from __future__ import annotations

from ..errors import ConfigError

TARGETS = ("host", "qemu")


def add_target_argument(p) -> None:
    p.add_argument("--target", choices=TARGETS, default="host",
                   help="where the ECU firmware runs: host (this process, default) or qemu (the image cross-compiled "
                        "for a Cortex-M4F in qemu-system-arm's mps2-an386, in lockstep over its UART: processor in "
                        "the loop; the same frames bit for bit, not real time; docs/firmware.md)")


def refuse_on_qemu(args, **flags) -> None:
    """A ConfigError naming the first given flag the emulated ECU does not take (flag name -> why)."""
    if getattr(args, "target", "host") != "qemu":
        return
    for flag, why in flags.items():
        if getattr(args, flag.lstrip("-").replace("-", "_"), None) not in (None, False, "off"):
            raise ConfigError(f"{flag} with --target qemu: {why}")


def make_ecu(args, config):
    """The ECU for ``config`` on the chosen target (a PilEcu: close it when done)."""
    if getattr(args, "target", "host") == "qemu":
        from ..service.pil import PilEcu, missing_tools

        why = missing_tools()
        if why:
            raise ConfigError(f"--target qemu: processor-in-the-loop unavailable here: {why}")
        return PilEcu(config)
    from ..systems.ecu import Ecu

    return Ecu(config)
