"""Shared helpers: a PNG writer on the standard library (no Pillow), and
closed-form integrals of a raster over rectangles."""

import json
import os
import pathlib
import shutil
import struct
import subprocess
import zlib

import numpy as np
import pytest

REPO = pathlib.Path(__file__).resolve().parents[3]


def write_png(path, pixels):
    """Writes `pixels` (H×W, H×W×{1,2,3,4}; uint8 or uint16) as a PNG."""
    a = np.asarray(pixels)
    if a.ndim == 2:
        a = a[:, :, None]
    h, w, c = a.shape
    colour_type = {1: 0, 2: 4, 3: 2, 4: 6}[c]
    depth = {np.dtype(np.uint8): 8, np.dtype(np.uint16): 16}[a.dtype]
    raw = a.astype(">u2" if depth == 16 else np.uint8)
    rows = b"".join(b"\x00" + raw[r].tobytes() for r in range(h))

    def chunk(kind, data):
        body = kind + data
        return struct.pack(">I", len(data)) + body + struct.pack(">I", zlib.crc32(body))

    header = struct.pack(">IIBBBBB", w, h, depth, colour_type, 0, 0, 0)
    png = (
        b"\x89PNG\r\n\x1a\n"
        + chunk(b"IHDR", header)
        + chunk(b"IDAT", zlib.compress(rows))
        + chunk(b"IEND", b"")
    )
    pathlib.Path(path).write_bytes(png)


def write_tiled_tiff(path, pixels, tile):
    """Writes `pixels` (H×W×3 uint8) as an uncompressed tiled TIFF of
    `tile`×`tile` tiles; edge tiles are padded, as the format stores them."""
    a = np.asarray(pixels, dtype=np.uint8)
    h, w, _ = a.shape
    across, down = -(-w // tile), -(-h // tile)
    padded = np.zeros((down * tile, across * tile, 3), np.uint8)
    padded[:h, :w] = a
    blobs = [
        padded[r * tile:(r + 1) * tile, c * tile:(c + 1) * tile].tobytes()
        for r in range(down)
        for c in range(across)
    ]
    n = len(blobs)
    entries = 11
    ifd = 8
    extra = ifd + 2 + 12 * entries + 4
    bits_at, offsets_at = extra, extra + 6
    counts_at = offsets_at + 4 * n
    data_at = counts_at + 4 * n
    offsets, at = [], data_at
    for b in blobs:
        offsets.append(at)
        at += len(b)

    def entry(tag, kind, count, value):
        if kind == 3 and count == 1:
            return struct.pack("<HHIHH", tag, kind, count, value, 0)
        return struct.pack("<HHII", tag, kind, count, value)

    out = b"II*\x00" + struct.pack("<I", ifd) + struct.pack("<H", entries)
    out += entry(256, 4, 1, w) + entry(257, 4, 1, h) + entry(258, 3, 3, bits_at)
    out += entry(259, 3, 1, 1) + entry(262, 3, 1, 2) + entry(277, 3, 1, 3)
    out += entry(284, 3, 1, 1) + entry(322, 4, 1, tile) + entry(323, 4, 1, tile)
    out += entry(324, 4, n, offsets_at) + entry(325, 4, n, counts_at)
    out += struct.pack("<I", 0) + struct.pack("<HHH", 8, 8, 8)
    out += struct.pack(f"<{n}I", *offsets) + struct.pack(f"<{n}I", *[len(b) for b in blobs])
    out += b"".join(blobs)
    pathlib.Path(path).write_bytes(out)


def exact_integral(texels, rects):
    """Integral of a W×H×C raster (row 0 at the top of the unit square) over
    each rectangle's overlap with the unit square: Σ value × overlap area."""
    texels = np.asarray(texels, dtype=np.float64)
    h, w = texels.shape[:2]
    out = []
    for x0, z0, x1, z1 in np.asarray(rects, dtype=np.float64):
        cols = np.arange(w)
        ox = np.clip(np.minimum(x1, (cols + 1) / w) - np.maximum(x0, cols / w), 0, None)
        rows = np.arange(h)
        oz = np.clip(
            np.minimum(z1, 1 - rows / h) - np.maximum(z0, 1 - (rows + 1) / h), 0, None
        )
        out.append(np.einsum("r,c,rck->k", oz, ox, texels))
    return np.array(out)


def srgb_to_linear(v):
    v = np.asarray(v, dtype=np.float64)
    return np.where(v <= 0.04045, v / 12.92, ((v + 0.055) / 1.055) ** 2.4)


@pytest.fixture
def rng():
    return np.random.default_rng(12)


@pytest.fixture
def random_texels(rng):
    """16×16 opaque RGB, linear, on the 16-bit grid (packs losslessly)."""
    return rng.integers(0, 65536, size=(16, 16, 3)) / 65535.0


@pytest.fixture(scope="session")
def cli():
    """The `quadtex` command: $QUADTEX_BIN (scripts/test sets it to the
    binary `cargo test` built), else what `cargo build --bin quadtex` makes."""
    exe = os.environ.get("QUADTEX_BIN")
    if exe:
        assert os.path.isfile(exe), f"QUADTEX_BIN={exe} is not a file"
        return exe
    cargo = shutil.which("cargo")
    if cargo is None:
        pytest.skip("no quadtex command: set QUADTEX_BIN or put cargo on the PATH")
    run = subprocess.run(
        [cargo, "build", "--quiet", "--bin", "quadtex", "--message-format=json"],
        cwd=REPO,
        capture_output=True,
        text=True,
        timeout=3600,
    )
    assert run.returncode == 0, run.stderr
    for line in run.stdout.splitlines():
        msg = json.loads(line)
        if msg.get("reason") == "compiler-artifact" and msg.get("executable"):
            if msg["target"]["name"] == "quadtex":
                return msg["executable"]
    raise AssertionError("cargo built no quadtex executable")
