//! The one colour under a fragment, when there is one: renderers use it
//! to skip the integral in uniform regions.

use super::{PAD, QuadTree, UNIFORM_SEARCH_NODES};
use crate::colour::{Rgba, Unorm16Rgba};
use crate::geometry::fragment::Fragment;
use crate::geometry::unit_side;

impl QuadTree {
    /// The colour of the fragment's overlap with the unit square when every
    /// point of it has that colour: one terminal square holds all of it, or
    /// the few terminal squares (texels of a raster block) it overlaps all
    /// hold the same colour. Found by descending through the squares that
    /// enclose the fragment, then through at most
    /// [`UNIFORM_SEARCH_NODES`] squares below the first one it straddles;
    /// `None` when the overlap is empty, crosses a border between squares
    /// whose colours differ, overlaps a gradient or contour leaf, or needs a
    /// longer search. Renderers use it to skip cutting footprints that lie
    /// in a uniform region.
    pub fn uniform_colour(&self, fragment: &Fragment) -> Option<Rgba> {
        let f = self.aspect.tree_fragment(fragment)?;
        let mut node = PAD;
        let (mut level, mut ix, mut iz) = (0u8, 0u64, 0u64);
        loop {
            if let Some(b) = self.block_at(node) {
                return self
                    .uniform_in_block(b, level, ix, iz, &f)
                    .map(Unorm16Rgba::to_rgba);
            }
            if !self.is_inner(node) {
                if self.gradient_leaf(node).is_some() || self.contour_leaf(node).is_some() {
                    return None;
                }
                let [r, g, b, a] = self.encoding.decode_colour(self.colour(node));
                return Some(Rgba::new(r as f32, g as f32, b as f32, a as f32));
            }
            let child_level = level + 1;
            let side = unit_side(child_level);
            let (mx, mz) = ((2 * ix + 1) as f64 * side, (2 * iz + 1) as f64 * side);
            // Half-open: the fragment lies in one half iff it does not cross the middle.
            let hx = if f.x1() <= mx {
                0
            } else if f.x0() >= mx {
                1
            } else {
                return self.uniform_below(node, level, ix, iz, &f);
            };
            let hz = if f.z1() <= mz {
                0
            } else if f.z0() >= mz {
                1
            } else {
                return self.uniform_below(node, level, ix, iz, &f);
            };
            node = self.first_child(node) + hx + 2 * hz;
            (level, ix, iz) = (child_level, 2 * ix + hx as u64, 2 * iz + hz as u64);
        }
    }

    /// [`QuadTree::uniform_colour`] from inner node `node` at
    /// `(level, ix, iz)`, which `f` (tree space) straddles: the one colour
    /// of every terminal square under `node` that `f` overlaps (half-open),
    /// if they share one and at most [`UNIFORM_SEARCH_NODES`] squares tell.
    fn uniform_below(
        &self,
        node: usize,
        level: u8,
        ix: u64,
        iz: u64,
        f: &Fragment,
    ) -> Option<Rgba> {
        let mut stack = [(0usize, 0u8, 0u64, 0u64); UNIFORM_SEARCH_NODES];
        stack[0] = (node, level, ix, iz);
        let (mut len, mut visited) = (1, 1);
        let mut colour: Option<Rgba> = None;
        while len > 0 {
            len -= 1;
            let (node, level, ix, iz) = stack[len];
            let here = if let Some(b) = self.block_at(node) {
                self.uniform_in_block(b, level, ix, iz, f)?.to_rgba()
            } else if !self.is_inner(node) {
                if self.gradient_leaf(node).is_some() || self.contour_leaf(node).is_some() {
                    return None;
                }
                let [r, g, b, a] = self.encoding.decode_colour(self.colour(node));
                Rgba::new(r as f32, g as f32, b as f32, a as f32)
            } else {
                let child_level = level + 1;
                let side = unit_side(child_level);
                let (mx, mz) = ((2 * ix + 1) as f64 * side, (2 * iz + 1) as f64 * side);
                let first = self.first_child(node);
                for hz in 0..2u64 {
                    let overlaps_z = if hz == 0 { f.z0() < mz } else { f.z1() > mz };
                    for hx in 0..2u64 {
                        let overlaps_x = if hx == 0 { f.x0() < mx } else { f.x1() > mx };
                        if !(overlaps_x && overlaps_z) {
                            continue;
                        }
                        if visited == UNIFORM_SEARCH_NODES {
                            return None;
                        }
                        visited += 1;
                        stack[len] = (
                            first + (hx + 2 * hz) as usize,
                            child_level,
                            2 * ix + hx,
                            2 * iz + hz,
                        );
                        len += 1;
                    }
                }
                continue;
            };
            match colour {
                None => colour = Some(here),
                Some(c) if c == here => {}
                Some(_) => return None,
            }
        }
        colour
    }

    /// The texel under all of fragment `f` (tree space) inside block `b` of
    /// square `(level, ix, iz)`, if one colour covers it.
    fn uniform_in_block(
        &self,
        b: usize,
        level: u8,
        ix: u64,
        iz: u64,
        f: &Fragment,
    ) -> Option<Unorm16Rgba> {
        let tb = self.texel_blocks.as_ref()?;
        let n = tb.side();
        let side = unit_side(level);
        let cell = side / f64::from(n);
        let (lo_x, lo_z) = (ix as f64 * side, iz as f64 * side);
        let range = |a: f64, b: f64, lo: f64| {
            let first = (((a - lo) / cell).floor().max(0.0) as u32).min(n - 1);
            let last = ((((b - lo) / cell).ceil().max(1.0) as u32) - 1).clamp(first, n - 1);
            first..=last
        };
        let (xs, zs) = (range(f.x0(), f.x1(), lo_x), range(f.z0(), f.z1(), lo_z));
        let first = tb.texel(b, *xs.start(), *zs.start());
        zs.into_iter()
            .all(|tz| xs.clone().all(|tx| tb.texel(b, tx, tz) == first))
            .then_some(first)
    }
}
