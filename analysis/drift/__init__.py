"""Drift modelling: pre-processing, hypothesis tests, ARMA order and estimates, RLS, smoother."""
