"""Decoded frames → the recording's SI samples (and back, for the simulated unit).

:class:`SampleConverter` is stateful across feeds: the counter tracker (gaps, resets and duplicates counted
separately, :class:`drivers.imu_unit.counts.CounterTracker`), the unwrapped sample index, the last multiplexed
temperature (KVH format C sends it every 4th frame), and a wrapping time stamp.

Conversions (per :class:`~drivers.imu_unit.description.Conversion`): ``si = raw × scale × unit`` (+ offset for
temperatures, which end in K); increments (Δθ, Δv) are divided by the nominal sample interval into rate and
specific force, since the identification needs rates; g is 9.80665 m/s². Several temperature fields
(STIM300: one per sensor) are averaged. Per-sample status is normalised into flag bits
(:data:`drivers.imu_unit.description.FLAG_BITS`, bit set = channel invalid); a non-finite decoded value (float
frames) also flags its channel. Invalid samples are kept and flagged, never silently used: the recorder
stores the flags (``/imu/status``) and the identification skips flagged samples.

Bench time is the unit's sample clock: the description's time-stamp field if it names one (``time:``), else
the unwrapped sample index divided by the sample rate.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np
from numpy.typing import NDArray

from drivers.imu_unit.counts import CounterCheck, CounterTracker
from drivers.imu_unit.decoder import FrameBatch, FrameCodec
from drivers.imu_unit.description import FLAG_BITS, RECORDED, TYPES, Conversion, FrameFormat

_TEMP_FLAG = np.uint16(1 << FLAG_BITS["temperature"])


@dataclass
class Samples:
    """Decoded samples (duplicates removed), SI, body frame b.

    Attributes
    ----------
    index : (n,) int64 sample index unwrapped from the counter (the recording's ``counter`` is index mod 2³²).
    counter : (n,) int64 the counter as on the wire.
    time : (n,) s. accel : (n, 3) m/s². gyro : (n, 3) rad/s. temperature : (n,) K (NaN if never sent).
    status : (n,) uint16 normalised flags (bit set = invalid; 0 = all valid).
    extras : dict name → (n,) other channels in SI (inclinometers m/s², magnetometer T, latency s, …) and
        every status field as sent (``status:<field>``).
    gaps, resets, duplicates : counter events in this batch (missing frames, backward jumps, repeats).
    """

    index: NDArray[np.int64]
    counter: NDArray[np.int64]
    time: NDArray[np.float64]
    accel: NDArray[np.float64]
    gyro: NDArray[np.float64]
    temperature: NDArray[np.float64]
    status: NDArray[np.uint16]
    extras: dict[str, NDArray] = field(default_factory=dict)
    gaps: int = 0
    resets: int = 0
    duplicates: int = 0

    def __len__(self) -> int:
        return int(self.index.shape[0])


def _si(raw: NDArray, c: Conversion, rate: float) -> NDArray[np.float64]:
    v = raw.astype(np.float64) * c.factor
    if c.increment:
        v = v * rate
    if c.offset:
        v = v + c.offset
    return v


class SampleConverter:
    """Stateful conversion of :class:`~drivers.imu_unit.decoder.FrameBatch` es into :class:`Samples`.

    Parameters
    ----------
    fmt : FrameFormat
    start_index : int or None
        Sample index of the first frame; None: derived from its counter (counter // step; for a 32-bit
        counter the counter itself).
    """

    def __init__(self, fmt: FrameFormat, start_index: int | None = None) -> None:
        self.fmt = fmt
        d = fmt.desc
        c = d.counter
        self.tracker = CounterTracker(c.modulus if c else 0, fmt.counter_step, start_index)
        self._last_temp: float | None = None
        carried = {c.channel for c in fmt.conversions.values()}
        self._absent = np.uint16(sum(1 << FLAG_BITS[ch] for ch in RECORDED if ch not in carried))
        self._time_last_raw: int | None = None
        self._time_unwrapped = 0
        # plain (non-multiplexed) converted fields become the columns of one matrix, converted at once
        plain = [
            (f, fmt.conversions[f.name])
            for f in d.fields
            if not f.mux and f.name in fmt.conversions and f.name != d.time_field
        ]
        self._names = [f.name for f, _ in plain]
        self._factor = np.array([c.factor * (fmt.sample_rate if c.increment else 1.0) for _, c in plain])
        off = np.array([c.offset for _, c in plain])
        self._offset = off if np.any(off) else None
        col = {c.channel: j for j, (_, c) in enumerate(plain) if c.channel in RECORDED}
        self._accel_cols = [col.get(f"accel_{a}", -1) for a in "xyz"]
        self._gyro_cols = [col.get(f"gyro_{a}", -1) for a in "xyz"]
        self._float_cols = [
            (j, FLAG_BITS[c.channel])
            for j, (f, c) in enumerate(plain)
            if c.channel in RECORDED and f.type.startswith("float")
        ]
        self._temp_cols = [j for j, (_, c) in enumerate(plain) if c.channel == "temperature"]
        self._extra_cols: list[tuple[str, int]] = []
        seen: set[str] = set()
        for j, (f, c) in enumerate(plain):
            if c.channel not in RECORDED and c.channel != "temperature":
                ch = "unit_time" if c.channel == "time" else c.channel  # a time stamp not used as bench time
                self._extra_cols.append((ch if ch not in seen else f.name, j))
                seen.add(ch)
        self._mux = [f for f in d.fields if f.mux]
        self._has_temp = bool(self._temp_cols) or any(ch == "temperature" for f in self._mux for _, ch, _s, _u in f.mux)
        self._status_masks = [(s, np.uint16(sum(1 << FLAG_BITS[ch] for ch in s.channels))) for s in d.status]
        # multi-layout description: one converter per data layout (index as in FrameBatch.layout)
        self._subs: dict[int, SampleConverter] = {}
        if fmt.alternates:
            base = FrameFormat(
                replace(d, alternates=()), fmt.options, fmt.sample_rate, fmt.conversions, fmt.counter_step
            )
            self._subs[0] = SampleConverter(base)
            for k, (role, alt) in enumerate(fmt.alternates, 1):
                if role == "data":
                    self._subs[k] = SampleConverter(alt)

    def _triad(self, si: NDArray[np.float64], cols: list[int], n: int) -> NDArray[np.float64]:
        if min(cols) >= 0:
            return si[:, cols]
        out = np.full((n, 3), np.nan)  # a channel the format does not carry is NaN (and flagged)
        for i, c in enumerate(cols):
            if c >= 0:
                out[:, i] = si[:, c]
        return out

    @property
    def absent_flags(self) -> np.uint16:
        """Status bits of the recorded channels the format never carries (an accelerometer-only unit's gyro):
        set on every sample, they say "not measured", not "the unit flagged this sample"."""
        if self._subs:
            out = np.uint16(0xFFFF)
            for sub in self._subs.values():
                out &= sub.absent_flags
            return np.uint16(out)
        return self._absent

    def convert(self, batch: FrameBatch) -> Samples:
        """SI samples of ``batch`` (in stream order, duplicates removed)."""
        if self._subs:
            return self._convert_multi(batch)
        d = self.fmt.desc
        n = len(batch)
        vals = batch.values
        if d.counter is not None and n:
            raw_counter = vals[d.counter.field].astype(np.int64)
            chk = self.tracker.update(raw_counter)
        else:
            raw_counter = np.zeros(n, np.int64)
            chk = self.tracker.update_uncounted(n)
        return self._finish(chk, raw_counter, *self._fields(vals, n))

    def _convert_multi(self, batch: FrameBatch) -> Samples:
        """A multi-layout batch: each layout's group converted by its own converter, merged in stream order,
        then one counter check over the merged counter (the counter runs on across layouts)."""
        lay = batch.layout if batch.layout is not None else np.zeros(0, np.intp)
        n = int(lay.size)
        accel, gyro = np.full((n, 3), np.nan), np.full((n, 3), np.nan)
        temperature = np.full(n, np.nan)
        status = np.zeros(n, np.uint16)
        raw_counter = np.zeros(n, np.int64)
        time_si: NDArray[np.float64] | None = None
        extras: dict[str, NDArray] = {}
        if len(batch.groups) == 1:  # the usual case: one layout, no scattering
            k, group = next(iter(batch.groups.items()))
            sub = self._subs[k]
            a, g, t, st, ex, tm = sub._fields(group.values, len(group))
            c = sub.fmt.desc.counter
            rc = group.values[c.field].astype(np.int64) if c is not None else np.zeros(n, np.int64)
            chk = self.tracker.update(rc) if c is not None and n else self.tracker.update_uncounted(n)
            return self._finish(chk, rc, a, g, t, st, ex, tm)
        for k, group in batch.groups.items():
            sub = self._subs[k]
            sel = lay == k
            a, g, t, st, ex, tm = sub._fields(group.values, len(group))
            accel[sel], gyro[sel], temperature[sel], status[sel] = a, g, t, st
            c = sub.fmt.desc.counter
            if c is not None:
                raw_counter[sel] = group.values[c.field]
            if tm is not None:
                time_si = np.full(n, np.nan) if time_si is None else time_si
                time_si[sel] = tm
            for key, v in ex.items():
                if key not in extras:
                    extras[key] = np.full(n, np.nan)
                extras[key][sel] = v
        if self.fmt.desc.counter is not None and n:
            chk = self.tracker.update(raw_counter)
        else:
            chk = self.tracker.update_uncounted(n)
        return self._finish(chk, raw_counter, accel, gyro, temperature, status, extras, time_si)

    def _fields(self, vals: dict[str, NDArray], n: int) -> tuple:
        """(accel, gyro, temperature, status, extras, time or None) of one layout's frames, SI."""
        fmt, d = self.fmt, self.fmt.desc
        rate = fmt.sample_rate
        if self._names and n:
            si = np.column_stack([vals[name] for name in self._names]) * self._factor
            if self._offset is not None:
                si += self._offset
        else:
            si = np.zeros((n, len(self._names)))
        accel = self._triad(si, self._accel_cols, n)
        gyro = self._triad(si, self._gyro_cols, n)
        status = np.full(n, self._absent, dtype=np.uint16)
        if self._float_cols and not np.isfinite(si[:, [j for j, _ in self._float_cols]]).all():
            for j, bit in self._float_cols:  # a non-finite float (KVH) flags its channel
                status[~np.isfinite(si[:, j])] |= np.uint16(1 << bit)
        temps: list[NDArray[np.float64]] = []
        if len(self._temp_cols) == 1:
            temps.append(si[:, self._temp_cols[0]])
        elif self._temp_cols:
            temps.append(si[:, self._temp_cols].mean(axis=1))
        extras: dict[str, NDArray] = {name: si[:, j] for name, j in self._extra_cols}
        for f in self._mux:
            raw = vals[f.name]
            sel = vals[f.mux_selector].astype(np.int64) % f.mux_modulus  # type: ignore[index]
            for slot, ch, _s, _u in f.mux:
                v = np.where(sel == slot, _si(raw, fmt.conversions[(f.name, slot)], rate), np.nan)
                if ch == "temperature":
                    temps.append(v)
                else:
                    extras[ch] = v
        time_si: NDArray[np.float64] | None = None
        if d.time_field is not None and n:
            time_si = self._time(vals[d.time_field], fmt.conversions[d.time_field])
        for st, mask in self._status_masks:
            raw = vals[st.field]
            extras[f"status:{st.field}"] = raw
            if st.valid == "flags":
                status |= (raw.astype(np.int64) & 0xFFFF).astype(np.uint16)
            elif st.valid == "zero":
                if mask and raw.any():
                    status[raw != 0] |= mask
            elif st.valid == "bits_clear":
                r = raw.astype(np.int64)
                bad_bits = sum(1 << bit for bit in {b for _ch, b in st.bits})  # a bit may flag several channels
                if (r & bad_bits).any():  # some channel flagged (clipping…): flag it
                    for ch, bit in st.bits:
                        status[((r >> bit) & 1) == 1] |= np.uint16(1 << FLAG_BITS[ch])
            else:
                r = raw.astype(np.int64)
                valid_bits = sum(1 << bit for bit in {b for _ch, b in st.bits})
                if ((~r) & valid_bits).any():  # some channel not valid (rare): flag it
                    for ch, bit in st.bits:
                        status[((r >> bit) & 1) == 0] |= np.uint16(1 << FLAG_BITS[ch])
        temperature = self._temperature(temps, n)
        if self._has_temp:  # a format without a temperature records NaN (not measured), which is not a fault
            status[~np.isfinite(temperature)] |= _TEMP_FLAG
        return accel, gyro, temperature, status, extras, time_si

    def _finish(
        self,
        chk: CounterCheck,
        raw_counter: NDArray[np.int64],
        accel: NDArray[np.float64],
        gyro: NDArray[np.float64],
        temperature: NDArray[np.float64],
        status: NDArray[np.uint16],
        extras: dict[str, NDArray],
        time_si: NDArray[np.float64] | None,
    ) -> Samples:
        rate = self.fmt.sample_rate
        index = chk.index
        if time_si is None:
            time_si = index.astype(np.float64) / rate
        if chk.duplicates:
            keep = chk.keep
            index, raw_counter, time_si = index[keep], raw_counter[keep], time_si[keep]
            accel, gyro, temperature, status = accel[keep], gyro[keep], temperature[keep], status[keep]
            extras = {k: v[keep] for k, v in extras.items()}
        return Samples(
            index=index,
            counter=raw_counter,
            time=time_si,
            accel=accel,
            gyro=gyro,
            temperature=temperature,
            status=status,
            extras=extras,
            gaps=chk.gaps,
            resets=chk.resets,
            duplicates=chk.duplicates,
        )

    def _time(self, raw: NDArray, c: Conversion) -> NDArray[np.float64]:
        """Time stamps in s; a wrapping stamp (``time.modulus``) is unwrapped across feeds."""
        mod = self.fmt.desc.time_modulus
        if not mod:
            return raw.astype(np.float64) * c.factor
        r = raw.astype(np.int64)
        if self._time_last_raw is None:
            prev, base = int(r[0]), int(r[0])
        else:
            prev, base = self._time_last_raw, self._time_unwrapped
        unwrapped = base + np.cumsum(np.diff(np.concatenate([[prev], r])) % mod)
        self._time_last_raw = int(r[-1])
        self._time_unwrapped = int(unwrapped[-1])
        return unwrapped.astype(np.float64) * c.factor

    def _temperature(self, temps: list[NDArray[np.float64]], n: int) -> NDArray[np.float64]:
        if not temps:
            return np.full(n, np.nan)
        t = temps[0] if len(temps) == 1 else np.nanmean(np.stack(temps), axis=0)
        if n and np.isnan(t).any():
            # multiplexed temperature: hold the last value sent (the first ones take the first value sent)
            ok = ~np.isnan(t)
            idx = np.where(ok, np.arange(n), -1)
            np.maximum.accumulate(idx, out=idx)
            filled = np.where(idx >= 0, t[np.maximum(idx, 0)], np.nan)
            if self._last_temp is not None:
                filled = np.where(idx >= 0, filled, self._last_temp)
            elif ok.any():
                filled = np.where(idx >= 0, filled, t[np.flatnonzero(ok)[0]])
            t = filled
        if n and np.isfinite(t[-1]):
            self._last_temp = float(t[-1])
        return t


def _raw_for(v: NDArray[np.float64], c: Conversion, rate: float, ftype: str) -> NDArray:
    x = v - c.offset if c.offset else v
    x = x / c.factor
    if c.increment:
        x = x / rate
    kind, size = TYPES[ftype]
    if kind.startswith("f"):
        return x
    bits = 8 * size
    lo, hi = (-(1 << (bits - 1)), (1 << (bits - 1)) - 1) if kind.startswith("i") else (0, (1 << bits) - 1)
    return np.clip(np.rint(np.nan_to_num(x)), lo, hi).astype(np.int64)


def encode_samples(
    fmt: FrameFormat,
    index: NDArray[np.int64],
    time: NDArray[np.float64],
    accel: NDArray[np.float64],
    gyro: NDArray[np.float64],
    temperature: NDArray[np.float64],
    status: NDArray[np.uint16] | None = None,
    codec: FrameCodec | None = None,
) -> NDArray[np.uint8]:
    """Frames (n, length) carrying SI samples in format ``fmt`` (the simulated unit's output stage).

    Values are quantised to the field types (24-bit, 16-bit, float32…) and clipped to their range; the
    counter is ``index × step mod modulus``; a time-stamp field carries ``time``; inclinometers carry the
    accelerometers' specific force; status fields carry their ``sim_value`` (the all-valid pattern) unless
    ``status`` (project flags) is given for a ``flags`` field. Body frame b, SI in.
    """
    d = fmt.desc
    codec = codec or FrameCodec(d)
    n = int(index.shape[0])
    rate = fmt.sample_rate
    si: dict[str, NDArray[np.float64]] = {ch: (accel if i < 3 else gyro)[:, i % 3] for i, ch in enumerate(RECORDED)}
    si.update({f"incl_{a}": accel[:, i] for i, a in enumerate("xyz")})
    si["temperature"] = temperature
    si["time"] = time
    values: dict[str, NDArray] = {}
    for f in d.fields:
        if d.counter is not None and f.name == d.counter.field:
            values[f.name] = (index * fmt.counter_step) % d.counter.modulus
            continue
        if f.mux:
            sel = (
                (index * fmt.counter_step) % f.mux_modulus
                if f.mux_selector == (d.counter.field if d.counter else None)
                else 0
            )
            out = np.zeros(n)
            for slot, ch, _s, _u in f.mux:
                c = fmt.conversions[(f.name, slot)]
                src = si.get(ch)
                if src is not None:
                    out = np.where(sel == slot, _raw_for(src, c, rate, f.type), out)
            values[f.name] = out
            continue
        c = fmt.conversions.get(f.name)
        if c is not None and c.channel in si:
            raw = _raw_for(si[c.channel], c, rate, f.type)
            if c.channel == "time":
                bits = 8 * TYPES[f.type][1]
                raw = np.rint(si["time"] / c.factor).astype(np.int64)
                if bits < 63:
                    raw = raw % (1 << bits)
            values[f.name] = raw
            continue
        values[f.name] = np.full(n, f.sim_value)
    for s in d.status:
        if s.valid == "flags" and status is not None:
            values[s.field] = status
    return codec.encode(values, n)
