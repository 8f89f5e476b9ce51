"""The ``tablebench`` command line: the parser and entry point (:mod:`benches.cli.main`), one module per
subcommand (:mod:`benches.cli.commands`), shared arguments (:mod:`benches.cli.arguments`) and the analysis
commands' input reader (:mod:`benches.cli.analysis_input`)."""

from .main import build_parser, main

__all__ = ["build_parser", "main"]
