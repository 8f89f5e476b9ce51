"""Bench files, the orchestration of a run, and its reports; the top layer (it imports every other package,
nothing imports it).

- bench files: :mod:`.bench_config` (format: ``BENCH_FORMAT.md``) and the shipped ``*.yaml`` benches;
- orchestration: :mod:`.session` (prepare, run, resume, finish), :mod:`.runner` (steps → commands, samples),
  :mod:`.factory` (a bench's drivers, opened through :mod:`drivers.connect`), :mod:`.recording` (the one HDF5
  writer and reader, ``RECORDING.md``), :mod:`.reference` (table readings → reference specific force),
  :mod:`.identify` (a recording → the identification), :mod:`.progress`;
- reports: :mod:`.calibration_result` (``calibration.json``, ``CALIBRATION_FORMAT.md``), :mod:`.certificate`
  (PDF + JSON) and :mod:`.certificate_register`, :mod:`.analysis_input` (what the analysis commands read);
- the ``tablebench`` CLI: :mod:`.cli`, one module per command in :mod:`.commands`, their shared argument
  helpers in :mod:`.arguments`.
"""
