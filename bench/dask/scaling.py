"""Scaling of quadtex.dask on this machine: a camera path rendered and a
tile folder packed by 1 and 2 worker processes (one thread each, renderer
and packer on one thread: RAYON_NUM_THREADS=1), against the same job in
one process with one thread: the scene opened and every frame rendered and
saved; the tiles packed and saved. The workers forget their open files
before each round, so they pay for opening the scene as the serial job does.
Not run by CI.

    python bench/dask/scaling.py --tiles DIR [--frames 48] [--width 960] [--rounds 5]

DIR: a tile folder (`cargo run --release --example tiles -- DIR 16 1024`).
Prints one table row per job: the median and range over the rounds (serial
and cluster alternate within a round; a warm-up round is not counted), and
the scaling efficiency
serial / (workers × parallel) of the medians.
"""

import argparse
import os
import pathlib
import shutil
import statistics
import subprocess
import sys
import tempfile
import time

os.environ["RAYON_NUM_THREADS"] = "1"

import distributed  # noqa: E402

import quadtex  # noqa: E402
import quadtex.dask as qdask  # noqa: E402

REPO = pathlib.Path(__file__).resolve().parents[2]
RUNWAY = REPO / "scenes" / "runway.toml"
APPROACH = REPO / "scenes" / "runway-approach.path.toml"


def timed(f):
    start = time.perf_counter()
    f()
    return time.perf_counter() - start


def forget_open_files(client):
    """Every worker closes what it kept open, so each round pays for opening
    the scene as the serial round does."""
    client.run(lambda: qdask._OPEN.clear())


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--tiles", required=True)
    ap.add_argument("--frames", type=int, default=48)
    ap.add_argument("--width", type=int, default=960)
    ap.add_argument("--rounds", type=int, default=5)
    args = ap.parse_args()
    scratch = pathlib.Path(tempfile.mkdtemp(prefix="quadtex-dask-bench-"))
    times = {k: [] for k in ("render 1", "render 1w", "render 2w", "pack 1", "pack 1w", "pack 2w")}

    def serial_render():
        out = scratch / "serial"
        shutil.rmtree(out, ignore_errors=True)
        out.mkdir()
        scene = quadtex.Scene.open(RUNWAY)
        for i in range(args.frames):
            image = scene.render(width=args.width, path=str(APPROACH), frame=i, frames=args.frames)
            quadtex.save_image(out / f"frame_{i:04d}.png", image)

    def serial_pack():
        quadtex.pack_tiles(args.tiles).save(scratch / "serial.qtx")

    try:
        # One cluster at a time: an idle second cluster's processes would
        # take their share of the two cores.
        for workers in (1, 2):
            cluster = distributed.LocalCluster(
                n_workers=workers,
                threads_per_worker=1,
                processes=True,
                dashboard_address=None,
                env={"RAYON_NUM_THREADS": "1"},
            )
            client = distributed.Client(cluster)
            out = scratch / f"w{workers}"
            qtx = scratch / f"w{workers}.qtx"

            def parallel_render():
                shutil.rmtree(out, ignore_errors=True)
                qdask.render_path(client, RUNWAY, APPROACH, args.frames, out, width=args.width)

            def parallel_pack():
                qdask.pack_tiles(client, args.tiles, qtx)

            try:
                # Round 0 warms caches and imports on every side; not counted.
                for round_ in range(args.rounds + 1):
                    # The serial rounds alternate with both cluster sizes.
                    serial = {"render": timed(serial_render), "pack": timed(serial_pack)}
                    forget_open_files(client)
                    parallel = {"render": timed(parallel_render), "pack": timed(parallel_pack)}
                    assert qtx.read_bytes() == (scratch / "serial.qtx").read_bytes()
                    if round_ > 0:
                        for job in ("render", "pack"):
                            times[f"{job} 1"].append(serial[job])
                            times[f"{job} {workers}w"].append(parallel[job])
            finally:
                client.close()
                cluster.close()
        print("| job | one process | 1 worker | 2 workers | efficiency at 2 |")
        print("|---|---:|---:|---:|---:|")
        for job, label in (("render", f"render_path, {args.frames} frames at {args.width} wide"), ("pack", "pack_tiles")):
            med = {k: statistics.median(times[f"{job} {k}"]) for k in ("1", "1w", "2w")}
            rng = {k: (min(times[f"{job} {k}"]), max(times[f"{job} {k}"])) for k in ("1", "1w", "2w")}
            cell = lambda k: f"{med[k]:.2f} s ({rng[k][0]:.2f}–{rng[k][1]:.2f})"
            print(f"| {label} | {cell('1')} | {cell('1w')} | {cell('2w')} | {med['1'] / (2 * med['2w']):.2f} |")
    finally:
        shutil.rmtree(scratch, ignore_errors=True)


if __name__ == "__main__":
    sys.exit(main())
