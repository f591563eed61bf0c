//! Paints: solid colours, gradients and patterns as the core's paints.

use quadtex_core::{Circle, Gradient, Interpolation, Spread, Stop};
use quadtex_core::{FillRule, Paint, Rgba};

use crate::Error;
use quadtex_core::srgb_decode_f32;

use super::Walker;
use super::geometry::*;

impl Walker<'_> {
    /// The core paint of `paint` with `opacity`, for a path drawn under
    /// `transform` (gradients are defined in the path's user space).
    pub(super) fn paint(
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

    /// Fills `contours` (texture space, of a path drawn under `transform`)
    /// with `paint` at `opacity`.
    pub(super) fn fill_with(
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
    pub(super) fn pattern(
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
}

/// Most tiles one pattern fill is laid out over (each tile copies the
/// pattern's content).
pub const MAX_PATTERN_TILES: f64 = 4096.0;

pub(super) fn fill_rule(rule: usvg::FillRule) -> FillRule {
    match rule {
        usvg::FillRule::NonZero => FillRule::NonZero,
        usvg::FillRule::EvenOdd => FillRule::EvenOdd,
    }
}

/// A flat paint from sRGB-encoded channels in `[0,1]` and an opacity.
pub(super) fn solid(rgb: [f64; 3], opacity: f64) -> Paint {
    let a = opacity as f32;
    let lin = |v: f64| srgb_decode_f32(v as f32) * a;
    Paint::Solid(Rgba::new(lin(rgb[0]), lin(rgb[1]), lin(rgb[2]), a))
}

pub(super) enum GradientGeometry<'a> {
    Linear(&'a usvg::LinearGradient),
    Radial(&'a usvg::RadialGradient),
}
