"""Spur-pair geometry on the base plane: base radii, path of contact, contact ratio.

Positions along the line of action are measured from T1, the tangency point of the line of
action on the pinion base circle (the pinion is the driver: contact runs from the gear tip,
at ``path_start_m``, through the pitch point to the pinion tip, at ``path_end_m``).

Examples
--------
>>> from physics.geometry import spur_geometry
>>> geo = spur_geometry(module_mm=10, pinion_teeth=20, gear_teeth=21)
>>> round(geo.contact_ratio, 3)
1.563
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt


class GeometryError(ValueError):
    """The tooth numbers and proportions do not make a working involute pair."""


@dataclass(frozen=True)
class SpurGeometry:
    module_m: float
    pinion_teeth: int
    gear_teeth: int
    pressure_angle_rad: float
    face_width_m: float
    pinion_base_radius_m: float
    gear_base_radius_m: float
    pinion_tip_radius_m: float
    gear_tip_radius_m: float
    centre_distance_m: float
    base_pitch_m: float
    path_start_m: float
    """Start of contact on the line of action, from T1 (gear tip circle)."""
    path_end_m: float
    """End of contact, from T1 (pinion tip circle)."""
    pitch_point_m: float
    """Pitch point, from T1."""

    @property
    def line_of_action_length_m(self) -> float:
        """T1T2: line of action between the two base-circle tangency points, a·sin α.

        The friction arms at a contact u (from T1) are u (pinion) and T1T2 − u (gear)."""
        return self.centre_distance_m * math.sin(self.pressure_angle_rad)

    @property
    def path_length_m(self) -> float:
        return self.path_end_m - self.path_start_m

    @property
    def contact_ratio(self) -> float:
        return self.path_length_m / self.base_pitch_m

    @property
    def gear_ratio(self) -> float:
        """Gear teeth / pinion teeth (pinion turns this many times per gear turn)."""
        return self.gear_teeth / self.pinion_teeth


def spur_geometry(
    module_mm: float,
    pinion_teeth: int,
    gear_teeth: int,
    pressure_angle_deg: float = 20.0,
    face_width_mm: float = 20.0,
    addendum_coefficient: float = 1.0,
    dedendum_coefficient: float = 1.25,
) -> SpurGeometry:
    """Geometry of a standard (unshifted) spur pair at the standard centre distance.

    Parameters
    ----------
    module_mm, pinion_teeth, gear_teeth, pressure_angle_deg, face_width_mm
        Usual gear data.
    addendum_coefficient, dedendum_coefficient
        Addendum and dedendum in modules. The dedendum is checked: the active profile of
        each wheel must stay above its root circle (no interference).

    Returns
    -------
    SpurGeometry

    Examples
    --------
    >>> geo = spur_geometry(4, 20, 40)
    >>> round(geo.base_pitch_m * 1e3, 4)
    11.8085
    """
    if module_mm <= 0 or face_width_mm <= 0:
        raise GeometryError("module and face width must be > 0")
    m = module_mm * 1e-3
    alpha = math.radians(pressure_angle_deg)
    r1, r2 = m * pinion_teeth / 2, m * gear_teeth / 2
    rb1, rb2 = r1 * math.cos(alpha), r2 * math.cos(alpha)
    ra1, ra2 = r1 + addendum_coefficient * m, r2 + addendum_coefficient * m
    a = r1 + r2
    t1t2 = a * math.sin(alpha)
    start = t1t2 - math.sqrt(ra2**2 - rb2**2)
    end = math.sqrt(ra1**2 - rb1**2)
    if start <= 0 or end >= t1t2:
        raise GeometryError("tip circles reach beyond the interference points (undercut pair)")
    # The active profile must lie above the root circle, or the teeth would interfere.
    for rb, ra_other, rf, label in (
        (rb1, start, r1 - dedendum_coefficient * m, "pinion"),
        (rb2, t1t2 - end, r2 - dedendum_coefficient * m, "gear"),
    ):
        start_active_radius = math.hypot(rb, ra_other)
        if start_active_radius < rf:
            raise GeometryError(f"{label}: active profile starts below the root circle")
    pb = math.pi * m * math.cos(alpha)
    if (end - start) < pb:
        raise GeometryError("contact ratio below 1: the pair cannot transmit motion continuously")
    return SpurGeometry(
        module_m=m,
        pinion_teeth=pinion_teeth,
        gear_teeth=gear_teeth,
        pressure_angle_rad=alpha,
        face_width_m=face_width_mm * 1e-3,
        pinion_base_radius_m=rb1,
        gear_base_radius_m=rb2,
        pinion_tip_radius_m=ra1,
        gear_tip_radius_m=ra2,
        centre_distance_m=a,
        base_pitch_m=pb,
        path_start_m=start,
        path_end_m=end,
        pitch_point_m=rb1 * math.tan(alpha),
    )


def pairs_in_contact(
    geometry: SpurGeometry, mesh_position_m: npt.ArrayLike
) -> npt.NDArray[np.int64]:
    """Number of tooth pairs on the path of contact.

    ``mesh_position_m`` is the position of one pair's contact point along the line of
    action (from T1); the other pairs are whole base pitches before and after it.

    Examples
    --------
    >>> geo = spur_geometry(10, 20, 21)
    >>> int(pairs_in_contact(geo, geo.pitch_point_m))
    1
    """
    pb = geometry.base_pitch_m
    u = np.asarray(mesh_position_m, dtype=float)
    # Reduce to the first pair at or after the start of contact, then count pitches to the end.
    first = geometry.path_start_m + np.mod(u - geometry.path_start_m, pb)
    return (np.floor((geometry.path_end_m - first) / pb) + 1).astype(np.int64)


def contact_line_length_m(geometry: SpurGeometry, mesh_position_m: npt.ArrayLike) -> np.ndarray:
    """Total length of the contact lines (spur: face width × pairs in contact).

    Examples
    --------
    >>> geo = spur_geometry(10, 20, 21)
    >>> round(float(contact_line_length_m(geo, geo.path_start_m + 1e-6)) * 1e3, 3)
    40.0
    """
    return geometry.face_width_m * pairs_in_contact(geometry, mesh_position_m).astype(float)
