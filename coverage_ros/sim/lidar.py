"""Planar lidar ray casting: a fast vectorized caster and a slow pymunk reference.

Range convention (REP 117, the same for both casters): a beam reports the distance from the
sensor origin to the first surface it meets; ``+inf`` if nothing lies within ``range_max``;
``-inf`` if the first surface is closer than ``range_min`` (too close to measure). The scanning
robot's own body is never seen. Beam ``k`` points at ``yaw + angle_min + k * angle_increment``.

The fast caster (:func:`cast_scans`) tests each beam only against the segments whose angular
extent, seen from the sensor, covers that beam: segments near the sensor come from a bucket
grid (:class:`SegmentIndex`), their endpoint angles give a beam-index interval, and ray/segment
intersections are computed for those (beam, segment) pairs only - a few per beam instead of
beams x segments. Circles (static pillars and other robots) are intersected analytically.
"""

from __future__ import annotations

import math

import numpy as np

from coverage_ros.core.world import LidarSpec

BUCKET_SIZE = 1.0  # [m] segment index cell; ~1/3 of an LDS-01's range keeps candidate sets small
_ANGLE_EPS = 1e-7  # [beams] widens a segment's beam interval so grazing beams are still tested
_U_EPS = 1e-9  # [-] segment parameter tolerance so a beam through a shared vertex hits


class SegmentIndex:
    """Segments bucketed on a square grid, for "which segments lie within ``reach`` of a point".

    Parameters
    ----------
    segments : (S, 4) float64
        ``[ax, ay, bx, by]`` [m].
    bucket : float
        [m] bucket edge length.
    """

    def __init__(self, segments: np.ndarray, bucket: float = BUCKET_SIZE) -> None:
        self.segments = np.ascontiguousarray(segments, dtype=np.float64).reshape(-1, 4)
        self.bucket = float(bucket)
        seg = self.segments
        if len(seg):
            self.lo = np.minimum(seg[:, :2], seg[:, 2:]).min(axis=0)
            hi = np.maximum(seg[:, :2], seg[:, 2:]).max(axis=0)
        else:
            self.lo, hi = np.zeros(2), np.zeros(2)
        self.shape = (np.floor((hi - self.lo) / self.bucket).astype(int) + 1)
        # Each segment lands in every bucket it passes through: sample it at half-bucket steps.
        lengths = np.hypot(seg[:, 2] - seg[:, 0], seg[:, 3] - seg[:, 1])
        n = np.ceil(lengths / (0.5 * self.bucket)).astype(int) + 1
        owner = np.repeat(np.arange(len(seg)), n)
        first = np.cumsum(n) - n
        frac = (np.arange(int(n.sum())) - np.repeat(first, n)) / np.repeat(np.maximum(n - 1, 1), n)
        pts = seg[owner, :2] + frac[:, None] * (seg[owner, 2:] - seg[owner, :2])
        cells = self._cells(pts)
        keys = np.unique(cells[:, 0] * self.shape[1] + cells[:, 1] + owner * self._n_buckets)
        owner = keys // self._n_buckets
        flat = keys % self._n_buckets
        order = np.argsort(flat, kind="stable")
        self._seg_of = owner[order]
        self._start = np.searchsorted(flat[order], np.arange(self._n_buckets + 1))
        self._cache: dict[tuple[int, int, int], np.ndarray] = {}

    @property
    def _n_buckets(self) -> int:
        return int(self.shape[0] * self.shape[1])

    def _cells(self, pts: np.ndarray) -> np.ndarray:
        c = np.floor((pts - self.lo) / self.bucket).astype(int)
        return np.clip(c, 0, self.shape - 1)

    def near(self, x: float, y: float, reach: float) -> np.ndarray:
        """Indices of segments that may come within ``reach`` [m] of ``(x, y)`` (a superset,
        cached per bucket)."""
        if not len(self.segments):
            return np.zeros(0, dtype=np.int64)
        ix, iy = self._cells(np.array([x, y]))
        k = math.ceil(reach / self.bucket)
        key = (int(ix), int(iy), k)
        hit = self._cache.get(key)
        if hit is None:
            x0, x1 = max(ix - k, 0), min(ix + k, self.shape[0] - 1)
            y0, y1 = max(iy - k, 0), min(iy + k, self.shape[1] - 1)
            parts = [self._seg_of[self._start[i * self.shape[1] + y0]:
                                  self._start[i * self.shape[1] + y1 + 1]]
                     for i in range(x0, x1 + 1)]
            hit = np.unique(np.concatenate(parts)) if parts else np.zeros(0, dtype=np.int64)
            self._cache[key] = hit
        return hit


def beam_angles(lidar: LidarSpec, yaw: float) -> np.ndarray:
    """``(B,)`` [rad] map-frame beam directions of a lidar on a robot heading ``yaw``."""
    return yaw + lidar.angle_min + lidar.angle_increment * np.arange(lidar.beams)


def _segments_distance(p: np.ndarray, seg: np.ndarray) -> np.ndarray:
    """``(S,)`` [m] distance from points ``p`` ((2,) or (S, 2)) to the segments ``(S, 4)``."""
    a, ab = seg[:, :2] - p, seg[:, 2:] - seg[:, :2]
    t = np.clip(-(a * ab).sum(1) / np.maximum((ab * ab).sum(1), 1e-300), 0.0, 1.0)
    return np.hypot(a[:, 0] + t * ab[:, 0], a[:, 1] + t * ab[:, 1])


def _beam_intervals(ang0: np.ndarray, ang1: np.ndarray, base: np.ndarray, lidar: LidarSpec
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Beams covered by the angular intervals ``[ang0, ang1]`` (``ang1 - ang0`` in [0, pi]).

    ``base`` is each interval's ``yaw + angle_min``. Returns ``(item, beam, count)``: one entry
    per (interval, beam) pair, ``item`` indexing the intervals (``(P,) int64`` each)."""
    nb, inc = lidar.beams, lidar.angle_increment
    u0 = ((ang0 - base) % (2.0 * np.pi)) / inc  # [beams] start of the interval
    u1 = u0 + (ang1 - ang0) / inc
    period = 2.0 * np.pi / inc  # [beams] one full turn (== beams for a 360 degree lidar)
    # The interval may wrap past a full turn: test it once as is and once a turn earlier.
    lo = np.ceil(np.concatenate([u0, u0 - period]) - _ANGLE_EPS)
    hi = np.floor(np.concatenate([u1, u1 - period]) + _ANGLE_EPS)
    lo = np.maximum(lo, 0).astype(np.int64)
    hi = np.minimum(hi, nb - 1).astype(np.int64)
    count = np.maximum(hi - lo + 1, 0)
    total = int(count.sum())
    item = np.repeat(np.tile(np.arange(len(ang0)), 2), count)
    first = np.cumsum(count) - count
    beam = np.arange(total) - np.repeat(first - lo, count)
    return item, beam, count


def cast_batch(origins: np.ndarray, yaws: np.ndarray, lidar: LidarSpec, segments: np.ndarray,
               seg_row: np.ndarray, circles: np.ndarray, circle_owner: np.ndarray) -> np.ndarray:
    """Raw first-hit distances ``(K, B)`` [m] (inf: no hit) of ``K`` scans with the same lidar.

    Parameters
    ----------
    origins : (K, 2) float64
        [m] sensor positions, map frame.
    yaws : (K,) float64
        [rad] headings.
    segments, seg_row : (S, 4) float64, (S,) int64
        Candidate segments ``[ax, ay, bx, by]`` and the scan row each one is tested for.
    circles, circle_owner : (C, 3) float64, (C,) int64
        ``[cx, cy, r]`` tested for every scan except the row in ``circle_owner`` (-1: none); a
        robot's own disc is thus never seen.
    """
    k_rows, nb = len(origins), lidar.beams
    out = np.full(k_rows * nb, np.inf)
    base = yaws + lidar.angle_min  # (K,)
    inc = lidar.angle_increment
    if len(segments):
        A = segments[:, :2] - origins[seg_row]  # (S, 2) relative to the row's sensor
        Bv = segments[:, 2:] - origins[seg_row]
        ang_a = np.arctan2(A[:, 1], A[:, 0])
        ang_b = np.arctan2(Bv[:, 1], Bv[:, 0])
        sweep = (ang_b - ang_a + np.pi) % (2.0 * np.pi) - np.pi
        start = np.where(sweep >= 0, ang_a, ang_b)
        item, beam, _ = _beam_intervals(start, start + np.abs(sweep), base[seg_row], lidar)
        row = seg_row[item]
        theta = base[row] + inc * beam
        dx, dy = np.cos(theta), np.sin(theta)
        ax, ay = A[item, 0], A[item, 1]
        ex, ey = Bv[item, 0] - ax, Bv[item, 1] - ay
        denom = dx * ey - dy * ex
        with np.errstate(divide="ignore", invalid="ignore"):
            t = (ax * ey - ay * ex) / denom
            u = (ax * dy - ay * dx) / denom
        ok = (denom != 0) & (u >= -_U_EPS) & (u <= 1.0 + _U_EPS) & (t >= 0)
        np.minimum.at(out, row[ok] * nb + beam[ok], t[ok])
    if len(circles):
        rel = circles[None, :, :2] - origins[:, None, :]  # (K, C, 2)
        dist = np.hypot(rel[..., 0], rel[..., 1])
        radius = circles[None, :, 2]
        keep = (dist - radius <= lidar.range_max) & (circle_owner[None, :] != np.arange(
            k_rows)[:, None])
        row, ci = np.nonzero(keep)
        if len(row):
            rel, dist, r = rel[row, ci], dist[row, ci], circles[ci, 2]
            centre = np.arctan2(rel[:, 1], rel[:, 0])
            half = np.where(dist > r, np.arcsin(np.minimum(r / np.maximum(dist, 1e-300), 1.0)),
                            0.5 * np.pi)
            item, beam, _ = _beam_intervals(centre - half, centre + half, base[row], lidar)
            pr = row[item]
            theta = base[pr] + inc * beam
            cx, cy = rel[item, 0], rel[item, 1]
            proj = np.cos(theta) * cx + np.sin(theta) * cy
            c2 = cx * cx + cy * cy - r[item] ** 2
            disc = proj * proj - c2
            with np.errstate(invalid="ignore"):
                t = proj - np.sqrt(disc)
            t = np.where((disc >= 0) & (proj >= 0), t, np.inf)
            inside = c2 < 0
            t[inside] = 0.0
            # Inside a circle every beam hits at 0 (the half-turn interval covers half of them).
            for j in np.unique(pr[inside]):
                out[j * nb:(j + 1) * nb] = 0.0
            np.minimum.at(out, pr * nb + beam, t)
    return out.reshape(k_rows, nb)


def ray_circle_ranges(origin: np.ndarray, angles: np.ndarray, circles: np.ndarray) -> np.ndarray:
    """``(B,)`` [m] distance along each beam (``angles`` (B,) [rad]) to the nearest circle
    ``(C, 3)`` ``[cx, cy, r]``; 0 if the origin is inside one, inf if none is hit (dense; a
    simple check for :func:`cast_batch`)."""
    out = np.full(len(angles), np.inf)
    if not len(circles):
        return out
    rel = circles[:, :2] - origin  # (C, 2)
    c2 = (rel * rel).sum(1) - circles[:, 2] ** 2  # (C,) < 0: origin inside
    proj = np.cos(angles)[:, None] * rel[:, 0] + np.sin(angles)[:, None] * rel[:, 1]  # (B, C)
    disc = proj * proj - c2
    with np.errstate(invalid="ignore"):
        t = proj - np.sqrt(disc)
    t = np.where((disc >= 0) & (proj >= 0), t, np.inf)
    t = np.where(c2 < 0, 0.0, t)
    return t.min(axis=1)


def finish_ranges(raw: np.ndarray, lidar: LidarSpec, noise_std: float,
                  rng: np.random.Generator | None) -> np.ndarray:
    """Apply the REP 117 convention (see module docstring) and optional Gaussian noise to raw
    first-hit distances ``(..., B)`` [m]; returns ``float32`` of the same shape."""
    ranges = raw.astype(np.float64, copy=True)
    hit = ranges <= lidar.range_max
    if noise_std > 0 and rng is not None:
        noisy = ranges + rng.normal(0.0, noise_std, size=ranges.shape)
        ranges = np.where(hit & (ranges >= lidar.range_min),
                          np.clip(noisy, lidar.range_min, lidar.range_max), ranges)
    ranges[~hit] = np.inf
    ranges[raw < lidar.range_min] = -np.inf
    return ranges.astype(np.float32)


def cast_scans(origins: np.ndarray, yaws: np.ndarray, lidar: LidarSpec, index: SegmentIndex,
               circles: np.ndarray, circle_owner: np.ndarray) -> np.ndarray:
    """``(K, B)`` raw first-hit distances (before :func:`finish_ranges`) of ``K`` scans with
    the same lidar against the indexed static segments and ``circles`` (see
    :func:`cast_batch`)."""
    origins = np.asarray(origins, dtype=np.float64).reshape(-1, 2)
    reach = lidar.range_max
    parts, rows = [], []
    for j, (x, y) in enumerate(origins):
        cand = index.near(float(x), float(y), reach)
        parts.append(cand)
        rows.append(np.full(len(cand), j, dtype=np.int64))
    cand = np.concatenate(parts)
    seg_row = np.concatenate(rows)
    seg = index.segments[cand]
    if len(seg):
        keep = _segments_distance(origins[seg_row], seg) <= reach
        seg, seg_row = seg[keep], seg_row[keep]
    return cast_batch(origins, np.asarray(yaws, dtype=np.float64).reshape(-1), lidar, seg,
                      seg_row, circles, circle_owner)


def pymunk_scan(space, origin: np.ndarray, yaw: float, lidar: LidarSpec,
                shape_filter) -> np.ndarray:
    """Slow reference: ``(B,)`` raw first-hit distances by one ``segment_query_first`` per beam
    (~4 us each). ``shape_filter`` must exclude the scanning robot's own shapes."""
    ox, oy = float(origin[0]), float(origin[1])
    out = np.full(lidar.beams, np.inf)
    reach = lidar.range_max
    for k, theta in enumerate(beam_angles(lidar, yaw)):
        end = (ox + reach * math.cos(theta), oy + reach * math.sin(theta))
        info = space.segment_query_first((ox, oy), end, 0.0, shape_filter)
        if info is not None:
            out[k] = info.alpha * reach
    return out
