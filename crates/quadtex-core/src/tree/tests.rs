#![allow(clippy::unwrap_used)]
use super::navigate::StoredKind;
use super::*;
use crate::{BuildOptions, TexelGrid};
use arbtest::arbitrary::Unstructured;

/// A photograph-like raster `side × side` (8 to 128 texels): noisy
/// texels, with uniform 4 × 4 blocks and uniform 16 × 16 squares
/// among them (stored terminal squares above the block level).
fn photo(u: &mut Unstructured<'_>) -> arbtest::arbitrary::Result<QuadTree> {
    let side = 1u32 << u.int_in_range(3..=7u32)?;
    let mut bytes = Vec::with_capacity((side * side) as usize);
    let (big, small) = (side.div_ceil(16), side / 4);
    let mut flat = |n: u32| -> arbtest::arbitrary::Result<Vec<Option<u8>>> {
        (0..n * n)
            .map(|_| Ok(u.ratio(1, 3)?.then_some(*u.choose(&[0u8, 90, 255])?)))
            .collect()
    };
    let (big_flat, small_flat) = (flat(big)?, flat(small)?);
    for k in 0..side * side {
        let (c, r) = (k % side, k / side);
        let v = match (big_flat[((r / 16) * big + c / 16) as usize])
            .or(small_flat[((r / 4) * small + c / 4) as usize])
        {
            Some(v) => v,
            None => *u.choose(&[0u8, 40, 128, 200, 255])?,
        };
        bytes.push([v, 255 - v, v / 2, 255]);
    }
    let grid = TexelGrid::from_srgb8(side, side, bytes).unwrap();
    Ok(QuadTree::from_texels(&grid, &BuildOptions::default())
        .unwrap()
        .0)
}

fn interval(u: &mut Unstructured<'_>) -> arbtest::arbitrary::Result<(f64, f64)> {
    let a = f64::from(u.int_in_range(0..=1 << 20u32)?) / f64::from(1 << 20u32);
    let b = a + f64::from(u.int_in_range(0..=1 << 16u32)?) / f64::from(1 << 20u32);
    Ok((a, b.min(1.0)))
}

/// Every cell's colour read by the stored descent (from the root, and
/// from the square holding a box around it) is the one the traversals'
/// node descent gives ([`QuadTree::finest_colour`]), to the bit.
#[test]
fn finest_cells_are_what_the_node_descent_finds() {
    arbtest::arbtest(|u| {
        let tree = photo(u)?;
        // An image of uniform squares alone has no texel blocks.
        if tree.texel_blocks().is_none() {
            return Ok(());
        }
        assert!(tree.is_plain_raster());
        let n = 1u32 << tree.depth();
        let h = unit_side(tree.depth());
        for cz in 0..n {
            for cx in 0..n {
                let want = tree.finest_colour(QuadTree::ROOT, 0, 0, 0, cx, cz).unwrap();
                let from_root = tree.finest_cell(QuadTree::ROOT_SQUARE, cx, cz).unwrap();
                assert_eq!(from_root.colour(), want, "cell ({cx}, {cz})");
                let (x, z) = (f64::from(cx) * h, f64::from(cz) * h);
                let start = tree.stored_square_holding((x, x + h), (z, z + h));
                let below = tree.finest_cell(start, cx, cz).unwrap();
                assert_eq!(below.colour(), want, "cell ({cx}, {cz}) from {start:?}");
                // The reader, from that square and from the root square's
                // corner block (the cell is under it or not).
                let read = tree.cells_below(start).cell(cx, cz).unwrap();
                assert_eq!(read.colour(), want, "cell ({cx}, {cz}) read from {start:?}");
                let corner = tree.stored_square_holding((0.0, h), (0.0, h));
                let read = tree.cells_below(corner).cell(cx, cz).unwrap();
                assert_eq!(
                    read.colour(),
                    want,
                    "cell ({cx}, {cz}) read from {corner:?}"
                );
            }
        }
        assert!(tree.finest_cell(QuadTree::ROOT_SQUARE, n, 0).is_none());
        Ok(())
    })
    .budget_ms(1_000);
}

/// The square [`QuadTree::stored_square_holding`] gives holds the box,
/// and no child of it does: it is a block or a terminal square, or the
/// box crosses one of its middle lines.
#[test]
fn the_square_holding_a_box_is_the_deepest() {
    arbtest::arbtest(|u| {
        let tree = photo(u)?;
        let (x, z) = (interval(u)?, interval(u)?);
        let s = tree.stored_square_holding(x, z);
        let side = unit_side(s.level);
        let (x0, z0) = (f64::from(s.ix) * side, f64::from(s.iz) * side);
        assert!(
            x0 <= x.0 && x.1 <= x0 + side && z0 <= z.0 && z.1 <= z0 + side,
            "{s:?} does not hold {x:?} × {z:?}"
        );
        if tree.stored_kind(s) == StoredKind::Inner {
            let (mx, mz) = (x0 + side / 2.0, z0 + side / 2.0);
            let crosses = |(a, b): (f64, f64), m: f64| a < m && b > m;
            assert!(
                crosses(x, mx) || crosses(z, mz),
                "a child of {s:?} holds {x:?} × {z:?}"
            );
        }
        Ok(())
    })
    .budget_ms(1_000);
}
