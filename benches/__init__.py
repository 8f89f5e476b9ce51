"""Bench files and the orchestration that uses everything below it: session (prepare, run, resume), runner,
recorder and reader, driver factory, identification glue, uncertainty budget and certificate, and the
``tablebench`` CLI (one module per command in :mod:`benches.commands`). The top layer: nothing imports it."""
