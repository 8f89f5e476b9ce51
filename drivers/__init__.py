"""Turntable and inertial-unit drivers, their transports, and the simulated world."""
