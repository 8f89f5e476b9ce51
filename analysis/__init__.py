"""Pure maths of inertial test: identification, noise, periodic error, drift (no I/O, no hardware)."""
