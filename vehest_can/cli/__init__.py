"""The one console script: ``vehest-can VERB ...``, one module per verb in this package (cantools
style): each exposes ``HELP`` (its line in ``vehest-can --help``) and ``add_subparser(subparsers)``, is
discovered automatically, and its parser's ``func`` default runs the verb. ``python -m vehest_can.cli``
is the same script.

A command builds the parser of its own verb only, and a verb module imports at its top only what its
flags need: the heavy parts (numpy, the C core, plotting, MF4, Dask) load when the verb runs, so
``vehest-can --help`` and ``vehest-can VERB --help`` start at once."""
from __future__ import annotations

import argparse
import importlib
import importlib.abc
import logging
import os
import pkgutil
import sys

from .. import __version__
from ..errors import VehestError


class _NoAsammdf(importlib.abc.MetaPathFinder):
    """While python-can is first imported: no asammdf (python-can imports it, and pandas with it, at
    import time for its MF4 reader and writer alone: about a second of every command's start)."""

    def find_spec(self, name, path=None, target=None):
        if name == "asammdf" or name.startswith("asammdf."):
            raise ModuleNotFoundError(f"No module named {name!r}", name=name)
        return None


def _defer_mf4(argv: list[str]) -> None:
    """A command line that names no MF4 file or format has no use for asammdf: python-can is imported
    without it (its MF4 support off in this process only). One that does gets python-can as it is."""
    if "can" in sys.modules or any("mf4" in a.lower() for a in argv):
        return
    finder = _NoAsammdf()
    sys.meta_path.insert(0, finder)
    try:
        import can  # noqa: F401 - the one import that counts
    finally:
        sys.meta_path.remove(finder)


def verbs() -> list[str]:
    return sorted(m.name for m in pkgutil.iter_modules(__path__) if not m.name.startswith("_"))


def build_parser(verb: str | None = None) -> argparse.ArgumentParser:
    """Every verb's full parser (`verb` None), or `verb`'s alone with the others listed by their HELP."""
    parser = argparse.ArgumentParser(
        prog="vehest-can",
        description="Vehicle state estimator ECU on a CAN bus: simulate, run, replay, measure.",
    )
    parser.add_argument("--version", action="version", version=f"%(prog)s {__version__}")
    parser.add_argument("--debug", action="store_true", help="show tracebacks on errors")
    parser.add_argument("-v", "--verbose", action="count", default=0, help="more log output on stderr")
    sub = parser.add_subparsers(title="verbs", dest="verb", metavar="VERB")
    sub.required = True
    for name in verbs():
        module = importlib.import_module(f"{__name__}.{name}")
        if verb is None or name == verb:
            module.add_subparser(sub)
        else:
            sub.add_parser(name, help=module.HELP)
    return parser


def _verb_in(argv: list[str]) -> str:
    """The verb a command line names ("" when none: the top-level help, or an error)."""
    first = next((a for a in argv if not a.startswith("-")), "")  # the global flags take no value
    return first if first in verbs() else ""


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    _defer_mf4(argv)
    parser = build_parser(_verb_in(argv))
    args = parser.parse_args(argv)
    logging.basicConfig(
        level=logging.WARNING - 10 * min(args.verbose, 2),
        format="%(levelname)s %(name)s: %(message)s",
        stream=sys.stderr,
    )
    try:
        rc = int(args.func(args) or 0)
        sys.stdout.flush()  # a closed pipe shows here, not at exit
        return rc
    except KeyboardInterrupt:
        return 130
    except BrokenPipeError:  # `vehest-can busload ... | head`: the reader has what it wanted
        _quiet_stdout()
        return 141  # 128 + SIGPIPE, as a program that the signal ended
    except (VehestError, OSError) as exc:
        if args.debug:
            raise
        print(f"error: {exc}", file=sys.stderr)
        return 1



def _quiet_stdout() -> None:
    """Point stdout at /dev/null so that the interpreter's own flush at exit finds no broken pipe."""
    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
    except (OSError, ValueError):
        pass
