"""Periodic error: identification of strong periodic terms and their online compensation."""
