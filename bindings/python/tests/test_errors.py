"""Bad input raises ValueError / TypeError naming the index, field or shape."""

import numpy as np
import pytest

import quadtex

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
    for quality in (0.5, float("nan"), float("inf")):
        with pytest.raises(ValueError, match="quality must be a finite number >= 1, got"):
            tex.filter(q, quality=quality)
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
