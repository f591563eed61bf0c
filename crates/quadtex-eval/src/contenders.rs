//! The filter configurations a comparison runs, in report order.

use quadtex_core::FilterOptions;
use quadtex_core::baseline::StripOptions;
use quadtex_render::{Filter, PixelFilter};

/// A filter configuration taking part in a comparison.
#[derive(Debug, Clone, PartialEq)]
pub struct Contender {
    /// Short name for tables and plots.
    pub label: String,
    /// Texture filter.
    pub filter: Filter,
    /// Pixel filter.
    pub pixel_filter: PixelFilter,
}

impl Contender {
    fn new(label: &str, filter: Filter, pixel_filter: PixelFilter) -> Contender {
        Contender {
            label: label.into(),
            filter,
            pixel_filter,
        }
    }
}

/// The filters users would pick, and quadtex's settings, in report order.
pub fn default_contenders() -> Vec<Contender> {
    use PixelFilter::{Box, Tent};
    vec![
        Contender::new("quadtree", Filter::default(), Box),
        Contender::new(
            "quadtree b1024",
            Filter::Quadtree(quadtree_budget(1024)),
            Box,
        ),
        Contender::new("quadtree tent", Filter::default(), Tent),
        Contender::new("nearest", Filter::Nearest, Box),
        Contender::new("bilinear", Filter::Bilinear, Box),
        Contender::new("trilinear", Filter::Trilinear, Box),
        Contender::new(
            "EWA aniso 8",
            Filter::Ewa {
                max_anisotropy: 8.0,
            },
            Box,
        ),
        Contender::new(
            "EWA aniso 32",
            Filter::Ewa {
                max_anisotropy: 32.0,
            },
            Box,
        ),
        Contender::new(
            "EWA 32, same memory",
            Filter::EwaSameMemory {
                max_anisotropy: 32.0,
            },
            Box,
        ),
        Contender::new("SAT", Filter::Sat(StripOptions::default()), Box),
        Contender::new("supersample 4", Filter::Supersample(2), Box),
        Contender::new("supersample 16", Filter::Supersample(4), Box),
        Contender::new("supersample 64", Filter::Supersample(8), Box),
    ]
}

/// Default filter options with a budget of `n` squares per region (≥ 1).
fn quadtree_budget(n: u64) -> FilterOptions {
    FilterOptions::default().with_budget(n).unwrap_or_default()
}
