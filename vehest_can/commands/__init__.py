"""CLI subcommands: one module each, exposing ``add_subparser(subparsers)`` (cantools style).

Modules here are discovered automatically; the parser's ``func`` default runs the command.
"""
