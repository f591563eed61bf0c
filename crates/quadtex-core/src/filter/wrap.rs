//! Texture space beyond the unit square: one wrap mode per axis, and the
//! exact integral of a wrapped texture over a fragment.
//!
//! A fragment in the plane is cut, axis by axis, into pieces that each lie
//! in one tile's `[0,1)`; every `x` piece is paired with every `z` piece.
//! Whole tiles are counted by multiplicity, not visited one by one, so the
//! cost of a query does not depend on how many tiles it covers.

use crate::Error;
use crate::baseline::SummedAreaTable;
use crate::colour::{Rgba, WeightedColour};
use crate::geometry::fragment::Fragment;
use crate::tree::{QuadTree, TraversalStats};

/// How one axis of texture space continues beyond `[0,1)`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub enum WrapMode {
    /// Tiles repeat forever: the texture at `x` is the texture at `x − ⌊x⌋`.
    #[default]
    Repeat,
    /// The edge extends outwards: beyond an edge, the texture is the
    /// texture's outermost finest cell along that edge, stretched.
    Clamp,
    /// Tiles repeat reflected: `[1,2)` is `[0,1)` mirrored, period 2.
    Mirror,
    /// Beyond the unit square the texture is the [`Wrap`]'s border colour.
    Border,
}

impl WrapMode {
    /// The mode's name as scene files and the bindings spell it.
    pub fn name(self) -> &'static str {
        match self {
            WrapMode::Repeat => "repeat",
            WrapMode::Clamp => "clamp",
            WrapMode::Mirror => "mirror",
            WrapMode::Border => "border",
        }
    }

    /// The mode named `name` (`repeat`, `clamp`, `mirror`, `border`).
    pub fn from_name(name: &str) -> Option<WrapMode> {
        match name {
            "repeat" => Some(WrapMode::Repeat),
            "clamp" => Some(WrapMode::Clamp),
            "mirror" => Some(WrapMode::Mirror),
            "border" => Some(WrapMode::Border),
            _ => None,
        }
    }

    /// The cell index `i` of an axis of `n` cells folded into `0..n`, or
    /// `None` where [`WrapMode::Border`] shows the border colour.
    pub fn fold_index(self, i: i64, n: i64) -> Option<i64> {
        match self {
            WrapMode::Repeat => Some(i.rem_euclid(n)),
            WrapMode::Clamp => Some(i.clamp(0, n - 1)),
            WrapMode::Mirror => {
                let m = i.rem_euclid(2 * n);
                Some(if m >= n { 2 * n - 1 - m } else { m })
            }
            WrapMode::Border => (0..n).contains(&i).then_some(i),
        }
    }

    /// The coordinate `v` folded into `[0,1)`, or `None` in the border.
    pub fn fold(self, v: f64) -> Option<f64> {
        match self {
            WrapMode::Repeat => Some(v - v.floor()),
            WrapMode::Clamp => Some(v.clamp(0.0, f64::from_bits(1.0f64.to_bits() - 1))),
            WrapMode::Mirror => {
                let tile = v.floor();
                let local = v - tile;
                Some(if tile.rem_euclid(2.0) == 1.0 {
                    (1.0 - local).min(f64::from_bits(1.0f64.to_bits() - 1))
                } else {
                    local
                })
            }
            WrapMode::Border => (0.0..1.0).contains(&v).then_some(v),
        }
    }
}

/// How a texture continues beyond the unit square: a [`WrapMode`] for each
/// axis (`x`, `z`) and the colour [`WrapMode::Border`] shows (linear,
/// premultiplied; transparent unless set, always finite: [`Wrap::new`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Wrap {
    x: WrapMode,
    z: WrapMode,
    border: Rgba,
}

impl Default for Wrap {
    fn default() -> Self {
        Wrap::REPEAT
    }
}

impl Wrap {
    /// Both axes repeat.
    pub const REPEAT: Wrap = Wrap::uniform(WrapMode::Repeat);
    /// Both axes clamp.
    pub const CLAMP: Wrap = Wrap::uniform(WrapMode::Clamp);
    /// Both axes mirror.
    pub const MIRROR: Wrap = Wrap::uniform(WrapMode::Mirror);

    /// The same mode on both axes, transparent border.
    pub const fn uniform(mode: WrapMode) -> Wrap {
        Wrap::per_axis(mode, mode)
    }

    /// Mode `x` along `x` and `z` along `z`, transparent border.
    pub const fn per_axis(x: WrapMode, z: WrapMode) -> Wrap {
        Wrap {
            x,
            z,
            border: Rgba::TRANSPARENT,
        }
    }

    /// Mode `x` along `x`, `z` along `z`, and the colour outside the unit
    /// square on a [`WrapMode::Border`] axis; an error names a channel of
    /// `border` that is not finite (it would make every filtered colour
    /// and bound that meets it NaN).
    pub fn new(x: WrapMode, z: WrapMode, border: Rgba) -> Result<Wrap, Error> {
        const CHANNELS: [&str; 4] = ["border.r", "border.g", "border.b", "border.a"];
        if let Some((name, value)) = CHANNELS
            .into_iter()
            .zip(border.to_array())
            .find(|(_, v)| !v.is_finite())
        {
            return Err(Error::BadOption {
                name,
                value: f64::from(value),
                expected: "a finite colour channel",
            });
        }
        Ok(Wrap { x, z, border })
    }

    /// Outside the unit square, `colour` on both axes ([`Wrap::new`]).
    pub fn border(colour: Rgba) -> Result<Wrap, Error> {
        Wrap::new(WrapMode::Border, WrapMode::Border, colour)
    }

    /// The mode along `x`.
    pub const fn x(&self) -> WrapMode {
        self.x
    }

    /// The mode along `z`.
    pub const fn z(&self) -> WrapMode {
        self.z
    }

    /// The colour outside the unit square on a [`WrapMode::Border`] axis.
    pub const fn border_colour(&self) -> Rgba {
        self.border
    }

    /// The texture point shown at `p`: `Some` point of `[0,1)²`, or `None`
    /// where the border colour shows.
    pub fn fold(&self, p: [f64; 2]) -> Option<[f64; 2]> {
        Some([self.x.fold(p[0])?, self.z.fold(p[1])?])
    }
}

/// An exact box filter over one tile of texture space: the quadtree, or a
/// baseline integrating the same fragments (the summed-area table).
pub trait BoxIntegral {
    /// Integral over the fragment's overlap with the unit square, with the
    /// traversal limited to level `k` where that means something.
    fn box_integral(&self, f: &Fragment, k: u8, stats: &mut TraversalStats) -> WeightedColour;
    /// Integral over the whole unit square.
    fn whole_tile(&self) -> WeightedColour;
    /// Width and height of the finest cell in texture units (the edge strip
    /// [`WrapMode::Clamp`] reads).
    fn finest_cell(&self) -> [f64; 2];
    /// The level of the finest cell: what a level-of-detail rule is capped
    /// by. A level-`k` cell is `finest_cell · 2^(finest_level − k)`.
    fn finest_level(&self) -> u8;
}

impl BoxIntegral for QuadTree {
    fn box_integral(&self, f: &Fragment, k: u8, stats: &mut TraversalStats) -> WeightedColour {
        self.weighted_colour_counted(f, k, stats)
    }
    fn whole_tile(&self) -> WeightedColour {
        WeightedColour(self.mean_colour())
    }
    fn finest_cell(&self) -> [f64; 2] {
        self.finest_cell_size()
    }
    fn finest_level(&self) -> u8 {
        self.depth()
    }
}

impl BoxIntegral for SummedAreaTable {
    fn box_integral(&self, f: &Fragment, _k: u8, stats: &mut TraversalStats) -> WeightedColour {
        stats.queries += 1;
        self.weighted_colour(f)
    }
    fn whole_tile(&self) -> WeightedColour {
        Fragment::new(0.0, 0.0, 1.0, 1.0).map_or(WeightedColour::ZERO, |f| self.weighted_colour(&f))
    }
    fn finest_cell(&self) -> [f64; 2] {
        [1.0 / self.width() as f64, 1.0 / self.height() as f64]
    }
    fn finest_level(&self) -> u8 {
        (self.width().max(self.height()) as f64)
            .log2()
            .ceil()
            .clamp(0.0, 255.0) as u8
    }
}

/// One piece of an axis interval: `[lo, hi) ⊆ [0,1]` in one tile's local
/// coordinate, counted `weight` times (whole tiles repeat; clamp stretches).
type Piece = (f64, f64, f64);

/// An axis interval `[a, b)` cut by a wrap mode: at most three pieces that
/// read the texture, and the length that shows the border colour.
struct AxisCut {
    pieces: [Option<Piece>; 3],
    border_length: f64,
}

impl AxisCut {
    #[inline(always)]
    fn new(mode: WrapMode, a: f64, b: f64, edge: f64) -> AxisCut {
        let (pieces, border_length) = match mode {
            WrapMode::Repeat => (split_repeat(a, b), 0.0),
            WrapMode::Mirror => (split_mirror(a, b), 0.0),
            WrapMode::Clamp => (split_clamp(a, b, edge), 0.0),
            WrapMode::Border => {
                let (lo, hi) = (a.max(0.0), b.min(1.0));
                if hi > lo {
                    ([Some((lo, hi, 1.0)), None, None], (b - a) - (hi - lo))
                } else {
                    ([None, None, None], b - a)
                }
            }
        };
        AxisCut {
            pieces,
            border_length,
        }
    }

    /// Length of `[a, b)` that reads the texture.
    #[inline]
    fn texture_length(&self) -> f64 {
        self.pieces
            .iter()
            .flatten()
            .map(|&(lo, hi, w)| (hi - lo) * w)
            .sum()
    }
}

/// The integral of the texture `source`, continued beyond the unit square by
/// `wrap`, over the fragment `f` (which may span any number of tiles), with
/// the traversal limited to level `k`.
///
/// Exact up to the source's own rounding: every piece is an exact box
/// integral, whole tiles count `n` times the tile's integral, and the
/// border's share is its exact area times the border colour. With
/// [`WrapMode::Repeat`] or [`WrapMode::Mirror`] on both axes the cost is at
/// most nine box queries, whatever the number of tiles.
#[inline]
pub fn integrate_wrapped<T: BoxIntegral + ?Sized>(
    source: &T,
    f: &Fragment,
    k: u8,
    wrap: Wrap,
    stats: &mut TraversalStats,
) -> WeightedColour {
    let [edge_x, edge_z] = source.finest_cell();
    let xs = AxisCut::new(wrap.x(), f.x0(), f.x1(), edge_x);
    let zs = AxisCut::new(wrap.z(), f.z0(), f.z1(), edge_z);
    let mut acc = WeightedColour::ZERO;
    for &(xa, xb, wx) in xs.pieces.iter().flatten() {
        for &(za, zb, wz) in zs.pieces.iter().flatten() {
            let count = wx * wz;
            if count == 0.0 {
                continue;
            }
            let whole = xa == 0.0 && xb == 1.0 && za == 0.0 && zb == 1.0;
            let piece = if whole {
                stats.queries += 1;
                source.whole_tile()
            } else {
                match Fragment::new(xa, za, xb, zb) {
                    Ok(p) => source.box_integral(&p, k, stats),
                    Err(_) => WeightedColour::ZERO,
                }
            };
            acc += piece * count;
        }
    }
    if xs.border_length > 0.0 || zs.border_length > 0.0 {
        // Everything outside (texture length × texture length) is border.
        let x_texture = xs.texture_length();
        let border_area = xs.border_length * (f.z1() - f.z0()) + x_texture * zs.border_length;
        acc += WeightedColour::from_colour(wrap.border_colour(), border_area);
    }
    acc
}

/// `[a, b)` cut at integers: up to three pieces `(lo, hi, count)` in local
/// tile coordinates: the left partial tile, the whole tiles (`[0,1)` ×
/// count), the right partial tile.
#[inline(always)]
fn split_repeat(a: f64, b: f64) -> [Option<Piece>; 3] {
    let (ta, tb) = (a.floor(), b.floor());
    if ta == tb || b == tb && tb - ta == 1.0 {
        // Within one tile (b may sit exactly on the next tile's border).
        let hi = if b == tb && tb != ta { 1.0 } else { b - ta };
        return [Some((a - ta, hi, 1.0)), None, None];
    }
    let left = Some((a - ta, 1.0, 1.0));
    let whole = tb - ta - 1.0;
    let middle = (whole > 0.0).then_some((0.0, 1.0, whole));
    let right = (b > tb).then_some((0.0, b - tb, 1.0));
    [left, middle, right]
}

/// As [`split_repeat`], with the pieces of odd tiles reflected (`[lo, hi)`
/// becomes `[1−hi, 1−lo)`; reflection does not change a whole tile).
fn split_mirror(a: f64, b: f64) -> [Option<Piece>; 3] {
    let odd = |tile: f64| tile.rem_euclid(2.0) == 1.0;
    let reflect = |p: Option<Piece>, tile: f64| {
        p.map(|(lo, hi, n)| {
            if odd(tile) {
                (1.0 - hi, 1.0 - lo, n)
            } else {
                (lo, hi, n)
            }
        })
    };
    let (ta, tb) = (a.floor(), b.floor());
    let [left, middle, right] = split_repeat(a, b);
    [reflect(left, ta), middle, reflect(right, tb)]
}

/// `[a, b)` against `[0,1)` for clamp mode: `(lo, hi, weight)` pieces, where
/// outside parts map to an edge strip of width `edge` and weigh their length
/// over `edge`.
fn split_clamp(a: f64, b: f64, edge: f64) -> [Option<Piece>; 3] {
    let below = (a < 0.0).then(|| (0.0, edge, (b.min(0.0) - a) / edge));
    let inside = (b > 0.0 && a < 1.0).then(|| (a.max(0.0), b.min(1.0), 1.0));
    let above = (b > 1.0).then(|| (1.0 - edge, 1.0, (b - a.max(1.0)) / edge));
    [below, inside, above]
}

/// The colour over the box `[lo, hi]` when one terminal square of the tree
/// holds it (folded into one tile by the wrap).
pub(crate) fn uniform_colour_in(
    tree: &QuadTree,
    lo: [f64; 2],
    hi: [f64; 2],
    wrap: Wrap,
) -> Option<Rgba> {
    if let Some(grid) = tree.flat_grid() {
        // A shallow tree (the repeated checker under most of a ground
        // plane): one cell of its flat grid, found by arithmetic instead
        // of a descent. Past a cell's side the search below still finds
        // neighbours of one colour.
        let depth = tree.depth();
        if let (Some(i), Some(j)) = (
            flat_cell(wrap.x(), lo[0], hi[0], depth),
            flat_cell(wrap.z(), lo[1], hi[1], depth),
        ) {
            let c = grid[(j << depth) + i];
            return Some(Rgba::new(
                c[0] as f32,
                c[1] as f32,
                c[2] as f32,
                c[3] as f32,
            ));
        }
    }
    let (x0, x1) = fold_interval(wrap.x(), lo[0], hi[0])?;
    let (z0, z1) = fold_interval(wrap.z(), lo[1], hi[1])?;
    let f = Fragment::new(x0, z0, x1, z1).ok()?;
    if f.area() <= 0.0 {
        return None;
    }
    tree.uniform_colour(&f)
}

/// The column (or row) of the `2^depth`-cell grid, folded into `[0, n)` by
/// `mode`, whose half-open cell holds `[lo, hi]`; `None` when the interval
/// crosses a cell's side, lies beyond a clamped or bordered edge, or is
/// empty or not finite.
fn flat_cell(mode: WrapMode, lo: f64, hi: f64, depth: u8) -> Option<usize> {
    let n = f64::from(1u32 << depth);
    let (a, b) = ((lo * n).floor(), (hi * n).ceil() - 1.0);
    // Cells beyond ±2⁵² would not be integers apart; the walk takes those.
    if a != b || a.abs() >= 4_503_599_627_370_496.0 || a.is_nan() {
        return None;
    }
    fold_cell(mode, a as i64, depth)
}

/// Cell `m` of the plane's `2^depth`-cell grid (along one axis) folded into
/// the texture's `[0, 2^depth)` by `mode`; `None` beyond a clamped or
/// bordered edge (their outside is not a cell of the grid).
#[inline]
pub(crate) fn fold_cell(mode: WrapMode, m: i64, depth: u8) -> Option<usize> {
    let n = 1i64 << depth;
    // The tile is an arithmetic shift (a floor), the cell within it a
    // mask: both exact for negative indices.
    let (tile, cell) = (m >> depth, m & (n - 1));
    match mode {
        WrapMode::Repeat => Some(cell as usize),
        WrapMode::Mirror if tile & 1 == 1 => Some((n - 1 - cell) as usize),
        WrapMode::Mirror => Some(cell as usize),
        WrapMode::Clamp | WrapMode::Border => (tile == 0).then_some(cell as usize),
    }
}

/// `[lo, hi]` moved into `[0,1]` when it lies in one tile the wrap folds
/// there without a seam; `None` otherwise.
fn fold_interval(mode: WrapMode, lo: f64, hi: f64) -> Option<(f64, f64)> {
    let (a, b) = match mode {
        WrapMode::Repeat => {
            let t = lo.floor();
            (lo - t, hi - t)
        }
        WrapMode::Mirror => {
            let t = lo.floor();
            if t.rem_euclid(2.0) == 1.0 {
                (1.0 - (hi - t), 1.0 - (lo - t))
            } else {
                (lo - t, hi - t)
            }
        }
        WrapMode::Clamp | WrapMode::Border => (lo, hi),
    };
    (a >= 0.0 && b <= 1.0).then_some((a, b))
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;
    use crate::{BuildOptions, TexelGrid};

    fn checker_tree() -> QuadTree {
        let g = TexelGrid::from_fn(8, 8, |c, r| {
            if (c + r) % 2 == 0 {
                Rgba::opaque(1.0, 1.0, 1.0)
            } else {
                Rgba::opaque(0.0, 0.0, 0.0)
            }
        })
        .unwrap();
        QuadTree::from_texels(&g, &BuildOptions::default())
            .unwrap()
            .0
    }

    /// A tree whose colour depends on both coordinates, so reflections and
    /// shifts show.
    fn ramp_tree() -> QuadTree {
        let g = TexelGrid::from_fn(8, 8, |c, r| {
            Rgba::opaque(c as f32 / 7.0, r as f32 / 7.0, ((c * r) % 5) as f32 / 4.0)
        })
        .unwrap();
        QuadTree::from_texels(&g, &BuildOptions::default())
            .unwrap()
            .0
    }

    /// The obvious reference: tile by tile, each tile's overlap folded back
    /// by hand.
    fn tile_by_tile(tree: &QuadTree, f: &Fragment, mirror: bool) -> WeightedColour {
        let mut slow = WeightedColour::ZERO;
        for tx in (f.x0().floor() as i64)..=(f.x1().floor() as i64) {
            for tz in (f.z0().floor() as i64)..=(f.z1().floor() as i64) {
                let (tx, tz) = (tx as f64, tz as f64);
                let x = (f.x0().max(tx) - tx, f.x1().min(tx + 1.0) - tx);
                let z = (f.z0().max(tz) - tz, f.z1().min(tz + 1.0) - tz);
                if x.1 <= x.0 || z.1 <= z.0 {
                    continue;
                }
                let fold = |(lo, hi): (f64, f64), t: f64| {
                    if mirror && t.rem_euclid(2.0) == 1.0 {
                        (1.0 - hi, 1.0 - lo)
                    } else {
                        (lo, hi)
                    }
                };
                let (x, z) = (fold(x, tx), fold(z, tz));
                slow += tree.weighted_colour(&Fragment::new(x.0, z.0, x.1, z.1).unwrap(), 30);
            }
        }
        slow
    }

    fn close(a: WeightedColour, b: WeightedColour, tol: f64) -> bool {
        (0..4).all(|c| (a.0[c] - b.0[c]).abs() <= tol)
    }

    /// The colour `uniform_colour_in` gives a box is the box's exact mean
    /// (the wrapped integral over its area), and a box inside one cell
    /// (of a tile the wrap maps onto the texture) always gets one: random
    /// boxes over shallow trees (their flat grid's arithmetic) and a deep
    /// one (the descent), boxes on cell sides, across tiles and beyond the
    /// edges, in every wrap mode.
    #[test]
    fn a_uniform_colour_is_the_mean_of_its_box() {
        let deep = {
            let g = TexelGrid::from_fn(64, 64, |c, r| {
                Rgba::opaque(c as f32 / 63.0, r as f32 / 63.0, ((c * r) % 5) as f32 / 4.0)
            })
            .unwrap();
            QuadTree::from_texels(&g, &BuildOptions::default())
                .unwrap()
                .0
        };
        let mut next = crate::test_rng::uniform(11);
        let (mut found, mut inside) = (0, 0);
        for tree in [checker_tree(), ramp_tree(), deep] {
            let n = f64::from(1u32 << tree.depth());
            for wrap in [
                Wrap::REPEAT,
                Wrap::MIRROR,
                Wrap::CLAMP,
                Wrap::uniform(WrapMode::Border),
            ] {
                for i in 0..400 {
                    // A box of up to 1.5 cells; every third one starts on a
                    // cell side, every fifth is one cell exactly.
                    let mut lo = [6.0 * next() - 3.0, 6.0 * next() - 3.0];
                    if i % 3 == 0 {
                        lo = lo.map(|v| (v * n).floor() / n);
                    }
                    let size = if i % 5 == 0 {
                        [1.0 / n; 2]
                    } else {
                        [1.5 * next() / n, 1.5 * next() / n]
                    };
                    let hi = [lo[0] + size[0], lo[1] + size[1]];
                    let cell = |v: f64| (v * n).floor();
                    let one_cell = cell(lo[0]) == (hi[0] * n).ceil() - 1.0
                        && cell(lo[1]) == (hi[1] * n).ceil() - 1.0;
                    let in_tile = |mode: WrapMode, v: f64| {
                        matches!(mode, WrapMode::Repeat | WrapMode::Mirror)
                            || (0.0..1.0).contains(&v)
                    };
                    let got = uniform_colour_in(&tree, lo, hi, wrap);
                    if one_cell && in_tile(wrap.x(), lo[0]) && in_tile(wrap.z(), lo[1]) {
                        inside += 1;
                        assert!(got.is_some(), "{lo:?} {hi:?} {wrap:?}: one cell, no colour");
                    }
                    let Some(c) = got else { continue };
                    found += 1;
                    let f = Fragment::new(lo[0], lo[1], hi[0], hi[1]).unwrap();
                    let exact =
                        integrate_wrapped(&tree, &f, 30, wrap, &mut TraversalStats::default());
                    let mean = exact.0.map(|v| v / f.area());
                    for (m, v) in mean.iter().zip(c.to_array()) {
                        assert!(
                            (m - f64::from(v)).abs() < 1e-5,
                            "{lo:?} {hi:?} {wrap:?}: {c:?} against the mean {mean:?}"
                        );
                    }
                }
            }
        }
        // Not vacuous: both branches ran often.
        assert!(
            inside > 300 && found >= inside,
            "{inside} inside, {found} found"
        );
    }

    #[test]
    fn repeat_costs_the_same_for_ten_or_a_million_tiles() {
        let tree = checker_tree();
        let mut few = TraversalStats::default();
        let mut many = TraversalStats::default();
        let small = integrate_wrapped(
            &tree,
            &Fragment::new(0.3, 0.3, 3.7, 3.2).unwrap(),
            30,
            Wrap::REPEAT,
            &mut few,
        );
        let huge = integrate_wrapped(
            &tree,
            &Fragment::new(0.3, 0.3, 1000.7, 1000.2).unwrap(),
            30,
            Wrap::REPEAT,
            &mut many,
        );
        assert_eq!(
            few.queries, many.queries,
            "queries must not grow with the tile count"
        );
        let mean = |w: WeightedColour, a: f64| w.0[0] / a;
        assert!((mean(small, 3.4 * 2.9) - 0.5).abs() < 0.02);
        assert!((mean(huge, 1000.4 * 999.9) - 0.5).abs() < 1e-4);
    }

    #[test]
    fn repeat_and_mirror_match_summing_tile_by_tile() {
        let tree = ramp_tree();
        for f in [
            Fragment::new(-1.25, 0.6, 1.4, 2.1).unwrap(),
            Fragment::new(-3.3, -2.9, -1.1, 0.2).unwrap(),
            Fragment::new(0.1, 0.2, 0.7, 0.3).unwrap(),
            Fragment::new(1.5, 1.25, 1.75, 1.5).unwrap(),
            Fragment::new(-2.0, 1.0, 3.0, 2.0).unwrap(),
        ] {
            for (mode, mirror) in [(Wrap::REPEAT, false), (Wrap::MIRROR, true)] {
                let fast = integrate_wrapped(&tree, &f, 30, mode, &mut TraversalStats::default());
                let slow = tile_by_tile(&tree, &f, mirror);
                assert!(
                    close(fast, slow, 1e-9),
                    "{mode:?} {f:?}: {fast:?} vs {slow:?}"
                );
            }
        }
    }

    /// Strips (a texture in part of the tree's square) wrap like squares:
    /// repeat and mirror against tile-by-tile sums, clamp against the edge
    /// cells stretched by hand, with cells of their own width and height.
    #[test]
    fn strips_wrap_like_squares() {
        for (w, h) in [(16u32, 2u32), (2, 16), (8, 1), (13, 6), (5, 11), (3, 1)] {
            let g = TexelGrid::from_fn(w, h, |c, r| {
                Rgba::opaque(
                    c as f32 / w as f32,
                    r as f32 / h as f32,
                    ((c * r) % 3) as f32 / 2.0,
                )
            })
            .unwrap();
            let (tree, _) = QuadTree::from_texels(&g, &BuildOptions::default()).unwrap();
            assert!(!tree.aspect().is_square());
            assert_eq!(
                tree.finest_cell_size(),
                [1.0 / f64::from(w), 1.0 / f64::from(h)]
            );
            for f in [
                Fragment::new(-1.25, 0.6, 1.4, 2.1).unwrap(),
                Fragment::new(-3.3, -2.9, -1.1, 0.2).unwrap(),
                Fragment::new(0.1, 0.2, 0.7, 0.3).unwrap(),
            ] {
                for (mode, mirror) in [(Wrap::REPEAT, false), (Wrap::MIRROR, true)] {
                    let fast =
                        integrate_wrapped(&tree, &f, 30, mode, &mut TraversalStats::default());
                    let slow = tile_by_tile(&tree, &f, mirror);
                    // Whole tiles count the root's mean, rounded once to 16 bits.
                    let tol = 1e-9 + f.area() * 0.5 / 65535.0;
                    assert!(
                        close(fast, slow, tol),
                        "{w}x{h} {mode:?} {f:?}: {fast:?} vs {slow:?}"
                    );
                }
            }
            let [cx, cz] = tree.finest_cell_size();
            let right = Fragment::new(1.0, 0.0, 3.0, 1.0).unwrap();
            let got = integrate_wrapped(
                &tree,
                &right,
                30,
                Wrap::CLAMP,
                &mut TraversalStats::default(),
            );
            let column = tree.weighted_colour(&Fragment::new(1.0 - cx, 0.0, 1.0, 1.0).unwrap(), 30);
            // Up to one rounded inner mean over the area (half a 16-bit step).
            let tol = 1e-9 + 2.0 * 0.5 / 65535.0;
            assert!(close(got, column * (2.0 / cx), tol), "{w}x{h}: {got:?}");
            let top = Fragment::new(0.0, 1.0, 1.0, 1.5).unwrap();
            let got =
                integrate_wrapped(&tree, &top, 30, Wrap::CLAMP, &mut TraversalStats::default());
            let row = tree.weighted_colour(&Fragment::new(0.0, 1.0 - cz, 1.0, 1.0).unwrap(), 30);
            assert!(close(got, row * (0.5 / cz), tol), "{w}x{h}: {got:?}");
        }
    }

    #[test]
    fn mirror_reflects_odd_tiles() {
        let tree = ramp_tree();
        let s = &mut TraversalStats::default();
        // [1, 1.25) mirrored is [0.75, 1).
        let a = integrate_wrapped(
            &tree,
            &Fragment::new(1.0, 0.0, 1.25, 1.0).unwrap(),
            30,
            Wrap::MIRROR,
            s,
        );
        let b = tree.weighted_colour(&Fragment::new(0.75, 0.0, 1.0, 1.0).unwrap(), 30);
        assert!(close(a, b, 1e-12), "{a:?} vs {b:?}");
        // A point just right of 1 shows the texel just left of 1.
        assert!((WrapMode::Mirror.fold(1.1).unwrap() - 0.9).abs() < 1e-12);
        assert!((WrapMode::Mirror.fold(-0.25).unwrap() - 0.25).abs() < 1e-12);
        assert_eq!(WrapMode::Mirror.fold_index(8, 8), Some(7));
        assert_eq!(WrapMode::Mirror.fold_index(-1, 8), Some(0));
        assert_eq!(WrapMode::Border.fold_index(8, 8), None);
    }

    /// A border colour that is not finite is refused by name; a finite one,
    /// however large, is kept.
    #[test]
    fn a_border_colour_must_be_finite() {
        for (k, name) in ["border.r", "border.g", "border.b", "border.a"]
            .into_iter()
            .enumerate()
        {
            for bad in [f32::NAN, f32::INFINITY, f32::NEG_INFINITY] {
                let mut c = [0.5f32; 4];
                c[k] = bad;
                let e = Wrap::border(Rgba::new(c[0], c[1], c[2], c[3])).unwrap_err();
                assert!(
                    matches!(e, Error::BadOption { name: n, .. } if n == name),
                    "{name}: {e}"
                );
            }
        }
        let hdr = Rgba::new(1e30, 0.0, 0.0, 1.0);
        let wrap = Wrap::new(WrapMode::Repeat, WrapMode::Border, hdr).unwrap();
        assert_eq!(
            (wrap.x(), wrap.z(), wrap.border_colour()),
            (WrapMode::Repeat, WrapMode::Border, hdr)
        );
    }

    #[test]
    fn border_and_clamp_fill_the_outside() {
        let tree = checker_tree();
        let mut s = TraversalStats::default();
        let f = Fragment::new(1.0, 0.0, 2.0, 1.0).unwrap();
        let b = integrate_wrapped(
            &tree,
            &f,
            30,
            Wrap::border(Rgba::opaque(0.0, 1.0, 0.0)).unwrap(),
            &mut s,
        );
        assert!((b.0[1] - 1.0).abs() < 1e-9 && b.0[0].abs() < 1e-9);
        // Clamp: the right edge column alternates black/white: mean 1/2.
        let c = integrate_wrapped(&tree, &f, 30, Wrap::CLAMP, &mut s);
        assert!((c.0[0] - 0.5).abs() < 1e-3, "{c:?}");
    }

    #[test]
    fn per_axis_modes_combine() {
        let tree = ramp_tree();
        let green = Rgba::opaque(0.0, 1.0, 0.0);
        // x repeats, z shows the border: a fragment half above the square.
        let wrap = Wrap::new(WrapMode::Repeat, WrapMode::Border, green).unwrap();
        let f = Fragment::new(1.25, 0.5, 1.75, 1.5).unwrap();
        let got = integrate_wrapped(&tree, &f, 30, wrap, &mut TraversalStats::default());
        let inside = tree.weighted_colour(&Fragment::new(0.25, 0.5, 0.75, 1.0).unwrap(), 30);
        let want = inside + WeightedColour::from_colour(green, 0.5 * 0.5);
        assert!(close(got, want, 1e-12), "{got:?} vs {want:?}");
        // Entirely outside on z: all border, even though x repeats.
        let out = Fragment::new(3.0, 2.0, 3.5, 2.5).unwrap();
        let got = integrate_wrapped(&tree, &out, 30, wrap, &mut TraversalStats::default());
        assert!(close(got, WeightedColour::from_colour(green, 0.25), 1e-12));
    }

    #[test]
    fn names_round_trip() {
        for m in [
            WrapMode::Repeat,
            WrapMode::Clamp,
            WrapMode::Mirror,
            WrapMode::Border,
        ] {
            assert_eq!(WrapMode::from_name(m.name()), Some(m));
        }
        assert_eq!(WrapMode::from_name("wrap"), None);
    }

    #[test]
    fn mirror_intervals_fold() {
        assert_eq!(
            fold_interval(WrapMode::Mirror, 1.25, 1.5),
            Some((0.5, 0.75))
        );
        assert_eq!(
            fold_interval(WrapMode::Repeat, 1.25, 1.5),
            Some((0.25, 0.5))
        );
        assert_eq!(fold_interval(WrapMode::Repeat, 0.75, 1.25), None);
        assert_eq!(fold_interval(WrapMode::Clamp, 0.75, 1.25), None);
    }
}
