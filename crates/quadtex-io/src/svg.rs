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
//! `quadtex_core::gradient`; a radial gradient whose focal circle is not
//! inside its end circle is refused); patterns, exact (the content laid out
//! once per tile the shape reaches, clipped to the tile and the shape; at
//! most [`MAX_PATTERN_TILES`] tiles a fill); `mix-blend-mode` (every CSS
//! mode, `plus-lighter` included); images: PNG and JPEG, from data URLs or from
//! files named relative to the SVG (each texel a flat square; every square
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

use quadtex_core::BlendMode;
use quadtex_core::ImagePaint;
use quadtex_core::{Circle, Gradient, Interpolation, Spread, Stop};
use quadtex_core::{ClipId, GroupId, MAX_VECTOR_COORDINATE, MAX_VECTOR_POINTS, MaskId, MaskKind};
use quadtex_core::{FillRule, Paint, QuadTree, Rgba, VectorArt, VectorOptions, VectorReport};
use usvg::tiny_skia_path::{self, PathSegment};

use crate::Error;
use crate::image_io::srgb_to_linear;
use crate::limits::Limits;

/// The font text is set in (DejaVu Sans Bold, subset to printable ASCII and
/// `°`; licence in `crates/quadtex-io/fonts/LICENSE`).
const FONT: &[u8] = include_bytes!("../fonts/DejaVuSans-Bold-ascii.ttf");

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

/// Reads an SVG file and packs it at `max_level`, gradients to the default
/// smooth-colour tolerance ([`quadtex_core::DEFAULT_SMOOTH_TOLERANCE`]).
pub fn pack_svg(
    path: &Path,
    max_level: u8,
    limits: &Limits,
) -> Result<(QuadTree, VectorReport), Error> {
    pack_svg_with_tolerance(
        path,
        max_level,
        quadtex_core::DEFAULT_SMOOTH_TOLERANCE,
        limits,
    )
}

/// As [`pack_svg`], with squares painted by gradients terminal once their
/// colour range is within `tolerance` ([`VectorOptions::tolerance`]).
pub fn pack_svg_with_tolerance(
    path: &Path,
    max_level: u8,
    tolerance: f64,
    limits: &Limits,
) -> Result<(QuadTree, VectorReport), Error> {
    pack_svg_with_options(
        path,
        &VectorOptions {
            max_level,
            tolerance,
            ..VectorOptions::default()
        },
        limits,
    )
}

/// As [`pack_svg`], with the packer's `options` (level, tolerance, whether
/// squares become gradient leaves); their node and memory budgets are
/// lowered to `limits`'.
pub fn pack_svg_with_options(
    path: &Path,
    options: &VectorOptions,
    limits: &Limits,
) -> Result<(QuadTree, VectorReport), Error> {
    check_level(options.max_level, path)?;
    let art = load_svg_flattened(path, options.curve_tolerance_or_default(), limits)?;
    let max_bytes = options
        .max_bytes
        .map_or(limits.max_memory, |b| b.min(limits.max_memory));
    QuadTree::from_vector(
        &art,
        &VectorOptions {
            max_nodes: options.max_nodes.min(limits.max_nodes),
            max_bytes: Some(max_bytes),
            ..*options
        },
    )
    .map_err(crate::error::core(path))
}

/// Reads an SVG file into vector art flattened for `max_level`.
pub fn load_svg(path: &Path, max_level: u8, limits: &Limits) -> Result<VectorArt, Error> {
    check_level(max_level, path)?;
    load_svg_flattened(path, level_curve_tolerance(max_level), limits)
}

/// Reads an SVG file into vector art whose curves are flattened to within
/// `curve_tolerance` of the texture's longer side (see
/// [`parse_svg_flattened`]).
pub fn load_svg_flattened(
    path: &Path,
    curve_tolerance: f64,
    limits: &Limits,
) -> Result<VectorArt, Error> {
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
    parse_svg_flattened(&data, path, curve_tolerance, limits)
}

/// Flattening for level `max_level`: a sixteenth of a square there.
fn level_curve_tolerance(max_level: u8) -> f64 {
    (-(f64::from(max_level) + 4.0)).exp2()
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

/// Finest curve flattening [`parse_svg_flattened`] accepts: 2⁻⁴⁰ of the
/// texture's side (below it, a curve's segments would outnumber what its
/// `f64` points resolve).
pub const MIN_CURVE_TOLERANCE: f64 = 1.0 / (1u64 << 40) as f64;

/// Parses SVG text into vector art flattened for `max_level` (curves
/// within a sixteenth of a square at that level); `path` names the source
/// in errors.
pub fn parse_svg(
    data: &[u8],
    path: &Path,
    max_level: u8,
    limits: &Limits,
) -> Result<VectorArt, Error> {
    check_level(max_level, path)?;
    parse_svg_flattened(data, path, level_curve_tolerance(max_level), limits)
}

/// Parses SVG text into vector art whose curves (fills and stroke
/// outlines) lie within `curve_tolerance` of the true curves, in units of
/// the texture's longer side, in `[MIN_CURVE_TOLERANCE, 1]`; the art
/// states it ([`VectorArt::curve_tolerance`]). `path` names the source in
/// errors.
pub fn parse_svg_flattened(
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
                let file = opts.get_abs_path(Path::new(href));
                let read = if href.contains("://") {
                    Err(svg_err(format!("image \"{href}\" is remote (not fetched)")))
                } else {
                    read_limited(&file, limits)
                        .map_err(|e| svg_err(format!("image \"{href}\" could not be read: {e}")))
                };
                read.and_then(|data| {
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

impl Walker<'_> {
    fn unsupported(&self, element: &str, id: &str) -> Error {
        Error::UnsupportedSvg {
            path: self.path.to_path_buf(),
            element: if id.is_empty() {
                element.to_string()
            } else {
                format!("{element} (id \"{id}\")")
            },
        }
    }

    /// Walks group `g` whose parent's absolute transform is `parent`.
    /// (Transforms are accumulated here, as resvg renders: usvg's
    /// `abs_transform` of a group that carries a clip path can miss the
    /// group's own transform.)
    fn group(&mut self, g: &usvg::Group, parent: usvg::Transform) -> Result<(), Error> {
        let transform = parent.pre_concat(g.transform());
        if let Some(filter) = g.filters().first() {
            // usvg moves the filtered element into an anonymous group; name the filter.
            return Err(self.unsupported("filter", filter.id()));
        }
        let blend = match g.blend_mode() {
            usvg::BlendMode::Normal => BlendMode::Normal,
            usvg::BlendMode::Multiply => BlendMode::Multiply,
            usvg::BlendMode::Screen => BlendMode::Screen,
            usvg::BlendMode::Overlay => BlendMode::Overlay,
            usvg::BlendMode::Darken => BlendMode::Darken,
            usvg::BlendMode::Lighten => BlendMode::Lighten,
            usvg::BlendMode::ColorDodge => BlendMode::ColorDodge,
            usvg::BlendMode::ColorBurn => BlendMode::ColorBurn,
            usvg::BlendMode::HardLight => BlendMode::HardLight,
            usvg::BlendMode::SoftLight => BlendMode::SoftLight,
            usvg::BlendMode::Difference => BlendMode::Difference,
            usvg::BlendMode::Exclusion => BlendMode::Exclusion,
            usvg::BlendMode::Hue => BlendMode::Hue,
            usvg::BlendMode::Saturation => BlendMode::Saturation,
            usvg::BlendMode::Color => BlendMode::Color,
            usvg::BlendMode::Luminosity => BlendMode::Luminosity,
            usvg::BlendMode::PlusLighter => BlendMode::PlusLighter,
        };
        let enclosing_clip = self.clip;
        if let Some(clip) = g.clip_path() {
            self.clip = Some(self.clip_region(clip, transform, enclosing_clip)?);
        }
        // A mask's own `mask` multiplies the masked content too (as resvg does).
        let mut masks = Vec::new();
        let mut next = g.mask();
        while let Some(mask) = next {
            masks.push(self.mask(mask, transform)?);
            next = mask.mask();
        }
        let opacity = f64::from(g.opacity().get());
        let pushed = opacity < 1.0 || blend != BlendMode::Normal || !masks.is_empty();
        if pushed {
            let id = self
                .art
                .masked_group(opacity, blend, &masks)
                .map_err(|e| self.core(e))?;
            self.groups.push(id);
        }
        for node in g.children() {
            match node {
                usvg::Node::Group(child) => self.group(child, transform)?,
                usvg::Node::Path(p) => self.path(p, transform)?,
                usvg::Node::Image(i) => self.image(i, transform)?,
                usvg::Node::Text(t) => self.group(t.flattened(), transform)?,
            }
        }
        if pushed {
            self.groups.pop();
        }
        self.clip = enclosing_clip;
        Ok(())
    }

    /// The content of `mask` applied under `transform` (the masked group's
    /// absolute transform): its children composited in isolation, within
    /// the mask's rectangle.
    fn mask(&mut self, mask: &usvg::Mask, transform: usvg::Transform) -> Result<MaskId, Error> {
        let kind = match mask.kind() {
            usvg::MaskType::Luminance => MaskKind::Luminance,
            usvg::MaskType::Alpha => MaskKind::Alpha,
        };
        let id = self.art.begin_mask(kind).map_err(|e| self.core(e))?;
        let r = mask.rect();
        let (x0, y0, x1, y1) = (r.left(), r.top(), r.right(), r.bottom());
        let k = self.to_unit;
        let m = affine(transform);
        let rect = [[x0, y0], [x1, y0], [x1, y1], [x0, y1]].map(|p| {
            let d = apply(m, p.map(f64::from));
            [k * d[0], 1.0 - k * d[1]]
        });
        let region = self.art.clip_region(&[]).map_err(|e| self.core(e))?;
        self.art
            .add_to_clip(region, vec![rect.to_vec()], FillRule::NonZero, None)
            .map_err(|e| self.core(e))?;
        let groups = std::mem::take(&mut self.groups);
        let enclosing = self.clip.replace(region);
        let result = self.group(mask.root(), transform);
        self.groups = groups;
        self.clip = enclosing;
        result?;
        self.art.end_mask(id).map_err(|e| self.core(e))?;
        Ok(id)
    }

    /// The region of `clip` applied under `transform` (the clipped group's
    /// absolute transform), within `within`: the union of its children's
    /// fills (strokes and paint do not matter, as in SVG), each child group
    /// within its own `clip-path`, all within the clip path's own `clip-path`.
    fn clip_region(
        &mut self,
        clip: &usvg::ClipPath,
        transform: usvg::Transform,
        within: Option<ClipId>,
    ) -> Result<ClipId, Error> {
        let mut regions: Vec<ClipId> = within.into_iter().collect();
        if let Some(nested) = clip.clip_path() {
            regions.push(self.clip_region(nested, transform, None)?);
        }
        let region = self.art.clip_region(&regions).map_err(|e| self.core(e))?;
        self.clip_members(
            region,
            clip.root(),
            transform.pre_concat(clip.transform()),
            None,
        )?;
        Ok(region)
    }

    fn clip_members(
        &mut self,
        region: ClipId,
        group: &usvg::Group,
        transform: usvg::Transform,
        member_clip: Option<ClipId>,
    ) -> Result<(), Error> {
        for node in group.children() {
            match node {
                usvg::Node::Path(p) => {
                    let Some(fill) = p.fill().filter(|_| p.is_visible()) else {
                        continue;
                    };
                    let rule = fill_rule(fill.rule());
                    let contours = self.flatten(p.data(), transform)?;
                    self.art
                        .add_to_clip(region, contours, rule, member_clip)
                        .map_err(|e| self.core(e))?;
                }
                usvg::Node::Text(t) => {
                    self.clip_members(region, t.flattened(), transform, member_clip)?
                }
                usvg::Node::Group(g) => {
                    let t = transform.pre_concat(g.transform());
                    let inner = match g.clip_path() {
                        Some(c) => Some(self.clip_region(c, t, member_clip)?),
                        None => member_clip,
                    };
                    self.clip_members(region, g, t, inner)?;
                }
                // Images do not clip (SVG 1.1 allows shapes and text only).
                usvg::Node::Image(_) => {}
            }
        }
        Ok(())
    }

    fn core(&self, source: quadtex_core::Error) -> Error {
        Error::Core {
            path: self.path.to_path_buf(),
            source,
        }
    }

    /// The core paint of `paint` with `opacity`, for a path drawn under
    /// `transform` (gradients are defined in the path's user space).
    fn paint(
        &self,
        paint: &usvg::Paint,
        opacity: f32,
        transform: usvg::Transform,
        id: &str,
    ) -> Result<Option<Paint>, Error> {
        let opacity = f64::from(opacity);
        let (base, geometry): (&usvg::BaseGradient, _) = match paint {
            usvg::Paint::Color(c) => {
                let rgb = [c.red, c.green, c.blue].map(|v| f64::from(v) / 255.0);
                return Ok(Some(solid(rgb, opacity)));
            }
            usvg::Paint::LinearGradient(g) => (g, GradientGeometry::Linear(g)),
            usvg::Paint::RadialGradient(g) => (g, GradientGeometry::Radial(g)),
            // Patterns are laid out as shapes by `Walker::pattern`.
            usvg::Paint::Pattern(_) => return Ok(None),
        };
        let stops: Vec<Stop> = base
            .stops()
            .iter()
            .map(|s| Stop {
                offset: f64::from(s.offset().get()),
                colour: [s.color().red, s.color().green, s.color().blue]
                    .map(|v| f64::from(v) / 255.0),
                opacity: f64::from(s.opacity().get()) * opacity,
            })
            .collect();
        let spread = match base.spread_method() {
            usvg::SpreadMethod::Pad => Spread::Pad,
            usvg::SpreadMethod::Reflect => Spread::Reflect,
            usvg::SpreadMethod::Repeat => Spread::Repeat,
        };
        // Texture space → device (user units) → the path's user space → gradient space.
        let device_to_gradient = match invert(concat(affine(transform), affine(base.transform()))) {
            Some(m) => m,
            None => return Ok(None), // a degenerate transform paints nothing
        };
        let k = self.to_unit;
        let [sx, ky, kx, sy, tx, ty] = device_to_gradient;
        // p = (k·dx, 1 − k·dy)  ⇒  dx = x/k, dy = (1 − z)/k.
        let map = [sx / k, ky / k, -kx / k, -sy / k, kx / k + tx, sy / k + ty];
        let interpolation = Interpolation::Srgb;
        let gradient = match geometry {
            GradientGeometry::Linear(g) => {
                let (start, end) = (
                    [f64::from(g.x1()), f64::from(g.y1())],
                    [f64::from(g.x2()), f64::from(g.y2())],
                );
                if start == end {
                    // SVG: the last stop's colour, flat.
                    let Some(last) = stops.last() else {
                        return Ok(None);
                    };
                    return Ok(Some(solid(last.colour, last.opacity)));
                }
                Gradient::linear(map, start, end, stops, spread, interpolation)
                    .map_err(|e| self.core(e))?
            }
            GradientGeometry::Radial(g) => Gradient::radial(
                map,
                Circle {
                    centre: [f64::from(g.fx()), f64::from(g.fy())],
                    radius: f64::from(g.fr().get()),
                },
                Circle {
                    centre: [f64::from(g.cx()), f64::from(g.cy())],
                    radius: f64::from(g.r().get()),
                },
                stops,
                spread,
                interpolation,
            )
            .map_err(|_| {
                self.unsupported(
                    "radialGradient with the focal circle not inside the end circle",
                    id,
                )
            })?,
        };
        Ok(Some(Paint::Gradient(gradient)))
    }

    fn path(&mut self, p: &usvg::Path, transform: usvg::Transform) -> Result<(), Error> {
        if !p.is_visible() {
            return Ok(());
        }
        let fill = |w: &mut Self| -> Result<(), Error> {
            if let Some(f) = p.fill() {
                let rule = fill_rule(f.rule());
                let contours = w.flatten(p.data(), transform)?;
                w.fill_with(
                    f.paint(),
                    f.opacity().get(),
                    transform,
                    contours,
                    rule,
                    p.id(),
                )?;
            }
            Ok(())
        };
        let stroke = |w: &mut Self| -> Result<(), Error> {
            if let Some(s) = p.stroke() {
                let ts = s.to_tiny_skia();
                // Scale the stroker's precision with the transform's largest stretch.
                let stretch = (transform.sx.hypot(transform.ky))
                    .max(transform.kx.hypot(transform.sy))
                    .max(1e-6);
                let res = w.res_scale * stretch;
                let dashed;
                let source = match &ts.dash {
                    Some(d) => match p.data().dash(d, res) {
                        Some(path) => {
                            dashed = path;
                            &dashed
                        }
                        None => return Ok(()),
                    },
                    None => p.data(),
                };
                if let Some(outline) = source.stroke(&ts, res) {
                    let contours = w.flatten(&outline, transform)?;
                    let (paint, opacity) = (s.paint(), s.opacity().get());
                    w.fill_with(
                        paint,
                        opacity,
                        transform,
                        contours,
                        FillRule::NonZero,
                        p.id(),
                    )?;
                }
            }
            Ok(())
        };
        match p.paint_order() {
            usvg::PaintOrder::FillAndStroke => {
                fill(self)?;
                stroke(self)
            }
            usvg::PaintOrder::StrokeAndFill => {
                stroke(self)?;
                fill(self)
            }
        }
    }

    /// Fills `contours` (texture space, of a path drawn under `transform`)
    /// with `paint` at `opacity`.
    fn fill_with(
        &mut self,
        paint: &usvg::Paint,
        opacity: f32,
        transform: usvg::Transform,
        contours: Vec<Vec<[f64; 2]>>,
        rule: FillRule,
        id: &str,
    ) -> Result<(), Error> {
        if let usvg::Paint::Pattern(pattern) = paint {
            return self.pattern(pattern, opacity, transform, contours, rule, id);
        }
        match self.paint(paint, opacity, transform, id)? {
            Some(paint) => self.add(contours, rule, paint),
            None => Ok(()),
        }
    }

    /// A pattern fill, exact: the pattern's content is laid out once per
    /// tile the shape reaches, each copy clipped to its tile and to the
    /// shape (clip regions), as a group faded by `opacity`. Tiles are the
    /// pattern's `rect` repeated in pattern space; the content is in tile
    /// coordinates, as resvg renders it.
    fn pattern(
        &mut self,
        pattern: &usvg::Pattern,
        opacity: f32,
        transform: usvg::Transform,
        contours: Vec<Vec<[f64; 2]>>,
        rule: FillRule,
        id: &str,
    ) -> Result<(), Error> {
        let rect = pattern.rect();
        let (x, y, w, h) = (
            f64::from(rect.x()),
            f64::from(rect.y()),
            f64::from(rect.width()),
            f64::from(rect.height()),
        );
        // Texture space → device → pattern space.
        let to_pattern = match invert(concat(affine(transform), affine(pattern.transform()))) {
            Some(m) => m,
            None => return Ok(()),
        };
        let k = self.to_unit;
        let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
        for p in contours.iter().flatten() {
            let d = [p[0] / k, (1.0 - p[1]) / k];
            let q = apply(to_pattern, d);
            for a in 0..2 {
                lo[a] = lo[a].min(q[a]);
                hi[a] = hi[a].max(q[a]);
            }
        }
        if !(lo[0] <= hi[0] && lo[1] <= hi[1]) {
            return Ok(()); // no contour
        }
        let (i0, i1) = (((lo[0] - x) / w).floor(), ((hi[0] - x) / w).floor());
        let (j0, j1) = (((lo[1] - y) / h).floor(), ((hi[1] - y) / h).floor());
        let tiles = (i1 - i0 + 1.0) * (j1 - j0 + 1.0);
        if tiles.is_nan() || tiles > MAX_PATTERN_TILES {
            return Err(self.unsupported(
                &format!("pattern repeated over more than {MAX_PATTERN_TILES} tiles"),
                id,
            ));
        }
        let shape = self
            .art
            .clip_region(self.clip.as_slice())
            .map_err(|e| self.core(e))?;
        self.art
            .add_to_clip(shape, contours, rule, None)
            .map_err(|e| self.core(e))?;
        let faded = f64::from(opacity) < 1.0;
        if faded {
            let g = self
                .art
                .group(f64::from(opacity))
                .map_err(|e| self.core(e))?;
            self.groups.push(g);
        }
        let enclosing = self.clip;
        let mut j = j0;
        while j <= j1 {
            let mut i = i0;
            while i <= i1 {
                let tile = transform
                    .pre_concat(pattern.transform())
                    .pre_translate((x + i * w) as f32, (y + j * h) as f32);
                let m = affine(tile);
                let corners = [[0.0, 0.0], [w, 0.0], [w, h], [0.0, h]].map(|p| {
                    let d = apply(m, p);
                    [k * d[0], 1.0 - k * d[1]]
                });
                let region = self.art.clip_region(&[shape]).map_err(|e| self.core(e))?;
                self.art
                    .add_to_clip(region, vec![corners.to_vec()], FillRule::NonZero, None)
                    .map_err(|e| self.core(e))?;
                self.clip = Some(region);
                let result = self.group(pattern.root(), tile);
                self.clip = enclosing;
                result?;
                i += 1.0;
            }
            j += 1.0;
        }
        if faded {
            self.groups.pop();
        }
        Ok(())
    }

    /// An image drawn under `transform` (usvg places it at the origin of its
    /// user space, one unit a pixel, its `preserveAspectRatio` turned into a
    /// transform and a clip): a raster becomes its rectangle painted with its
    /// texels (exact area means, see `quadtex_core::image_paint`); a nested
    /// SVG is walked like a group, clipped to its size.
    fn image(&mut self, image: &usvg::Image, transform: usvg::Transform) -> Result<(), Error> {
        if !image.is_visible() {
            return Ok(());
        }
        let size = image.size();
        let (w, h) = (f64::from(size.width()), f64::from(size.height()));
        let k = self.to_unit;
        let m = affine(transform);
        let rect = [[0.0, 0.0], [w, 0.0], [w, h], [0.0, h]].map(|p| {
            let d = apply(m, p);
            [k * d[0], 1.0 - k * d[1]]
        });
        let data = match image.kind() {
            usvg::ImageKind::PNG(data) | usvg::ImageKind::JPEG(data) => data,
            usvg::ImageKind::GIF(_) => {
                return Err(self.unsupported("image in GIF format", image.id()));
            }
            usvg::ImageKind::WEBP(_) => {
                return Err(self.unsupported("image in WebP format", image.id()));
            }
            usvg::ImageKind::SVG(tree) => {
                let enclosing = self.clip;
                let region = self
                    .art
                    .clip_region(enclosing.as_slice())
                    .map_err(|e| self.core(e))?;
                self.art
                    .add_to_clip(region, vec![rect.to_vec()], FillRule::NonZero, None)
                    .map_err(|e| self.core(e))?;
                self.clip = Some(region);
                let result = self.group(tree.root(), transform);
                self.clip = enclosing;
                return result;
            }
        };
        let key = Arc::as_ptr(data) as usize;
        let texels = match self.decoded.get(&key) {
            Some(t) => Arc::clone(t),
            None => {
                let t = Arc::new(crate::image_io::load_texels_from_bytes(
                    data,
                    self.path,
                    self.limits,
                )?);
                self.decoded.insert(key, Arc::clone(&t));
                t
            }
        };
        self.image_texels = self
            .image_texels
            .saturating_add(u64::from(texels.width()) * u64::from(texels.height()));
        if self.image_texels > self.limits.max_svg_image_texels {
            return Err(Error::Limit {
                path: self.path.to_path_buf(),
                limit: "max_svg_image_texels",
                value: self.image_texels,
                max: self.limits.max_svg_image_texels,
            });
        }
        // Texture → device (user units) → the image's user space → texels.
        let texture_to_device = [1.0 / k, 0.0, 0.0, -1.0 / k, 0.0, 1.0 / k];
        let Some(device_to_local) = invert(m) else {
            return Ok(()); // a degenerate transform draws nothing
        };
        let local_to_texels = [
            f64::from(texels.width()) / w,
            0.0,
            0.0,
            f64::from(texels.height()) / h,
            0.0,
            0.0,
        ];
        let placement = concat(local_to_texels, concat(device_to_local, texture_to_device));
        let paint = ImagePaint::new(texels, placement).map_err(|e| self.core(e))?;
        self.add(vec![rect.to_vec()], FillRule::NonZero, Paint::Image(paint))
    }

    fn add(
        &mut self,
        contours: Vec<Vec<[f64; 2]>>,
        rule: FillRule,
        paint: Paint,
    ) -> Result<(), Error> {
        let groups = self.groups.clone();
        self.art
            .fill_paint(contours, rule, paint, &groups, self.clip)
            .map_err(|e| self.core(e))
    }

    /// The path's contours in unit-square coordinates, curves flattened.
    /// Refused before they are made: a point beyond the packer's
    /// coordinate bound, and more points in all than the packer takes (a
    /// circle stroked at a radius of 10¹⁹ flattened to 2 GB).
    fn flatten(
        &mut self,
        path: &tiny_skia_path::Path,
        t: usvg::Transform,
    ) -> Result<Vec<Vec<[f64; 2]>>, Error> {
        let (sx, kx, ky, sy, tx, ty) = (
            f64::from(t.sx),
            f64::from(t.kx),
            f64::from(t.ky),
            f64::from(t.sy),
            f64::from(t.tx),
            f64::from(t.ty),
        );
        let k = self.to_unit;
        let svg = self.path;
        let map = |p: tiny_skia_path::Point| -> Result<[f64; 2], Error> {
            let (x, y) = (f64::from(p.x), f64::from(p.y));
            let q = [k * (sx * x + kx * y + tx), 1.0 - k * (ky * x + sy * y + ty)];
            if q.iter().all(|v| v.abs() <= MAX_VECTOR_COORDINATE) {
                Ok(q)
            } else {
                Err(Error::Svg {
                    path: svg.to_path_buf(),
                    message: format!(
                        "a path point lands at {q:?} in texture units (the view box's longer side is 1), beyond ±{MAX_VECTOR_COORDINATE:e}"
                    ),
                })
            }
        };
        let points = &mut self.flattened_points;
        let mut spend = |n: usize| -> Result<(), Error> {
            *points += n;
            if *points > MAX_VECTOR_POINTS {
                return Err(Error::Svg {
                    path: svg.to_path_buf(),
                    message: format!(
                        "its paths flatten to more than {MAX_VECTOR_POINTS} points (curves drawn far outside the view box?)"
                    ),
                });
            }
            Ok(())
        };
        let tol = self.tolerance;
        let mut contours = Vec::new();
        let mut current: Vec<[f64; 2]> = Vec::new();
        for seg in path.segments() {
            match seg {
                PathSegment::MoveTo(p) => {
                    if current.len() >= 3 {
                        contours.push(std::mem::take(&mut current));
                    }
                    current.clear();
                    spend(1)?;
                    current.push(map(p)?);
                }
                PathSegment::LineTo(p) => {
                    spend(1)?;
                    current.push(map(p)?);
                }
                PathSegment::QuadTo(c, p) => {
                    let p0 = *current.last().unwrap_or(&[0.0, 0.0]);
                    let (p1, p2) = (map(c)?, map(p)?);
                    let d = norm(sub(add(p0, p2), scale(p1, 2.0)));
                    let n = segments_for(d / (4.0 * tol));
                    spend(n)?;
                    for i in 1..=n {
                        let t = i as f64 / n as f64;
                        let u = 1.0 - t;
                        current.push(add(
                            add(scale(p0, u * u), scale(p1, 2.0 * u * t)),
                            scale(p2, t * t),
                        ));
                    }
                }
                PathSegment::CubicTo(c1, c2, p) => {
                    let p0 = *current.last().unwrap_or(&[0.0, 0.0]);
                    let (p1, p2, p3) = (map(c1)?, map(c2)?, map(p)?);
                    let d = norm(sub(add(p0, p2), scale(p1, 2.0)))
                        .max(norm(sub(add(p1, p3), scale(p2, 2.0))));
                    let n = segments_for(3.0 * d / (4.0 * tol));
                    spend(n)?;
                    for i in 1..=n {
                        let t = i as f64 / n as f64;
                        let u = 1.0 - t;
                        let q = add(
                            add(scale(p0, u * u * u), scale(p1, 3.0 * u * u * t)),
                            add(scale(p2, 3.0 * u * t * t), scale(p3, t * t * t)),
                        );
                        current.push(q);
                    }
                }
                PathSegment::Close => {
                    if current.len() >= 3 {
                        contours.push(std::mem::take(&mut current));
                    }
                    current.clear();
                }
            }
        }
        if current.len() >= 3 {
            contours.push(current);
        }
        Ok(contours)
    }
}

/// Most tiles one pattern fill is laid out over (each tile copies the
/// pattern's content).
pub const MAX_PATTERN_TILES: f64 = 4096.0;

fn fill_rule(rule: usvg::FillRule) -> FillRule {
    match rule {
        usvg::FillRule::NonZero => FillRule::NonZero,
        usvg::FillRule::EvenOdd => FillRule::EvenOdd,
    }
}

/// A flat paint from sRGB-encoded channels in `[0,1]` and an opacity.
fn solid(rgb: [f64; 3], opacity: f64) -> Paint {
    let a = opacity as f32;
    let lin = |v: f64| srgb_to_linear(v as f32) * a;
    Paint::Solid(Rgba::new(lin(rgb[0]), lin(rgb[1]), lin(rgb[2]), a))
}

enum GradientGeometry<'a> {
    Linear(&'a usvg::LinearGradient),
    Radial(&'a usvg::RadialGradient),
}

/// A transform as `[sx, ky, kx, sy, tx, ty]` in `f64`:
/// `x' = sx·x + kx·y + tx`, `y' = ky·x + sy·y + ty`.
fn affine(t: usvg::Transform) -> [f64; 6] {
    [t.sx, t.ky, t.kx, t.sy, t.tx, t.ty].map(f64::from)
}

/// `m` applied to point `p`.
fn apply(m: [f64; 6], p: [f64; 2]) -> [f64; 2] {
    [
        m[0] * p[0] + m[2] * p[1] + m[4],
        m[1] * p[0] + m[3] * p[1] + m[5],
    ]
}

/// `a ∘ b` (apply `b` first).
fn concat(a: [f64; 6], b: [f64; 6]) -> [f64; 6] {
    let [a0, a1, a2, a3, a4, a5] = a;
    let [b0, b1, b2, b3, b4, b5] = b;
    [
        a0 * b0 + a2 * b1,
        a1 * b0 + a3 * b1,
        a0 * b2 + a2 * b3,
        a1 * b2 + a3 * b3,
        a0 * b4 + a2 * b5 + a4,
        a1 * b4 + a3 * b5 + a5,
    ]
}

fn invert(m: [f64; 6]) -> Option<[f64; 6]> {
    let [a, b, c, d, e, f] = m;
    let det = a * d - b * c;
    if !(det.is_finite() && det.abs() > f64::MIN_POSITIVE) {
        return None;
    }
    let inv = [d / det, -b / det, -c / det, a / det];
    let r = [
        inv[0],
        inv[1],
        inv[2],
        inv[3],
        -(inv[0] * e + inv[2] * f),
        -(inv[1] * e + inv[3] * f),
    ];
    r.iter().all(|v| v.is_finite()).then_some(r)
}

/// Chords needed for a curve whose error bound with one chord is `ratio`
/// tolerances (the error falls as `1/n²`); at most 65536.
fn segments_for(ratio: f64) -> usize {
    if ratio.is_finite() {
        ratio.sqrt().ceil().clamp(1.0, 65536.0) as usize
    } else {
        1
    }
}

fn add(a: [f64; 2], b: [f64; 2]) -> [f64; 2] {
    [a[0] + b[0], a[1] + b[1]]
}
fn sub(a: [f64; 2], b: [f64; 2]) -> [f64; 2] {
    [a[0] - b[0], a[1] - b[1]]
}
fn scale(a: [f64; 2], k: f64) -> [f64; 2] {
    [a[0] * k, a[1] * k]
}
fn norm(a: [f64; 2]) -> f64 {
    a[0].hypot(a[1])
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;
    use quadtex_core::Fragment;

    /// The packed alpha integral over the unit square (the root colour,
    /// within one 16-bit step) of an SVG 100 units wide.
    fn coverage(svg: &str) -> f64 {
        let art = parse_svg(svg.as_bytes(), Path::new("t.svg"), 8, &Limits::default()).unwrap();
        let options = VectorOptions {
            max_level: 8,
            ..VectorOptions::default()
        };
        let (tree, _) = QuadTree::from_vector(&art, &options).unwrap();
        let f = Fragment::new(0.0, 0.0, 1.0, 1.0).unwrap();
        tree.weighted_colour(&f, 8).0[3]
    }

    /// A circle flattened to a stated tolerance, packed with contour
    /// leaves: where its edge crosses a small fragment, the covered area
    /// is within `tolerance × arc length` of the true circle's (and, for a
    /// coarse tolerance, visibly not the true one).
    #[test]
    fn curves_are_flattened_to_the_stated_tolerance() {
        let svg = r#"<svg xmlns="http://www.w3.org/2000/svg" viewBox="0 0 100 100"><circle cx="50" cy="50" r="40"/></svg>"#;
        let (r, w) = (0.4, 0.004);
        let f = Fragment::new(0.5 - w, 0.1 - w, 0.5 + w, 0.1 + w).unwrap();
        // The true circle's area in the fragment (its edge nearly level
        // there): ∫ (z1 − max(z0, 0.5 − √(r² − (x − 0.5)²))) dx, Simpson.
        let n = 20_000;
        let inside = |x: f64| f.z1() - f.z0().max(0.5 - (r * r - (x - 0.5) * (x - 0.5)).sqrt());
        let h = (f.x1() - f.x0()) / f64::from(n);
        let mut truth = inside(f.x0()) + inside(f.x1());
        for i in 1..n {
            truth += inside(f.x0() + f64::from(i) * h) * if i % 2 == 1 { 4.0 } else { 2.0 };
        }
        truth *= h / 3.0;
        for tolerance in [1e-6, 1e-3] {
            let art = parse_svg_flattened(
                svg.as_bytes(),
                Path::new("c.svg"),
                tolerance,
                &Limits::default(),
            )
            .unwrap();
            assert_eq!(art.curve_tolerance(), Some(tolerance));
            let options = VectorOptions {
                max_level: 20,
                contour_leaves: Some(16),
                ..VectorOptions::default()
            };
            let (tree, _) = QuadTree::from_vector(&art, &options).unwrap();
            assert_eq!(
                tree.contour_leaves().unwrap().curve_tolerance(),
                Some(tolerance)
            );
            let got = tree.weighted_colour(&f, u8::MAX).0[3];
            let bound = tolerance * 2.0 * w * 1.01;
            assert!(
                (got - truth).abs() <= bound,
                "{tolerance}: {got} vs {truth}, bound {bound}"
            );
            if tolerance >= 1e-3 {
                assert!((got - truth).abs() > 0.01 * bound, "{got} vs {truth}");
            }
        }
        let refused = parse_svg_flattened(
            svg.as_bytes(),
            Path::new("c.svg"),
            1e-13,
            &Limits::default(),
        );
        assert!(refused.unwrap_err().to_string().contains("curve tolerance"));
    }

    #[test]
    fn clip_paths_cut_exact_areas() {
        let head = r#"<svg xmlns="http://www.w3.org/2000/svg" viewBox="0 0 100 100">"#;
        // A 60×60 square clipped by a 20×50 rectangle moved by the clip
        // path's own transform: 20×40 remain.
        let moved = format!(
            r#"{head}<clipPath id="c"><rect x="0" y="0" width="20" height="50"
            transform="translate(30 40)"/></clipPath>
            <rect x="20" y="20" width="60" height="60" clip-path="url(#c)"/></svg>"#
        );
        assert!(
            (coverage(&moved) - 0.08).abs() < 2e-5,
            "{}",
            coverage(&moved)
        );
        // objectBoundingBox units: the left half of the square's box.
        let bbox = format!(
            r#"{head}<clipPath id="c" clipPathUnits="objectBoundingBox">
            <rect x="0" y="0" width="0.5" height="1"/></clipPath>
            <rect x="20" y="20" width="60" height="60" clip-path="url(#c)"/></svg>"#
        );
        assert!((coverage(&bbox) - 0.18).abs() < 2e-5, "{}", coverage(&bbox));
        // A clip path clipped by another: two overlapping bands leave 20×20.
        let nested = format!(
            r#"{head}<clipPath id="a"><rect x="0" y="40" width="100" height="20"/></clipPath>
            <clipPath id="b" clip-path="url(#a)"><rect x="40" y="0" width="20" height="100"/></clipPath>
            <rect x="0" y="0" width="100" height="100" clip-path="url(#b)"/></svg>"#
        );
        assert!(
            (coverage(&nested) - 0.04).abs() < 2e-5,
            "{}",
            coverage(&nested)
        );
        // clip-rule evenodd on a doubled square cuts the whole square away.
        let evenodd = format!(
            r#"{head}<clipPath id="c"><path clip-rule="evenodd"
            d="M10 10h50v50h-50z M10 10h50v50h-50z"/></clipPath>
            <rect x="0" y="0" width="100" height="100" clip-path="url(#c)"/></svg>"#
        );
        assert!(coverage(&evenodd).abs() < 2e-5, "{}", coverage(&evenodd));
    }

    #[test]
    fn patterns_tile_exactly() {
        // Black 10×10 squares every 20 units, filling 5..95 on both axes:
        // 45 units a side are black, 0.2025 of the square.
        let svg = r#"<svg xmlns="http://www.w3.org/2000/svg" viewBox="0 0 100 100">
            <pattern id="p" width="20" height="20" patternUnits="userSpaceOnUse">
            <rect width="10" height="10"/></pattern>
            <rect x="5" y="5" width="90" height="90" fill="url(#p)"/></svg>"#;
        assert!((coverage(svg) - 0.2025).abs() < 2e-5, "{}", coverage(svg));
        // Half opacity fades the whole pattern.
        let faded = svg.replace(r#"fill="url(#p)""#, r#"fill="url(#p)" fill-opacity="0.5""#);
        assert!(
            (coverage(&faded) - 0.10125).abs() < 2e-5,
            "{}",
            coverage(&faded)
        );
    }

    #[test]
    fn multiply_blends_encoded_colours_exactly() {
        // Opaque #808080 multiplied onto opaque #ff4000 over the whole square:
        // encoded (0.502·1, 0.502·0.251, 0), decoded.
        let svg = r##"<svg xmlns="http://www.w3.org/2000/svg" viewBox="0 0 10 10">
            <rect width="10" height="10" fill="#ff4000"/>
            <rect width="10" height="10" fill="#808080" style="mix-blend-mode:multiply"/></svg>"##;
        let art = parse_svg(svg.as_bytes(), Path::new("t.svg"), 2, &Limits::default()).unwrap();
        let (tree, _) = QuadTree::from_vector(&art, &VectorOptions::default()).unwrap();
        let f = Fragment::new(0.0, 0.0, 1.0, 1.0).unwrap();
        let got = tree.weighted_colour(&f, 0).0;
        let g = 128.0 / 255.0;
        let want = [g, g * 64.0 / 255.0, 0.0].map(quadtex_core::srgb_decode);
        for k in 0..3 {
            assert!(
                (got[k] - want[k]).abs() < 2e-5,
                "channel {k}: {} vs {}",
                got[k],
                want[k]
            );
        }
    }

    /// A 2×2 PNG: red, green / blue, white.
    const PNG_2X2: &str = "iVBORw0KGgoAAAANSUhEUgAAAAIAAAACCAIAAAD91JpzAAAAEklEQVR4nGP4z8DAAMIM/4EAAB/uBfsL2WiLAAAAAElFTkSuQmCC";

    #[test]
    fn an_embedded_image_packs_to_its_exact_texel_means() {
        let svg = format!(
            r#"<svg xmlns="http://www.w3.org/2000/svg" viewBox="0 0 10 10">
            <image width="10" height="10" href="data:image/png;base64,{PNG_2X2}"/></svg>"#
        );
        let art = parse_svg(svg.as_bytes(), Path::new("t.svg"), 4, &Limits::default()).unwrap();
        let (tree, report) = QuadTree::from_vector(
            &art,
            &VectorOptions {
                max_level: 4,
                ..VectorOptions::default()
            },
        )
        .unwrap();
        assert_eq!(report.max_mean_error, 0.0);
        // Texture z is up: the top-left quadrant is texel (0, 0), red.
        let mean = |x0: f64, z0: f64| {
            let f = Fragment::new(x0, z0, x0 + 0.5, z0 + 0.5).unwrap();
            tree.weighted_colour(&f, 4).0.map(|v| v / 0.25)
        };
        let quadrant = mean;
        let close = |a: [f64; 4], b: [f64; 4]| (0..4).all(|k| (a[k] - b[k]).abs() < 1e-4);
        assert!(
            close(quadrant(0.0, 0.5), [1.0, 0.0, 0.0, 1.0]),
            "{:?}",
            quadrant(0.0, 0.5)
        );
        assert!(close(quadrant(0.5, 0.5), [0.0, 1.0, 0.0, 1.0]));
        assert!(close(quadrant(0.0, 0.0), [0.0, 0.0, 1.0, 1.0]));
        assert!(close(quadrant(0.5, 0.0), [1.0, 1.0, 1.0, 1.0]));
        // A square across the centre: a quarter of each texel.
        assert!(
            close(mean(0.25, 0.25), [0.5, 0.5, 0.5, 1.0]),
            "{:?}",
            mean(0.25, 0.25)
        );
    }

    #[test]
    fn image_copies_beyond_the_texel_limit_are_refused() {
        // The pattern is laid out over 5 × 5 tiles (the shape's edges touch
        // a fifth row and column), each drawing the 2×2 image: 100 texels.
        let svg = format!(
            r#"<svg xmlns="http://www.w3.org/2000/svg" viewBox="0 0 8 8">
            <pattern id="p" width="2" height="2" patternUnits="userSpaceOnUse">
              <image width="2" height="2" href="data:image/png;base64,{PNG_2X2}"/></pattern>
            <rect width="8" height="8" fill="url(#p)"/></svg>"#
        );
        let limits = Limits {
            max_svg_image_texels: 99,
            ..Limits::default()
        };
        let e = parse_svg(svg.as_bytes(), Path::new("t.svg"), 4, &limits).unwrap_err();
        assert!(e.to_string().contains("max_svg_image_texels"), "{e}");
        let limits = Limits {
            max_svg_image_texels: 100,
            ..Limits::default()
        };
        assert!(parse_svg(svg.as_bytes(), Path::new("t.svg"), 4, &limits).is_ok());
    }

    #[test]
    fn images_that_cannot_be_drawn_are_errors_naming_them() {
        let parse = |body: &str| {
            let svg = format!(
                r#"<svg xmlns="http://www.w3.org/2000/svg" viewBox="0 0 10 10">{body}</svg>"#
            );
            parse_svg(svg.as_bytes(), Path::new("t.svg"), 4, &Limits::default())
                .unwrap_err()
                .to_string()
        };
        let e = parse(r#"<image href="missing.png" width="10" height="10"/>"#);
        assert!(
            e.contains("t.svg") && e.contains("image \"missing.png\" could not be read"),
            "{e}"
        );
        let e = parse(r#"<image href="https://example.com/a.png" width="10" height="10"/>"#);
        assert!(e.contains("is remote"), "{e}");
        let e = parse(
            r#"<image id="anim" width="10" height="10" href="data:image/gif;base64,R0lGODlhAQABAIAAAP///wAAACH5BAEAAAAALAAAAAABAAEAAAICRAEAOw=="/>"#,
        );
        assert!(e.contains("unsupported: image in GIF format"), "{e}");
        let e = parse(
            r#"<image width="10" height="10" href="data:image/png;base64,iVBORw0KGgoAAAA"/>"#,
        );
        assert!(e.contains("t.svg"), "{e}");
        // Found by the SVG fuzz target: a PNG header claiming 8 × 2³¹ + 2
        // texels (its CRC right), placed by a malformed `preserveAspectRatio`,
        // made usvg 0.49 panic.
        let e = parse(
            r#"<image x="0" y="1" width="18" height="18" preserveAspectRatio="xMidYMx2 slice" href="data:image/png;base64,iVBORw0KGgoAAAANSUhEUgAAAAiAAAACCAIAAACMowr1AAAAC0lEQVR4nGNggAEAAAoAAX+AdF4AAAAASUVORK5CYII="/>"#,
        );
        assert!(
            e.contains("t.svg") && e.contains("max_dimension") && e.contains("2147483650"),
            "{e}"
        );
    }

    /// Found by the SVG fuzz target after 13 M executions: stroked text
    /// whose outline sends tiny-skia's curvature search (inside usvg's
    /// parser) to an `unwrap` on NaN. The panic is this file's error.
    #[test]
    fn a_panic_inside_the_svg_parser_is_an_error_naming_the_file() {
        let data = include_bytes!("../tests/data/stroked-text-parser-panic.svg");
        let e = parse_svg(data, Path::new("panic.svg"), 4, &Limits::default())
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("panic.svg") && e.contains("the SVG parser (usvg) failed"),
            "{e}"
        );
    }

    /// Found by the SVG fuzz target: a stroked circle of radius 8 × 10¹⁸
    /// flattened to 2 GB of points before the packer refused its
    /// coordinates. Both bounds are now checked while flattening.
    #[test]
    fn far_away_curves_are_refused_before_they_are_flattened() {
        let parse = |body: &str| {
            let svg = format!(
                r#"<svg xmlns="http://www.w3.org/2000/svg" viewBox="0 0 100 100">{body}</svg>"#
            );
            parse_svg(svg.as_bytes(), Path::new("far.svg"), 4, &Limits::default())
                .unwrap_err()
                .to_string()
        };
        let e = parse(
            r#"<circle cx="88" cy="12" r="8111111111111111111.0" fill="none" stroke="black" stroke-width="0.4"/>"#,
        );
        assert!(
            e.contains("far.svg") && e.contains("texture units") && e.contains("beyond ±1e12"),
            "{e}"
        );
        // Within the coordinate bound, but each curve flattens to the most
        // segments one curve may have (65 536).
        let curves = " C 1e9 0 -1e9 100 0 100 C 1e9 100 -1e9 0 0 0".repeat(130);
        let e = parse(&format!(r#"<path d="M0 0{curves}Z"/>"#));
        assert!(
            e.contains("far.svg") && e.contains("flatten to more than 16777216 points"),
            "{e}"
        );
    }
}
