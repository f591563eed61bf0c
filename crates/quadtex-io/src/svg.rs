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
//! gives the same tree). Gradients, patterns, images, masks, clip paths,
//! filters and blend modes other than normal are refused with
//! [`Error::UnsupportedSvg`] naming the element, never approximated silently.
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
use std::sync::{Arc, OnceLock};

use quadtex_core::vector::GroupId;
use quadtex_core::{FillRule, QuadTree, Rgba, VectorArt, VectorOptions, VectorReport};
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

/// Reads an SVG file and packs it at `max_level`.
pub fn pack_svg(
    path: &Path,
    max_level: u8,
    limits: &Limits,
) -> Result<(QuadTree, VectorReport), Error> {
    let art = load_svg(path, max_level, limits)?;
    QuadTree::from_vector(
        &art,
        &VectorOptions {
            max_level,
            max_nodes: limits.max_nodes,
            max_bytes: Some(limits.max_memory),
        },
    )
    .map_err(crate::error::core(path))
}

/// Reads an SVG file into vector art flattened for `max_level`.
pub fn load_svg(path: &Path, max_level: u8, limits: &Limits) -> Result<VectorArt, Error> {
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
    parse_svg(&data, path, max_level, limits)
}

/// Parses SVG text into vector art flattened for `max_level`; `path` names
/// the source in errors.
pub fn parse_svg(
    data: &[u8],
    path: &Path,
    max_level: u8,
    limits: &Limits,
) -> Result<VectorArt, Error> {
    let svg_err = |message: String| Error::Svg {
        path: path.to_path_buf(),
        message,
    };
    if max_level > quadtex_core::vector::MAX_VECTOR_LEVEL {
        return Err(Error::Core {
            path: path.to_path_buf(),
            source: quadtex_core::Error::DepthTooLarge {
                depth: max_level.into(),
                max: quadtex_core::vector::MAX_VECTOR_LEVEL.into(),
            },
        });
    }
    let text = std::str::from_utf8(data).map_err(|e| svg_err(format!("not UTF-8: {e}")))?;
    count_elements(text, path, limits)?;
    let options = usvg::Options {
        font_family: FAMILY.into(),
        fontdb: fonts(),
        ..usvg::Options::default()
    };
    let tree = usvg::Tree::from_str(text, &options).map_err(|e| svg_err(e.to_string()))?;
    let size = tree.size();
    let side = f64::from(size.width().max(size.height()));
    let mut walker = Walker {
        art: VectorArt::new(),
        path,
        to_unit: 1.0 / side,
        tolerance: (-(f64::from(max_level) + 4.0)).exp2(),
        res_scale: (f64::from(max_level) + 4.0).exp2() as f32 / side as f32,
        groups: Vec::new(),
    };
    walker.group(tree.root())?;
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

    fn group(&mut self, g: &usvg::Group) -> Result<(), Error> {
        if g.clip_path().is_some() {
            return Err(self.unsupported("clip-path", g.id()));
        }
        if g.mask().is_some() {
            return Err(self.unsupported("mask", g.id()));
        }
        if !g.filters().is_empty() {
            return Err(self.unsupported("filter", g.id()));
        }
        if g.blend_mode() != usvg::BlendMode::Normal {
            return Err(self.unsupported("mix-blend-mode", g.id()));
        }
        let opacity = f64::from(g.opacity().get());
        let pushed = opacity < 1.0;
        if pushed {
            let id = self.art.group(opacity).map_err(|e| self.core(e))?;
            self.groups.push(id);
        }
        for node in g.children() {
            match node {
                usvg::Node::Group(child) => self.group(child)?,
                usvg::Node::Path(p) => self.path(p)?,
                usvg::Node::Image(i) => return Err(self.unsupported("image", i.id())),
                usvg::Node::Text(t) => self.group(t.flattened())?,
            }
        }
        if pushed {
            self.groups.pop();
        }
        Ok(())
    }

    fn core(&self, source: quadtex_core::Error) -> Error {
        Error::Core {
            path: self.path.to_path_buf(),
            source,
        }
    }

    fn paint_colour(&self, paint: &usvg::Paint, opacity: f32, id: &str) -> Result<Rgba, Error> {
        match paint {
            usvg::Paint::Color(c) => {
                let lin = |v: u8| srgb_to_linear(f32::from(v) / 255.0) * opacity;
                Ok(Rgba::new(lin(c.red), lin(c.green), lin(c.blue), opacity))
            }
            usvg::Paint::LinearGradient(_) => Err(self.unsupported("linearGradient", id)),
            usvg::Paint::RadialGradient(_) => Err(self.unsupported("radialGradient", id)),
            usvg::Paint::Pattern(_) => Err(self.unsupported("pattern", id)),
        }
    }

    fn path(&mut self, p: &usvg::Path) -> Result<(), Error> {
        if !p.is_visible() {
            return Ok(());
        }
        let transform = p.abs_transform();
        let fill = |w: &mut Self| -> Result<(), Error> {
            if let Some(f) = p.fill() {
                let colour = w.paint_colour(f.paint(), f.opacity().get(), p.id())?;
                let rule = match f.rule() {
                    usvg::FillRule::NonZero => FillRule::NonZero,
                    usvg::FillRule::EvenOdd => FillRule::EvenOdd,
                };
                let contours = w.flatten(p.data(), transform);
                w.add(contours, rule, colour)?;
            }
            Ok(())
        };
        let stroke = |w: &mut Self| -> Result<(), Error> {
            if let Some(s) = p.stroke() {
                let colour = w.paint_colour(s.paint(), s.opacity().get(), p.id())?;
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
                    let contours = w.flatten(&outline, transform);
                    w.add(contours, FillRule::NonZero, colour)?;
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

    fn add(
        &mut self,
        contours: Vec<Vec<[f64; 2]>>,
        rule: FillRule,
        colour: Rgba,
    ) -> Result<(), Error> {
        let groups = self.groups.clone();
        self.art
            .fill(contours, rule, colour, &groups)
            .map_err(|e| self.core(e))
    }

    /// The path's contours in unit-square coordinates, curves flattened.
    fn flatten(&self, path: &tiny_skia_path::Path, t: usvg::Transform) -> Vec<Vec<[f64; 2]>> {
        let (sx, kx, ky, sy, tx, ty) = (
            f64::from(t.sx),
            f64::from(t.kx),
            f64::from(t.ky),
            f64::from(t.sy),
            f64::from(t.tx),
            f64::from(t.ty),
        );
        let k = self.to_unit;
        let map = |p: tiny_skia_path::Point| -> [f64; 2] {
            let (x, y) = (f64::from(p.x), f64::from(p.y));
            [k * (sx * x + kx * y + tx), 1.0 - k * (ky * x + sy * y + ty)]
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
                    current.push(map(p));
                }
                PathSegment::LineTo(p) => current.push(map(p)),
                PathSegment::QuadTo(c, p) => {
                    let p0 = *current.last().unwrap_or(&[0.0, 0.0]);
                    let (p1, p2) = (map(c), map(p));
                    let d = norm(sub(add(p0, p2), scale(p1, 2.0)));
                    let n = segments_for(d / (4.0 * tol));
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
                    let (p1, p2, p3) = (map(c1), map(c2), map(p));
                    let d = norm(sub(add(p0, p2), scale(p1, 2.0)))
                        .max(norm(sub(add(p1, p3), scale(p2, 2.0))));
                    let n = segments_for(3.0 * d / (4.0 * tol));
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
        contours
    }
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
