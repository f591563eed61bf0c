"""quadtex.dask on a real cluster: a LocalCluster of two worker processes
(not a mock). Results equal the serial calls byte for byte."""

import os
import pathlib

import numpy as np
import pytest

import quadtex

from conftest import write_png, write_tiled_tiff

distributed = pytest.importorskip("distributed")
da = pytest.importorskip("dask.array")
qdask = pytest.importorskip("quadtex.dask")


@pytest.fixture(scope="module")
def client():
    with distributed.LocalCluster(
        n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None
    ) as cluster, distributed.Client(cluster) as c:
        yield c


def test_importing_quadtex_does_not_import_dask():
    import subprocess
    import sys

    code = "import sys, quadtex; quadtex.pack; print('dask' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"


def test_filter_equals_the_serial_call(client, tmp_path, rng):
    texels = rng.random((64, 48, 4))
    texels[..., :3] *= texels[..., 3:]
    path = tmp_path / "t.qtx"
    quadtex.pack(texels).save(path)
    centres = rng.random((5000, 1, 2)) * 3 - 1
    corners = np.array([[0, 0], [1, 0], [1.3, 1], [0.2, 0.8]]) * 0.05
    quads = centres + corners
    serial = quadtex.open(path).filter(quads, wrap="mirror", weighting="texture")
    lazy = qdask.filter(path, da.from_array(quads, chunks=(700, 4, 2)), wrap="mirror", weighting="texture")
    assert lazy.shape == (5000, 4) and lazy.dtype == np.float32
    got = client.compute(lazy).result()
    np.testing.assert_array_equal(got, serial)
    # A numpy array is split into tasks of chunk_rows rows.
    got = client.compute(qdask.filter(path, quads, chunk_rows=1000, wrap="mirror", weighting="texture")).result()
    np.testing.assert_array_equal(got, serial)
    with pytest.raises(ValueError, match=r"\(N, 4, 2\)"):
        qdask.filter(path, np.zeros((3, 4, 3)))


def test_pack_tiles_writes_the_pack_tiles_file(client, tmp_path, rng):
    mosaic = rng.integers(0, 4, size=(64, 64, 3)).astype(np.uint8) * 80
    mosaic[:32, :32] = 200
    mosaic[32:, 32:, 1] = 7
    tiles = tmp_path / "tiles"
    tiles.mkdir()
    for row in range(4):
        for col in range(4):
            write_png(tiles / f"{row}_{col}.png", mosaic[row * 16:(row + 1) * 16, col * 16:(col + 1) * 16])
    out = tmp_path / "cluster.qtx"
    texture = qdask.pack_tiles(client, tiles, out)
    quadtex.pack_tiles(tiles).save(tmp_path / "serial.qtx")
    assert out.read_bytes() == (tmp_path / "serial.qtx").read_bytes()
    assert texture.source_size == (64, 64)
    os.remove(tiles / "1_2.png")
    with pytest.raises(ValueError, match="1_2"):
        qdask.pack_tiles(client, tiles, tmp_path / "never.qtx")
    assert not (tmp_path / "never.qtx").exists()


def test_pack_tiles_reads_a_cloud_optimized_layout(client, cli, tmp_path, rng):
    """A tiled TIFF of 100 × 70 texels in 32² tiles (partial tiles on the
    right and bottom edges, a 4 × 3 grid): packed on the cluster, byte for
    byte the file `quadtex pack` writes from the whole image."""
    import subprocess

    image = rng.integers(0, 3, size=(70, 100, 3)).astype(np.uint8) * 90
    image[:40, :50] = (200, 30, 10)
    tif = tmp_path / "cog.tif"
    write_tiled_tiff(tif, image, 32)
    assert quadtex.tile_grid(tif) == (4, 32)
    tiles = quadtex.mosaic_tiles(tif)
    # Tree tiles line up with the image's bottom edge: 4 columns, 3 rows.
    assert len(tiles) == 12 and tiles[0] == (3, 0)
    out = tmp_path / "cluster.qtx"
    texture = qdask.pack_tiles(client, tif, out)
    assert texture.source_size == (100, 70)
    subprocess.run([cli, "pack", str(tif), "-o", str(tmp_path / "whole.qtx")], check=True, capture_output=True)
    assert out.read_bytes() == (tmp_path / "whole.qtx").read_bytes()
    quadtex.pack_tiles(tif).save(tmp_path / "serial.qtx")
    assert out.read_bytes() == (tmp_path / "serial.qtx").read_bytes()
    with pytest.raises(ValueError, match="holds none of the 100x70 texture"):
        quadtex.pack_tile(tif, 0, 0)


RUNWAY = pathlib.Path(__file__).resolve().parents[3] / "scenes" / "runway.toml"
APPROACH = RUNWAY.with_name("runway-approach.path.toml")


def test_render_path_writes_the_cli_frames(client, cli, tmp_path):
    serial = tmp_path / "cli"
    run = __import__("subprocess").run(
        [cli, "render", str(RUNWAY), "--path", str(APPROACH), "--frames", "6", "--width", "64", "-o", f"{serial}/"],
        capture_output=True,
        timeout=600,
    )
    assert run.returncode == 0, run.stderr.decode()
    out = tmp_path / "cluster"
    files = qdask.render_path(client, RUNWAY, APPROACH, 6, out, width=64)
    assert [pathlib.Path(f).name for f in files] == sorted(os.listdir(serial))
    for f in files:
        assert pathlib.Path(f).read_bytes() == (serial / pathlib.Path(f).name).read_bytes(), f
    # A rerun finds every frame complete and renders none; a range, part.
    before = {f: os.stat(f).st_mtime_ns for f in files}
    assert qdask.render_path(client, RUNWAY, APPROACH, 6, out, width=64) == files
    assert {f: os.stat(f).st_mtime_ns for f in files} == before
    assert qdask.render_path(client, RUNWAY, APPROACH, 6, out, width=64, frame_range=(2, 3)) == files[2:4]
    with pytest.raises(ValueError, match="frame_range"):
        qdask.render_path(client, RUNWAY, APPROACH, 6, out, frame_range=(4, 6))
    with pytest.raises(ValueError, match="filter"):
        qdask.render_path(client, RUNWAY, APPROACH, 6, tmp_path / "bad", filter="blurry")


def test_a_worker_killed_mid_path_loses_no_frame(cli, tmp_path):
    """Kills one of two worker processes while a path renders: the
    scheduler gives its frames to the other (or its restarted self), every
    frame is written once, whole, and equals the CLI's."""
    import signal
    import threading
    import time

    frames, width = 16, 320
    serial = tmp_path / "cli"
    run = __import__("subprocess").run(
        [cli, "render", str(RUNWAY), "--path", str(APPROACH), "--frames", str(frames), "--width", str(width), "-o", f"{serial}/"],
        capture_output=True,
        timeout=600,
    )
    assert run.returncode == 0, run.stderr.decode()
    out = tmp_path / "cluster"
    with distributed.LocalCluster(
        n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None
    ) as cluster, distributed.Client(cluster) as c:
        result = {}

        def render():
            result["files"] = qdask.render_path(c, RUNWAY, APPROACH, frames, out, width=width)

        thread = threading.Thread(target=render)
        thread.start()
        deadline = time.monotonic() + 120
        while not (out.exists() and any(n.startswith("frame_") for n in os.listdir(out))):
            assert time.monotonic() < deadline, "no frame was written"
            time.sleep(0.01)
        pids = c.run(os.getpid)
        victim = sorted(pids.values())[0]
        os.kill(victim, signal.SIGKILL)
        written = sum(n.startswith("frame_") for n in os.listdir(out))
        assert written < frames, "the path was done before the kill"
        thread.join(timeout=300)
        assert not thread.is_alive()
    files = result["files"]
    assert len(files) == frames
    names = sorted(n for n in os.listdir(out) if n.startswith("frame_"))
    assert names == sorted(os.listdir(serial))
    for n in names:
        assert (out / n).read_bytes() == (serial / n).read_bytes(), n
