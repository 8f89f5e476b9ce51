"""The ``tablebench`` command line.

Every subcommand lives in its own module under :mod:`benches.cli.commands` and defines::

    def register(subparsers: argparse._SubParsersAction) -> None:
        p = subparsers.add_parser("noise", help=..., description=..., epilog=EXAMPLES,
                                  formatter_class=argparse.RawDescriptionHelpFormatter)
        ...
        p.set_defaults(func=run)          # run(args) -> int exit code

Modules are discovered automatically. Every user error derives from
:class:`core.errors.UserError` and is printed as one clear line with exit code 2, never a traceback.

Imports: ``tablebench --help`` lists the commands from :data:`benches.cli.commands.SUMMARIES` and imports none
of their modules; ``tablebench COMMAND …`` imports that command's module only. Inside a command module, imports
sit at the top, except where that would load a heavy library (scipy, matplotlib, fpdf, filterpy, pymodbus, tqdm,
starlette, uvicorn) before the command needs it: those are imported inside the function, marked
``# lazy: <library> (--help time)`` (``tests/test_architecture.py`` checks the marks, that ``SUMMARIES`` names
every command module with its help, and that ``--help`` imports no command module and nothing numerical).
"""

from __future__ import annotations

import argparse
import importlib
import os
import pkgutil
import sys
from collections.abc import Sequence

import benches.cli.commands as commands_pkg
from benches.cli.commands import SUMMARIES
from core.errors import UserError
from core.outputs import clear_inputs, protect_inputs
from core.provenance import software_version


def _modules() -> list[str]:
    """The command modules present (``SUMMARIES`` should name them all; one it does not is imported to list it)."""
    return sorted(m.name for m in pkgutil.iter_modules(commands_pkg.__path__) if not m.name.startswith("_"))


def build_parser(command: str | None = None, *, everything: bool = True) -> argparse.ArgumentParser:
    """The top-level parser.

    Parameters
    ----------
    command : str, optional
        The one subcommand whose module is imported and registered in full; the others are listed by their
        one-line help only (:data:`benches.cli.commands.SUMMARIES`), without importing them.
    everything : bool
        With no ``command``: import and register every command module (tests, documentation); False lists
        them only (what ``tablebench --help`` needs).
    """
    parser = argparse.ArgumentParser(
        prog="tablebench",
        description="Calibrate inertial units on a three-axis turntable: run procedures, record, identify, "
        "analyse noise, and issue certificates. The simulated bench (benches/sim.yaml) is the default.",
        epilog="Run 'tablebench COMMAND --help' for a command's options and examples.",
    )
    parser.add_argument("--version", action="version", version=f"tablebench {software_version()}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for name in _modules():
        if name == command or (command is None and everything) or name not in SUMMARIES:
            register = getattr(importlib.import_module(f"benches.cli.commands.{name}"), "register", None)
            if register is not None:
                register(sub)
        else:
            sub.add_parser(name, help=SUMMARIES[name], add_help=False)
    for name, command_parser in sub.choices.items():
        command_parser.set_defaults(_parser=command_parser, command=name)
    return parser


def _command_of(argv: Sequence[str]) -> str | None:
    """The subcommand named on the command line (the first word that is not an option), if any."""
    for word in argv:
        if not word.startswith("-"):
            return word
    return None


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the console script; returns the process exit code."""
    program = argv is None  # the tablebench process itself (not a caller in the same process, e.g. a test)
    argv = list(sys.argv[1:] if argv is None else argv)
    parser = build_parser(_command_of(argv), everything=False)
    args, extra = parser.parse_known_args(argv)
    if extra:  # name the command in the message, as its own parser does for its other errors
        getattr(args, "_parser", parser).error(f"unrecognized arguments: {' '.join(extra)}")
    func = getattr(args, "func", None)
    if func is None:
        parser.print_help()
        return 2
    protect_inputs(_inputs(args))
    try:
        return int(func(args) or 0)
    except UserError as exc:
        print(f"tablebench {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"tablebench {args.command}: interrupted", file=sys.stderr)
        if program and "benches.cli.work" in sys.modules:  # an analysis command (benches.cli.work) was stopped:
            # its outputs are written completely or not at all, its worker writes nothing; end the process now
            # (the interpreter's orderly exit takes over a second with scipy/matplotlib loaded, and would wait
            # for a worker still inside one long numerical call)
            sys.stdout.flush()
            sys.stderr.flush()
            os._exit(130)
        return 130
    finally:
        clear_inputs()


OUTPUT_DESTS = ("out", "json")
"""Arguments that name outputs; every other path-valued argument names an input (core.outputs)."""


def _inputs(args: argparse.Namespace) -> list[str]:
    """The files and folders named on the command line other than outputs: no output may replace them."""
    return [
        v
        for k, v in vars(args).items()
        if isinstance(v, str) and k not in OUTPUT_DESTS and not k.startswith("_") and k != "command"
    ]


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
