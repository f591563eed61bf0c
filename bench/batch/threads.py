"""Batch filtering on one thread and on every core: Texture.filter and
Texture.integrate over the same footprints, alternating within each round.
Not run by CI.

    python bench/batch/threads.py [--footprints 1000000] [--rounds 3] [--svg samples/threshold.svg]

The footprints are projective quads (a rectangle with its far corner pulled
outwards) of log-uniform sizes from 1e-4 to 0.05 texture widths, anywhere
on the texture; the rectangles for `integrate` are their bounding boxes.
Prints the median (and range) of each call's time and the speed-up of every
core over one thread, and checks that the results are bit-identical.
"""

import argparse
import os
import statistics
import sys
import time

import numpy as np

import quadtex


def footprints(n, seed=7):
    rng = np.random.default_rng(seed)
    size = np.exp(rng.uniform(np.log(1e-4), np.log(0.05), n))
    x0, z0 = rng.uniform(0, 1, n), rng.uniform(0, 1, n)
    aspect = np.exp(rng.uniform(np.log(0.25), np.log(4), n))
    x1, z1 = x0 + size * aspect, z0 + size / aspect
    quads = np.stack(
        [np.stack([x0, z0], -1), np.stack([x1, z0], -1), np.stack([x1, z1], -1), np.stack([x0, z1], -1)],
        axis=1,
    )
    quads[:, 2] += 0.3 * (quads[:, 2] - quads[:, 0])
    rects = np.stack([quads[..., 0].min(1), quads[..., 1].min(1), quads[..., 0].max(1), quads[..., 1].max(1)], 1)
    return quads, np.clip(rects, 0, 1)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--footprints", type=int, default=1_000_000)
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--svg", default=os.path.join(os.path.dirname(__file__), "..", "..", "samples", "threshold.svg"))
    args = ap.parse_args()
    texture = quadtex.pack(args.svg)
    quads, rects = footprints(args.footprints)
    cores = os.cpu_count()
    times = {k: [] for k in ("filter 1", "filter all", "integrate 1", "integrate all")}
    results = {}
    for _ in range(args.rounds):
        for call, run in (
            ("filter", lambda t: texture.filter(quads, threads=t)),
            ("integrate", lambda t: texture.integrate(rects, threads=t)),
        ):
            for label, threads in (("1", 1), ("all", None)):
                start = time.perf_counter()
                out = run(threads)
                times[f"{call} {label}"].append(time.perf_counter() - start)
                first = results.setdefault(call, out)
                assert np.array_equal(first.view(np.uint8), out.view(np.uint8)), f"{call}: results differ"
    print(f"{args.footprints} footprints on {os.path.basename(args.svg)}, {cores} cores, {args.rounds} rounds")
    print("| call | 1 thread | every core | speed-up |")
    print("|---|---:|---:|---:|")
    for call in ("filter", "integrate"):
        one, every = times[f"{call} 1"], times[f"{call} all"]
        cell = lambda t: f"{statistics.median(t):.3f} s ({min(t):.3f}–{max(t):.3f})"
        print(f"| `{call}` | {cell(one)} | {cell(every)} | {statistics.median(one) / statistics.median(every):.2f} |")


if __name__ == "__main__":
    sys.exit(main())
