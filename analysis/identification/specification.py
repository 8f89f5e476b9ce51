"""Model specification: what an identification needs to know about a sensor-error model, in one object.

After statsmodels' ``tsa/arima/specification.py``: the estimators (Kalman filter, batch least squares, plan,
uncertainty budget) and the calibration result take a :class:`ModelSpec` and never import a model's
constants. A model states

* its parameter **names**, quantity **kinds** (keys of :data:`analysis.units.DISPLAY_UNITS`, which give the
  display unit) and SI unit per kind;
* its **blocks**: the measurement has ``n_axes`` components (three per sensor triad); component i depends
  only on the parameters ``axis_params[i]``, with regressors taken from a small set of **base regressors**
  at the columns ``axis_base[i]`` — so the information matrix is block diagonal per axis and every sum the
  estimators need is a sub-block of the Gram matrix of the base regressors and the measurement;
* its **regressors**: :meth:`ModelSpec.fill_base` writes the base regressors of a chunk of samples from the
  reference (body frame, SI): the specific force ``f`` (m/s²), the table's body rate relative to the local
  level frame ``omega`` (rad/s), and the Earth rate in the body frame ``earth`` (rad/s, may be None = 0);
* the **reference output** (:meth:`ModelSpec.ideal`, what an error-free sensor reads), the forward model
  (:meth:`ModelSpec.predict`) and its exact inverse (:meth:`ModelSpec.correct`).

Everything generic — the design matrix, the chunked Gram, the information pair, residual moments, display
conversion, priors by kind — lives here, once. A composite (:class:`UnitModel`) joins the models of the
triads of one unit into one identification: one state vector, one reference, one time base; its Gram is
the block diagonal of the parts' Grams (they share no parameter), so the cost is the sum of the parts'.

A new model is a module defining a :class:`ModelSpec` subclass instance plus one line in
:data:`MODEL_MODULES` (its registration); :func:`get_model` finds it by name. See ``docs/methods/``.
"""

from __future__ import annotations

import importlib
from collections.abc import Mapping, Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray

from analysis.columns import side_by_side
from analysis.units import DISPLAY_UNITS

MODEL_MODULES: dict[str, str] = {
    "accelerometer": "analysis.identification.model",
    "gyro": "analysis.identification.gyro",
}
"""Registration: model name → the module that defines (and :func:`register` s) it."""

_REGISTRY: dict[str, ModelSpec] = {}


def as_n3(a: ArrayLike | None, name: str, n: int | None = None) -> NDArray[np.float64]:
    """Validate a per-sample body-frame vector array (n, 3); a (3,) vector is one sample; None → zeros(n, 3)."""
    if a is None:
        return np.zeros((0 if n is None else n, 3))
    arr = np.asarray(a, dtype=float)
    if arr.ndim == 1 and arr.shape == (3,):
        arr = arr[None, :]
    if arr.ndim != 2 or arr.shape[1] != 3:
        raise ValueError(f"{name} must have shape (n, 3) (one body-frame vector per sample), got {arr.shape}")
    if n is not None and arr.shape[0] != n:
        raise ValueError(f"{name} must have {n} samples, got {arr.shape[0]}")
    return arr


class ModelSpec:
    """A sensor-error model for identification (see the module docstring).

    Subclasses set the class or instance attributes ``name``, ``output``, ``names``, ``kinds``,
    ``si_units``, ``kind_labels``, ``axis_params``, ``axis_base``, ``n_base``, ``reference_scale``,
    ``equation`` and implement :meth:`fill_base`, :meth:`ideal`, :meth:`predict` and :meth:`correct`.
    """

    name: str = ""
    output: str = ""  # the recording's channel ("accel", "gyro")
    names: tuple[str, ...] = ()
    kinds: tuple[str, ...] = ()
    si_units: Mapping[str, str] = {}
    kind_labels: Mapping[str, str] = {}
    axis_params: tuple[tuple[int, ...], ...] = ()
    axis_base: tuple[tuple[int, ...], ...] = ()
    n_base: int = 0
    reference_scale: NDArray[np.float64] = np.zeros(0)
    equation: str = ""
    unobservable_fix: Mapping[str, str] = {}
    """Per kind: what motion makes it observable (plain words, for the plan's warnings)."""
    rate_power: Mapping[str, int] = {}
    """Per kind: p when its σ from spins scales as 1/ω^p at a fixed spin time (the plan's rate advice)."""

    # ---- derived sizes and tables --------------------------------------------------------------------------------
    @property
    def n_params(self) -> int:
        """Number of states."""
        return len(self.names)

    @property
    def n_axes(self) -> int:
        """Number of measurement components (3 per triad)."""
        return len(self.axis_params)

    @property
    def param_axis(self) -> NDArray[np.int64]:
        """Measurement axis of each state."""
        out = np.empty(self.n_params, dtype=np.int64)
        for i, idx in enumerate(self.axis_params):
            out[list(idx)] = i
        return out

    @property
    def groups(self) -> tuple[slice, ...]:
        """State slices of the parts (one for a single triad): ranks are judged part by part."""
        return (slice(0, self.n_params),)

    @property
    def parts(self) -> tuple[ModelSpec, ...]:
        """The single-triad models this one is made of (itself for a single triad)."""
        return (self,)

    def layout(self, with_z: bool) -> tuple[tuple[tuple[int, ...], ...], tuple[int, ...], tuple[int, ...]]:
        """Gram columns per axis: (base columns, measurement column, constant column) for a Gram with/without z."""
        return self.axis_base, tuple(self.n_base + i for i in range(self.n_axes)), (0,) * self.n_axes

    def gram_size(self, with_z: bool) -> int:
        """Side of the Gram matrix :meth:`regressor_gram` returns."""
        return self.n_base + (self.n_axes if with_z else 0)

    def index(self, name: str) -> int:
        """State index of a parameter name."""
        return self.names.index(name)

    def display_scale(self) -> NDArray[np.float64]:
        """One display unit of each state, in SI (divide an SI value by it to display)."""
        return np.array([DISPLAY_UNITS[k][1] for k in self.kinds])

    def unique_kinds(self) -> tuple[str, ...]:
        """The kinds in state order, each once."""
        return tuple(dict.fromkeys(self.kinds))

    # ---- the model proper (subclasses) --------------------------------------------------------------------------
    def fill_base(
        self,
        out: NDArray[np.float64],
        f: NDArray[np.float64],
        omega: NDArray[np.float64],
        earth: NDArray[np.float64] | None,
    ) -> None:
        """Write the base regressors of a chunk (m, n_base) into ``out`` (body frame, SI)."""
        raise NotImplementedError

    def ideal(self, f: ArrayLike, omega: ArrayLike, earth: ArrayLike | None = None) -> NDArray[np.float64]:
        """What an error-free sensor reads for the reference (n, n_axes), SI."""
        raise NotImplementedError

    def fill_measurement(
        self,
        out: NDArray[np.float64],
        y: NDArray[np.float64],
        f: NDArray[np.float64],
        omega: NDArray[np.float64],
        earth: NDArray[np.float64] | None,
        base: NDArray[np.float64],
    ) -> None:
        """Write z = y − :meth:`ideal` of a chunk (m, n_axes) into ``out``, column by column (SI); ``base``: the
        chunk's regressors as :meth:`fill_base` wrote them (a model whose ideal output is among them takes it
        from there, the same values)."""
        ideal = self.ideal(f, omega, earth)
        for k in range(self.n_axes):
            np.subtract(y[:, k], ideal[:, k], out=out[:, k])

    def predict(
        self, x: ArrayLike, f: ArrayLike, omega: ArrayLike, earth: ArrayLike | None = None
    ) -> NDArray[np.float64]:
        """Modelled output (n, n_axes) for parameters x and the reference, SI."""
        ff = as_n3(f, "f")
        h = self.design_matrix(ff, omega, earth)
        return self.ideal(ff, omega, earth) + np.einsum("nij,j->ni", h, self.as_state(x))

    def correct(
        self, x: ArrayLike, y: ArrayLike, f: ArrayLike, omega: ArrayLike, earth: ArrayLike | None = None
    ) -> NDArray[np.float64]:
        """The exact inverse of :meth:`predict`: the true quantity that produces the output y."""
        raise NotImplementedError

    # ---- reference-error shapes (for the uncertainty budget) -------------------------------------------------------
    def attitude_vectors(self, f: ArrayLike, omega: ArrayLike, earth: ArrayLike | None = None) -> NDArray[np.float64]:
        """Per triad, the body-frame vector whose direction the reference takes from the table attitude (m, t, 3).

        A nav-frame tilt δφ moves it by [v×] C_n^b δφ (the accelerometer's f; the gyro's Earth rate).
        """
        ff = as_n3(f, "f")
        return np.zeros((ff.shape[0], self.n_axes // 3, 3))

    def gravity_shape(self, f: ArrayLike, omega: ArrayLike, g: float) -> NDArray[np.float64]:
        """∂(y_ref)/∂g per sample (m, n_axes, 1): how a local-g error enters the measurement equation."""
        ff = as_n3(f, "f")
        return np.zeros((ff.shape[0], self.n_axes, 1))

    # ---- validation ----------------------------------------------------------------------------------------------
    def as_state(self, x: ArrayLike, name: str = "x") -> NDArray[np.float64]:
        """Validate a state vector: (n_params,), finite, SI, in :attr:`names` order."""
        arr = np.asarray(x, dtype=float).reshape(-1)
        if arr.shape != (self.n_params,):
            raise ValueError(f"{name} must have {self.n_params} entries ({', '.join(self.names)}), got {arr.size}")
        if not np.all(np.isfinite(arr)):
            raise ValueError(f"{name} contains non-finite values")
        return arr

    def as_noise_variance(self, r_var: ArrayLike) -> NDArray[np.float64]:
        """Validate per-axis white-noise variances (n_axes,) per sample, SI²; a scalar applies to all axes."""
        try:
            r = np.broadcast_to(np.asarray(r_var, dtype=float), (self.n_axes,)).copy()
        except ValueError:
            raise ValueError(
                f"measurement noise variance must have {self.n_axes} entries (one per axis), got {np.shape(r_var)}"
            ) from None
        if not np.all(np.isfinite(r)) or np.any(r <= 0.0):
            raise ValueError(f"measurement noise variance must be finite and > 0 per axis, got {r}")
        return r

    def as_output(self, y: ArrayLike, name: str = "output") -> NDArray[np.float64]:
        """Validate a sensor output array (n, n_axes)."""
        arr = np.asarray(y, dtype=float)
        if arr.ndim != 2 or arr.shape[1] != self.n_axes:
            raise ValueError(f"{name} must have shape (n, {self.n_axes}), got {arr.shape}")
        return arr

    # ---- regressors ---------------------------------------------------------------------------------------------
    def base_regressors(self, f: ArrayLike, omega: ArrayLike, earth: ArrayLike | None = None) -> NDArray[np.float64]:
        """Base regressors (n, n_base), body frame, SI."""
        ff = as_n3(f, "f")
        om = as_n3(omega, "omega", ff.shape[0])
        ea = None if earth is None else as_n3(earth, "earth", ff.shape[0])
        out = np.empty((ff.shape[0], self.n_base))
        self.fill_base(out, ff, om, ea)
        return out

    def design_matrix(self, f: ArrayLike, omega: ArrayLike, earth: ArrayLike | None = None) -> NDArray[np.float64]:
        """Measurement matrix H (n, n_axes, n_params) of z = y − ideal = H x, derived from the model."""
        base = self.base_regressors(f, omega, earth)
        h = np.zeros((base.shape[0], self.n_axes, self.n_params))
        cols, _, _ = self.layout(False)
        for i in range(self.n_axes):
            h[:, i, list(self.axis_params[i])] = base[:, list(cols[i])]
        return h

    def regressor_gram(
        self,
        f: ArrayLike,
        omega: ArrayLike,
        z: ArrayLike | None = None,
        weights: ArrayLike | None = None,
        *,
        earth: ArrayLike | None = None,
        chunk: int = 1 << 17,
        y: ArrayLike | None = None,
    ) -> NDArray[np.float64]:
        """Weighted Gram ``Σ_n w_n a_n a_nᵀ`` of the base regressors and (optionally) the measurement z.

        Computed in chunks with one matrix product each, so memory stays bounded for 10⁷ samples. Row and
        column 0 hold the plain sums (the base regressor 0 is the constant 1). ``y``: the sensor output
        (n, n_axes) instead of z: z = y − :meth:`ideal` is formed in each chunk's block (the same values as
        passing z; :meth:`fill_measurement`); or a tuple of numpy arrays (n, k_i) whose columns side by side are
        that output (a unit's accelerometer and gyro outputs as read, without copying them into one array).
        """
        ff = as_n3(f, "f")
        n = ff.shape[0]
        om = as_n3(omega, "omega")
        if om.shape[0] != n:
            raise ValueError(f"f and omega must have the same number of samples, got {n} and {om.shape[0]}")
        ea = None if earth is None else as_n3(earth, "earth", n)
        if z is not None and y is not None:
            raise ValueError("give the measurement z or the output y, not both")
        zz: NDArray[np.float64] | list[NDArray[np.float64]] | None = None
        if is_output_columns(y):
            zz = output_columns(y, n, self.n_axes)
        elif z is not None or y is not None:
            zz = np.asarray(z if y is None else y, dtype=float)
            if zz.ndim != 2 or zz.shape[1] != self.n_axes or zz.shape[0] != n:
                lab = "z" if y is None else "y"
                raise ValueError(f"{lab} must have shape ({n}, {self.n_axes}), got {zz.shape}")
        w = _weights(weights, n)
        return self._gram(ff, om, ea, zz, w, chunk, y is not None)

    def _gram(
        self,
        ff: NDArray[np.float64],
        om: NDArray[np.float64],
        ea: NDArray[np.float64] | None,
        zz: NDArray[np.float64] | None,
        w: NDArray[np.float64] | None,
        chunk: int,
        output: bool = False,
    ) -> NDArray[np.float64]:
        """The Gram (see :meth:`regressor_gram`); ``output``: ``zz`` is the sensor output y, not z (one array, or
        the arrays whose columns side by side are y)."""
        if isinstance(zz, list):
            zz = zz[0] if len(zz) == 1 else side_by_side(zz)
        n = ff.shape[0]
        nb = self.n_base
        ncol = self.gram_size(zz is not None)
        gram = np.zeros((ncol, ncol))
        a = np.empty((min(chunk, max(n, 1)), ncol))
        for s in range(0, n, chunk):
            e = min(n, s + chunk)
            blk = a[: e - s]
            ec = None if ea is None else ea[s:e]
            self.fill_base(blk[:, :nb], ff[s:e], om[s:e], ec)
            if zz is not None and output:
                self.fill_measurement(blk[:, nb:], zz[s:e], ff[s:e], om[s:e], ec, blk[:, :nb])
            elif zz is not None:
                for k in range(ncol - nb):  # column by column (an (n, 3) copy into the wide block is 3× slower)
                    blk[:, nb + k] = zz[s:e, k]
            if w is None:
                gram += blk.T @ blk
            else:
                gram += (blk * w[s:e, None]).T @ blk
        return gram

    # ---- information --------------------------------------------------------------------------------------------
    def information_from_gram(
        self, gram: NDArray[np.float64], r_var: ArrayLike
    ) -> tuple[NDArray[np.float64], NDArray[np.float64] | None]:
        """Data information Λ = Σ HᵀR⁻¹H and η = Σ HᵀR⁻¹z from a :meth:`regressor_gram` (η None without z)."""
        r = self.as_noise_variance(r_var)
        with_z = gram.shape[0] == self.gram_size(True)
        info = np.zeros((self.n_params, self.n_params))
        eta = np.zeros(self.n_params) if with_z else None
        idx = self._information_index(with_z)
        if idx is not None:  # one gather per matrix: the same quotients gram[q, q'] / r[i], element by element
            pi, pj, qi, qj, ai, ep, eq, ez, ea = idx
            info[pi, pj] = gram[qi, qj] / r[ai]
            if eta is not None:
                eta[ep] = gram[eq, ez] / r[ea]
            return info, eta
        cols, zc, _ = self.layout(with_z)
        for i in range(self.n_axes):
            p = list(self.axis_params[i])
            q = list(cols[i])
            info[np.ix_(p, p)] = gram[np.ix_(q, q)] / r[i]
            if eta is not None:
                eta[p] = gram[q, zc[i]] / r[i]
        return info, eta

    def _information_index(self, with_z: bool) -> tuple[NDArray[np.int64], ...] | None:
        """Flat indices for :meth:`information_from_gram`, formed once per layout (None when two axes share a state:
        the axis-by-axis loop keeps its order of assignment there).

        (info rows, info columns, Gram rows, Gram columns, axis) of every Λ entry Λ[p, p'] = Gram[q, q'] / r[axis]
        and (state, Gram row, z column, axis) of every η entry η[p] = Gram[q, z] / r[axis]; the same quotients as
        the loop's ``np.ix_`` blocks (a test compares them bit for bit), without its ~20 small numpy calls per
        axis on each of the filter's windows."""
        key = (with_z, self.axis_params, self.axis_base, self.n_base)
        cache: dict[object, tuple[NDArray[np.int64], ...] | None] = self.__dict__.setdefault("_info_index_cache", {})
        if key in cache:
            return cache[key]
        cols, zc, _ = self.layout(with_z)
        flat = [k for ax in self.axis_params for k in ax]
        out: tuple[NDArray[np.int64], ...] | None = None
        if len(set(flat)) == len(flat):
            lam: list[list[int]] = [[], [], [], [], []]
            et: list[list[int]] = [[], [], [], []]
            for i, (p, q) in enumerate(zip(self.axis_params, cols, strict=True)):
                for a in range(len(p)):
                    for b in range(len(p)):
                        for lst, v in zip(lam, (p[a], p[b], q[a], q[b], i), strict=True):
                            lst.append(v)
                    for lst, v in zip(et, (p[a], q[a], zc[i] if with_z else 0, i), strict=True):
                        lst.append(v)
            out = tuple(np.array(v, dtype=np.int64) for v in lam + et)
        cache[key] = out
        return out

    def offset_gains(self, gram: NDArray[np.float64], r_var: ArrayLike) -> NDArray[np.float64]:
        """G = Σ_n w_n H_nᵀ R⁻¹ (n_params, n_axes): the effect of a constant error per axis on η."""
        r = self.as_noise_variance(r_var)
        cols, _, one = self.layout(gram.shape[0] == self.gram_size(True))
        out = np.zeros((self.n_params, self.n_axes))
        for i in range(self.n_axes):
            out[list(self.axis_params[i]), i] = gram[one[i], list(cols[i])] / r[i]
        return out

    def residual_moments(
        self, gram: NDArray[np.float64], x: ArrayLike
    ) -> tuple[float, NDArray[np.float64], NDArray[np.float64]]:
        """Count, per-axis mean and RMS of the residual e = z − H x, exactly, from a Gram with z."""
        xs = self.as_state(x)
        cols, zc, one = self.layout(True)
        count = float(gram[0, 0])
        mean = np.zeros(self.n_axes)
        rms = np.zeros(self.n_axes)
        if count <= 0:
            return 0.0, np.full(self.n_axes, np.nan), np.full(self.n_axes, np.nan)
        for i in range(self.n_axes):
            q = [*cols[i], zc[i]]
            v = np.append(-xs[list(self.axis_params[i])], 1.0)
            sub = gram[np.ix_(q, q)]
            mean[i] = float(gram[one[i], q] @ v) / count
            rms[i] = np.sqrt(max(float(v @ sub @ v), 0.0) / count)
        return count, mean, rms

    # ---- display ------------------------------------------------------------------------------------------------
    def to_display(self, x: ArrayLike) -> NDArray[np.float64]:
        """State (or 1σ) vector in SI → display units per kind."""
        xs = np.asarray(x, dtype=float).reshape(-1)
        if xs.shape != (self.n_params,):
            raise ValueError(f"expected {self.n_params} values, got {xs.size}")
        return xs / self.display_scale()

    def from_display(self, x_display: ArrayLike) -> NDArray[np.float64]:
        """State (or 1σ) vector in display units → SI."""
        xs = np.asarray(x_display, dtype=float).reshape(-1)
        if xs.shape != (self.n_params,):
            raise ValueError(f"expected {self.n_params} values, got {xs.size}")
        return xs * self.display_scale()

    def display_units(self) -> tuple[str, ...]:
        """Display unit label of each state."""
        return tuple(DISPLAY_UNITS[k][0] for k in self.kinds)

    def sigma_from_display(self, values: Mapping[str, float]) -> NDArray[np.float64]:
        """Per-parameter SI values (e.g. prior 1σ) from display-unit values given per kind or per name.

        ``values`` maps a kind or a parameter name (overrides its kind) to a value in that kind's display
        unit; every parameter must be covered.
        """
        out = np.full(self.n_params, np.nan)
        unknown = set(values) - set(self.kinds) - set(self.names)
        if unknown:
            raise ValueError(f"unknown parameter kinds/names {sorted(unknown)}; use {sorted(set(self.kinds))}")
        for k, (name, kind) in enumerate(zip(self.names, self.kinds, strict=True)):
            v = values.get(name, values.get(kind))
            if v is not None:
                out[k] = float(v) * DISPLAY_UNITS[kind][1]
        missing = [n for n, v in zip(self.names, out, strict=True) if not np.isfinite(v)]
        if missing:
            raise ValueError(f"no value given for {', '.join(missing)} (give it by kind or by name)")
        return out

    def __repr__(self) -> str:
        return f"<model {self.name!r}: {self.n_params} states, {self.n_axes} axes>"


def is_output_columns(y: object) -> bool:
    """Whether a sensor output is given as a tuple of numpy arrays whose columns side by side are the model's
    channels (:func:`output_columns`), not as one array_like (a nested list is one array)."""
    return isinstance(y, tuple) and len(y) > 0 and all(isinstance(a, np.ndarray) for a in y)


def output_columns(y: Sequence[ArrayLike], n: int, n_axes: int) -> list[NDArray[np.float64]]:
    """A sensor output given as arrays (n, k_i) whose columns side by side are the model's n_axes channels (a
    unit's accelerometer and gyro outputs as read): the arrays as float, checked; ``ValueError`` naming the shapes.
    """
    arrs = [np.asarray(a, dtype=float) for a in y]
    if not arrs or any(a.ndim != 2 or a.shape[0] != n for a in arrs) or sum(a.shape[1] for a in arrs) != n_axes:
        raise ValueError(
            f"y must be arrays of {n} rows whose columns side by side are the model's {n_axes} channels, got "
            f"shapes {[a.shape for a in arrs]}"
        )
    return arrs


def _weights(weights: ArrayLike | None, n: int) -> NDArray[np.float64] | None:
    if weights is None:
        return None
    w = np.asarray(weights, dtype=float).reshape(-1)
    if w.shape != (n,) or not np.all(np.isfinite(w)) or np.any(w < 0):
        raise ValueError(f"weights must be {n} finite non-negative sample counts")
    return w


class UnitModel(ModelSpec):
    """Several triads' models identified together: one state vector [part 1 | part 2 | …], one reference.

    The measurement is the parts' outputs side by side (n, Σ n_axes); the Gram is block diagonal in the
    parts (each block is the part's own Gram with its own measurement columns), so the cost is the sum of
    the parts' costs and the accelerometer block is bit-for-bit the accelerometer model's own.
    """

    def __init__(self, parts: Sequence[ModelSpec]) -> None:
        if not parts:
            raise ValueError("a unit model needs at least one part")
        self._parts = tuple(parts)
        self.name = "+".join(p.name for p in parts)
        self.output = "+".join(p.output for p in parts)
        self.names = tuple(n for p in parts for n in p.names)
        if len(set(self.names)) != len(self.names):
            raise ValueError(f"the parts of {self.name} share parameter names")
        self.kinds = tuple(k for p in parts for k in p.kinds)
        self.si_units = {k: v for p in parts for k, v in p.si_units.items()}
        self.kind_labels = {k: v for p in parts for k, v in p.kind_labels.items()}
        self.unobservable_fix = {k: v for p in parts for k, v in p.unobservable_fix.items()}
        self.rate_power = {k: v for p in parts for k, v in p.rate_power.items()}
        self.equation = "; ".join(p.equation for p in parts)
        self.reference_scale = np.concatenate([p.reference_scale for p in parts])
        p_off = np.cumsum([0] + [p.n_params for p in parts])
        self._p_off = p_off
        self.axis_params = tuple(
            tuple(int(o) + k for k in ax) for p, o in zip(parts, p_off, strict=False) for ax in p.axis_params
        )
        self.n_base = sum(p.n_base for p in parts)
        b_off = np.cumsum([0] + [p.n_base for p in parts])
        self.axis_base = tuple(
            tuple(int(o) + k for k in ax) for p, o in zip(parts, b_off, strict=False) for ax in p.axis_base
        )

    @property
    def parts(self) -> tuple[ModelSpec, ...]:
        return self._parts

    @property
    def groups(self) -> tuple[slice, ...]:
        return tuple(slice(int(a), int(b)) for a, b in zip(self._p_off[:-1], self._p_off[1:], strict=True))

    def _axis_offsets(self) -> NDArray[np.int64]:
        return np.cumsum([0] + [p.n_axes for p in self._parts])

    def gram_size(self, with_z: bool) -> int:
        return sum(p.gram_size(with_z) for p in self._parts)

    def layout(self, with_z: bool) -> tuple[tuple[tuple[int, ...], ...], tuple[int, ...], tuple[int, ...]]:
        cols: list[tuple[int, ...]] = []
        zc: list[int] = []
        one: list[int] = []
        off = 0
        for p in self._parts:
            pc, pz, po = p.layout(with_z)
            cols += [tuple(off + k for k in ax) for ax in pc]
            zc += [off + k for k in pz]
            one += [off + k for k in po]
            off += p.gram_size(with_z)
        return tuple(cols), tuple(zc), tuple(one)

    def _split(
        self, a: NDArray[np.float64] | list[NDArray[np.float64]] | None, axis_off: NDArray[np.int64], k: int
    ) -> NDArray[np.float64] | list[NDArray[np.float64]] | None:
        """Part k's columns of ``a``: (n, n_axes) → (n, part k's n_axes); a list of arrays (the output's columns side
        by side, :func:`output_columns`) → the arrays holding exactly part k's columns (no copy when the arrays
        line up with the parts, as a unit's accelerometer and gyro outputs do)."""
        if a is None:
            return None
        lo, hi = int(axis_off[k]), int(axis_off[k + 1])
        if not isinstance(a, list):
            return a[:, lo:hi]
        out, col = [], 0
        for arr in a:
            w = arr.shape[1]
            if col + w > lo and col < hi:  # overlaps the part's columns: those of them it holds
                out.append(arr[:, max(lo - col, 0) : min(hi - col, w)])
            col += w
        return out

    def fill_base(self, out, f, omega, earth) -> None:  # type: ignore[no-untyped-def]
        off = 0
        for p in self._parts:
            p.fill_base(out[:, off : off + p.n_base], f, omega, earth)
            off += p.n_base

    def _gram(self, ff, om, ea, zz, w, chunk, output=False):  # type: ignore[no-untyped-def]
        size = self.gram_size(zz is not None)
        gram = np.zeros((size, size))
        ax = self._axis_offsets()
        off = 0
        for k, p in enumerate(self._parts):
            g = p._gram(ff, om, ea, self._split(zz, ax, k), w, chunk, output)
            m = g.shape[0]
            gram[off : off + m, off : off + m] = g
            off += m
        return gram

    def ideal(self, f: ArrayLike, omega: ArrayLike, earth: ArrayLike | None = None) -> NDArray[np.float64]:
        return side_by_side([p.ideal(f, omega, earth) for p in self._parts])

    def predict(
        self, x: ArrayLike, f: ArrayLike, omega: ArrayLike, earth: ArrayLike | None = None
    ) -> NDArray[np.float64]:
        xs = self.as_state(x)
        return np.concatenate(
            [p.predict(xs[g], f, omega, earth) for p, g in zip(self._parts, self.groups, strict=True)], axis=1
        )

    def correct(
        self, x: ArrayLike, y: ArrayLike, f: ArrayLike, omega: ArrayLike, earth: ArrayLike | None = None
    ) -> NDArray[np.float64]:
        xs = self.as_state(x)
        yy = self.as_output(y)
        ax = self._axis_offsets()
        return np.concatenate(
            [
                p.correct(xs[g], yy[:, ax[k] : ax[k + 1]], f, omega, earth)
                for k, (p, g) in enumerate(zip(self._parts, self.groups, strict=True))
            ],
            axis=1,
        )

    def attitude_vectors(self, f, omega, earth=None):  # type: ignore[no-untyped-def]
        return np.concatenate([p.attitude_vectors(f, omega, earth) for p in self._parts], axis=1)

    def gravity_shape(self, f, omega, g):  # type: ignore[no-untyped-def]
        return np.concatenate([p.gravity_shape(f, omega, g) for p in self._parts], axis=1)

    def correct_outputs(self, x: ArrayLike, y: ArrayLike, *, max_iter: int = 8) -> NDArray[np.float64]:
        """Compensate the unit's outputs alone (no reference): the exact joint inverse, (n, n_axes), SI.

        For accelerometer + gyro: the specific force needs the body rate (size effect) and the gyro rate
        needs the specific force (g-sensitivity), so the two inverses are iterated from the raw gyro rate
        until nothing changes at the rounding level (the coupling is ≲ 1e-6, two or three passes). The
        accelerometer's size effect then uses ω_ib (the Earth rate adds < 1e-8 m/s² to c(ω)).
        """
        xs = self.as_state(x)
        yy = self.as_output(y)
        names = [p.name for p in self._parts]
        if names != ["accelerometer", "gyro"]:
            raise ValueError(f"correct_outputs needs an accelerometer + gyro unit model, got {self.name}")
        acc, gyr = self._parts
        xa, xg = xs[self.groups[0]], xs[self.groups[1]]
        w = yy[:, 3:].copy()
        f = acc.correct(xa, yy[:, :3], None, w)  # type: ignore[arg-type]
        for _ in range(max_iter):
            w_new = gyr.correct(xg, yy[:, 3:], f)  # type: ignore[arg-type]
            f_new = acc.correct(xa, yy[:, :3], None, w_new)  # type: ignore[arg-type]
            done = np.allclose(w_new, w, rtol=1e-15, atol=1e-18) and np.allclose(f_new, f, rtol=1e-15, atol=1e-15)
            w, f = w_new, f_new
            if done:
                break
        return np.hstack([f, w])

    def part(self, name: str) -> tuple[ModelSpec, slice, slice]:
        """The part called ``name`` with its state slice and its measurement-axis slice."""
        ax = self._axis_offsets()
        for k, (p, g) in enumerate(zip(self._parts, self.groups, strict=True)):
            if p.name == name:
                return p, g, slice(int(ax[k]), int(ax[k + 1]))
        raise KeyError(f"{self.name} has no part {name!r}")


# ---- registry ------------------------------------------------------------------------------------------------------


def register(spec: ModelSpec) -> ModelSpec:
    """Register a model instance under its name (called by the model's module at import)."""
    _REGISTRY[spec.name] = spec
    return spec


def get_model(name: str = "accelerometer", **options: object) -> ModelSpec:
    """The registered model called ``name`` (its module is imported on first use).

    Options (e.g. ``full_g=True`` for the gyro) are passed to the module's ``build(**options)`` when it has
    one; without options the registered default instance is returned.
    """
    if name not in MODEL_MODULES:
        raise KeyError(f"unknown model {name!r}; registered: {', '.join(MODEL_MODULES)}")
    mod = importlib.import_module(MODEL_MODULES[name])
    if options:
        return mod.build(**options)  # type: ignore[no-any-return]
    return _REGISTRY[name]


def resolve(model: ModelSpec | None) -> ModelSpec:
    """``model`` itself, or the accelerometer model when None (the estimators' default)."""
    return get_model("accelerometer") if model is None else model


def model_for_names(names: Sequence[str]) -> ModelSpec:
    """The (unit) model whose state names are ``names`` (calibration files name their states)."""
    names = tuple(names)
    acc = get_model("accelerometer")
    if names == acc.names:
        return acc
    if names[: acc.n_params] == acc.names:
        rest = names[acc.n_params :]
        mod = importlib.import_module(MODEL_MODULES["gyro"])
        gyro = mod.model_for_names(rest)
        return UnitModel((acc, gyro))
    raise ValueError(f"no registered model has the states {', '.join(names)}")


__all__ = [
    "MODEL_MODULES",
    "ModelSpec",
    "UnitModel",
    "as_n3",
    "get_model",
    "model_for_names",
    "register",
    "resolve",
]
