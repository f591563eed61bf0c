//! Screen cells: the unit squares between four pixel centres. On each, the
//! tent and Mitchell filters are one polynomial piece for every pixel whose
//! support covers it, so a cell's integrals, computed once, give each of
//! those pixels its part ([`CellIntegral`]): a tent pixel's support is
//! 2 × 2 cells and each cell serves 4 pixels, a Mitchell pixel's 4 × 4
//! and 16. The weights are not fewer so (each piece of the texture needs
//! one for each pixel whose support it lies in); what the pixels share is
//! the cutting of the texture's cells by the screen cell, and their
//! mapping to the screen, done once instead of 4 or 16 times.
//!
//! The convention (which cell, which pixel) is [`CellIntegral`]'s.

use std::ops::{Add, Mul, Neg, Sub};
use std::sync::OnceLock;

use crate::filter::options::{FilterOptions, FilterStats, LevelOfDetail};
use crate::filter::pixel_filter::{GAUSS2, PixelFilter, at, integrated};
use crate::filter::projection::{Projection, apply};
use crate::filter::region::{MAX_SCREEN_COORDINATE, horizon_floor};
use crate::filter::scan::{EdgeTerms, FlatGrid, Grid, SCAN_CELLS, scan_bands};
use crate::filter::wrap::{Wrap, uniform_colour_in};
use crate::geometry::polygon::{ConvexPolygon, GAUSS4};
use crate::tree::QuadTree;

/// Most pixels sharing a screen cell, `(2r)²` for Mitchell's `r = 2`.
const MOST_SHARING: usize = 16;

/// The integrals over one screen cell of the texture weighted by the
/// filter of each pixel sharing the cell, and of the filter alone: each
/// pixel's part of its [`Texture::integrate_region`] over its whole
/// support, exactly as that computes it up to rounding.
///
/// A screen cell is a unit square between four pixel centres. Pixel
/// `(x, y)` has its centre at `(x + ½, y + ½)`; screen cell `(i, j)` is
/// `[i + ½, i + 3⁄2] × [j + ½, j + 3⁄2]`. Under a filter of radius `r` (1
/// for the tent, 2 for Mitchell), pixel `x` covers cells `x − r ..= x + r
/// − 1`, and cell `i` lies in the supports of pixels `i − r + 1 ..= i +
/// r`: pixel `i − r + 1 + p` is the cell's `p`-th (`p < 2r`), on each
/// axis alike. On a cell each pixel's filter is one polynomial piece.
///
/// [`Texture::integrate_region`]: crate::Texture::integrate_region
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CellIntegral {
    /// Per channel, per sharing pixel (`q·side + p`): `∫ colour · k`.
    colour: [[f64; MOST_SHARING]; 4],
    /// Per sharing pixel: `∫ k`.
    weight: [f64; MOST_SHARING],
    /// Pixels sharing the cell a side: `2r`.
    side: usize,
}

impl CellIntegral {
    /// The `(∫ colour·k, ∫ k)` of the cell's `p`-th pixel across and
    /// `q`-th down (pixel `(i − r + 1 + p, j − r + 1 + q)` of cell `(i,
    /// j)`); `None` past the pixels sharing the cell.
    pub fn part(&self, p: usize, q: usize) -> Option<([f64; 4], f64)> {
        if p >= self.side || q >= self.side {
            return None;
        }
        let k = q * self.side + p;
        Some((self.colour.map(|c| c[k]), self.weight[k]))
    }
}

/// Weights, one for each pixel sharing a screen cell, added piece by
/// piece.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct Weights<const N: usize>([f64; N]);

impl<const N: usize> Default for Weights<N> {
    fn default() -> Self {
        Weights([0.0; N])
    }
}

impl<const N: usize> Weights<N> {
    /// `f` of the two weights of each pixel.
    #[inline(always)]
    fn zip_with(mut self, other: Self, f: impl Fn(f64, f64) -> f64) -> Self {
        for (a, b) in self.0.iter_mut().zip(other.0) {
            *a = f(*a, b);
        }
        self
    }
}

impl<const N: usize> Add for Weights<N> {
    type Output = Self;
    #[inline(always)]
    fn add(self, other: Self) -> Self {
        self.zip_with(other, |a, b| a + b)
    }
}

impl<const N: usize> Sub for Weights<N> {
    type Output = Self;
    #[inline(always)]
    fn sub(self, other: Self) -> Self {
        self.zip_with(other, |a, b| a - b)
    }
}

impl<const N: usize> Neg for Weights<N> {
    type Output = Self;
    #[inline(always)]
    fn neg(self) -> Self {
        Weights(self.0.map(|a| -a))
    }
}

impl<const N: usize> Mul<f64> for Weights<N> {
    type Output = Self;
    #[inline(always)]
    fn mul(self, s: f64) -> Self {
        Weights(self.0.map(|a| a * s))
    }
}

/// The filter of each of the `SIDE × SIDE` pixels sharing a screen cell
/// (`N = SIDE²`), in the cell's own coordinates `(u, v) = s − (i + ½, j +
/// ½)`, `u, v ∈ [0, 1]`: pixel column `p`'s filter is one piece `k_p(u)`
/// over the whole cell, `F_p(u) = ∫₀ᵘ k_p` (a polynomial in `u` of degree
/// `SIDE`, no constant term), and likewise `k_q(v)` for pixel row `q` (of
/// degree `SIDE − 1`). The pair `(p, q)`'s Green's-theorem term of an
/// edge is `∫ F_p(u)·k_q(v) dv`. A scan adds up, instead, the edge terms
/// of the monomials, the moments `∫ u^(a+1)·v^b dv` for `a, b < SIDE`
/// (cheaper at each Gauss point than the pixels' polynomials), and
/// [`CellKernel::pixel_weights`] turns their sums into the pixels' weights
/// once a cell: the terms are linear in the monomials. No edge is split.
#[derive(Debug, Clone, Copy)]
pub(super) struct CellKernel<const N: usize, const SIDE: usize> {
    /// `F_p(u) = Σ_a big[p][a]·u^(a+1)`.
    big: [[f64; SIDE]; SIDE],
    /// `k_q(v) = Σ_b small[q][b]·v^b`.
    small: [[f64; SIDE]; SIDE],
    /// Per pixel: `F_p(1)`, its filter's integral across the cell.
    across: [f64; SIDE],
}

impl<const N: usize, const SIDE: usize> CellKernel<N, SIDE> {
    /// The kernel of the tent (`SIDE` 2) or Mitchell's filter (`SIDE` 4).
    fn new() -> Self {
        let filter = if SIDE == 2 {
            PixelFilter::Tent
        } else {
            PixelFilter::Mitchell
        };
        let r = filter.radius() as i32;
        let binomial = |n: usize, k: usize| -> f64 {
            (0..k).fold(1.0, |c, j| c * (n - j) as f64 / (j + 1) as f64)
        };
        let mut kernel = CellKernel {
            big: [[0.0; SIDE]; SIDE],
            small: [[0.0; SIDE]; SIDE],
            across: [0.0; SIDE],
        };
        for p in 0..SIDE {
            // Pixel `p`'s filter cell: `k_p(u) = k₁(u + i)`.
            let i = r - 1 - p as i32;
            let shift = f64::from(i);
            let piece = filter.cubic(i);
            // `A(x) = Σ_k a_k·x^(k+1)`, `F_p(u) = A(u + i) − A(i)`: the
            // binomial expansion's terms in `u^m`, `m ≥ 1`.
            let running = integrated(piece);
            for m in 1..=SIDE {
                kernel.big[p][m - 1] = (0..4)
                    .filter(|&k| k + 1 >= m)
                    .map(|k| running[k] * binomial(k + 1, m) * shift.powi((k + 1 - m) as i32))
                    .sum();
            }
            for m in 0..SIDE {
                kernel.small[p][m] = (m..4)
                    .map(|k| piece[k] * binomial(k, m) * shift.powi((k - m) as i32))
                    .sum();
            }
            kernel.across[p] = at(&running, shift + 1.0) - at(&running, shift);
        }
        kernel
    }

    /// The weights of the whole cell: `∫∫ k_p(u)·k_q(v)`, the product of
    /// the two integrals across it.
    fn whole(&self) -> Weights<N> {
        let mut out = [0.0; N];
        for q in 0..SIDE {
            for p in 0..SIDE {
                out[q * SIDE + p] = self.across[q] * self.across[p];
            }
        }
        Weights(out)
    }

    /// The pixels' weights (`q·SIDE + p`) from the monomials' moments
    /// (`b·SIDE + a`, see the type): `Σ_(a,b) big[p][a]·small[q][b]·m[b][a]`.
    fn pixel_weights(&self, moments: &[f64; N]) -> [f64; N] {
        // `t[q][a] = Σ_b small[q][b]·m[b][a]`, then against `big[p]`.
        let mut t = [[0.0; SIDE]; SIDE];
        for (q, row) in t.iter_mut().enumerate() {
            for (a, v) in row.iter_mut().enumerate() {
                *v = (0..SIDE)
                    .map(|b| self.small[q][b] * moments[b * SIDE + a])
                    .sum();
            }
        }
        let mut out = [0.0; N];
        for q in 0..SIDE {
            for p in 0..SIDE {
                out[q * SIDE + p] = (0..SIDE).map(|a| self.big[p][a] * t[q][a]).sum();
            }
        }
        out
    }
}

impl<const N: usize, const SIDE: usize> EdgeTerms for CellKernel<N, SIDE> {
    type Weight = Weights<N>;

    /// The monomials' terms (see the type), `(b, a)` at `b·SIDE + a`.
    #[inline(always)]
    fn edge(&self, a: [f64; 2], b: [f64; 2]) -> Weights<N> {
        let dy = b[1] - a[1];
        let mut out = [0.0; N];
        if dy == 0.0 {
            return Weights(out);
        }
        // `u^(a+1)·v^b` along a line: degree at most 2 + 1 for the tent
        // (2 points), 4 + 3 for Mitchell (4 points).
        let points: &[(f64, f64)] = if SIDE == 2 { &GAUSS2 } else { &GAUSS4 };
        for &(t, w) in points {
            let (u, v) = (a[0] + t * (b[0] - a[0]), a[1] + t * dy);
            let (mut big, mut small) = ([0.0; SIDE], [0.0; SIDE]);
            let (mut up, mut vp) = (u, w);
            for k in 0..SIDE {
                big[k] = up;
                small[k] = vp;
                up *= u;
                vp *= v;
            }
            for (b, s) in small.iter().enumerate() {
                for (a, g) in big.iter().enumerate() {
                    out[b * SIDE + a] += s * g;
                }
            }
        }
        Weights(out.map(|o| o * dy))
    }
}

/// What one screen cell's integral is asked: the texture (its tree and
/// wrap), the map from the screen, the pixel filter and the options.
pub(crate) struct CellQuery<'a> {
    pub(crate) tree: &'a QuadTree,
    pub(crate) wrap: Wrap,
    pub(crate) projection: &'a Projection,
    pub(crate) filter: PixelFilter,
    pub(crate) options: &'a FilterOptions,
}

/// The tent's and Mitchell's cell kernels, expanded once (not per cell).
static TENT: OnceLock<CellKernel<4, 2>> = OnceLock::new();
static MITCHELL: OnceLock<CellKernel<16, 4>> = OnceLock::new();

/// [`crate::Texture::integrate_screen_cell`].
pub(crate) fn integrate_screen_cell(
    query: &CellQuery<'_>,
    cell: [i64; 2],
    stats: &mut FilterStats,
) -> Option<CellIntegral> {
    match query.filter {
        PixelFilter::Box => None,
        PixelFilter::Tent => cell_integral(query, cell, TENT.get_or_init(CellKernel::new), stats),
        PixelFilter::Mitchell => {
            cell_integral(query, cell, MITCHELL.get_or_init(CellKernel::new), stats)
        }
    }
}

/// The cell's integral under `kernel` (the query's filter's).
fn cell_integral<const N: usize, const SIDE: usize>(
    query: &CellQuery<'_>,
    cell: [i64; 2],
    kernel: &CellKernel<N, SIDE>,
    stats: &mut FilterStats,
) -> Option<CellIntegral> {
    let CellQuery {
        tree,
        wrap,
        projection,
        filter,
        options,
    } = *query;
    // The walk's adaptive bound and a fixed level are per region: the
    // cells take only what they integrate exactly.
    if matches!(options.level_of_detail(), LevelOfDetail::Fixed(_)) {
        return None;
    }
    let origin = [cell[0] as f64 + 0.5, cell[1] as f64 + 0.5];
    if !(origin[0].abs() < MAX_SCREEN_COORDINATE && origin[1].abs() < MAX_SCREEN_COORDINATE) {
        return None;
    }
    let corners = [
        origin,
        [origin[0] + 1.0, origin[1]],
        [origin[0] + 1.0, origin[1] + 1.0],
        [origin[0], origin[1] + 1.0],
    ];
    // Where a pixel's support would keep its every vertex in front of
    // the horizon's sliver (every support is the same size), so would
    // the cells it is made of, and the support's vertices are theirs.
    let floor = horizon_floor(projection, &filter.support(origin), options);
    let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
    let mut texture = [[0.0; 2]; 4];
    for (s, t) in corners.iter().zip(texture.iter_mut()) {
        let w = projection.w(*s);
        if w.is_nan() || w < floor.max(f64::MIN_POSITIVE) {
            return None;
        }
        *t = apply(&projection.texture_from_screen, *s);
        if !(t[0].is_finite() && t[1].is_finite()) {
            return None;
        }
        for a in 0..2 {
            lo[a] = lo[a].min(t[a]);
            hi[a] = hi[a].max(t[a]);
        }
    }
    let mut out = CellIntegral {
        colour: [[0.0; MOST_SHARING]; 4],
        weight: [0.0; MOST_SHARING],
        side: SIDE,
    };
    let mut add = |colour: [f64; 4], w: Weights<N>| {
        for (sum, c) in out.colour.iter_mut().zip(colour) {
            for (s, w) in sum.iter_mut().zip(w.0) {
                *s += c * w;
            }
        }
        for (s, w) in out.weight.iter_mut().zip(w.0) {
            *s += w;
        }
    };
    // A shallow repeated texture's cells are scanned even where the
    // image is one colour: its grid holds the exact means (the tree's
    // colours are `f32`), the same a support's scan takes.
    if let Some(grid) = FlatGrid::over(tree, wrap, (lo, hi)) {
        let h = grid.side();
        let (x, z) = ((lo[0] / h).floor(), (lo[1] / h).floor());
        if (hi[0] / h).ceil() - x <= 1.0 && (hi[1] / h).ceil() - z <= 1.0 {
            // The image within one of the grid's cells: its colour times
            // the whole cell's weights (what the scan's one cell gives).
            add(grid.colour(x as i64, z as i64)?, kernel.whole());
            stats.traversal.nodes_visited += 1;
            return Some(out);
        }
        let region = ConvexPolygon::from_trusted(&texture);
        let grid_of_cells = Grid {
            m: &projection.screen_from_texture,
            h: grid.side(),
            centre: origin,
        };
        // The scan's sums are the monomials' moments: turned into the
        // pixels' weights once, at the end.
        let (mut colour_moments, mut weight_moments) = ([[0.0; N]; 4], [0.0; N]);
        let cells = scan_bands(
            &region,
            &grid_of_cells,
            kernel,
            SCAN_CELLS,
            &mut |x, z| grid.colour(x, z),
            &mut |colour: [f64; 4], w: Weights<N>| {
                for (sum, c) in colour_moments.iter_mut().zip(colour) {
                    for (s, w) in sum.iter_mut().zip(w.0) {
                        *s += c * w;
                    }
                }
                for (s, w) in weight_moments.iter_mut().zip(w.0) {
                    *s += w;
                }
            },
        )?;
        stats.traversal.nodes_visited += cells as u64;
        for (sum, moments) in out.colour.iter_mut().zip(&colour_moments) {
            sum[..N].copy_from_slice(&kernel.pixel_weights(moments));
        }
        out.weight[..N].copy_from_slice(&kernel.pixel_weights(&weight_moments));
    } else {
        // The whole cell at one colour: the cell's weights, its four
        // sides' terms.
        let c = uniform_colour_in(tree, lo, hi, wrap)?;
        add(c.to_array().map(f64::from), kernel.whole());
    }
    let finite = out.weight.iter().all(|w| w.is_finite())
        && out.colour.iter().flatten().all(|c| c.is_finite());
    finite.then_some(out)
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;
    use crate::{BuildOptions, Rgba, TexelGrid, Texture};

    /// A shallow repeated texture whose colour depends on both
    /// coordinates (8 × 8 texels: a flat grid of depth 3).
    fn ramp() -> Texture {
        let g = TexelGrid::from_fn(8, 8, |c, r| {
            Rgba::opaque(c as f32 / 7.0, r as f32 / 7.0, ((c * r) % 5) as f32 / 4.0)
        })
        .unwrap();
        let tree = QuadTree::from_texels(&g, &BuildOptions::default())
            .unwrap()
            .0;
        assert!(tree.flat_grid().is_some());
        Texture::new(tree, Wrap::REPEAT)
    }

    /// A pixel's parts of the screen cells its support covers, summed,
    /// are what integrating its whole support gives (the scan, exact:
    /// its bound is zero; or the one texel's colour), for the tent and Mitchell under random
    /// perspective, from magnified (a texel over many pixels) to
    /// minified (hundreds of texels a support), and pixels at negative
    /// coordinates.
    #[test]
    fn a_pixels_cells_sum_to_its_support() {
        let texture = ramp();
        let options = FilterOptions::default();
        let mut next = crate::test_rng::uniform(53);
        let (mut checked, mut one_cell, mut scanned) = ([0; 2], 0, 0);
        for case in 0..600 {
            let filter = [PixelFilter::Tent, PixelFilter::Mitchell][case % 2];
            let scale = [0.005, 0.05, 0.15, 0.3][case % 4] * (0.5 + next());
            let g = 0.002 * (next() - 0.5);
            let projection = Projection::new([
                [scale * (0.5 + next()), scale * (next() - 0.5), next() * 3.0],
                [scale * (next() - 0.5), scale * (0.5 + next()), next() * 3.0],
                [g, 0.002 * (next() - 0.5), 1.0],
            ])
            .unwrap();
            let (x, y) = (
                (next() * 100.0 - 50.0).floor() as i64,
                (next() * 100.0 - 50.0).floor() as i64,
            );
            let centre = [x as f64 + 0.5, y as f64 + 0.5];
            let mut stats = FilterStats::default();
            let whole = texture.integrate_region(
                &projection,
                &filter.support(centre),
                filter,
                centre,
                &options,
                &mut stats,
            );
            assert_eq!(whole.error_bound, 0.0, "case {case}: not the exact scan");
            let r = filter.radius() as i64;
            let (mut colour, mut weight) = ([0.0; 4], 0.0);
            for j in y - r..y + r {
                for i in x - r..x + r {
                    let before = stats.traversal.nodes_visited;
                    let cell = texture
                        .integrate_screen_cell(&projection, [i, j], filter, &options, &mut stats)
                        .unwrap();
                    if stats.traversal.nodes_visited == before + 1 {
                        one_cell += 1;
                    } else {
                        scanned += 1;
                    }
                    let (p, q) = ((x - (i - r + 1)) as usize, (y - (j - r + 1)) as usize);
                    let (c, w) = cell.part(p, q).unwrap();
                    for (s, c) in colour.iter_mut().zip(c) {
                        *s += c;
                    }
                    weight += w;
                }
            }
            // Where the support's image lies in one texel, the reference
            // takes the tree's colour (`f32`), the cells the grid's exact
            // mean (`f64`): half an `f32` step apart.
            let tolerance =
                1e-11 * (1.0 + stats.traversal.nodes_visited as f64) + 6e-8 * whole.weight.abs();
            assert!(
                (weight - whole.weight).abs() <= tolerance,
                "case {case}, {filter:?}: weight {weight} against {}",
                whole.weight
            );
            for (c, (a, b)) in colour.iter().zip(whole.colour.0).enumerate() {
                assert!(
                    (a - b).abs() <= tolerance,
                    "case {case}, {filter:?}: channel {c}: {a} against {b}"
                );
            }
            checked[case % 2] += 1;
        }
        assert!(
            checked == [300, 300] && one_cell > 500 && scanned > 2000,
            "{checked:?}, {one_cell} in one texture cell, {scanned} across more"
        );
    }

    /// The kernel's polynomials in the cell's coordinates are the
    /// filter's: `k_q(v)` is `k₁` at the pixel's offset, `F_p(u)` its
    /// integral from the cell's side (a dense midpoint sum), and the
    /// whole cell's weights are the products of the integrals across.
    #[test]
    fn the_cells_polynomials_are_the_filters() {
        fn check<const N: usize, const SIDE: usize>(filter: PixelFilter) {
            let kernel = CellKernel::<N, SIDE>::new();
            let r = filter.radius();
            for p in 0..SIDE {
                let offset = r - 1.0 - p as f64;
                for step in 0..=20 {
                    let u = f64::from(step) / 20.0;
                    let small: f64 = (0..SIDE)
                        .map(|b| kernel.small[p][b] * u.powi(b as i32))
                        .sum();
                    let k = filter.k1(u + offset);
                    assert!(
                        (small - k).abs() < 1e-12,
                        "{filter:?} k_{p}({u}): {small} against {k}"
                    );
                    let big: f64 = (0..SIDE)
                        .map(|a| kernel.big[p][a] * u.powi(a as i32 + 1))
                        .sum();
                    let n = 2000;
                    let dense: f64 = (0..n)
                        .map(|i| filter.k1((f64::from(i) + 0.5) / f64::from(n) * u + offset))
                        .sum::<f64>()
                        * u
                        / f64::from(n);
                    assert!(
                        (big - dense).abs() < 1e-6,
                        "{filter:?} F_{p}({u}): {big} against {dense}"
                    );
                }
            }
            let whole = kernel.whole();
            assert!(
                (whole.0.iter().sum::<f64>() - 1.0).abs() < 1e-12,
                "{filter:?}: {whole:?}"
            );
        }
        check::<4, 2>(PixelFilter::Tent);
        check::<16, 4>(PixelFilter::Mitchell);
    }

    /// No cell under the box, under a fixed level, or nearer the horizon
    /// than a support is taken as it is; no part past the sharing pixels.
    #[test]
    fn cells_it_does_not_take() {
        let texture = ramp();
        let options = FilterOptions::default();
        let mut stats = FilterStats::default();
        // w = 1 − y/100: the horizon at y = 100.
        let projection =
            Projection::new([[0.1, 0.0, 0.0], [0.0, 0.1, 0.0], [0.0, -0.01, 1.0]]).unwrap();
        let cell = |c: [i64; 2], filter, options: &FilterOptions, stats: &mut FilterStats| {
            texture.integrate_screen_cell(&projection, c, filter, options, stats)
        };
        let tent = cell([3, 4], PixelFilter::Tent, &options, &mut stats).unwrap();
        assert!(tent.part(1, 1).is_some() && tent.part(2, 0).is_none());
        assert!(cell([3, 4], PixelFilter::Box, &options, &mut stats).is_none());
        let fixed = FilterOptions::new().with_level(3);
        assert!(cell([3, 4], PixelFilter::Tent, &fixed, &mut stats).is_none());
        assert!(cell([3, 99], PixelFilter::Mitchell, &options, &mut stats).is_none());
        assert!(cell([3, 120], PixelFilter::Mitchell, &options, &mut stats).is_none());
    }
}
