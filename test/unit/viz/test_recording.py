"""Recordings as a user opens them (coverage_ros/viz/recording.py): where a saved file starts,
the region layer, and a file that cannot be indexed."""

from __future__ import annotations

import numpy as np
from rrdutil import read_rrd

from coverage_ros.core.world.grid import GridMap


def test_a_saved_recording_opens_at_its_end_and_shows_the_region(tmp_path):
    """The blueprint's time panel follows the newest data: a saved file opens on the team at
    its end, not on an empty map at its first second. The region of interest is a layer."""
    from rerun.chunk import RrdReader

    from coverage_ros.viz.recording import CoverageRecorder

    path = tmp_path / "r.rrd"
    rec = CoverageRecorder()
    rec.set_outputs(path)
    rec.log_map(GridMap(np.zeros((10, 10), np.int8), 0.1))
    rec.send_blueprint()
    rec.set_time(1.0)
    rec.log_robots([0], np.array([[0.5, 0.5]]), [0.1])
    rec.log_region([np.array([[0.1, 0.1], [0.6, 0.1], [0.6, 0.6]])])
    rec.close()
    reader = RrdReader(path)
    states = []
    for bp in reader.blueprints():
        for chunk in reader.store(store=bp).stream():
            batch = chunk.to_record_batch()
            if "TimePanelBlueprint:play_state" in batch.schema.names:
                states += batch.column("TimePanelBlueprint:play_state").to_pylist()
    assert states and all(s == [3] for s in states), states  # 3: following
    region = read_rrd(path)["/world/region"]
    strips = region[-1][1]["LineStrips3D:strips"][0]
    assert len(strips) == 4  # closed triangle


def test_a_recording_that_cannot_be_indexed_is_left_as_it_was(tmp_path):
    from coverage_ros.viz.recording import index_recording

    bad = tmp_path / "broken.rrd"
    bad.write_bytes(b"not a recording at all")
    problem = index_recording(bad)
    assert problem is not None and "without rerun's chunk index" in problem
    assert bad.read_bytes() == b"not a recording at all"
    assert [p.name for p in tmp_path.iterdir()] == ["broken.rrd"]  # no half-written file left
