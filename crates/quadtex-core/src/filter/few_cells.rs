//! Regions over a few cells of a plain raster: the texture box
//! ([`RasterBox`]) and its direct scans ([`SmallBox`], [`FewCells`]).

use crate::colour::Rgba;
use crate::filter::pixel_filter::PixelFilter;
use crate::filter::projection::Mat3;
use crate::filter::scan::scan_grid;
use crate::filter::tiles::{Segment, segments, tile_map};
use crate::filter::wrap::{Wrap, WrapMode};
use crate::geometry::polygon::ConvexPolygon;
use crate::tree::{FinestCell, QuadTree, StoredSquare, unit_side};

/// Most cells of the grid at the tree's depth [`raster_box`] and
/// [`SmallBox::scan`] take a region over, before any walk is set up
/// (measured for the scan that came before them, reading cells by the
/// traversals' node descent). Measured (callgrind, whole
/// `quadtex render` runs at 960×540, against no such scan): the terrain
/// 24.14 → 22.25, 22.06 and 22.05 G instructions with 4, 16 and 64 cells,
/// the demo 3.258 → 3.244, 3.244 and 3.225 G.
pub(super) const SMALL_SCAN_CELLS: f64 = 64.0;

/// A region's texture box over a plain raster
/// ([`QuadTree::is_plain_raster`]), from [`raster_box`].
pub(super) enum RasterBox {
    /// One colour covers the whole box: a terminal square holds it, or
    /// every cell of the grid at the depth it reaches has that colour.
    Uniform(Rgba),
    /// In one tile, at most [`SMALL_SCAN_CELLS`] cells, not one colour:
    /// for [`SmallBox::scan`].
    Small(SmallBox),
    /// Two cells of one tile or four (two a side), not one colour: for
    /// [`FewCells::integrate`].
    Few(FewCells),
    /// Neither: across tiles, or more cells.
    Other,
}

/// A box in one tile of a plain raster, over a few cells of the grid at
/// the tree's depth.
pub(super) struct SmallBox {
    /// The tile's frame per axis, `(sign, offset)`: texture = sign·local +
    /// offset ([`tile_map`]), as the walk's tile frame takes it.
    frame: [(f64, f64); 2],
    /// The deepest stored square holding the box: each cell's colour is a
    /// short descent from it.
    start: StoredSquare,
}

/// A texture box over two cells or four (two a side) of one tile: the
/// region's part in each cell is where it lies on that cell's side of the
/// grid lines between them, and a grid line `x = t` (or `z = t`) of the
/// texture is the screen line `(m₀ − t·m₂)·(x, y, 1) = 0` of the map
/// `m = texture_from_screen` (a projective map sends lines to lines; the
/// region lies in front of the camera, `m₂·(x, y, 1) > 0`, so the sign
/// tells the side). Each part is one clip of the screen region, no texture
/// polygon built and no band swept: most of a photograph's pieces in the
/// terrain's pixels are of this kind (1×2, 2×1 or 2×2 texels: 91 % of
/// those [`SmallBox::scan`] took before).
pub(super) struct FewCells {
    /// Per axis, where the box reaches two cells: the texture coordinate
    /// of the grid line between them and the tile's sign on that axis
    /// (the cell of the lower local coordinate comes first).
    lines: [Option<(f64, f64)>; 2],
    /// `colours[z][x]`: the cells' colours (premultiplied, linear), by
    /// local position, low first; the second of an axis the box does not
    /// span is unused.
    colours: [[[f64; 4]; 2]; 2],
    /// How many cells the box reaches (2 or 4).
    cells: f64,
}

impl FewCells {
    /// The cells `x0..x1` by `z0..z1` (at most two a side) of the grid of
    /// side `h` in the tile of `frame` ([`SmallBox::frame`]), and their
    /// `colours` (`[z][x]`, low local position first).
    pub(super) fn new(
        frame: [(f64, f64); 2],
        h: f64,
        (x0, x1): (i64, i64),
        (z0, z1): (i64, i64),
        colours: [[[f64; 4]; 2]; 2],
    ) -> FewCells {
        // The grid line between two cells, in texture coordinates: local
        // `(c0 + 1)·h` (a multiple of a power of two, exact).
        let line = |(c0, c1): (i64, i64), (sign, offset): (f64, f64)| {
            (c1 - c0 == 2).then(|| (sign * ((c0 + 1) as f64 * h) + offset, sign))
        };
        FewCells {
            lines: [line((x0, x1), frame[0]), line((z0, z1), frame[1])],
            colours,
            cells: ((x1 - x0) * (z1 - z0)) as f64,
        }
    }

    /// The integral under `filter` centred at `centre` over screen region
    /// `region` (whose weight there is `total`): `(Σ colour·k, Σ k,
    /// cells)`, or `None` where a grid line's screen image is not finite
    /// (the caller then walks the region). The parts' weights sum to `total`: each
    /// second part's is what its axis leaves of the first's.
    pub(super) fn integrate(
        &self,
        region: &ConvexPolygon,
        texture_from_screen: &Mat3,
        filter: PixelFilter,
        centre: [f64; 2],
        total: f64,
    ) -> Option<([f64; 4], f64, f64)> {
        let m = texture_from_screen;
        // `l·(x, y, 1) ≥ 0` on the cell of the higher local coordinate.
        let line = |axis: usize| -> Option<Option<[f64; 3]>> {
            let Some((t, sign)) = self.lines[axis] else {
                return Some(None);
            };
            let l = [0, 1, 2].map(|j| sign * (m[axis][j] - t * m[2][j]));
            l.iter().all(|v| v.is_finite()).then_some(Some(l))
        };
        let (lx, lz) = (line(0)?, line(1)?);
        let low_side = |p: &ConvexPolygon, l: [f64; 3]| p.clip(-l[0], -l[1], -l[2]);
        // The weights of the low and high cells of z within `part`.
        let split_z = |part: &ConvexPolygon, weight: f64| match lz {
            None => [weight, 0.0],
            Some(l) => {
                let low = filter.integral(&low_side(part, l), centre);
                [low, weight - low]
            }
        };
        let weights: [[f64; 2]; 2] = match lx {
            None => {
                let [a, b] = split_z(region, total);
                [[a, 0.0], [b, 0.0]]
            }
            Some(l) => {
                let low = low_side(region, l);
                let w_low = filter.integral(&low, centre);
                let [a, b] = split_z(&low, w_low);
                let [c, d] = match lz {
                    None => [total - w_low, 0.0],
                    Some(_) => split_z(&region.clip(l[0], l[1], l[2]), total - w_low),
                };
                [[a, c], [b, d]]
            }
        };
        let mut colour = [0.0; 4];
        for (cz, row) in weights.iter().enumerate() {
            for (cx, &w) in row.iter().enumerate() {
                for (a, c) in colour.iter_mut().zip(self.colours[cz][cx]) {
                    *a += c * w;
                }
            }
        }
        Some((colour, total, self.cells))
    }
}

/// What the texture box `lo..hi` of a region over a plain raster
/// ([`QuadTree::is_plain_raster`]) is: one colour, a few cells of one
/// tile, or neither. One descent of stored nodes, and a look at each
/// cell the box reaches (at most [`SMALL_SCAN_CELLS`]).
///
/// A mesh triangle's region of a pixel over a photograph spans one to four
/// texels: here it costs a descent and a texel read or four, where the
/// uniform search ([`crate::filter::wrap::uniform_colour_in`]) and the walk's set-up (buffers,
/// tile frame, start node, first square) each cost several times that.
pub(super) fn raster_box(tree: &QuadTree, wrap: Wrap, lo: [f64; 2], hi: [f64; 2]) -> RasterBox {
    let one_tile = |mode: WrapMode, lo: f64, hi: f64| match segments(mode, lo, hi) {
        [Some(Segment::Tiles(a, b)), None, None] | [None, Some(Segment::Tiles(a, b)), None]
            if a == b =>
        {
            Some(a)
        }
        _ => None,
    };
    let (Some(i), Some(j)) = (
        one_tile(wrap.x(), lo[0], hi[0]),
        one_tile(wrap.z(), lo[1], hi[1]),
    ) else {
        return RasterBox::Other;
    };
    let frame = [tile_map(wrap.x(), i), tile_map(wrap.z(), j)];
    let local = |a: f64, b: f64, (sign, offset): (f64, f64)| {
        let (p, q) = ((a - offset) * sign, (b - offset) * sign);
        (p.min(q), p.max(q))
    };
    let (x, z) = (local(lo[0], hi[0], frame[0]), local(lo[1], hi[1], frame[1]));
    let start = tree.stored_square_holding(x, z);
    // A plain raster's terminal squares are of one colour each.
    if let Some(cell) = tree.terminal_cell(start) {
        return RasterBox::Uniform(cell.rgba());
    }
    // The cells the box reaches, half-open (a box ending on a cell's side
    // does not reach the next), at least one a side.
    let n = 1i64 << tree.depth();
    let h = unit_side(tree.depth());
    let cells = |(a, b): (f64, f64)| {
        let first = ((a / h).floor() as i64).clamp(0, n - 1);
        let end = ((b / h).ceil() as i64).clamp(first + 1, n);
        (first, end)
    };
    let ((x0, x1), (z0, z1)) = (cells(x), cells(z));
    if ((x1 - x0) * (z1 - z0)) as f64 > SMALL_SCAN_CELLS {
        return RasterBox::Other;
    }
    let cells = tree.cells_below(start);
    if x1 - x0 <= 2 && z1 - z0 <= 2 {
        return few_cells(&cells, frame, h, (x0, x1), (z0, z1));
    }
    let Some(first) = cells.cell(x0 as u32, z0 as u32) else {
        return RasterBox::Other;
    };
    let colour = first.rgba();
    for cz in z0..z1 {
        // The first cell is read above.
        let from = if cz == z0 { x0 + 1 } else { x0 };
        for cx in from..x1 {
            match cells.cell(cx as u32, cz as u32) {
                Some(c) if c.rgba() == colour => {}
                Some(_) => return RasterBox::Small(SmallBox { frame, start }),
                None => return RasterBox::Other,
            }
        }
    }
    RasterBox::Uniform(colour)
}

/// [`raster_box`]'s answer for a box over at most two cells a side,
/// `x0..x1` by `z0..z1` of the grid (side `h`) in the tile of `frame`:
/// one colour, or the cells for [`FewCells`] (neither when a cell has no
/// colour, as [`raster_box`] answers then).
pub(super) fn few_cells(
    cells: &crate::tree::CellReader<'_>,
    frame: [(f64, f64); 2],
    h: f64,
    (x0, x1): (i64, i64),
    (z0, z1): (i64, i64),
) -> RasterBox {
    let mut colours = [[[0.0; 4]; 2]; 2];
    let mut first = None;
    let mut uniform = true;
    for (cz, z) in (z0..z1).enumerate() {
        for (cx, x) in (x0..x1).enumerate() {
            let Some(c) = cells.cell(x as u32, z as u32) else {
                return RasterBox::Other;
            };
            let rgba = c.rgba();
            uniform &= *first.get_or_insert(rgba) == rgba;
            colours[cz][cx] = c.colour();
        }
    }
    match first {
        Some(c) if uniform => RasterBox::Uniform(c),
        _ => RasterBox::Few(FewCells::new(frame, h, (x0, x1), (z0, z1), colours)),
    }
}

impl SmallBox {
    /// The region (texture space, counter-clockwise), whose box this is,
    /// exactly: each cell of the grid at the tree's depth it crosses
    /// clipped and weighted ([`scan_grid`]), as the walk's texel scan does
    /// ([`crate::filter::walk::Walk::scan_texels`]), but with no walk set up. `(Σ colour·k, Σ
    /// k, cells)`, or `None` (nothing computed) past [`SMALL_SCAN_CELLS`]
    /// cells: the walk's own scan of the tile would fail the same way.
    pub(super) fn scan(
        &self,
        tree: &QuadTree,
        region: &ConvexPolygon,
        screen_from_texture: &Mat3,
        filter: PixelFilter,
        centre: [f64; 2],
    ) -> Option<([f64; 4], f64, f64)> {
        let [(sx, ox), (sz, oz)] = self.frame;
        // The first tile's frame maps each coordinate to itself (`(x − 0)·1
        // = x`, signed zeros and all): a counter-clockwise region is then
        // its own local polygon, not copied.
        let (moved, clipped);
        let mut local = if self.frame == [(1.0, 0.0), (1.0, 0.0)] && region.signed_area() >= 0.0 {
            region
        } else {
            moved = region.map_counter_clockwise(|[x, z]| [(x - ox) * sx, (z - oz) * sz]);
            &moved
        };
        let (llo, lhi) = local.bounds();
        if llo[0] < 0.0 || llo[1] < 0.0 || lhi[0] > 1.0 || lhi[1] > 1.0 {
            clipped = local.clip_rect(0.0, 0.0, 1.0, 1.0);
            local = &clipped;
        }
        if local.is_empty() {
            return None;
        }
        let m = screen_from_texture;
        // Row by row, not by an array `map` (not inlined: this runs per region).
        let row = |r: &[f64; 3]| [r[0] * sx, r[1] * sz, r[0] * ox + r[1] * oz + r[2]];
        let to_screen = [row(&m[0]), row(&m[1]), row(&m[2])];
        let cells = tree.cells_below(self.start);
        scan_grid(
            local,
            &to_screen,
            unit_side(tree.depth()),
            filter,
            centre,
            SMALL_SCAN_CELLS,
            |x, z| {
                let (x, z) = (u32::try_from(x).ok()?, u32::try_from(z).ok()?);
                cells.cell(x, z).map(FinestCell::colour)
            },
        )
    }
}
