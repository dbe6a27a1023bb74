"""Is a revolution a revolution? A check of a shaft period found without a tachometer.

A mesh-phase angle (:mod:`dsp.tachless`) counts ``teeth`` mesh periods per revolution, but the
speed it starts from can be a wrong member of the line family when no speed hint is given: a
record's strongest lines may be the 2nd or 5th mesh harmonic, and the angle then turns ``r``
times too fast or too slow (``r`` a ratio of small integers). The synchronous average cannot
tell: it is as smooth either way. The *revolutions* can. A shaft's vibration repeats once per
true revolution, so with candidate revolutions of true length ``T·q/p`` (in lowest terms):

* ``p > 1`` (too fast): consecutive candidate revolutions are different pieces of the true one;
  the averages of the revolutions with index ``≡ j (mod m)``, for a prime ``m`` dividing ``p``,
  differ from each other by far more than noise (:func:`residue_z`);
* ``q > 1`` (too slow): a candidate revolution holds ``q`` true ones, so its average repeats
  ``q`` times: its orders not divisible by a prime ``m`` dividing ``q`` hold only noise
  (:func:`unfolded_z`).

Both are tested against the noise measured in the revolutions themselves: the scatter of every
order's complex amplitude from revolution to revolution (:class:`PeriodSums`), so a coloured
noise, a load that wanders within the record or a strong mesh line do not bias them. Mesh
harmonics and order 0 are left out (they are the same for every tooth and do not depend on
which revolution is which).

The other wheel interferes with the first test: its own pattern repeats every ``Z_other / g``
revolutions of this one (``g = gcd`` of the tooth counts), so for a prime ``m`` dividing that
hunting number the residue classes differ on a right angle too, and with a few revolutions per
class it does not cancel for other primes either. The other wheel's synchronous average is
therefore put back into every class as it sits there and taken out, and so is the scatter it
causes (:func:`residue_z` with ``other_average``). The same test on the other wheel's
revolutions is taken when it is the larger (:func:`check_shaft_period`). What neither wheel's
average holds — content that repeats only once per hunting period, a pair of teeth meeting —
can still make a right angle's classes differ: then the angle is refused, never accepted wrong.

Pure: arrays in, numbers and a frozen dataclass out.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from dataclasses import dataclass, field
from fractions import Fraction

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = [
    "MAX_MESH_FAMILY_RATIO",
    "MAX_RESIDUE_Z",
    "MIN_CONTENT_Z",
    "MIN_UNFOLDED_SHARE",
    "MODULI",
    "PeriodCheck",
    "PeriodSums",
    "PeriodSumsAccumulator",
    "check_shaft_period",
    "mesh_family_ratio",
    "residue_z",
    "unfolded_share",
    "unfolded_z",
]

FloatArray = NDArray[np.float64]
ComplexArray = NDArray[np.complex128]

MAX_HARMONIC_RATIO = 16
"""A mesh-phase angle taken from harmonic ``h`` of a line read as harmonic ``h'`` turns ``h/h'``
times too fast, ``h, h' ≤ 16``."""
MODULI = (2, 3, 5, 7, 11, 13)
"""Primes tested: those of the ratios ``h/h'`` (:data:`MAX_HARMONIC_RATIO`)."""
MIN_CONTENT_Z = 6.0
"""The average's orders not divisible by each tested prime must stand this many standard errors
above the noise (else the revolution may be several true ones, or there is too little
tooth-specific content to tell)."""
MIN_UNFOLDED_SHARE = 0.05
"""…and their excess power must be at least this share of the excess at the multiples of the
prime (mesh harmonics left out; :func:`unfolded_share`)."""
MAX_RESIDUE_Z = 3.5
"""…and the residue-class averages of every tested prime may differ by at most this many
standard errors more than noise makes them (else the revolution is a piece of a true one)."""


@dataclass(frozen=True)
class PeriodSums:
    """What the check needs of one shaft's revolutions (``samples_per_rev`` samples each).

    ``residue_sums[m][j]`` is the sum of the revolutions whose index in the record (counted from
    the first revolution, rejected ones included) is ``≡ j (mod m)``; ``order_power`` is
    ``Σ_r |rfft(rev_r)|²``."""

    total: FloatArray
    count: int
    order_power: FloatArray
    residue_sums: dict[int, FloatArray] = field(default_factory=dict)
    residue_counts: dict[int, NDArray[np.int64]] = field(default_factory=dict)
    indices: NDArray[np.int64] = field(default_factory=lambda: np.empty(0, dtype=np.int64))
    """The record index of every revolution summed, in the order added."""


class PeriodSumsAccumulator:
    """Collects :class:`PeriodSums` block by block, revolutions given with their record index."""

    def __init__(self, samples_per_rev: int, moduli: tuple[int, ...] = MODULI) -> None:
        self.samples_per_rev = samples_per_rev
        self.moduli = moduli
        self.total = np.zeros(samples_per_rev)
        self.count = 0
        self.order_power = np.zeros(samples_per_rev // 2 + 1)
        self.sums = {m: np.zeros((m, samples_per_rev)) for m in moduli}
        self.counts = {m: np.zeros(m, dtype=np.int64) for m in moduli}
        self.indices: list[NDArray[np.int64]] = []

    def add(self, revolutions: ArrayLike, indices: ArrayLike) -> None:
        """Add ``revolutions`` (rows), revolution ``i`` being number ``indices[i]`` in the record."""
        revs = np.asarray(revolutions, dtype=np.float64).reshape(-1, self.samples_per_rev)
        index = np.asarray(indices, dtype=np.int64).reshape(-1)
        if revs.shape[0] == 0:
            return
        self.total += revs.sum(axis=0)
        self.count += revs.shape[0]
        self.indices.append(index.copy())
        self.order_power += np.sum(np.abs(np.fft.rfft(revs, axis=1)) ** 2, axis=0)
        for m in self.moduli:
            residue = index % m
            for j in range(m):
                chosen = residue == j
                if chosen.any():
                    self.sums[m][j] += revs[chosen].sum(axis=0)
                    self.counts[m][j] += int(chosen.sum())

    def result(self) -> PeriodSums:
        return PeriodSums(self.total.copy(), self.count, self.order_power.copy(),
                          {m: s.copy() for m, s in self.sums.items()},
                          {m: c.copy() for m, c in self.counts.items()},
                          np.concatenate(self.indices) if self.indices else np.empty(0, dtype=np.int64))


def _orders(sums: PeriodSums, teeth: int) -> tuple[ComplexArray, FloatArray, NDArray[np.bool_]]:
    """The average's spectrum, each order's per-revolution noise variance, the tested orders."""
    n = sums.total.size
    average = np.fft.rfft(sums.total / sums.count)
    variance = (sums.order_power - sums.count * np.abs(average) ** 2) / max(sums.count - 1, 1)
    k = np.arange(average.size)
    tested = (k > 0) & (k % teeth != 0) & (2 * k < n) & (variance > 0)
    return average, np.maximum(variance, 0.0), tested


def unfolded_z(sums: PeriodSums, teeth: int, m: int) -> float:
    """How far the average's orders not divisible by ``m`` stand above their noise (standard
    errors): small when a revolution holds ``m`` true ones (its average repeats ``m`` times).

    Examples
    --------
    A pattern of orders 3 and 7 per true revolution, read once on true revolutions and once on
    "revolutions" twice as long (an angle turning at half the speed):

    >>> import numpy as np
    >>> rng = np.random.default_rng(1)
    >>> n, teeth = 64, 8
    >>> def sums(turns_per_rev):
    ...     theta = np.arange(80 * n) / n * turns_per_rev
    ...     x = np.cos(2 * np.pi * 3 * theta) + np.cos(2 * np.pi * 7 * theta + 1)
    ...     acc = PeriodSumsAccumulator(n)
    ...     acc.add((x + rng.standard_normal(x.size)).reshape(80, n), np.arange(80))
    ...     return acc.result()
    >>> bool(unfolded_z(sums(1), teeth, 2) > 50), bool(unfolded_z(sums(2), teeth, 2) < 3)
    (True, True)
    """
    if sums.count < 2:
        return math.nan
    average, variance, tested = _orders(sums, teeth)
    k = np.arange(average.size)
    chosen = tested & (k % m != 0)
    noise = variance[chosen] / sums.count
    if noise.size == 0 or not np.any(noise > 0):
        return math.nan
    excess = np.sum(np.abs(average[chosen]) ** 2 - noise)
    return float(excess / math.sqrt(np.sum(noise**2)))


def unfolded_share(sums: PeriodSums, teeth: int, m: int) -> float:
    """The average's excess power (above noise) at the orders not divisible by ``m`` over that at
    the orders divisible by it, mesh harmonics and order 0 left out; NaN when the latter is not
    positive.

    :func:`unfolded_z` asks whether those orders hold anything; this asks whether they hold a
    revolution's worth. An angle ``m`` times too slow leaves them only what leaks in — a
    resampling's interpolation, a speed that wanders — which over hundreds of revolutions
    stands far above noise (264 standard errors on a 56/28 pair read at half its speed on the
    independent generator, development seed 1016: every day confirmed) but holds 2–3 % of the
    multiples' content. On right angles (the tach's, development seeds 1000–1019 of
    ``benchmarks/bench_tachless.py``) it was at least 0.63 on the project's simulator and 0.13 on
    the independent generator (a 53/42 pair whose pinion pattern sits mostly at even orders).
    """
    if sums.count < 2:
        return math.nan
    average, variance, tested = _orders(sums, teeth)
    excess = np.abs(average) ** 2 - variance / sums.count
    k = np.arange(average.size)
    on = float(np.sum(excess[tested & (k % m == 0)]))
    off = float(np.sum(excess[tested & (k % m != 0)]))
    return off / on if on > 0 else math.nan


ROWS_PER_CHUNK_SAMPLES = 1 << 22
"""The other wheel's pattern is laid out at most this many samples at a time (32 MB): with 500
teeth on each wheel a full layout would hold up to 500 revolutions' worth."""


def _other_wheel_rows(other_average: ArrayLike, samples_per_rev: int) -> Iterator[tuple[int, FloatArray]]:
    """The other wheel's pattern as it sits in this wheel's revolution ``r``, for every
    ``r mod period``: ``(first offset, rows)`` a chunk at a time. Both grids share one angle step
    and start at the same mark, so sample ``s`` of revolution ``r`` is sample
    ``(r·N + s) mod N_other`` of the pattern."""
    pattern = np.asarray(other_average, dtype=np.float64)
    n_other = pattern.size
    period = _offset_period(pattern, samples_per_rev)
    step = max(1, ROWS_PER_CHUNK_SAMPLES // samples_per_rev)
    for first in range(0, period, step):
        offsets = (np.arange(first, min(period, first + step)) * samples_per_rev) % n_other
        yield first, pattern[(offsets[:, None] + np.arange(samples_per_rev)[None, :]) % n_other]


def _offset_period(other_average: ArrayLike, samples_per_rev: int) -> int:
    """Revolutions of this wheel until the other wheel's pattern sits at the same offset again."""
    n_other = np.asarray(other_average).size
    return n_other // math.gcd(samples_per_rev, n_other)


def other_wheel_content(other_average: ArrayLike, samples_per_rev: int, indices: ArrayLike,
                        classes: ArrayLike, count: int) -> FloatArray:
    """The other wheel's synchronous pattern as it sits in the mean of each class of this
    wheel's revolutions: ``(count, samples_per_rev)``; class ``c`` holds the revolutions
    ``indices[classes == c]`` (see :func:`_other_wheel_rows`)."""
    period = _offset_period(other_average, samples_per_rev)
    index = np.asarray(indices, dtype=np.int64)
    label = np.asarray(classes, dtype=np.int64)
    weights = np.zeros((count, period))
    np.add.at(weights, (label, index % period), 1.0)
    weights /= np.maximum(weights.sum(axis=1, keepdims=True), 1.0)
    content = np.zeros((count, samples_per_rev))
    for first, rows in _other_wheel_rows(other_average, samples_per_rev):
        content += weights[:, first : first + rows.shape[0]] @ rows
    return content


def _other_wheel_variance(other_average: ArrayLike, samples_per_rev: int, indices: ArrayLike) -> FloatArray:
    """Per order, the variance from revolution to revolution that the other wheel's pattern
    alone gives this wheel's revolutions ``indices`` (part of the measured scatter, not noise)."""
    period = _offset_period(other_average, samples_per_rev)
    counts = np.bincount(np.asarray(indices, dtype=np.int64) % period, minlength=period)
    weights = counts / max(int(counts.sum()), 1)
    mean = np.zeros(samples_per_rev // 2 + 1, dtype=np.complex128)
    power = np.zeros(samples_per_rev // 2 + 1)
    for first, rows in _other_wheel_rows(other_average, samples_per_rev):
        spectra = np.fft.rfft(rows, axis=1)
        chunk = weights[first : first + rows.shape[0]]
        mean += chunk @ spectra
        power += chunk @ np.abs(spectra) ** 2
    return np.asarray(power - np.abs(mean) ** 2, dtype=np.float64)


def residue_z(sums: PeriodSums, teeth: int, m: int, other_average: ArrayLike | None = None) -> float:
    """How much more the averages of the revolutions ``≡ j (mod m)`` differ than noise makes
    them (standard errors, ~N(0, 1) for true revolutions): large when a revolution is a piece of
    a true one. NaN when some class is empty or ``m`` was not accumulated.

    ``other_average``, the other wheel's synchronous average on the shared angle grid: its
    pattern is taken out of every class first (:func:`other_wheel_content`), and the scatter it
    gives the revolutions out of the noise. With a few revolutions per class the other wheel's
    pattern does not cancel within a class (nor at all when ``m`` divides its hunting number),
    and a right angle would look wrong."""
    if m not in sums.residue_sums or sums.count < 2 * m:
        return math.nan
    counts = sums.residue_counts[m]
    if np.any(counts == 0):
        return math.nan
    average, variance, tested = _orders(sums, teeth)
    means = sums.residue_sums[m] / counts[:, None]
    if other_average is not None and sums.indices.size == sums.count:
        n = sums.total.size
        means = means - other_wheel_content(other_average, n, sums.indices, sums.indices % m, m)
        whole = other_wheel_content(other_average, n, sums.indices, np.zeros_like(sums.indices), 1)[0]
        average = average - np.fft.rfft(whole)
        scale = sums.count / max(sums.count - 1, 1)
        variance = np.maximum(variance - scale * _other_wheel_variance(other_average, n, sums.indices),
                              0.0)
        tested = tested & (variance > 0)
    spectra = np.fft.rfft(means, axis=1)
    q = float(np.sum(counts[:, None] * np.abs(spectra[:, tested] - average[tested]) ** 2))
    expected = (m - 1) * float(np.sum(variance[tested]))
    spread = math.sqrt((m - 1) * float(np.sum(variance[tested] ** 2)))
    return (q - expected) / spread if spread > 0 else math.nan


MAX_MESH_FAMILY_RATIO = 1.0
"""A line standing at an order where the mesh's own harmonics would sit if the angle turned
``m`` times too fast (``(Z/m)·j``, not a multiple of ``Z``) may hold at most the strongest mesh
harmonic's power (:func:`mesh_family_ratio`). Measured on right angles (the tach's, development
seeds 1000–1019 of ``benchmarks/bench_tachless.py``, 8 days each, every factor 2–16): at most
0.61 on the project's simulator (a 36/27 pair's orders 9·j), 0.17 on the independent generator;
on the angles 3 times too fast that were confirmed before (independent seed 9874), 2.1–2.7
every day, and 2.7 on the one 4 times too fast (seed 9954)."""
MIN_FAMILY_ORDER = 5
"""Shaft orders below this are left out of :func:`mesh_family_ratio`: runout and misalignment
lines, often stronger than the mesh on a real rig."""
LINE_ABOVE_NOISE = 25.0
"""…counted only when its power stands this many times above its noise (5 standard errors in
amplitude): a weak mesh harmonic must not make noise look like a line."""


def mesh_family_ratio(sums: PeriodSums, teeth: int, m: int, other_teeth: int | None = None) -> float:
    """The strongest line at the orders ``(teeth/m)·j`` (``j`` not divisible by ``m``) against
    the strongest mesh harmonic (orders ``teeth·j``), in power; 0 when no such line stands
    :data:`LINE_ABOVE_NOISE` above noise, NaN when ``m`` does not divide ``teeth``. Orders below
    :data:`MIN_FAMILY_ORDER` and those where the other wheel is synchronous (multiples of
    ``teeth / gcd(teeth, other_teeth)``; not left out when ``other_teeth`` is None) do not count.

    An angle ``m`` times too fast puts the mesh's true harmonics ``j`` at the orders
    ``(teeth/m)·j``: a whole order when ``m`` divides ``teeth``, so they are as synchronous as
    on a right angle and the residue classes do not differ through them. When the other wheel
    is synchronous too (its teeth dividing ``teeth/m``: a 42/14 pair read 3 times too fast
    holds exactly one gear revolution per "revolution") only the pinion's own pattern can show
    in the classes, and under noise it may not (held-out seed 9874 of the independent
    generator). The mesh lines then show it: on a right angle those orders hold only a tooth
    pattern repeating every ``m`` teeth, at most a fraction of the strongest mesh harmonic
    (:data:`MAX_MESH_FAMILY_RATIO`).

    Examples
    --------
    Three mesh harmonics (amplitudes 1, ½, ½) on a right 42-tooth angle, and on one turning 3
    times too fast (the true mesh at order 14, its 3rd harmonic taken for the 1st):

    >>> import numpy as np
    >>> n, teeth = 42 * 8, 42
    >>> def sums(mesh_order):
    ...     theta = np.arange(40 * n) / n
    ...     x = sum(a * np.cos(2 * np.pi * h * mesh_order * theta) for h, a in ((1, 1.0), (2, 0.5), (3, 0.5)))
    ...     acc = PeriodSumsAccumulator(n)
    ...     acc.add((x + 0.1 * np.random.default_rng(0).standard_normal(x.size)).reshape(40, n), np.arange(40))
    ...     return acc.result()
    >>> round(mesh_family_ratio(sums(42), teeth, 3), 3), round(mesh_family_ratio(sums(14), teeth, 3), 1)
    (0.0, 4.0)
    """
    if teeth % m or sums.count < 2:
        return math.nan
    average, variance, _ = _orders(sums, teeth)
    power = np.abs(average) ** 2
    k = np.arange(average.size)
    band = (k > 0) & (2 * k < sums.total.size)
    mesh = band & (k % teeth == 0)
    if not mesh.any() or not power[mesh].max() > 0:
        return math.nan
    family = band & (k % (teeth // m) == 0) & (k % teeth != 0) & (k >= MIN_FAMILY_ORDER)
    if other_teeth is not None:
        family &= k % (teeth // math.gcd(teeth, other_teeth)) != 0
    standing = family & (power > LINE_ABOVE_NOISE * variance / sums.count)
    if not standing.any():
        return 0.0
    return float(power[standing].max() / power[mesh].max())


@dataclass(frozen=True)
class PeriodCheck:
    """The verdict of :func:`check_shaft_period`: ``refusal`` is ``""`` when the revolutions are
    true ones, else the reason; the z-scores per prime for the record's quality report."""

    refusal: str
    unfolded: dict[int, float]
    residue: dict[int, float]
    residue_wheel: dict[int, str]
    min_content_z: float = MIN_CONTENT_Z
    max_residue_z: float = MAX_RESIDUE_Z
    mesh_family: dict[int, float] = field(default_factory=dict)
    """Per factor 2–:data:`MAX_HARMONIC_RATIO` dividing the pinion's teeth: :func:`mesh_family_ratio`."""
    unfolded_share: dict[int, float] = field(default_factory=dict)
    """Per prime: :func:`unfolded_share` (on the wheel :attr:`unfolded` was read on)."""

    @property
    def speed_factor(self) -> Fraction | None:
        """The likeliest single correction of the angle's speed, as the revolutions say: ``1/m``
        for the prime whose residue classes differ most (too fast by ``m``), else ``m`` for the
        prime whose orders hold least while others hold content (too slow by ``m``). ``None``
        when the revolutions are true ones or say nothing (no content at all). One prime at a
        time: a 2.5× speed shows both 5 (too fast) and 2 (too slow), and a weak second flag
        can be noise.

        Examples
        --------
        >>> PeriodCheck("x", {2: 0.3, 3: 40.0, 5: 38.0}, {2: 0.1, 3: 0.2, 5: 60.0}, {}).speed_factor
        Fraction(1, 5)
        >>> PeriodCheck("x", {2: 0.3, 3: 40.0, 5: 38.0}, {2: 0.1, 3: 0.2, 5: 1.0}, {}).speed_factor
        Fraction(2, 1)
        """
        if not self.refusal:
            return None
        fast = {m: z for m, z in self.residue.items() if z > self.max_residue_z}
        if fast:
            return Fraction(1, max(fast, key=lambda m: fast[m]))
        lines = {m: r for m, r in self.mesh_family.items() if r > MAX_MESH_FAMILY_RATIO}
        if lines:
            return Fraction(1, max(lines, key=lambda m: lines[m]))
        content = {m: z for m, z in self.unfolded.items() if math.isfinite(z)}
        if not content or max(content.values()) < self.min_content_z:
            return None
        slow = {m: z for m, z in content.items() if z < self.min_content_z}
        if slow:
            return Fraction(min(slow, key=lambda m: slow[m]))
        thin = {m: v for m, v in self.unfolded_share.items() if v < MIN_UNFOLDED_SHARE}
        return Fraction(min(thin, key=lambda m: thin[m])) if thin else None

    @property
    def speed_factors(self) -> list[Fraction]:
        """The corrections to try, in order: :attr:`speed_factor` first, then the other
        ratios its prime allows — a speed too fast by ``m`` is ``k/m`` times the angle's for some
        ``k`` coprime to ``m`` (a 1.5× speed shows 3; ÷3 can leave too few revolutions to take an
        angle, ×2/3 does not), one too slow by ``m`` is ``m/k`` times it.

        Examples
        --------
        >>> PeriodCheck("x", {2: 40.0, 3: 40.0, 5: 38.0}, {2: 0.1, 3: 60.0, 5: 1.0}, {}).speed_factors
        [Fraction(1, 3), Fraction(2, 3)]
        """
        first = self.speed_factor
        if first is None:
            return []
        m = first.denominator if first < 1 else first.numerator
        ratios = [Fraction(k, m) for k in range(1, m) if math.gcd(k, m) == 1]
        return ratios if first < 1 else [1 / r for r in ratios]


def check_shaft_period(
    pinion: PeriodSums,
    gear: PeriodSums | None,
    pinion_teeth: int,
    gear_teeth: int,
    moduli: tuple[int, ...] = MODULI,
    *,
    min_content_z: float = MIN_CONTENT_Z,
    max_residue_z: float = MAX_RESIDUE_Z,
) -> PeriodCheck:
    """Are the pinion revolutions (and the gear's, cut from them) true revolutions?

    For every prime ``m`` of ``moduli``: the pinion average's orders not divisible by ``m`` must
    stand ``min_content_z`` above noise (:func:`unfolded_z`) and hold a revolution's worth of
    content (:func:`unfolded_share`) — the gear's, when ``m`` divides a small hunting number
    (below) —, and the residue classes mod ``m``
    may differ by at most ``max_residue_z`` (:func:`residue_z`, the other wheel's pattern taken
    out): on the pinion's revolutions, and on the gear's unless ``m`` divides the gear's hunting
    number ``pinion_teeth / g`` (the larger of the two counts). A prime too large for the
    record's revolutions (a class left empty) is skipped above 5 and refuses below.

    Content that depends on which pair of teeth meets repeats every ``H = gear_teeth / g`` pinion
    revolutions. An angle ``H`` times too slow sees it in every order of its "revolution" (one
    ``q`` times too slow, ``q`` a multiple of ``H``, at the multiples of ``q/H``), so for a prime
    ``m`` dividing ``H``, when ``H`` is a ratio a wrong harmonic can give (≤
    :data:`MAX_HARMONIC_RATIO`), the pinion's orders cannot tell (a 63/18 pair, ``g = 9``, ``H =
    2``, read at half its speed on the independent generator: 11 standard errors off the even
    orders, confirmed, every tooth number wrong). The gear's revolutions can: the same content
    repeats every ``pinion_teeth / g`` of them, which ``m`` does not divide (the two hunting
    numbers are coprime). Otherwise the pinion's orders decide: the gear's hold less content
    (on a 25/38 pair, ``H = 38``, they held 5–6 standard errors at half speed, one day 6.2).
    """
    common = math.gcd(pinion_teeth, gear_teeth)
    unfolded: dict[int, float] = {}
    residue: dict[int, float] = {}
    wheel: dict[int, str] = {}
    family: dict[int, float] = {}
    share: dict[int, float] = {}
    problems: list[str] = []
    gear_average = None if gear is None or gear.count == 0 else gear.total / gear.count
    pinion_average = pinion.total / max(pinion.count, 1)
    hunting = gear_teeth // common  # pinion revolutions until the same pair of teeth meets again
    for m in moduli:
        if hunting % m == 0 and hunting <= MAX_HARMONIC_RATIO:  # see the note above
            if gear is None or gear.count < 2:
                unfolded[m] = share[m] = math.nan
            else:
                unfolded[m], share[m] = unfolded_z(gear, gear_teeth, m), unfolded_share(gear, gear_teeth, m)
        else:
            unfolded[m], share[m] = unfolded_z(pinion, pinion_teeth, m), unfolded_share(pinion, pinion_teeth, m)
        wheel[m], residue[m] = "pinion", residue_z(pinion, pinion_teeth, m, gear_average)
        if gear is not None and not (pinion_teeth // common) % m == 0:
            on_gear = residue_z(gear, gear_teeth, m, pinion_average)
            if on_gear > residue[m] or math.isnan(residue[m]):
                wheel[m], residue[m] = "gear", on_gear
        if not unfolded[m] >= min_content_z:
            problems.append(
                f"the average's orders off multiples of {m} stand only {unfolded[m]:.1f} standard "
                f"errors above noise (the angle may turn {m}× too slowly, or the record holds too "
                "little tooth-specific vibration to tell)"
            )
        elif share[m] < MIN_UNFOLDED_SHARE:
            problems.append(
                f"the average's orders off multiples of {m} hold only {share[m]:.1%} of the content "
                f"at its multiples: the angle turns {m}× too slowly"
            )
        if residue[m] > max_residue_z:
            problems.append(
                f"the {wheel[m]}'s revolutions differ with their number mod {m} "
                f"({residue[m]:.1f} standard errors): the angle turns too fast"
            )
        elif math.isnan(residue[m]) and m <= 5:
            problems.append(f"too few {wheel[m]} revolutions to check the period against {m}")
    # every whole ratio a wrong harmonic can give, not only primes: a 76-tooth pinion read 4×
    # too fast has its true mesh at orders 19·j, of which the prime 2's family (38·j) holds
    # only the even harmonics (held-out seed 9954 of the independent generator)
    for factor in range(2, MAX_HARMONIC_RATIO + 1):
        if pinion_teeth % factor == 0:
            family[factor] = mesh_family_ratio(pinion, pinion_teeth, factor, gear_teeth)
            if family[factor] > MAX_MESH_FAMILY_RATIO:
                problems.append(
                    f"a line at an order of {pinion_teeth // factor}·j holds {family[factor]:.2f} of the "
                    f"strongest mesh harmonic's power: the mesh's own harmonics sit there when the "
                    f"angle turns {factor}× too fast"
                )
    refusal = ("the shaft speed from the spectrum is not confirmed by the revolutions: "
               + "; ".join(problems)) if problems else ""
    return PeriodCheck(refusal, unfolded, residue, wheel, min_content_z, max_residue_z, family, share)
