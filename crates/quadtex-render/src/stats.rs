//! What a render cost: per-pixel counters summed in row order, and the
//! summary printed after a render.

use quadtex_core::FilterStats;

/// What a render cost.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct RenderSummary {
    /// Image size.
    pub width: u32,
    /// Image size.
    pub height: u32,
    /// Wall-clock seconds.
    pub seconds: f64,
    /// Textured pixels (those whose ray hit a textured surface).
    pub textured_pixels: u64,
    /// What filtering cost: regions (footprints, or the visible parts of a
    /// pixel's support), tree queries and nodes, the error bounds of the
    /// exact integral and (SAT baseline) the strips' area excess.
    pub filter: FilterStats,
    /// The quadtree filter's self-check: over the pixels cut among
    /// several surfaces (or integrated over one), the largest difference
    /// between the weight their pieces were given and the pixel filter's
    /// whole weight, relative to it. What the cut and the region integrals
    /// lost or counted twice (slivers of rounding; 0 where nothing was).
    pub max_weight_error: f64,
}

impl std::fmt::Display for RenderSummary {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let pixels = u64::from(self.width) * u64::from(self.height);
        let tp = self.textured_pixels.max(1) as f64;
        let s = &self.filter;
        write!(
            f,
            "{}x{} in {:.3} s ({:.2} Mpixel/s); {:.2} regions and {:.2} tree queries per textured pixel, {:.1} nodes per query",
            self.width,
            self.height,
            self.seconds,
            pixels as f64 / self.seconds.max(1e-9) / 1e6,
            s.fragments as f64 / tp,
            s.traversal.queries as f64 / tp,
            s.traversal.nodes_visited as f64 / s.traversal.queries.max(1) as f64,
        )?;
        // Strips exist only where a rectangle-only baseline (SAT) cut them;
        // error bounds only where the exact integral took squares whole.
        if s.max_mismatch > 0.0 {
            write!(
                f,
                "; footprint area mismatch mean {:.2}%, max {:.1}%",
                100.0 * s.sum_mismatch / s.footprints.max(1) as f64,
                100.0 * s.max_mismatch
            )?;
        }
        if s.max_error_bound > 0.0 {
            write!(
                f,
                "; error bound per textured pixel mean {:.2e}, max {:.2e}, above the target in {} pixels; pixel weight off by {:.1e} at most",
                s.sum_error_bound / tp,
                s.max_error_bound,
                s.over_target,
                self.max_weight_error
            )?;
        }
        Ok(())
    }
}

/// Counters of the pixels of one row (or of the parts of one pixel).
#[derive(Debug, Default, Clone, Copy)]
pub(crate) struct PixelStats {
    /// Textured surfaces seen (one per textured pixel, once parts are merged).
    pub textured: u64,
    /// The texture filter's own counters.
    pub filter: FilterStats,
    /// [`RenderSummary::max_weight_error`] over these pixels.
    pub weight_error: f64,
}

impl PixelStats {
    /// Adds the statistics of the parts one pixel was shaded in as that one
    /// pixel: all their cost, but one textured pixel.
    pub fn merge_parts(&mut self, parts: &PixelStats) {
        if parts.textured > 0 {
            self.textured += 1;
        }
        self.filter.merge(&parts.filter);
        self.weight_error = self.weight_error.max(parts.weight_error);
    }

    /// Adds another row's statistics.
    pub fn merge(&mut self, other: &PixelStats) {
        self.textured += other.textured;
        self.filter.merge(&other.filter);
        self.weight_error = self.weight_error.max(other.weight_error);
    }
}
