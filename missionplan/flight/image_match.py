"""Which capture record each image of a camera's card is: the camera clock's offset from UTC, then one image to one
record. Pure: times in, pairs out (exif_geotag.py reads the cards and writes the copies).

A camera stamps each image with its own clock (EXIF DateTimeOriginal, local time, rarely set to the second); the
ledger has each photo's time on our UTC clock. Between them lies one unknown offset (plus a slow drift), and photos
missing on either side: a camera that skipped a trigger, a capture report lost on the link. The offset is found as
the one that lines the most images up with records:

1. candidates: every record time minus the time of each of a few anchor images spread over the card (a real image
   pairs with its own record in one of them, wherever the crew's test shots or skipped photos are);
2. score: how many images lie within the tolerance of a record once shifted; the best score wins, ties go to the
   smallest residuals. Photos taken at a steady interval line up almost as well one interval off, but the turns
   and the gaps between legs line up only at the true offset;
3. refine: a straight line (offset and drift) through the pairs found, then match again.

By name first (match_names): a MAVLink camera's capture records name each image's file (file_url); an image whose
file name is that of exactly one record is that record, no clock needed.

Tolerance: half the short intervals between records (their 10th percentile, so one pair of reports bunched by the
link does not shrink it for all), never below half the images' time resolution (1 s without SubSecTimeOriginal).
An image within it of exactly one record free for it is matched; of two or more, ambiguous; of none, unmatched.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

ANCHORS = 12  # images tried as the pair of each record for the offset candidates
MIN_TOLERANCE_S = 0.001  # EXIF SubSecTimeOriginal rarely says more than milliseconds


@dataclass(frozen=True)
class Match:
    """The outcome for one card against one vehicle's records."""

    record_of: list[int | None]  # per image (in the order given): the record's index, or None
    ambiguous: list[bool]  # per image: within the tolerance of two or more records
    offset_s: float  # UTC minus camera clock at the card's first matched image (positive: the camera is behind)
    drift: float  # seconds gained by UTC per second of the camera clock (0 for a camera on time)
    tolerance_s: float
    span_s: float = 0.0  # camera seconds from the first matched image to the last
    residual_s: float = 0.0  # the median distance of a matched image from its record, once shifted

    @property
    def matched(self) -> int:
        return sum(r is not None for r in self.record_of)

    @property
    def ambiguous_count(self) -> int:
        return sum(self.ambiguous)

    @property
    def unmatched(self) -> int:
        return len(self.record_of) - self.matched - self.ambiguous_count


def tolerance_s(records: np.ndarray, resolution_s: float) -> float:
    """Half the short intervals between consecutive records, not below half the images' time resolution."""
    gaps = np.diff(np.sort(records))
    gaps = gaps[gaps > 0]
    half = 0.5 * float(np.percentile(gaps, 10)) if len(gaps) else 1.0
    return max(half, 0.5 * resolution_s, MIN_TOLERANCE_S)


def _nearest(shifted: np.ndarray, records: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """For each shifted image time: the index of the nearest record and the distance to it."""
    right = np.clip(np.searchsorted(records, shifted), 1, len(records) - 1) if len(records) > 1 else \
        np.zeros(len(shifted), dtype=np.int64)
    if len(records) == 1:
        return right, np.abs(shifted - records[0])
    left = right - 1
    d_left, d_right = np.abs(shifted - records[left]), np.abs(records[right] - shifted)
    take_left = d_left <= d_right
    return np.where(take_left, left, right), np.where(take_left, d_left, d_right)


def best_offset(images: np.ndarray, records: np.ndarray, tol: float) -> tuple[float, int]:
    """The offset (record time - image time) that lines up the most images with a record within tol, and how many.

    images, records: sorted times (s). Candidates pair each of ANCHORS images spread over the card with every
    record; each candidate is scored in one numpy pass (records sorted, searchsorted)."""
    anchors = images[np.unique(np.linspace(0, len(images) - 1, min(ANCHORS, len(images))).round().astype(int))]
    candidates = np.unique((records[None, :] - anchors[:, None]).ravel())
    best, best_count, best_cost = 0.0, -1, np.inf
    for chunk in np.array_split(candidates, max(1, len(candidates) * len(images) // 2_000_000 + 1)):
        shifted = images[None, :] + chunk[:, None]  # (candidates, images)
        _, dist = _nearest(shifted.ravel(), records)
        dist = dist.reshape(shifted.shape)
        within = dist <= tol
        count = within.sum(axis=1)
        cost = np.where(within, dist, 0.0).sum(axis=1)
        order = np.lexsort((cost, -count))  # the most images, then the smallest residuals
        k = int(order[0])
        if count[k] > best_count or (count[k] == best_count and cost[k] < best_cost):
            best, best_count, best_cost = float(chunk[k]), int(count[k]), float(cost[k])
    return best, best_count


def _assign(shifted: np.ndarray, records: np.ndarray, tol: float) -> tuple[list[int | None], list[bool]]:
    """One image to one record: an image near exactly one record is matched to it unless a nearer image claims
    it; near two or more, ambiguous."""
    n = len(shifted)
    near = [np.flatnonzero(np.abs(records - t) <= tol) for t in shifted]
    record_of: list[int | None] = [None] * n
    ambiguous = [len(c) > 1 for c in near]
    claims: dict[int, int] = {}
    for i, c in enumerate(near):
        if len(c) != 1:
            continue
        j = int(c[0])
        other = claims.get(j)
        if other is None or abs(shifted[i] - records[j]) < abs(shifted[other] - records[j]):
            if other is not None:
                record_of[other] = None
                ambiguous[other] = True  # two images for one record: the farther one cannot be told
            claims[j] = i
            record_of[i] = j
        else:
            ambiguous[i] = True
    return record_of, ambiguous


def match_images(image_times: np.ndarray, record_times: np.ndarray, resolution_s: float = 0.001) -> Match:
    """Match a card's images (camera clock, seconds; NaN where an image has no time) to one vehicle's capture
    records (UTC seconds). Images and records may come in any order; indices refer to the arrays given."""
    image_times = np.asarray(image_times, dtype=float)
    record_times = np.asarray(record_times, dtype=float)
    timed = np.flatnonzero(np.isfinite(image_times))
    order_r = np.argsort(record_times, kind="stable")
    records = record_times[order_r]
    tol = tolerance_s(records, resolution_s)
    none: list[int | None] = [None] * len(image_times)
    if not len(timed) or not len(records):
        return Match(none, [False] * len(image_times), 0.0, 0.0, tol)
    order_i = timed[np.argsort(image_times[timed], kind="stable")]
    images = image_times[order_i]
    offset, _ = best_offset(images, records, tol)
    origin, drift = images[0], 0.0
    for _ in range(2):  # refine: offset and drift through the pairs found, then match again
        shifted = images + offset + drift * (images - origin)
        rec_of, _amb = _assign(shifted, records, tol)
        pairs = [(k, j) for k, j in enumerate(rec_of) if j is not None]
        if len(pairs) < 2:
            break
        k_idx = np.array([k for k, _ in pairs])
        residual = records[[j for _, j in pairs]] - images[k_idx]
        span = images[k_idx[-1]] - images[k_idx[0]]
        if len(pairs) >= 10 and span > 0:
            slope, intercept = np.polyfit(images[k_idx] - origin, residual, 1)
            drift, offset = float(slope), float(intercept)
        else:
            offset = float(np.median(residual))
    shifted = images + offset + drift * (images - origin)
    rec_of, amb = _assign(shifted, records, tol)
    record_of = list(none)
    ambiguous = [False] * len(image_times)
    for k, i in enumerate(order_i):
        j = rec_of[k]
        record_of[i] = None if j is None else int(order_r[j])
        ambiguous[i] = amb[k]
    paired = [k for k, j in enumerate(rec_of) if j is not None]
    first, span = (paired[0], float(images[paired[-1]] - images[paired[0]])) if paired else (0, 0.0)
    residual = float(np.median([abs(shifted[k] - records[rec_of[k]]) for k in paired])) if paired else tol
    return Match(record_of, ambiguous, offset + drift * (images[first] - origin), drift, tol, span, residual)


def file_name(url: str) -> str:
    """The file name a camera's file_url ends in (a path on its card or a URL), in capitals: card file systems
    (FAT) do not keep case."""
    return url.split("?", 1)[0].rstrip("/").rsplit("/", 1)[-1].upper()


def match_names(image_names: list[str], record_urls: list[str | None]) -> Match:
    """Match a card's images to one vehicle's capture records by file name: an image named as exactly one record's
    file_url is that record; named as two or more (a camera whose numbering restarted between flights), ambiguous.
    The clock fields are 0: the caller says the offset where it wants one."""
    by_name: dict[str, list[int]] = {}
    for j, url in enumerate(record_urls):
        if url:
            by_name.setdefault(file_name(url), []).append(j)
    named = [by_name.get(name.upper(), []) for name in image_names]
    record_of: list[int | None] = [c[0] if len(c) == 1 else None for c in named]
    return Match(record_of, [len(c) > 1 for c in named], 0.0, 0.0, 0.0)
