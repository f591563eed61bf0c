//! Where texture space lies in the tree's square ([`Aspect`]).

use super::MAX_DEPTH;
use crate::Error;
use crate::geometry::fragment::Fragment;
use crate::geometry::unit_side;

/// Where texture space lies in the tree's square, for textures that are not
/// square.
///
/// **Tree space** is the square the tree subdivides, `[0,1)²`, `x` right
/// and `z` up. **Texture space** is the image: `[0,1)²` spans it whatever its
/// aspect (the usual UV convention), so a texel of a `W × H` image is
/// `1/W × 1/H` texture units. A texture `2^s` times wider than high sits in
/// the bottom `2^-s` of the tree's square (`z` shrunk by `s`), one `2^s`
/// times higher than wide in its left `2^-s` (`x` shrunk):
/// `tree = (x·2^-sx, z·2^-sz)`, with at most one of `sx`, `sz` non-zero.
/// Both scales are powers of two, so the map is exact in floating point.
///
/// The rest of the square, the *pad*, is never read: queries are clipped
/// to the texture first. Its squares are terminal and carry their parent's
/// mean, so every inner colour is the mean of its children and the root's
/// is the texture's mean. A `2^a × 2^b` raster packs into `2^(a+b)` finest
/// cells plus `O(2^|a−b|)` nodes along the pad, not `4^max(a,b)`.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Hash)]
pub struct Aspect {
    shrink: [u8; 2],
}

impl Aspect {
    /// A square texture: texture space is tree space.
    pub const SQUARE: Aspect = Aspect { shrink: [0, 0] };

    /// Texture space shrunk by `2^-x_shrink` along `x` and `2^-z_shrink`
    /// along `z`; at most one may be non-zero, each at most [`MAX_DEPTH`].
    pub fn new(x_shrink: u8, z_shrink: u8) -> Result<Aspect, Error> {
        if x_shrink != 0 && z_shrink != 0 {
            return Err(Error::MalformedTree(format!(
                "aspect shrinks both axes ({x_shrink}, {z_shrink}); at most one may be shrunk"
            )));
        }
        if x_shrink.max(z_shrink) > MAX_DEPTH {
            return Err(Error::DepthTooLarge {
                depth: x_shrink.max(z_shrink).into(),
                max: MAX_DEPTH.into(),
            });
        }
        Ok(Aspect {
            shrink: [x_shrink, z_shrink],
        })
    }

    /// The aspect of a `2^a × 2^b` grid of cells (`a = log2 columns`,
    /// `b = log2 rows`).
    pub fn of_grid(log2_columns: u8, log2_rows: u8) -> Aspect {
        let (a, b) = (log2_columns.min(MAX_DEPTH), log2_rows.min(MAX_DEPTH));
        Aspect {
            shrink: [b.saturating_sub(a), a.saturating_sub(b)],
        }
    }

    /// `[sx, sz]`: tree space is texture space times `2^-s` per axis.
    pub fn shrink(self) -> [u8; 2] {
        self.shrink
    }

    /// True for a square texture.
    pub fn is_square(self) -> bool {
        self.shrink == [0, 0]
    }

    /// `[2^-sx, 2^-sz]`: tree units per texture unit along each axis, which
    /// is also the texture's extent in tree space.
    #[inline]
    pub fn scale(self) -> [f64; 2] {
        [unit_side(self.shrink[0]), unit_side(self.shrink[1])]
    }

    /// Texture area per tree area: `2^(sx+sz)`.
    #[inline]
    pub fn area_ratio(self) -> f64 {
        f64::from_bits((1023 + u64::from(self.shrink[0]) + u64::from(self.shrink[1])) << 52)
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
        Fragment::new(f.x0() * sx, f.z0() * sz, f.x1() * sx, f.z1() * sz).ok()
    }

    /// True when square `(level, ix, iz)` of tree space lies wholly in the pad.
    #[inline]
    pub fn is_pad(self, level: u8, ix: u32, iz: u32) -> bool {
        let beyond = |i: u32, s: u8| (u64::from(i) << s) >= 1u64 << level;
        beyond(ix, self.shrink[0]) || beyond(iz, self.shrink[1])
    }
}
