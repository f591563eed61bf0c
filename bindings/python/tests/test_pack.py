"""quadtex.pack (arrays and files), open, save."""

import os
import pathlib

import numpy as np
import pytest

import quadtex
from conftest import REPO, exact_integral, srgb_to_linear, write_png

WHOLE = np.array([[0.0, 0.0, 1.0, 1.0]])
QUARTERS = np.array([[0, 0, 0.5, 0.5], [0.5, 0, 1, 0.5], [0, 0.5, 0.5, 1], [0.5, 0.5, 1, 1]])


def test_float_array_integrates_analytically(random_texels, rng):
    tex = quadtex.pack(random_texels)
    assert (tex.depth, tex.source_size) == (4, (16, 16))
    # Texel-aligned rectangles and arbitrary ones: Σ texel × overlap.
    aligned = np.array([[3 / 16, 5 / 16, 11 / 16, 6 / 16], [0, 0, 1, 1], [0.25, 0.5, 0.75, 1]])
    rects = np.vstack([aligned, QUARTERS])
    got = tex.integrate(rects)
    # Exact but for inner nodes' colours, rounded to 16 bits (half a step per unit area).
    np.testing.assert_allclose(got[:, :3], exact_integral(random_texels, rects), atol=1e-5)
    # Row 0 is the top of the texture: the top-left texel is at x < 1/16, z ≥ 15/16.
    top_left = tex.integrate([[0, 15 / 16, 1 / 16, 1]])[0, :3] * 256
    np.testing.assert_allclose(top_left, random_texels[0, 0], atol=1e-7)


@pytest.mark.parametrize("shape", [(4, 64), (64, 4), (1, 300), (300, 1), (6, 40), (37, 23)])
def test_any_shape_packs_its_own_texels_and_integrates_exactly(rng, shape):
    texels = rng.random((*shape, 3))
    tex = quadtex.pack(texels)
    h, w = shape
    # Cells are the texels, whatever the sizes: no square around them, no resampling.
    assert tex.cells == (w, h)
    rects = np.vstack([WHOLE, QUARTERS, rng.random((20, 4)) * 1.2 - 0.1])
    rects[:, [0, 2]] = np.sort(rects[:, [0, 2]], axis=1)
    rects[:, [1, 3]] = np.sort(rects[:, [1, 3]], axis=1)
    got = tex.integrate(rects)
    # Every rectangle is Σ texel × overlap (inner colours rounded to 16 bits).
    np.testing.assert_allclose(got[:, :3], exact_integral(texels, rects), atol=1e-5)
    # A texel's own rectangle gives that texel.
    r, c = h // 2, w // 3
    one = tex.integrate([[c / w, 1 - (r + 1) / h, (c + 1) / w, 1 - r / h]])[0, :3] * (w * h)
    np.testing.assert_allclose(one, texels[r, c], atol=2e-5)


def test_hdr_float_arrays_keep_their_range_to_half_precision(rng):
    texels = rng.random((8, 16, 4)) * np.array([2000.0, -4.0, 1.0, 1.0]) - np.array([1000.0, 0, 0, 0])
    texels[..., 3] = 1.0
    ldr = quadtex.pack(texels)
    hdr = quadtex.pack(texels, hdr=True)
    rects = np.array([[c / 16, 1 - (r + 1) / 8, (c + 1) / 16, 1 - r / 8] for r in range(8) for c in range(16)])
    got = hdr.integrate(rects) * 128
    want = texels.reshape(-1, 4)
    # Half floats: 11 significant bits.
    np.testing.assert_allclose(got, want, rtol=1 / 1024, atol=1e-6)
    # Without hdr the same floats are clamped to [0, alpha].
    assert ldr.integrate(rects).max() <= 1 / 128 + 1e-9
    bad = texels.copy()
    bad[2, 3, 1] = np.nan
    with pytest.raises(ValueError):
        quadtex.pack(bad, hdr=True)


def test_float_arrays_are_linear_premultiplied():
    px = np.array([0.2, 0.1, 0.05, 0.5], dtype=np.float32)
    tex = quadtex.pack(np.broadcast_to(px, (4, 4, 4)))
    np.testing.assert_allclose(tex.integrate(WHOLE)[0], px, atol=1e-5)
    # Colour above alpha is clamped to alpha; alpha to [0, 1]; no alpha = opaque.
    tex = quadtex.pack(np.full((2, 2, 4), [0.9, 0.3, -1.0, 0.5], dtype=np.float64))
    np.testing.assert_allclose(tex.integrate(WHOLE)[0], [0.5, 0.3, 0.0, 0.5], atol=1e-5)
    tex = quadtex.pack(np.full((2, 2, 3), [2.0, 0.25, 0.5], dtype=np.float16))
    np.testing.assert_allclose(tex.integrate(WHOLE)[0], [1.0, 0.25, 0.5, 1.0], atol=1e-5)
    grey = quadtex.pack(np.full((3, 5), 0.25))
    np.testing.assert_allclose(grey.integrate(WHOLE)[0], [0.25, 0.25, 0.25, 1.0], atol=1e-5)


def test_uint8_arrays_are_srgb_with_straight_alpha():
    tex = quadtex.pack(np.full((4, 4, 3), 128, dtype=np.uint8))
    want = srgb_to_linear(128 / 255)
    np.testing.assert_allclose(tex.integrate(WHOLE)[0], [want, want, want, 1], atol=1e-5)
    # Straight alpha: white at half coverage is premultiplied to (a, a, a, a).
    tex = quadtex.pack(np.full((4, 4, 4), [255, 255, 255, 128], dtype=np.uint8))
    np.testing.assert_allclose(tex.integrate(WHOLE)[0], [128 / 255] * 4, atol=1e-5)
    tex = quadtex.pack(np.full((2, 2, 4), [64, 128, 255, 51], dtype=np.uint8))
    a = 51 / 255
    want = [*(srgb_to_linear(np.array([64, 128, 255]) / 255) * a), a]
    np.testing.assert_allclose(tex.integrate(WHOLE)[0], want, atol=1e-5)


@pytest.mark.parametrize("channels", [None, 1, 2, 3, 4])
@pytest.mark.parametrize("dtype", [np.uint8, np.uint16])
def test_arrays_pack_exactly_as_the_same_png(tmp_path, rng, channels, dtype):
    shape = (12, 20) if channels is None else (12, 20, channels)
    pixels = rng.integers(0, np.iinfo(dtype).max + 1, size=shape).astype(dtype)
    path = tmp_path / "image.png"
    write_png(path, pixels)
    from_file = quadtex.pack(path)
    from_array = quadtex.pack(pixels)
    assert from_file.source_size == from_array.source_size == (20, 12)
    assert (from_file.depth, from_file.node_count) == (from_array.depth, from_array.node_count)
    rects = np.vstack([WHOLE, QUARTERS, [[0.1, 0.2, 0.7, 0.9], [0.33, 0.01, 0.34, 0.99]]])
    np.testing.assert_array_equal(from_file.integrate(rects), from_array.integrate(rects))


def test_pack_options(random_texels):
    lossless = quadtex.pack(random_texels)
    lossy = quadtex.pack(random_texels, tolerance=0.5)
    # Noise packs losslessly into texel blocks (few nodes); a tolerance
    # merges squares instead: fewer bytes.
    assert lossy.nbytes < lossless.nbytes
    coarse = quadtex.pack(random_texels, max_level=2)
    assert coarse.depth <= 2
    # Cells resampled by area: the whole-texture integral is unchanged.
    np.testing.assert_allclose(
        coarse.integrate(WHOLE), lossless.integrate(WHOLE), atol=1e-4
    )


def test_save_open_round_trip(tmp_path, random_texels, rng):
    tex = quadtex.pack(random_texels)
    path = tmp_path / "t.qtx"
    tex.save(path)
    assert sorted(os.listdir(tmp_path)) == ["t.qtx"], "no temporary file left behind"
    back = quadtex.open(path)
    assert (back.depth, back.node_count, back.nbytes, back.source_size) == (
        tex.depth,
        tex.node_count,
        tex.nbytes,
        tex.source_size,
    )
    # Random parallelograms (random corners would often cross: refused).
    p0, u, v = rng.uniform(-1, 2, size=(3, 100, 2))
    quads = np.stack([p0, p0 + u, p0 + u + v, p0 + v], axis=1)
    np.testing.assert_array_equal(back.filter(quads), tex.filter(quads))
    # str paths work too, and saving over an existing file replaces it.
    quadtex.pack(np.zeros((2, 2))).save(str(path))
    assert quadtex.open(str(path)).node_count == 1
    assert repr(back).startswith("<quadtex.Texture depth=4 node_count=")
    assert "source=16x16" in repr(back)


def test_save_through_a_symlink_keeps_the_link(tmp_path, random_texels):
    tex = quadtex.pack(random_texels)
    (tmp_path / "real").mkdir()
    link = tmp_path / "link.qtx"
    link.symlink_to("real/t.qtx")  # dangling: save creates real/t.qtx
    tex.save(link)
    tex.save(link)  # existing: replaced through the link
    assert link.is_symlink()
    assert os.readlink(link) == "real/t.qtx"
    assert quadtex.open(tmp_path / "real" / "t.qtx").node_count == tex.node_count
    assert sorted(os.listdir(tmp_path / "real")) == ["t.qtx"]


def test_pack_svg_sample():
    svg = REPO / "samples" / "sign.svg"
    tex = quadtex.pack(svg, max_level=7)
    assert tex.depth <= 7 and tex.source_size == (128, 128)
    mean = tex.integrate(WHOLE)[0]
    assert 0 < mean[3] <= 1 and np.all(mean[:3] <= mean[3] + 1e-9)
    with pytest.raises(ValueError, match="tolerance applies to raster images"):
        quadtex.pack(svg, tolerance=0.1)


def test_pack_svg_with_contour_leaves():
    svg = REPO / "samples" / "threshold.svg"
    plain = quadtex.pack(svg)
    tex = quadtex.pack(svg, contour_leaves=16)
    assert tex.depth == 30 and tex.node_count * 20 < plain.node_count
    # Both trees hold the exact mean of the art over the whole texture.
    assert np.allclose(tex.integrate(WHOLE)[0], plain.integrate(WHOLE)[0], atol=1e-4)
    with pytest.raises(ValueError, match="contour_leaves must be in 3..=1024"):
        quadtex.pack(svg, contour_leaves=2)
    with pytest.raises(ValueError, match="applies to SVG art"):
        quadtex.pack(np.zeros((4, 4), dtype=np.uint8), contour_leaves=16)


def test_pack_svg_default_level_fits_the_memory_limit():
    """Without max_level, as `quadtex pack`: level 12 of the star needs an
    estimated 57.1 MiB, so under 20 MiB it packs at level 10; level 12 given
    is refused."""
    star = REPO / "samples" / "star.svg"
    tex = quadtex.pack(star, memory_limit=20 << 20)
    assert (tex.depth, tex.source_size) == (10, (1024, 1024))
    with pytest.raises(ValueError, match=r"packing at level 12 needs an estimated 57\.1 MiB"):
        quadtex.pack(star, max_level=12, memory_limit=20 << 20)


def test_pack_svg_sweep_budget():
    # Dashes piled on a point: 3.9e8 sweep steps at the default level.
    slow = REPO / "fuzz" / "slow" / "dashed-star-15s.svg"
    with pytest.raises(ValueError, match=r"above the limit of 1000000 \(max sweep work\)"):
        quadtex.pack(slow, max_sweep_work=1_000_000)
    svg = REPO / "samples" / "threshold.svg"
    assert quadtex.pack(svg, max_sweep_work=1 << 40).node_count == quadtex.pack(svg).node_count
    with pytest.raises(ValueError, match="max_sweep_work must be at least 1"):
        quadtex.pack(svg, max_sweep_work=0)
    with pytest.raises(ValueError, match="max_sweep_work applies to SVG art"):
        quadtex.pack(np.zeros((4, 4), dtype=np.uint8), max_sweep_work=10)


def test_pack_svg_resources(tmp_path):
    """An SVG's image outside its folder is refused unless widened."""
    sub = tmp_path / "sub"
    sub.mkdir()
    red = np.full((2, 2, 3), [200, 10, 10], dtype=np.uint8)
    write_png(tmp_path / "outside.png", red)
    write_png(sub / "beside.png", red)
    head = '<svg xmlns="http://www.w3.org/2000/svg" viewBox="0 0 10 10">'

    def svg(name, href):
        path = sub / name
        path.write_text(f'{head}<image width="10" height="10" href="{href}"/></svg>')
        return path

    for href in ["../outside.png", str(tmp_path / "outside.png")]:
        path = svg("a.svg", href)
        with pytest.raises(ValueError, match="external resource") as e:
            quadtex.pack(path, max_level=4)
        assert "a.svg" in str(e.value) and f'"{href}"' in str(e.value)
        wide = quadtex.pack(path, max_level=4, resources="anywhere")
        assert wide.integrate(WHOLE)[0, 3] > 0.99
    beside = svg("b.svg", "beside.png")
    assert quadtex.pack(beside, max_level=4).integrate(WHOLE)[0, 3] > 0.99
    with pytest.raises(ValueError, match='"beside.png" refused'):
        quadtex.pack(beside, max_level=4, resources="none")
    with pytest.raises(ValueError, match="resources must be one of same-folder, anywhere, none"):
        quadtex.pack(beside, resources="everywhere")
    with pytest.raises(ValueError, match="resources applies to SVG art"):
        quadtex.pack(np.zeros((4, 4), dtype=np.uint8), resources="none")


def test_file_errors(tmp_path):
    missing = tmp_path / "missing.qtx"
    with pytest.raises(FileNotFoundError) as e:
        quadtex.open(missing)
    assert e.value.filename == str(missing)
    with pytest.raises(FileNotFoundError):
        quadtex.pack(tmp_path / "missing.png")
    junk = tmp_path / "junk.qtx"
    junk.write_bytes(b"\x89QTX\r\n\x1a\n" + b"\x00" * 100)
    with pytest.raises(ValueError, match=r"junk\.qtx: invalid \.qtx file: "):
        quadtex.open(junk)
    bad_png = tmp_path / "bad.png"
    bad_png.write_bytes(b"not a png")
    with pytest.raises(ValueError, match=r"bad\.png"):
        quadtex.pack(bad_png)
    with pytest.raises(OSError):
        quadtex.pack(np.zeros((2, 2))).save(tmp_path / "no" / "such" / "dir.qtx")
    bad_svg = tmp_path / "bad.svg"
    bad_svg.write_text("<svg")
    with pytest.raises(ValueError, match=r"bad\.svg"):
        quadtex.pack(bad_svg)


def test_paths_accept_pathlike(tmp_path):
    class Custom:
        def __init__(self, p):
            self.p = p

        def __fspath__(self):
            return str(self.p)

    path = tmp_path / "p.qtx"
    tex = quadtex.pack(np.eye(2, dtype=np.uint8) * 255)
    tex.save(Custom(path))
    assert quadtex.open(Custom(path)).node_count == tex.node_count == 5
    assert isinstance(pathlib.Path(path), os.PathLike)


def test_pack_tiles_equals_packing_the_mosaic(tmp_path, rng):
    mosaic = rng.integers(0, 4, size=(32, 32, 3)).astype(np.uint8) * 80
    mosaic[:16, :16] = 200  # a uniform quadrant
    tiles = tmp_path / "tiles"
    tiles.mkdir()
    for row in range(4):
        for col in range(4):
            write_png(tiles / f"{row}_{col}.png", mosaic[row * 8:(row + 1) * 8, col * 8:(col + 1) * 8])
    (tiles / "notes.txt").write_text("not a tile")
    whole = tmp_path / "whole.png"
    write_png(whole, mosaic)
    a, b = quadtex.pack_tiles(tiles), quadtex.pack(whole)
    assert a.source_size == b.source_size == (32, 32)
    assert (a.depth, a.node_count) == (b.depth, b.node_count)
    rects = np.vstack([WHOLE, QUARTERS, [[0.1, 0.2, 0.7, 0.9]]])
    np.testing.assert_array_equal(a.integrate(rects), b.integrate(rects))
    os.remove(tiles / "2_3.png")
    with pytest.raises(ValueError, match="2_3.png"):
        quadtex.pack_tiles(tiles)
    with pytest.raises(ValueError, match="tolerance"):
        quadtex.pack_tiles(tiles, tolerance=2.0)


def test_tiles_packed_apart_splice_into_the_pack_tiles_file(tmp_path, rng):
    # Grey tiles first, then coloured and translucent ones: the mosaic's
    # block format widens, so some tiles are asked for again.
    mosaic = np.repeat(rng.integers(0, 256, size=(32, 32, 1)), 4, axis=2).astype(np.uint8)
    mosaic[..., 3] = 255
    mosaic[:16, 16:, 1] //= 2
    mosaic[16:, 16:, 3] = 200
    tiles = tmp_path / "tiles"
    tiles.mkdir()
    for row in range(4):
        for col in range(4):
            write_png(tiles / f"{row}_{col}.png", mosaic[row * 8:(row + 1) * 8, col * 8:(col + 1) * 8])
    assert quadtex.tile_grid(tiles) == (4, 8)
    packed = {(r, c): quadtex.pack_tile(tiles, r, c) for r in range(4) for c in range(4)}
    asked_again = []

    def load(row, col, block_format):
        if block_format is None:
            return packed[row, col]
        asked_again.append((row, col))
        return quadtex.pack_tile(tiles, row, col, block_format=block_format)

    spliced = quadtex.splice_tiles(tiles, load)
    assert asked_again, "no tile was asked for again in the wider format"
    spliced.save(tmp_path / "spliced.qtx")
    quadtex.pack_tiles(tiles).save(tmp_path / "serial.qtx")
    assert (tmp_path / "spliced.qtx").read_bytes() == (tmp_path / "serial.qtx").read_bytes()
    # Damaged bytes are refused by name; the callable's own error passes through.
    damaged = bytearray(packed[0, 0])
    damaged[30] ^= 1
    with pytest.raises(ValueError, match="checksum"):
        quadtex.splice_tiles(tiles, lambda r, c, f: bytes(damaged))

    def fails(row, col, block_format):
        raise KeyError("worker lost")

    with pytest.raises(KeyError, match="worker lost"):
        quadtex.splice_tiles(tiles, fails)
    with pytest.raises(ValueError, match="outside"):
        quadtex.pack_tile(tiles, 4, 0)
