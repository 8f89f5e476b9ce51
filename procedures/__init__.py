"""Procedure files: schema, loader and compiler to plain motion/acquisition steps."""
