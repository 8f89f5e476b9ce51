"""The simulated chamber and the unit's temperature-dependent truth (docs/methods/thermal.md).

:class:`ChamberPhysics` integrates, on bench time, the chamber model of :class:`~drivers.sim.thermal_config.ChamberSim`:

* the effective set point SP_eff moves toward the commanded SP at no more than ``ramp_up`` / ``ramp_down``;
* the air is second order on SP_eff: T̈_a = ω²(SP_eff − T_a) − 2ζω Ṫ_a;
* the unit is first order on the air: Ṫ_u = (T_a + ΔT_self − T_u)/τ_u.

Each step of ``step`` seconds is integrated exactly (matrix exponential of the linear system, SP_eff held at
its mid-step value). When the chamber is stopped the air returns to the lab's ambient with the same dynamics.
The unit's temperature at the sample times is interpolated linearly between steps; its rate comes from the
state. :class:`ThermalEffect` turns (T_u, Ṫ_u) into the per-sample change of the unit's scale/misalignment
matrices and biases (:class:`~drivers.sim.thermal_config.ThermalTruth`).
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray
from scipy.linalg import expm

from drivers.sim.thermal_config import ChamberSim, ThermalTruth, TriadThermal

_PAIRS = ((0, 1), (0, 2), (1, 0), (1, 2), (2, 0), (2, 1))  # τ order of MISALIGNMENT_PAIRS


class ChamberPhysics:
    """The chamber's state on bench time (not thread-safe: the world's lock guards it).

    Parameters
    ----------
    cfg : ChamberSim
    rng : numpy Generator
        Noise of the reported air temperature.
    """

    def __init__(self, cfg: ChamberSim, rng: np.random.Generator) -> None:
        self.cfg = cfg
        self._rng = rng
        self.setpoint = cfg.ambient
        self.running = False
        self.alarm = False
        self._sp_eff = cfg.ambient
        h = cfg.step
        w = 1.0 / cfg.air_time_constant
        z = cfg.air_damping
        tu = cfg.unit_time_constant
        # x = [T_a, Ṫ_a, T_u]; inputs [SP_eff, 1]
        a = np.array([[0.0, 1.0, 0.0], [-w * w, -2 * z * w, 0.0], [1.0 / tu, 0.0, -1.0 / tu]])
        b = np.array([[0.0, 0.0], [w * w, 0.0], [0.0, cfg.self_heating / tu]])
        m = np.zeros((5, 5))
        m[:3, :3], m[:3, 3:] = a, b
        e = expm(m * h)
        self._ad = [[float(e[i, j]) for j in range(3)] for i in range(3)]
        self._bd = [[float(e[i, j]) for j in (3, 4)] for i in range(3)]
        self._k = 0  # grid index of the last state
        self._x = [cfg.ambient, 0.0, cfg.ambient + cfg.self_heating]
        self._hist_k0 = 0
        self._hist: list[list[float]] = [[self._x[0], self._x[1], self._x[2], self._rate(self._x)]]

    # ---- commands -------------------------------------------------------------------------------------
    def allows(self, temperature: float) -> bool:
        """Is ``temperature`` (K) within the controller's own range?"""
        return math.isfinite(temperature) and self.cfg.setpoint_min <= temperature <= self.cfg.setpoint_max

    def command_setpoint(self, t: float, temperature: float) -> None:
        """Set point ``temperature`` (K) from bench time ``t`` on (the caller checked :meth:`allows`)."""
        self.advance_to(t)
        self.setpoint = float(temperature)

    def command_run(self, t: float, on: bool) -> None:
        """Start (control to the set point) or stop (drift back to ambient) from bench time ``t``."""
        self.advance_to(t)
        self.running = bool(on)

    # ---- integration ----------------------------------------------------------------------------------
    def _rate(self, x: list[float]) -> float:
        return (x[0] + self.cfg.self_heating - x[2]) / self.cfg.unit_time_constant

    def _step(self) -> None:
        cfg = self.cfg
        target = self.setpoint if self.running else cfg.ambient
        h = cfg.step
        d = target - self._sp_eff
        lim = (cfg.ramp_up if d > 0 else cfg.ramp_down) * h
        new_eff = target if abs(d) <= lim else self._sp_eff + math.copysign(lim, d)
        u = 0.5 * (self._sp_eff + new_eff)
        self._sp_eff = new_eff
        x, ad, bd = self._x, self._ad, self._bd
        self._x = [ad[i][0] * x[0] + ad[i][1] * x[1] + ad[i][2] * x[2] + bd[i][0] * u + bd[i][1] for i in range(3)]
        self._k += 1
        self._hist.append([self._x[0], self._x[1], self._x[2], self._rate(self._x)])

    def advance_to(self, t: float) -> None:
        """Integrate up to the first grid time ≥ ``t`` (s)."""
        k_end = math.ceil(t / self.cfg.step - 1e-9)
        while self._k < k_end:
            self._step()

    def forget_before(self, t: float) -> None:
        """Drop history older than one step before ``t`` (the world's clock only moves forward)."""
        k = max(0, math.floor(t / self.cfg.step) - 1)
        if k > self._hist_k0:
            del self._hist[: min(k - self._hist_k0, len(self._hist) - 1)]
            self._hist_k0 = self._k - len(self._hist) + 1

    def _at(self, t: NDArray[np.float64], column: int) -> NDArray[np.float64]:
        t = np.asarray(t, dtype=float)
        if t.size == 0:
            return np.zeros(0)
        self.advance_to(float(np.max(t)))
        h = self.cfg.step
        hist = np.asarray(self._hist)
        grid = (self._hist_k0 + np.arange(hist.shape[0])) * h
        return np.interp(t, grid, hist[:, column])

    def unit_temperature(self, t: NDArray[np.float64]) -> NDArray[np.float64]:
        """The unit's temperature at bench times ``t`` (s, ≥ the last forgotten time), K."""
        return self._at(t, 2)

    def unit_rate(self, t: NDArray[np.float64]) -> NDArray[np.float64]:
        """Ṫ_u at bench times ``t``, K/s."""
        return self._at(t, 3)

    def air_temperature(self, t: float) -> float:
        """True air temperature at bench time ``t``, K."""
        return float(self._at(np.array([t]), 0)[0])

    def air_reading(self, t: float) -> float:
        """The controller's air reading at ``t``: truth + noise, at the wire's resolution, K."""
        v = self.air_temperature(t) + self._rng.normal(0.0, self.cfg.air_noise)
        r = self.cfg.resolution
        return round(v / r) * r if r > 0 else v


class ThermalEffect:
    """Per-sample change of the unit's error model with its temperature (:class:`ThermalTruth`)."""

    def __init__(self, truth: ThermalTruth) -> None:
        self.reference = float(truth.reference)
        self.accel = self._triad(truth.accel)
        self.gyro = self._triad(truth.gyro)

    @staticmethod
    def _triad(tr: TriadThermal) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
        bias, scale, mis, rate = tr.arrays()
        order = max(bias.shape[0], scale.shape[0], mis.shape[0])
        b = np.zeros((order, 3))
        b[: bias.shape[0]] = bias
        m = np.zeros((order, 3, 3))
        for k in range(scale.shape[0]):
            m[k] += np.diag(scale[k])
        for k in range(mis.shape[0]):
            for (i, j), v in zip(_PAIRS, mis[k], strict=True):
                m[k, i, j] += v
        return b, m, rate

    def apply(
        self,
        which: str,
        temperature: NDArray[np.float64],
        rate: NDArray[np.float64],
        signal_in: NDArray[np.float64],
    ) -> NDArray[np.float64]:
        """The output change (n, 3) of triad ``which`` ("accel"/"gyro") for the input ``signal_in`` (n, 3)
        (specific force m/s² or angular rate rad/s, body frame) at unit temperatures (K) and rates (K/s)."""
        b, m, brate = self.accel if which == "accel" else self.gyro
        d = np.asarray(temperature, dtype=float) - self.reference
        out = np.outer(rate, brate)
        p = np.ones_like(d)
        for k in range(b.shape[0]):
            p = p * d
            out += np.outer(p, b[k]) + p[:, None] * (signal_in @ m[k].T)
        return out
