"""A team's iCVT + projection run forward on the mass cells, and the measures of where it ends:
the paper's metric (I, I^L or I^H) and the coverage cost H (Eq. 2).

The centralized alpha-CVT (:mod:`.dropout`) steps its agents with :func:`cvt_step`; the
relocation (:mod:`.relocation`) predicts where a team settles after a move with :func:`settle`
and weighs it with :func:`team_metric` and :func:`coverage_energy`.
"""

from __future__ import annotations

import numpy as np

from coverage_ros.core.strategies.acvt.cells import CellSpec, MassCells, deviation_metric


def cvt_step(cells: MassCells, spec: CellSpec, positions: np.ndarray,
             reach: np.ndarray | None, movers: np.ndarray | None = None,
             projection: bool = True) -> np.ndarray:
    """One iCVT (+ projection, Eq. 8) step of the agents ``movers`` (bool mask; all by
    default) on the partition among themselves; the others keep their place. An agent with an
    empty cell keeps its position as virtual target (then projected). ``(k, 2)`` [m] in and
    out."""
    P = np.asarray(positions, dtype=np.float64)
    idx = np.arange(len(P)) if movers is None else np.flatnonzero(movers)
    sub_reach = None if reach is None else reach[idx]
    labels = cells.labels(P[idx], sub_reach, spec)
    _, centroids = cells.stats(labels, len(idx))
    virt = np.where(np.isnan(centroids), P[idx], centroids)
    out = P.copy()
    out[idx] = cells.project(virt) if projection else virt
    return out


def team_metric(cells: MassCells, spec: CellSpec, positions: np.ndarray,
                reach: np.ndarray | None) -> tuple[np.ndarray, np.ndarray, float]:
    """``(labels (N,), masses (k,), metric)`` of the partition at ``positions``: I (Eq. 9),
    I^L (Eq. 13) or I^H (Eq. 18), as the paper uses for the scenario."""
    labels = cells.labels(positions, reach, spec)
    masses, _ = cells.stats(labels, len(positions))
    return labels, masses, deviation_metric(masses, cells.total, reach, spec.visibility)


def coverage_energy(cells: MassCells, labels: np.ndarray, positions: np.ndarray,
                    reach: np.ndarray | None = None) -> float:
    """Eq. 2: H = sum of |s - p_i|^2 rho(s) ds over each agent's labelled cells (uncovered
    cells count nothing); with ``reach (k,)`` each agent's term is divided by R_i^2 - the
    energy that the partition by |s - p_i| / R_i (Eq. 17) and the centroid step descend."""
    ok = labels >= 0
    d = cells.xy[ok] - np.asarray(positions, dtype=np.float64)[labels[ok]]
    d2 = (d * d).sum(axis=1)
    if reach is not None:
        d2 /= np.asarray(reach, dtype=np.float64)[labels[ok]] ** 2
    return float((d2 * cells.wdA[ok]).sum())


def settle(cells: MassCells, spec: CellSpec, positions: np.ndarray, reach: np.ndarray | None,
           horizon: int, tolerance: float) -> np.ndarray:
    """iCVT + projection from ``positions`` until no agent moves farther than ``tolerance`` [m]
    or ``horizon`` steps have run; the positions reached."""
    P = np.asarray(positions, dtype=np.float64)
    for _ in range(horizon):
        new = cvt_step(cells, spec, P, reach)
        moved = float(np.hypot(*(new - P).T).max()) if len(P) else 0.0
        P = new
        if moved < tolerance:
            break
    return P
