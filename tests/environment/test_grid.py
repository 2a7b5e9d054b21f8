"""OccupancyGrid: ROS map_server semantics against hand-made fixtures with known cells."""

from __future__ import annotations

import numpy as np
import pytest
import yaml
from PIL import Image

from are_stats import OccupancyGrid
from are_stats.environment import DEFAULT_MODELS
from are_stats.inputs import InputError, LimitError, limits
from tests.helpers import assert_allclose

# image rows top to bottom (image row 0 is the top of the map)
PIX = np.array([[0, 254, 205], [100, 50, 255]], dtype=np.uint8)


def _write(tmp_path, pixels, pil_mode="L", name="m", **meta):
    img = tmp_path / f"{name}.png" if pil_mode != "L" else tmp_path / f"{name}.pgm"
    Image.fromarray(pixels, mode=pil_mode).save(img, format="PNG" if pil_mode != "L" else "PPM")
    doc = {
        "image": img.name,
        "resolution": 0.5,
        "origin": [1.0, 2.0, 0.0],
        "negate": 0,
        "occupied_thresh": 0.65,
        "free_thresh": 0.196,
    }
    doc.update(meta)
    y = tmp_path / f"{name}.yaml"
    y.write_text(yaml.safe_dump(doc))
    return y


def test_trinary_known_cells(tmp_path):
    g = OccupancyGrid.from_ros_yaml(_write(tmp_path, PIX))
    # occ = (255 - p) / 255: 0->1.0 occ, 254->0.004 free, 205->0.196078 unknown,
    # 100->0.608 unknown, 50->0.804 occ, 255->0 free; the bottom image row is row 0
    assert g.data.tolist() == [[-1, 100, 0], [100, 0, -1]]
    assert g.shape == (2, 3)
    assert g.free_area == pytest.approx(2 * 0.25)


def test_trinary_negate(tmp_path):
    g = OccupancyGrid.from_ros_yaml(_write(tmp_path, PIX, negate=1))
    # occ = p / 255: 0 free, 254 occ, 205 (0.804) occ, 100 (0.392) unknown,
    # 50 (0.19608 > 0.196) unknown, 255 occ
    assert g.data.tolist() == [[-1, -1, 100], [0, 100, 100]]


def test_scale_mode_with_alpha(tmp_path):
    la = np.stack([PIX, np.array([[255, 255, 255], [255, 0, 255]], np.uint8)], -1)
    g = OccupancyGrid.from_ros_yaml(_write(tmp_path, la, pil_mode="LA", mode="scale"))
    # 100: ratio (0.60784 - 0.196) / 0.454 = 0.90714 -> rint(100 * r) = 91
    # 205: occ 0.196078 -> ratio 1.7e-4 -> 0 ; 50 with alpha 0 -> not opaque -> -1
    assert g.data.tolist() == [[91, -1, 0], [100, 0, 0]]
    la2 = la.copy()
    la2[0, 0] = [100, 254]  # any pixel that is not fully opaque is unknown (Nav2)
    g2 = OccupancyGrid.from_ros_yaml(_write(tmp_path, la2, pil_mode="LA", name="b", mode="scale"))
    assert g2.data[1, 0] == -1


def test_raw_mode(tmp_path):
    # Nav2: round(255 * shade) kept in 0..100, anything above is unknown; negate ignored
    for negate in (0, 1):
        g = OccupancyGrid.from_ros_yaml(_write(tmp_path, PIX, mode="raw", negate=negate))
        assert g.data.tolist() == [[100, 50, -1], [0, -1, -1]]


def test_rgb_mean_of_channels(tmp_path):
    rgb = np.zeros((1, 2, 3), np.uint8)
    rgb[0, 0] = [254, 254, 254]
    rgb[0, 1] = [255, 0, 0]  # mean 85 -> occ 0.667 > 0.65
    g = OccupancyGrid.from_ros_yaml(_write(tmp_path, rgb, pil_mode="RGB"))
    assert g.data.tolist() == [[0, 100]]


@pytest.mark.parametrize("mode", ["trinary", "scale", "raw"])
def test_round_trip_all_modes(tmp_path, mode):
    la = np.stack([PIX, np.array([[255, 255, 255], [255, 0, 255]], np.uint8)], -1)
    src = (
        _write(tmp_path, la, pil_mode="LA", name="src", mode=mode)
        if mode == "scale"
        else _write(tmp_path, PIX, name="src", mode=mode)
    )
    g = OccupancyGrid.from_ros_yaml(src)
    g.origin = (1.0, -2.0, 0.7)
    out = g.to_ros_yaml(tmp_path / "out.yaml")
    back = OccupancyGrid.from_ros_yaml(out)
    assert back.data.tolist() == g.data.tolist()
    assert back.mode == mode
    assert back.origin == pytest.approx(g.origin)
    assert back.resolution == g.resolution


def test_map_saver_pixels(tmp_path):
    g = OccupancyGrid(np.array([[0, 100, -1]]), 0.05)
    g.to_ros_yaml(tmp_path / "s.yaml")
    pix = np.asarray(Image.open(tmp_path / "s.pgm"))
    assert pix.tolist() == [[254, 0, 205]]
    meta = yaml.safe_load((tmp_path / "s.yaml").read_text())
    assert meta["negate"] == 0 and meta["image"] == "s.pgm"


def test_round_trip_random_grid(tmp_path, rng):
    data = rng.choice([-1, 0, 100], size=(37, 53))
    g = OccupancyGrid(data, 0.1, (3.0, -1.0, -0.4))
    back = OccupancyGrid.from_ros_yaml(g.to_ros_yaml(tmp_path / "r.yaml"))
    assert (back.data == g.data).all()


def test_write_refuses_to_clobber(tmp_path):
    g = OccupancyGrid(np.zeros((2, 2)), 0.1)
    g.to_ros_yaml(tmp_path / "a.yaml")
    with pytest.raises(FileExistsError, match="already exists"):
        g.to_ros_yaml(tmp_path / "a.yaml")
    g.to_ros_yaml(tmp_path / "a.yaml", force=True)


def test_world_cell_transforms_with_yaw():
    g = OccupancyGrid(np.zeros((4, 4)), 0.5, (1.0, 2.0, np.pi / 2))
    # local axes: u along world +y, v along world -x
    # world (0.25, 2.25) -> dx=-0.75, dy=0.25 -> u=0.25/0.5=0.5, v=0.75/0.5=1.5 -> row 1, col 0
    assert g.world_to_cell([0.25, 2.25]).tolist() == [1, 0]
    assert_allclose(g.cell_to_world([1, 0]), [1.0 - 0.75, 2.0 + 0.25], atol=1e-12)
    pts = np.random.default_rng(0).uniform(-1, 1, (50, 2)) + [0.0, 3.0]
    assert_allclose(g.local_to_world(g.world_to_local(pts)), pts, atol=1e-12)
    ij = g.world_to_cell(pts)
    back = g.cell_to_world(ij)
    assert (np.abs(g.world_to_local(back) - g.world_to_local(pts)) <= 0.5 + 1e-12).all()


def test_world_to_cell_no_yaw():
    g = OccupancyGrid(np.zeros((4, 5)), 0.5, (-1.0, -1.0, 0.0))
    assert g.world_to_cell([[-0.9, -0.9], [1.4, 0.6]]).tolist() == [[0, 0], [3, 4]]
    assert g.in_bounds([[3, 4], [4, 0], [-1, 2]]).tolist() == [True, False, False]


def test_masks_and_free_area():
    g = OccupancyGrid(np.array([[0, 0, 100], [-1, 50, 0]]), 0.2)
    assert g.free.sum() == 3 and g.occupied.sum() == 1 and g.unknown.sum() == 2
    assert g.free_area == pytest.approx(3 * 0.04)


def test_a_grid_read_from_a_file_knows_it():
    """Errors about a map (not the fit's, turned) name its file: the grid carries it."""
    path = DEFAULT_MODELS / "courtyard.yaml"
    grid = OccupancyGrid.from_ros_yaml(path)
    assert grid.source == str(path) and grid.copy().source == str(path)
    assert OccupancyGrid(np.zeros((2, 3)), 0.5).source is None
    assert OccupancyGrid(np.zeros((2, 3)), 0.5, source=path).source == str(path)


def test_inflation_against_brute_force(rng):
    data = np.where(rng.random((30, 40)) < 0.05, 100, 0)
    g = OccupancyGrid(data, 0.1)
    occ = np.argwhere(g.occupied)
    cells = np.argwhere(np.ones(g.shape, bool))
    d = np.sqrt(((cells[:, None, :] - occ[None, :, :]) ** 2).sum(-1)).min(1) * 0.1
    assert_allclose(g.distance_to_occupied().ravel(), d, atol=1e-12)
    assert (g.inflate(0.25).ravel() == (d <= 0.25)).all()
    cost = g.inflation_costmap(0.15, 0.5, 3.0).ravel()
    expect = np.where(d <= 0.15, 253, np.where(d <= 0.5, (252 * np.exp(-3 * (d - 0.15))), 0))
    expect = np.where(d == 0, 254, expect).astype(np.uint8)
    assert (cost == expect).all()


def test_malformed_maps(tmp_path):
    y = _write(tmp_path, PIX)
    (tmp_path / "m.pgm").unlink()
    with pytest.raises(InputError, match=r"m\.yaml: image: expected an existing image file"):
        OccupancyGrid.from_ros_yaml(y)
    with pytest.raises(FileNotFoundError, match="no such file"):
        OccupancyGrid.from_ros_yaml(tmp_path / "nothing.yaml")
    with pytest.raises(ValueError, match="free_thresh < occupied_thresh"):
        OccupancyGrid.from_ros_yaml(_write(tmp_path, PIX, name="t", free_thresh=0.7))
    with pytest.raises(InputError, match="r.yaml: resolution: expected a finite number >= 1e-06"):
        OccupancyGrid.from_ros_yaml(_write(tmp_path, PIX, name="r", resolution=-1))
    with pytest.raises(InputError, match="o.yaml: origin: expected a list of 3 values"):
        OccupancyGrid.from_ros_yaml(_write(tmp_path, PIX, name="o", origin=[1, 2]))
    with pytest.raises(InputError, match="d.yaml: mode: expected one of 'trinary'"):
        OccupancyGrid.from_ros_yaml(_write(tmp_path, PIX, name="d", mode="bogus"))
    with pytest.raises(InputError, match=r"w.yaml: width: expected the image's width \(3 pixels"):
        OccupancyGrid.from_ros_yaml(_write(tmp_path, PIX, name="w", width=7))
    bad = tmp_path / "g.yaml"
    bad.write_text(yaml.safe_dump({"image": "junk.pgm", "resolution": 0.1, "origin": [0, 0, 0]}))
    (tmp_path / "junk.pgm").write_bytes(b"not an image at all")
    with pytest.raises(InputError, match="g.yaml: image: expected a PGM or PNG image"):
        OccupancyGrid.from_ros_yaml(bad)
    miss = tmp_path / "f.yaml"
    miss.write_text(yaml.safe_dump({"resolution": 0.1, "origin": [0, 0, 0]}))
    with pytest.raises(InputError, match="f.yaml: image: expected this key to be present"):
        OccupancyGrid.from_ros_yaml(miss)
    with pytest.raises(ValueError, match="data"):
        OccupancyGrid(np.array([[0, 101]]), 0.1)
    with pytest.raises(ValueError, match="resolution"):
        OccupancyGrid(np.zeros((2, 2)), 0.0)
    with pytest.raises(ValueError, match="resolution"):
        OccupancyGrid(np.zeros((2, 2)), 1e200)
    with pytest.raises(ValueError, match="origin"):
        OccupancyGrid(np.zeros((2, 2)), 0.1, (True, 0.0, 0.0))


_OK_META = "image: m.pgm\nresolution: 0.1\norigin: [0.0, 0.0, 0.0]\n"
_BOMB = (
    "image: m.pgm\nresolution: 0.1\norigin: [0.0, 0.0, 0.0]\n"
    "x: &a [a, a, a, a, a, a, a, a, a, a]\n"
    + "".join(f"x{k}: &{chr(98 + k)} [{', '.join([f'*{chr(97 + k)}'] * 10)}]\n" for k in range(6))
)


@pytest.mark.parametrize(
    ("meta", "image", "match"),
    [
        # a 100000 x 100000 PGM header: refused from its header, before any pixel is read
        (
            _OK_META,
            b"P5\n100000 100000\n255\n" + bytes(64),
            r"m\.yaml: expected the 100000 x "
            r"100000 map image m\.pgm to fit in the memory limit",
        ),
        (_OK_META.replace("0.1", "1e200"), None, r"resolution: expected a finite number .*1e\+200"),
        (_OK_META.replace("0.1", "true"), None, r"resolution: expected .*True \(a bool\)"),
        (_OK_META.replace("0.1", "'0.1'"), None, r"resolution: expected .*'0\.1' \(a string\)"),
        (_OK_META.replace("[0.0, 0.0", "[true, 0.0"), None, r"origin\[0\]: expected .*True"),
        (_OK_META.replace("0.0]", "1e9]"), None, r"origin\[2\] \(yaw\): expected"),
        (_OK_META.replace("[0.0, 0.0", "[1e308, 0.0"), None, r"origin\[0\]: expected"),
        (_OK_META + "resolutoin: 2\n", None, r"resolutoin: expected one of the known keys image,"),
        (_OK_META + "negate: 2\n", None, r"negate: expected 0 or 1, got 2"),
        (_OK_META + "negate: 1.0\n", None, r"negate: expected 0 or 1, got 1\.0"),
        (_OK_META + "width: true\n", None, r"width: expected an integer >= 1, got True"),
        (_OK_META + "occupied_thresh: .nan\n", None, r"occupied_thresh: expected a finite"),
        (_OK_META + "resolution: 0.2\n", None, r"line 4: expected each key once"),
        (_BOMB, None, r"expected YAML that expands to at most"),
        ("- 1\n- 2\n", None, r"expected a mapping of image, resolution"),
        ("", None, r"expected a mapping of image, resolution"),
        ("image: [\n", None, r"expected a ROS map YAML in valid YAML"),
        (_OK_META.replace("m.pgm", "[1]"), None, r"image: expected a string, got a list"),
        (_OK_META.replace("m.pgm", "."), None, r"image: expected an image file, got .*not a file"),
        (_OK_META, b"garbage", r"image: expected a PGM or PNG image"),
        (_OK_META, b"P5\n20 20\n255\n" + bytes(10), r"image: expected a decodable PGM"),
        (_OK_META, b"P5\n2 2\n65535\n" + bytes(8), r"image: expected an 8-bit greyscale"),
    ],
)
def test_bad_map_inputs_name_file_and_key(tmp_path, meta, image, match):
    (tmp_path / "m.pgm").write_bytes(image or b"P5\n2 2\n255\n" + bytes(4))
    y = tmp_path / "m.yaml"
    y.write_text(meta)
    with pytest.raises(InputError, match=match):
        OccupancyGrid.from_ros_yaml(y)


def test_map_yaml_that_is_a_directory_or_not_utf8(tmp_path):
    with pytest.raises(InputError, match="expected a ROS map YAML, got a directory"):
        OccupancyGrid.from_ros_yaml(tmp_path)
    y = tmp_path / "m.yaml"
    y.write_bytes(b"image: \xff\xfe\n")
    with pytest.raises(InputError, match="m.yaml: byte 7: expected a ROS map YAML in UTF-8"):
        OccupancyGrid.from_ros_yaml(y)


def test_map_memory_limit_can_be_raised(tmp_path):
    y = _write(tmp_path, np.zeros((40, 50), np.uint8))
    with limits(memory="10K"), pytest.raises(LimitError, match="40 map image"):
        OccupancyGrid.from_ros_yaml(y)
    with limits(memory="1M"):
        assert OccupancyGrid.from_ros_yaml(y).shape == (40, 50)


# ---------------------------------------------------------------- Nav2 map_server, bit for bit
# The reference below transcribes nav2_map_server/src/map_io.cpp (loadMapFromFile) pixel by
# pixel, with GraphicsMagick Q16 quanta (8-bit v -> 257 v, MaxRGB 65535), doubles, and
# std::rint / std::round done exactly on the double's decimal value.
def _nav2_cell(rgb, alpha, matte, mode, negate, occ_th, free_th):
    from decimal import ROUND_HALF_EVEN, ROUND_HALF_UP, Decimal

    channels = [float(c * 257) for c in rgb]
    if mode == "trinary" and matte:
        channels.append(65535.0 - float((255 - alpha) * 257))  # MaxRGB - opacity
    total = 0.0
    for c in channels:
        total += c
    shade = (total / len(channels)) / 65535.0  # scaleQuantumToDouble(sum / size)
    occ = shade if negate else 1.0 - shade
    if mode == "trinary":
        return 100 if occ_th < occ else 0 if occ < free_th else -1
    if mode == "scale":
        if alpha != 255:  # pixel.alphaQuantum() != OpaqueOpacity
            return -1
        if occ_th < occ:
            return 100
        if occ < free_th:
            return 0
        x = (occ - free_th) / (occ_th - free_th) * 100.0
        return int(Decimal(x).quantize(Decimal(1), ROUND_HALF_EVEN))  # std::rint
    pct = int(Decimal(shade * 255).quantize(Decimal(1), ROUND_HALF_UP))  # std::round
    return pct if 0 <= pct <= 100 else -1


# (occupied_thresh, free_thresh): the shipped maps and Nav2's example maps, map_saver's
# defaults, and Nav2's filter masks (speed / keepout)
_THRESHOLDS = [(0.65, 0.196), (0.65, 0.25), (1.0, 0.0)]


def test_shipped_map_thresholds_are_covered():
    for y in sorted(DEFAULT_MODELS.glob("*.yaml")):
        meta = yaml.safe_load(y.read_text())
        assert (meta["occupied_thresh"], meta["free_thresh"]) in _THRESHOLDS, y.name


@pytest.mark.parametrize("mode", ["trinary", "scale", "raw"])
@pytest.mark.parametrize("negate", [0, 1])
@pytest.mark.parametrize(("occ_th", "free_th"), _THRESHOLDS)
def test_all_grey_levels_read_as_nav2(tmp_path, mode, negate, occ_th, free_th):
    grey = np.arange(256, dtype=np.uint8).reshape(16, 16)
    y = _write(
        tmp_path, grey, mode=mode, negate=negate, occupied_thresh=occ_th, free_thresh=free_th
    )
    g = OccupancyGrid.from_ros_yaml(y)
    expect = [
        [_nav2_cell((v, v, v), 255, False, mode, negate, occ_th, free_th) for v in row]
        for row in grey.tolist()[::-1]
    ]
    assert g.data.tolist() == expect
    # the same levels with an alpha channel (opaque, then half transparent)
    for a in (255, 128):
        la = np.stack([grey, np.full_like(grey, a)], -1)
        name = f"la{a}"
        y = _write(
            tmp_path,
            la,
            pil_mode="LA",
            name=name,
            mode=mode,
            negate=negate,
            occupied_thresh=occ_th,
            free_thresh=free_th,
        )
        expect = [
            [_nav2_cell((v, v, v), a, True, mode, negate, occ_th, free_th) for v in row]
            for row in grey.tolist()[::-1]
        ]
        assert OccupancyGrid.from_ros_yaml(y).data.tolist() == expect


@pytest.mark.parametrize("mode", ["trinary", "scale", "raw"])
@pytest.mark.parametrize("negate", [0, 1])
def test_colour_pixels_read_as_nav2(tmp_path, rng, mode, negate):
    # colour means that are not whole quanta (sum / 3 rounds) and random alpha
    rgba = rng.integers(0, 256, size=(24, 24, 4), dtype=np.uint8)
    rgba[..., 3] = np.where(rng.random((24, 24)) < 0.7, 255, rgba[..., 3])
    for pil_mode, img in (("RGB", rgba[..., :3]), ("RGBA", rgba)):
        y = _write(
            tmp_path,
            np.ascontiguousarray(img),
            pil_mode=pil_mode,
            name=pil_mode,
            mode=mode,
            negate=negate,
        )
        matte = pil_mode == "RGBA"
        expect = [
            [
                _nav2_cell(px[:3], px[3] if matte else 255, matte, mode, negate, 0.65, 0.196)
                for px in row
            ]
            for row in rgba.tolist()[::-1]
        ]
        assert OccupancyGrid.from_ros_yaml(y).data.tolist() == expect


def test_speed_mask_reads_0_20_25_50_100(tmp_path):
    # issue 17: a Nav2 speed mask in scale mode; the old 99 * ratio truncation read 0/19/24/49/99
    pix = np.array([[255, 204, 191, 127, 0]], np.uint8)
    y = _write(tmp_path, pix, mode="scale", occupied_thresh=1.0, free_thresh=0.0)
    assert OccupancyGrid.from_ros_yaml(y).data.tolist() == [[0, 20, 25, 50, 100]]
    y = _write(
        tmp_path, 255 - pix, name="n", mode="scale", negate=1, occupied_thresh=1.0, free_thresh=0.0
    )
    assert OccupancyGrid.from_ros_yaml(y).data.tolist() == [[0, 20, 25, 50, 100]]


def test_trinary_alpha_is_averaged_with_three_colour_channels(tmp_path):
    # Nav2 averages R, G, B and alpha: grey 0 with alpha 0 -> shade 0 -> occupied; grey 255
    # with alpha 0 -> shade 0.75 -> occ 0.25 -> unknown (map_server 1 averaged 2 channels)
    la = np.array([[[0, 0], [255, 0], [255, 255], [200, 100]]], np.uint8)
    g = OccupancyGrid.from_ros_yaml(_write(tmp_path, la, pil_mode="LA"))
    # 200/100: (600 + 100) / 1020 = 0.686 -> occ 0.314 -> unknown
    assert g.data.tolist() == [[100, -1, 0, -1]]


def test_transparency_chunk_counts_as_alpha(tmp_path):
    img = tmp_path / "t.png"
    Image.fromarray(np.array([[254, 100, 0]], np.uint8), mode="L").save(img, transparency=100)
    y = tmp_path / "t.yaml"
    doc = {"image": "t.png", "resolution": 0.1, "origin": [0, 0, 0], "mode": "scale"}
    y.write_text(yaml.safe_dump(doc))
    assert OccupancyGrid.from_ros_yaml(y).data.tolist() == [[0, -1, 100]]


def test_values_outside_nav_msgs_range_are_refused():
    with pytest.raises(ValueError, match="data: expected integers in -1..100"):
        OccupancyGrid(np.array([[0, 150]]), 0.1, mode="raw")


@pytest.mark.parametrize("mode", ["trinary", "scale", "raw"])
def test_round_trip_every_value_nav2_can_read(tmp_path, mode):
    table = {"trinary": [-1, 0, 100], "scale": [-1, *range(0, 101)], "raw": [-1, *range(101)]}
    vals = np.array(table[mode])
    th = (1.0, 0.0) if mode == "scale" else (0.65, 0.196)
    g = OccupancyGrid(vals[None, :], 0.1, mode=mode, occupied_thresh=th[0], free_thresh=th[1])
    back = OccupancyGrid.from_ros_yaml(g.to_ros_yaml(tmp_path / "v.yaml"))
    if mode == "scale":  # 8-bit greys hold only some of 1..99: each comes back within 1
        assert back.data[0, 0] == -1
        assert np.abs(back.data[0, 1:].astype(int) - vals[1:]).max() <= 1
        assert back.data[0, 1] == 0 and back.data[0, -1] == 100
    else:
        assert back.data.tolist() == g.data.tolist()


def test_values_no_pixel_can_hold_are_refused_on_writing(tmp_path):
    # trinary with occupied_thresh 1: occ > 1 never happens, so no pixel reads as 100
    g = OccupancyGrid(np.array([[0, 100]]), 0.1, occupied_thresh=1.0, free_thresh=0.196)
    with pytest.raises(ValueError, match="no 8-bit pixel reads back as 100 in mode 'trinary'"):
        g.to_ros_yaml(tmp_path / "x.yaml")
    with pytest.raises(ValueError, match="no 8-bit pixel reads back as 50"):
        OccupancyGrid(np.array([[50]]), 0.1).to_ros_yaml(tmp_path / "y.yaml")


def test_one_coarsener_keeps_a_straddling_door_open_on_every_grid():
    """A 1 m door whose edges fall mid-cell of a 1 m coarse grid: each coarse cell it touches
    is exactly half free. The behaviour grid (coarse_free with a source) and the
    entry-density grid (coarse_free) agree, and keep the door open."""
    from are_stats.environment import coarse_free

    data = np.zeros((40, 40))  # 0.1 m free cells
    data[20:30, :] = 100  # a wall band of coarse row 2 ...
    data[20:30, 15:25] = 0  # ... with a 1 m door from x = 1.5 to 2.5 m
    grid = OccupancyGrid(data, 0.1)
    behaviour, res = coarse_free(grid.free, grid.resolution, 1.0, source="--behaviour-cell")
    free, res2 = coarse_free(grid.free, 0.1, 1.0)
    assert res == res2 == pytest.approx(1.0)
    np.testing.assert_array_equal(behaviour, free)
    assert free[2].tolist() == [False, True, True, False]  # both half-free cells stay open
    assert free[[0, 1, 3]].all()


@pytest.mark.parametrize(
    ("cell", "match"),
    [
        (0.0, "--behaviour-cell: expected"),
        (float("nan"), "--behaviour-cell: expected"),
        ("1", "--behaviour-cell: expected"),
        (2.5, "--behaviour-cell: expected a cell much smaller than the map, got 2.5"),
    ],
)
def test_coarse_free_with_a_source_names_a_bad_cell(cell, match):
    from are_stats.environment import coarse_free

    free = np.ones((40, 40), bool)  # 4 m x 4 m at 0.1 m: a 2.5 m cell leaves 1 x 1
    with pytest.raises(ValueError, match=match):
        coarse_free(free, 0.1, cell, source="--behaviour-cell")
    if isinstance(cell, float) and cell > 1.0:  # without a source: the map's own cells
        kept, res = coarse_free(free, 0.1, cell)
        assert kept.shape == (40, 40) and res == 0.1


def test_coarse_free_is_a_majority_vote_on_whole_cells(rng):
    from are_stats.environment import coarse_free

    fine = rng.random((37, 23)) < 0.6
    free, res = coarse_free(fine, 0.1, 0.3)
    want = fine[:36, :21].reshape(12, 3, 7, 3).mean(axis=(1, 3)) >= 0.5
    np.testing.assert_array_equal(free, want)
    assert res == pytest.approx(0.3)
    tiny, res1 = coarse_free(fine[:3, :3], 0.1, 0.3)  # under 2 x 2 coarse cells: kept as is
    np.testing.assert_array_equal(tiny, fine[:3, :3])
    assert res1 == pytest.approx(0.1)


@pytest.mark.parametrize(
    ("shape", "res", "cell", "want"),
    [
        ((40, 40), 0.1, 1.0, 1.0),  # 10 map cells a side
        ((40, 40), 0.1, 0.34, 0.3),  # 3.4 map cells: 3
        ((40, 40), 0.1, 0.04, 0.1),  # under one map cell: one
        ((40, 40), 0.1, 2.5, 0.1),  # 25 cells leave 1 x 1 coarse cells: the map's own
        ((40, 41), 0.05, 1.0, 1.0),  # 20 cells: 2 x 2 coarse cells
    ],
)
def test_coarse_cell_is_the_side_coarse_free_makes(shape, res, cell, want):
    from are_stats.environment import coarse_cell, coarse_free

    assert coarse_cell(shape, res, cell) == pytest.approx(want)
    assert coarse_free(np.ones(shape, bool), res, cell)[1] == pytest.approx(want)


def test_coarse_cell_with_a_source_names_a_bad_cell():
    from are_stats.environment import coarse_cell

    assert coarse_cell((40, 40), 0.1, 1.0, source="--behaviour-cell") == pytest.approx(1.0)
    with pytest.raises(ValueError, match="--behaviour-cell: expected a cell much smaller"):
        coarse_cell((40, 40), 0.1, 2.5, source="--behaviour-cell")
    with pytest.raises(ValueError, match="--behaviour-cell: expected"):
        coarse_cell((40, 40), 0.1, 0.0, source="--behaviour-cell")
