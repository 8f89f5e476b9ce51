"""Dynamic Allan deviation (DAVAR): the overlapping Allan deviation over a window sliding along the record.

How the stability changes over a long record — a temperature transient, a noise burst, a drift that sets in —
is invisible in one curve over the whole record. The dynamic Allan deviation (L. Galleani & P. Tavella, "The
dynamic Allan variance", IEEE UFFC 56, 2009) computes the overlapping ADEV of each window of ``window`` seconds,
the window moved by ``step`` seconds, on one τ grid (octave up to a third of the window), and is drawn as a
picture: time along the record against τ, colour the deviation (:func:`analysis.noise.plot.plot_dynamic`).
Each window's values equal allantools' ``oadev`` of that window. See docs/methods/noise.md.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from analysis.noise.stability import stability


def dynamic_adev(
    data: ArrayLike, rate: float, window: float, step: float | None = None, data_type: str = "freq"
) -> dict[str, NDArray[np.float64]]:
    """Overlapping ADEV of sliding windows of one record.

    Parameters
    ----------
    data : array_like (N,)
        Rate (frequency) or angle (phase) record, SI; gaps (NaN) are skipped as in the whole-record estimate.
    rate : float
        Sample rate, Hz.
    window, step : float
        Window length and its step along the record, s (default step: a quarter window).
    data_type : {"freq", "phase"}

    Returns
    -------
    dict
        {"t_start", "t_centre": (W,) s, "tau": (M,) s, "adev": (W, M) in the rate unit (NaN where undefined)}.
    """
    y = np.asarray(data, dtype=np.float64).ravel()
    n_win = int(round(window * rate))
    n_step = int(round((step if step is not None else window / 4.0) * rate))
    if n_win < 16:
        raise ValueError(f"a dynamic-ADEV window of {window} s holds {n_win} samples; give at least 16")
    if n_win > y.size:
        raise ValueError(f"the window ({window} s) is longer than the record ({y.size / rate:.6g} s)")
    if n_step < 1:
        raise ValueError(f"the window step ({step} s) is shorter than one sample")
    starts = np.arange(0, y.size - n_win + 1, n_step)
    m = 2 ** np.arange(int(np.log2(max(n_win // 3, 1))) + 1)
    taus = m / rate
    rows = []
    for s0 in starts:
        est = stability(y[s0 : s0 + n_win], rate, ("oadev",), taus, data_type, confidence=None).estimates["oadev"]
        row = np.full(taus.size, np.nan)
        row[np.searchsorted(m, est.m)] = est.dev[:, 0]
        rows.append(row)
    t0 = starts / rate
    return {"t_start": t0, "t_centre": t0 + 0.5 * n_win / rate, "tau": taus, "adev": np.array(rows)}
