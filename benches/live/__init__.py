"""The live view of a run in a browser (``docs/live-view.md``).

``feed`` (numbered events, replayable, kept in ``RUN/live.jsonl``), ``observer`` (the runner observer that
decimates the unit's channels and publishes table, estimates and link health), ``server`` (the read-only
Starlette app + uvicorn thread), ``replay`` (``tablebench view``'s sources) and ``run_view`` (one run's feed,
observer and server). Nothing is imported here, so ``--help`` stays light.
"""
