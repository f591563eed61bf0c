//! The walk over usvg's tree: groups, masks, clip paths, paths and images
//! become vector art (paints are in `paint`).

use std::sync::Arc;

use quadtex_core::BlendMode;
use quadtex_core::ImagePaint;
use quadtex_core::{ClipId, MAX_VECTOR_COORDINATE, MAX_VECTOR_POINTS, MaskId, MaskKind};
use quadtex_core::{FillRule, Paint};
use usvg::tiny_skia_path::{self, PathSegment};

use crate::Error;

use super::Walker;
use super::geometry::*;
use super::paint::*;

impl Walker<'_> {
    pub(super) fn unsupported(&self, element: &str, id: &str) -> Error {
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
    pub(super) fn group(&mut self, g: &usvg::Group, parent: usvg::Transform) -> Result<(), Error> {
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
    pub(super) fn mask(
        &mut self,
        mask: &usvg::Mask,
        transform: usvg::Transform,
    ) -> Result<MaskId, Error> {
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
    pub(super) fn clip_region(
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

    pub(super) fn clip_members(
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

    pub(super) fn core(&self, source: quadtex_core::Error) -> Error {
        Error::Core {
            path: self.path.to_path_buf(),
            source,
        }
    }

    pub(super) fn path(&mut self, p: &usvg::Path, transform: usvg::Transform) -> Result<(), Error> {
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

    /// An image drawn under `transform` (usvg places it at the origin of its
    /// user space, one unit a pixel, its `preserveAspectRatio` turned into a
    /// transform and a clip): a raster becomes its rectangle painted with its
    /// texels (exact area means, see `quadtex_core::image_paint`); a nested
    /// SVG is walked like a group, clipped to its size.
    pub(super) fn image(
        &mut self,
        image: &usvg::Image,
        transform: usvg::Transform,
    ) -> Result<(), Error> {
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

    pub(super) fn add(
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
    pub(super) fn flatten(
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
