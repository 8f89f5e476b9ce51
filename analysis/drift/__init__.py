"""Drift modelling: pre-processing, hypothesis tests, ARMA order and estimates (exact likelihood and its
optimiser), RLS, smoother; :mod:`.report` runs one channel's analysis and :mod:`.plot` returns its figures."""
