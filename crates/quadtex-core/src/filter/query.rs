//! What a region integral is asked ([`RegionQuery`]) and what it answers
//! ([`RegionIntegral`]): the values the region's walk, scans and cell
//! shortcuts share, kept apart from [`crate::filter::region`] so that those
//! files depend on this one and not on each other.

use crate::colour::{Rgba, WeightedColour};
use crate::filter::options::FilterOptions;
use crate::filter::pixel_filter::PixelFilter;
use crate::filter::projection::Projection;
use crate::filter::wrap::Wrap;
use crate::tree::QuadTree;

/// What one region integral is asked: the texture (its tree and wrap), the
/// map from the screen, and the pixel filter with its centre (pixel units).
pub(crate) struct RegionQuery<'a> {
    pub(crate) tree: &'a QuadTree,
    pub(crate) wrap: Wrap,
    /// [`crate::Texture::bound_scale`]: what unit-contrast bounds become.
    pub(crate) bound_scale: f64,
    pub(crate) projection: &'a Projection,
    pub(crate) filter: PixelFilter,
    pub(crate) centre: [f64; 2],
    pub(crate) options: &'a FilterOptions,
}

/// What [`crate::Texture::integrate_region`] returns.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct RegionIntegral {
    /// `∫ colour · k` over the region (linear, premultiplied; units of
    /// colour × screen area).
    pub colour: WeightedColour,
    /// `∫ k` over the region.
    pub weight: f64,
    /// A bound on `|colour − exact|` per channel, in the same units: what
    /// taking squares at their mean cost ([`crate::filter::region`] documentation).
    pub error_bound: f64,
}

impl RegionIntegral {
    /// Adds another region's integral.
    pub fn add(&mut self, other: &RegionIntegral) {
        self.colour += other.colour;
        self.weight += other.weight;
        self.error_bound += other.error_bound;
    }

    /// `colour / weight`, `None` when the weight is zero.
    pub fn mean(&self) -> Option<Rgba> {
        // Not `mean_over`: a Mitchell lobe's weight may be negative.
        (self.weight != 0.0 && self.weight.is_finite()).then(|| {
            let s = 1.0 / self.weight;
            let c = self.colour.0;
            Rgba::new(
                (c[0] * s) as f32,
                (c[1] * s) as f32,
                (c[2] * s) as f32,
                (c[3] * s) as f32,
            )
        })
    }
}
