"""Calibration parameters as functions of the unit's temperature (docs/methods/thermal.md).

Each parameter p (bias, scale factor, misalignment of either triad) is modelled as

    p(T, Ṫ) = Σ_{k=0..n_p} c_{p,k} (T − T_ref)^k  [+ c_{p,Ṫ} Ṫ]

with T the unit's own temperature (K) and an optional term in its rate Ṫ (K/s) that models the thermal lag /
hysteresis explicitly (our modelling choice; Niu et al., Sensors 13(9) 2013, cancel the lag by balancing
heating and cooling ramps instead). PX4 keeps third-order offset polynomials per sensor; here every parameter
has its own order n_p.

Fit: the per-plateau (or per-ramp-segment) estimates x_i with their full covariance C_i are stacked and all
coefficients are fitted at once by generalised least squares, weight blockdiag(C_i⁻¹), so the coefficient
covariance is complete (correlations between parameters of one plateau carry into the coefficients).

Order: the orders are chosen by the Bayesian information criterion of the joint fit,
BIC = −2 ln L + k ln N = χ² + k ln N (+ const), with N the number of scalar estimates fitted (plateaus ×
parameters) and k the number of coefficients — the known-variance form of the spec's N ln(RSS/N) + k ln N
(the per-plateau uncertainties are known, so the likelihood is χ²); a coordinate search over the orders
0..``max_order`` per parameter, then a check on held-out plateaus (leave one plateau out): a parameter whose
chosen order predicts the held-out plateaus worse than one order less is stepped down.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.linalg import solve_triangular


@dataclass(frozen=True)
class PlateauEstimate:
    """One plateau's (or ramp segment's) calibration result.

    Attributes
    ----------
    temperature : float
        Mean unit temperature during the calibration sequence, K.
    x : ndarray (P,)
        Parameter estimates, SI.
    covariance : ndarray (P, P)
        Their covariance (standard uncertainties squared), SI.
    rate : float
        Mean dT/dt of the unit during the sequence, K/s (≈ 0 on a plateau).
    direction : str
        ``"heating"``, ``"cooling"`` or ``""`` (how the plateau was reached; for the hysteresis).
    """

    temperature: float
    x: NDArray[np.float64]
    covariance: NDArray[np.float64]
    rate: float = 0.0
    direction: str = ""


@dataclass(frozen=True)
class ThermalModel:
    """Fitted temperature model of P parameters.

    Attributes
    ----------
    names : tuple of str
        Parameter names.
    reference : float
        T_ref, K.
    orders : tuple of int
        Polynomial order per parameter.
    rate_term : bool
        True if every parameter has a Ṫ coefficient.
    coefficients : ndarray (K,)
        All coefficients, parameter after parameter: c_{p,0..n_p} (SI per K^k) then c_{p,Ṫ} (SI per K/s).
    covariance : ndarray (K, K)
        Their full covariance.
    temperature_range : (float, float)
        The plateau temperatures' span, K: the model's validity range.
    chi2 : float
        χ² of the fit; ``n_data`` scalar estimates, ``dof`` = n_data − K.
    bic : float
    """

    names: tuple[str, ...]
    reference: float
    orders: tuple[int, ...]
    rate_term: bool
    coefficients: NDArray[np.float64]
    covariance: NDArray[np.float64]
    temperature_range: tuple[float, float]
    chi2: float
    n_data: int
    bic: float
    bic_table: dict[str, list[float]] = field(default_factory=dict)

    @property
    def dof(self) -> int:
        """Degrees of freedom of the fit."""
        return self.n_data - self.coefficients.size

    def slices(self) -> list[slice]:
        """The coefficient slice of each parameter."""
        out, i = [], 0
        for n in self.orders:
            w = n + 1 + int(self.rate_term)
            out.append(slice(i, i + w))
            i += w
        return out

    def parameter(self, name: str) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """(coefficients, covariance) of one parameter, SI per K^k (then per K/s)."""
        s = self.slices()[self.names.index(name)]
        return self.coefficients[s], self.covariance[s, s]

    def design(self, temperature: ArrayLike, rate: ArrayLike | float = 0.0) -> NDArray[np.float64]:
        """(m, P, K) rows mapping the coefficients to the parameters at m (T, Ṫ) points."""
        t = np.atleast_1d(np.asarray(temperature, dtype=float))
        r = np.broadcast_to(np.asarray(rate, dtype=float), t.shape)
        a = np.zeros((t.size, len(self.names), self.coefficients.size))
        d = t - self.reference
        for p, (s, n) in enumerate(zip(self.slices(), self.orders, strict=True)):
            a[:, p, s.start : s.start + n + 1] = d[:, None] ** np.arange(n + 1)
            if self.rate_term:
                a[:, p, s.stop - 1] = r
        return a

    def evaluate(
        self, temperature: ArrayLike, rate: ArrayLike | float = 0.0
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Parameters (m, P) at the given unit temperatures (K) and rates (K/s), and their standard
        uncertainties (m, P) from the coefficient covariance."""
        a = self.design(temperature, rate)
        values = a @ self.coefficients
        var = np.einsum("mpk,kl,mpl->mp", a, self.covariance, a)
        return values, np.sqrt(np.maximum(var, 0.0))

    def covariance_at(self, temperature: float, rate: float = 0.0) -> NDArray[np.float64]:
        """(P, P) covariance of the parameters at one temperature (K) and rate (K/s)."""
        a = self.design(temperature, rate)[0]
        return a @ self.covariance @ a.T

    def in_range(self, temperature: ArrayLike, margin: float = 0.0) -> NDArray[np.bool_]:
        """True where T (K) lies inside the calibrated range (± ``margin`` K)."""
        t = np.asarray(temperature, dtype=float)
        lo, hi = self.temperature_range
        return (t >= lo - margin) & (t <= hi + margin)

    def as_dict(self) -> dict[str, object]:
        """JSON-ready description (SI)."""
        out: dict[str, object] = {
            "reference_K": self.reference,
            "temperature_range_K": list(self.temperature_range),
            "rate_term": self.rate_term,
            "chi2": self.chi2,
            "dof": self.dof,
            "bic": self.bic,
            "parameters": {},
        }
        params: dict[str, object] = {}
        for name in self.names:
            c, cov = self.parameter(name)
            params[name] = {"coefficients": c.tolist(), "covariance": cov.tolist()}
        out["parameters"] = params
        out["covariance"] = self.covariance.tolist()
        return out


def _whitened(plateaus: Sequence[PlateauEstimate]) -> tuple[list[NDArray[np.float64]], NDArray[np.float64]]:
    """Per plateau, the factor L⁻¹ with C = L Lᵀ (so L⁻¹ whitens); and the whitened stacked estimates."""
    w, y = [], []
    for i, pl in enumerate(plateaus):
        c = np.asarray(pl.covariance, dtype=float)
        try:
            lo = np.linalg.cholesky(c)
        except np.linalg.LinAlgError:
            raise ValueError(f"plateau {i} ({pl.temperature:.2f} K): covariance is not positive definite") from None
        li = np.linalg.inv(lo)
        w.append(li)
        y.append(li @ np.asarray(pl.x, dtype=float))
    return w, np.concatenate(y)


def _solve(
    plateaus: Sequence[PlateauEstimate],
    orders: Sequence[int],
    rate_term: bool,
    reference: float,
    scale: float,
    white: list[NDArray[np.float64]],
    y: NDArray[np.float64],
    rows: Sequence[int] | None = None,
) -> tuple[NDArray[np.float64], NDArray[np.float64], float]:
    """GLS in scaled coordinates u = (T − T_ref)/scale: (coefficients, covariance, χ²) over plateaus ``rows``."""
    n_par = len(orders)
    idx = list(range(len(plateaus))) if rows is None else list(rows)
    blocks, ys = [], []
    for i in idx:
        a = _plateau_design(plateaus[i], orders, rate_term, reference, scale)
        blocks.append(white[i] @ a)
        ys.append(y[i * n_par : (i + 1) * n_par])
    a_all, y_all = np.vstack(blocks), np.concatenate(ys)
    q, r = np.linalg.qr(a_all)
    if np.min(np.abs(np.diag(r))) < 1e-12 * np.max(np.abs(np.diag(r))):
        raise np.linalg.LinAlgError("rank-deficient thermal design")
    beta = np.linalg.solve(r, q.T @ y_all)
    rinv = np.linalg.inv(r)
    res = y_all - a_all @ beta
    return beta, rinv @ rinv.T, float(res @ res)


def _plateau_design(
    pl: PlateauEstimate, orders: Sequence[int], rate_term: bool, reference: float, scale: float
) -> NDArray[np.float64]:
    """One plateau's rows of the design (P, K) in scaled coordinates: per parameter the powers of
    (T − T_ref)/scale up to its order, then its dT/dt column when ``rate_term``."""
    widths = [n + 1 + int(rate_term) for n in orders]
    u = (pl.temperature - reference) / scale
    a = np.zeros((len(orders), sum(widths)))
    col = 0
    for p, n in enumerate(orders):
        a[p, col : col + n + 1] = u ** np.arange(n + 1)
        if rate_term:
            a[p, col + n + 1] = pl.rate * scale
        col += widths[p]
    return a


def _forward(lo: NDArray[np.float64], b: NDArray[np.float64]) -> NDArray[np.float64]:
    """L⁻¹ b for lower-triangular L (so that bᵀ(LLᵀ)⁻¹b = |L⁻¹b|²)."""
    return solve_triangular(lo, b, lower=True)


def _whitened_design(
    plateaus: Sequence[PlateauEstimate],
    orders: Sequence[int],
    rate_term: bool,
    reference: float,
    scale: float,
    white: list[NDArray[np.float64]],
) -> NDArray[np.float64]:
    """The stacked whitened design (m·P, K) in scaled coordinates (columns as :func:`_solve`)."""
    return np.vstack([white[i] @ _plateau_design(pl, orders, rate_term, reference, scale)
                      for i, pl in enumerate(plateaus)])  # fmt: skip


def _unscale(
    beta: NDArray[np.float64], cov: NDArray[np.float64], orders: Sequence[int], rate_term: bool, scale: float
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    s = []
    for n in orders:
        s += [scale ** (-k) for k in range(n + 1)]
        if rate_term:
            s.append(scale)
    d = np.asarray(s)
    return beta * d, cov * np.outer(d, d)


def _holdout(
    plateaus: Sequence[PlateauEstimate],
    orders: list[int],
    p: int,
    rate_term: bool,
    reference: float,
    scale: float,
) -> float:
    """Leave-one-plateau-out prediction χ² of parameter ``p`` alone (its marginal variances)."""
    m = len(plateaus)
    total = 0.0
    one = [orders[p]]
    for i in range(m):
        keep = [j for j in range(m) if j != i]
        sub = [
            PlateauEstimate(
                pl.temperature, np.asarray(pl.x)[p : p + 1], np.asarray(pl.covariance)[p : p + 1, p : p + 1], pl.rate
            )
            for pl in plateaus
        ]
        w, y = _whitened(sub)
        try:
            beta, cov, _ = _solve(sub, one, rate_term, reference, scale, w, y, keep)
        except np.linalg.LinAlgError:
            return math.inf
        u = (plateaus[i].temperature - reference) / scale
        row = u ** np.arange(orders[p] + 1)
        if rate_term:
            row = np.append(row, plateaus[i].rate * scale)
        e = float(np.asarray(plateaus[i].x)[p] - row @ beta)
        v = float(np.asarray(plateaus[i].covariance)[p, p] + row @ cov @ row)
        total += e * e / v
    return total


def fit_thermal_model(
    plateaus: Sequence[PlateauEstimate],
    names: Sequence[str],
    *,
    reference: float | None = None,
    max_order: int = 3,
    orders: Sequence[int] | None = None,
    rate_term: bool = False,
    holdout_check: bool = True,
) -> ThermalModel:
    """Fit every parameter as a polynomial in (T − T_ref), orders by BIC unless given (module docstring).

    Parameters
    ----------
    plateaus : sequence of PlateauEstimate
        At least 2 (distinct temperatures).
    names : sequence of str
        Names of the P parameters.
    reference : float or None
        T_ref, K (None: the mean plateau temperature rounded to 0.1 K).
    max_order : int
        Highest order tried (limited to plateaus − 2 so that every fit keeps a degree of freedom).
    orders : sequence of int or None
        Fixed orders (no selection).
    rate_term : bool
        Add a Ṫ coefficient to every parameter (needs plateaus/ramps with different rates).
    holdout_check : bool
        Step an order down when it predicts held-out plateaus worse than one order less.
    """
    m = len(plateaus)
    n_par = len(names)
    if m < 2:
        raise ValueError(f"a thermal model needs at least 2 plateaus, got {m}")
    for i, pl in enumerate(plateaus):
        if np.asarray(pl.x).shape != (n_par,) or np.asarray(pl.covariance).shape != (n_par, n_par):
            raise ValueError(f"plateau {i}: x must be ({n_par},) and covariance ({n_par}, {n_par})")
    temps = np.array([pl.temperature for pl in plateaus])
    if not np.all(np.isfinite(temps)) or np.ptp(temps) <= 0:
        raise ValueError("plateau temperatures must be finite and not all equal")
    ref = float(np.round(np.mean(temps), 1)) if reference is None else float(reference)
    scale = max(float(np.max(np.abs(temps - ref))), 1e-3)
    white, y = _whitened(plateaus)
    n_data = m * n_par
    top = max(0, min(int(max_order), m - 2 - int(rate_term)))
    bic_table: dict[str, list[float]] = {}
    if orders is not None:
        chosen = [int(o) for o in orders]
        if len(chosen) != n_par or min(chosen) < 0:
            raise ValueError(f"orders must be {n_par} integers >= 0")
    else:
        chosen = [0] * n_par
        # the whitened design at the highest order, built once; an order vector selects its columns
        full_orders = [top] * n_par
        a_full = _whitened_design(plateaus, full_orders, rate_term, ref, scale, white)
        width = top + 1 + int(rate_term)

        # normal equations of the full design once; each order vector solves its (small) sub-system:
        # χ² = yᵀy − bᵀβ (sub-system solves are far cheaper than a least squares per trial)
        info = a_full.T @ a_full
        rhs = a_full.T @ y
        yy = float(y @ y)

        def bic(o: list[int]) -> float:
            cols = [p * width + j for p, n in enumerate(o) for j in range(n + 1)]
            if rate_term:
                cols += [p * width + width - 1 for p in range(n_par)]
            sub = info[np.ix_(cols, cols)]
            try:
                lo = np.linalg.cholesky(sub)
            except np.linalg.LinAlgError:
                return math.inf
            z = _forward(lo, rhs[cols])
            return max(yy - float(z @ z), 0.0) + len(cols) * math.log(n_data)

        for _sweep in range(6):
            changed = False
            for p in range(n_par):
                scores = []
                for n in range(top + 1):
                    trial = chosen.copy()
                    trial[p] = n
                    scores.append(bic(trial))
                best = int(np.argmin(scores))
                bic_table[names[p]] = scores
                if best != chosen[p]:
                    chosen[p], changed = best, True
            if not changed:
                break
        if holdout_check and m >= 4:
            for p in range(n_par):
                while chosen[p] > 0:
                    lower = chosen.copy()
                    lower[p] -= 1
                    if _holdout(plateaus, chosen, p, rate_term, ref, scale) > _holdout(
                        plateaus, lower, p, rate_term, ref, scale
                    ):
                        chosen[p] -= 1
                    else:
                        break
    beta, cov, chi2 = _solve(plateaus, chosen, rate_term, ref, scale, white, y)
    coef, ccov = _unscale(beta, cov, chosen, rate_term, scale)
    k = coef.size
    return ThermalModel(
        names=tuple(names),
        reference=ref,
        orders=tuple(chosen),
        rate_term=rate_term,
        coefficients=coef,
        covariance=ccov,
        temperature_range=(float(temps.min()), float(temps.max())),
        chi2=chi2,
        n_data=n_data,
        bic=chi2 + k * math.log(n_data),
        bic_table=bic_table,
    )


def with_common_offset(model: ThermalModel, names: Sequence[str], covariance: ArrayLike) -> ThermalModel:
    """``model`` with an error common to every plateau added: an offset δ of the parameters ``names`` shared by
    all plateaus (covariance ``covariance``, len(names)²) shifts only their constant coefficients c_0 by δ
    (a polynomial fitted to data shifted by a constant shifts by that constant), so the covariance of those
    c_0 grows by ``covariance``; the other coefficients are unchanged. Used for a reference common to the whole
    run, such as the time base that scales every gyro scale-factor estimate."""
    c = np.asarray(covariance, dtype=float)
    if c.shape != (len(names), len(names)):
        raise ValueError(f"covariance must be ({len(names)}, {len(names)}), got {c.shape}")
    idx = [model.slices()[model.names.index(n)].start for n in names]
    cov = model.covariance.copy()
    cov[np.ix_(idx, idx)] += c
    return ThermalModel(
        model.names, model.reference, model.orders, model.rate_term, model.coefficients, cov,
        model.temperature_range, model.chi2, model.n_data, model.bic, model.bic_table,
    )  # fmt: skip


def compensation_residual(model: ThermalModel, plateaus: Sequence[PlateauEstimate]) -> list[dict[str, object]]:
    """After compensation: per plateau, estimate − model (SI) with its standard uncertainty (the plateau's and
    the model's, which are correlated: u² = C_ii − (A Σ Aᵀ)_ii for the plateaus the model was fitted on)."""
    out = []
    for pl in plateaus:
        val, _ = model.evaluate(pl.temperature, pl.rate)
        a = model.design(pl.temperature, pl.rate)[0]
        var = np.diag(np.asarray(pl.covariance)) - np.einsum("pk,kl,pl->p", a, model.covariance, a)
        out.append(
            {
                "temperature_K": pl.temperature,
                "residual": (np.asarray(pl.x) - val[0]).tolist(),
                "u": np.sqrt(np.maximum(var, 0.0)).tolist(),
            }
        )
    return out


def hysteresis(
    heating: ThermalModel, cooling: ThermalModel, temperatures: ArrayLike
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Heating − cooling difference of every parameter at ``temperatures`` (K) inside both ranges, with its
    standard uncertainty (the two fits are independent): ((m, P), (m, P))."""
    t = np.atleast_1d(np.asarray(temperatures, dtype=float))
    if not (np.all(heating.in_range(t)) and np.all(cooling.in_range(t))):
        raise ValueError("hysteresis temperatures must lie inside both the heating and the cooling range")
    vh, uh = heating.evaluate(t)
    vc, uc = cooling.evaluate(t)
    return vh - vc, np.hypot(uh, uc)
