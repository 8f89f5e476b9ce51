"""Online (recursive) least squares for AR models and extended least squares for ARMA models.

Specification: docs/methods/drift.md ("Online"). Per sample, with regressor φ_t and target y_t:

    K = P φ / (λ + φᵀ P φ);   θ̂ ← θ̂ + K (y − φᵀ θ̂);   P ← (P − K φᵀ P) / λ,

λ ∈ (0, 1] the forgetting factor. The recursion is initialised from a batch least-squares fit on the first
samples (θ̂ = batch estimate, P = (ΦᵀΦ)⁻¹), so that with λ = 1 it reproduces the batch fit of all data exactly
(to rounding). For ARMA(p, q) (sign convention of :mod:`analysis.drift.arma`) the regressor is
[x_{t−1} … x_{t−p}, ε_{t−1} … ε_{t−q}] with ε the a-posteriori residuals
ε_t = y_t − φ_tᵀθ̂_t = (y − φᵀθ̂_{t−1}) λ/(λ+φᵀPφ) (extended least squares);
its initial batch fit is a Hannan–Rissanen regression (long AR for the residuals).
The regression coefficients of the residual lags are −θ_j (Box–Jenkins sign convention); :meth:`OnlineArma.state`
returns θ in the convention of :mod:`analysis.drift.arma`.

Speed: the recursion is truly per sample. numpy has a large per-call overhead for 2×2…6×6 matrices, so the
inner loop is plain-Python float arithmetic, generated once per (p, q) with every matrix element in a local
variable and only the upper triangle of the symmetric P updated (``_kernel``). Measured figures are in
``benchmarks/RESULTS.md`` (section "drift").
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from analysis.drift.preprocess import DriftInputError, check_series


class RecursiveLeastSquares:
    """Generic RLS with forgetting factor for an arbitrary regressor (pure Python, per sample).

    Parameters
    ----------
    theta : array_like
        Initial parameter estimate (d,).
    P : array_like
        Initial covariance-like matrix (d, d), e.g. (ΦᵀΦ)⁻¹ of a batch fit.
    lam : float
        Forgetting factor λ ∈ (0, 1].
    """

    def __init__(self, theta: ArrayLike, P: ArrayLike, lam: float = 1.0) -> None:
        if not (0.0 < lam <= 1.0):
            raise DriftInputError(f"forgetting factor must be in (0, 1], got {lam}")
        self.theta = [float(v) for v in np.asarray(theta, dtype=float).ravel()]
        pm = np.asarray(P, dtype=float)
        d = len(self.theta)
        if pm.shape != (d, d):
            raise DriftInputError(f"P must be {d}×{d}, got {pm.shape}")
        self.P = [[float(v) for v in row] for row in pm]
        self.lam = float(lam)

    @classmethod
    def from_batch(cls, regressors: ArrayLike, targets: ArrayLike, lam: float = 1.0) -> RecursiveLeastSquares:
        """Initialise from a batch least-squares fit: θ̂ = (ΦᵀΦ)⁻¹Φᵀy, P = (ΦᵀΦ)⁻¹."""
        phi = np.asarray(regressors, dtype=float)
        y = np.asarray(targets, dtype=float)
        theta, P = batch_least_squares(phi, y)
        return cls(theta, P, lam)

    def update(self, y: float, phi: ArrayLike) -> float:
        """Process one sample; returns the a-priori error y − φᵀθ̂ (before the update)."""
        f = [float(v) for v in phi]
        d = len(f)
        P, th, lam = self.P, self.theta, self.lam
        pf = [sum(P[i][j] * f[j] for j in range(d)) for i in range(d)]
        den = lam + sum(f[i] * pf[i] for i in range(d))
        err = y - sum(th[i] * f[i] for i in range(d))
        k = [v / den for v in pf]
        for i in range(d):
            th[i] += k[i] * err
        inv = 1.0 / lam
        for i in range(d):
            row = P[i]
            for j in range(d):
                row[j] = (row[j] - k[i] * pf[j]) * inv
        return err


def batch_least_squares(regressors: NDArray[np.float64], targets: NDArray[np.float64]) -> tuple[np.ndarray, np.ndarray]:
    """θ̂ and (ΦᵀΦ)⁻¹ of the linear regression y = Φθ + ε (raises DriftInputError when Φ is rank deficient)."""
    gram = regressors.T @ regressors
    try:
        P = np.linalg.inv(gram)
    except np.linalg.LinAlgError:
        raise DriftInputError("batch least-squares initialisation is singular (constant or too short data)") from None
    if not np.all(np.isfinite(P)) or np.linalg.cond(gram) > 1e14:
        raise DriftInputError("batch least-squares initialisation is ill-conditioned; use more initial samples")
    theta = np.linalg.solve(gram, regressors.T @ targets)
    return theta, P


def lag_matrix(x: NDArray[np.float64], lags: int, start: int) -> NDArray[np.float64]:
    """Rows t = start..n−1 of [x_{t−1} … x_{t−lags}] (start ≥ lags)."""
    n = x.size
    return np.stack([x[start - j : n - j] for j in range(1, lags + 1)], axis=1) if lags else np.zeros((n - start, 0))


@functools.lru_cache(maxsize=64)
def _kernel(p: int, q: int, record: bool):
    """Generate the unrolled per-sample recursion for ARMA(p, q) regressors (see the module docstring)."""
    d = p + q
    f = [f"xl{j}" for j in range(1, p + 1)] + [f"el{j}" for j in range(1, q + 1)]
    th = [f"t{i}" for i in range(d)]

    def pn(i: int, j: int) -> str:
        return f"P{min(i, j)}_{max(i, j)}"

    pnames = [pn(i, j) for i in range(d) for j in range(i, d)]
    lines = ["def kernel(xs, state, lam, trace):"]
    unpack = ", ".join(th + pnames + f)
    lines.append(f"    ({unpack},) = state" if unpack else "    pass")
    lines.append("    ilam = 1.0 / lam")
    lines.append("    for y in xs:")
    for i in range(d):
        lines.append(f"        g{i} = " + " + ".join(f"{pn(i, j)} * {f[j]}" for j in range(d)))
    lines.append("        den = lam + " + " + ".join(f"{f[i]} * g{i}" for i in range(d)))
    lines.append("        err = y - (" + " + ".join(f"{th[i]} * {f[i]}" for i in range(d)) + ")")
    lines.append("        c = err / den")
    for i in range(d):
        lines.append(f"        {th[i]} += g{i} * c")
    lines.append("        r = 1.0 / den")
    for i in range(d):
        lines.append(f"        h{i} = g{i} * r")
    for i in range(d):
        for j in range(i, d):
            lines.append(f"        {pn(i, j)} = ({pn(i, j)} - h{i} * g{j}) * ilam")
    if q:
        lines.append("        eps = err * lam * r")
        for j in range(q, 1, -1):
            lines.append(f"        el{j} = el{j - 1}")
        lines.append("        el1 = eps")
    for j in range(p, 1, -1):
        lines.append(f"        xl{j} = xl{j - 1}")
    if p:
        lines.append("        xl1 = y")
    if record:
        lines.append("        trace.append(" + ("eps" if q else "err * lam * r") + ")")
    lines.append(f"    return [{unpack}]")
    src = "\n".join(lines)
    ns: dict = {}
    exec(compile(src, f"<rls kernel p={p} q={q}>", "exec"), ns)  # noqa: S102 - code generated above, no input
    return ns["kernel"]


@dataclass
class OnlineArmaState:
    """Snapshot of an :class:`OnlineArma` estimator.

    φ̂, θ̂ in the convention of :mod:`analysis.drift.arma`; P in the regressor order [x lags, residual lags], whose
    coefficients are (φ, −θ).
    """

    phi: NDArray[np.float64]
    theta: NDArray[np.float64]
    P: NDArray[np.float64]
    samples: int


class OnlineArma:
    """Recursive LS (q = 0) / extended LS (q > 0) estimator of ARMA(p, q) coefficients, fed sample by sample.

    Parameters
    ----------
    p, q : int
        Orders (p + q ≥ 1).
    lam : float
        Forgetting factor λ ∈ (0, 1].

    Examples
    --------
    >>> est = OnlineArma(1, 1).initialise(x[:2000])   # batch fit on the first samples
    >>> est.feed(x[2000:])                             # recursive, one sample at a time
    >>> est.state().phi, est.state().theta
    """

    def __init__(self, p: int, q: int, lam: float = 1.0) -> None:
        if p < 0 or q < 0 or p + q == 0 or p > 10 or q > 10:
            raise DriftInputError(f"online ARMA needs 1 ≤ p+q with p, q ≤ 10; got p={p}, q={q}")
        if not (0.0 < lam <= 1.0):
            raise DriftInputError(f"forgetting factor must be in (0, 1], got {lam}")
        self.p, self.q, self.lam = p, q, float(lam)
        self._state: list[float] | None = None
        self.samples = 0

    def initialise(self, x0: ArrayLike, long_ar: int | None = None) -> OnlineArma:
        """Batch least-squares start on the first samples ``x0`` (zero-mean series, any unit).

        For q > 0 the residual lags come from a long AR(``long_ar``, default max(20, 3(p+q))) fit
        (Hannan–Rissanen), then the ARMA regression is solved by least squares on those residuals.
        """
        p, q = self.p, self.q
        a = check_series(x0, "initial samples", min_samples=1)
        m = long_ar if long_ar is not None else max(20, 3 * (p + q))
        start = p if q == 0 else m + q
        if a.size < start + 10 * (p + q):
            raise DriftInputError(
                f"{a.size} initial samples are too few for ARMA({p},{q}); give at least {start + 10 * (p + q)}"
            )
        if q == 0:
            eps = np.zeros(a.size)
        else:
            coef, _ = batch_least_squares(lag_matrix(a, m, m), a[m:])
            eps = np.zeros(a.size)
            eps[m:] = a[m:] - lag_matrix(a, m, m) @ coef
        reg = np.concatenate([lag_matrix(a, p, start), lag_matrix(eps, q, start)], axis=1)
        theta, P = batch_least_squares(reg, a[start:])
        self._set_state(theta, P, a[-p:][::-1] if p else np.zeros(0), eps[-q:][::-1] if q else np.zeros(0))
        self.samples = a.size
        self.init_regression = (reg, a[start:])
        self.init_residuals = eps
        return self

    def _set_state(self, theta: NDArray, P: NDArray, xlags: NDArray, elags: NDArray) -> None:
        d = self.p + self.q
        pvals = [float(P[i, j]) for i in range(d) for j in range(i, d)]
        self._state = [float(v) for v in theta] + pvals + [float(v) for v in xlags] + [float(v) for v in elags]

    def feed(self, xs: ArrayLike, record_residuals: bool = False) -> list[float] | None:
        """Process the samples ``xs`` one at a time (the recursion above); optionally return the ε_t."""
        if self._state is None:
            raise DriftInputError("call initialise() with the first samples before feeding the online estimator")
        data = np.asarray(xs, dtype=np.float64)
        if data.ndim != 1 or not np.all(np.isfinite(data)):
            raise DriftInputError("online ARMA input must be a finite 1-D series (no NaN/inf)")
        trace: list[float] = []
        self._state = _kernel(self.p, self.q, record_residuals)(data.tolist(), self._state, self.lam, trace)
        self.samples += data.size
        return trace if record_residuals else None

    def update(self, x: float) -> None:
        """Process one sample (convenience wrapper around :meth:`feed`)."""
        self.feed(np.array([x], dtype=np.float64))

    def state(self) -> OnlineArmaState:
        """Current estimates φ̂, θ̂ and the symmetric P."""
        if self._state is None:
            raise DriftInputError("the online estimator is not initialised")
        d = self.p + self.q
        th = np.array(self._state[:d])
        P = np.zeros((d, d))
        k = d
        for i in range(d):
            for j in range(i, d):
                P[i, j] = P[j, i] = self._state[k]
                k += 1
        return OnlineArmaState(th[: self.p], -th[self.p :], P, self.samples)
