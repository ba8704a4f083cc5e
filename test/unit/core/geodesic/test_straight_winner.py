"""Every cell's nearest generator in straight-line distance from the Voronoi runs
(coverage_ros.core.geodesic.straight_winner) equals the brute-force loop over every generator,
bit for bit, ties and the tie bias included; each generator's box holds all of its cells."""

from __future__ import annotations

import numpy as np
import pytest

from coverage_ros.core.geodesic.domain import tie_bias
from coverage_ros.core.geodesic.straight_winner import straight_winner


def _brute_force(grids: np.ndarray, biases: np.ndarray, shape: tuple[int, int],
                 res: float) -> tuple[np.ndarray, np.ndarray]:
    """Every cell against every generator in turn, a strictly nearer one taking over."""
    H, W = shape
    cx, cy = np.arange(W) + 0.5, np.arange(H) + 0.5
    best = np.full((H, W), np.inf)
    winner = np.full((H, W), -1, dtype=np.int64)
    for k, (gx, gy) in enumerate(grids):
        d = np.sqrt((cy - gy)[:, None] ** 2 + (cx - gx)[None, :] ** 2) * res + biases[k]
        closer = d < best
        winner[closer] = k
        best = np.minimum(best, d)
    return best.ravel(), winner.ravel()


def _generators(kind: str, n: int, shape: tuple[int, int],
                rng: np.random.Generator) -> np.ndarray:
    H, W = shape
    if kind == "anywhere":
        return rng.uniform(-2.0, [W + 2.0, H + 2.0], (n, 2))
    if kind == "centres":  # cell centres: many cells exactly as far from two generators
        return rng.integers(0, [W, H], (n, 2)) + 0.5
    if kind == "corners":  # grid corners: four or more generators on one circle
        return rng.integers(0, [W, H], (n, 2)).astype(np.float64)
    g = rng.integers(0, [W // 2 + 1, H // 2 + 1], (n, 2)) * 2 + 0.5  # twins
    g[-1] = g[0]
    return g.astype(np.float64)


@pytest.mark.parametrize("kind", ["anywhere", "centres", "corners", "twins"])
@pytest.mark.parametrize("n", [1, 2, 3, 8, 30])
def test_straight_winner_is_the_brute_force_loop(kind, n):
    rng = np.random.default_rng(n * 7 + len(kind))
    for trial in range(12):
        shape = tuple(int(v) for v in rng.integers(4, 70, 2))
        grids = _generators(kind, n, shape, rng)
        biases = np.array([tie_bias(g) for g in grids]) if trial % 3 else np.zeros(n)
        res = float(rng.choice([0.01, 0.05, 0.1]))
        best, winner = straight_winner(grids, biases, shape, res)
        ref_best, ref_winner = _brute_force(grids, biases, shape, res)
        assert np.array_equal(winner, ref_winner)
        assert np.array_equal(best, ref_best)
