"""Noise analysis: the Allan / total variance family, confidence intervals and the noise-term fit."""
