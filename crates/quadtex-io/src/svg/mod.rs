//! SVG art to [`VectorArt`] through `usvg` (parsing, CSS, `use`, transforms
//! and text-to-paths are its job), ready for [`QuadTree::from_vector`].
//!
//! ## What is supported
//!
//! Filled paths with solid colours and `fill-opacity`, both fill rules;
//! strokes (outlined by tiny-skia's stroker, dashes included, then filled
//! non-zero); groups with `opacity` (composited in isolation, then faded);
//! text, converted to paths with the font shipped in the crate (DejaVu Sans
//! Bold, printable ASCII; no system fonts are consulted, so every machine
//! gives the same tree); clip paths, exact (nested, with `clip-rule`,
//! `clipPathUnits` and `clip-path` on the clip path or on its children: a
//! clip region is a union of filled shapes intersected with other regions,
//! see [`VectorArt::clip_region`]); linear and radial gradients with
//! `gradientTransform`, `gradientUnits`, `spreadMethod`, stop opacity and
//! SVG 2's `fr`, interpolated in sRGB as SVG specifies (see
//! `quadtex_core::Gradient`; a radial gradient whose focal circle is not
//! inside its end circle is refused); patterns, exact (the content laid out
//! once per tile the shape reaches, clipped to the tile and the shape; at
//! most [`MAX_PATTERN_TILES`] tiles a fill); `mix-blend-mode` (every CSS
//! mode, `plus-lighter` included); images: PNG and JPEG, from data URLs or from
//! files named relative to the SVG, by default only inside the SVG's own
//! folder (see [`crate::ExternalResources`]; each texel a flat square; every square
//! of the tree gets the exact area mean of the texels it covers, see
//! `quadtex_core::image_paint`), and SVG images, walked as nested art
//! clipped to their size. An image that cannot be read (a missing file, a
//! corrupt one, a remote URL, which is never fetched) is an error naming
//! it, never dropped. Masks (luminance and alpha, nested, with their
//! rectangle; exact on flat content, bounded on gradients and images, see
//! [`VectorArt::begin_mask`]). Filters and images in GIF,
//! WebP or compressed SVG are refused with [`Error::UnsupportedSvg`]
//! naming the element, never approximated silently.
//!
//! ## Geometry
//!
//! The SVG's size (its `viewBox` after `usvg` resolves it) is scaled
//! uniformly so its **longer side spans the unit square**; the art sits at the
//! top-left corner (SVG `y` down becomes texture `z` up: `z = 1 − y/side`),
//! and a non-square drawing leaves the rest of the square transparent.
//! Curves are flattened to chords within `2^-(L+4)` of the true curve (a
//! sixteenth of a leaf's side at max level `L`).
//!
//! ## Colour
//!
//! sRGB colours are decoded to linear light and premultiplied by their
//! opacity; compositing is in linear light (see `quadtex_core::vector`), which
//! differs from browsers where translucent shapes overlap.

use std::collections::HashMap;
use std::path::Path;
use std::sync::{Arc, Mutex, OnceLock};

use quadtex_core::{Adjustable, BudgetFit, QuadTree, VectorArt, VectorOptions, VectorReport};
use quadtex_core::{ClipId, GroupId};

use crate::Error;
use crate::limits::Limits;

mod geometry;
mod paint;
#[cfg(test)]
mod tests;
mod walk;

pub use paint::MAX_PATTERN_TILES;

/// The font text is set in (DejaVu Sans Bold, subset to printable ASCII and
/// `°`; licence in `crates/quadtex-io/fonts/LICENSE`).
const FONT: &[u8] = include_bytes!("../../fonts/DejaVuSans-Bold-ascii.ttf");

const FAMILY: &str = "DejaVu Sans";

/// The font database: only the shipped font, under every generic family;
/// built once per process.
fn fonts() -> Arc<usvg::fontdb::Database> {
    static FONTS: OnceLock<Arc<usvg::fontdb::Database>> = OnceLock::new();
    FONTS
        .get_or_init(|| {
            let mut fonts = usvg::fontdb::Database::new();
            fonts.load_font_data(FONT.to_vec());
            fonts.set_serif_family(FAMILY);
            fonts.set_sans_serif_family(FAMILY);
            fonts.set_monospace_family(FAMILY);
            fonts.set_cursive_family(FAMILY);
            fonts.set_fantasy_family(FAMILY);
            Arc::new(fonts)
        })
        .clone()
}

/// How [`pack_svg`] reads and packs SVG art: the packer's options (level,
/// smooth-colour tolerance, gradient and contour leaves, budgets) and the
/// resource limits of reading. The default packs at level 12 with the
/// default smooth-colour tolerance ([`quadtex_core::DEFAULT_SMOOTH_TOLERANCE`])
/// under the default [`Limits`], and refuses art whose estimate is above
/// the memory budget; `adjustable` lets it lower the level instead.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct SvgOptions {
    /// The vector packer's options; their node and memory budgets are
    /// lowered to `limits`'.
    pub vector: VectorOptions,
    /// Limits on the file, its elements, images and memory.
    pub limits: Limits,
    /// The settings of `vector` the packer may change to fit the memory
    /// budget (see [`QuadTree::from_vector_within`]): those the user left
    /// at their defaults. `quadtex pack`, Python's `quadtex.pack` and C's
    /// `qtx_pack` leave the level to it when none is given, and the
    /// contour-leaf edge budget when contour leaves are asked for without
    /// one. None by default: settings that do not fit are refused.
    pub adjustable: Adjustable,
}

impl SvgOptions {
    /// The default options packing down to `max_level` (curves flattened to
    /// a sixteenth of a square there).
    pub fn at_level(max_level: u8) -> SvgOptions {
        SvgOptions {
            vector: VectorOptions {
                max_level,
                ..VectorOptions::default()
            },
            ..SvgOptions::default()
        }
    }

    /// These options with curves flattened to within `curve_tolerance` of
    /// the texture's longer side, in `[MIN_CURVE_TOLERANCE, 1]`, whatever
    /// the level.
    pub fn with_curve_tolerance(mut self, curve_tolerance: f64) -> SvgOptions {
        self.vector.curve_tolerance = Some(curve_tolerance);
        self
    }

    /// These options under `limits`.
    pub fn with_limits(mut self, limits: Limits) -> SvgOptions {
        self.limits = limits;
        self
    }
}

/// Reads an SVG file and packs it with `options` (level, tolerance, leaf
/// kinds, budgets and limits; see [`SvgOptions`]).
pub fn pack_svg(path: &Path, options: &SvgOptions) -> Result<(QuadTree, VectorReport), Error> {
    pack_svg_fitted(path, options).map(|(tree, report, _)| (tree, report))
}

/// [`pack_svg`], also returning the level and contour-leaf budget it
/// packed with, their estimated peak and the budget, and what was asked
/// for when `options.adjustable` let it change them to fit the budget
/// (to be said to the user).
pub fn pack_svg_fitted(
    path: &Path,
    options: &SvgOptions,
) -> Result<(QuadTree, VectorReport, BudgetFit), Error> {
    let SvgOptions {
        vector,
        limits,
        adjustable,
    } = options;
    let art = load_svg(path, options)?;
    let max_bytes = vector
        .max_bytes
        .map_or(limits.max_memory, |b| b.min(limits.max_memory));
    QuadTree::from_vector_within(
        &art,
        &VectorOptions {
            max_nodes: vector.max_nodes.min(limits.max_nodes),
            max_bytes: Some(max_bytes),
            ..*vector
        },
        *adjustable,
    )
    .map_err(crate::error::core(path))
}

/// Reads an SVG file into vector art flattened as `options` say (their
/// curve tolerance, or a sixteenth of a square at their level), under
/// their limits; see [`parse_svg`].
pub fn load_svg(path: &Path, options: &SvgOptions) -> Result<VectorArt, Error> {
    check_level(options.vector.max_level, path)?;
    let limits = &options.limits;
    let len = std::fs::metadata(path)
        .map_err(|source| Error::Io {
            path: path.to_path_buf(),
            source,
        })?
        .len();
    limits.check_file_size(path, len)?;
    let data = std::fs::read(path).map_err(|source| Error::Io {
        path: path.to_path_buf(),
        source,
    })?;
    parse_flattened(
        &data,
        path,
        options.vector.curve_tolerance_or_default(),
        limits,
    )
}

/// Refuses levels the vector packer cannot reach.
fn check_level(max_level: u8, path: &Path) -> Result<(), Error> {
    if max_level > quadtex_core::MAX_VECTOR_LEVEL {
        return Err(Error::Core {
            path: path.to_path_buf(),
            source: quadtex_core::Error::DepthTooLarge {
                depth: max_level.into(),
                max: quadtex_core::MAX_VECTOR_LEVEL.into(),
            },
        });
    }
    Ok(())
}

/// Finest curve flattening [`parse_svg`] accepts: 2⁻⁴⁰ of the
/// texture's side (below it, a curve's segments would outnumber what its
/// `f64` points resolve).
pub const MIN_CURVE_TOLERANCE: f64 = 1.0 / (1u64 << 40) as f64;

/// Parses SVG text into vector art flattened as `options` say (curves,
/// fills and stroke outlines within their curve tolerance of the true
/// curves, in units of the texture's longer side, in
/// `[MIN_CURVE_TOLERANCE, 1]`; by default a sixteenth of a square at their
/// level), under their limits; the art states its tolerance
/// ([`VectorArt::curve_tolerance`]). `path` names the source in errors.
pub fn parse_svg(data: &[u8], path: &Path, options: &SvgOptions) -> Result<VectorArt, Error> {
    check_level(options.vector.max_level, path)?;
    parse_flattened(
        data,
        path,
        options.vector.curve_tolerance_or_default(),
        &options.limits,
    )
}

/// [`parse_svg`] with the tolerance resolved.
fn parse_flattened(
    data: &[u8],
    path: &Path,
    curve_tolerance: f64,
    limits: &Limits,
) -> Result<VectorArt, Error> {
    let svg_err = |message: String| Error::Svg {
        path: path.to_path_buf(),
        message,
    };
    if !(MIN_CURVE_TOLERANCE..=1.0).contains(&curve_tolerance) {
        return Err(svg_err(format!(
            "curve tolerance {curve_tolerance} is outside [2^-40, 1]"
        )));
    }
    let text = std::str::from_utf8(data).map_err(|e| svg_err(format!("not UTF-8: {e}")))?;
    count_elements(text, path, limits)?;
    // usvg drops an image it cannot load without a word; the resolvers
    // record the first failure instead, so nothing is lost silently.
    let failure: Mutex<Option<Error>> = Mutex::new(None);
    let fail = |e: Error| {
        let mut f = failure.lock().unwrap_or_else(|p| p.into_inner());
        f.get_or_insert(e);
    };
    let options = usvg::Options {
        font_family: FAMILY.into(),
        fontdb: fonts(),
        resources_dir: path.parent().map(Path::to_path_buf),
        image_href_resolver: usvg::ImageHrefResolver {
            resolve_data: Box::new(|mime, data, opts| {
                resolve_image(mime, data, opts, path, limits).unwrap_or_else(|e| {
                    fail(e);
                    None
                })
            }),
            resolve_string: Box::new(|href, opts| {
                // Data URLs never get here (usvg hands them to `resolve_data`).
                let read = if href.contains("://") {
                    Err(svg_err(format!("image \"{href}\" is remote (not fetched)")))
                } else {
                    limits
                        .external_resources
                        .resolve(path, href)
                        .and_then(|file| read_limited(&file, limits).map(|data| (file, data)))
                        .map_err(|e| match e {
                            Error::ExternalResource { .. } => e,
                            e => svg_err(format!("image \"{href}\" could not be read: {e}")),
                        })
                };
                read.and_then(|(file, data)| {
                    resolve_image("text/plain", Arc::new(data), opts, &file, limits)
                })
                .unwrap_or_else(|e| {
                    fail(e);
                    None
                })
            }),
        },
        ..usvg::Options::default()
    };
    // usvg (through tiny-skia's stroker) can panic on hostile input (an
    // outline whose curvature search meets NaN, found by the SVG fuzz
    // target): caught here and reported as this file's error, not a crash.
    let parsed = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
        usvg::Tree::from_str(text, &options)
    }))
    .map_err(|panic| {
        let what = panic
            .downcast_ref::<&str>()
            .map(|s| (*s).to_string())
            .or_else(|| panic.downcast_ref::<String>().cloned())
            .unwrap_or_else(|| "a panic".to_string());
        svg_err(format!(
            "the SVG parser (usvg) failed on this document: {what}"
        ))
    })?;
    let tree = parsed.map_err(|e| svg_err(e.to_string()))?;
    drop(options);
    if let Some(e) = failure.into_inner().unwrap_or_else(|p| p.into_inner()) {
        return Err(e);
    }
    let size = tree.size();
    let side = f64::from(size.width().max(size.height()));
    let mut walker = Walker {
        art: VectorArt::new(),
        path,
        to_unit: 1.0 / side,
        tolerance: curve_tolerance,
        res_scale: (1.0 / (curve_tolerance * side)) as f32,
        groups: Vec::new(),
        clip: None,
        limits,
        image_texels: 0,
        flattened_points: 0,
        decoded: HashMap::new(),
    };
    walker.group(tree.root(), usvg::Transform::identity())?;
    walker.art.set_curve_tolerance(curve_tolerance);
    Ok(walker.art)
}

/// Refuses documents whose elements, with every `use` expanded, exceed
/// [`Limits::max_svg_elements`] (a `use` bomb), before `usvg` expands them.
fn count_elements(text: &str, path: &Path, limits: &Limits) -> Result<(), Error> {
    let doc = usvg::roxmltree::Document::parse_with_options(
        text,
        usvg::roxmltree::ParsingOptions {
            allow_dtd: true,
            ..Default::default()
        },
    )
    .map_err(|e| Error::Svg {
        path: path.to_path_buf(),
        message: e.to_string(),
    })?;
    let by_id: HashMap<&str, usvg::roxmltree::Node<'_, '_>> = doc
        .descendants()
        .filter_map(|n| n.attribute("id").map(|id| (id, n)))
        .collect();
    // Expanded size per node, memoised; `None` while being computed (a cycle).
    let mut memo: HashMap<usvg::roxmltree::NodeId, Option<u64>> = HashMap::new();
    let max = limits.max_svg_elements;
    let expanded = expanded_size(doc.root_element(), &by_id, &mut memo, max, 0);
    match expanded {
        Some(n) if n <= max => Ok(()),
        Some(n) => Err(Error::Limit {
            path: path.to_path_buf(),
            limit: "max_svg_elements",
            value: n,
            max,
        }),
        None => Err(Error::Svg {
            path: path.to_path_buf(),
            message: "`use` elements refer to each other in a cycle (or nest too deep)".into(),
        }),
    }
}

fn expanded_size<'a, 'i>(
    node: usvg::roxmltree::Node<'a, 'i>,
    by_id: &HashMap<&str, usvg::roxmltree::Node<'a, 'i>>,
    memo: &mut HashMap<usvg::roxmltree::NodeId, Option<u64>>,
    max: u64,
    depth: u32,
) -> Option<u64> {
    if depth > 256 {
        return None;
    }
    match memo.get(&node.id()) {
        Some(Some(n)) => return Some(*n),
        Some(None) => return None,
        None => {}
    }
    memo.insert(node.id(), None);
    let mut total = 1u64;
    for child in node.children().filter(|c| c.is_element()) {
        total = total.saturating_add(expanded_size(child, by_id, memo, max, depth + 1)?);
        if total > max {
            break;
        }
    }
    if node.tag_name().name() == "use" {
        let href = node
            .attribute(("http://www.w3.org/1999/xlink", "href"))
            .or_else(|| node.attribute("href"));
        if let Some(target) = href
            .and_then(|h| h.strip_prefix('#'))
            .and_then(|id| by_id.get(id))
        {
            total = total.saturating_add(expanded_size(*target, by_id, memo, max, depth + 1)?);
        }
    }
    memo.insert(node.id(), Some(total));
    Some(total)
}

struct Walker<'p> {
    art: VectorArt,
    path: &'p Path,
    /// SVG user units to unit-square units.
    to_unit: f64,
    /// Flattening tolerance in unit-square units.
    tolerance: f64,
    /// The stroker's resolution scale (device units per user unit).
    res_scale: f32,
    /// Enclosing translucent groups.
    groups: Vec<GroupId>,
    /// The clip region enclosing groups impose, if any.
    clip: Option<ClipId>,
    limits: &'p Limits,
    /// Texels of the images drawn so far, each pattern copy counted.
    image_texels: u64,
    /// Points of the paths flattened so far.
    flattened_points: usize,
    /// Images decoded so far, by the address of their bytes (a pattern
    /// draws the same image once per tile).
    decoded: HashMap<usize, Arc<quadtex_core::TexelGrid>>,
}

/// An image `data` (of `mime` type, `text/plain` to sniff) as usvg's kind,
/// refusing what quadtex would not draw: data that is no image, a nested
/// SVG that is malformed or expands past the element limit. `path` names
/// the data in errors.
fn resolve_image(
    mime: &str,
    data: Arc<Vec<u8>>,
    opts: &usvg::Options<'_>,
    path: &Path,
    limits: &Limits,
) -> Result<Option<usvg::ImageKind>, Error> {
    let svg_err = |message: String| Error::Svg {
        path: path.to_path_buf(),
        message,
    };
    limits.check_file_size(path, data.len() as u64)?;
    let magic = |m: &[u8]| data.starts_with(m);
    let raster = magic(b"\x89PNG")
        || magic(&[0xff, 0xd8, 0xff])
        || magic(b"GIF8")
        || (magic(b"RIFF") && data.get(8..12) == Some(b"WEBP"));
    let svg = mime == "image/svg+xml" || (mime == "text/plain" && !raster);
    if svg {
        if magic(&[0x1f, 0x8b]) {
            return Err(Error::UnsupportedSvg {
                path: path.to_path_buf(),
                element: "image in compressed SVG (svgz) format".into(),
            });
        }
        let text = std::str::from_utf8(&data)
            .map_err(|e| svg_err(format!("nested SVG image is not UTF-8: {e}")))?;
        count_elements(text, path, limits)?;
    }
    let unsupported = |format: &str| Error::UnsupportedSvg {
        path: path.to_path_buf(),
        element: format!("image in {format} format"),
    };
    if magic(b"GIF8") || mime == "image/gif" {
        return Err(unsupported("GIF"));
    }
    if magic(b"RIFF") || mime == "image/webp" {
        return Err(unsupported("WebP"));
    }
    if raster {
        // usvg skips an image whose size it cannot read, without a word.
        let (w, h) = image::ImageReader::new(std::io::Cursor::new(data.as_slice()))
            .with_guessed_format()
            .map_err(|e| svg_err(format!("image: {e}")))?
            .into_dimensions()
            .map_err(|e| svg_err(format!("image: {e}")))?;
        // And usvg 0.49 panics placing an image whose header claims a
        // side in the billions (the placed rectangle overflows f32), so
        // the side limit is checked before usvg sees it.
        limits.check_dimensions(path, w, h)?;
    }
    match usvg::ImageHrefResolver::default_data_resolver()(mime, data, opts) {
        Some(kind) => Ok(Some(kind)),
        None => Err(svg_err(format!(
            "an image of type \"{mime}\" could not be read (PNG, JPEG or SVG expected)"
        ))),
    }
}

/// The bytes of file `path`, refused beyond [`Limits::max_file_bytes`].
fn read_limited(path: &Path, limits: &Limits) -> Result<Vec<u8>, Error> {
    let io = |source| Error::Io {
        path: path.to_path_buf(),
        source,
    };
    let len = std::fs::metadata(path).map_err(io)?.len();
    limits.check_file_size(path, len)?;
    std::fs::read(path).map_err(io)
}
