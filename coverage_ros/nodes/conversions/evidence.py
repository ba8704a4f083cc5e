"""Message conversions: an exploring robot's evidence (conventions: :mod:`..conversions`).

``observations`` is a ``sensor_msgs/PointCloud2`` in the ``map`` frame, one point per cell of
the sender's own evidence: fields ``x``, ``y`` (FLOAT32, the cell centre [m]), ``hits`` and
``misses`` (UINT16, how many of the sender's scans saw the cell occupied / free). Counts only
grow, so a receiver keeps the largest it has heard per sender and cell; the sender is the robot
whose namespace the topic is in. A point cloud of cell centres shows in RViz as it is.
"""

from __future__ import annotations

import array

import numpy as np
from builtin_interfaces.msg import Time
from sensor_msgs.msg import PointCloud2, PointField

from coverage_ros.core.exploration.belief import Evidence
from coverage_ros.core.world.grid import GridMap
from coverage_ros.errors import ConfigError
from coverage_ros.nodes.conversions.basics import MAP_FRAME

#: The cloud's point layout: (name, offset, datatype, numpy dtype).
EVIDENCE_FIELDS = (("x", 0, PointField.FLOAT32, "<f4"), ("y", 4, PointField.FLOAT32, "<f4"),
                   ("hits", 8, PointField.UINT16, "<u2"), ("misses", 10, PointField.UINT16, "<u2"))
EVIDENCE_DTYPE = np.dtype({"names": [f[0] for f in EVIDENCE_FIELDS],
                           "formats": [f[3] for f in EVIDENCE_FIELDS],
                           "offsets": [f[1] for f in EVIDENCE_FIELDS], "itemsize": 12})


def evidence_msg(evidence: Evidence, lattice: GridMap, stamp: Time) -> PointCloud2:
    """One robot's evidence at some cells as ``sensor_msgs/PointCloud2``."""
    rows, cols = np.divmod(evidence.cells, lattice.width)
    xy = lattice.cell_centers(np.stack([rows, cols], axis=-1))
    points = np.zeros(len(evidence.cells), dtype=EVIDENCE_DTYPE)
    points["x"], points["y"] = xy[:, 0], xy[:, 1]
    points["hits"], points["misses"] = evidence.hits, evidence.misses
    msg = PointCloud2()
    msg.header.stamp = stamp
    msg.header.frame_id = MAP_FRAME
    msg.height, msg.width = 1, len(points)
    msg.fields = [PointField(name=n, offset=o, datatype=d, count=1)
                  for n, o, d, _ in EVIDENCE_FIELDS]
    msg.is_bigendian = False
    msg.point_step = EVIDENCE_DTYPE.itemsize
    msg.row_step = msg.point_step * len(points)
    msg.is_dense = True
    msg.data = array.array("B", points.tobytes())
    return msg


def evidence_from_msg(msg: PointCloud2, source: int, lattice: GridMap) -> Evidence:
    """The evidence of robot ``source`` in a cloud; raises ConfigError if the cloud is not an
    evidence cloud (fields, sizes, frame) or a point is not a cell centre of ``lattice``."""
    if msg.header.frame_id != MAP_FRAME:
        raise ConfigError.at("observations.header.frame_id", "must be the map frame",
                             msg.header.frame_id, MAP_FRAME)
    layout = [(f.name, f.offset, f.datatype) for f in msg.fields]
    if layout != [(n, o, d) for n, o, d, _ in EVIDENCE_FIELDS] or msg.is_bigendian \
            or msg.point_step != EVIDENCE_DTYPE.itemsize:
        raise ConfigError.at("observations.fields", "are not x, y (float32), hits, misses "
                             "(uint16), little-endian, 12 bytes a point",
                             [f.name for f in msg.fields])
    n = int(msg.width) * int(msg.height)
    data = bytes(msg.data)
    if len(data) != n * EVIDENCE_DTYPE.itemsize:
        raise ConfigError.at("observations.data", "size does not match width * height * 12",
                             len(data), str(n * EVIDENCE_DTYPE.itemsize))
    points = np.frombuffer(data, dtype=EVIDENCE_DTYPE)
    xy = np.stack([points["x"], points["y"]], axis=-1).astype(np.float64)
    if not np.all(np.isfinite(xy)):
        raise ConfigError.at("observations", "holds non-finite positions")
    cells = lattice.world_to_cell(xy)
    if not lattice.contains_cell(cells).all():
        raise ConfigError.at("observations", "holds points outside the map", int(
            (~lattice.contains_cell(cells)).sum()))
    flat = cells[:, 0] * lattice.width + cells[:, 1]
    return Evidence(int(source), flat.astype(np.int64), points["hits"].astype(np.uint16),
                    points["misses"].astype(np.uint16))
