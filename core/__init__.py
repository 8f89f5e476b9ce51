"""The lowest layer, imported by every other package and importing none of them: the user-error family,
YAML with line numbers, strict JSON writing, file hashing and the software version.

Layers (each imports only from those below it): core ← analysis ← procedures, drivers ← benches.
"""
