"""The ground under a track's legs: sampling them, splitting them for an autopilot without a terrain frame,
and the height above the ground a track flown straight in sea-level altitude keeps.

Owns three pure numpy functions (no I/O). A ground is any callable `ground(lat, lon) -> heights`, arrays of
degrees in, metres above sea level out (geo's DEM reader has that signature; tests use analytic hills):
- `sample_legs`: points every `step_m` or closer along each leg (both ends included) and the leg each
  belongs to: where "the ground under every metre of the track" is looked at;
- `amsl_track`: what a PX4 mission flies (PX4 takes no terrain frame): every point at ground + the height
  asked for, above sea level, and each leg split wherever the straight line between its ends, in sea-level
  altitude, leaves ground + height by more than `tolerance_m` at one of its samples (and, with
  `lead_in_turns`, where a multicopter that reaches a leg's next altitude early would leave it);
- `flown_heights`: the height above the ground along the legs of a sea-level track flown straight.

How the split compares with QGroundControl's terrain-following survey (TransectStyleComplexItem): QGroundControl
adds a waypoint at every terrain sample along a transect (_addInterstitialTerrainPoints), at ground +
distance to surface, written in MAV_FRAME_GLOBAL whatever the autopilot, then drops each added point whose
altitude differs from the last kept point's by no more than its TerrainAdjustTolerance (10 m by default;
_adjustForTolerance). That compares neighbouring altitudes, not the line flown between kept points, so a
ridge between two kept points at equal altitude can pass under the line unchecked. Here the check is on
the line itself: a leg is split at the sample of largest departure (Douglas-Peucker on the vertical), and
the halves checked again, until every sample of every leg is within the tolerance.

Why a straight line is not enough for PX4 (`lead_in_turns`): a PX4 multicopter does not hold the 3-D line
between two waypoints while it turns onto a leg. Its trajectory generator (src/lib/motion_planning/
PositionSmoothing.cpp, v1.15: `_getCrossingPoint` returns, while `_isTurning`, the L1 point 5 m ahead in the
horizontal but at the *target's* altitude, and `_generateVelocitySetpoint` heads for it at up to the vertical
speed limit) climbs or descends to the next waypoint's altitude while its horizontal speed is still low, then
flies the rest of the way straight from there. On PX4 SIH over a hill that put the vehicle 4.5 m under
ground + height a few metres after a corner where the next waypoint was 5.4 m lower, on a leg whose straight
line was within 0.2 m of it. So with `lead_in_turns` the first stretch of every leg is also cut short where
the ground + height under it spans more than the tolerance: the vehicle is then within the tolerance at any
altitude between that stretch's two ends, early or not.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from numpy.typing import ArrayLike, NDArray

from missionplan.geo.errors import GeoError

Ground = Callable[[NDArray[np.float64], NDArray[np.float64]], NDArray[np.float64]]

WGS84_A_M = 6_378_137.0  # the WGS84 ellipsoid's semi-major axis
WGS84_E2 = (1 / 298.257223563) * (2 - 1 / 298.257223563)  # its first eccentricity squared


def _track(lat: ArrayLike, lon: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Latitudes and longitudes as two 1-D float arrays of one length, in range."""
    lat_a = np.asarray(lat, dtype=float)
    lon_a = np.asarray(lon, dtype=float)
    if lat_a.ndim != 1 or lat_a.shape != lon_a.shape:
        raise ValueError(f"a track is two 1-D arrays of one length, got shapes {lat_a.shape} and {lon_a.shape}")
    if not (np.all(np.abs(lat_a) <= 90.0) and np.all(np.abs(lon_a) <= 180.0)):
        raise ValueError("a track's latitudes must be within +-90 and its longitudes within +-180 degrees")
    return lat_a, lon_a


def _positive(value: float, name: str) -> float:
    if not (np.isfinite(value) and value > 0):
        raise ValueError(f"{name} must be a positive number of metres, got {value!r}")
    return float(value)


def _leg_lengths(lat: NDArray[np.float64], lon: NDArray[np.float64]) -> NDArray[np.float64]:
    """Each leg's length in metres, in an equirectangular projection about the track's mean latitude, with the
    WGS84 ellipsoid's radii of curvature there (meridian for north, prime vertical for east).

    Why not pyproj.Geod: legs are at most a few kilometres, where this length differs from the geodesic by
    about a millionth per kilometre of latitude spanned, and a straight line in latitude / longitude is then
    the straight line the autopilot flies to within centimetres; the projection is one vectorised expression,
    where Geod would sample each leg in a Python loop. (A sphere's mean radius would be 0.3 % short east-west
    at mid latitudes: samples "every 5 m" would be 5.015 m apart.)
    """
    sin2 = np.sin(np.radians(np.mean(lat))) ** 2 if lat.size else 0.0
    prime_vertical = WGS84_A_M / np.sqrt(1 - WGS84_E2 * sin2)
    meridian = WGS84_A_M * (1 - WGS84_E2) / (1 - WGS84_E2 * sin2) ** 1.5
    cos_lat = np.sqrt(1 - sin2)
    dlon = (np.diff(lon) + 180.0) % 360.0 - 180.0  # a leg across the antimeridian is short, not 360 degrees
    east = np.radians(dlon) * cos_lat * prime_vertical
    north = np.radians(np.diff(lat)) * meridian
    return np.hypot(east, north)


def _leg_samples(lat: NDArray[np.float64], lon: NDArray[np.float64], step_m: float
                 ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.intp], NDArray[np.float64]]:
    """sample_legs' (lat, lon, leg) and each sample's fraction of the way along its leg (0 at its start, 1 at
    its end)."""
    lengths = _leg_lengths(lat, lon)
    pieces = np.maximum(1, np.ceil(lengths / step_m - 1e-9)).astype(np.intp)  # 1e-9: 10 m at 5 m is 2 pieces
    leg = np.repeat(np.arange(lengths.size, dtype=np.intp), pieces + 1)
    starts = np.concatenate(([0], np.cumsum(pieces + 1)[:-1]))
    position = np.arange(leg.size, dtype=np.intp) - starts[leg]  # 0 .. pieces within each leg
    fraction = position / pieces[leg]
    dlon = (lon[1:] - lon[:-1] + 180.0) % 360.0 - 180.0
    sample_lat = lat[leg] + fraction * (lat[leg + 1] - lat[leg])
    sample_lon = lon[leg] + fraction * dlon[leg]
    sample_lon = np.where(np.abs(sample_lon) > 180.0, (sample_lon + 180.0) % 360.0 - 180.0, sample_lon)
    ends = fraction == 1.0  # a leg's end is the next waypoint itself, to the last bit
    sample_lat[ends], sample_lon[ends] = lat[leg[ends] + 1], lon[leg[ends] + 1]
    return sample_lat, sample_lon, leg, fraction


def sample_legs(lat: ArrayLike, lon: ArrayLike, step_m: float
                ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.intp]]:
    """Points every `step_m` metres or closer along each leg of the track, both ends of every leg included
    (a waypoint between two legs appears twice, once for each), evenly spaced within a leg, and the index
    of the leg each belongs to (leg i runs from point i to point i + 1). A track of one point has no legs."""
    lat_a, lon_a = _track(lat, lon)
    sample_lat, sample_lon, leg, _ = _leg_samples(lat_a, lon_a, _positive(step_m, "step_m"))
    return sample_lat, sample_lon, leg


def _ground_at(ground: Ground, lat: NDArray[np.float64], lon: NDArray[np.float64]) -> NDArray[np.float64]:
    """The ground's heights at the points, GeoError naming the first point it has none for."""
    heights = np.asarray(ground(lat, lon), dtype=float)
    if heights.shape != lat.shape:
        raise ValueError(f"the ground gave {heights.shape} heights for {lat.shape} points")
    missing = np.flatnonzero(~np.isfinite(heights))
    if missing.size:
        first = missing[0]
        raise GeoError(f"no ground height at {lat[first]:.6f}, {lon[first]:.6f} under the track ({missing.size} "
                       "such points): the terrain data has a hole there or does not reach it")
    return heights


def amsl_track(lat: ArrayLike, lon: ArrayLike, height_m: ArrayLike, ground: Ground, tolerance_m: float = 2.0,
               step_m: float = 5.0, lead_in_turns: bool = False
               ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64], NDArray[np.intp]]:
    """The track as a mission without a terrain frame flies it: (lat, lon, amsl, source_index).

    Every input point is kept, at ground + its height above sea level (`height_m`: one height for all points
    or one per point, the height above the ground asked for). Each leg is sampled every `step_m` or closer
    (sample_legs) and split at the sample where the straight line between its kept ends departs most from
    ground + height (the height taken linearly between the leg's ends), again and again, until every sample
    is within `tolerance_m` of it. An added point sits on the original leg at ground + height there.
    `lead_in_turns` (for a multicopter that reaches the next altitude early as it turns onto a leg: PX4, see the
    module docstring): each leg is first cut at the last sample from its start up to which ground + height spans
    no more than `tolerance_m` (at least one sample on), so that any altitude between that stretch's ends is
    within the tolerance of it; the rest of the leg is then split as above.
    `source_index` gives, for each output point, the input point it is (-1 for an added one), so that the
    commands attached to a waypoint (camera triggers, speed) stay with it.
    """
    lat_a, lon_a = _track(lat, lon)
    tolerance_m = _positive(tolerance_m, "tolerance_m")
    step_m = _positive(step_m, "step_m")
    heights = np.broadcast_to(np.asarray(height_m, dtype=float), lat_a.shape)
    if not np.all(np.isfinite(heights)):
        raise ValueError("height_m must be finite")
    if lat_a.size < 2:
        amsl = _ground_at(ground, lat_a, lon_a) + heights
        return lat_a.copy(), lon_a.copy(), amsl, np.arange(lat_a.size, dtype=np.intp)

    sample_lat, sample_lon, leg, fraction = _leg_samples(lat_a, lon_a, step_m)
    wanted = _ground_at(ground, sample_lat, sample_lon) + heights[leg] + fraction * (heights[leg + 1] - heights[leg])
    # Distance along the whole track: within one leg the line flown is linear in it.
    lengths = _leg_lengths(lat_a, lon_a)
    along = np.concatenate(([0.0], np.cumsum(lengths)))[leg] + fraction * lengths[leg]
    first = np.flatnonzero(np.diff(leg, prepend=-1))  # the first sample of every leg
    last = np.append(first[1:], leg.size) - 1
    kept = np.union1d(first, last)
    if lead_in_turns:
        kept = np.union1d(kept, _level_stretch_ends(wanted, leg, first, last, tolerance_m))
    kept = _split_until_within(wanted, along, kept, tolerance_m)

    is_leg_start = np.zeros(leg.size, dtype=bool)
    is_leg_start[first] = True
    # A waypoint between two legs is both the last sample of one and the first of the next: keep it once.
    out = kept[~is_leg_start[kept] | (kept == 0)]
    source = np.full(out.size, -1, dtype=np.intp)
    at_point = (fraction[out] == 0.0) | (fraction[out] == 1.0)
    source[at_point] = leg[out[at_point]] + (fraction[out[at_point]] == 1.0)
    return sample_lat[out], sample_lon[out], wanted[out], source


def _level_stretch_ends(wanted: NDArray[np.float64], leg: NDArray[np.intp], first: NDArray[np.intp],
                        last: NDArray[np.intp], tolerance_m: float) -> NDArray[np.intp]:
    """For each leg, the last sample from its first on up to which `wanted` spans at most `tolerance_m` (the
    sample after its first where even that one departs by more): where its first stretch ends."""
    # The running maximum and minimum within each leg, for all legs at once: offsetting leg k by k times more
    # than the whole span makes an accumulation over the track restart at every leg.
    offset = leg * (np.ptp(wanted) + 1.0)
    high = np.maximum.accumulate(wanted + offset) - offset
    low = -(np.maximum.accumulate(-wanted + offset) - offset)
    within = (high - low) <= tolerance_m
    # Within a leg the span only grows, so the samples within it are the leg's first ones.
    counted = np.bincount(leg, weights=within, minlength=first.size).astype(np.intp)
    return np.minimum(np.maximum(first + counted - 1, first + 1), last)


def _split_until_within(wanted: NDArray[np.float64], along: NDArray[np.float64], kept: NDArray[np.intp],
                        tolerance_m: float) -> NDArray[np.intp]:
    """The sample indices to keep so that the straight lines between consecutive kept samples of a leg are
    within `tolerance_m` of `wanted` at every sample: each pass splits every segment that is not at its sample
    of largest departure (all segments of all legs at once, so a pass is a few numpy calls)."""
    index = np.arange(wanted.size, dtype=np.intp)
    while True:
        segment = np.searchsorted(kept, index, side="right") - 1  # the kept sample at or before each sample
        segment = np.minimum(segment, kept.size - 2)
        start, end = kept[segment], kept[segment + 1]
        span = along[end] - along[start]
        share = np.divide(along - along[start], span, out=np.zeros_like(span), where=span > 0)
        line = wanted[start] + share * (wanted[end] - wanted[start])
        departure = np.abs(line - wanted)
        departure[kept] = 0.0
        over = departure > tolerance_m
        if not over.any():
            return kept
        # The sample of largest departure in each segment that has one over the tolerance.
        candidates = np.flatnonzero(over)
        order = np.lexsort((-departure[candidates], segment[candidates]))
        first = np.unique(segment[candidates][order], return_index=True)[1]
        kept = np.union1d(kept, candidates[order][first])


def flown_heights(lat: ArrayLike, lon: ArrayLike, amsl: ArrayLike, ground: Ground, step_m: float
                  ) -> NDArray[np.float64]:
    """The height above the ground of a track flown straight from point to point at the given sea-level
    altitudes, at the points sample_legs(lat, lon, step_m) gives (in that order): what a clearance check and
    the judge compare with the height asked for."""
    lat_a, lon_a = _track(lat, lon)
    amsl_a = np.asarray(amsl, dtype=float)
    if amsl_a.shape != lat_a.shape:
        raise ValueError(f"amsl has shape {amsl_a.shape}, the track {lat_a.shape}")
    sample_lat, sample_lon, leg, fraction = _leg_samples(lat_a, lon_a, _positive(step_m, "step_m"))
    flown = amsl_a[leg] + fraction * (amsl_a[leg + 1] - amsl_a[leg]) if leg.size else np.empty(0)
    return flown - _ground_at(ground, sample_lat, sample_lon)
