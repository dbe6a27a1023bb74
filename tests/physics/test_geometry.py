"""Spur geometry against textbook values and independent counting."""

from __future__ import annotations

import math

import numpy as np
import pytest

from physics.geometry import GeometryError, contact_line_length_m, pairs_in_contact, spur_geometry


def test_textbook_contact_ratio_20_20_teeth() -> None:
    # Standard full-depth 20° pair, 20/20 teeth: ε ≈ 1.557 (e.g. Shigley, Maitra tables).
    geo = spur_geometry(module_mm=5, pinion_teeth=20, gear_teeth=20)
    assert geo.contact_ratio == pytest.approx(1.557, abs=5e-4)


def test_radii_and_base_pitch_of_the_cetim_like_pair() -> None:
    geo = spur_geometry(module_mm=10, pinion_teeth=20, gear_teeth=21, face_width_mm=20)
    cos20 = math.cos(math.radians(20))
    assert geo.pinion_base_radius_m == pytest.approx(0.1 * cos20)
    assert geo.gear_base_radius_m == pytest.approx(0.105 * cos20)
    assert geo.base_pitch_m == pytest.approx(2 * math.pi * geo.pinion_base_radius_m / 20)
    assert geo.base_pitch_m == pytest.approx(2 * math.pi * geo.gear_base_radius_m / 21)
    assert geo.path_start_m < geo.pitch_point_m < geo.path_end_m
    # The pitch point is where the two base-circle tangent lengths are in the radius ratio.
    t1t2 = geo.centre_distance_m * math.sin(geo.pressure_angle_rad)
    assert geo.pitch_point_m / (t1t2 - geo.pitch_point_m) == pytest.approx(20 / 21)


def test_mean_number_of_pairs_is_the_contact_ratio() -> None:
    geo = spur_geometry(module_mm=10, pinion_teeth=20, gear_teeth=21)
    positions = np.linspace(0.0, geo.base_pitch_m, 100_001)[:-1] + 0.123
    pairs = pairs_in_contact(geo, positions)
    assert set(np.unique(pairs)) == {1, 2}
    assert pairs.mean() == pytest.approx(geo.contact_ratio, abs=1e-4)
    lengths = contact_line_length_m(geo, positions)
    assert lengths.mean() == pytest.approx(geo.contact_ratio * geo.face_width_m, rel=1e-4)


def test_pitch_point_is_in_single_contact_for_this_pair() -> None:
    geo = spur_geometry(module_mm=10, pinion_teeth=20, gear_teeth=21)
    assert int(pairs_in_contact(geo, geo.pitch_point_m)) == 1
    assert int(pairs_in_contact(geo, geo.path_start_m + 1e-6)) == 2


def test_impossible_pairs_are_refused() -> None:
    with pytest.raises(GeometryError):
        spur_geometry(module_mm=10, pinion_teeth=6, gear_teeth=60)
    with pytest.raises(GeometryError):
        spur_geometry(module_mm=10, pinion_teeth=20, gear_teeth=21, addendum_coefficient=0.3)
    with pytest.raises(GeometryError):
        spur_geometry(module_mm=-1, pinion_teeth=20, gear_teeth=21)
