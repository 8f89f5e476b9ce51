"""One module per ``tablebench`` subcommand; each defines ``register(subparsers)``.

``SUMMARIES`` names every command module with the one-line help ``tablebench --help`` lists, so that listing
imports none of them (and nothing heavy: ``tablebench --help`` costs a few interpreter start-ups), and a
command imports only its own module. ``tests/test_architecture.py`` checks that it names every module, with the
same help the module registers.
"""

SUMMARIES: dict[str, str] = {
    "certificate": "issue the calibration certificate (PDF + JSON) of a run",
    "chamber": "check a bench's temperature chamber (status, set T, stop)",
    "check": "validate a procedure against a bench (limits, attitudes, rates, duration); nothing moves",
    "correct": "apply a calibration to raw unit data (accelerometer, and gyro with a whole-unit calibration)",
    "decode": "decode a raw unit capture (frames → SI samples) and summarise the link",
    "drift": "drift modelling of a static record: stationarity/normality/periodicity tests, ARMA, RLS",
    "identify": "identify the unit's error model (accelerometer and gyro triads) from a recording",
    "noise": "stability family (ADEV … HTOTDEV, Theo1, MTIE) and noise terms (Q, N, B, K, R) of a static record",
    "periodic": "identify and compensate periodic error terms",
    "plan": "predict parameter uncertainties of a procedure before running it",
    "registry": "the calibration registry: history, trends, comparisons, due dates, exports",
    "run": "run a procedure on a bench and record it",
    "runs": "list recordings with their status; salvage a damaged one",
    "scalefactor": "gyro scale factor, nonlinearity and asymmetry (IEEE 952/1431) from a rate-transfer run",
    "table": "check and jog a bench's turntable (status, idn, move, spin, stop, reset-fault)",
    "thermal": "thermal calibration of a run: parameters against temperature, thermal_calibration.json, certificate",
    "view": "watch a run (going on or finished) in a browser",
}
"""Command (= module) name → the one-line help of ``tablebench --help``."""
