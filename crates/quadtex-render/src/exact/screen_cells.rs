//! The screen cells ([`quadtex_core::CellIntegral`]) of the last few rows
//! of pixels a thread shaded: the integrals over each unit square between
//! four pixel centres, kept while the pixels that share them are shaded,
//! so that a tent or Mitchell pixel over one primitive adds its cells'
//! parts instead of integrating its whole support again. A thread shades
//! runs of consecutive rows (the render splits the rows in halves), so a
//! cell is integrated about once for the `(2r)²` pixels sharing it.

use quadtex_core::{CellIntegral, FilterOptions, FilterStats, PixelFilter, Texture};

use crate::caster::Seen;
use crate::view::View;

/// Cell rows kept: a Mitchell support's 4 (a thread moving down a row
/// keeps three of them), a power of two (a cell row's slot is its index
/// modulo this). A row of cells is about 1.3 MB at 1920 pixels.
const ROWS: usize = 4;

/// Cells left of the image a support reaches: Mitchell's 2.
const LEFT: i64 = 2;

/// The cells of the last few cell rows a thread's pixels asked for, in
/// frame `frame`.
#[derive(Default)]
pub(crate) struct ScreenCells {
    frame: u64,
    /// By cell row `j` modulo [`ROWS`], then column `i + LEFT`.
    rows: [Vec<Slot>; ROWS],
}

/// Cell `(i, j)` (`j` kept; `i` is the slot's column), once asked for
/// under primitive `Seen`: `None` where the texture did not take it.
type Slot = Option<(i64, Seen, Option<CellIntegral>)>;

thread_local! {
    /// Each thread's cells between rows ([`ScreenCells::take_for`]).
    static KEPT_CELLS: std::cell::RefCell<ScreenCells> = std::cell::RefCell::default();
}

impl ScreenCells {
    /// The cells this thread kept from its last row, when that row was of
    /// frame `frame`; else none, for it.
    pub(crate) fn take_for(frame: u64) -> ScreenCells {
        let mut kept = KEPT_CELLS
            .try_with(|k| std::mem::take(&mut *k.borrow_mut()))
            .unwrap_or_default();
        if kept.frame != frame {
            // The rows' allocations are kept; their cells are another
            // frame's.
            kept.frame = frame;
            for row in &mut kept.rows {
                row.fill(None);
            }
        }
        kept
    }

    /// Keeps the cells for the thread's next row.
    pub(crate) fn keep(self) {
        // A thread being torn down keeps nothing.
        let _ = KEPT_CELLS.try_with(|k| *k.borrow_mut() = self);
    }

    /// `(Σ colour·k, Σ k)` of pixel `(x, y)` under `filter` over the
    /// texture of primitive `id` seen through `view`, its whole support
    /// on the primitive, from the screen cells its support covers (each
    /// computed once while kept); `None` when one of them is not taken
    /// ([`Texture::integrate_screen_cell`]): the caller integrates the
    /// support.
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn pixel(
        &mut self,
        texture: &Texture,
        view: &View,
        id: Seen,
        filter: PixelFilter,
        (x, y): (u32, u32),
        options: &FilterOptions,
        stats: &mut FilterStats,
    ) -> Option<([f64; 4], f64)> {
        let r = filter.radius() as i64;
        if filter == PixelFilter::Box || 2 * r > ROWS as i64 {
            return None;
        }
        let (x, y) = (i64::from(x), i64::from(y));
        let (mut colour, mut weight) = ([0.0; 4], 0.0);
        for j in y - r..y + r {
            let row = &mut self.rows[j.rem_euclid(ROWS as i64) as usize];
            // This pixel is the cell's `y − (j − r + 1)`-th down.
            let q = (y - (j - r + 1)) as usize;
            for i in x - r..x + r {
                let column = usize::try_from(i + LEFT).ok()?;
                if column >= row.len() {
                    row.resize(column + 1, None);
                }
                let slot = &mut row[column];
                let cell = match slot {
                    Some((row_of, seen, cell)) if *row_of == j && *seen == id => cell,
                    _ => {
                        let cell = texture.integrate_screen_cell(
                            view.projection(),
                            [i, j],
                            filter,
                            options,
                            stats,
                        );
                        &mut slot.insert((j, id, cell)).2
                    }
                };
                // ... and its `x − (i − r + 1)`-th across.
                let (c, w) = cell.as_ref()?.part((x - (i - r + 1)) as usize, q)?;
                for (s, c) in colour.iter_mut().zip(c) {
                    *s += c;
                }
                weight += w;
            }
        }
        // Counted as the support's integral would be: one region, one
        // query (the cells' scans count their texture cells as nodes).
        stats.footprints += 1;
        stats.fragments += 1;
        stats.traversal.queries += 1;
        Some((colour, weight))
    }
}
