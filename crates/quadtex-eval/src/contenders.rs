//! The filter configurations a comparison runs, in report order.

use quadtex_core::FilterOptions;
use quadtex_core::baseline::StripOptions;
use quadtex_render::{PixelFilter, TextureFilter};

/// A filter configuration taking part in a comparison.
#[derive(Debug, Clone, PartialEq)]
pub struct Contender {
    /// Short name for tables and plots.
    pub label: String,
    /// Texture filter.
    pub filter: TextureFilter,
    /// Pixel filter.
    pub pixel_filter: PixelFilter,
}

impl Contender {
    fn new(label: &str, filter: TextureFilter, pixel_filter: PixelFilter) -> Contender {
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
        Contender::new("quadtree", TextureFilter::default(), Box),
        Contender::new(
            "quadtree b1024",
            TextureFilter::Quadtree(quadtree_budget(1024)),
            Box,
        ),
        Contender::new("quadtree tent", TextureFilter::default(), Tent),
        Contender::new("nearest", TextureFilter::Nearest, Box),
        Contender::new("bilinear", TextureFilter::Bilinear, Box),
        Contender::new("trilinear", TextureFilter::Trilinear, Box),
        Contender::new(
            "EWA aniso 8",
            TextureFilter::Ewa {
                max_anisotropy: 8.0,
            },
            Box,
        ),
        Contender::new(
            "EWA aniso 32",
            TextureFilter::Ewa {
                max_anisotropy: 32.0,
            },
            Box,
        ),
        Contender::new(
            "EWA 32, same memory",
            TextureFilter::EwaSameMemory {
                max_anisotropy: 32.0,
            },
            Box,
        ),
        Contender::new("SAT", TextureFilter::Sat(StripOptions::default()), Box),
        Contender::new("supersample 4", TextureFilter::Supersample(2), Box),
        Contender::new("supersample 16", TextureFilter::Supersample(4), Box),
        Contender::new("supersample 64", TextureFilter::Supersample(8), Box),
    ]
}

/// Default filter options with a budget of `n` squares per region (≥ 1).
fn quadtree_budget(n: u64) -> FilterOptions {
    FilterOptions::default().with_budget(n).unwrap_or_default()
}
