"""Procedure files (YAML, ``SCHEMA.md``): the loader (validated, SI, every value with its line), the compiler
to typed steps (:mod:`procedures.steps`: ``Move``, ``Warmup``, ``Hold``, ``Spin``, ``Note``) against a table's
limits and the unit's mounting, and the nominal trajectory of the pre-run plan. Imports ``core``,
``analysis`` and the seam :mod:`drivers.protocols` (``AxisLimits``) only."""
