//! Exact area-weighted resampling of texels onto the cell grid.

use super::TexelGrid;
use crate::Error;
use crate::colour::Unorm16Rgba;
use crate::memory::try_vec;

/// [`try_resample`] onto a square, for callers that check sizes first (the
/// mip pyramid): an allocation failure aborts, as `vec!` does.
pub(crate) fn resample(grid: &TexelGrid, side: usize) -> Vec<Unorm16Rgba> {
    match try_resample(grid, side, side) {
        Ok(cells) => cells,
        Err(_) => std::alloc::handle_alloc_error(std::alloc::Layout::new::<[f32; 4]>()),
    }
}

/// Exact area-weighted resampling of the texels onto a `columns × rows`
/// cell grid (row 0 at the top).
pub(super) fn try_resample(
    grid: &TexelGrid,
    columns: usize,
    rows_out: usize,
) -> Result<Vec<Unorm16Rgba>, Error> {
    resample_with(
        (grid.width as usize, grid.height as usize),
        (columns, rows_out),
        |i| grid.texels[i].0.map(f32::from),
        |acc| {
            let q = acc.map(|v| (v + 0.5).clamp(0.0, 65535.0) as u16);
            let a = q[3];
            Unorm16Rgba([q[0].min(a), q[1].min(a), q[2].min(a), a])
        },
    )
}

/// Exact area-weighted resampling of `width × height` texels (`texel(i)`,
/// row-major from the top) onto `columns × rows` cells, each made by `cell`
/// from its weighted sum: a horizontal pass into `f32` rows, then a
/// vertical one.
pub(super) fn resample_with<T: Copy + Default>(
    (width, height): (usize, usize),
    (columns, rows_out): (usize, usize),
    texel: impl Fn(usize) -> [f32; 4],
    cell: impl Fn([f32; 4]) -> T,
) -> Result<Vec<T>, Error> {
    let side = columns;
    let xw = weights_1d(width, columns);
    let zw = weights_1d(height, rows_out);
    let mut rows = try_vec(height * side, [0f32; 4], "resampling rows")?;
    for row in 0..height {
        for (cx, taps) in xw.iter().enumerate() {
            let mut acc = [0f32; 4];
            for &(col, wgt) in taps {
                for (a, c) in acc.iter_mut().zip(texel(row * width + col)) {
                    *a += wgt * c;
                }
            }
            rows[row * side + cx] = acc;
        }
    }
    let mut out = try_vec(side * rows_out, T::default(), "cell grid")?;
    for (cz, taps) in zw.iter().enumerate() {
        for cx in 0..side {
            let mut acc = [0f32; 4];
            for &(row, wgt) in taps {
                for (a, &c) in acc.iter_mut().zip(&rows[row * side + cx]) {
                    *a += wgt * c;
                }
            }
            out[cz * side + cx] = cell(acc);
        }
    }
    Ok(out)
}

/// For each of `cells` equal cells of `[0,1)`, the texels (of `texels` equal
/// ones) it overlaps and the fraction of the cell each covers.
pub(super) fn weights_1d(texels: usize, cells: usize) -> Vec<Vec<(usize, f32)>> {
    (0..cells)
        .map(|c| {
            // In units of 1/(texels·cells): cell c spans [c·texels, (c+1)·texels), texel t [t·cells, (t+1)·cells).
            let (lo, hi) = (c * texels, (c + 1) * texels);
            (lo / cells..hi.div_ceil(cells))
                .filter_map(|t| {
                    let overlap = hi.min((t + 1) * cells) - lo.max(t * cells);
                    (overlap > 0).then_some((t, overlap as f32 / texels as f32))
                })
                .collect()
        })
        .collect()
}
