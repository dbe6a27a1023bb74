"""Forward model: the simulator's hunting-period spectrum for a configuration, and its transfer path.

The simulator is deterministic without noise and periodic over a hunting period once the
start transient has decayed, so one hunting period after the warm-up is all a prediction
needs. Each configured structural mode of the reconciled sensor is simulated as its own
unit-gain channel ``C_m(k)``; the sensor prediction is ``Y(k) = Σ_m g_m R_m(k) C_m(k)``
with the gains ``g_m`` linear (closed form) and ``R_m = H(f; f'_m, ζ'_m) / H(f; f_m, ζ_m)``
re-tuning a mode's frequency and damping without a new simulation (the transfer path is
linear and time-invariant, ``H(s) = s² / (s² + 2ζωs + ω²)``). A mode the configuration
lacks is ``H_new / H_1 · C_1`` — still the simulator's bearing force, through another path.

Examples
--------
>>> import numpy as np
>>> f = np.array([1000.0, 3000.0])
>>> np.round(np.abs(mode_response(f, 3000.0, 0.05)), 2).tolist()
[0.12, 10.0]
"""

from __future__ import annotations

import dataclasses
import math
from collections import OrderedDict
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from dsp.angle import angle_resample
from physics.config import GearPairModel, Sensor, StructuralMode
from physics.reconcile.observables import revs_per_hunting_period

FloatArray = NDArray[np.float64]
ComplexArray = NDArray[np.complex128]

DEFAULT_REFERENCE_MODE = StructuralMode(frequency_hz=3000.0, damping_ratio=0.5, gain_m_s2_per_n=1.0)
"""Used as the force path when the sensor has no configured mode."""


def mode_response(frequency_hz: FloatArray, mode_frequency_hz: float, damping_ratio: float) -> ComplexArray:
    """Unit-gain ``s² / (s² + 2ζωs + ω²)`` at ``frequency_hz`` (complex).

    Examples
    --------
    >>> round(float(abs(mode_response(np.array([1e6]), 100.0, 0.1))[0]), 3)
    1.0
    """
    s = 2j * np.pi * np.asarray(frequency_hz, dtype=np.float64)
    w = 2 * np.pi * mode_frequency_hz
    return np.asarray(s**2 / (s**2 + 2 * damping_ratio * w * s + w**2), dtype=np.complex128)


@dataclass(frozen=True)
class ForwardSetup:
    """What fixes the prediction grid: speed, hunting period, angle grid, bins, sensor."""

    speed_rpm: float
    pinion_teeth: int
    gear_teeth: int
    samples_per_mesh: int
    n_bins: int
    sensor_index: int = 0
    warmup_s: float | None = None
    """Override of the model's warm-up (None: the model's)."""
    oversampling: int | None = None
    """Override of the model's integrator steps per output sample (None: the model's)."""

    @property
    def revs_per_hunt(self) -> int:
        return revs_per_hunting_period(self.pinion_teeth, self.gear_teeth)

    @property
    def samples_per_rev(self) -> int:
        return self.pinion_teeth * self.samples_per_mesh

    def bin_frequency_hz(self) -> FloatArray:
        hunt_hz = self.speed_rpm / 60.0 / self.revs_per_hunt
        return np.asarray(np.arange(self.n_bins) * hunt_hz, dtype=np.float64)


def reconciled_modes(model: GearPairModel, setup: ForwardSetup) -> list[StructuralMode]:
    sensor = model.sensors[setup.sensor_index]
    return list(sensor.modes) or [DEFAULT_REFERENCE_MODE]


def channel_model(model: GearPairModel, setup: ForwardSetup) -> GearPairModel:
    """The configuration actually simulated: measured speed, one noiseless unit-gain channel per mode."""
    sensor = model.sensors[setup.sensor_index]
    modes = reconciled_modes(model, setup)
    sensors = [
        Sensor(
            name=f"mode{i}",
            source=sensor.source,
            # The sensor's direction: an off-line sensor sees friction, not the mesh force.
            direction=sensor.direction,
            noise_rms_m_s2=0.0,
            modes=[dataclasses.replace(mode, gain_m_s2_per_n=1.0)],
        )
        for i, mode in enumerate(modes)
    ]
    acquisition = model.acquisition
    if setup.warmup_s is not None:
        acquisition = dataclasses.replace(acquisition, warmup_s=setup.warmup_s)
    if setup.oversampling is not None:
        acquisition = dataclasses.replace(acquisition, oversampling=setup.oversampling)
    tach = dataclasses.replace(model.tachometer, name="tach", shaft="pinion")
    return model.replace(
        operating=dataclasses.replace(model.operating, speed_rpm=setup.speed_rpm),
        sensors=sensors,
        tachometer=tach,
        acquisition=acquisition,
    )


class ForwardModel:
    """Cached simulator-in-the-loop predictions on one :class:`ForwardSetup`."""

    def __init__(self, setup: ForwardSetup, cache_size: int = 256) -> None:
        self.setup = setup
        self.frequency_hz = setup.bin_frequency_hz()
        self._cache: OrderedDict[object, ComplexArray] = OrderedDict()
        self._cache_size = cache_size
        self._ratios: dict[tuple[float, float, float, float], ComplexArray] = {}
        """``H(f; f', ζ') / H(f; f, ζ)`` on this grid by (f', ζ', f, ζ): the fit asks for the same
        few re-tunings again and again (every Jacobian column of a non-mode parameter)."""
        self.simulations = 0
        self.on_simulation: Callable[[int], None] | None = None
        """Called with the simulation count after each simulation (progress reporting)."""

    def mode_channels(self, model: GearPairModel) -> ComplexArray:
        """``C_m(k)``, shape ``(n_modes, n_bins)``: each configured mode at unit gain."""
        key = _cache_key(model.replace(sensors=[model.sensors[self.setup.sensor_index]]))
        hit = self._cache.get(key)
        if hit is not None:
            self._cache.move_to_end(key)
            return hit
        value = self._simulate(model)
        self._cache[key] = value
        if len(self._cache) > self._cache_size:
            self._cache.popitem(last=False)
        return value

    def _simulate(self, model: GearPairModel) -> ComplexArray:
        from physics.simulator import simulate

        setup = self.setup
        sim_model = channel_model(model, setup)
        rev_s = 60.0 / setup.speed_rpm
        seconds = (setup.revs_per_hunt + 1.5) * rev_s
        result = simulate(sim_model, seconds=seconds, seed=None)
        self.simulations += 1
        if self.on_simulation is not None:
            self.on_simulation(self.simulations)
        channels = np.stack([result.channels[s.name] for s in sim_model.sensors])
        revs = angle_resample(
            channels,
            result.sample_rate_hz,
            result.tach_pulse_times_s,
            sim_model.tachometer.pulses_per_rev,
            setup.samples_per_rev,
        )
        if revs.shape[-2] < setup.revs_per_hunt:
            raise RuntimeError("simulated record shorter than a hunting period")  # pragma: no cover
        period = revs[:, : setup.revs_per_hunt].reshape(len(sim_model.sensors), -1)
        spectrum = np.fft.rfft(period, axis=-1) / period.shape[-1]
        out: ComplexArray = spectrum[:, : setup.n_bins]
        if out.shape[-1] < setup.n_bins:
            raise ValueError("n_bins exceeds the simulated spectrum")  # pragma: no cover
        return out

    def transfer_columns(
        self,
        channels: ComplexArray,
        configured: list[StructuralMode],
        tuned: list[tuple[float, float]],
        extra: list[tuple[float, float]] = (),  # type: ignore[assignment]
    ) -> ComplexArray:
        """Unit-gain sensor columns: configured modes re-tuned to ``tuned`` (f, ζ), then extra modes.

        An extra mode is the first configured mode's channel through the new mode's path.
        """
        cols = []
        for m, (mode, (f_new, z_new)) in enumerate(zip(configured, tuned, strict=True)):
            if f_new == mode.frequency_hz and z_new == mode.damping_ratio:
                cols.append(channels[m])
            else:
                cols.append(channels[m] * self._ratio(f_new, z_new, mode.frequency_hz, mode.damping_ratio))
        ref = configured[0]
        for f_new, z_new in extra:
            cols.append(channels[0] * self._ratio(f_new, z_new, ref.frequency_hz, ref.damping_ratio))
        return np.stack(cols)

    def _ratio(self, f_new: float, z_new: float, f_old: float, z_old: float) -> ComplexArray:
        key = (f_new, z_new, f_old, z_old)
        hit = self._ratios.get(key)
        if hit is None:
            f = self.frequency_hz
            hit = _safe_ratio(mode_response(f, f_new, z_new), mode_response(f, f_old, z_old))
            if len(self._ratios) >= 256:
                self._ratios.clear()
            self._ratios[key] = hit
        return hit


def _cache_key(value: object) -> object:
    """Exact, hashable image of a configuration for the simulation cache: every field of
    every dataclass in order, floats by their hex digits (no rounding; −0.0 ≠ 0.0). It tells
    apart what the TOML text told apart, at a fraction of its cost (the TOML text of the model
    was ~1 ms, at every evaluation of the fit).

    Examples
    --------
    >>> from physics.config import GearPairModel
    >>> a = GearPairModel()
    >>> _cache_key(a) == _cache_key(GearPairModel())
    True
    >>> b = a.replace(operating=dataclasses.replace(a.operating, load_torque_nm=200.0 + 1e-12))
    >>> _cache_key(a) == _cache_key(b)
    False
    """
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return (type(value).__name__, *(_cache_key(getattr(value, f.name)) for f in dataclasses.fields(value)))
    if isinstance(value, list | tuple):
        return tuple(_cache_key(v) for v in value)
    if isinstance(value, float):
        return float(value).hex()
    if isinstance(value, np.ndarray):
        return (value.dtype.str, value.shape, value.tobytes())
    if isinstance(value, str | int | None):
        return value
    return repr(value)


def _safe_ratio(num: ComplexArray, den: ComplexArray) -> ComplexArray:
    out = np.zeros_like(num)
    ok = np.abs(den) > 0
    out[ok] = num[ok] / den[ok]
    return out


def hunting_frequency_hz(speed_rpm: float, pinion_teeth: int, gear_teeth: int) -> float:
    return speed_rpm / 60.0 / (math.lcm(pinion_teeth, gear_teeth) // pinion_teeth)
