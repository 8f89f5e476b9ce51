"""Streaming Kalman identification of a sensor-error model over a whole turntable sequence.

One filter (filterpy ``KalmanFilter``, dim_x = the model's state count: 18 for the accelerometer triad,
33 or more for the whole unit) carries **all** states across every step of the procedure (a single
position has rank 3 of 18; separate per-step filters, as published, cannot work — see
``docs/methods/accelerometer-calibration.md``). The model is a
:class:`analysis.identification.specification.ModelSpec` (default: the accelerometer model); frames:
body frame, z = y − y_ref = H x + v, per-axis white noise of variance R_i per sample.

Block updates (exact)
---------------------
Each :meth:`StreamingIdentifier.update` call condenses its n samples into the information pair
Λ = Σ HᵀR⁻¹H, η = Σ HᵀR⁻¹z (via the model's ``regressor_gram``, chunked, one matrix product
per chunk) and then applies **one** filterpy update with an n-dimensional whitened pseudo-measurement

    H' = diag(√λ) Vᵀ,  z' = diag(1/√λ) Vᵀ η,  R' = I        (Λ = V diag(λ) Vᵀ, λ clipped at 0)

which carries exactly the same information (H'ᵀH' = Λ, H'ᵀz' = η; rows with λ = 0 carry none). With
Q = 0 the posterior therefore equals sequential per-sample updates and the batch least-squares solution
(:mod:`analysis.identification.batch`) to rounding.

Internally the filter state is the parameter vector divided by the prior 1σ (each state has prior
variance 1), which keeps the filter's matrices well conditioned across parameter kinds whose SI
magnitudes span 10⁻⁷ (d, s²/m) to 10⁻² (r, m). :attr:`estimate`/:attr:`covariance` are SI.

Process noise: Φ = I and Q = q·dt between updates (dt = time since the previous update). A scalar ``q``
(1/s) is a random walk relative to the prior variance (Q_ii = q·dt·P0_ii); an (n,) array is the SI
random-walk PSD per state. Q is applied between blocks (block-internal drift is ignored), so with
q ≠ 0 keep blocks short relative to the drift time scale. Default q = 0 (constant parameters).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from analysis.identification._filterpy import kalman_filter_class
from analysis.identification.batch import information_rank
from analysis.identification.specification import ModelSpec, is_output_columns, resolve


@dataclass(frozen=True)
class StepRecord:
    """State of the filter after one update block.

    Attributes
    ----------
    step : str
        Step label given to :meth:`StreamingIdentifier.update`.
    time : float
        Time of the block's last sample, s (NaN when neither sample times nor a sample rate are known).
    n_samples : int
        Samples in the block.
    x : ndarray (n,)
        Estimate after the block, SI.
    sigma : ndarray (n,)
        1σ after the block, SI (√diag P).
    """

    step: str
    time: float
    n_samples: int
    x: NDArray[np.float64]
    sigma: NDArray[np.float64]


@dataclass(frozen=True)
class ResidualStats:
    """Residual z − H x̂ statistics of one step, per measurement axis (SI of the axis's sensor)."""

    count: int
    mean: NDArray[np.float64]
    rms: NDArray[np.float64]


class StreamingIdentifier:
    """Kalman filter over a model's parameters, fed block by block as data arrive.

    Parameters
    ----------
    r_var : array_like (n_axes,)
        White measurement-noise variance per sample and measurement axis, SI² (see
        :func:`estimate_measurement_noise`, or noise density² × sample rate).
    p0 : array_like (n, n)
        Prior covariance (the bench's datasheet bounds), SI; must be positive definite.
    x0 : array_like (n,), optional
        Prior mean, SI (default 0).
    q : float or array_like (n,)
        Process noise (see the module docstring). Default 0.
    sample_rate : float, optional
        Sample rate, Hz, used for the history time and dt when :meth:`update` gets no sample times.
    model : ModelSpec, optional
        The error model (default: the accelerometer model).
    """

    def __init__(
        self,
        r_var: ArrayLike,
        p0: ArrayLike,
        x0: ArrayLike | None = None,
        *,
        q: float | ArrayLike = 0.0,
        sample_rate: float | None = None,
        model: ModelSpec | None = None,
    ) -> None:
        self.model = m = resolve(model)
        n_p = m.n_params
        self.r_var = m.as_noise_variance(r_var)
        p = np.asarray(p0, dtype=float)
        if p.shape != (n_p, n_p) or not np.all(np.isfinite(p)):
            raise ValueError(f"prior covariance p0 must be a finite ({n_p}, {n_p}) matrix, got {p.shape}")
        if np.any(np.diag(p) <= 0.0):
            raise ValueError("prior covariance p0 must have positive variances (a KF needs a proper prior)")
        self._scale = np.sqrt(np.diag(p))
        p_s = p / np.outer(self._scale, self._scale)
        try:
            np.linalg.cholesky(p_s)
        except np.linalg.LinAlgError as exc:
            raise ValueError("prior covariance p0 must be symmetric positive definite") from exc
        xm = np.zeros(n_p) if x0 is None else m.as_state(x0, "x0")
        q_arr = np.asarray(q, dtype=float)
        if q_arr.ndim == 0:
            self._q_s = np.full(n_p, float(q_arr))
        elif q_arr.shape == (n_p,):
            self._q_s = q_arr / self._scale**2
        else:
            raise ValueError(f"q must be a scalar or have {n_p} entries")
        if not np.all(np.isfinite(self._q_s)) or np.any(self._q_s < 0):
            raise ValueError("process noise q must be finite and >= 0")
        if sample_rate is not None and not (np.isfinite(sample_rate) and sample_rate > 0):
            raise ValueError(f"sample_rate must be > 0 Hz, got {sample_rate}")
        self.sample_rate = sample_rate
        kf = kalman_filter_class()(dim_x=n_p, dim_z=n_p)  # filterpy's, without filterpy.stats
        kf.x = (xm / self._scale).reshape(n_p, 1)
        kf.P = 0.5 * (p_s + p_s.T)
        kf.F = np.eye(n_p)
        kf.Q = np.zeros((n_p, n_p))
        kf.R = np.eye(n_p)
        self._kf = kf
        self._x0 = xm.copy()
        self._info = np.zeros((n_p, n_p))
        self._grams: dict[str, NDArray[np.float64]] = {}
        self._x_before: dict[str, NDArray[np.float64]] = {}
        self.history: list[StepRecord] = []
        self._n_total = 0
        self._t_last: float | None = None

    # ------------------------------------------------------------------ feeding
    def update(
        self,
        f_out: ArrayLike,
        f_ref: ArrayLike,
        omega: ArrayLike,
        step: str,
        t: ArrayLike | None = None,
        earth: ArrayLike | None = None,
    ) -> None:
        """Fuse a block of samples (exactly, one filter update).

        Parameters
        ----------
        f_out : array_like (n, n_axes), or a tuple of arrays (n, k_i)
            Sensor output (the model's channels side by side: accelerometer m/s², gyro rad/s), body frame; as a
            tuple, the arrays whose columns side by side are that output (each triad's output as read, not
            copied into one array).
        f_ref : array_like (n, 3)
            Reference specific force from the table attitude and local g, body frame, m/s².
        omega : array_like (n, 3)
            Body angular rate from the table, body frame, rad/s.
        step : str
            Label of the procedure step the samples belong to (residual statistics are kept per label;
            several blocks may share a label).
        t : array_like (n,), optional
            Sample times, s (for the history and the process-noise dt).
        earth : array_like (n, 3), optional
            Earth rate in the body frame, rad/s (the gyro reference ω_ib = omega + earth; None = 0).
        """
        m = self.model
        fos = [np.asarray(a, dtype=float) for a in (f_out if is_output_columns(f_out) else (f_out,))]
        fr = np.asarray(f_ref, dtype=float)
        om = np.asarray(omega, dtype=float)
        n = fos[0].shape[0] if fos[0].ndim == 2 else -1
        ea = None if earth is None else np.asarray(earth, dtype=float)
        if (
            any(a.ndim != 2 or a.shape[0] != n for a in fos) or sum(a.shape[1] for a in fos) != m.n_axes
            or fr.shape != (n, 3) or om.shape != (n, 3) or (ea is not None and ea.shape != (n, 3))
        ):  # fmt: skip
            shapes = fos[0].shape if len(fos) == 1 else [a.shape for a in fos]
            raise ValueError(
                f"step {step!r}: f_out, f_ref and omega must have shapes (n, {m.n_axes}), (n, 3), (n, 3); "
                f"got {shapes}, {fr.shape}, {om.shape}"
            )
        if n == 0:
            return
        if not all(np.isfinite(np.min(a)) and np.isfinite(np.max(a)) for a in (*fos, fr, om)):  # NaN, ±inf
            raise ValueError(f"step {step!r}: non-finite samples; drop or interpolate them before identification")
        t_end = self._block_end_time(n, t, step)
        dt = 0.0 if (self._t_last is None or not np.isfinite(t_end)) else max(t_end - self._t_last, 0.0)
        fo = tuple(fos) if len(fos) > 1 else fos[0]
        gram = m.regressor_gram(fr, om, earth=ea, y=fo)  # z = fo − ideal formed in the Gram's blocks
        info, eta = m.information_from_gram(gram, self.r_var)
        assert eta is not None
        if step not in self._grams:
            self._grams[step] = np.zeros_like(gram)
            self._x_before[step] = self.estimate
        self._grams[step] += gram
        self._info += info
        kf = self._kf
        if np.any(self._q_s > 0.0) and dt > 0.0:
            kf.predict(Q=np.diag(self._q_s * dt))
        h_p, z_p = self._pseudo_measurement(info, eta)
        kf.update(z_p, R=np.eye(m.n_params), H=h_p)
        kf.P = 0.5 * (kf.P + kf.P.T)
        self._n_total += n
        if np.isfinite(t_end):
            self._t_last = t_end
        self.history.append(StepRecord(step, float(t_end), n, self.estimate, self.sigma))

    def _block_end_time(self, n: int, t: ArrayLike | None, step: str) -> float:
        if t is not None:
            tt = np.asarray(t, dtype=float).reshape(-1)
            if tt.shape != (n,):
                raise ValueError(f"step {step!r}: t must have one time per sample ({n}), got {tt.size}")
            return float(tt[-1])
        if self.sample_rate is not None:
            return (self._n_total + n) / self.sample_rate
        return float("nan")

    def _pseudo_measurement(
        self, info: NDArray[np.float64], eta: NDArray[np.float64]
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Whitened 18-row pseudo-measurement with exactly the information (Λ, η), in the scaled state."""
        s = self._scale
        lam_s = info * np.outer(s, s)
        eta_s = eta * s
        ev, vec = np.linalg.eigh(0.5 * (lam_s + lam_s.T))
        ev = np.clip(ev, 0.0, None)
        root = np.sqrt(ev)
        h_p = root[:, None] * vec.T
        proj = vec.T @ eta_s
        z_p = np.divide(proj, root, out=np.zeros_like(proj), where=root > 0.0)
        return h_p, z_p.reshape(-1, 1)

    # ------------------------------------------------------------------ results
    @property
    def estimate(self) -> NDArray[np.float64]:
        """Current estimate x̂ (n,), SI, in the model's name order."""
        return self._kf.x.reshape(-1) * self._scale

    @property
    def covariance(self) -> NDArray[np.float64]:
        """Current covariance P (n, n), SI."""
        return self._kf.P * np.outer(self._scale, self._scale)

    @property
    def sigma(self) -> NDArray[np.float64]:
        """Current 1σ (n,), SI."""
        return np.sqrt(np.clip(np.diag(self._kf.P), 0.0, None)) * self._scale

    @property
    def information(self) -> NDArray[np.float64]:
        """Accumulated data information Σ HᵀR⁻¹H (n, n), SI (without the prior)."""
        return self._info.copy()

    @property
    def n_samples(self) -> int:
        """Number of samples fused so far."""
        return self._n_total

    def rank_and_condition(self) -> tuple[int, float]:
        """Numerical rank and condition of the accumulated data information (see :mod:`.batch`)."""
        return information_rank(self._info, self.r_var, model=self.model)

    def residual_statistics(self, x: ArrayLike | None = None, *, prior: bool = False) -> dict[str, ResidualStats]:
        """Per-step residual statistics of z − H x, exact, from the stored per-step sums (no samples kept).

        Parameters
        ----------
        x : array_like (n,), optional
            Parameters to evaluate the residual with; default the current (final) estimate.
        prior : bool
            If True, use for each step the estimate held *before* its first block (innovation statistics).
        """
        out: dict[str, ResidualStats] = {}
        xs = self.estimate if x is None else self.model.as_state(x)
        for step, gram in self._grams.items():
            count, mean, rms = self.model.residual_moments(gram, self._x_before[step] if prior else xs)
            out[step] = ResidualStats(int(round(count)), mean, rms)
        return out

    def nees(self, truth: ArrayLike) -> float:
        """Normalised estimation error squared (x̂ − x)ᵀ P⁻¹ (x̂ − x) against known truth x (SI, n)."""
        e_s = (self.estimate - self.model.as_state(truth, "truth")) / self._scale
        return float(e_s @ np.linalg.solve(self._kf.P, e_s))


def estimate_measurement_noise(f_out_static: ArrayLike, method: str = "detrend") -> NDArray[np.float64]:
    """Per-axis white-noise variance per sample, SI², from a static record (e.g. the warm-up hold).

    Parameters
    ----------
    f_out_static : array_like (n, k)
        Sensor output at rest, body frame (accelerometer m/s², gyro rad/s; n ≥ 10).
    method : {"detrend", "difference"}
        ``"detrend"``: variance about a per-axis straight-line fit (robust to a linear warm-up drift; the
        per-sample variance the filter's R means). ``"difference"``: var(Δf)/2, insensitive to any slow
        drift but biased low when the output is low-pass filtered (correlated adjacent samples).
    """
    f = np.asarray(f_out_static, dtype=float)
    if f.ndim != 2 or f.shape[1] < 1:
        raise ValueError(f"static record must have shape (n, axes), got {f.shape}")
    n = f.shape[0]
    if n < 10:
        raise ValueError(f"static record too short to estimate noise: {n} samples (need at least 10)")
    if not np.all(np.isfinite(f)):
        raise ValueError("static record contains non-finite samples")
    if method == "difference":
        return np.var(np.diff(f, axis=0), axis=0, ddof=1) / 2.0
    if method == "detrend":
        tt = np.linspace(-1.0, 1.0, n)
        a = np.column_stack([np.ones(n), tt])
        coef, *_ = np.linalg.lstsq(a, f, rcond=None)
        res = f - a @ coef
        return np.sum(res**2, axis=0) / (n - 2)
    raise ValueError(f"unknown method {method!r}; use 'detrend' or 'difference'")


__all__ = ["ResidualStats", "StepRecord", "StreamingIdentifier", "estimate_measurement_noise"]
