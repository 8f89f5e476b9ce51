"""The ``tablebench`` command line.

Every subcommand lives in its own module under :mod:`benches.cli.commands` and defines::

    def register(subparsers: argparse._SubParsersAction) -> None:
        p = subparsers.add_parser("noise", help=..., description=..., epilog=EXAMPLES,
                                  formatter_class=argparse.RawDescriptionHelpFormatter)
        ...
        p.set_defaults(func=run)          # run(args) -> int exit code

Modules are discovered automatically. Every user error derives from
:class:`core.errors.UserError` and is printed as one clear line with exit code 2, never a traceback.

Imports: building this parser imports every command module, so what they import at the top is what
``tablebench --help`` pays for. Modules import at the top, except where that would load a heavy library
(scipy, matplotlib, fpdf, filterpy, pymodbus, tqdm): the identification, the certificate, the bench factory
and the analyses are imported inside the function that needs them, marked ``# lazy: <library> (--help time)``
(``tests/test_architecture.py`` checks both: every function-level import in ``benches/`` carries the mark, and
every marked one keeps a heavy library out of ``--help``). ``tablebench --help`` takes ≈ 0.3 s this way,
≈ 1.5 s with everything loaded.
"""

from __future__ import annotations

import argparse
import importlib
import pkgutil
import sys
from collections.abc import Sequence

import benches.cli.commands as commands_pkg
from core.errors import UserError
from core.provenance import software_version


def build_parser() -> argparse.ArgumentParser:
    """The top-level parser with every discovered subcommand."""
    parser = argparse.ArgumentParser(
        prog="tablebench",
        description="Calibrate inertial units on a three-axis turntable: run procedures, record, identify, "
        "analyse noise, and issue certificates. The simulated bench (benches/sim.yaml) is the default.",
        epilog="Run 'tablebench COMMAND --help' for a command's options and examples.",
    )
    parser.add_argument("--version", action="version", version=f"tablebench {software_version()}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for info in sorted(pkgutil.iter_modules(commands_pkg.__path__), key=lambda m: m.name):
        if info.name.startswith("_"):
            continue
        module = importlib.import_module(f"benches.cli.commands.{info.name}")
        register = getattr(module, "register", None)
        if register is not None:
            register(sub)
    for name, command_parser in sub.choices.items():
        command_parser.set_defaults(_parser=command_parser, command=name)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the console script; returns the process exit code."""
    parser = build_parser()
    args, extra = parser.parse_known_args(argv)
    if extra:  # name the command in the message, as its own parser does for its other errors
        getattr(args, "_parser", parser).error(f"unrecognized arguments: {' '.join(extra)}")
    func = getattr(args, "func", None)
    if func is None:
        parser.print_help()
        return 2
    try:
        return int(func(args) or 0)
    except UserError as exc:
        print(f"tablebench {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"tablebench {args.command}: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
