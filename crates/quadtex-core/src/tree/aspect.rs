//! Where texture space lies in the tree's square ([`Aspect`]).

use super::MAX_DEPTH;
use crate::Error;
use crate::geometry::fragment::Fragment;
use crate::geometry::unit_side;

/// Where texture space lies in the tree's square, for textures that are not
/// a power-of-two square.
///
/// **Tree space** is the square the tree subdivides, `[0,1)²`, `x` right
/// and `z` up. **Texture space** is the image: `[0,1)²` spans it whatever its
/// size (the usual UV convention), so a texel of a `W × H` image is
/// `1/W × 1/H` texture units. The texture fills the bottom-left rectangle
/// `[0, ex) × [0, ez)` of the tree's square, its **extent**, and
/// `tree = (x·ex, z·ez)`.
///
/// The extent is `(columns, rows)` cells of level `level`:
/// `ex = columns·2^-level`, `ez = rows·2^-level`, each at most 1. A
/// `W × H` raster packed at its natural depth `D = ⌈log2 max(W, H)⌉` has
/// the extent `(W, H)` at level `D`, so its finest cells are its texels,
/// never resampled. A `2^a × 2^b` strip has `(2^a, 2^b)` at
/// `max(a, b)`: both scales are powers of two and the map is exact in
/// floating point. The extent is kept reduced (not both counts even above
/// level 0), so equal extents compare equal.
///
/// The rest of the square, the *pad*, is never read: queries are clipped
/// to the texture first. A square is *of the pad* when it lies wholly
/// outside the extent; it is terminal and carries its parent's colour. Every
/// other square's colour is the mean of the texture under it (its part
/// inside the extent), so the root's is the texture's mean. A square that
/// straddles the extent's border keeps, in a texel block, copies of its
/// nearest texels where it crosses into the pad; they too are never read.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct Aspect {
    cells: [u32; 2],
    level: u8,
}

impl Default for Aspect {
    fn default() -> Self {
        Aspect::SQUARE
    }
}

impl Aspect {
    /// A square texture: texture space is tree space.
    pub const SQUARE: Aspect = Aspect {
        cells: [1, 1],
        level: 0,
    };

    /// Texture space shrunk by `2^-x_shrink` along `x` and `2^-z_shrink`
    /// along `z`; at most one may be non-zero, each at most [`MAX_DEPTH`].
    pub fn new(x_shrink: u8, z_shrink: u8) -> Result<Aspect, Error> {
        if x_shrink != 0 && z_shrink != 0 {
            return Err(Error::MalformedTree(format!(
                "aspect shrinks both axes ({x_shrink}, {z_shrink}); at most one may be shrunk"
            )));
        }
        let s = x_shrink.max(z_shrink);
        if s > MAX_DEPTH {
            return Err(Error::DepthTooLarge {
                depth: s.into(),
                max: MAX_DEPTH.into(),
            });
        }
        let long = 1u32 << s;
        Ok(Aspect {
            cells: [
                if x_shrink > 0 { 1 } else { long },
                if z_shrink > 0 { 1 } else { long },
            ],
            level: s,
        })
    }

    /// The texture spanning `columns × rows` cells of `level` from the
    /// tree's bottom-left corner (see the type's documentation). Refused
    /// when a count is zero or exceeds `2^level`, or `level` exceeds
    /// [`MAX_DEPTH`].
    pub fn from_extent(columns: u32, rows: u32, level: u8) -> Result<Aspect, Error> {
        if level > MAX_DEPTH {
            return Err(Error::DepthTooLarge {
                depth: level.into(),
                max: MAX_DEPTH.into(),
            });
        }
        let side = 1u64 << level;
        if columns == 0 || rows == 0 || u64::from(columns) > side || u64::from(rows) > side {
            return Err(Error::MalformedTree(format!(
                "texture extent {columns}x{rows} cells does not fit the {side}x{side} cells of level {level}"
            )));
        }
        let (mut cells, mut level) = ([columns, rows], level);
        while level > 0 && cells[0] % 2 == 0 && cells[1] % 2 == 0 {
            cells = cells.map(|c| c / 2);
            level -= 1;
        }
        Ok(Aspect { cells, level })
    }

    /// The aspect of a `2^a × 2^b` grid of cells (`a = log2 columns`,
    /// `b = log2 rows`).
    pub fn of_grid(log2_columns: u8, log2_rows: u8) -> Aspect {
        let (a, b) = (log2_columns.min(MAX_DEPTH), log2_rows.min(MAX_DEPTH));
        Aspect::new(b.saturating_sub(a), a.saturating_sub(b)).unwrap_or(Aspect::SQUARE)
    }

    /// `Some([sx, sz])` when the extent is `2^-sx × 2^-sz` (a square or a
    /// power-of-two strip: tree space is texture space times `2^-s` per
    /// axis); `None` for other extents.
    pub fn shrink(self) -> Option<[u8; 2]> {
        let [c, r] = self.cells;
        if !(c.is_power_of_two() && r.is_power_of_two()) {
            return None;
        }
        let s = |n: u32| self.level - n.trailing_zeros() as u8;
        Some([s(c), s(r)])
    }

    /// The extent as `(columns, rows)` cells of [`Aspect::level`], reduced.
    pub fn cells(self) -> [u32; 2] {
        self.cells
    }

    /// The level whose cells [`Aspect::cells`] counts.
    pub fn level(self) -> u8 {
        self.level
    }

    /// Texture cells of `level ≥` [`Aspect::level`] along each axis:
    /// `cells·2^(level − self.level)`; for a coarser level, those that hold
    /// some texture (rounded up).
    pub fn cells_at(self, level: u8) -> [u64; 2] {
        self.cells.map(|c| {
            if level >= self.level {
                u64::from(c) << (level - self.level)
            } else {
                u64::from(c).div_ceil(1u64 << (self.level - level))
            }
        })
    }

    /// True for a square texture.
    pub fn is_square(self) -> bool {
        self == Aspect::SQUARE
    }

    /// `[ex, ez]`: tree units per texture unit along each axis, which is
    /// also the texture's extent in tree space.
    #[inline]
    pub fn scale(self) -> [f64; 2] {
        let side = unit_side(self.level);
        self.cells.map(|c| f64::from(c) * side)
    }

    /// Texture area per tree area: `1 / (ex·ez)`.
    #[inline]
    pub fn area_ratio(self) -> f64 {
        let [ex, ez] = self.scale();
        1.0 / (ex * ez)
    }

    /// The fragment (texture space) clipped to the texture and mapped to
    /// tree space; `None` when nothing of it is on the texture.
    #[inline]
    pub(crate) fn tree_fragment(self, f: &Fragment) -> Option<Fragment> {
        let f = f.clip_to_unit()?;
        if self.is_square() {
            return Some(f);
        }
        let [sx, sz] = self.scale();
        // The texture's far edges map to ex and ez exactly (x1 ≤ 1).
        Fragment::new(f.x0() * sx, f.z0() * sz, f.x1() * sx, f.z1() * sz).ok()
    }

    /// True when square `(level, ix, iz)` of tree space lies wholly in the pad.
    #[inline]
    pub fn is_pad(self, level: u8, ix: u32, iz: u32) -> bool {
        // ix·2^-level ≥ cells·2^-self.level, in integers.
        let beyond =
            |i: u32, c: u32| (u128::from(i) << self.level) >= (u128::from(c) << level.min(100));
        beyond(ix, self.cells[0]) || beyond(iz, self.cells[1])
    }

    /// The fraction of square `(level, ix, iz)` that is texture, in `[0, 1]`.
    pub fn texture_fraction(self, level: u8, ix: u32, iz: u32) -> f64 {
        let side = unit_side(level);
        let [ex, ez] = self.scale();
        let part = |i: u32, e: f64| {
            let lo = f64::from(i) * side;
            ((lo + side).min(e) - lo).max(0.0) / side
        };
        part(ix, ex) * part(iz, ez)
    }

    /// Index, at `level`, of the last square along `axis` that holds
    /// texture: the square on the texture's high edge.
    #[inline]
    pub fn last_index(self, axis: usize, level: u8) -> u64 {
        self.cells_at(level)[axis] - 1
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn extents_reduce_and_strips_keep_their_shrink() {
        let a = Aspect::from_extent(600, 400, 10).unwrap();
        assert_eq!((a.cells(), a.level()), ([75, 50], 7));
        assert_eq!(a.shrink(), None);
        assert_eq!(a.cells_at(10), [600, 400]);
        assert_eq!(a.scale(), [600.0 / 1024.0, 400.0 / 1024.0]);
        let strip = Aspect::from_extent(1024, 128, 10).unwrap();
        assert_eq!(strip, Aspect::new(0, 3).unwrap());
        assert_eq!(strip.shrink(), Some([0, 3]));
        assert_eq!(Aspect::from_extent(8, 8, 3).unwrap(), Aspect::SQUARE);
        assert_eq!(Aspect::of_grid(3, 0).shrink(), Some([0, 3]));
        assert!(Aspect::from_extent(0, 1, 2).is_err());
        assert!(Aspect::from_extent(5, 1, 2).is_err());
    }

    #[test]
    fn pad_and_straddling_squares() {
        let a = Aspect::from_extent(5, 3, 3).unwrap();
        assert!(!a.is_pad(3, 4, 2) && a.is_pad(3, 5, 0) && a.is_pad(3, 0, 3));
        assert!(!a.is_pad(1, 1, 0) && a.is_pad(1, 0, 1));
        assert!(a.is_pad(2, 3, 0) && !a.is_pad(2, 2, 1));
        assert_eq!(a.texture_fraction(2, 2, 1), 0.5 * 0.5);
        assert_eq!(a.last_index(0, 3), 4);
        assert_eq!(a.last_index(1, 1), 0);
        assert_eq!(a.last_index(0, 0), 0);
        assert_eq!(a.last_index(0, 4), 9);
    }
}
