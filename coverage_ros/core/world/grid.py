"""Occupancy grids in the ROS convention, and conversions between cells and map coordinates.

Conventions (the same as nav_msgs/OccupancyGrid, REP 103):

* ``occupancy[row, col]`` with row 0 at the map origin (lowest y), col 0 at the lowest x;
  values 0 = free, 100 = occupied, -1 = unknown, 1..99 = occupancy probability in percent.
* ``origin = (x, y, yaw)`` is the pose, in the ``map`` frame, of the lower-left corner of cell
  (0, 0); yaw rotates the grid counter-clockwise about that corner.
* Cell centres are at ``origin + R(yaw) @ ((col + 0.5) * resolution, (row + 0.5) * resolution)``.
* Points are ``(N, 2) float64`` arrays of ``(x, y)`` in metres, map frame; cells are
  ``(N, 2) int64`` arrays of ``(row, col)``.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from coverage_ros.errors import ConfigError

FREE = 0
OCCUPIED = 100
UNKNOWN = -1
#: [percent] cells at or above this occupancy count as obstacles (map_server's occupied_thresh
#: of 0.65 maps to 100 in trinary mode; scale-mode maps carry intermediate values).
OCCUPIED_PERCENT = 65


@dataclass(frozen=True)
class GridMap:
    """An occupancy grid with its resolution and origin (see module docstring for conventions)."""

    occupancy: np.ndarray
    resolution: float
    origin: tuple[float, float, float] = (0.0, 0.0, 0.0)
    _rot: np.ndarray = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        occ = np.asarray(self.occupancy)
        if occ.ndim != 2 or occ.shape[0] < 1 or occ.shape[1] < 1:
            raise ConfigError.at("grid.occupancy", "must be a non-empty 2-D array", occ.shape)
        if not np.isfinite(self.resolution) or self.resolution <= 0:
            raise ConfigError.at("grid.resolution", "must be a positive number of metres per cell",
                                 self.resolution)
        if len(self.origin) != 3 or not np.all(np.isfinite(self.origin)):
            raise ConfigError.at("grid.origin", "must be three finite numbers [x, y, yaw]",
                                 self.origin)
        occ = np.ascontiguousarray(occ, dtype=np.int8)
        occ.setflags(write=False)
        object.__setattr__(self, "occupancy", occ)
        object.__setattr__(self, "resolution", float(self.resolution))
        object.__setattr__(self, "origin", tuple(float(v) for v in self.origin))
        c, s = np.cos(self.origin[2]), np.sin(self.origin[2])
        object.__setattr__(self, "_rot", np.array([[c, -s], [s, c]]))

    # ------------------------------------------------------------------ shape and extent
    @property
    def shape(self) -> tuple[int, int]:
        """``(height, width)`` in cells."""
        H, W = self.occupancy.shape
        return H, W

    @property
    def height(self) -> int:
        return int(self.occupancy.shape[0])

    @property
    def width(self) -> int:
        return int(self.occupancy.shape[1])

    @property
    def cell_area(self) -> float:
        """[m^2] area of one cell."""
        return self.resolution * self.resolution

    def extent(self) -> tuple[float, float, float, float]:
        """``(xmin, ymin, xmax, ymax)`` of the grid's bounding box in the map frame [m]."""
        corners = self.grid_to_world(np.array([[0.0, 0.0], [self.width, 0.0],
                                               [0.0, self.height], [self.width, self.height]]))
        return (float(corners[:, 0].min()), float(corners[:, 1].min()),
                float(corners[:, 0].max()), float(corners[:, 1].max()))

    # ------------------------------------------------------------------ masks
    def occupied_mask(self, unknown_is_occupied: bool = True) -> np.ndarray:
        """``(H, W) bool``: cells that are obstacles (and unknown ones, by default)."""
        occ = self.occupancy
        mask = occ >= OCCUPIED_PERCENT
        if unknown_is_occupied:
            mask |= occ < 0
        return mask

    def free_mask(self, unknown_is_free: bool = False) -> np.ndarray:
        """``(H, W) bool``: cells a robot centre may occupy, before inflation."""
        return ~self.occupied_mask(unknown_is_occupied=not unknown_is_free)

    def clearance(self, unknown_is_free: bool = False) -> np.ndarray:
        """``(H, W) float64`` [m]: distance from each cell centre to the nearest blocked cell.

        Blocked cells have clearance 0; cells outside the grid count as blocked, so a robot
        never plans off the map.
        """
        from scipy import ndimage  # scipy's import is a tenth of a second: only when used

        free = np.pad(self.free_mask(unknown_is_free), 1, constant_values=False)
        dist: np.ndarray = ndimage.distance_transform_edt(free) * self.resolution
        return dist[1:-1, 1:-1]

    def inflated_free_mask(self, radius: float, unknown_is_free: bool = False) -> np.ndarray:
        """``(H, W) bool``: free cells whose centre is farther than ``radius`` [m] from any
        blocked cell centre (the configuration space of a disc robot of that radius)."""
        if radius < 0 or not np.isfinite(radius):
            raise ConfigError.at("robot_radius", "must be a finite number >= 0", radius)
        if radius == 0:
            return self.free_mask(unknown_is_free)
        # A blocked cell occupies a square of half-width res/2 around its centre; the robot
        # clears it when its centre is more than radius from that square, approximated by
        # distance between centres > radius + res/2.
        return erode_by_disc(self.free_mask(unknown_is_free), self.resolution,
                             radius + 0.5 * self.resolution)

    # ------------------------------------------------------------------ coordinates
    def grid_to_world(self, grid_xy: np.ndarray) -> np.ndarray:
        """Continuous grid coordinates ``(gx, gy)`` in cells -> map-frame ``(x, y)`` [m]."""
        g = np.asarray(grid_xy, dtype=np.float64) * self.resolution
        xy: np.ndarray = _rotate(g, self._rot) + np.array(self.origin[:2])
        return xy

    def world_to_grid(self, xy: np.ndarray) -> np.ndarray:
        """Map-frame ``(x, y)`` [m] -> continuous grid coordinates ``(gx, gy)`` in cells."""
        p = np.asarray(xy, dtype=np.float64) - np.array(self.origin[:2])
        return _rotate(p, self._rot.T) / self.resolution

    def direction_to_grid(self, v: np.ndarray) -> np.ndarray:
        """Map-frame vectors ``(..., 2)`` -> the same vectors in grid axes (rotation only, same
        length)."""
        rotated: np.ndarray = np.asarray(v, dtype=np.float64) @ self._rot
        return rotated

    def cell_centers(self, cells: np.ndarray) -> np.ndarray:
        """``(N, 2)`` cells ``(row, col)`` -> ``(N, 2)`` centres ``(x, y)`` [m]."""
        c = np.asarray(cells)
        return self.grid_to_world(np.stack([c[..., 1] + 0.5, c[..., 0] + 0.5], axis=-1))

    def world_to_cell(self, xy: np.ndarray) -> np.ndarray:
        """``(N, 2)`` points [m] -> ``(N, 2) int64`` cells ``(row, col)`` containing them
        (may lie outside the grid; check with :meth:`contains_cell`)."""
        g = np.floor(self.world_to_grid(xy)).astype(np.int64)
        return np.stack([g[..., 1], g[..., 0]], axis=-1)

    def contains_cell(self, cells: np.ndarray) -> np.ndarray:
        c = np.asarray(cells)
        return ((c[..., 0] >= 0) & (c[..., 0] < self.height)
                & (c[..., 1] >= 0) & (c[..., 1] < self.width))

    def contains_point(self, xy: np.ndarray) -> np.ndarray:
        return self.contains_cell(self.world_to_cell(xy))

    def all_cell_centers(self) -> tuple[np.ndarray, np.ndarray]:
        """``(X, Y)``, each ``(H, W)``: map-frame coordinates of every cell centre."""
        # x = o + R (c + 1/2, r + 1/2) res, summed from a row and a column term (no (H*W, 2)
        # temporaries)
        gx = (np.arange(self.width) + 0.5) * self.resolution
        gy = (np.arange(self.height) + 0.5) * self.resolution
        rot, (ox, oy) = self._rot, self.origin[:2]
        X = (rot[0, 0] * gx + ox)[None, :] + (rot[0, 1] * gy)[:, None]
        Y = (rot[1, 0] * gx)[None, :] + (rot[1, 1] * gy + oy)[:, None]
        return X, Y

    def with_occupancy(self, occupancy: np.ndarray) -> GridMap:
        """A grid with the same geometry and new cell values."""
        if np.shape(occupancy) != self.shape:
            raise ConfigError.at("grid.occupancy", "shape must match the grid",
                                 np.shape(occupancy), str(self.shape))
        return GridMap(occupancy, self.resolution, self.origin)


def erode_by_disc(free: np.ndarray, resolution: float, reach: float) -> np.ndarray:
    """``free`` cells whose centre is farther than ``reach`` [m] from every blocked cell centre
    (cells outside the grid count as blocked): ``clearance > reach`` without the distance
    transform, one horizontal run test per row offset (the same float comparison, so the same
    cells)."""
    H, W = free.shape
    k = int(reach / resolution) + 1  # offsets beyond k cells are farther than reach
    blocked = np.pad(~free, k, constant_values=True)
    counts = np.zeros((H + 2 * k, W + 2 * k + 1), dtype=np.int32)
    np.cumsum(blocked, axis=1, out=counts[:, 1:])
    near = np.zeros((H, W), dtype=bool)
    cols = np.arange(W) + k
    for dr in range(-k, k + 1):
        dc = np.arange(k + 1)
        within = np.sqrt(dr * dr + dc * dc) * resolution <= reach
        if not within.any():
            continue
        half = int(dc[within].max())  # blocked within [c - half, c + half] on row r + dr
        rows = counts[k + dr:k + dr + H]
        near |= rows[:, cols + half + 1] > rows[:, cols - half]
    return free & ~near


def _rotate(xy: np.ndarray, rot: np.ndarray) -> np.ndarray:
    """``xy @ rot.T`` for ``(..., 2)`` points: two multiply-adds per point (faster than a BLAS
    product with a 2 x 2 matrix)."""
    x, y = xy[..., 0], xy[..., 1]
    return np.stack([rot[0, 0] * x + rot[0, 1] * y, rot[1, 0] * x + rot[1, 1] * y], axis=-1)
