"""Rendering from Python: `Scene.open` / `Scene.render` give the pixels of
`quadtex render` (its OpenEXR output, bit for bit), `to_srgb8` and
`save_image` the bytes of its PNG output; camera paths, footprints from
ray differentials, and bad arguments."""

import errno
import json
import os
import pathlib
import shutil
import struct
import subprocess
import threading
import time
import zlib

import numpy as np
import pytest

import quadtex
from conftest import REPO

SCENES = REPO / "scenes"
CHECKER = SCENES / "checker.toml"
MESH = SCENES / "mesh.toml"  # an OBJ model

# A short camera path over the checker plane (three keys, a curve).
PATH_TOML = """
[[key]]
time = 0
position = [0, 1.5, 0]
look_at = [0, 0, 40]
fov = 40

[[key]]
time = 2
position = [1, 3, 2]
look_at = [2, 0, 30]
fov = 30

[[key]]
time = 3
position = [-1, 0.5, 4]
look_at = [0, 0, 20]
up = [0.1, 1, 0]
"""


def quadtex_cli(cli, *args):
    run = subprocess.run([cli, *map(str, args)], capture_output=True, timeout=600)
    assert run.returncode == 0, run.stderr.decode()
    return run


@pytest.fixture(scope="module")
def checker():
    return quadtex.Scene.open(CHECKER)


@pytest.fixture(scope="module")
def camera_path(tmp_path_factory):
    path = tmp_path_factory.mktemp("path") / "wobble.path.toml"
    path.write_text(PATH_TOML)
    return path


# --- Minimal readers (standard library only) -------------------------------


def read_exr(path):
    """An OpenEXR file of float32 RGBA, scanlines or one level of tiles, as
    the `image` crate writes them (no, RLE or ZIP compression): (H, W, 4)
    float32."""
    data = pathlib.Path(path).read_bytes()
    assert data[:4] == b"\x76\x2f\x31\x01", "not OpenEXR"
    pos = 8
    header = {}
    while data[pos] != 0:
        end = data.index(b"\0", pos)
        name = data[pos:end].decode()
        end2 = data.index(b"\0", end + 1)
        kind = data[end + 1 : end2].decode()
        (size,) = struct.unpack_from("<i", data, end2 + 1)
        header[name] = (kind, data[end2 + 5 : end2 + 5 + size])
        pos = end2 + 5 + size
    pos += 1
    channels = []
    raw = header["channels"][1]
    i = 0
    while raw[i] != 0:
        end = raw.index(b"\0", i)
        (ptype,) = struct.unpack_from("<i", raw, end + 1)
        channels.append((raw[i:end].decode(), ptype))
        i = end + 1 + 16
    assert all(t == 2 for _, t in channels), channels  # FLOAT
    xmin, ymin, xmax, ymax = struct.unpack("<4i", header["dataWindow"][1])
    w, h = xmax - xmin + 1, ymax - ymin + 1
    compression = header["compression"][1][0]
    nc = len(channels)
    out = np.zeros((h, w, nc), dtype=np.float32)
    if "tiles" in header:
        tw, th, mode = struct.unpack("<IIB", header["tiles"][1])
        assert mode & 0xF == 0, "one level only"
        blocks = -(-w // tw) * -(-h // th)
    else:
        lines = {0: 1, 1: 1, 2: 1, 3: 16}[compression]
        blocks = -(-h // lines)
    offsets = struct.unpack_from(f"<{blocks}Q", data, pos)
    for off in offsets:
        if "tiles" in header:
            tx, ty, _, _, size = struct.unpack_from("<5i", data, off)
            chunk = data[off + 20 : off + 20 + size]
            x0, y0 = tx * tw, ty * th
            cols, rows = min(tw, w - x0), min(th, h - y0)
        else:
            y, size = struct.unpack_from("<ii", data, off)
            chunk = data[off + 8 : off + 8 + size]
            x0, y0, cols, rows = 0, y - ymin, w, min(lines, ymax + 1 - y)
        expected = rows * cols * nc * 4
        if len(chunk) < expected:
            chunk = _exr_decompress(chunk, compression, expected)
        a = np.frombuffer(chunk, dtype="<f4").reshape(rows, nc, cols)
        out[y0 : y0 + rows, x0 : x0 + cols] = a.transpose(0, 2, 1)
    names = [n for n, _ in channels]
    return out[:, :, [names.index(c) for c in "RGBA"]]


def _exr_decompress(chunk, compression, expected):
    if compression == 1:  # RLE
        raw = bytearray()
        i = 0
        while i < len(chunk):
            n = struct.unpack_from("b", chunk, i)[0]
            i += 1
            if n < 0:
                raw += chunk[i : i - n]
                i -= n
            else:
                raw += chunk[i : i + 1] * (n + 1)
                i += 1
    elif compression in (2, 3):  # ZIPS, ZIP
        raw = bytearray(zlib.decompress(chunk))
    else:
        raise AssertionError(f"EXR compression {compression}")
    # Undo the predictor, then the byte interleave.
    for i in range(1, len(raw)):
        raw[i] = (raw[i - 1] + raw[i] - 128) & 0xFF
    half = (len(raw) + 1) // 2
    out = bytearray(len(raw))
    out[0::2] = raw[:half]
    out[1::2] = raw[half:]
    assert len(out) == expected
    return bytes(out)


def read_png_rgba8(path):
    """An 8-bit RGBA, non-interlaced PNG: (H, W, 4) uint8."""
    data = pathlib.Path(path).read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n"
    pos, idat = 8, b""
    while pos < len(data):
        (n,) = struct.unpack_from(">I", data, pos)
        kind = data[pos + 4 : pos + 8]
        body = data[pos + 8 : pos + 8 + n]
        if kind == b"IHDR":
            w, h, depth, colour, _, _, interlace = struct.unpack(">IIBBBBB", body)
            assert (depth, colour, interlace) == (8, 6, 0)
        elif kind == b"IDAT":
            idat += body
        pos += 12 + n
    raw = zlib.decompress(idat)
    stride = 4 * w
    out = np.zeros((h, stride), dtype=np.int32)
    prev = np.zeros(stride, dtype=np.int32)
    for y in range(h):
        f = raw[y * (stride + 1)]
        line = np.frombuffer(raw, dtype=np.uint8, count=stride, offset=y * (stride + 1) + 1).astype(np.int32)
        cur = np.zeros(stride, dtype=np.int32)
        for x in range(stride):
            a = cur[x - 4] if x >= 4 else 0
            b = prev[x]
            c = prev[x - 4] if x >= 4 else 0
            if f == 0:
                p = 0
            elif f == 1:
                p = a
            elif f == 2:
                p = b
            elif f == 3:
                p = (a + b) // 2
            else:
                pa, pb, pc = abs(b - c), abs(a - c), abs(a + b - 2 * c)
                p = a if pa <= pb and pa <= pc else (b if pb <= pc else c)
            cur[x] = (line[x] + p) & 0xFF
        out[y] = cur
        prev = cur
    return out.reshape(h, w, 4).astype(np.uint8)


# --- The CLI's pixels, bit for bit ------------------------------------------


@pytest.mark.parametrize(
    "scene, args, kwargs",
    [
        (CHECKER, [], {}),
        (CHECKER, ["--pixel-filter", "tent", "--height", "20"], {"pixel_filter": "tent", "height": 20}),
        (MESH, ["--pixel-filter", "mitchell"], {"pixel_filter": "mitchell"}),
        (SCENES / "runway.toml", [], {}),
        (SCENES / "sign80.toml", [], {}),  # an SVG file packed on load
        (CHECKER, ["--filter", "ewa"], {"filter": "ewa"}),
        (CHECKER, ["--error-bound", "0.01", "--budget", "8"], {"error_bound": 0.01, "budget": 8}),
    ],
)
def test_render_is_the_cli_exr_bit_for_bit(cli, tmp_path, scene, args, kwargs):
    out = tmp_path / "cli.exr"
    quadtex_cli(cli, "render", scene, "--width", 48, *args, "-o", out)
    want = read_exr(out)
    got = quadtex.Scene.open(scene).render(width=48, **kwargs)
    assert got.dtype == np.float32 and got.flags.c_contiguous
    assert got.shape == want.shape
    assert np.array_equal(got.view(np.uint32), want.view(np.uint32))
    # save_image writes the very file the CLI wrote.
    mine = tmp_path / "py.exr"
    quadtex.save_image(mine, got)
    assert mine.read_bytes() == out.read_bytes()


def test_a_path_frame_is_the_cli_frame_bit_for_bit(cli, tmp_path, checker, camera_path):
    frames = 5
    quadtex_cli(
        cli, "render", CHECKER, "--width", 48, "--path", camera_path, "--frames", frames,
        "--format", "exr", "-o", tmp_path / "frames",
    )
    for k in (0, 3, 4):
        want = read_exr(tmp_path / "frames" / f"frame_{k:04}.exr")
        got = checker.render(width=48, path=camera_path, frame=k, frames=frames)
        assert np.array_equal(got.view(np.uint32), want.view(np.uint32)), k
    # Another frame is another picture.
    assert not np.array_equal(got, checker.render(width=48))


def test_png_bytes_are_the_cli_png(cli, tmp_path, checker):
    out = tmp_path / "cli.png"
    quadtex_cli(cli, "render", CHECKER, "--width", 48, "-o", out)
    image = checker.render(width=48)
    mine = tmp_path / "py.png"
    quadtex.save_image(mine, image)
    assert mine.read_bytes() == out.read_bytes()
    srgb = quadtex.to_srgb8(image)
    assert srgb.dtype == np.uint8 and srgb.shape == image.shape
    assert np.array_equal(srgb, read_png_rgba8(out))


# --- Scene and render --------------------------------------------------------


def test_default_size_is_the_camera_and_one_side_keeps_the_aspect(checker):
    assert (checker.width, checker.height) == (960, 540)
    assert checker.render(width=32).shape == (18, 32, 4)
    assert checker.render(height=9).shape == (9, 16, 4)
    assert checker.render(width=10, height=30).shape == (30, 10, 4)
    assert "checker.toml" in repr(checker) and "960x540" in repr(checker)


def test_render_is_linear_premultiplied(checker):
    image = checker.render(width=64)
    assert np.all(image[..., 3] == 1.0)  # sky and ground are opaque
    assert np.all(image[..., :3] >= 0) and np.all(image[..., :3] <= image[..., 3:])
    # The top row is sky, blue and symmetric about the view; the bottom row
    # the black and white checker, grey.
    top, bottom = image[0, :, :3], image[-1, :, :3]
    assert np.all(top[:, 2] > top[:, 0]) and np.allclose(top, top[::-1], atol=1e-6)
    assert np.allclose(bottom, bottom[:, :1], atol=1e-6)


def test_summary(checker):
    image, summary = checker.render(width=48, return_summary=True)
    assert image.shape == (27, 48, 4)
    assert summary["width"] == 48 and summary["height"] == 27
    assert summary["textured_pixels"] > 0 and summary["seconds"] > 0
    assert 0 <= summary["mean_error_bound"] <= summary["max_error_bound"]
    assert summary["text"].startswith("48x27 in ")
    assert set(summary) == {
        "width", "height", "seconds", "textured_pixels", "max_error_bound",
        "mean_error_bound", "over_target", "max_weight_error", "text",
    }


def test_every_filter_renders(checker):
    for name in ("quadtree", "nearest", "bilinear", "supersample:2", "trilinear", "ewa", "sat"):
        image = checker.render(width=24, filter=name)
        assert image.shape == (14, 24, 4) and np.isfinite(image).all(), name
    fixed = checker.render(width=24, level=4)
    assert not np.array_equal(fixed, checker.render(width=24))


def test_progress_goes_to_stderr_only_when_asked(checker, capfd):
    checker.render(width=40)
    assert capfd.readouterr().err == ""
    checker.render(width=40, progress=True)
    lines = capfd.readouterr().err.splitlines()
    assert len(lines) == 10, lines
    assert all(line.startswith("quadtex: rendered ") for line in lines)
    assert "quadtex: rendered 23/23 rows (100%)" in lines


def test_render_releases_the_gil(checker):
    state = {"inside": False, "done": False}

    def work():
        state["inside"] = True
        state["start"] = time.perf_counter()
        checker.render(width=480)
        state["end"] = time.perf_counter()
        state["done"] = True

    worker = threading.Thread(target=work)
    ticks = []
    worker.start()
    while not state["done"]:
        if state["inside"]:
            ticks.append(time.perf_counter())
    worker.join()
    call = state["end"] - state["start"]
    during = [t for t in ticks if state["start"] <= t <= state["end"]]
    assert call > 0.01, call
    assert during and during[-1] - during[0] > 0.5 * call, (call, len(during))


def test_path_frames(checker, camera_path):
    cams = checker.path_frames(camera_path, 4)
    assert [c.frame for c in cams] == [0, 1, 2, 3]
    assert [c.time for c in cams] == [0.0, 1.0, 2.0, 3.0]
    # Frames at key times pass through the keys; fov and up carry over.
    assert cams[0].position == (0.0, 1.5, 0.0) and cams[0].look_at == (0.0, 0.0, 40.0)
    assert cams[0].up == (0.0, 1.0, 0.0) and cams[0].fov == 40.0
    assert np.allclose(cams[2].position, (1, 3, 2)) and cams[2].fov == pytest.approx(30.0)
    assert cams[3].position == (-1.0, 0.5, 4.0) and cams[3].up == (0.1, 1.0, 0.0)
    assert cams[3].fov == 30.0
    # Between keys: up and fov linear, position on the spline (not the chord).
    assert cams[1].fov == pytest.approx(35.0)
    assert "frame=1" in repr(cams[1]) and "fov=" in repr(cams[1])
    one = checker.path_frames(camera_path, 1)
    assert len(one) == 1 and one[0].time == 0.0
    shipped = checker.path_frames(SCENES / "runway-approach.path.toml", 48)
    assert len(shipped) == 48


# --- Bad arguments and files -------------------------------------------------


def test_bad_render_arguments_name_the_field(checker, camera_path):
    cases = [
        (dict(filter="box"), r'unknown filter "box"'),
        (dict(filter="supersample:x"), r'unknown filter "supersample:x"'),
        (dict(filter="supersample:0"), r"supersample:0: the sample grid must be 1..=64"),
        (dict(pixel_filter="gauss"), r'unknown pixel_filter "gauss"'),
        (dict(width=0), r"width must be at least 1 pixel, got 0"),
        (dict(height=-3), r"height must be at least 1 pixel, got -3"),
        (dict(width=100000, height=100000), r"resolution 100000x100000 is zero or above"),
        (dict(frame=0), r"frame applies to a camera path"),
        (dict(frames=3), r"frames applies to a camera path"),
        (dict(path=camera_path), r"path needs frame"),
        (dict(path=camera_path, frame=0), r"path needs frames"),
        (dict(path=camera_path, frame=3, frames=3), r"frame must be in 0..3 \(frames\), got 3"),
        (dict(path=camera_path, frame=-1, frames=3), r"frame must be in 0..3"),
        (dict(path=camera_path, frame=0, frames=0), r"frames must be in 1..=100000, got 0"),
        (dict(error_bound=0.0), r"error bound must be a finite number > 0"),
        (dict(budget=0), r"budget must be at least 1, got 0"),
        (dict(level=31), r"level must be in 0..=30, got 31"),
        (dict(quality=0.5), r"quality must be in \[1, 64\], got 0.5"),
    ]
    for kwargs, message in cases:
        with pytest.raises(ValueError, match=message):
            checker.render(**kwargs)
    with pytest.raises(ValueError, match="frames must be in 1..=100000, got 100001"):
        checker.path_frames(camera_path, 100001)


def test_missing_files_are_os_errors(checker, tmp_path):
    missing = tmp_path / "nowhere.toml"
    with pytest.raises(FileNotFoundError) as e:
        quadtex.Scene.open(missing)
    assert e.value.errno == errno.ENOENT and e.value.filename == str(missing)
    with pytest.raises(FileNotFoundError) as e:
        checker.render(width=8, path=missing, frame=0, frames=1)
    assert e.value.errno == errno.ENOENT and e.value.filename == str(missing)
    with pytest.raises(FileNotFoundError):
        checker.path_frames(missing, 2)


def test_malformed_scenes_and_paths_name_file_line_and_key(tmp_path, checker):
    scene = tmp_path / "bad.toml"
    scene.write_text(CHECKER.read_text().replace('"builtin:checker"', '"missing.qtx"'))
    with pytest.raises(ValueError, match=r"shape\[0\]\.texture.*missing\.qtx"):
        quadtex.Scene.open(scene)
    path = tmp_path / "bad.path.toml"
    path.write_text(PATH_TOML.replace("fov = 30", "fov = 300"))
    with pytest.raises(ValueError, match=r"bad\.path\.toml.*key\[1\]"):
        checker.path_frames(path, 3)
    with pytest.raises(ValueError, match=r"resources must be one of"):
        quadtex.Scene.open(CHECKER, resources="everywhere")
    with pytest.raises(ValueError, match=r"memory_limit must be at least 1 byte"):
        quadtex.Scene.open(CHECKER, memory_limit=0)


def test_a_degenerate_frame_is_named(tmp_path, checker):
    # The spline passes look_at through position between the keys.
    path = tmp_path / "through.path.toml"
    path.write_text(
        "[[key]]\ntime = 0\nposition = [0, 1, 0]\nlook_at = [0, 1, 2]\nfov = 40\n"
        "[[key]]\ntime = 1\nposition = [0, 1, 2]\nlook_at = [0, 1, 0]\n"
    )
    with pytest.raises(ValueError, match=r"through\.path\.toml: frame 1 \(time 0\.5\).*degenerate"):
        checker.path_frames(path, 3)
    with pytest.raises(ValueError, match=r"frame 1 \(time 0\.5\)"):
        checker.render(width=8, path=path, frame=1, frames=3)
    # Frames that are cameras still render.
    assert checker.render(width=8, path=path, frame=0, frames=3).shape == (5, 8, 4)  # 4.5 rounds up


# --- Footprints from ray differentials ---------------------------------------


def test_footprints_from_differentials_are_the_rust_parallelograms():
    quads = quadtex.footprints_from_differentials([[0.5, 0.5]], [[0.25, 0.0]], [[0.0, 0.125]])
    assert quads.dtype == np.float64 and quads.shape == (1, 4, 2)
    assert quads[0].tolist() == [[0.375, 0.4375], [0.625, 0.4375], [0.625, 0.5625], [0.375, 0.5625]]
    # A sheared one: corner (i, j) = st + (i - 1/2) dx + (j - 1/2) dy.
    rng = np.random.default_rng(3)
    st, dx, dy = rng.normal(size=(3, 50, 2))
    quads = quadtex.footprints_from_differentials(st, dx, dy)
    for c, (i, j) in enumerate([(0, 0), (1, 0), (1, 1), (0, 1)]):
        assert np.allclose(quads[:, c], st + (i - 0.5) * dx + (j - 0.5) * dy, rtol=0, atol=1e-15)
    assert quadtex.footprints_from_differentials(np.zeros((0, 2)), np.zeros((0, 2)), np.zeros((0, 2))).shape == (0, 4, 2)


def test_differential_footprints_filter_as_texture_footprints():
    checker = np.array([[[255] * 3, [0] * 3], [[0] * 3, [255] * 3]], dtype=np.uint8)
    tex = quadtex.pack(checker)
    # One white cell (top left of the raster: x in [0, .5), z in [.5, 1)) and
    # 40 whole tiles: the mean.
    quads = quadtex.footprints_from_differentials([[0.25, 0.75], [20.0, 20.0]], [[0.5, 0], [40, 0]], [[0, -0.5], [0, 40]])
    rgba = tex.filter(quads, wrap="repeat")
    assert np.allclose(rgba[0], 1.0, atol=1e-4)
    assert np.allclose(rgba[1, :3], 0.5, atol=1e-4)


def test_bad_differentials():
    ok = np.zeros((3, 2))
    with pytest.raises(ValueError, match=r"dpdx must have shape \(N, 2\), got \(3, 3\)"):
        quadtex.footprints_from_differentials(ok, np.zeros((3, 3)), ok)
    with pytest.raises(ValueError, match=r"dpdy has 2 rows, points has 3"):
        quadtex.footprints_from_differentials(ok, ok, np.zeros((2, 2)))
    bad = ok.copy()
    bad[2, 1] = np.nan
    with pytest.raises(ValueError, match=r"dpdx\[2, 1\] is not finite \(NaN\)"):
        quadtex.footprints_from_differentials(ok, bad, ok)
    far = ok.copy()
    far[1] = [1e16, 0]
    with pytest.raises(ValueError, match=r"row 1: .*corner\[0\]\.x.*MAX_TEXTURE_COORDINATE"):
        quadtex.footprints_from_differentials(far, ok, ok)
    with pytest.raises(TypeError, match="points must hold real numbers"):
        quadtex.footprints_from_differentials(ok.astype(complex), ok, ok)


# --- to_srgb8 and save_image -------------------------------------------------


def srgb8_reference(v):
    v = np.asarray(v, dtype=np.float64)
    s = np.where(v <= 0.0031308, 12.92 * v, 1.055 * np.power(np.maximum(v, 0), 1 / 2.4) - 0.055)
    return np.floor(255 * np.clip(s, 0, 1) + 0.5).astype(np.uint8)


def test_to_srgb8_unpremultiplies_and_encodes():
    image = np.array(
        [[[0.25, 0.25, 0.25, 0.5], [0.0, 0.0, 0.0, 0.0], [1.0, 2.0, -1.0, 1.0], [np.nan, 0.5, 0.5, 1.0]]],
        dtype=np.float32,
    )
    out = quadtex.to_srgb8(image)
    assert out.shape == (1, 4, 4) and out.dtype == np.uint8
    assert out[0, 0].tolist() == [188, 188, 188, 128]  # linear 0.5 is sRGB 188
    assert out[0, 1].tolist() == [0, 0, 0, 0]
    assert out[0, 2].tolist() == [255, 255, 0, 255]
    assert out[0, 3, 0] == 0
    rng = np.random.default_rng(5)
    colour = rng.random((64, 64, 3)).astype(np.float32)
    opaque = np.concatenate([colour, np.ones((64, 64, 1), np.float32)], axis=2)
    assert np.array_equal(quadtex.to_srgb8(opaque)[..., :3], srgb8_reference(colour))
    # float64 is rounded to float32 first; lists work.
    assert np.array_equal(quadtex.to_srgb8(opaque.astype(np.float64)), quadtex.to_srgb8(opaque))
    assert quadtex.to_srgb8([[[1.0, 1.0, 1.0, 1.0]]]).tolist() == [[[255, 255, 255, 255]]]


def test_bad_images():
    with pytest.raises(ValueError, match=r"image must have shape \(H, W, 4\), got \(2, 2, 3\)"):
        quadtex.to_srgb8(np.zeros((2, 2, 3), np.float32))
    with pytest.raises(ValueError, match=r"image must have shape \(H, W, 4\), got \(4,\)"):
        quadtex.to_srgb8(np.zeros(4, np.float32))
    with pytest.raises(ValueError, match=r"at least 1x1 pixels, got 3x0"):
        quadtex.to_srgb8(np.zeros((0, 3, 4), np.float32))
    with pytest.raises(TypeError, match="image must be floating point"):
        quadtex.to_srgb8(np.zeros((2, 2, 4), np.uint8))


def test_save_image_by_extension_and_errors(tmp_path):
    image = np.full((3, 5, 4), 0.5, dtype=np.float32)
    quadtex.save_image(tmp_path / "a.PNG", image)
    assert np.array_equal(read_png_rgba8(tmp_path / "a.PNG"), quadtex.to_srgb8(image))
    quadtex.save_image(str(tmp_path / "a.exr"), image)
    assert np.array_equal(read_exr(tmp_path / "a.exr"), image)
    with pytest.raises(ValueError, match=r"a\.tif: unsupported output format \(use \.png or \.exr\)"):
        quadtex.save_image(tmp_path / "a.tif", image)
    with pytest.raises(IsADirectoryError) as e:
        (tmp_path / "dir.png").mkdir()
        quadtex.save_image(tmp_path / "dir.png", image)
    assert e.value.errno == errno.EISDIR
    with pytest.raises(FileNotFoundError) as e:
        quadtex.save_image(tmp_path / "no" / "such.png", image)
    assert e.value.errno == errno.ENOENT
