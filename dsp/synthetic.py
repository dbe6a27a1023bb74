"""Known-answer synthetic gear records for tests, benchmarks and the demo.

:func:`synthetic_gear_record` builds an accelerometer signal in the **angle domain**: every
deterministic component is a band-limited Fourier series in the angle of the shaft it belongs to,
evaluated at the true shaft angle ``θ(t)`` of a known, slowly fluctuating speed profile. The exact,
noise-free synchronous average of each shaft is therefore known in closed form
(:meth:`SyntheticRecord.true_pinion_average`, :meth:`SyntheticRecord.true_gear_average`).

Components (pinion angle ``θ`` and gear angle ``γ = θ·Z1/Z2`` in revolutions, both 0 at the
first tachometer pulse):

- **mesh**: ``Σ_h A_h cos(2π h Z1 (θ - θ1))``, ``θ1`` = tooth 1's pitch angle;
- **gear-shaft component**: ``B cos(2π m γ + 0.7)`` at gear order ``m``; it sits at the
  non-integer pinion order ``m·Z1/Z2`` (for coprime tooth counts and ``m`` not a multiple of Z2),
  so it averages out of the pinion average and appears in the gear average;
- **spall** on pinion tooth ``k`` (El Badaoui et al. 2001, §2-3): the second derivative ``W''``
  of a rectangular window of width ``spall_width_deg`` (the defect trace in the profile
  direction), centred on tooth ``k``'s pitch angle ``θ1 + (k-1)/Z1``, convolved with the impulse
  response of one damped structural mode ``h(τ) = exp(-ζωτ) sin(ω_d τ)``. Since
  ``W'' * h = h'(θ - θ_a) - h'(θ - θ_b)``, the spall adds a decaying ring of the mode, started
  with opposite signs at the two window edges. ``spall_depth`` is the amplitude of each ring at
  its start, before the band limit below rounds the start off. The mode is expressed in angle at the *nominal* speed (``ω`` in rad per revolution
  = ``2π f_mode / f_rev``), which keeps the spall exactly pinion-periodic;
- **band limit**: every pinion- and gear-periodic component is multiplied, order by order, by a
  raised-cosine taper equal to 1 up to ``bandwidth_hz / 2`` and 0 from ``bandwidth_hz`` (in Hz at
  the nominal speed; equivalently, the spall's edges are slightly rounded). The record is thus
  alias-free and its averages exactly known on any grid finer than twice the top order;
- white Gaussian noise of RMS ``noise_rms``.

Speed: ``f(t) = f0 (1 + a sin(2π t / T))`` revolutions of the pinion per second, with
``a = speed_fluctuation`` and ``T = speed_fluctuation_period_s``; so the per-revolution speed
varies by about ``2a`` peak to peak. The tachometer is a 0-5 V TTL square wave on the chosen shaft,
``pulses_per_rev`` rising edges per revolution (the first at a random angle after the start), each
edge a 2-sample linear ramp whose midpoint (2.5 V) is exactly at the pulse time.

Examples
--------
>>> rec = synthetic_gear_record(duration_s=1.0, spall_tooth=16, seed=1)
>>> rec.acceleration.shape, rec.pulse_times_s.size
((20000,), 17)
>>> rec.true_pinion_average(1280).shape
(1280,)
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Literal

import numba
import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = ["SyntheticRecord", "synthetic_gear_record"]

FloatArray = NDArray[np.float64]
ComplexArray = NDArray[np.complex128]

TTL_HIGH_V = 5.0
GEAR_COMPONENT_PHASE_RAD = 0.7


@numba.njit(cache=True)
def _real_fourier_series(coefficients: ComplexArray, angle_rev: FloatArray) -> FloatArray:
    """``Re Σ_k c_k exp(2πi k θ)`` at every angle, by the recurrence ``z^k = z^(k-1)·z``."""
    out = np.empty(angle_rev.size)
    n_orders = coefficients.size
    for n in range(angle_rev.size):
        theta = angle_rev[n] - np.floor(angle_rev[n])  # reduce first: keeps z accurate
        z = complex(np.cos(2.0 * np.pi * theta), np.sin(2.0 * np.pi * theta))
        zk = complex(1.0, 0.0)
        acc = coefficients[0].real
        for k in range(1, n_orders):
            zk *= z
            acc += coefficients[k].real * zk.real - coefficients[k].imag * zk.imag
        out[n] = acc
    return out


def _series_at(coefficients: ComplexArray, angle_rev: ArrayLike) -> FloatArray:
    nonzero = np.flatnonzero(coefficients)
    angles = np.ascontiguousarray(angle_rev, dtype=np.float64)
    if nonzero.size == 0:
        return np.zeros(angles.shape)
    coeffs = np.ascontiguousarray(coefficients[: nonzero[-1] + 1], dtype=np.complex128)
    return _real_fourier_series(coeffs, angles.ravel()).reshape(angles.shape)


@dataclass(frozen=True)
class SyntheticRecord:
    """A synthetic record and everything needed to know its exact answer.

    Fourier coefficients are one-sided: a component is ``Re Σ_k c[k] exp(2πi k angle)`` with the
    angle in revolutions of the shaft named in the attribute.

    Attributes
    ----------
    acceleration : ndarray
        Accelerometer signal (zero mean, arbitrary units).
    tach_waveform : ndarray
        0-5 V TTL tachometer waveform on ``tach_shaft``.
    pulse_times_s : ndarray
        Exact rising-edge (pulse) times within the record (s).
    sample_rate_hz : float
    pinion_coefficients : ndarray of complex
        Pinion-periodic components (mesh + spall), index = pinion order.
    gear_coefficients : ndarray of complex
        Gear-only components, index = gear order.
    initial_pinion_angle_rev : float
        Pinion angle at t = 0 (negative: the reference pulse comes later).
    """

    acceleration: FloatArray
    tach_waveform: FloatArray
    pulse_times_s: FloatArray
    sample_rate_hz: float
    pinion_teeth: int
    gear_teeth: int
    pinion_rpm: float
    speed_fluctuation: float
    speed_fluctuation_period_s: float
    tach_shaft: Literal["pinion", "gear"]
    pulses_per_rev: int
    spall_tooth: int | None
    tooth1_pitch_angle_deg: float
    noise_rms: float
    seed: int
    pinion_coefficients: ComplexArray = field(repr=False)
    gear_coefficients: ComplexArray = field(repr=False)
    initial_pinion_angle_rev: float = 0.0
    parameters: dict[str, Any] = field(default_factory=dict, repr=False)
    """Every argument :func:`synthetic_gear_record` was called with."""

    @property
    def tach_shaft_ratio(self) -> float:
        """Tach-shaft revolutions per pinion revolution."""
        return 1.0 if self.tach_shaft == "pinion" else self.pinion_teeth / self.gear_teeth

    @property
    def pinion_ratio(self) -> float:
        """Pinion revolutions per tach-shaft revolution (``shaft_ratio`` for the pinion)."""
        return 1.0 / self.tach_shaft_ratio

    @property
    def gear_ratio(self) -> float:
        """Gear revolutions per tach-shaft revolution (``shaft_ratio`` for the gear)."""
        return self.pinion_ratio * self.pinion_teeth / self.gear_teeth

    @property
    def tooth_pitch_angles_deg(self) -> FloatArray:
        """Pitch angle of pinion teeth 1..Z1 after the reference pulse, in [0, 360)."""
        angles = (
            self.tooth1_pitch_angle_deg + np.arange(self.pinion_teeth) * 360.0 / self.pinion_teeth
        )
        return np.asarray(np.mod(angles, 360.0), dtype=np.float64)

    @property
    def spall_pitch_angle_deg(self) -> float | None:
        """Pitch angle of the spalled tooth (the spall window's centre), or None."""
        if self.spall_tooth is None:
            return None
        return float(self.tooth_pitch_angles_deg[self.spall_tooth - 1])

    def pinion_angle_rev(self, time_s: ArrayLike) -> FloatArray:
        """True pinion angle (revolutions after the reference pulse) at the given times."""
        return _pinion_angle_rev(
            np.asarray(time_s, dtype=np.float64),
            self.initial_pinion_angle_rev,
            self.pinion_rpm / 60.0,
            self.speed_fluctuation,
            self.speed_fluctuation_period_s,
        )

    def _average(
        self,
        own: ComplexArray,
        other: ComplexArray,
        own_teeth: int,
        other_teeth: int,
        samples_per_rev: int,
        n_revs: int | None,
    ) -> FloatArray:
        """Noise-free average over own-shaft revolutions on the grid ``j / samples_per_rev``.

        A component at order ``m`` of the other shaft is at own order ``q = m·own_teeth /
        other_teeth`` (both shafts turn through the same mesh angle). Averaged over revolutions
        ``r = 0 .. n-1`` it becomes ``c·S·exp(2πi q j/N)`` with ``S = mean_r exp(2πi q r)``:
        ``S = 1`` when ``q`` is an integer (periodic in the own shaft), otherwise ``S → 0`` as
        ``n`` grows (exactly 0 over whole hunting periods). ``n_revs=None`` is that limit.
        """
        angles = np.arange(samples_per_rev) / samples_per_rev
        values = _series_at(own, angles)
        orders = np.flatnonzero(other)
        if orders.size == 0:
            return values
        own_orders = orders * own_teeth / other_teeth
        integer = (orders * own_teeth) % other_teeth == 0
        if n_revs is None:
            weights = integer.astype(np.float64).astype(np.complex128)
        else:
            if n_revs < 1:
                raise ValueError(f"n_revs must be >= 1, got {n_revs}")
            r = np.arange(n_revs)
            weights = np.exp(2j * np.pi * np.outer(own_orders, r)).mean(axis=1)
            weights[integer] = 1.0  # exact, without rounding
        phases = np.exp(2j * np.pi * np.outer(angles, own_orders))
        return np.asarray(values + (phases @ (other[orders] * weights)).real, dtype=np.float64)

    def true_pinion_average(self, samples_per_rev: int, n_revs: int | None = None) -> FloatArray:
        """Exact noise-free pinion synchronous average on ``samples_per_rev`` grid angles.

        Grid angle ``j / samples_per_rev`` pinion revolutions after the reference pulse. With
        ``n_revs=None`` this is the limit of the average (mesh, spall, and any gear component
        that is also pinion-periodic); the gear-shaft component cancels exactly only over whole
        hunting periods (``Z2 / gcd(Z1, Z2)`` pinion revolutions). With ``n_revs`` it is the exact
        average of the first ``n_revs`` pinion revolutions, including what is left of the
        gear-shaft component.
        """
        return self._average(
            self.pinion_coefficients,
            self.gear_coefficients,
            self.pinion_teeth,
            self.gear_teeth,
            samples_per_rev,
            n_revs,
        )

    def true_gear_average(self, samples_per_rev: int, n_revs: int | None = None) -> FloatArray:
        """Exact noise-free gear synchronous average (mesh, gear component, gear-periodic part of
        the spall) on ``samples_per_rev`` grid angles after the reference pulse; with ``n_revs``,
        the exact average of the first ``n_revs`` gear revolutions (what is left of the spall
        included)."""
        return self._average(
            self.gear_coefficients,
            self.pinion_coefficients,
            self.gear_teeth,
            self.pinion_teeth,
            samples_per_rev,
            n_revs,
        )


def _pinion_angle_rev(
    time_s: FloatArray, angle0_rev: float, f0_hz: float, fluctuation: float, period_s: float
) -> FloatArray:
    # θ(t) = θ0 + ∫ f0 (1 + a sin(2π t / T)) dt
    w = 2.0 * np.pi / period_s
    return np.asarray(
        angle0_rev + f0_hz * time_s - f0_hz * fluctuation / w * (np.cos(w * time_s) - 1.0),
        dtype=np.float64,
    )


def _solve_times(
    targets_rev: FloatArray, angle0_rev: float, f0_hz: float, fluctuation: float, period_s: float
) -> FloatArray:
    """Times at which the pinion reaches the given angles (Newton; θ is strictly increasing)."""
    t = (targets_rev - angle0_rev) / f0_hz
    w = 2.0 * np.pi / period_s
    for _ in range(50):
        residual = _pinion_angle_rev(t, angle0_rev, f0_hz, fluctuation, period_s) - targets_rev
        t = t - residual / (f0_hz * (1.0 + fluctuation * np.sin(w * t)))
        if np.max(np.abs(residual), initial=0.0) < 1e-13 * max(
            1.0, float(np.max(np.abs(targets_rev), initial=1.0))
        ):
            break
    return np.asarray(t, dtype=np.float64)


def _taper(orders: FloatArray, top_order: float) -> FloatArray:
    """Raised cosine: 1 up to top_order/2, 0 from top_order."""
    x = np.clip((orders - 0.5 * top_order) / (0.5 * top_order), 0.0, 1.0)
    return np.asarray(0.5 + 0.5 * np.cos(np.pi * x), dtype=np.float64)


def synthetic_gear_record(
    *,
    duration_s: float,
    sample_rate_hz: float = 20_000.0,
    pinion_teeth: int = 20,
    gear_teeth: int = 21,
    pinion_rpm: float = 1000.0,
    speed_fluctuation: float = 0.01,
    speed_fluctuation_period_s: float = 5.0,
    mesh_harmonic_amplitudes: tuple[float, ...] = (1.0, 0.5, 0.25),
    gear_order_amplitude: float = 0.3,
    gear_order: int = 1,
    spall_tooth: int | None = None,
    spall_depth: float = 0.3,
    spall_width_deg: float = 2.8125,
    tooth1_pitch_angle_deg: float = 0.0,
    structural_mode_hz: float = 2400.0,
    structural_damping_ratio: float = 0.05,
    bandwidth_hz: float = 6000.0,
    noise_rms: float = 0.05,
    tach_shaft: Literal["pinion", "gear"] = "pinion",
    pulses_per_rev: int = 1,
    tach_duty_cycle: float = 0.25,
    seed: int = 0,
) -> SyntheticRecord:
    """Build a known-answer synthetic gear record (see the module docstring for the model).

    Parameters
    ----------
    duration_s : float
        Record length (s).
    sample_rate_hz : float
        Sampling rate.
    pinion_teeth, gear_teeth : int
        Tooth counts Z1, Z2.
    pinion_rpm : float
        Nominal pinion speed.
    speed_fluctuation : float
        Relative amplitude ``a`` of the slow sinusoidal speed fluctuation, in [0, 0.5).
    speed_fluctuation_period_s : float
        Its period ``T``.
    mesh_harmonic_amplitudes : tuple of float
        ``A_h`` of mesh harmonics 1, 2, ...
    gear_order_amplitude : float
        Amplitude ``B`` of the gear-shaft component.
    gear_order : int
        Its gear order ``m``.
    spall_tooth : int, optional
        1-based pinion tooth with a spall; None for a healthy pinion.
    spall_depth : float
        Amplitude of each edge's mode ring (same units as the mesh amplitudes).
    spall_width_deg : float
        Width of the spall window in pinion degrees (default: 10 samples at 64 samples per mesh
        period of a 20-tooth pinion, the seed's simulated spall).
    tooth1_pitch_angle_deg : float
        Pinion angle after the reference pulse at which tooth 1 passes the pitch point.
    structural_mode_hz : float
        Natural frequency of the structural mode.
    structural_damping_ratio : float
        Its damping ratio ζ, in (0, 1).
    bandwidth_hz : float
        Top of the raised-cosine band limit (Hz at nominal speed); must stay below the Nyquist
        frequency at the highest speed.
    noise_rms : float
        RMS of the additive white Gaussian noise.
    tach_shaft : {"pinion", "gear"}
        Shaft carrying the tachometer.
    pulses_per_rev : int
        Tach pulses per revolution of ``tach_shaft``.
    tach_duty_cycle : float
        Fraction of each pulse period the TTL is high.
    seed : int
        Seed of the noise and of the initial shaft angle.

    Returns
    -------
    SyntheticRecord

    Examples
    --------
    >>> rec = synthetic_gear_record(duration_s=0.5, noise_rms=0.0, gear_order_amplitude=0.0)
    >>> import numpy as np
    >>> theta = rec.pinion_angle_rev(np.arange(rec.acceleration.size) / rec.sample_rate_hz)
    >>> expected = sum(a * np.cos(2 * np.pi * (h + 1) * 20 * theta)
    ...                for h, a in enumerate((1.0, 0.5, 0.25)))
    >>> bool(np.allclose(rec.acceleration, expected))
    True
    """
    # Long function: a known-answer generator whose stages (mesh and spall by pinion order, the
    # gear's component, the speed profile, the tach, the noise) are written out in order, so that
    # a test can read what the answer is.
    parameters = dict(locals())  # the arguments, before any other local exists
    if not duration_s > 0 or not sample_rate_hz > 0:
        raise ValueError("duration_s and sample_rate_hz must be positive")
    if pinion_teeth < 1 or gear_teeth < 1:
        raise ValueError("tooth counts must be >= 1")
    if not pinion_rpm > 0:
        raise ValueError("pinion_rpm must be positive")
    if not 0 <= speed_fluctuation < 0.5 or not speed_fluctuation_period_s > 0:
        raise ValueError("speed_fluctuation must be in [0, 0.5) and its period positive")
    if spall_tooth is not None and not 1 <= spall_tooth <= pinion_teeth:
        raise ValueError(f"spall_tooth must be in 1..{pinion_teeth}, got {spall_tooth}")
    if not 0 < structural_damping_ratio < 1 or not structural_mode_hz > 0:
        raise ValueError("structural mode needs a positive frequency and damping ratio in (0, 1)")
    if tach_shaft not in ("pinion", "gear"):
        raise ValueError(f"tach_shaft must be 'pinion' or 'gear', got {tach_shaft!r}")
    if pulses_per_rev < 1 or not 0 < tach_duty_cycle < 1:
        raise ValueError("pulses_per_rev must be >= 1 and tach_duty_cycle in (0, 1)")
    if gear_order < 1:
        raise ValueError("gear_order must be >= 1")
    f0_hz = pinion_rpm / 60.0
    if not 0 < bandwidth_hz * (1.0 + speed_fluctuation) < 0.5 * sample_rate_hz:
        raise ValueError(
            f"bandwidth_hz {bandwidth_hz:g} must be positive and, at the highest speed, below the "
            f"Nyquist frequency {0.5 * sample_rate_hz:g} Hz"
        )

    rng = np.random.default_rng(seed)
    n_samples = round(duration_s * sample_rate_hz)
    time_s = np.arange(n_samples) / sample_rate_hz

    # --- pinion-periodic components (mesh + spall), one-sided coefficients by pinion order
    top_pinion_order = bandwidth_hz / f0_hz
    n_pinion_orders = int(np.ceil(top_pinion_order)) + 1
    orders = np.arange(n_pinion_orders, dtype=np.float64)
    pinion = np.zeros(n_pinion_orders, dtype=np.complex128)
    tooth1_rev = tooth1_pitch_angle_deg / 360.0
    for h, amplitude in enumerate(mesh_harmonic_amplitudes, start=1):
        k = h * pinion_teeth
        if k < n_pinion_orders:
            pinion[k] += amplitude * np.exp(-2j * np.pi * k * tooth1_rev)
    if spall_tooth is not None:
        centre_rev = tooth1_rev + (spall_tooth - 1) / pinion_teeth
        half_width_rev = 0.5 * spall_width_deg / 360.0
        omega_n = 2.0 * np.pi * structural_mode_hz / f0_hz  # rad per pinion revolution
        alpha = structural_damping_ratio * omega_n
        beta = omega_n * np.sqrt(1.0 - structural_damping_ratio**2)
        big_omega = 2.0 * np.pi * orders
        mode_response = beta / ((alpha + 1j * big_omega) ** 2 + beta**2)
        # Two-sided coefficient of h'(θ-θa) - h'(θ-θb), periodised; FT[h'] = iΩ H(Ω) as h(0) = 0.
        two_sided = (1j * big_omega * mode_response) * (
            np.exp(-1j * big_omega * (centre_rev - half_width_rev))
            - np.exp(-1j * big_omega * (centre_rev + half_width_rev))
        )
        # h' starts at β; its envelope there is sqrt(α² + β²) = ω_n.
        pinion[1:] += 2.0 * two_sided[1:] * (spall_depth / omega_n)
    pinion *= _taper(orders, top_pinion_order)

    # --- gear-only component, by gear order
    gear_f0_hz = f0_hz * pinion_teeth / gear_teeth
    top_gear_order = bandwidth_hz / gear_f0_hz
    gear = np.zeros(gear_order + 1, dtype=np.complex128)
    gear[gear_order] = gear_order_amplitude * np.exp(1j * GEAR_COMPONENT_PHASE_RAD)
    gear *= _taper(np.arange(gear_order + 1, dtype=np.float64), top_gear_order)

    # --- speed profile: reference pulse (tach angle 0) a random fraction of a pulse after t = 0
    tach_per_pinion = 1.0 if tach_shaft == "pinion" else pinion_teeth / gear_teeth
    start_offset_pulses = 0.2 + 0.6 * rng.random()
    angle0_rev = -start_offset_pulses / (pulses_per_rev * tach_per_pinion)
    args = (angle0_rev, f0_hz, speed_fluctuation, speed_fluctuation_period_s)
    theta = _pinion_angle_rev(time_s, *args)

    acceleration = _series_at(pinion, theta)
    acceleration += _series_at(gear, theta * pinion_teeth / gear_teeth)
    if noise_rms > 0:
        acceleration += noise_rms * rng.standard_normal(n_samples)

    # --- tachometer: rising edge at tach angle k/ppr, falling edge duty·period later
    last_pulse = int(np.ceil(float(theta[-1]) * tach_per_pinion * pulses_per_rev)) + 1
    pulse_index = np.arange(-1, last_pulse + 1, dtype=np.float64)
    per_pulse_rev = 1.0 / (pulses_per_rev * tach_per_pinion)  # pinion revolutions per pulse
    rise_s = _solve_times(pulse_index * per_pulse_rev, *args)
    fall_s = _solve_times((pulse_index + tach_duty_cycle) * per_pulse_rev, *args)
    ramp_s = 2.0 / sample_rate_hz
    # The last edge whose ramp has begun; its falling edge ends the high state.
    edge = np.searchsorted(rise_s, time_s + 0.5 * ramp_s, side="right") - 1
    edge = np.clip(edge, 0, rise_s.size - 1)
    rising = np.clip(0.5 + (time_s - rise_s[edge]) / ramp_s, 0.0, 1.0)
    falling = np.clip(0.5 - (time_s - fall_s[edge]) / ramp_s, 0.0, 1.0)
    tach_waveform = TTL_HIGH_V * rising * falling
    end_s = (n_samples - 1) / sample_rate_hz
    pulse_times = rise_s[(pulse_index >= 0) & (rise_s <= end_s)]

    return SyntheticRecord(
        acceleration=acceleration,
        tach_waveform=tach_waveform,
        pulse_times_s=pulse_times,
        sample_rate_hz=float(sample_rate_hz),
        pinion_teeth=int(pinion_teeth),
        gear_teeth=int(gear_teeth),
        pinion_rpm=float(pinion_rpm),
        speed_fluctuation=float(speed_fluctuation),
        speed_fluctuation_period_s=float(speed_fluctuation_period_s),
        tach_shaft=tach_shaft,
        pulses_per_rev=int(pulses_per_rev),
        spall_tooth=spall_tooth,
        tooth1_pitch_angle_deg=float(tooth1_pitch_angle_deg),
        noise_rms=float(noise_rms),
        seed=int(seed),
        pinion_coefficients=pinion,
        gear_coefficients=gear,
        initial_pinion_angle_rev=float(angle0_rev),
        parameters=parameters,
    )
