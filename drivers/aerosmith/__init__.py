"""Ideal Aerosmith single-axis rate tables (three-letter text commands, RS-232): docs/protocols/ideal-aerosmith.md."""

from drivers.aerosmith.driver import AerosmithTable
from drivers.aerosmith.settings import AerosmithSettings

__all__ = ["AerosmithSettings", "AerosmithTable"]
