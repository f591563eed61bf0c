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
