"""Known answers for the service's derived views: tooth sectors, the robust band, the cache."""

from __future__ import annotations

import time

import numpy as np
import pytest

from service.queries import ResponseCache, robust_band, tooth_sectors


def test_tooth_sectors_cover_the_revolution_once_centred_on_pitch_angles() -> None:
    sectors = tooth_sectors(20, 9.0)  # tooth 1 at 9°: its sector is 0°–18°
    assert len(sectors) == 20
    assert [s.tooth for s in sectors] == list(range(1, 21))
    assert (sectors[0].start_deg, sectors[0].end_deg) == (0.0, 18.0)
    assert sectors[15].start_deg == pytest.approx(15 * 18.0)  # tooth 16 at 279°


def test_a_sector_across_zero_comes_in_two_pieces() -> None:
    sectors = tooth_sectors(4, 0.0)  # tooth 1 at 0°: −45°..45°
    pieces = [(s.tooth, s.start_deg, s.end_deg) for s in sectors]
    assert (1, 0.0, 45.0) in pieces and (1, 315.0, 360.0) in pieces
    assert sum(s.end_deg - s.start_deg for s in sectors) == pytest.approx(360.0)
    assert tooth_sectors(None, 0.0) == [] and tooth_sectors(0, 0.0) == []


def test_robust_band_is_median_plus_minus_three_scaled_mads() -> None:
    curves = np.array([[1.0, 10.0], [2.0, 10.0], [3.0, 10.0], [4.0, 10.0], [100.0, 10.0]])
    lower, upper = robust_band(curves)
    # column 0: median 3, |dev| = 2,1,0,1,97 → MAD 1 → 3 ± 3·1.4826; the outlier does not count
    assert lower[0] == pytest.approx(3 - 3 * 1.4826) and upper[0] == pytest.approx(3 + 3 * 1.4826)
    assert lower[1] == upper[1] == 10.0


def test_response_cache_versions_and_freshness() -> None:
    cache = ResponseCache(max_entries=2)
    assert cache.fresh("a", 10.0) is None
    cache.put("a", 1, b"one")
    assert cache.fresh("a", 10.0) == (1, b"one")
    assert cache.fresh("a", 0.0) is None  # max age 0: always re-check the version
    assert cache.get("a", 1) == b"one" and cache.get("a", 2) is None
    cache.put("b", 1, b"b")
    cache.put("c", 1, b"c")  # evicts the least recently used ("a")
    assert cache.get("a", 1) is None and cache.get("c", 1) == b"c"
    time.sleep(0.02)
    assert cache.fresh("c", 0.01) is None and cache.fresh("c", 10.0) == (1, b"c")
