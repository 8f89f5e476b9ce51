"""The simulated inertial unit: accelerometer and gyro triads with their errors, noise and output stage.

Physics (body frame b, SI; docs/methods/simulation.md, docs/methods/accelerometer-calibration.md):

* Accelerometer i sits at ρ_i (row i of ``lever_arms``, from the table's rotation centre) and senses the
  specific force there, F_i = f + ω×(ω×ρ_i) + ω̇×ρ_i, with f = C_n^b [0, 0, g]ᵀ at the reference point
  (the rotation centre; the table does not translate it) and ω, ω̇ the table's body rate and angular
  acceleration relative to the Earth (the Earth-rate centripetal term is inside g; ω×Ω cross terms,
  ~1e-11 m/s² for 3 cm, are neglected). Its output is
  u_i = Σ_j M_ij F_{i,j} + b_i + d_i F_{i,i}², with M = I + diag(S) + T, T_ij = τ_ij (δf_i += τ_ij f_j).
  For a spin about axis j ≠ i this reduces to the 3-parameter model with r_i = −ρ_{i,i}; off-axis
  ω_iω_j and ω̇ terms are present here although the identification model neglects them.
* Gyro: u = (I + diag(S_g) + T_g)(ω + C_n^b Ω^n) + b_g + G f.
* Temperature (optional): T(t) = ambient + rise (1 − e^(−t/τ)); biases and scales drift linearly with
  T − T_settled.
* Anti-alias: a 2nd-order Butterworth low-pass (``scipy.signal.butter``) at ``anti_alias_hz`` applied to
  the physical signal above, state carried across calls, initialised at steady state on the first sample.
  Noise, periodic terms and ARMA drift are defined at the output (their configured values are what the
  output shows).
* Noise per channel (IEEE 952 / 1293 conventions): white (per-sample std N√f_s, Allan deviation N/√τ);
  bias instability B as a sum of first-order Gauss–Markov processes with corner frequencies two per
  decade over the flicker band, each of variance B²Δ/π (Δ = ln10/2): a GM of variance σ² and corner f_c
  has one-sided PSD 2σ²/(π f_c (1 + (f/f_c)²)), and the log-spaced sum approximates the one-sided flicker
  law B²/(π f), i.e. IEEE 952's two-sided S_Ω = B²/(2π f) (same two-sided convention as N² for the
  white part), whose Allan floor is B √(2 ln2/π) ≈ 0.664 B; random walk K (increments K√T_s);
  periodic terms A cos(2π f t + φ); ARMA drift (lfilter with carried ``zi``).
* Output stage: quantisation to int32 counts (``CountScale``), a uint32 frame counter, uint64 time stamps
  (ns, optional white jitter), optional dropped frames (the counter skips).

Determinism and speed: every random process has its own ``np.random.Generator`` from
``SeedSequence(seed).spawn(...)``. Everything that does not depend on the motion (noise of every kind,
periodic and ARMA terms, time-stamp jitter, frame drops) is generated ahead in blocks of ``NOISE_BLOCK``
samples aligned on absolute sample indices, with sequential recursions (``lfilter`` with carried ``zi``,
cumulative sums from the carried state), so it is a function of the seed and the sample index only; the
anti-alias filter state is carried across calls. Any split of the same sample range therefore gives
bit-identical frames. Slow Gauss–Markov processes are simulated on a decimated grid (see
:class:`_GaussMarkovBank`).
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray
from scipy import signal

from analysis.units import CELSIUS_ZERO
from drivers.imu_unit.counts import RawFrames
from drivers.sim.chamber import ChamberPhysics, ThermalEffect
from drivers.sim.config import CHANNELS, MISALIGNMENT_PAIRS, NoiseTruth, SimConfig

_INT32_MAX = float(np.iinfo(np.int32).max)
NOISE_BLOCK = 8192
"""Samples of motion-independent noise generated ahead per block (aligned on absolute sample indices)."""
LAB_TEMPERATURE_C = 23.0
"""The unit's temperature, °C, on a bench with neither a warm-up model nor a chamber."""
MAX_DECIMATION = 4096
"""Largest grid step (samples) of the decimated Gauss–Markov processes; divides NOISE_BLOCK."""
N_FIXED_STREAMS = 8
"""Random streams spawned for the unit (before one per ARMA term)."""


def misalignment_matrix(tau: tuple[float, ...] | NDArray[np.float64]) -> NDArray[np.float64]:
    """(3, 3) matrix T with T_ij = τ_ij from the 6-vector τ_xy τ_xz τ_yx τ_yz τ_zx τ_zy (rad)."""
    t = np.zeros((3, 3))
    for (i, j), v in zip(MISALIGNMENT_PAIRS, tau, strict=True):
        t[i, j] = v
    return t


def _skew(r: NDArray[np.float64]) -> NDArray[np.float64]:
    """Cross-product matrix S(r): S(r) x = r × x."""
    return np.array([[0.0, -r[2], r[1]], [r[2], 0.0, -r[0]], [-r[1], r[0], 0.0]])


class _GaussMarkovBank:
    """Sums of first-order Gauss–Markov processes approximating flicker noise, one sum per channel.

    Processes sharing a pole are filtered together. A process with corner f_c is simulated on a coarser
    grid of step D = 2^j ≤ f_s / (100 f_c) samples (at most ``MAX_DECIMATION``), exactly (pole a^D), and
    linearly interpolated in between: its correlation over D samples is ≥ 0.94, so interpolation loses
    ≤ 3 % of its variance mid-step while needing ~50× fewer random numbers. Grids are aligned on absolute
    sample indices and every call covers whole ``NOISE_BLOCK``s, so results are split-invariant.
    """

    def __init__(self, noises: list[NoiseTruth], fs: float, rng: np.random.Generator) -> None:
        self.rng = rng
        cols: list[tuple[int, float, float]] = []  # (channel, corner Hz, process std σ)
        ch = 0
        for noise in noises:
            for b in noise.bias_instability:
                if b > 0:
                    f_lo, f_hi = noise.flicker_band
                    f_hi = min(f_hi, 0.25 * fs)
                    n_dec = max(math.log10(f_hi / f_lo), 0.0)
                    k = max(int(math.ceil(2 * n_dec)) + 1, 1)
                    sigma = b * math.sqrt(math.log(10.0) / 2.0 / math.pi)  # see module docstring
                    for fc in np.logspace(math.log10(f_lo), math.log10(f_hi), k):
                        cols.append((ch, float(fc), sigma))
                ch += 1
        self.n_channels = ch
        self.n_proc = len(cols)
        # groups: (decimation D, pole over D samples, channel of each column, driving std, process std)
        self.groups: list[tuple[int, float, NDArray[np.int64], NDArray[np.float64], NDArray[np.float64]]] = []
        for fc in sorted({c[1] for c in cols}):
            members = [c for c in cols if c[1] == fc]
            d = 1
            while d * 2 <= min(fs / (100.0 * fc), MAX_DECIMATION):
                d *= 2
            a_d = math.exp(-2.0 * math.pi * fc * d / fs)
            chans = np.array([c[0] for c in members], dtype=np.int64)
            sig = np.array([c[2] for c in members])
            self.groups.append((d, a_d, chans, sig * math.sqrt(1.0 - a_d * a_d), sig))
        # stationary start: value of each process at the sample before the first block
        self.state = [rng.standard_normal(len(g[2])) * g[4] for g in self.groups]
        self._ramps: dict[int, NDArray[np.float64]] = {}  # (1 … D) / D of each grid step D
        self._scratch: NDArray[np.float64] | None = None

    def draw(self, n: int) -> NDArray[np.float64]:
        """(n, n_channels) summed Gauss–Markov output for the next n samples (n a multiple of NOISE_BLOCK).

        Summed channel by channel along time ((n_channels, n) in memory, returned transposed): the
        interpolation's broadcasts then run over long contiguous rows instead of six values at a time. Each
        sample gets the same additions in the same order (group by group: the previous grid value, then the
        interpolated step), so the values are those of the sample-major sum bit for bit."""
        out = np.zeros((self.n_channels, n))
        if self._scratch is None or self._scratch.size < out.size:
            self._scratch = np.empty(out.size)  # the interpolation's products, reused (no fresh pages per group)
        for gi, (d, a_d, chans, w_std, _) in enumerate(self.groups):
            m = n // d
            w = self.rng.standard_normal((m, len(chans))) * w_std
            p, _ = signal.lfilter([1.0], [1.0, -a_d], w, axis=0, zi=a_d * self.state[gi][None, :])
            full = len(chans) == self.n_channels  # every channel has this corner (the usual case)
            tgt = out if full else np.zeros((len(chans), n))
            pt = np.ascontiguousarray(p.T)  # (channels, m)
            if d == 1:
                tgt += pt
            else:
                prev = np.empty_like(pt)
                prev[:, 0] = self.state[gi]
                prev[:, 1:] = pt[:, :-1]
                t3 = tgt.reshape(len(chans), m, d)
                t3 += prev[:, :, None]
                ramp = self._ramps.get(d)
                if ramp is None:
                    ramp = self._ramps[d] = (np.arange(1, d + 1) / d)[None, None, :]
                prod = self._scratch[: t3.size].reshape(t3.shape)
                np.multiply((pt - prev)[:, :, None], ramp, out=prod)
                t3 += prod
            self.state[gi] = p[-1].copy()
            if not full:
                out[chans] += tgt  # one process per channel per corner: no repeated indices
        return out.T


class InertialModel:
    """Stateful generator of the unit's raw frames from the table's motion (see module docstring).

    Parameters
    ----------
    config : SimConfig
    seed_seq : np.random.SeedSequence
        Parent seed sequence of the unit's random streams.
    """

    def __init__(self, config: SimConfig, seed_seq: np.random.SeedSequence) -> None:
        self.cfg = config
        self.fs = float(config.sample_rate)
        self.dt = 1.0 / self.fs
        streams = seed_seq.spawn(N_FIXED_STREAMS + len(config.arma))
        rngs = [np.random.default_rng(s) for s in streams]
        self._rng_white = rngs[0]
        self._gm = _GaussMarkovBank([config.accel_noise, config.gyro_noise], self.fs, rngs[1])
        self._rng_rw = rngs[3]
        self._rng_ts = rngs[4]
        self._rng_drop = rngs[5]
        self._white = np.concatenate([config.accel_noise.white, config.gyro_noise.white]) * math.sqrt(self.fs)
        self._rw = np.concatenate([config.accel_noise.random_walk, config.gyro_noise.random_walk]) * math.sqrt(self.dt)
        self._rw_state = np.zeros(6)
        a = config.accel
        self.m_acc = np.eye(3) + np.diag(a.scale) + misalignment_matrix(a.misalignment)
        self.b_acc = np.asarray(a.bias, dtype=float)
        self.d_acc = np.asarray(a.quadratic, dtype=float)
        self.rho = np.asarray(a.lever_arms, dtype=float)
        self._has_lever = bool(np.any(self.rho != 0.0))
        skews = [_skew(r) for r in self.rho]
        self._rho_m = np.einsum("ij,ij->i", self.rho, self.m_acc)  # ρ_i·m_i
        self._rho_d = np.diag(self.rho).copy()  # ρ_ii
        self._q_m = np.stack([skews[i] @ self.m_acc[i] for i in range(3)], 1)  # column i: S(ρ_i) m_i
        self._q_d = np.stack([skews[i][:, i] for i in range(3)], 1)  # column i: S(ρ_i) e_i
        gy = config.gyro
        self.m_gyr = np.eye(3) + np.diag(gy.scale) + misalignment_matrix(gy.misalignment)
        self.b_gyr = np.asarray(gy.bias, dtype=float)
        self.g_sens = np.asarray(gy.g_sensitivity, dtype=float)
        self.s2_gyr = np.asarray(gy.quadratic, dtype=float)
        self.a_gyr = np.asarray(gy.asymmetry, dtype=float)
        self._gyr_nonlinear = bool(np.any(self.s2_gyr) or np.any(self.a_gyr))
        # temperature: a simulated chamber (set by the world) and the temperature-dependent truth
        self.chamber: ChamberPhysics | None = None
        self.thermal = ThermalEffect(config.thermal) if config.thermal is not None else None
        # ARMA drifts
        self._arma = []
        for term, rng in zip(config.arma, rngs[N_FIXED_STREAMS:], strict=True):
            b = np.concatenate([[1.0], -np.asarray(term.theta, dtype=float)])
            aa = np.concatenate([[1.0], -np.asarray(term.phi, dtype=float)])
            order = max(len(b), len(aa)) - 1
            self._arma.append([CHANNELS.index(term.channel), b, aa, float(term.sigma), rng, np.zeros(order)])
        # anti-alias filter on the physical signal
        self._aa: tuple[NDArray[np.float64], NDArray[np.float64]] | None = None
        self._aa_zi: NDArray[np.float64] | None = None
        if config.anti_alias_hz:
            bb, ab = signal.butter(2, float(config.anti_alias_hz), fs=self.fs)
            self._aa = (bb, ab)
        self._buf = np.empty((0, 8))
        self._buf_k0 = 0
        self._periodic = [(CHANNELS.index(p.channel), p.frequency_hz, p.amplitude, p.phase) for p in config.periodic]
        # the error model's output depends on time only through temperature (warm-up, chamber, thermal truth)
        tm = config.temperature
        self._time_free = self.thermal is None and (tm is None or tm.warmup_rise_c == 0.0)
        self._rest_phys: tuple[tuple[object, int], NDArray[np.float64]] | None = None
        # a hold's blocks repeat the same filter step and the same output stage (see frames): their results,
        # kept while the inputs are the same objects/bits
        self._aa_rest: tuple[NDArray[np.float64], bytes, NDArray[np.float64], NDArray[np.float64], int] | None = None
        self._stage: tuple[NDArray[np.float64], NDArray[np.uint64], NDArray[np.uint32]] | None = None
        self._rest_counts: tuple[NDArray[np.float64], NDArray[np.float64], int, NDArray[np.int32]] | None = None
        self._const: dict[tuple[int, str], NDArray[np.generic]] = {}
        sc = config.scale
        self._lsb = np.array([sc.accel_lsb] * 3 + [sc.gyro_lsb] * 3)
        # the temperature word of a unit at the fixed lab temperature (no warm-up model, no chamber)
        self._temp_word = np.rint(np.full(1, LAB_TEMPERATURE_C) / sc.temperature_lsb).astype(np.int16)[0]

    # ---- temperature ---------------------------------------------------------------------------------
    def temperature_c(self, t: NDArray[np.float64]) -> NDArray[np.float64]:
        """Unit temperature, °C, at bench times ``t`` (s)."""
        if self.chamber is not None:
            return self.chamber.unit_temperature(t) - CELSIUS_ZERO
        tm = self.cfg.temperature
        if tm is None:
            return np.full(t.shape, LAB_TEMPERATURE_C)
        return tm.ambient_c + tm.warmup_rise_c * (1.0 - np.exp(-t / tm.warmup_tau))

    # ---- the physics ---------------------------------------------------------------------------------
    def physical(
        self,
        t: NDArray[np.float64],
        f0: NDArray[np.float64],
        omega: NDArray[np.float64],
        alpha: NDArray[np.float64],
        earth_b: NDArray[np.float64],
    ) -> NDArray[np.float64]:
        """Error-model output before filtering and noise, (n, 6) [accel m/s², gyro rad/s], body frame.

        Parameters
        ----------
        t : (n,) bench time, s. f0 : (n, 3) specific force at the reference point, m/s², body frame.
        omega, alpha : (n, 3) table angular rate (rad/s) and acceleration (rad/s²) w.r.t. the Earth, body.
        earth_b : (n, 3) Earth rate in the body frame, rad/s.
        """
        n = t.shape[0]
        out = np.empty((n, 6))
        w2 = np.einsum("ij,ij->i", omega, omega)
        m_acc, b_acc = self.m_acc, self.b_acc
        m_gyr, b_gyr = self.m_gyr, self.b_gyr
        tm = self.cfg.temperature
        dtemp = None
        if tm is not None and tm.warmup_rise_c != 0.0:
            dtemp = self.temperature_c(t) - (tm.ambient_c + tm.warmup_rise_c)
        # u_i = F_i·m_i + b_i + d_i F_ii², F_i = f + ω(ω·ρ_i) − |ω|²ρ_i + ω̇×ρ_i, written with dot products
        # (ω̇×ρ)·m = ω̇·(S(ρ) m), S(ρ) the cross-product matrix: all three accelerometers at once.
        f_all = f0 @ m_acc.T  # (n, 3): f·m_i
        f_ii = f0.copy()  # along-axis specific force F_ii
        if self._has_lever:
            wr = omega @ self.rho.T  # (n, 3): ω·ρ_i
            f_all += wr * (omega @ m_acc.T) - w2[:, None] * self._rho_m[None, :] + alpha @ self._q_m
            f_ii += omega * wr - w2[:, None] * self._rho_d[None, :] + alpha @ self._q_d
        u = f_all + b_acc + self.d_acc * f_ii**2
        if dtemp is not None:
            u += np.asarray(tm.accel_bias_tc) * dtemp[:, None] + np.asarray(tm.accel_scale_tc) * dtemp[:, None] * f_ii  # type: ignore[union-attr]
        thermal = self._thermal_state(t)
        if thermal is not None:
            u = u + self.thermal.apply("accel", thermal[0], thermal[1], f0)  # type: ignore[union-attr]
        out[:, :3] = u
        w_s = omega + earth_b
        g = w_s @ m_gyr.T + b_gyr + f0 @ self.g_sens.T
        if self._gyr_nonlinear:
            g = g + self.s2_gyr * w_s * w_s + self.a_gyr * np.abs(w_s)
        if dtemp is not None:
            g = g + np.asarray(tm.gyro_bias_tc)[None, :] * dtemp[:, None]  # type: ignore[union-attr]
            g = g + np.asarray(tm.gyro_scale_tc)[None, :] * dtemp[:, None] * w_s  # type: ignore[union-attr]
        if thermal is not None:
            g = g + self.thermal.apply("gyro", thermal[0], thermal[1], w_s)  # type: ignore[union-attr]
        out[:, 3:] = g
        return out

    def _thermal_state(self, t: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]] | None:
        """(unit temperature K, its rate K/s) at ``t`` when the truth depends on temperature, else None."""
        if self.thermal is None:
            return None
        if self.chamber is not None:
            return self.chamber.unit_temperature(t), self.chamber.unit_rate(t)
        return self.temperature_c(t) + CELSIUS_ZERO, np.zeros(t.shape)

    def _generate(self, k0: int, n: int) -> NDArray[np.float64]:
        """Motion-independent streams for samples k0…k0+n−1: (n, 8) = 6 output-referred noise channels
        (white, flicker, random walk, periodic, ARMA; SI), time-stamp jitter (s), drop uniform."""
        out = np.empty((n, 8))
        white = self._rng_white.standard_normal((n, 6))
        white *= self._white
        out[:, :6] = white
        out[:, :6] += self._gm.draw(n)
        if np.any(self._rw != 0):  # (its stream feeds nothing else: not drawn for a bench without random walk)
            inc = self._rng_rw.standard_normal((n, 6)) * self._rw
            # sequential accumulation from the carried state (split-invariant rounding)
            rw = np.cumsum(np.vstack([self._rw_state[None, :], inc]), axis=0)[1:]
            self._rw_state = rw[-1].copy()
            out[:, :6] += rw
        k = np.arange(k0, k0 + n, dtype=np.int64)
        for ch, f, amp, ph in self._periodic:
            # phase from the integer sample index keeps long runs exact: 2π f k / f_s mod 2π
            cyc = np.mod(k * (f / self.fs), 1.0)
            out[:, ch] += amp * np.cos(2.0 * math.pi * cyc + ph)
        for term in self._arma:
            ch, b, aa, sig, rng, zi = term
            e = rng.standard_normal(n) * sig
            if zi.size:
                x, zf = signal.lfilter(b, aa, e, zi=zi)
                term[5] = zf
            else:
                x = e
            out[:, ch] += x
        out[:, 6] = self._rng_ts.standard_normal(n) * self.cfg.timestamp_jitter
        # the drop stream feeds nothing else: not drawn when frames never drop (column 7 is read only then)
        out[:, 7] = self._rng_drop.random(n) if self.cfg.drop_probability > 0 else 1.0
        return out

    def streams(self, k0: int, n: int) -> NDArray[np.float64]:
        """Rows k0…k0+n−1 of the motion-independent streams (see :meth:`_generate`), (n, 8).

        They depend only on the seed and the sample index, so they are generated ahead in fixed blocks of
        ``NOISE_BLOCK`` samples aligned on absolute sample indices (cheap small reads, split-invariant).
        Sample indices must be requested in increasing order.
        """
        if k0 < self._buf_k0:
            raise ValueError(f"sample {k0} was already consumed (streams are generated forward only)")
        end = k0 + n
        while self._buf_k0 + self._buf.shape[0] < end:
            nxt = self._buf_k0 + self._buf.shape[0]
            keep = self._buf[k0 - self._buf_k0 :] if k0 < nxt else self._buf[:0]
            self._buf_k0 = min(k0, nxt)
            self._buf = np.vstack([keep, self._generate(nxt, NOISE_BLOCK)])
        i = k0 - self._buf_k0
        out = self._buf[i : i + n]
        return out

    def frames(
        self,
        k0: int,
        f0: NDArray[np.float64],
        omega: NDArray[np.float64],
        alpha: NDArray[np.float64],
        earth_b: NDArray[np.float64],
        rest_key: object = None,
    ) -> RawFrames:
        """Frames for samples k0 … k0+n−1 (n = len(f0)); see :meth:`physical` for the inputs.

        ``rest_key``: the inputs are those of a table at rest at one attitude, which the key names (equal keys,
        equal inputs). Where the error model does not depend on time (no temperature term) its output for the
        same key and length is the same array, so it is computed once for a hold's blocks, not every block; so
        is its anti-aliasing once the filter has settled (the same input and state give the same output, bit
        for bit: a constant, or a last-bit cycle of a few samples), and then the counts of a whole noise block
        at once (element-wise, the same values)."""
        n = f0.shape[0]
        t = None  # the samples' times, formed where they are used (a settled hold's block needs none)
        rest = rest_key is not None and self._time_free
        if rest:
            if self._rest_phys is None or self._rest_phys[0] != (rest_key, n):
                t = np.arange(k0, k0 + n, dtype=np.int64) * self.dt
                phys = self.physical(t, f0, omega, alpha, earth_b)
                phys.flags.writeable = False
                self._rest_phys = ((rest_key, n), phys)
            phys = self._rest_phys[1]
        else:
            t = np.arange(k0, k0 + n, dtype=np.int64) * self.dt
            phys = self.physical(t, f0, omega, alpha, earth_b)
        period = 0  # the filtered physical signal repeats every ``period`` rows (a settled hold; 0: it does not)
        if self._aa is not None:
            phys, period = self._anti_alias(phys, rest)
        st = self.streams(k0, n)
        i = k0 - self._buf_k0
        if period:
            counts = self._settled_counts(phys, period, k0, i, n)
        else:
            y = phys + st[:, :6]
            q = np.rint(y / self._lsb, out=y)
            counts = np.clip(q, -_INT32_MAX, _INT32_MAX, out=q).astype(np.int32)
        ts_ns, counter = self._output_stage()
        if self.chamber is None and self.cfg.temperature is None:  # temperature_c is the lab's: its word
            temp = self._constant(n, "temperature")
        else:
            if t is None:
                t = np.arange(k0, k0 + n, dtype=np.int64) * self.dt
            temp = np.rint(self.temperature_c(t) / self.cfg.scale.temperature_lsb).astype(np.int16)
        frames = RawFrames(
            counter=counter[i : i + n],
            timestamp_ns=ts_ns[i : i + n],
            counts=counts,
            temperature=temp,
            status=self._constant(n, "status"),
        )
        if self.cfg.drop_probability > 0:
            keep = st[:, 7] >= self.cfg.drop_probability
            frames = RawFrames(
                counter=frames.counter[keep],
                timestamp_ns=frames.timestamp_ns[keep],
                counts=frames.counts[keep],
                temperature=frames.temperature[keep],
                status=frames.status[keep],
            )
        return frames

    def _anti_alias(self, phys: NDArray[np.float64], rest: bool) -> tuple[NDArray[np.float64], int]:
        """The anti-alias filter over ``phys`` (state carried); and for a hold's block (``rest``: the same
        read-only input array) the period P ≤ 8 dividing n with which its rows repeat bit for bit (0: none). A
        hold's block that meets the state the previous one left is filtered once: the same input and state give
        the same output and final state."""
        assert self._aa is not None
        bb, ab = self._aa
        if self._aa_zi is None:
            self._aa_zi = signal.lfilter_zi(bb, ab)[:, None] * phys[0][None, :]
        cache = self._aa_rest
        if rest and cache is not None and cache[0] is phys and cache[1] == self._aa_zi.tobytes():
            self._aa_zi = cache[3]
            return cache[2], cache[4]
        zi = self._aa_zi
        out, self._aa_zi = signal.lfilter(bb, ab, phys, axis=0, zi=zi)
        if not rest:
            return out, 0
        out.flags.writeable = False
        bits = out.view(np.uint64)
        n = out.shape[0]
        period = next((p for p in (1, 2, 4, 8) if n % p == 0 and np.array_equal(bits[p:], bits[:-p])), 0)
        self._aa_rest = (phys, zi.tobytes(), out, self._aa_zi, period)
        return out, period

    def _settled_counts(self, phys: NDArray[np.float64], period: int, k0: int, i: int, n: int) -> NDArray[np.int32]:
        """Counts of rows i … i+n−1 of the noise buffer (samples k0 …) added to the filtered physical signal
        ``phys`` of a settled hold (read-only, kept by :meth:`_anti_alias`), whose row for sample k is
        ``phys[(k − k0) mod period]``: computed for the whole buffer once per buffer and filtered block
        (element-wise: the values of each block's own sum)."""
        phase = k0 % period
        c = self._rest_counts
        if c is None or c[0] is not self._buf or c[1] is not phys or c[2] != phase:
            ks = np.arange(self._buf_k0, self._buf_k0 + self._buf.shape[0], dtype=np.int64)
            y = phys[:period][(ks - k0) % period] + self._buf[:, :6]
            q = np.rint(y / self._lsb, out=y)
            counts = np.clip(q, -_INT32_MAX, _INT32_MAX, out=q).astype(np.int32)
            counts.flags.writeable = False
            self._rest_counts = c = (self._buf, phys, phase, counts)
        return c[3][i : i + n]

    def _output_stage(self) -> tuple[NDArray[np.uint64], NDArray[np.uint32]]:
        """Time stamps (ns) and frame counters of every sample of the noise buffer (computed once per buffer;
        read-only): the unit clock's k / f_s plus the time-stamp jitter, and k mod 2³²."""
        s = self._stage
        if s is None or s[0] is not self._buf:
            k = np.arange(self._buf_k0, self._buf_k0 + self._buf.shape[0], dtype=np.int64)
            ts_ns = k * (1e9 / self.fs)  # exact integers for rates dividing 1 GHz (e.g. 1 kHz → 1 000 000 ns)
            if self.cfg.timestamp_jitter > 0:
                ts_ns = ts_ns + self._buf[:, 6] * 1e9
            ts = np.rint(np.maximum(ts_ns, 0.0)).astype(np.uint64)
            counter = (k % (1 << 32)).astype(np.uint32)
            ts.flags.writeable = False
            counter.flags.writeable = False
            self._stage = s = (self._buf, ts, counter)
        return s[1], s[2]

    def _constant(self, n: int, what: str) -> NDArray[np.generic]:
        """A read-only (n,) array of the lab temperature word (``"temperature"``) or of status 0 (``"status"``)."""
        a = self._const.get((n, what))
        if a is None:
            a = np.full(n, self._temp_word, dtype=np.int16) if what == "temperature" else np.zeros(n, np.uint16)
            a.flags.writeable = False
            if len(self._const) > 64:
                self._const.clear()
            self._const[(n, what)] = a
        return a
