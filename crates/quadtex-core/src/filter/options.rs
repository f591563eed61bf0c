//! What a filter call is asked to do ([`FilterOptions`]: weighting, level
//! of detail, budget) and what it cost ([`FilterStats`]).

use crate::Error;
use crate::tree::TraversalStats;

/// The renderer's square budget: most squares and blocks one pixel region
/// evaluates under an error bound in `quadtex-render` (and the CLI's
/// `render --budget` default). Past it the largest remaining errors are
/// left unrefined and the bound reported is what was reached. Library
/// calls ([`FilterOptions::default`]) have no budget: they opt in with
/// [`FilterOptions::with_budget`].
pub const SQUARE_BUDGET: u64 = 64;

/// How a footprint's points are weighted in its mean colour.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub enum Weighting {
    /// Uniform over the pixel square (a screen-space box filter): texture
    /// area is weighed by the screen area that sees it, from the projective
    /// map the footprint's corners fix. The right choice for a renderer.
    #[default]
    Screen,
    /// Uniform over the footprint in texture space, as the seed paper does.
    Texture,
}

/// Where the traversal may take a non-terminal square at its mean.
///
/// For [`crate::Texture::filter`] and [`crate::Texture::integrate_region`]
/// ([`crate::filter::region`]): `ErrorBound(ε)` aims the bound on each pixel's error
/// (relative to full contrast) at `ε`; `Fixed(k)` descends every square to
/// level `k` or to a terminal square (the tree's depth: exact).
///
/// For the strip baseline ([`crate::baseline::filter_by_strips`]): a fragment of sides
/// `w × h` may stop at level `k` only where the squares it treats as whole
/// are partially covered; their area is at most `2(w+h)·2^-k`, so the mean
/// colour is off by at most `2(w+h)·2^-k/(w·h)` of the texture's contrast.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum LevelOfDetail {
    /// The smallest level whose truncation bound is `≤ epsilon` (relative to
    /// the texture's contrast), capped by the tree's depth.
    ErrorBound(f64),
    /// Always this level (clamped to the tree's depth).
    Fixed(u8),
}

impl Default for LevelOfDetail {
    /// `ErrorBound(1/512)`: half an 8-bit step at full contrast.
    fn default() -> Self {
        LevelOfDetail::ErrorBound(1.0 / 512.0)
    }
}

impl LevelOfDetail {
    /// The level for a fragment of `w × h` texture units in a tree of `depth`.
    pub fn level(&self, w: f64, h: f64, depth: u8) -> u8 {
        match *self {
            LevelOfDetail::Fixed(k) => k.min(depth),
            LevelOfDetail::ErrorBound(eps) => {
                if !(w > 0.0 && h > 0.0) {
                    return depth;
                }
                let needed = (2.0 * (w + h) / (w * h * eps)).log2().ceil();
                if needed.is_finite() {
                    needed.clamp(0.0, f64::from(depth)) as u8
                } else {
                    depth
                }
            }
        }
    }
}

/// Options of [`crate::Texture::filter`]: weighting, level of detail, and
/// an optional square budget.
///
/// Invariants (checked by the `with_*` constructors): an error bound is
/// finite and `> 0`, a budget at least 1.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FilterOptions {
    weighting: Weighting,
    lod: LevelOfDetail,
    /// `None`: refine until the bound is met (up to the hard cap
    /// [`crate::FIXED_LEVEL_CAP`] squares a region).
    budget: Option<u64>,
}

impl Default for FilterOptions {
    /// [`FilterOptions::DEFAULT`].
    fn default() -> Self {
        FilterOptions::DEFAULT
    }
}

impl FilterOptions {
    /// Screen weighting, error bound 1/512, no square budget: every
    /// footprint is refined until its bound is met (a region stops only at
    /// the hard cap of [`crate::FIXED_LEVEL_CAP`] squares, and then reports
    /// the larger bound it reached).
    pub const DEFAULT: FilterOptions = FilterOptions {
        weighting: Weighting::Screen,
        lod: LevelOfDetail::ErrorBound(1.0 / 512.0),
        budget: None,
    };

    /// What the renderer asks for: [`FilterOptions::DEFAULT`] with a budget
    /// of [`SQUARE_BUDGET`] squares a region (pixels near a horizon stop at
    /// it and report the bound reached).
    pub const RENDER: FilterOptions = FilterOptions {
        weighting: Weighting::Screen,
        lod: LevelOfDetail::ErrorBound(1.0 / 512.0),
        budget: Some(SQUARE_BUDGET),
    };

    /// The defaults ([`FilterOptions::default`]).
    pub fn new() -> FilterOptions {
        FilterOptions::default()
    }

    /// With this weighting.
    pub fn with_weighting(self, weighting: Weighting) -> FilterOptions {
        FilterOptions { weighting, ..self }
    }

    /// With the level of detail chosen by the error bound `epsilon`
    /// (finite, `> 0`; relative to the texture's contrast).
    pub fn with_error_bound(self, epsilon: f64) -> Result<FilterOptions, Error> {
        if !(epsilon.is_finite() && epsilon > 0.0) {
            return Err(Error::BadOption {
                name: "error bound",
                value: epsilon,
                expected: "a finite number > 0",
            });
        }
        Ok(FilterOptions {
            lod: LevelOfDetail::ErrorBound(epsilon),
            ..self
        })
    }

    /// With every fragment traversed down to level `level` (clamped to the
    /// tree's depth), whatever its size.
    pub fn with_level(self, level: u8) -> FilterOptions {
        FilterOptions {
            lod: LevelOfDetail::Fixed(level),
            ..self
        }
    }

    /// With at most `budget` squares and tile blocks evaluated per region
    /// under an error bound (`≥ 1`; see [`crate::filter::region`]): past it the
    /// largest remaining errors stay and the bound reached is reported
    /// (it may then exceed the error bound asked for; [`FilterStats`]
    /// counts such footprints). Opt-in: the default has no budget.
    /// Shallow repeated textures (depth ≤ 4) are scanned cell by cell
    /// instead, exactly, up to 512 cells a region, whatever the budget.
    pub fn with_budget(self, budget: u64) -> Result<FilterOptions, Error> {
        if budget == 0 {
            return Err(Error::BadOption {
                name: "budget",
                value: 0.0,
                expected: "at least 1",
            });
        }
        Ok(FilterOptions {
            budget: Some(budget),
            ..self
        })
    }

    /// With no square budget (the default): refine until the bound is met,
    /// up to the hard cap of [`crate::FIXED_LEVEL_CAP`] squares a region.
    pub fn without_budget(self) -> FilterOptions {
        FilterOptions {
            budget: None,
            ..self
        }
    }

    /// The square budget per region, `None` when there is none.
    pub fn budget(&self) -> Option<u64> {
        self.budget
    }

    /// The error bound aimed at (relative to full contrast), `None` under a
    /// fixed level.
    pub fn target_bound(&self) -> Option<f64> {
        match self.lod {
            LevelOfDetail::ErrorBound(e) => Some(e),
            LevelOfDetail::Fixed(_) => None,
        }
    }

    /// The weighting.
    pub fn weighting(&self) -> Weighting {
        self.weighting
    }

    /// The level-of-detail rule.
    pub fn level_of_detail(&self) -> LevelOfDetail {
        self.lod
    }
}

/// What filtering cost, summed over calls (for reports).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct FilterStats {
    /// Footprints filtered.
    pub footprints: u64,
    /// Fragments integrated (1 for a footprint the uniform shortcut answers).
    pub fragments: u64,
    /// Tree queries (after wrap splitting) and nodes they visited.
    pub traversal: TraversalStats,
    /// Largest relative area excess of a footprint's strips (the strip
    /// baseline only, [`crate::baseline::filter_by_strips`]; 0 otherwise).
    pub max_mismatch: f64,
    /// Sum of the footprints' relative area excess (mean = sum / footprints).
    pub sum_mismatch: f64,
    /// Largest error bound of a filtered colour, relative to full contrast
    /// (exact pipeline: [`crate::filter::region`]).
    pub max_error_bound: f64,
    /// Sum of the filtered colours' error bounds (mean = sum / footprints).
    pub sum_error_bound: f64,
    /// Footprints whose reported bound (relative to the texture's
    /// contrast) is above the error bound asked for: stopped by a square
    /// budget or by the hard cap ([`crate::FIXED_LEVEL_CAP`]).
    pub over_target: u64,
}

impl FilterStats {
    /// Adds `other`'s counts to these.
    pub fn merge(&mut self, other: &FilterStats) {
        self.footprints += other.footprints;
        self.fragments += other.fragments;
        self.traversal.queries += other.traversal.queries;
        self.traversal.nodes_visited += other.traversal.nodes_visited;
        self.max_mismatch = self.max_mismatch.max(other.max_mismatch);
        self.sum_mismatch += other.sum_mismatch;
        self.max_error_bound = self.max_error_bound.max(other.max_error_bound);
        self.sum_error_bound += other.sum_error_bound;
        self.over_target += other.over_target;
    }

    /// Records one filtered colour's relative error bound.
    pub fn record_bound(&mut self, relative: f64) {
        self.max_error_bound = self.max_error_bound.max(relative);
        self.sum_error_bound += relative;
    }

    /// Records one result's relative error bound, counting it in
    /// [`FilterStats::over_target`] when it is above `target` (the bound
    /// asked for; `None` under a fixed level, which aims at none).
    pub fn record_bound_against(&mut self, relative: f64, target: Option<f64>) {
        self.record_bound(relative);
        if target.is_some_and(|t| relative > t) {
            self.over_target += 1;
        }
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    #[test]
    fn bounds_above_the_target_are_counted() {
        let mut stats = FilterStats::default();
        stats.record_bound_against(1e-3, Some(1.0 / 512.0));
        stats.record_bound_against(1.0 / 512.0, Some(1.0 / 512.0));
        stats.record_bound_against(0.5, Some(1.0 / 512.0));
        stats.record_bound_against(0.9, None);
        assert_eq!(stats.over_target, 1);
        assert_eq!(stats.max_error_bound, 0.9);
    }

    #[test]
    fn level_of_detail_rule() {
        let lod = LevelOfDetail::ErrorBound(1.0 / 512.0);
        // A fragment of 1/64 on a side needs k with 4·2^-k/(1/64) ≤ 1/512 → k ≥ 6 + 11.
        assert_eq!(lod.level(1.0 / 64.0, 1.0 / 64.0, 30), 17);
        assert_eq!(lod.level(1.0 / 64.0, 1.0 / 64.0, 12), 12);
        assert_eq!(LevelOfDetail::Fixed(5).level(0.1, 0.1, 3), 3);
    }

    #[test]
    fn options_refuse_bad_values() {
        let o = FilterOptions::new();
        assert!(o.with_error_bound(0.0).is_err());
        assert!(o.with_error_bound(f64::INFINITY).is_err());
        let e = o.with_error_bound(-1.0).unwrap_err().to_string();
        assert!(e.contains("error bound"), "{e}");
        assert!(o.with_budget(0).is_err());
    }

    #[test]
    fn library_default_has_no_budget_renderer_keeps_64() {
        assert_eq!(FilterOptions::default().budget(), None);
        assert_eq!(FilterOptions::RENDER.budget(), Some(SQUARE_BUDGET));
        assert_eq!(
            FilterOptions::default().with_budget(SQUARE_BUDGET).unwrap(),
            FilterOptions::RENDER
        );
        assert_eq!(
            FilterOptions::RENDER.without_budget(),
            FilterOptions::DEFAULT
        );
    }
}
