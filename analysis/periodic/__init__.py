"""Periodic error: identification of strong periodic terms and their online compensation
(``docs/methods/periodic.md``).

Modules, each with one reason to change (imports only go down this list; no loops):

- :mod:`.compensator` — online, phase-exact subtraction of known terms (imports nothing from the package);
- :mod:`.model` — the model types (terms, fit report, the identified model) and the Cramér–Rao bound;
- :mod:`.linear` — linear least squares at fixed frequencies;
- :mod:`.detection` — coarse periodogram peaks with a false-alarm probability that holds, and the post-fit
  significance threshold;
- :mod:`.refine` — Levenberg–Marquardt on the exact model (default refinement);
- :mod:`.grid` — the published grid-refinement search (``method="grid"``, reproduces the paper);
- :mod:`.identify` — detection → refinement → covariance → post-fit test;
- :mod:`.comparison` — compensation vs averaging / low-pass on the same data;
- :mod:`.report` — one channel's analysis and its ``periodic.json`` structure (SI, units explicit);
- :mod:`.plot` — the figure (returned, never written here).
"""
