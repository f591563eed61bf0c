//! The layout of a texture packed tile by tile ([`Mosaic`]).

use super::MAX_DIMENSION;
use crate::Error;
use crate::tree::MAX_DEPTH;
use crate::tree::texel_block::BLOCK_LOG2_SIDE;

/// How a `width × height` texture is cut into the tiles
/// [`QuadTree::from_tiles`](crate::QuadTree::from_tiles) packs one at a
/// time: the tree's square is a grid of `tiles × tiles` tile squares
/// (`tiles` a power of two), each `side × side` texels (a power of two, at
/// least 4). As for any raster ([`crate::raster_cells`]), the texture
/// covers the square's bottom-left `width × height` texels and the rest is
/// pad, never read.
///
/// Tile `(row, col)` is the tile square in row `row` from the **top** of
/// the tree's square and column `col` from the left. Its texels are the
/// part of the texture inside it ([`Mosaic::tile_extent`]); a tile wholly
/// in the pad is never asked for. When `width` and `height` are whole
/// numbers of tiles, tile `(row, col)` holds texture rows `row · side ..`
/// counted from the texture's top; otherwise the rows are those of
/// [`Mosaic::tile_rect`], which lines the tiles up with the texture's
/// **bottom** edge (where texture coordinate `v = 0` is).
///
/// Invariants (checked by the constructors): `tiles` is the fewest that
/// cover the texture, so the tree's depth `log2(tiles · side)` is the
/// texture's natural depth `ceil(log2 max(width, height))`, and that
/// depth is at most [`MAX_DEPTH`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct Mosaic {
    tiles: u32,
    side: u32,
    width: u32,
    height: u32,
}

impl Mosaic {
    /// A complete square mosaic: `tiles × tiles` tiles of `side × side`
    /// texels, both powers of two.
    pub fn square(tiles: u32, side: u32) -> Result<Mosaic, Error> {
        if !tiles.is_power_of_two() || !side.is_power_of_two() {
            return Err(Error::BadDimensions {
                width: u64::from(tiles),
                height: u64::from(side),
                reason: "tiles a side and texels a tile side must be powers of two",
            });
        }
        let texels = u64::from(tiles) * u64::from(side);
        if texels > u64::from(u32::MAX) {
            return Err(Error::DepthTooLarge {
                depth: texels.trailing_zeros(),
                max: MAX_DEPTH.into(),
            });
        }
        Mosaic::of_texture(texels as u32, texels as u32, side)
    }

    /// The fewest `side × side` tiles (a power of two texels, at least 4)
    /// that cover a `width × height` texture. Refused when the texture is
    /// no larger than half a tile on both sides (pack it whole:
    /// [`crate::QuadTree::from_texels`]), or deeper than [`MAX_DEPTH`].
    pub fn of_texture(width: u32, height: u32, side: u32) -> Result<Mosaic, Error> {
        if !side.is_power_of_two() || side > MAX_DIMENSION {
            return Err(Error::BadDimensions {
                width: u64::from(side),
                height: u64::from(side),
                reason: "texels a tile side must be a power of two",
            });
        }
        if side < 1 << BLOCK_LOG2_SIDE {
            return Err(Error::BadDimensions {
                width: u64::from(side),
                height: u64::from(side),
                reason: "tiles must be at least 4x4 texels",
            });
        }
        if width == 0 || height == 0 {
            return Err(Error::BadDimensions {
                width: width.into(),
                height: height.into(),
                reason: "zero-sized",
            });
        }
        let long = width.max(height);
        if u64::from(long) * 2 <= u64::from(side) {
            return Err(Error::BadDimensions {
                width: width.into(),
                height: height.into(),
                reason: "no larger than half a tile: pack it whole",
            });
        }
        let tiles = long.div_ceil(side).next_power_of_two();
        let depth = tiles.trailing_zeros() + side.trailing_zeros();
        if depth > u32::from(MAX_DEPTH) {
            return Err(Error::DepthTooLarge {
                depth,
                max: MAX_DEPTH.into(),
            });
        }
        Ok(Mosaic {
            tiles,
            side,
            width,
            height,
        })
    }

    /// Tiles on the tree square's side.
    pub fn tiles(self) -> u32 {
        self.tiles
    }

    /// Texels on a tile's side.
    pub fn side(self) -> u32 {
        self.side
    }

    /// The texture's width in texels.
    pub fn width(self) -> u32 {
        self.width
    }

    /// The texture's height in texels.
    pub fn height(self) -> u32 {
        self.height
    }

    /// True when the texture fills every tile (a square of whole tiles).
    pub fn is_square(self) -> bool {
        let texels = u64::from(self.tiles) * u64::from(self.side);
        u64::from(self.width) == texels && u64::from(self.height) == texels
    }

    /// The level whose squares are the tiles: `log2 tiles`.
    pub fn tile_level(self) -> u8 {
        self.tiles.trailing_zeros() as u8
    }

    /// The tree's depth: `log2(tiles · side)`.
    pub fn depth(self) -> u8 {
        self.tile_level() + self.side.trailing_zeros() as u8
    }

    /// The part of the texture in tile `(row, col)`, `(x0, y0, w, h)` in
    /// texels from the texture's top-left corner (row 0 at the top);
    /// `None` for a tile wholly in the pad or outside the grid.
    pub fn tile_rect(self, row: u32, col: u32) -> Option<(u32, u32, u32, u32)> {
        if row >= self.tiles || col >= self.tiles {
            return None;
        }
        let side = u64::from(self.side);
        // Tile rows counted from the bottom, where the texture starts.
        let from_bottom = u64::from(self.tiles - 1 - row);
        let (x0, z0) = (u64::from(col) * side, from_bottom * side);
        let (w, h) = (u64::from(self.width), u64::from(self.height));
        if x0 >= w || z0 >= h {
            return None;
        }
        let (x1, z1) = ((x0 + side).min(w), (z0 + side).min(h));
        // Texture rows from the top: z counts up from the bottom.
        let y0 = h - z1;
        Some((x0 as u32, y0 as u32, (x1 - x0) as u32, (z1 - z0) as u32))
    }

    /// The size of tile `(row, col)`'s texels, `(w, h)` (`side × side`
    /// inside the texture, less on its top and right edges); `None` for a
    /// tile wholly in the pad.
    pub fn tile_extent(self, row: u32, col: u32) -> Option<(u32, u32)> {
        self.tile_rect(row, col).map(|(_, _, w, h)| (w, h))
    }

    /// The tiles that hold texture, `(row, col)`, in the order
    /// [`crate::QuadTree::from_tiles`] asks for them: Morton order of the
    /// tile squares, `x` the low bit, counted from the bottom-left.
    pub fn tiles_in_order(self) -> Vec<(u32, u32)> {
        let n = u64::from(self.tiles) * u64::from(self.tiles);
        (0..n)
            .map(|m| {
                let (mut x, mut z) = (0u32, 0u32);
                for bit in 0..32 {
                    x |= (((m >> (2 * bit)) & 1) as u32) << bit;
                    z |= (((m >> (2 * bit + 1)) & 1) as u32) << bit;
                }
                (self.tiles - 1 - z, x)
            })
            .filter(|&(row, col)| self.tile_rect(row, col).is_some())
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tiles_cover_the_texture_once_lined_up_with_its_bottom_edge() {
        for (w, h, side) in [
            (64, 64, 16),
            (100, 37, 16),
            (17, 130, 32),
            (5, 3, 4),
            (33, 1, 32),
        ] {
            let m = Mosaic::of_texture(w, h, side).unwrap();
            assert_eq!(
                m.depth(),
                (32 - (w.max(h) - 1).leading_zeros()) as u8,
                "natural depth"
            );
            let mut covered = vec![0u8; (w * h) as usize];
            for (row, col) in m.tiles_in_order() {
                let (x0, y0, tw, th) = m.tile_rect(row, col).unwrap();
                assert!(tw <= side && th <= side && tw > 0 && th > 0);
                // Whole tiles below the top row of tiles, left of the last column.
                assert!(x0 + tw == w || tw == side);
                assert!(y0 == 0 || th == side);
                for y in y0..y0 + th {
                    for x in x0..x0 + tw {
                        covered[(y * w + x) as usize] += 1;
                    }
                }
            }
            assert!(covered.iter().all(|&c| c == 1), "{w}x{h}/{side}");
            // Pad tiles are not asked for; tile rows count from the top.
            let n = m.tiles();
            let asked = m.tiles_in_order().len() as u32;
            let expect = w.div_ceil(side) * h.div_ceil(side);
            assert_eq!(asked, expect);
            assert!(m.tile_rect(n, 0).is_none() && m.tile_rect(0, n).is_none());
            assert!(m.tile_rect(n - 1, 0).is_some());
        }
        let full = Mosaic::square(4, 16).unwrap();
        assert!(full.is_square());
        assert_eq!(full.tile_rect(0, 3), Some((48, 0, 16, 16)));
        assert_eq!(full.tiles_in_order()[..3], [(3, 0), (3, 1), (2, 0)]);
    }

    #[test]
    fn mosaics_that_cannot_be_tiled_are_refused() {
        assert!(Mosaic::of_texture(8, 8, 16).is_err(), "half a tile");
        assert!(Mosaic::of_texture(9, 1, 16).is_ok());
        assert!(Mosaic::of_texture(0, 5, 16).is_err());
        assert!(Mosaic::of_texture(100, 100, 24).is_err());
        assert!(Mosaic::of_texture(100, 100, 2).is_err());
        assert!(Mosaic::square(3, 16).is_err());
        assert!(Mosaic::square(1 << 20, 1 << 12).is_err(), "too deep");
    }
}
