"""Identification plan: predicted 1σ per parameter *before* any motion, with plain warnings.

Input: nominal samples of each procedure step (reference specific force and body rate at a few points,
each standing for ``weights`` real samples, and the Earth rate in the body frame for gyro models), the white
noise R, the prior P0, and the unit's bias stability. The model is a
:class:`analysis.identification.specification.ModelSpec` (default: the accelerometer model; body frame,
z = y − y_ref = H x + v + β).

Error model (documented assumption)
-----------------------------------
Besides the white noise v (variance R_i per sample and axis), the output carries an **unmodelled DC offset
β_s per step** — bias instability, thermal drift — constant within a step, independent between steps and
axes, of standard deviation σ_bi (``bias_stability``). Steps are identified by their label: points with
the same label share one offset. This is a first-order model of flicker/drift: the offset that matters is
the *difference* between the steps that separate two parameters (e.g. a static hold and a spin separate
r from b), and an independent offset per step is the honest worst case for that difference. (A common
offset shared by all steps would simply be absorbed by b.)

The estimator is the Kalman/batch solution with prior (:mod:`analysis.identification.batch`),
x̂ = A⁻¹ (P0⁻¹ x0 + Σ HᵀR⁻¹ z) with A = P0⁻¹ + Λ. Its error is

    x̂ − x = A⁻¹ (P0⁻¹ (x0 − x) + Σ HᵀR⁻¹ v) + A⁻¹ Σ_s G_s β_s,      G_s = Σ_{n∈s} w_n H_nᵀ R⁻¹   (18×3)

(G_s is n × n_axes) so the predicted covariance is ``A⁻¹`` (white, the filter's own P) plus the systematic term
``A⁻¹ (Σ_s G_s diag(σ_bi²) G_sᵀ) A⁻¹``, which the filter does not know about (its P is optimistic by
that amount). The same is reported for the data alone (no prior), where the data have full rank.

A parameter is flagged *not identified* when the data cannot observe it (information rank, see
:func:`analysis.identification.batch.information_rank`) or when its predicted total 1σ **from the data alone**
exceeds its magnitude divided by ``min_snr`` (default 3: a parameter of datasheet size must be resolved at
3σ). The data-alone σ is used for the judgement because the posterior σ can never exceed the prior σ: a
parameter the motion does not see would otherwise look "identified to its prior". Magnitudes default to
the prior 1σ (datasheet bounds).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray

from analysis import gimbal
from analysis.identification.batch import information_rank, unobservable_parameters
from analysis.identification.plan_legend import PLAN_LEGEND
from analysis.identification.specification import ModelSpec, resolve
from analysis.units import DEG, DISPLAY_UNITS


@dataclass(frozen=True)
class PlanStep:
    """Nominal samples of one procedure step.

    Attributes
    ----------
    label : str
        Step label (points with the same label share one unmodelled bias offset).
    f_ref : ndarray (m, 3)
        Nominal specific force, body frame, m/s².
    omega : ndarray (m, 3)
        Nominal body angular rate, body frame, rad/s.
    weights : ndarray (m,)
        Number of real samples each point stands for.
    angles : ndarray (m, 3), optional
        Gimbal angles (ψ, θ, γ), rad (for simulation and display; unused by the plan).
    earth : ndarray (m, 3), optional
        Earth rate in the body frame, rad/s (the gyro reference ω_ib = omega + earth; None = 0).
    """

    label: str
    f_ref: NDArray[np.float64]
    omega: NDArray[np.float64]
    weights: NDArray[np.float64]
    angles: NDArray[np.float64] | None = None
    earth: NDArray[np.float64] | None = None

    def __post_init__(self) -> None:
        f = np.asarray(self.f_ref, dtype=float)
        w = np.asarray(self.omega, dtype=float)
        n = np.asarray(self.weights, dtype=float).reshape(-1)
        if f.ndim != 2 or f.shape[1] != 3 or w.shape != f.shape or n.shape != (f.shape[0],):
            raise ValueError(
                f"plan step {self.label!r}: f_ref and omega must be (m, 3) and weights (m,); "
                f"got {f.shape}, {w.shape}, {n.shape}"
            )
        if np.any(n < 0) or not np.all(np.isfinite(n)):
            raise ValueError(f"plan step {self.label!r}: weights must be finite sample counts >= 0")
        object.__setattr__(self, "f_ref", f)
        object.__setattr__(self, "omega", w)
        object.__setattr__(self, "weights", n)


@dataclass(frozen=True)
class IdentificationPlan:
    """Predicted identification accuracy (SI, in the model's name order).

    Attributes
    ----------
    sigma_white, sigma_total : ndarray (n,)
        Predicted 1σ with the prior: white noise only (the filter's own P), and including the
        bias-instability systematic term.
    sigma_data_white, sigma_data_total : ndarray (n,)
        The same from the data alone (no prior); ``inf`` for unobservable parameters. ``sigma_data_total``
        is what the flags judge.
    sigma_prior, magnitudes : ndarray (n,)
        Prior 1σ and the magnitudes the σ are judged against.
    rank, condition : int, float
        Data-information rank and condition (:func:`analysis.identification.batch.information_rank`).
    unidentifiable : tuple of str
        Parameters flagged as not identified.
    warnings : list of str
        Plain-words warnings, each saying what change would fix it.
    covariance_white, covariance_total : ndarray (n, n)
    n_samples : float
        Total real samples the plan stands for.
    max_rate : float
        Largest body rate in the plan, rad/s.
    """

    sigma_white: NDArray[np.float64]
    sigma_total: NDArray[np.float64]
    sigma_data_white: NDArray[np.float64]
    sigma_data_total: NDArray[np.float64]
    sigma_prior: NDArray[np.float64]
    magnitudes: NDArray[np.float64]
    rank: int
    condition: float
    unidentifiable: tuple[str, ...]
    warnings: list[str]
    covariance_white: NDArray[np.float64]
    covariance_total: NDArray[np.float64]
    n_samples: float
    max_rate: float
    min_snr: float = 3.0
    notes: list[str] = field(default_factory=list)
    model: ModelSpec | None = None

    @property
    def names(self) -> tuple[str, ...]:
        """State names, in order."""
        return resolve(self.model).names

    def table(self) -> str:
        """Plain-text table of the prediction in display units."""
        m = resolve(self.model)
        w = max(8, *(len(n) for n in m.names))
        lines = [f"{'param':{w}s} {'unit':7s} {'prior':>10s} {'σ white':>10s} {'σ total':>10s} {'σ data':>10s}  status"]
        for k, name in enumerate(m.names):
            unit, one = DISPLAY_UNITS[m.kinds[k]]
            status = "NOT IDENTIFIED" if name in self.unidentifiable else "ok"
            lines.append(
                f"{name:{w}s} {unit:7s} {self.sigma_prior[k] / one:10.4g} {self.sigma_white[k] / one:10.4g} "
                f"{self.sigma_total[k] / one:10.4g} {self.sigma_data_total[k] / one:10.4g}  {status}"
            )
        lines.append(f"data information rank {self.rank}/{m.n_params}, condition {self.condition:.3g}")
        lines += PLAN_LEGEND
        return "\n".join(lines + self.warnings)




def _fmt(kind: str, value_si: float) -> str:
    unit, one = DISPLAY_UNITS[kind]
    if not math.isfinite(value_si):
        return "∞"
    return f"{value_si / one:.3g} {unit}"


def plan_identification(
    steps: Sequence[PlanStep],
    r_var: ArrayLike,
    p0: ArrayLike,
    bias_stability: float | ArrayLike = 0.0,
    *,
    magnitudes: ArrayLike | None = None,
    min_snr: float = 3.0,
    offset_covariance: ArrayLike | None = None,
    model: ModelSpec | None = None,
) -> IdentificationPlan:
    """Predict the identification accuracy of a procedure before running it.

    Parameters
    ----------
    steps : sequence of PlanStep
        Nominal samples per step (body-frame f_ref, m/s², and ω, rad/s; weights = real samples per point).
    r_var : array_like (n_axes,)
        White-noise variance per sample and measurement axis, SI² (noise density² × sample rate).
    p0 : array_like (n, n)
        Prior covariance, SI (datasheet bounds).
    bias_stability : float or array_like (n_axes,)
        σ_bi, SI: standard deviation of the unmodelled per-step DC offset (module docstring).
    magnitudes : array_like (n,), optional
        Datasheet magnitude of each parameter, SI (default: the prior 1σ).
    min_snr : float
        A parameter counts as identified when σ_total ≤ magnitude / min_snr.
    offset_covariance : array_like (n_axes, K, K), optional
        Covariance of the per-step DC offsets, per measurement axis, over the K distinct step labels in order of
        first appearance (e.g. correlated flicker from :func:`.bias_drift.window_mean_covariance`).
        Replaces the independent-offset model diag(σ_bi²); ``bias_stability`` then only words the warnings.
    model : ModelSpec, optional
        The error model (default: the accelerometer model).
    """
    if not steps:
        raise ValueError("the plan has no steps: give the nominal samples of at least one step")
    mdl = resolve(model)
    n_p, n_ax, r = mdl.n_params, mdl.n_axes, mdl.as_noise_variance(r_var)
    p = np.asarray(p0, dtype=float)
    if p.shape != (n_p, n_p) or np.any(np.diag(p) <= 0) or not np.all(np.isfinite(p)):
        raise ValueError(f"prior covariance p0 must be a finite ({n_p}, {n_p}) matrix with variances > 0")
    sbi = np.broadcast_to(np.asarray(bias_stability, dtype=float), (n_ax,)).copy()
    if np.any(sbi < 0) or not np.all(np.isfinite(sbi)):
        raise ValueError(f"bias_stability must be finite and >= 0 (SI), got {sbi}")
    if not min_snr > 0:
        raise ValueError(f"min_snr must be > 0, got {min_snr}")
    sig_prior = np.sqrt(np.diag(p))
    mag = sig_prior.copy() if magnitudes is None else np.asarray(magnitudes, dtype=float).reshape(-1)
    if mag.shape != (n_p,) or np.any(mag <= 0):
        raise ValueError(f"magnitudes must be {n_p} positive SI values")

    grams: dict[str, NDArray[np.float64]] = {}
    max_rate = 0.0
    for st in steps:
        g = mdl.regressor_gram(st.f_ref, st.omega, weights=st.weights, earth=st.earth)
        grams[st.label] = grams.get(st.label, 0.0) + g
        moving = st.weights > 0
        if np.any(moving):
            max_rate = max(max_rate, float(np.max(np.linalg.norm(st.omega[moving], axis=1))))
    info = np.zeros((n_p, n_p))
    gains = np.zeros((len(grams), n_p, n_ax))
    for idx, g in enumerate(grams.values()):
        info_s, _ = mdl.information_from_gram(g, r)
        info += info_s
        gains[idx] = mdl.offset_gains(g, r)
    if offset_covariance is None:
        sys_info = sum(((gs * sbi**2) @ gs.T for gs in gains), np.zeros((n_p, n_p)))
    else:
        c_off = np.asarray(offset_covariance, dtype=float)
        if c_off.shape != (n_ax, len(grams), len(grams)) or not np.all(np.isfinite(c_off)):
            raise ValueError(
                f"offset_covariance must be a finite ({n_ax}, {len(grams)}, {len(grams)}) array over the step labels"
            )
        sys_info = sum((gains[:, :, a].T @ c_off[a] @ gains[:, :, a] for a in range(n_ax)), np.zeros((n_p, n_p)))
    rank, cond = information_rank(info, r, model=mdl)
    unobs = unobservable_parameters(info, r, model=mdl) if rank < n_p else ()

    # With prior, in per-kind scaled coordinates for numerical balance.
    s = mdl.reference_scale
    ss = np.outer(s, s)
    a_s = info * ss + np.linalg.inv(p / ss)
    a_inv = np.linalg.inv(a_s)
    cov_w = a_inv * ss
    cov_t = (a_inv + a_inv @ (sys_info * ss) @ a_inv) * ss
    sig_w = np.sqrt(np.diag(cov_w))
    sig_t = np.sqrt(np.diag(cov_t))

    # Data alone (unobservable parameters held by their prior only, reported as ∞).
    obs_mask, reg = np.array([n not in unobs for n in mdl.names]), np.zeros(n_p)
    reg[~obs_mask] = 1.0 / (sig_prior[~obs_mask] / s[~obs_mask]) ** 2
    d_s = info * ss + np.diag(reg)
    d_inv = np.linalg.inv(d_s) if rank == n_p or np.any(reg > 0) else np.full_like(d_s, np.inf)
    sig_dw = np.sqrt(np.abs(np.diag(d_inv * ss)))
    sig_dt = np.sqrt(np.abs(np.diag((d_inv + d_inv @ (sys_info * ss) @ d_inv) * ss)))
    sig_dw[~obs_mask] = np.inf
    sig_dt[~obs_mask] = np.inf

    flagged = [k for k in range(n_p) if (not obs_mask[k]) or sig_dt[k] > mag[k] / min_snr]
    unid = tuple(mdl.names[k] for k in flagged)
    warnings = _warnings(mdl, flagged, obs_mask, sig_dw, sig_dt, mag, min_snr, max_rate, sbi, magnitudes is None)
    warnings += _weak_warnings(mdl, flagged, sig_dt, mag, max_rate)
    n_total = float(sum(g[0, 0] for g in grams.values()))
    return IdentificationPlan(
        sigma_white=sig_w,
        sigma_total=sig_t,
        sigma_data_white=sig_dw,
        sigma_data_total=sig_dt,
        sigma_prior=sig_prior,
        magnitudes=mag,
        rank=rank,
        condition=cond,
        unidentifiable=unid,
        warnings=warnings,
        covariance_white=0.5 * (cov_w + cov_w.T),
        covariance_total=0.5 * (cov_t + cov_t.T),
        n_samples=n_total,
        max_rate=max_rate,
        min_snr=min_snr,
        model=mdl,
    )


def _warnings(
    mdl: ModelSpec,
    flagged: list[int],
    obs_mask: NDArray[np.bool_],
    sig_dw: NDArray[np.float64],
    sig_dt: NDArray[np.float64],
    mag: NDArray[np.float64],
    min_snr: float,
    max_rate: float,
    sbi: NDArray[np.float64],
    mag_is_prior: bool,
) -> list[str]:
    against = "prior" if mag_is_prior else "datasheet magnitude"
    out: list[str] = []
    off_p = off_a = 0
    for part in mdl.parts:
        sbi_max = float(sbi[off_a : off_a + part.n_axes].max())
        for kind in part.unique_kinds():
            ks = [k for k in flagged if off_p <= k < off_p + part.n_params and mdl.kinds[k] == kind]
            if ks:
                out.append(_kind_warning(part, kind, ks, mdl.names, obs_mask, sig_dw, sig_dt, mag, min_snr, max_rate,
                                         sbi_max, against))  # fmt: skip
        off_p += part.n_params
        off_a += part.n_axes
    return out


WEAK_FRACTION: float = 0.1
"""A spin-identified parameter whose predicted 1σ exceeds this fraction of its magnitude is "weakly identified"."""


def _weak_warnings(
    mdl: ModelSpec, flagged: list[int], sig_dt: NDArray[np.float64], mag: NDArray[np.float64], max_rate: float
) -> list[str]:
    """Spin-identified parameters that pass the 3σ rule but only weakly (1σ ≥ 10 % of their magnitude)."""
    out = []
    for kind in mdl.unique_kinds():
        if not mdl.rate_power.get(kind):
            continue
        ks = [k for k in range(mdl.n_params) if mdl.kinds[k] == kind and k not in flagged]
        ks = [k for k in ks if np.isfinite(sig_dt[k]) and sig_dt[k] > WEAK_FRACTION * mag[k]]
        if ks:
            worst = max(ks, key=lambda k: sig_dt[k] / mag[k])
            out.append(
                f"{', '.join(mdl.names[k] for k in ks)} ({mdl.kind_labels[kind]}) only weakly identified: predicted "
                f"1σ {_fmt(kind, sig_dt[worst])} is {100 * sig_dt[worst] / mag[worst]:.0f} % of "
                f"{_fmt(kind, mag[worst])}; spins reach only {max_rate / DEG:.3g} °/s — spin faster and in both "
                "directions (bias and Earth rate cancel in the ± difference)."
            )
    return out


def _kind_warning(
    part: ModelSpec,
    kind: str,
    ks: list[int],
    names_all: tuple[str, ...],
    obs_mask: NDArray[np.bool_],
    sig_dw: NDArray[np.float64],
    sig_dt: NDArray[np.float64],
    mag: NDArray[np.float64],
    min_snr: float,
    max_rate: float,
    sbi_max: float,
    against: str,
) -> str:
    """The warning for the flagged parameters ``ks`` of one kind of one model part."""
    bias_kind = getattr(part, "bias_kind", "bias")
    names = ", ".join(names_all[k] for k in ks)
    worst = max(ks, key=lambda k: sig_dt[k] / mag[k])
    target = mag[worst] / min_snr
    head = f"{names} ({part.kind_labels[kind]}) will not be identified: "
    if not all(obs_mask[k] for k in ks):
        fix = part.unobservable_fix.get(kind, getattr(part, "default_fix", "the motion does not excite it"))
        return head + "not observable with this motion; " + fix + "."
    data_sig = sig_dt[worst]
    base = (
        f"predicted 1σ {_fmt(kind, data_sig)} against a {_fmt(kind, mag[worst])} {against} "
        f"(needs ≤ {_fmt(kind, target)} to resolve it at {min_snr:g}σ)"
    )
    white_share = (sig_dw[worst] / data_sig) ** 2 if np.isfinite(data_sig) and data_sig > 0 else 1.0
    pw = part.rate_power.get(kind, 0)
    if pw:
        if max_rate > 0 and np.isfinite(data_sig):
            need = max_rate * (data_sig / target) ** (1.0 / pw)  # σ ∝ 1/ω^p at the same spin duration
            need10 = max_rate * (data_sig / (0.1 * mag[worst])) ** (1.0 / pw)
            law = "1/ω²" if pw == 2 else "1/ω"
            fix = (
                f"spins reach only {max_rate / DEG:.3g} °/s; spin at ≥ {math.ceil(need / DEG):.0f} °/s "
                f"for the same spin time (σ scales as {law}; ≥ {math.ceil(need10 / DEG):.0f} °/s for 1σ ≤ "
                f"{_fmt(kind, 0.1 * mag[worst])}), or longer and in both directions"
            )
            if white_share < 0.5:
                fix += (
                    f"; it is dominated by the bias stability ({_fmt(bias_kind, sbi_max)} between "
                    "hold and spin), so a longer spin alone will not help"
                )
        else:
            fix = "add constant-rate spins about each body axis at ≥ 30 °/s"
    elif white_share >= 0.5 and np.isfinite(data_sig):
        factor = (data_sig / target) ** 2
        fix = f"hold about {math.ceil(factor):.0f}× longer at each position (white-noise limited, σ ∝ 1/√time)"
    else:
        fix = (
            f"it is limited by the bias stability ({_fmt(bias_kind, sbi_max)} between steps), not by "
            "hold time: improve warm-up/thermal stability or shorten the time between the positions that "
            "separate it"
        )
    return head + base + "; " + fix + "."


# ---------------------------------------------------------------------------------------------------------------
# Nominal motion of the reference procedures (for plans, simulations and benchmarks)

GROUPS: dict[str, tuple[tuple[float, float, float], int]] = {
    "A": ((0.0, 0.0, 0.0), 2),  # x E, y N, z U; steps about the inner gimbal = body y
    "B": ((-90.0 * DEG, -90.0 * DEG, 0.0), 1),  # x S, y Down, z E; middle gimbal = body x
    "C": ((90.0 * DEG, 0.0, 90.0 * DEG), 1),  # x Down, y W, z N; middle gimbal = body z
}
"""Base gimbal angles (ψ, θ, γ), rad, and the gimbal index stepped/spun, of the ten-step groups A, B, C."""


def _step(
    label: str, angles: NDArray[np.float64], rates: NDArray[np.float64], g: float, w: NDArray[np.float64]
) -> PlanStep:
    return PlanStep(
        label=label,
        f_ref=gimbal.gravity_in_body(angles, g),
        omega=gimbal.body_rate(angles, rates),
        weights=w,
        angles=angles,
    )


def ten_step_sequence(
    g: float,
    sample_rate: float,
    *,
    hold_s: float = 60.0,
    spin_rate: float = 1.6 * DEG,
    revolutions: float = 1.0,
    both_directions: bool = False,
    points_per_rev: int | None = None,
) -> list[PlanStep]:
    """Nominal samples of the reference ten-step procedure (8 holds + one spin per base orientation A, B, C).

    Parameters
    ----------
    g : float
        Local gravity, m/s².
    sample_rate : float
        Output sample rate, Hz.
    hold_s : float
        Duration of each static hold, s.
    spin_rate : float
        Constant spin rate, rad/s (published 1.6 °/s).
    revolutions : float
        Revolutions per spin (per direction).
    both_directions : bool
        Add a spin in the negative direction after each positive one.
    points_per_rev : int, optional
        If given, compress: one point per hold and this many points per spin revolution, with weights =
        samples represented (for plans). Otherwise every sample is returned (weights 1), for simulation.

    Returns
    -------
    list of PlanStep
        Labels ``"A+0" … "A+315"``, ``"A spin+"`` (``"A spin-"``), then B and C likewise.
    """
    if not (sample_rate > 0 and hold_s >= 0 and spin_rate > 0 and revolutions > 0):
        raise ValueError("sample_rate, spin_rate and revolutions must be > 0 and hold_s >= 0")
    steps: list[PlanStep] = []
    n_hold = int(round(hold_s * sample_rate))
    t_spin = 2.0 * math.pi * revolutions / spin_rate
    n_spin = int(round(t_spin * sample_rate))
    for grp, (base, axis) in GROUPS.items():
        base_a = np.array(base)
        for k in range(8):
            ang = base_a.copy()
            ang[axis] += k * math.pi / 4.0
            if points_per_rev is None:
                angles = np.tile(ang, (n_hold, 1))
                w = np.ones(n_hold)
            else:
                angles = ang[None, :]
                w = np.array([float(n_hold)])
            steps.append(_step(f"{grp}+{45 * k}", angles, np.zeros_like(angles), g, w))
        for sign in (1.0, -1.0) if both_directions else (1.0,):
            if points_per_rev is None:
                tt = (np.arange(n_spin) + 0.5) / sample_rate
                w = np.ones(n_spin)
            else:
                m = max(int(math.ceil(points_per_rev * revolutions)), 1)
                tt = (np.arange(m) + 0.5) * t_spin / m
                w = np.full(m, n_spin / m)
            angles = np.tile(base_a, (tt.size, 1))
            angles[:, axis] += sign * spin_rate * tt
            rates = np.zeros_like(angles)
            rates[:, axis] = sign * spin_rate
            steps.append(_step(f"{grp} spin{'+' if sign > 0 else '-'}", angles, rates, g, w))
    return steps


def cube_orientations() -> NDArray[np.float64]:
    """The 24 rotation matrices C_b^n of the cube group (signed permutations with det +1), shape (24, 3, 3)."""
    import itertools

    mats = []
    for perm in itertools.permutations(range(3)):
        for signs in itertools.product((1.0, -1.0), repeat=3):
            m = np.zeros((3, 3))
            for row, (col, sg) in enumerate(zip(perm, signs, strict=True)):
                m[row, col] = sg
            if np.linalg.det(m) > 0:
                mats.append(m)
    return np.array(mats)


def cube24_sequence(g: float, sample_rate: float, *, hold_s: float = 60.0, compress: bool = False) -> list[PlanStep]:
    """Nominal samples of the conventional 24-position static method (each cube orientation held ``hold_s``)."""
    steps: list[PlanStep] = []
    n_hold = int(round(hold_s * sample_rate))
    for k, c in enumerate(cube_orientations()):
        ang = gimbal.euler_from_body_to_nav(c)
        m = 1 if compress else n_hold
        angles = np.tile(ang, (m, 1))
        w = np.array([float(n_hold)]) if compress else np.ones(n_hold)
        f = np.tile(g * c[2, :], (m, 1))  # C_n^b [0, 0, g]: third row of C_b^n
        steps.append(PlanStep(f"cube{k:02d}", f, np.zeros_like(f), w, angles))
    return steps


__all__ = [
    "GROUPS",
    "IdentificationPlan",
    "PlanStep",
    "cube24_sequence",
    "cube_orientations",
    "plan_identification",
    "ten_step_sequence",
]
