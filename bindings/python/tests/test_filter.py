"""Texture.filter and Texture.integrate against closed forms."""

import threading
import time

import numpy as np
import pytest

import quadtex
from conftest import exact_integral


def rect_quads(rects):
    """Axis-aligned rectangles x0 z0 x1 z1 as footprints (pixel corner order)."""
    r = np.asarray(rects, dtype=np.float64)
    x0, z0, x1, z1 = r.T
    return np.stack(
        [np.stack([x0, z0], -1), np.stack([x1, z0], -1), np.stack([x1, z1], -1), np.stack([x0, z1], -1)],
        axis=1,
    )


def random_rects(rng, n, lo=0.0, hi=1.0):
    a = rng.uniform(lo, hi, size=(n, 2, 2))
    a.sort(axis=1)
    return np.stack([a[:, 0, 0], a[:, 0, 1], a[:, 1, 0], a[:, 1, 1]], axis=1)


@pytest.fixture(scope="module")
def checker():
    """An 8×8 black-and-white checkerboard (linear 0 and 1, opaque): cell
    (col, row) is white iff col + row is even; row 0 at the top."""
    cols, rows = np.meshgrid(np.arange(8), np.arange(8))
    white = ((cols + rows) % 2 == 0).astype(np.float32)
    texels = np.repeat(white[:, :, None], 3, axis=2)
    return texels, quadtex.pack(texels)


def test_checker_cells_and_whole_periods(checker):
    texels, tex = checker
    assert tex.depth == 3
    # One cell: its colour exactly (col 2, row 5 → x in [2/8, 3/8), z in [2/8, 3/8)).
    cell = rect_quads([[2 / 8, 2 / 8, 3 / 8, 3 / 8], [3 / 8, 2 / 8, 4 / 8, 3 / 8]])
    out = tex.filter(cell)
    assert out.dtype == np.float32 and out.shape == (2, 4)
    np.testing.assert_array_equal(out[:, 3], [1, 1])
    np.testing.assert_array_equal(out[:, 0], [texels[5, 2, 0], texels[5, 3, 0]])
    # Whole checker periods (1/4 of the texture) in both directions, anywhere
    # in the repeating plane: exactly half white.
    rects = [[0.3, -1.2, 0.3 + 2.5, -1.2 + 0.75], [-7.1, 3.3, -7.1 + 0.25, 3.3 + 0.25], [0, 0, 1, 1]]
    for weighting in ("screen", "texture"):
        out = tex.filter(rect_quads(rects), weighting=weighting)
        np.testing.assert_allclose(out[:, :3], 0.5, atol=2e-5)
        np.testing.assert_allclose(out[:, 3], 1.0, atol=1e-6)


def test_checker_diamonds(checker):
    texels, tex = checker
    d = 1 / 8
    # A diamond centred where four cells meet covers two white and two black
    # quarters: 0.5. One inside a single cell is that cell's colour.
    centres = np.array([[2 / 8, 3 / 8], [5 / 8, 1 / 8], [2.5 / 8, 2.5 / 8]])
    half = np.array([d, d, d / 4])[:, None]
    quads = np.stack(
        [
            centres + half * [0, -1],
            centres + half * [1, 0],
            centres + half * [0, 1],
            centres + half * [-1, 0],
        ],
        axis=1,
    )
    for weighting in ("screen", "texture"):
        out = tex.filter(quads, weighting=weighting, level=3)
        np.testing.assert_allclose(out[:2, :3], 0.5, atol=1e-6)
        np.testing.assert_array_equal(out[2, :3], texels[5, 2])


def test_checker_rectangles_closed_form(checker, rng):
    texels, tex = checker
    rects = random_rects(rng, 200)
    expected = exact_integral(texels, rects)
    area = ((rects[:, 2] - rects[:, 0]) * (rects[:, 3] - rects[:, 1]))[:, None]
    keep = area[:, 0] > 1e-6
    exact = tex.filter(rect_quads(rects), weighting="texture", level=tex.depth)
    np.testing.assert_allclose(exact[keep, :3], (expected / area)[keep], atol=5e-5)
    # The default level of detail stays within its error bound (1/512 of the contrast).
    lod = tex.filter(rect_quads(rects), weighting="texture")
    np.testing.assert_allclose(lod[keep, :3], (expected / area)[keep], atol=1 / 512 + 1e-5)


def test_texture_weighting_of_rectangles_is_integral_over_area(random_texels, rng):
    tex = quadtex.pack(random_texels)
    rects = random_rects(rng, 500)
    area = (rects[:, 2] - rects[:, 0]) * (rects[:, 3] - rects[:, 1])
    rects, area = rects[area > 1e-8], area[area > 1e-8]
    want = tex.integrate(rects) / area[:, None]
    for weighting in ("texture", "screen"):
        got = tex.filter(rect_quads(rects), weighting=weighting, level=tex.depth)
        np.testing.assert_allclose(got, want, rtol=1e-5, atol=1e-6)


def test_integrate_matches_query_semantics(random_texels, rng):
    tex = quadtex.pack(random_texels)
    # Rectangles reaching outside the unit square count only their overlap (no wrap).
    rects = random_rects(rng, 300, lo=-0.3, hi=1.3)
    got = tex.integrate(rects)
    assert got.dtype == np.float64 and got.shape == (300, 4)
    # Exact but for inner nodes' colours, rounded to 16 bits (half a step per unit area).
    np.testing.assert_allclose(got[:, :3], exact_integral(random_texels, rects), atol=1e-5)
    full_alpha = exact_integral(np.ones((16, 16, 1)), rects)[:, 0]
    np.testing.assert_allclose(got[:, 3], full_alpha, atol=1e-12)
    # A coarser level is an approximation of the same integral.
    coarse = tex.integrate(rects, level=2)
    np.testing.assert_allclose(coarse[:, 3], full_alpha, atol=1e-12)
    assert not np.allclose(coarse[:, :3], got[:, :3], atol=1e-6)


def test_parallelograms_screen_equals_texture(random_texels, rng):
    tex = quadtex.pack(random_texels)
    n = 400
    p0 = rng.uniform(-1, 2, size=(n, 2))
    u = rng.normal(scale=0.2, size=(n, 2))
    v = rng.normal(scale=0.2, size=(n, 2))
    quads = np.stack([p0, p0 + u, p0 + u + v, p0 + v], axis=1)
    for wrap in ("repeat", "mirror", "clamp", ("border", "repeat")):
        # Exact at full depth (the default error bound lets each differ
        # from the exact value by up to its bound), up to the rounding of
        # the projective map of thin parallelograms (measured 2.7e-6).
        screen = tex.filter(quads, weighting="screen", wrap=wrap, level=30)
        texture = tex.filter(quads, weighting="texture", wrap=wrap, level=30)
        np.testing.assert_allclose(screen, texture, atol=1e-5)


def test_projective_screen_weighting_favours_the_near_side():
    # Linear ramp in z (row 0 at the top is brightest).
    ramp = np.linspace(1, 0, 64, dtype=np.float32)
    tex = quadtex.pack(np.repeat(ramp[:, None], 64, axis=1))
    # A trapezoid narrow at the bottom (near the viewer, dense on screen) and wide at the top.
    quad = np.array([[[0.45, 0.1], [0.55, 0.1], [0.9, 0.9], [0.1, 0.9]]])
    screen = tex.filter(quad, weighting="screen")[0, 0]
    texture = tex.filter(quad, weighting="texture")[0, 0]
    # Texture weighting leans to the wide side (high z, bright: about the
    # area centroid, z ≈ 0.6); the pixel sees mostly the narrow side (the
    # pixel centre maps to z ≈ 0.19).
    assert texture > screen + 0.1, (screen, texture)


def test_budget_refines_towards_the_exact_value(rng):
    # A long grazing footprint: many squares along its edges. Clamped, and
    # 64 texels a side: a small repeated texture would be scanned cell by
    # cell, and a region of at most 256 texels texel by texel, exactly,
    # with no budget to spend.
    tex = quadtex.pack(rng.integers(0, 65536, size=(64, 64, 3)) / 65535.0)
    quad = np.array([[[0.30, 0.05], [0.32, 0.05], [0.95, 0.95], [0.05, 0.95]]])
    exact = tex.filter(quad, level=30, wrap="clamp")
    coarse = tex.filter(quad, budget=4, error_bound=1e-6, wrap="clamp")
    fine = tex.filter(quad, budget=100_000, error_bound=1e-6, wrap="clamp")
    assert np.abs(fine - exact).max() < 1e-5
    assert np.abs(coarse - exact).max() > np.abs(fine - exact).max()
    with pytest.raises(ValueError, match="budget"):
        tex.filter(quad, budget=0)


def photo_like(rng):
    """Issue 62's texture: 64×64 sRGB uint8 texels of random colours (a
    6-level tree; at the old default budget of 64 squares, 170 of 200
    random rectangles missed the bound, by up to 2.8e-2)."""
    return rng.integers(0, 256, size=(64, 64, 3), dtype=np.uint8)


def test_default_calls_keep_their_bound(rng):
    # Issue 62: with the old default budget of 64 squares, large rectangles
    # on this texture were off by up to 2.3e-2 (twelve times the bound).
    tex = quadtex.pack(photo_like(rng))
    rects = random_rects(rng, 200)
    area = (rects[:, 2] - rects[:, 0]) * (rects[:, 3] - rects[:, 1])
    rects, area = rects[area > 1e-8], area[area > 1e-8]
    want = tex.integrate(rects) / area[:, None]
    got, bound = tex.filter(rect_quads(rects), weighting="texture", return_bound=True)
    assert got.dtype == np.float32 and got.shape == (len(rects), 4)
    assert bound.dtype == np.float64 and bound.shape == (len(rects),)
    assert (bound <= 1 / 512).all(), bound.max()
    # Within each footprint's bound (plus the 16-bit rounding of stored means).
    err = np.abs(got - want).max(axis=1)
    assert (err <= bound + 2e-5).all(), (err - bound).max()
    # The same colours without the bounds; a budget is opt-in and a
    # footprint it stops reports a bound above the target.
    np.testing.assert_array_equal(tex.filter(rect_quads(rects), weighting="texture"), got)
    _, budgeted = tex.filter(
        rect_quads(rects), weighting="texture", budget=64, return_bound=True
    )
    assert (budgeted > 1 / 512).sum() > len(rects) // 2


def test_batches_give_the_same_bits_on_any_number_of_threads(rng):
    tex = quadtex.pack(photo_like(rng))
    rects = random_rects(rng, 3000, lo=-0.5, hi=1.5)
    quads = rect_quads(rects)
    # Projective footprints: the far corner pulled outwards (still convex).
    quads[:, 2] += 0.3 * (quads[:, 2] - quads[:, 0])
    one, one_bound = tex.filter(quads, return_bound=True, threads=1)
    for threads in (None, 2, 5):
        got, bound = tex.filter(quads, return_bound=True, threads=threads)
        np.testing.assert_array_equal(got, one)
        np.testing.assert_array_equal(bound, one_bound)
    inside = random_rects(rng, 3000)
    np.testing.assert_array_equal(tex.integrate(inside, threads=3), tex.integrate(inside, threads=1))
    # Past one part of a batch (65 536 rectangles copied at a time): each
    # written in its place, C- or Fortran-ordered, and a refused one named
    # by its index in the whole batch.
    many = random_rects(rng, 70_000)
    serial = tex.integrate(many, threads=1)
    np.testing.assert_array_equal(tex.integrate(many), serial)
    np.testing.assert_array_equal(tex.integrate(np.asfortranarray(many), threads=2), serial)
    many[66_000] = [0.5, 0.0, 0.25, 1.0]
    with pytest.raises(ValueError, match=r"^rects\[66000\]: reversed bounds on x"):
        tex.integrate(many)
    for bad in (0, -2):
        with pytest.raises(ValueError, match="threads must be None"):
            tex.filter(quads[:2], threads=bad)
        with pytest.raises(ValueError, match="threads must be None"):
            tex.integrate(inside[:2], threads=bad)


def test_bow_ties_and_huge_coordinates_are_value_errors(random_texels):
    tex = quadtex.pack(random_texels)
    bow = np.array([[[0.0, 0.0], [1.0, 0.0], [0.0, 1.0], [1.0, 1.0]]])
    with pytest.raises(ValueError, match=r"quads\[0\].*bow tie"):
        tex.filter(bow)
    huge = np.array([[[0.0, 0.0], [1e20, 0.0], [1e20, 1.0], [0.0, 1.0]]])
    with pytest.raises(ValueError, match="MAX_TEXTURE_COORDINATE"):
        tex.filter(huge)
    # Up to 1e15 the mean of a huge footprint is the texture's mean.
    big = np.array([[[-1e15, -1e15], [1e15, -1e15], [1e15, 1e15], [-1e15, 1e15]]])
    got, bound = tex.filter(big, return_bound=True)
    mean = tex.integrate(np.array([[0.0, 0.0, 1.0, 1.0]]))
    assert np.abs(got - mean).max() <= bound[0] + 1e-4


def test_wrap_modes(random_texels):
    tex = quadtex.pack(random_texels)
    inside = rect_quads([[0.1, 0.2, 0.3, 0.25]])
    out_x = inside + [[1.0, 0.0]]
    # Repeat: a shift by a whole tile changes nothing.
    np.testing.assert_allclose(tex.filter(out_x), tex.filter(inside), atol=1e-6)
    # Mirror: [1, 2) is [0, 1) reflected in x.
    mirrored = rect_quads([[2 - 0.3, 0.2, 2 - 0.1, 0.25]])
    np.testing.assert_allclose(
        tex.filter(mirrored, wrap="mirror"), tex.filter(inside, wrap="mirror"), atol=1e-6
    )
    # Border: outside the unit square on a border axis, the border colour.
    border = (0.1, 0.2, 0.3, 0.4)
    got = tex.filter(out_x, wrap=("border", "repeat"), border=border)
    np.testing.assert_allclose(got[0], border, atol=1e-7)
    got = tex.filter(out_x, wrap=("border", "repeat"), border=np.array(border, np.float32))
    np.testing.assert_allclose(got[0], border, atol=1e-7)
    got = tex.filter(out_x, wrap=["repeat", "border"], border=border)
    np.testing.assert_allclose(got, tex.filter(inside), atol=1e-6)
    # Clamp: left of the texture, its left column stretched.
    left = rect_quads([[-3.0, 0.0, -2.0, 1.0]])
    col = random_texels[:, 0, :].mean(axis=0)
    np.testing.assert_allclose(tex.filter(left, wrap="clamp", level=tex.depth)[0, :3], col, atol=1e-5)


def test_non_contiguous_inputs_give_the_same_result(random_texels, rng):
    tex = quadtex.pack(random_texels)
    n = 256
    p0 = rng.uniform(0, 1, size=(n, 2))
    quads = np.stack([p0, p0 + [0.05, 0.01], p0 + [0.07, 0.08], p0 + [0.01, 0.06]], axis=1)
    want = tex.filter(quads)
    big = np.zeros((2 * n, 4, 2))
    big[::2] = quads
    strided = big[::2]
    assert not strided.flags.c_contiguous
    fortran = np.asfortranarray(quads)
    transposed = np.ascontiguousarray(quads.transpose(2, 1, 0)).transpose(2, 1, 0)
    assert not transposed.flags.c_contiguous
    swapped = quads.astype(">f8")
    for variant in (strided, fortran, transposed, swapped, quads.tolist()):
        np.testing.assert_array_equal(tex.filter(variant), want)
    # Other real dtypes are converted to float64.
    f32 = quads.astype(np.float32)
    np.testing.assert_array_equal(tex.filter(f32), tex.filter(f32.astype(np.float64)))
    ints = np.array([[[0, 0], [1, 0], [1, 1], [0, 1]]], dtype=np.int32)
    np.testing.assert_array_equal(tex.filter(ints), tex.filter(ints.astype(float)))
    # Rectangles likewise.
    rects = random_rects(rng, 64)
    wide = np.zeros((64, 8))
    wide[:, ::2] = rects
    np.testing.assert_array_equal(tex.integrate(wide[:, ::2]), tex.integrate(rects))


def test_empty_batches(random_texels):
    tex = quadtex.pack(random_texels)
    assert tex.filter(np.empty((0, 4, 2))).shape == (0, 4)
    assert tex.integrate(np.empty((0, 4))).shape == (0, 4)


def test_batches_release_the_gil(random_texels, rng):
    tex = quadtex.pack(random_texels)
    n = 200_000
    p0 = rng.uniform(0, 1, size=(n, 2))
    quads = np.stack([p0, p0 + [0.3, 0.01], p0 + [0.32, 0.2], p0 + [0.01, 0.19]], axis=1)
    state = {"inside": False, "done": False}

    def work():
        state["inside"] = True
        state["start"] = time.perf_counter()
        tex.filter(quads)
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
    # With the GIL held for the whole call, this thread would be frozen for
    # all of it; released, it runs for (nearly) all of it.
    assert call > 0.02, call
    during = [t for t in ticks if state["start"] <= t <= state["end"]]
    assert during and during[-1] - during[0] > 0.5 * call, (call, len(during))
