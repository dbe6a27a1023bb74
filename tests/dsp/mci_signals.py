"""Known-answer signals for the cepstrum and MCI tests, built in the angle domain.

:func:`spalled_average` is a zero-mean (AC-coupled) synchronous average of one pinion
revolution: mesh harmonics + the seed's spall signature W'' (second derivative of a
rectangular window, seed eq. 18) convolved with a damped structural impulse response, placed
after the pitch angle of a chosen tooth (the transfer-path delay of notes §4), + noise.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray


def echo_term(length: int, delay_samples: int, gain: float) -> NDArray[np.float64]:
    """``δ[n] + g·δ[n − τ]`` on ``length`` samples (seed eq. 16)."""
    signal = np.zeros(length)
    signal[0] = 1.0
    signal[delay_samples % length] += gain
    return signal


def echo_cepstrum_closed_form(
    length: int, delay_samples: int, gain: float, terms: int = 400
) -> NDArray[np.float64]:
    """Real cepstrum of an echo term, seed eq. 17, aliased onto a length-``length`` DFT.

    ``c[±kτ] += (−1)^{k+1} g^k/(2k)`` for ``k ≥ 1``, indices modulo ``length``; ``|g| < 1``.
    """
    ceps = np.zeros(length)
    for k in range(1, terms + 1):
        term = (-1.0) ** (k + 1) * gain**k / (2 * k)
        ceps[(k * delay_samples) % length] += term
        ceps[(-k * delay_samples) % length] += term
    return ceps


def rectangular_window_second_derivative(
    length: int, width_samples: int, amplitude: float = 1.0
) -> NDArray[np.float64]:
    """``A·(δ[n] − δ[n−1] − δ[n−N] + δ[n−N−1])`` = A·e_{1,−1} * e_{N,−1} (seed eq. 18)."""
    signal = np.zeros(length)
    signal[0] += amplitude
    signal[1] -= amplitude
    signal[width_samples] -= amplitude
    signal[width_samples + 1] += amplitude
    return signal


def damped_impulse_response(
    length: int, cycles_per_sample: float, damping_ratio: float
) -> NDArray[np.float64]:
    """Unit-peak impulse response of one damped structural mode, ``length`` samples."""
    n = np.arange(length)
    omega = 2 * np.pi * cycles_per_sample
    response = np.exp(-damping_ratio * omega * n) * np.sin(
        omega * np.sqrt(1 - damping_ratio**2) * n
    )
    return response / np.max(np.abs(response))


@dataclass(frozen=True)
class SpalledAverage:
    signal: NDArray[np.float64]
    """One revolution, zero mean."""
    spall_tooth: int
    event_centre_sample: int
    """Centre of the W'' pattern convolved with the structural response's main lobe."""
    tooth1_pitch_angle_deg: float
    pinion_teeth: int
    samples_per_mesh: int


def spalled_average(
    rng: np.random.Generator,
    *,
    spall_tooth: int,
    pinion_teeth: int = 20,
    samples_per_mesh: int = 64,
    tooth1_pitch_angle_deg: float = 0.0,
    spall_width_samples: int = 10,
    spall_amplitude: float = 0.3,
    noise_rms: float = 0.02,
    mesh_amplitudes: tuple[float, ...] = (1.0, 0.5, 0.25),
    resonance_cycles_per_sample: float = 0.2,
    damping_ratio: float = 0.08,
    transfer_delay_samples: int = 3,
    once_per_rev_modulation: float = 0.0,
) -> SpalledAverage:
    """A zero-mean pinion average with a spall on ``spall_tooth`` (1-based); ``spall_amplitude=0``
    gives a healthy one. Mesh phases are random; ``once_per_rev_modulation`` is the depth of a
    slow amplitude modulation of the meshing (eccentricity-like)."""
    samples_per_rev = pinion_teeth * samples_per_mesh
    n = np.arange(samples_per_rev)
    mesh_phase = 2 * np.pi * n / samples_per_mesh
    mesh = sum(
        amplitude * np.cos((h + 1) * mesh_phase + rng.uniform(0, 2 * np.pi))
        for h, amplitude in enumerate(mesh_amplitudes)
    )
    modulation = 1.0 + once_per_rev_modulation * np.cos(
        2 * np.pi * n / samples_per_rev + rng.uniform(0, 2 * np.pi)
    )
    signal = np.asarray(mesh, dtype=np.float64) * modulation

    pitch_deg = (tooth1_pitch_angle_deg + 360.0 * (spall_tooth - 1) / pinion_teeth) % 360.0
    start = round(pitch_deg / 360.0 * samples_per_rev) + transfer_delay_samples
    excitation = rectangular_window_second_derivative(samples_per_rev, spall_width_samples)
    response = damped_impulse_response(samples_per_rev, resonance_cycles_per_sample, damping_ratio)
    # circular convolution: the revolution repeats
    pattern = np.fft.irfft(np.fft.rfft(excitation) * np.fft.rfft(response), n=samples_per_rev)
    signal += spall_amplitude * np.roll(pattern, start)
    signal += noise_rms * rng.standard_normal(samples_per_rev)
    signal -= signal.mean()  # AC coupling: an average of a zero-mean signal
    ringing = round(1.0 / (2 * np.pi * resonance_cycles_per_sample * damping_ratio))
    centre = (start + (spall_width_samples + 1 + ringing) // 2) % samples_per_rev
    return SpalledAverage(
        signal=signal,
        spall_tooth=spall_tooth,
        event_centre_sample=centre,
        tooth1_pitch_angle_deg=tooth1_pitch_angle_deg,
        pinion_teeth=pinion_teeth,
        samples_per_mesh=samples_per_mesh,
    )


def random_spalled_average(
    rng: np.random.Generator,
    *,
    noise_rms: float,
    spall_amplitude: float,
    once_per_rev_modulation: float = 0.0,
    pinion_teeth: int = 20,
) -> SpalledAverage:
    """A :func:`spalled_average` with random tooth, pitch offset, spall width, resonance and
    damping (the campaign used for the hit-rate table in :mod:`dsp.mci`)."""
    return spalled_average(
        rng,
        spall_tooth=int(rng.integers(1, pinion_teeth + 1)),
        pinion_teeth=pinion_teeth,
        tooth1_pitch_angle_deg=float(rng.uniform(0, 360)),
        spall_width_samples=int(rng.integers(6, 15)),
        spall_amplitude=spall_amplitude,
        noise_rms=noise_rms,
        resonance_cycles_per_sample=float(rng.uniform(0.1, 0.35)),
        damping_ratio=float(rng.uniform(0.05, 0.15)),
        transfer_delay_samples=int(rng.integers(0, 6)),
        once_per_rev_modulation=once_per_rev_modulation,
    )
