"""Importance densities w(q) >= 0 over the map, and their parsing from YAML.

Three kinds, all evaluated on ``(N, 2)`` map-frame points [m]:

* :class:`UniformDensity` - w = 1 everywhere.
* :class:`GaussianMixture` - w = floor + sum_k weight_k * exp(-0.5 (q - mu_k)^T S_k^-1 (q - mu_k)),
  unnormalised so a peak of weight 1 has value 1.
* :class:`TargetPolygons` - w = value inside any target polygon and ``outside`` (0 by default)
  elsewhere: disjoint target regions as in Lee & Lee 2024.

Densities are immutable; :func:`density_on_grid` rasterises one at the cell centres.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np

from coverage_ros.core.geometry import points_in_polygon
from coverage_ros.core.world.grid import GridMap
from coverage_ros.errors import ConfigError


class Density(Protocol):
    @property
    def kind(self) -> str:
        """The ``type`` of the YAML form."""
        ...

    def __call__(self, points: np.ndarray) -> np.ndarray:
        """``(N,) float64 >= 0`` density at ``(N, 2)`` points."""
        ...

    def to_dict(self) -> dict[str, Any]:
        """The YAML/JSON form that :func:`parse_density` reads back."""
        ...


@dataclass(frozen=True)
class UniformDensity:
    kind: str = "uniform"

    def __call__(self, points: np.ndarray) -> np.ndarray:
        return np.ones(np.asarray(points).reshape(-1, 2).shape[0])

    def to_dict(self) -> dict[str, Any]:
        return {"type": "uniform"}


@dataclass(frozen=True)
class GaussianMixture:
    """Sum of unnormalised Gaussian bumps plus a constant floor."""

    means: np.ndarray  # (K, 2) [m]
    covariances: np.ndarray  # (K, 2, 2) [m^2]
    weights: np.ndarray  # (K,)
    floor: float = 0.0
    kind: str = "gaussian_mixture"

    def __post_init__(self) -> None:
        means = np.asarray(self.means, dtype=np.float64).reshape(-1, 2)
        covs = np.asarray(self.covariances, dtype=np.float64).reshape(-1, 2, 2)
        weights = np.asarray(self.weights, dtype=np.float64).reshape(-1)
        if not (len(means) == len(covs) == len(weights)) or len(means) == 0:
            raise ConfigError.at("density.components", "need matching, non-empty means, "
                                 "covariances and weights", (len(means), len(covs), len(weights)))
        for k, cov in enumerate(covs):
            if not np.allclose(cov, cov.T) or np.any(np.linalg.eigvalsh(cov) <= 0):
                raise ConfigError.at(f"density.components[{k}]", "covariance must be symmetric "
                                     "positive definite", cov.tolist())
        if np.any(weights < 0) or not np.all(np.isfinite(weights)):
            raise ConfigError.at("density.components", "weights must be finite and >= 0",
                                 weights.tolist())
        if self.floor < 0 or not np.isfinite(self.floor):
            raise ConfigError.at("density.floor", "must be finite and >= 0", self.floor)
        object.__setattr__(self, "means", means)
        object.__setattr__(self, "covariances", covs)
        object.__setattr__(self, "weights", weights)

    def __call__(self, points: np.ndarray) -> np.ndarray:
        pts = np.asarray(points, dtype=np.float64).reshape(-1, 2)
        out = np.full(len(pts), float(self.floor))
        for mean, cov, weight in zip(self.means, self.covariances, self.weights, strict=True):
            dx, dy = pts[:, 0] - mean[0], pts[:, 1] - mean[1]
            inv = np.linalg.inv(cov)
            # d^T S^-1 d term by term (faster than a three-operand einsum)
            m2 = inv[0, 0] * dx * dx + (inv[0, 1] + inv[1, 0]) * dx * dy + inv[1, 1] * dy * dy
            out += weight * np.exp(-0.5 * m2)
        return out

    def to_dict(self) -> dict[str, Any]:
        return {"type": "gaussian_mixture", "floor": float(self.floor), "components": [
            {"mean": m.tolist(), "covariance": c.tolist(), "weight": float(w)}
            for m, c, w in zip(self.means, self.covariances, self.weights, strict=True)]}


@dataclass(frozen=True)
class TargetPolygons:
    """``value`` inside any of the polygons, ``outside`` elsewhere."""

    polygons: tuple[np.ndarray, ...]
    value: float = 1.0
    outside: float = 0.0
    kind: str = "targets"

    def __post_init__(self) -> None:
        polys = tuple(np.asarray(p, dtype=np.float64).reshape(-1, 2) for p in self.polygons)
        if not polys:
            raise ConfigError.at("density.polygons", "need at least one target polygon", [])
        for k, p in enumerate(polys):
            if len(p) < 3 or not np.all(np.isfinite(p)):
                raise ConfigError.at(f"density.polygons[{k}]",
                                     "need at least 3 finite [x, y] vertices", p.tolist())
        if self.value <= 0 or self.outside < 0:
            raise ConfigError.at("density.value/outside", "need value > 0 and outside >= 0",
                                 (self.value, self.outside))
        object.__setattr__(self, "polygons", polys)

    def inside(self, points: np.ndarray) -> np.ndarray:
        pts = np.asarray(points, dtype=np.float64).reshape(-1, 2)
        mask = np.zeros(len(pts), dtype=bool)
        for poly in self.polygons:
            lo, hi = poly.min(axis=0), poly.max(axis=0)
            cand = np.all((pts >= lo) & (pts <= hi), axis=1) & ~mask
            if np.any(cand):
                mask[cand] = points_in_polygon(pts[cand], poly)
        return mask

    def __call__(self, points: np.ndarray) -> np.ndarray:
        return np.where(self.inside(points), self.value, self.outside)

    def to_dict(self) -> dict[str, Any]:
        return {"type": "targets", "value": float(self.value), "outside": float(self.outside),
                "polygons": [p.tolist() for p in self.polygons]}


def density_on_grid(density: Density, grid: GridMap, mask: np.ndarray | None = None) -> np.ndarray:
    """``(H, W) float64``: the density at every cell centre (0 where ``mask`` is False)."""
    if isinstance(density, UniformDensity):  # no cell centres: an exploring robot's every
        w = np.ones(grid.shape)  # update builds a domain (they were a sixth of its CPU)
    else:
        X, Y = grid.all_cell_centers()
        w = density(np.stack([X.ravel(), Y.ravel()], axis=-1)).reshape(grid.shape)
    if mask is not None:
        w = np.where(mask, w, 0.0)
    return w


# ---------------------------------------------------------------------------- parsing
_KEYS = {
    "uniform": {"type"},
    "gaussian_mixture": {"type", "components", "floor"},
    "targets": {"type", "polygons", "value", "outside"},
}
_COMPONENT_KEYS = {"mean", "sigma", "covariance", "weight"}


def _vec2(where: str, value: Any) -> np.ndarray:
    arr = np.asarray(value, dtype=np.float64) if _is_numeric_list(value, 2) else None
    if arr is None or not np.all(np.isfinite(arr)):
        raise ConfigError.at(where, "must be a list of two numbers [x, y]", value)
    return arr


def _is_numeric_list(value: Any, n: int) -> bool:
    return (isinstance(value, list | tuple) and len(value) == n
            and all(isinstance(v, int | float) and not isinstance(v, bool) for v in value))


def _positive(where: str, value: Any) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float) or not value > 0:
        raise ConfigError.at(where, "must be a number > 0", value)
    return float(value)


def parse_density(data: Any, where: str = "density") -> Density:
    """Build a density from its YAML mapping (``type: uniform | gaussian_mixture | targets``).

    ``gaussian_mixture`` components take ``mean: [x, y]``, ``weight`` (default 1) and either
    ``sigma`` (a number or ``[sx, sy]``, metres) or ``covariance: [[a, b], [b, c]]``.
    """
    if data is None:
        return UniformDensity()
    if isinstance(data, str):
        data = {"type": data}
    if not isinstance(data, dict):
        raise ConfigError.at(where, "must be a mapping with a 'type'", data)
    kind = data.get("type")
    if kind not in _KEYS:
        raise ConfigError.at(f"{where}.type", "unknown density type", kind,
                             f"one of {list(_KEYS)}")
    unknown = sorted(set(data) - _KEYS[kind])
    if unknown:
        raise ConfigError.at(f"{where}.{unknown[0]}", f"unknown key for a {kind} density",
                             expected=f"one of {sorted(_KEYS[kind])}")
    if kind == "uniform":
        return UniformDensity()
    if kind == "gaussian_mixture":
        comps = data.get("components")
        if not isinstance(comps, list) or not comps:
            raise ConfigError.at(f"{where}.components", "need a non-empty list of components",
                                 comps)
        means, covs, weights = [], [], []
        for k, comp in enumerate(comps):
            cw = f"{where}.components[{k}]"
            if not isinstance(comp, dict):
                raise ConfigError.at(cw, "must be a mapping", comp)
            bad = sorted(set(comp) - _COMPONENT_KEYS)
            if bad:
                raise ConfigError.at(f"{cw}.{bad[0]}", "unknown key",
                                     expected=f"one of {sorted(_COMPONENT_KEYS)}")
            means.append(_vec2(f"{cw}.mean", comp.get("mean")))
            if "covariance" in comp:
                cov = np.asarray(comp["covariance"], dtype=np.float64)
                if cov.shape != (2, 2):
                    raise ConfigError.at(f"{cw}.covariance", "must be a 2x2 matrix",
                                         comp["covariance"])
            else:
                sigma: Any = comp.get("sigma", None)
                if _is_numeric_list(sigma, 2):
                    sx, sy = (_positive(f"{cw}.sigma", s) for s in sigma)
                else:
                    sx = sy = _positive(f"{cw}.sigma", sigma)
                cov = np.diag([sx * sx, sy * sy])
            covs.append(cov)
            weights.append(float(comp.get("weight", 1.0)))
        return GaussianMixture(np.array(means), np.array(covs), np.array(weights),
                               float(data.get("floor", 0.0)))
    polys = data.get("polygons")
    if not isinstance(polys, list) or not polys:
        raise ConfigError.at(f"{where}.polygons", "need a non-empty list of polygons", polys)
    parsed = []
    for k, poly in enumerate(polys):
        if not isinstance(poly, list) or not all(_is_numeric_list(p, 2) for p in poly):
            raise ConfigError.at(f"{where}.polygons[{k}]", "must be a list of [x, y] points", poly)
        parsed.append(np.array(poly, dtype=np.float64))
    return TargetPolygons(tuple(parsed), float(data.get("value", 1.0)),
                          float(data.get("outside", 0.0)))
