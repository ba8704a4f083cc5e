"""map_server maps: cell-for-cell loading, modes, errors."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import shared_map

from coverage_ros.core.world.grid import GridMap
from coverage_ros.core.world.map_server import load_map_yaml, write_map_yaml
from coverage_ros.errors import MapError


def read_pgm(path):
    """A minimal independent P5 reader: header tokens, then raw bytes."""
    data = path.read_bytes()
    tokens, pos = [], 0
    while len(tokens) < 4:
        while data[pos:pos + 1].isspace():
            pos += 1
        if data[pos:pos + 1] == b"#":
            pos = data.index(b"\n", pos) + 1
            continue
        end = pos
        while not data[end:end + 1].isspace():
            end += 1
        tokens.append(data[pos:end].decode())
        pos = end
    assert tokens[0] == "P5"
    width, height, maxval = int(tokens[1]), int(tokens[2]), int(tokens[3])
    pos += 1
    pixels = np.frombuffer(data[pos:pos + width * height], dtype=np.uint8)
    return pixels.reshape(height, width), maxval


@pytest.mark.parametrize("name", ["tb3_sandbox", "depot", "warehouse"])
def test_map_server_map_loads_cell_for_cell(name):
    import yaml

    yaml_path = shared_map(name)
    meta = yaml.safe_load(yaml_path.read_text())
    pixels, maxval = read_pgm(yaml_path.parent / meta["image"])
    grid = load_map_yaml(yaml_path)
    assert grid.shape == pixels.shape
    assert grid.resolution == pytest.approx(meta["resolution"])
    assert grid.origin == pytest.approx(tuple(meta["origin"]))
    # nav2 map_io, trinary: occ = (255 - v)/255; > occupied_thresh -> 100, < free_thresh -> 0.
    for row in range(0, pixels.shape[0], 7):
        for col in range(0, pixels.shape[1], 5):
            v = pixels[row, col] * 255.0 / maxval
            occ = (255.0 - v) / 255.0
            expected = 100 if occ > meta["occupied_thresh"] else (
                0 if occ < meta["free_thresh"] else -1)
            # Image row 0 is the top of the map, grid row 0 the bottom.
            assert grid.occupancy[pixels.shape[0] - 1 - row, col] == expected, (row, col)


def test_cell_centres_follow_origin_and_resolution():
    yaml_path = shared_map("tb3_sandbox")
    grid = load_map_yaml(yaml_path)
    centre = grid.cell_centers(np.array([[0, 0], [10, 20]]))
    assert centre[0] == pytest.approx([-10.0 + 0.025, -10.0 + 0.025])
    assert centre[1] == pytest.approx([-10.0 + 20.5 * 0.05, -10.0 + 10.5 * 0.05])
    assert grid.world_to_cell(centre).tolist() == [[0, 0], [10, 20]]


def test_rotated_origin_round_trips():
    grid = GridMap(np.zeros((4, 6), np.int8), 0.5, (1.0, -2.0, 0.7))
    cells = np.array([[0, 0], [3, 5], [2, 1]])
    assert grid.world_to_cell(grid.cell_centers(cells)).tolist() == cells.tolist()


@pytest.mark.parametrize("yaw", [0.0, 0.7, -2.9])
def test_all_cell_centres_are_every_cells_centre(yaw):
    grid = GridMap(np.zeros((5, 7), np.int8), 0.3, (1.0, -2.0, yaw))
    X, Y = grid.all_cell_centers()
    rows, cols = np.mgrid[0:5, 0:7]
    xy = grid.cell_centers(np.stack([rows.ravel(), cols.ravel()], axis=-1))
    assert X.shape == Y.shape == (5, 7)
    assert np.allclose(X.ravel(), xy[:, 0], atol=1e-12)
    assert np.allclose(Y.ravel(), xy[:, 1], atol=1e-12)
    assert grid.world_to_cell(np.stack([X[4, 6], Y[4, 6]])[None]).tolist() == [[4, 6]]


def _write(tmp_path, pixels: np.ndarray, **meta):
    from PIL import Image

    Image.fromarray(pixels).save(tmp_path / "m.png")
    import yaml

    doc = {"image": "m.png", "resolution": 0.1, "origin": [0, 0, 0], "negate": 0,
           "occupied_thresh": 0.65, "free_thresh": 0.25}
    doc.update(meta)
    (tmp_path / "m.yaml").write_text(yaml.safe_dump(doc))
    return tmp_path / "m.yaml"


def test_modes_negate_and_scale(tmp_path):
    img = np.array([[0, 100, 205, 254]], dtype=np.uint8)
    # occ = (255 - v) / 255 = 1.0, 0.608, 0.196, 0.004 against thresholds 0.65 / 0.25.
    trinary = load_map_yaml(_write(tmp_path, img)).occupancy[0].tolist()
    assert trinary == [100, -1, 0, 0]
    # negate: occ = v / 255 = 0.0, 0.392, 0.804, 0.996.
    negated = load_map_yaml(_write(tmp_path, img, negate=1)).occupancy[0].tolist()
    assert negated == [0, -1, 100, 100]
    # scale: in-between values map linearly onto 0..100.
    scale = load_map_yaml(_write(tmp_path, img, mode="scale")).occupancy[0].tolist()
    assert scale == [100, round(100 * ((255 - 100) / 255 - 0.25) / 0.4), 0, 0]
    raw = load_map_yaml(_write(tmp_path, np.array([[0, 50, 100, 255]], np.uint8), mode="raw"))
    assert raw.occupancy[0].tolist() == [0, 50, 100, -1]


def test_save_and_reload_round_trip(tmp_path):
    occ = np.zeros((5, 7), np.int8)
    occ[1, 2] = 100
    occ[3, :] = -1
    grid = GridMap(occ, 0.2, (-1.0, 2.0, 0.0))
    back = load_map_yaml(write_map_yaml(grid, tmp_path / "saved.yaml"))
    assert np.array_equal(back.occupancy, occ)
    assert back.origin == pytest.approx(grid.origin)


@pytest.mark.parametrize("meta, message", [
    ({"resolution": -0.1}, "resolution: must be > 0"),
    ({"origin": [0, 0]}, "origin: must be a list of three numbers"),
    ({"mode": "fancy"}, "mode: unknown map mode"),
    ({"free_thresh": 0.9}, "need 0 <= free_thresh < occupied_thresh"),
    ({"colour": 1}, "colour: unknown key"),
    ({"image": "missing.pgm"}, "map image not found"),
])
def test_bad_map_yaml_is_named(tmp_path, meta, message):
    path = _write(tmp_path, np.zeros((2, 2), np.uint8), **meta)
    with pytest.raises(MapError, match=message) as info:
        load_map_yaml(path)
    assert str(path) in str(info.value)


def test_missing_and_malformed_files(tmp_path):
    with pytest.raises(MapError, match="file not found"):
        load_map_yaml(tmp_path / "nope.yaml")
    bad = tmp_path / "bad.yaml"
    bad.write_text("image: [unclosed\n")
    with pytest.raises(MapError, match=r"bad.yaml:\d+: malformed YAML"):
        load_map_yaml(bad)


def test_the_image_given_for_the_yaml_is_named(tmp_path):
    image = tmp_path / "map.pgm"
    image.write_bytes(b"P5\n2 2\n255\n\xcd\xff\x00\xfe")
    with pytest.raises(MapError, match=r"map.pgm: is not a text file .*its \.yaml, not the image"):
        load_map_yaml(image)
