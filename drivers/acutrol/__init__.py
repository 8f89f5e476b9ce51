"""ACUTROL3000 controllers over the ACUTROL command language (ACL): driver and settings."""

from drivers.acutrol.driver import AclTurntable, format_number, wrap_deg
from drivers.acutrol.settings import AclSettings, default_profile

__all__ = ["AclSettings", "AclTurntable", "default_profile", "format_number", "wrap_deg"]
