//! What a render is asked to do: the texture filter, the pixel filter, the
//! output size.

use quadtex_core::FilterOptions;
use quadtex_core::baseline::StripOptions;

/// How pixels sample textures.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum TextureFilter {
    /// The method: each pixel's footprint filtered by
    /// [`quadtex_core::Texture::filter`] with these options. The default is
    /// [`FilterOptions::RENDER`]: the library's defaults with a budget of
    /// [`quadtex_core::SQUARE_BUDGET`] (64) squares a pixel region, which
    /// pixels near a horizon reach (the render summary reports their bounds).
    Quadtree(FilterOptions),
    /// The texel under the pixel centre (finest level), no filtering.
    Nearest,
    /// Bilinear interpolation of the finest level at the pixel centre.
    Bilinear,
    /// `n × n` stratified sub-pixel rays per pixel (one jittered ray per
    /// cell of an `n × n` grid; the cell centre when `n = 1`), each a nearest
    /// lookup.
    Supersample(u32),
    /// Baseline: trilinear mip-mapping after pbrt-v4 (level from the
    /// footprint's longest axis), on the tree rasterised at ≤ 4096².
    Trilinear,
    /// Baseline: pbrt-v4's elliptically weighted average on the same pyramid.
    Ewa {
        /// Largest major/minor axis ratio (pbrt's default: 8).
        max_anisotropy: f64,
    },
    /// Baseline: EWA as above on the largest raster that fits the tree's
    /// memory: `2^L` texels a side, RGBA8 with mips (16/3 bytes a texel,
    /// as a GPU stores it) within [`quadtex_core::QuadTree::memory_bytes`]
    /// ([`crate::scene::same_memory_level`]). What a user with the same
    /// memory budget would ship.
    EwaSameMemory {
        /// Largest major/minor axis ratio.
        max_anisotropy: f64,
    },
    /// Baseline: the strip pipeline ([`quadtex_core::baseline::filter_by_strips`],
    /// with these options' quality and weighting), integrated exactly by a
    /// summed-area table (f64) of the rasterised tree, no uniform shortcut.
    Sat(StripOptions),
}

impl Default for TextureFilter {
    fn default() -> Self {
        TextureFilter::Quadtree(FilterOptions::RENDER)
    }
}

/// The pixel's reconstruction filter in screen space (box, tent, Mitchell):
/// the core's [`quadtex_core::PixelFilter`]. The quadtree filter integrates
/// it exactly over each planar primitive's part of the support
/// (`crate::exact` in the source); supersampling weighs its samples by it.
pub use quadtex_core::PixelFilter;

/// The jitter stream references are rendered with
/// ([`RenderOptions::seed`]); contenders keep the default 0, so a reference
/// never shares its samples with a contender of the same sample count.
pub const REFERENCE_SEED: u64 = 0x5EED_0000_0000_0001;

/// Options of one render.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct RenderOptions {
    /// Override the camera's width (height follows unless also given).
    pub width: Option<u32>,
    /// Override the camera's height.
    pub height: Option<u32>,
    /// Texture filter.
    pub filter: TextureFilter,
    /// Pixel filter (for `Quadtree` and `Supersample`).
    pub pixel_filter: PixelFilter,
    /// The stream `Supersample` draws its jitter from (default 0). Two
    /// renders with different seeds draw independent samples: a reference
    /// must not share its seed with the contenders it judges.
    pub seed: u64,
}
