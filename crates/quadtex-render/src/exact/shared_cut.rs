//! Shared cuts: a run of a row's pixels whose centres in reach see more
//! than one thing, cut as one support under the box filter
//! ([`Scratch::shared_cut`]).
//!
//! Where a far hillside crowds a pixel with triangles, most of its cost is
//! listing them, clipping each to the support, ordering and cutting them,
//! not integrating the texture over the pieces; and a pixel's neighbours
//! in its row list, clip and cut the same triangles again. The box
//! filter's supports of a row's pixels tile the rectangle they span, so
//! the rectangle is cut once among the primitives of all their centres
//! (with the flood, the gaps' search and the occluders' search of
//! [`super::pixel`], their caps the pixels' added up), and each visible
//! region, sliver and gap of that cut is then split along the pixels'
//! sides and shaded by the pixel it lies in, with that pixel's own filter
//! centre ([`by_column`](super::pixel::by_column)). Each pixel's colour is
//! the sum of its pieces, as if its own support had been cut: the pieces
//! are the same regions, split differently along their edges, so the two
//! differ by rounding (and each pixel's bound takes the whole rectangle's
//! unaccounted weight). A list that holds a sphere is left to the pixels
//! one by one (its outline is clipped by chords over one support's
//! angles).

use quadtex_core::{ConvexPolygon, FilterOptions, PixelFilter, Rgba};

use crate::caster::Seen;
use crate::frame::Frame;
use crate::stats::PixelStats;

use super::MAX_GAP_PRIMITIVES;
use super::lighting::Shading;
use super::pixel::{ExactPixel, Scratch, Sums};
use super::views::SurfaceViews;

/// Most pixels a shared cut holds.
pub(crate) const SHARED_CUT_PIXELS: u32 = 16;

/// Most primitives the centres of a shared cut's pixels see, past its
/// first two pixels: a cut's cost grows faster than its list (pairs
/// overlap, pieces multiply), so crowded rows take shorter runs. Measured
/// on `quadtex bench --frames`' terrain, one thread (docs/performance.md):
/// 9–12 with 16 pixels at most beat 8 pixels with no limit at 480 × 270
/// and at 1920 × 1080, 24 and 48 lost at 480, 6 at 1920.
pub(crate) const SHARED_CUT_PRIMITIVES: usize = 12;

impl<'a> Scratch<'a> {
    /// Cuts pixels `x0..x1` of row `y` as one support among the primitives
    /// `candidates` (what their centres in reach see) under the box
    /// filter, keeping each pixel's colour and counters for
    /// [`Scratch::shared_cut_fill`]. Returns false, keeping nothing, when a
    /// candidate or a primitive found has no view or one listed is a
    /// sphere: the pixels are then taken one by one.
    pub(crate) fn shared_cut(
        &mut self,
        frame: &Frame<'_>,
        options: &FilterOptions,
        (x0, x1, y): (u32, u32, u32),
        candidates: &[Seen],
        cache: &'a SurfaceViews,
    ) -> bool {
        self.shared_cut.pixels.clear();
        let columns = x1.saturating_sub(x0) as usize;
        if columns == 0 {
            return false;
        }
        let (left, top) = (f64::from(x0), f64::from(y));
        let cell = |support: ConvexPolygon, at: (u32, u32), cap: usize| {
            let (lo, hi) = support.bounds();
            ExactPixel {
                shading: Shading {
                    frame,
                    filter: PixelFilter::Box,
                    centre: [0.5 * (lo[0] + hi[0]), 0.5 * (lo[1] + hi[1])],
                    options,
                    support: (lo, hi),
                    share: 1.0,
                },
                at,
                support,
                cache,
                cap,
            }
        };
        let rectangle = cell(
            ConvexPolygon::rect(left, top, left + columns as f64, top + 1.0),
            (x0, y),
            MAX_GAP_PRIMITIVES * columns,
        );
        if rectangle.list_candidates(candidates, self).is_none()
            || self.lists_a_sphere()
            || rectangle.cut(self).is_none()
        {
            return false;
        }
        // (The frame's lifetime keeps these out of the thread's buffers:
        // one small allocation a cut.)
        let pixels: Vec<ExactPixel<'_, 'a>> = (0..columns)
            .map(|c| {
                let x = left + c as f64;
                let support = ConvexPolygon::rect(x, top, x + 1.0, top + 1.0);
                cell(support, (x0 + c as u32, y), MAX_GAP_PRIMITIVES)
            })
            .collect();
        let (mut sums, mut parts) = (
            std::mem::take(&mut self.shared_cut.sums),
            std::mem::take(&mut self.shared_cut.parts),
        );
        sums.clear();
        sums.resize(columns, Sums::default());
        parts.clear();
        parts.resize(columns, PixelStats::default());
        let shaded = rectangle.shade_cut(self, &pixels, &mut sums, &mut parts);
        let fill = &mut self.shared_cut;
        if shaded.is_some() {
            (fill.y, fill.left) = (y, x0);
            for ((pixel, sums), parts) in pixels.iter().zip(sums.drain(..)).zip(&parts) {
                let mut stats = PixelStats::default();
                let colour = pixel.finish(sums, *parts, &mut stats);
                fill.pixels.push((colour, stats));
            }
        }
        (fill.sums, fill.parts) = (sums, parts);
        shaded.is_some()
    }

    /// The colour and counters of pixel `(x, y)` when the row's last
    /// shared cut holds it ([`Scratch::shared_cut`]).
    pub(crate) fn shared_cut_fill(&self, (x, y): (u32, u32)) -> Option<&(Rgba, PixelStats)> {
        let fill = &self.shared_cut;
        if fill.y != y || x < fill.left {
            return None;
        }
        fill.pixels.get((x - fill.left) as usize)
    }
}
