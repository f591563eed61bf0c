"""Scaling of quadtex.dask on this machine: a camera path rendered and a
tile folder packed by 1 and 2 worker processes (one thread each, renderer
and packer on one thread: RAYON_NUM_THREADS=1), against the same work in
one process with one thread. Not run by CI.

    python bench/dask/scaling.py --tiles DIR [--frames 48] [--width 960] [--rounds 3]

DIR: a tile folder (`cargo run --release --example tiles -- DIR 16 1024`).
Prints one table row per job: the median and range over the rounds (the
configurations alternate within a round), and the scaling efficiency
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


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--tiles", required=True)
    ap.add_argument("--frames", type=int, default=48)
    ap.add_argument("--width", type=int, default=960)
    ap.add_argument("--rounds", type=int, default=3)
    args = ap.parse_args()
    scratch = pathlib.Path(tempfile.mkdtemp(prefix="quadtex-dask-bench-"))
    times = {k: [] for k in ("render 1", "render 1w", "render 2w", "pack 1", "pack 1w", "pack 2w")}
    clusters = {}
    try:
        for workers in (1, 2):
            cluster = distributed.LocalCluster(
                n_workers=workers,
                threads_per_worker=1,
                processes=True,
                dashboard_address=None,
                env={"RAYON_NUM_THREADS": "1"},
            )
            clusters[workers] = (cluster, distributed.Client(cluster))
        for _ in range(args.rounds):
            out = scratch / "serial"
            shutil.rmtree(out, ignore_errors=True)
            scene = quadtex.Scene.open(RUNWAY)

            def serial_render():
                out.mkdir()
                for i in range(args.frames):
                    image = scene.render(width=args.width, path=str(APPROACH), frame=i, frames=args.frames)
                    quadtex.save_image(out / f"frame_{i:04d}.png", image)

            times["render 1"].append(timed(serial_render))
            times["pack 1"].append(timed(lambda: quadtex.pack_tiles(args.tiles).save(scratch / "serial.qtx")))
            for workers, (_, client) in clusters.items():
                out = scratch / f"w{workers}"
                shutil.rmtree(out, ignore_errors=True)
                times[f"render {workers}w"].append(
                    timed(lambda: qdask.render_path(client, RUNWAY, APPROACH, args.frames, out, width=args.width))
                )
                times[f"pack {workers}w"].append(
                    timed(lambda: qdask.pack_tiles(client, args.tiles, scratch / f"w{workers}.qtx"))
                )
                assert (scratch / f"w{workers}.qtx").read_bytes() == (scratch / "serial.qtx").read_bytes()
        print(f"| job | one process | 1 worker | 2 workers | efficiency at 2 |")
        print("|---|---:|---:|---:|---:|")
        for job, label in (("render", f"render_path, {args.frames} frames at {args.width} wide"), ("pack", "pack_tiles")):
            med = {k: statistics.median(times[f"{job} {k}"]) for k in ("1", "1w", "2w")}
            rng = {k: (min(times[f"{job} {k}"]), max(times[f"{job} {k}"])) for k in ("1", "1w", "2w")}
            cell = lambda k: f"{med[k]:.2f} s ({rng[k][0]:.2f}–{rng[k][1]:.2f})"
            print(f"| {label} | {cell('1')} | {cell('1w')} | {cell('2w')} | {med['1'] / (2 * med['2w']):.2f} |")
    finally:
        for cluster, client in clusters.values():
            client.close()
            cluster.close()
        shutil.rmtree(scratch, ignore_errors=True)


if __name__ == "__main__":
    sys.exit(main())
