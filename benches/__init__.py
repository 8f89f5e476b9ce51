"""Bench definitions and the orchestrator: runner, recorder, CLI, certificates."""
