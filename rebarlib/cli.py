"""The ``rebar`` command: ``rebar synth``, ``rebar inspect``, ``rebar report``.

Each subcommand lives in its own module (``_cli_<name>.py``) exposing ``add_parser(subparsers)``
and ``run(args) -> int``, so the command grows with the library without one crowded file.
"""

from __future__ import annotations

import argparse
import importlib
import sys

from ._checks import RebarInputError

SUBCOMMANDS = ("synth", "inspect", "inspect-cloud", "report", "calibrate")


def build_parser() -> argparse.ArgumentParser:
    from . import __version__

    parser = argparse.ArgumentParser(prog="rebar", description="Rebar inspection from RGB-D captures.")
    parser.add_argument("--version", action="version", version=f"rebarlib {__version__}")
    sub = parser.add_subparsers(dest="command", required=True)
    for name in SUBCOMMANDS:
        try:
            mod = importlib.import_module(f"rebarlib._cli_{name.replace('-', '_')}")
        except ModuleNotFoundError as exc:
            if exc.name != f"rebarlib._cli_{name.replace('-', '_')}":
                raise
            continue
        p = mod.add_parser(sub)
        p.set_defaults(_run=mod.run)
    return parser


def main(argv=None) -> int:
    args = build_parser().parse_args(argv)
    try:
        return int(args._run(args) or 0)
    except RebarInputError as exc:
        from ._terminal import clean  # the message may quote text from a file

        print(f"rebar {args.command}: error: {clean(exc)}", file=sys.stderr)
        return 2


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
