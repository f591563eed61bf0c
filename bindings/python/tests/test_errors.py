"""Bad input raises ValueError / TypeError naming the index, field or shape."""

import errno
import random
import re
import struct
import zlib

import numpy as np
import pytest

import quadtex
from conftest import write_png

UNIT = [[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]]


@pytest.fixture(scope="module")
def tex():
    return quadtex.pack(np.linspace(0, 1, 16, dtype=np.float32).reshape(4, 4))


def test_non_finite_corner_names_the_index_and_field(tex):
    quads = np.tile(np.array(UNIT), (20, 1, 1))
    quads[17, 2, 1] = np.nan
    with pytest.raises(ValueError, match=r"^quads\[17\]: coordinate corner\[2\]\.z is not finite \(NaN\)$"):
        tex.filter(quads)
    quads[17, 2, 1] = 0.5
    quads[3, 0, 0] = -np.inf
    with pytest.raises(ValueError, match=r"quads\[3\]: coordinate corner\[0\]\.x is not finite \(-inf\)"):
        tex.filter(quads)


@pytest.mark.parametrize(
    "shape, text",
    [((3, 4), "(3, 4)"), ((5, 4, 3), "(5, 4, 3)"), ((8,), "(8,)"), ((2, 3, 2), "(2, 3, 2)"), ((), "()")],
)
def test_wrong_quad_shape(tex, shape, text):
    with pytest.raises(ValueError) as e:
        tex.filter(np.zeros(shape))
    assert str(e.value) == f"quads must have shape (N, 4, 2), got {text}"


def test_wrong_dtype(tex):
    with pytest.raises(TypeError, match="quads must hold real numbers, got dtype complex128"):
        tex.filter(np.zeros((1, 4, 2), dtype=complex))
    with pytest.raises(TypeError, match="quads must hold real numbers"):
        tex.filter("not an array")
    with pytest.raises(TypeError, match="rects must hold real numbers, got dtype bool"):
        tex.integrate(np.zeros((1, 4), dtype=bool))


def test_bad_options(tex):
    q = np.array([UNIT])
    with pytest.raises(ValueError, match=r'unknown wrap mode "wrapped" \(expected "repeat", "clamp", "mirror" or "border"\)'):
        tex.filter(q, wrap="wrapped")
    with pytest.raises(ValueError, match='unknown wrap mode "tile"'):
        tex.filter(q, wrap=("repeat", "tile"))
    with pytest.raises(ValueError, match="wrap must be a mode name or a pair"):
        tex.filter(q, wrap=("repeat", "clamp", "mirror"))
    with pytest.raises(ValueError, match='unknown weighting "pixel"'):
        tex.filter(q, weighting="pixel")
    # The strip quality went with the strips: the exact filter has none.
    with pytest.raises(TypeError, match="quality"):
        tex.filter(q, quality=4)
    for bound in (0.0, -1.0, float("nan")):
        with pytest.raises(ValueError, match="error bound must be a finite number > 0"):
            tex.filter(q, error_bound=bound)
    for level in (-1, 31, 1000):
        with pytest.raises(ValueError, match=rf"level must be in 0..=30, got {level}"):
            tex.filter(q, level=level)
        with pytest.raises(ValueError, match=rf"level must be in 0..=30, got {level}"):
            tex.integrate([[0, 0, 1, 1]], level=level)
    with pytest.raises(ValueError, match=r"border\[1\] is not finite"):
        tex.filter(q, wrap="border", border=(0, float("nan"), 0, 0))
    # Finite as a double, infinite as the float the texture keeps.
    with pytest.raises(ValueError, match=r"border\[0\] is beyond float32 range \(1e\+?39\)"):
        tex.filter(q, wrap="border", border=(1e39, 0, 0, 1))
    with pytest.raises(ValueError, match=r"border must have shape \(4,\), got \(3,\)"):
        tex.filter(q, border=(0, 0, 0))


def test_bad_rectangles(tex):
    rects = np.array([[0, 0, 1, 1], [0.5, 0, 0.25, 1], [0, 0, 1, 1]], dtype=float)
    with pytest.raises(ValueError, match=r"^rects\[1\]: reversed bounds on x: upper 0.25 < lower 0.5$"):
        tex.integrate(rects)
    rects[1] = [0, 0, 1, np.inf]
    with pytest.raises(ValueError, match=r"^rects\[1\]: coordinate z1 is not finite \(inf\)$"):
        tex.integrate(rects)
    with pytest.raises(ValueError, match=r"rects must have shape \(N, 4\), got \(4,\)"):
        tex.integrate([0, 0, 1, 1])


def test_bad_images():
    with pytest.raises(ValueError, match=r"image must have shape \(H, W\) or \(H, W, C\) with C in 1..4, got \(4, 4, 5\)"):
        quadtex.pack(np.zeros((4, 4, 5), np.uint8))
    with pytest.raises(ValueError, match=r"got \(4,\)"):
        quadtex.pack(np.zeros(4, np.uint8))
    with pytest.raises(ValueError, match="image must be 1 to 1048576 texels on a side, got 0x3"):
        quadtex.pack(np.zeros((3, 0, 3), np.uint8))
    with pytest.raises(TypeError, match="image dtype must be uint8 or uint16 .* got int64"):
        quadtex.pack(np.zeros((4, 4), np.int64))
    img = np.zeros((3, 4, 3), np.float32)
    img[1, 2, 0] = np.nan
    with pytest.raises(ValueError, match=r"image\[1, 2, 0\] is not finite \(NaN\)"):
        quadtex.pack(img)
    with pytest.raises(ValueError, match=r"image\[0, 3\] is not finite \(inf\)"):
        quadtex.pack(np.array([[0, 0, 0, np.inf]]))
    for t in (-0.1, 1.5, float("nan")):
        with pytest.raises(ValueError, match="tolerance must be in"):
            quadtex.pack(np.zeros((2, 2)), tolerance=t)
    with pytest.raises(ValueError, match="max_level must be in 0..=30, got 31"):
        quadtex.pack(np.zeros((2, 2)), max_level=31)
    with pytest.raises(ValueError, match="tree depth 16 exceeds the limit 15"):
        quadtex.pack(np.zeros((2, 2)), max_level=16)


def test_texture_cannot_be_constructed_directly():
    with pytest.raises(TypeError):
        quadtex.Texture()


# Files: the Python share of the bad-input catalogue (tests/bad_inputs.rs
# holds the command line's). The operating system's refusals are OSError
# subclasses with `filename` set; bad contents are ValueErrors naming the
# file and the field.

@pytest.fixture
def qtx_bytes(tmp_path, tex):
    path = tmp_path / "ok.qtx"
    tex.save(path)
    return path.read_bytes()


def _png_chunk(kind, data):
    body = kind + data
    return struct.pack(">I", len(data)) + body + struct.pack(">I", zlib.crc32(body))


def _png_header_only(w, h):
    return (
        b"\x89PNG\r\n\x1a\n"
        + _png_chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, 8, 6, 0, 0, 0))
        + _png_chunk(b"IDAT", b"")
        + _png_chunk(b"IEND", b"")
    )


def test_open_missing_file(tmp_path):
    path = tmp_path / "absent.qtx"
    with pytest.raises(FileNotFoundError) as e:
        quadtex.open(path)
    assert e.value.filename == str(path)


def test_open_a_directory(tmp_path):
    with pytest.raises(OSError) as e:
        quadtex.open(tmp_path)
    assert str(tmp_path) in str(e.value)


@pytest.mark.parametrize("cut", [0, 10, 63, 64, -20, -1])
def test_open_truncated_qtx(tmp_path, qtx_bytes, cut):
    path = tmp_path / "cut.qtx"
    path.write_bytes(qtx_bytes[:cut])
    with pytest.raises(ValueError, match=r"cut\.qtx: invalid \.qtx file: (header|length)"):
        quadtex.open(path)


def test_open_trailing_garbage(tmp_path, qtx_bytes):
    path = tmp_path / "long.qtx"
    path.write_bytes(qtx_bytes + b"extra")
    with pytest.raises(ValueError, match=r"long\.qtx: invalid \.qtx file: length"):
        quadtex.open(path)


def test_open_bit_flipped_payload(tmp_path, qtx_bytes):
    b = bytearray(qtx_bytes)
    b[-9] ^= 0x01
    path = tmp_path / "flip.qtx"
    path.write_bytes(bytes(b))
    with pytest.raises(ValueError, match=r"flip\.qtx: invalid \.qtx file: payload_crc"):
        quadtex.open(path)


def test_open_text_as_qtx(tmp_path):
    path = tmp_path / "notes.qtx"
    path.write_text("x0 z0 x1 z1\n0 0 1 1\n" * 5)
    with pytest.raises(ValueError, match=r"notes\.qtx: invalid \.qtx file: magic"):
        quadtex.open(path)


def test_pack_missing_file(tmp_path):
    path = tmp_path / "absent.png"
    with pytest.raises(FileNotFoundError) as e:
        quadtex.pack(path)
    assert e.value.filename == str(path)


@pytest.mark.parametrize(
    "name, data",
    [
        ("notes.png", b"these are not pixels"),
        ("empty.jpg", b""),
        ("noidat.png", _png_header_only(4, 4)),
        ("zero.png", _png_header_only(0, 0)),
        ("idat.png", b"\x89PNG\r\n\x1a\n"
         + _png_chunk(b"IHDR", struct.pack(">IIBBBBB", 4, 4, 8, 6, 0, 0, 0))
         + _png_chunk(b"IDAT", b"\x78\x9c not deflate")
         + _png_chunk(b"IEND", b"")),
    ],
)
def test_pack_corrupt_image_bytes(tmp_path, name, data):
    path = tmp_path / name
    path.write_bytes(data)
    with pytest.raises(ValueError, match=re.escape(str(path))):
        quadtex.pack(path)


def test_pack_truncated_png(tmp_path):
    path = tmp_path / "whole.png"
    write_png(path, np.arange(64 * 64 * 3, dtype=np.uint32).reshape(64, 64, 3).astype(np.uint8))
    data = path.read_bytes()
    for cut in (8, 33, len(data) // 4, len(data) // 2, len(data) * 3 // 4):
        cut_path = tmp_path / f"cut{cut}.png"
        cut_path.write_bytes(data[:cut])
        with pytest.raises(ValueError, match=re.escape(f"cut{cut}.png")):
            quadtex.pack(cut_path)


def test_pack_png_declaring_100000_squared(tmp_path):
    path = tmp_path / "huge.png"
    path.write_bytes(_png_header_only(100_000, 100_000))
    with pytest.raises(ValueError, match=r"huge\.png: max_dimension exceeded: 100000 > 32768"):
        quadtex.pack(path)


def test_pack_radiance_hdr_packs_unclamped(tmp_path):
    path = tmp_path / "sky.hdr"
    # RGBE (128, 64, 32, 131): 4.0, 2.0, 1.0 — above 1, kept.
    path.write_bytes(b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y 2 +X 2\n" + bytes([128, 64, 32, 131]) * 4)
    tex = quadtex.pack(path)
    np.testing.assert_allclose(tex.integrate([[0, 0, 1, 1]])[0], [4.0, 2.0, 1.0, 1.0], rtol=2e-2)


SVG_HEAD = '<svg xmlns="http://www.w3.org/2000/svg" xmlns:xlink="http://www.w3.org/1999/xlink" viewBox="0 0 10 10">'


@pytest.mark.parametrize(
    "body, message",
    [
        ('<pattern id="p" width="0.1" height="0.1" patternUnits="userSpaceOnUse"><rect width="0.05" height="0.05"/></pattern>'
         '<rect id="sky" width="10" height="10" fill="url(#p)"/>', 'unsupported: pattern repeated over more than 4096 tiles (id "sky")'),
        ('<image width="10" height="10" href="data:image/gif;base64,R0lGODlhAQABAIAAAP///wAAACH5BAEAAAAALAAAAAABAAEAAAICRAEAOw=="/>',
         "unsupported: image in GIF format"),
        ('<image width="10" height="10" href="runway.png"/>', 'image "runway.png" could not be read'),
        ('<filter id="f"><feGaussianBlur stdDeviation="2"/></filter>'
         '<rect width="10" height="10" filter="url(#f)"/>', "unsupported: filter"),
        ('<rect width="5" height="5"></svg', "invalid SVG"),
        ('<g id="a"><use xlink:href="#b"/></g><g id="b"><use xlink:href="#a"/></g>', "cycle"),
    ],
)
def test_pack_unsupported_or_broken_svg(tmp_path, body, message):
    path = tmp_path / "art.svg"
    path.write_text(SVG_HEAD + body + "</svg>")
    with pytest.raises(ValueError, match=re.escape(str(path)) + ".*" + re.escape(message)):
        quadtex.pack(path)


def test_pack_svg_use_bomb(tmp_path):
    s = SVG_HEAD + '<defs><rect id="l0" width="1" height="1"/>'
    for level in range(1, 11):
        s += f'<g id="l{level}">' + f'<use xlink:href="#l{level - 1}"/>' * 10 + "</g>"
    s += '</defs><use xlink:href="#l10"/></svg>'
    path = tmp_path / "bomb.svg"
    path.write_text(s)
    with pytest.raises(ValueError, match=r"bomb\.svg: max_svg_elements exceeded"):
        quadtex.pack(path)


def test_save_into_missing_folder(tmp_path, tex):
    path = tmp_path / "no" / "such" / "folder" / "t.qtx"
    with pytest.raises(FileNotFoundError):
        tex.save(path)
    assert not path.exists()


def test_filter_nan_in_every_field(tex):
    for corner in range(4):
        for axis, name in ((0, "x"), (1, "z")):
            quads = np.tile(np.array(UNIT), (3, 1, 1))
            quads[2, corner, axis] = np.nan
            with pytest.raises(ValueError, match=rf"^quads\[2\]: coordinate corner\[{corner}\]\.{name} is not finite \(NaN\)$"):
                tex.filter(quads)


def test_bad_wrap_types(tex):
    q = np.array([UNIT])
    for wrap in (3, ("repeat",)):
        with pytest.raises((ValueError, TypeError), match="wrap"):
            tex.filter(q, wrap=wrap)


def test_integrate_nan_rect(tex):
    with pytest.raises(ValueError, match=r"^rects\[0\]: coordinate x0 is not finite \(NaN\)$"):
        tex.integrate([[np.nan, 0, 1, 1]])


def test_mapped_open_reads_colours_lazily_and_verify_finds_them(tmp_path, tex, qtx_bytes):
    path = tmp_path / "lazy.qtx"
    path.write_bytes(qtx_bytes)
    mapped = quadtex.open(path, mapped=True)
    mapped.verify()
    rects = np.array([[0.1, 0.2, 0.6, 0.9], [0.0, 0.0, 1.0, 1.0]])
    np.testing.assert_array_equal(mapped.integrate(rects), tex.integrate(rects))
    # The last node's alpha zeroed: mapping refuses it by its payload
    # checksum; mapped unverified it opens (colours are not read) and
    # answers without crashing, but verify and a full open refuse it.
    nodes = struct.unpack_from("<Q", qtx_bytes, 32)[0]
    colours = 64 + (nodes + 7) // 8
    b = bytearray(qtx_bytes)
    b[colours + 8 * nodes - 2 : colours + 8 * nodes] = b"\0\0"
    path.write_bytes(bytes(b))
    with pytest.raises(ValueError, match=r"lazy\.qtx: invalid \.qtx file: payload_crc"):
        quadtex.open(path, mapped=True)
    lazy = quadtex.open(path, mapped=True, verify=False)
    assert np.isfinite(lazy.integrate(rects)).all()
    with pytest.raises(ValueError, match=r"lazy\.qtx: .*node"):
        lazy.verify()
    with pytest.raises(ValueError, match=r"lazy\.qtx: invalid \.qtx file: payload_crc"):
        quadtex.open(path)


def test_every_open_refuses_flipped_colour_bits(tmp_path, qtx_bytes):
    # 50 copies, one to three bits flipped at random in the colours.
    rng = random.Random(62)
    nodes = struct.unpack_from("<Q", qtx_bytes, 32)[0]
    colours = 64 + (nodes + 7) // 8
    for copy in range(50):
        b = bytearray(qtx_bytes)
        for bit in rng.sample(range(64 * nodes), 1 + copy % 3):
            b[colours + bit // 8] ^= 1 << (bit % 8)
        path = tmp_path / f"flip{copy}.qtx"
        path.write_bytes(bytes(b))
        for mapped in (False, True):
            with pytest.raises(ValueError, match=rf"flip{copy}\.qtx: .*payload_crc.*bytes"):
                quadtex.open(path, mapped=mapped)
    with pytest.raises(ValueError, match="mapped=True only"):
        quadtex.open(path, verify=False)


def test_mapped_open_refuses_corrupt_structure(tmp_path, qtx_bytes):
    b = bytearray(qtx_bytes)
    b[64] ^= 0x01
    path = tmp_path / "flags.qtx"
    path.write_bytes(bytes(b))
    with pytest.raises(ValueError, match=r"flags\.qtx: invalid \.qtx file: structure_crc"):
        quadtex.open(path, mapped=True)


def test_save_to_a_directory_is_isadirectoryerror_with_errno_and_filename(tmp_path, tex):
    with pytest.raises(IsADirectoryError) as e:
        tex.save(tmp_path)
    assert e.value.errno == errno.EISDIR
    assert e.value.filename == str(tmp_path)
    assert e.value.strerror


def test_open_missing_file_has_errno_and_filename(tmp_path):
    path = tmp_path / "absent.qtx"
    with pytest.raises(FileNotFoundError) as e:
        quadtex.open(path)
    assert (e.value.errno, e.value.filename) == (errno.ENOENT, str(path))
    with pytest.raises(FileNotFoundError) as e:
        quadtex.open(path, mapped=True)
    assert (e.value.errno, e.value.filename) == (errno.ENOENT, str(path))


def test_save_into_missing_folder_has_errno_and_filename(tmp_path, tex):
    path = tmp_path / "no" / "t.qtx"
    with pytest.raises(FileNotFoundError) as e:
        tex.save(path)
    assert e.value.errno == errno.ENOENT
    assert e.value.filename is not None and str(tmp_path / "no") in e.value.filename


def test_memory_limit_refuses_work_above_it(tmp_path):
    img = np.random.default_rng(3).integers(0, 256, (512, 512, 3), dtype=np.uint8)
    png = tmp_path / "big.png"
    write_png(png, img)
    for source in (img, png):
        with pytest.raises(ValueError, match=r"above the memory budget of 1\.0 KiB"):
            quadtex.pack(source, memory_limit=1024)
        # The same work under the detected budget packs.
        assert quadtex.pack(source).source_size == (512, 512)
    svg = tmp_path / "art.svg"
    svg.write_text(SVG_HEAD + '<rect width="5" height="7" fill="red"/></svg>')
    with pytest.raises(ValueError, match=r"art\.svg.*above the memory budget of 1\.0 KiB"):
        quadtex.pack(svg, max_level=9, memory_limit=1024)
    tiles = tmp_path / "tiles"
    tiles.mkdir()
    write_png(tiles / "0_0.png", img)
    with pytest.raises(ValueError, match=r"above the memory budget of 1\.0 KiB"):
        quadtex.pack_tiles(tiles, memory_limit=1024)
    assert quadtex.pack_tiles(tiles).source_size == (512, 512)
    for bad in (0, -5):
        with pytest.raises(ValueError, match=rf"memory_limit must be at least 1 byte, got {bad}"):
            quadtex.pack(img, memory_limit=bad)
