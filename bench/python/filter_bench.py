#!/usr/bin/env python3
"""Python `Texture.filter` against the same calls from Rust.

Acceptance (issue 12): Python filter over 1 M footprints costs within 1.3× of
the same calls from Rust.

The script packs a texture and saves it as .qtx, generates N deterministic
projective footprints (the pixels of a W×W screen looking at a textured ground
plane, from near-magnified to far-minified), writes them as raw little-endian
f64 (N×4×2), then alternates over the rounds:

  (a) Python: `quadtex.open(qtx).filter(quads)` (defaults: repeat wrap,
      screen weighting, quality 1, error bound 1/512), timed around the call
      (array checks, footprint construction, filtering, output array);
  (b) Rust: the example `filter_batch` (crates/quadtex-eval/examples), which
      reads the same files and times `Texture::filter_batch` alone over a
      prebuilt `Vec<Footprint>` (one untimed warm-up call per process).

It checks that both sides give bit-identical colours, then prints
min/median/max seconds per side and the ratio of medians (Python / Rust).

    python bench/python/filter_bench.py                  # runway art, 1 M footprints, 5 rounds
    python bench/python/filter_bench.py --image some.png --n 200000 --rounds 7

Needs the bindings installed (pip install ./bindings/python) and cargo.
"""

import argparse
import json
import pathlib
import statistics
import subprocess
import sys
import tempfile
import time

import numpy as np

import quadtex

REPO = pathlib.Path(__file__).resolve().parents[2]


def footprints(n, seed=12):
    """N projective footprints: screen pixels of a camera over a ground plane.

    Pixel (px, py) of a W×W screen (W = ceil(sqrt(N))) sees the ground point
    Z = f·h / (py + y0), X = (px − W/2)·Z / f; texture space is the ground
    rotated, scaled and shifted. Corners are the images of the pixel's
    corners (px, py), (px+1, py), (px+1, py+1), (px, py+1).
    """
    rng = np.random.default_rng(seed)
    w = int(np.ceil(np.sqrt(n)))
    f, h, y0 = float(w), 1.0, 0.02 * w
    angle = np.deg2rad(30.0 + rng.uniform(-1, 1))
    scale, offset = 0.25, rng.uniform(0, 1, size=2)
    rot = np.array([[np.cos(angle), -np.sin(angle)], [np.sin(angle), np.cos(angle)]]) * scale
    py, px = np.divmod(np.arange(n, dtype=np.float64), w)
    corners = []
    for dx, dy in ((0, 0), (1, 0), (1, 1), (0, 1)):
        z = f * h / (py + dy + y0)
        x = (px + dx - w / 2) * z / f
        corners.append(np.stack([x, z], axis=-1) @ rot.T + offset)
    return np.ascontiguousarray(np.stack(corners, axis=1))


def make_texture(args, work):
    """The texture to filter, saved as work/texture.qtx."""
    if args.image:
        source = pathlib.Path(args.image)
    else:
        source = work / "runway.png"
        cmd = ["cargo", "run", "--release", "-q", "--bin", "quadtex", "--",
               "sample", "runway", "-o", str(source), "--size", str(args.size)]
        done = subprocess.run(cmd, cwd=REPO, capture_output=True, text=True)
        if done.returncode != 0:
            print(f"`quadtex sample runway` failed ({done.stderr.strip()[-300:]}); "
                  "using numpy-made art instead", file=sys.stderr)
            source = numpy_art(args.size)
    tex = quadtex.pack(source)
    path = work / "texture.qtx"
    tex.save(path)
    name = source if isinstance(source, pathlib.Path) else "numpy art"
    return path, name


def numpy_art(size):
    """Flat regions with sharp edges and a smooth gradient (sRGB uint8)."""
    y, x = np.mgrid[0:size, 0:size] / size
    img = np.zeros((size, size, 3), np.uint8)
    img[..., 0] = (255 * x).astype(np.uint8)
    img[..., 1] = np.where(((x * 8).astype(int) + (y * 8).astype(int)) % 2 == 0, 200, 40)
    disc = (x - 0.5) ** 2 + (y - 0.5) ** 2 < 0.1
    img[disc] = [250, 250, 250]
    return img


def build_example():
    """Builds the Rust example; returns its executable's path."""
    cmd = ["cargo", "build", "--release", "-p", "quadtex-eval", "--example", "filter_batch",
           "--message-format=json"]
    done = subprocess.run(cmd, cwd=REPO, capture_output=True, text=True)
    if done.returncode != 0:
        sys.exit(f"building the Rust example failed:\n{done.stderr}")
    for line in done.stdout.splitlines():
        msg = json.loads(line)
        if msg.get("reason") == "compiler-artifact" and msg["target"]["name"] == "filter_batch":
            if msg.get("executable"):
                return msg["executable"]
    sys.exit("cargo did not report the filter_batch executable")


def run_rust(exe, qtx, quads_bin, out=None):
    cmd = [exe, str(qtx), str(quads_bin)] + (["--out", str(out)] if out else [])
    done = subprocess.run(cmd, capture_output=True, text=True, check=True)
    line = [l for l in done.stdout.splitlines() if l.startswith("seconds=")][-1]
    return float(line.split()[0].split("=")[1])


def summary(name, times):
    return (f"{name:>6}: min {min(times):.3f} s  median {statistics.median(times):.3f} s  "
            f"max {max(times):.3f} s")


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--n", type=int, default=1_000_000, help="footprints (default 1 000 000)")
    p.add_argument("--rounds", type=int, default=5, help="alternating rounds (default 5)")
    p.add_argument("--image", help="image to pack (default: `quadtex sample runway`)")
    p.add_argument("--size", type=int, default=1024, help="runway art size (default 1024)")
    p.add_argument("--max-ratio", type=float, help="exit 1 if median ratio exceeds this")
    args = p.parse_args()

    with tempfile.TemporaryDirectory(prefix="quadtex-bench-") as tmp:
        work = pathlib.Path(tmp)
        qtx, name = make_texture(args, work)
        tex = quadtex.open(qtx)
        quads = footprints(args.n)
        quads_bin = work / "quads.bin"
        quads.astype("<f8").tofile(quads_bin)
        exe = build_example()
        print(f"texture: {name}: {tex!r}")
        print(f"footprints: {args.n}, texture-space area median {np.median(area(quads)):.3g}, "
              f"5-95 % {np.percentile(area(quads), 5):.3g}..{np.percentile(area(quads), 95):.3g}")

        # Warm-up, and both sides must agree bit for bit.
        ours = tex.filter(quads)
        colours_bin = work / "colours.bin"
        run_rust(exe, qtx, quads_bin, out=colours_bin)
        theirs = np.fromfile(colours_bin, dtype="<f4").reshape(-1, 4)
        if not np.array_equal(ours, theirs):
            bad = np.flatnonzero(np.any(ours != theirs, axis=1))
            sys.exit(f"Python and Rust colours differ at {len(bad)} footprints, first {bad[0]}")
        print("colours: Python == Rust (bit-identical)")

        py_times, rust_times = [], []
        for r in range(args.rounds):
            sides = ["python", "rust"] if r % 2 == 0 else ["rust", "python"]
            for side in sides:
                if side == "python":
                    start = time.perf_counter()
                    tex.filter(quads)
                    py_times.append(time.perf_counter() - start)
                else:
                    rust_times.append(run_rust(exe, qtx, quads_bin))
            print(f"round {r + 1}: python {py_times[-1]:.3f} s, rust {rust_times[-1]:.3f} s")
        print(summary("python", py_times))
        print(summary("rust", rust_times))
        ratio = statistics.median(py_times) / statistics.median(rust_times)
        per = statistics.median(py_times) / args.n * 1e9
        print(f"ratio of medians (python / rust): {ratio:.3f}  ({per:.0f} ns per footprint from Python)")
        if args.max_ratio is not None and ratio > args.max_ratio:
            sys.exit(f"ratio {ratio:.3f} exceeds {args.max_ratio}")


def area(quads):
    x, z = quads[..., 0], quads[..., 1]
    return 0.5 * np.abs(np.sum(x * np.roll(z, -1, axis=1) - np.roll(x, -1, axis=1) * z, axis=1))


if __name__ == "__main__":
    main()
