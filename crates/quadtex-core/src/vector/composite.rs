//! Compositing: the colour of painted, grouped, masked and clipped
//! shapes at a point or over a polygon, and its range.

use super::art::{MaskKind, Point, Varying, VectorArt};
use crate::geometry::winding;
use crate::vector::blend::{BlendMode, blend, blend_range};

impl VectorArt {
    /// The exact composite colour at point `p` (linear, premultiplied), by
    /// winding numbers over the unclipped contours. Slow; for tests and
    /// references. Points on an edge count as on its left or right
    /// arbitrarily.
    pub fn colour_at(&self, p: [f64; 2]) -> [f64; 4] {
        if !(0.0..1.0).contains(&p[0]) || !(0.0..1.0).contains(&p[1]) {
            return [0.0; 4];
        }
        let covered: Vec<u32> = (0..self.shapes.len() as u32)
            .filter(|&s| {
                let shape = &self.shapes[s as usize];
                let w: i32 = shape.contours.iter().map(|c| winding(&c.points, p)).sum();
                shape.rule.covers(w)
            })
            .collect();
        let mut visible = Vec::new();
        self.visible(&covered, &mut visible);
        self.composite_by(&visible, 0, &covered, &|s| self.paint_at(s, p))
    }

    /// Shape `s`'s colour at point `p`.
    pub(super) fn paint_at(&self, s: u32, p: Point) -> [f64; 4] {
        let shape = &self.shapes[s as usize];
        match shape.gradient {
            Some(g) => self.gradients[g as usize].colour_at(p),
            None => shape.colour,
        }
    }

    /// True when a shape of `list` is painted with a gradient or an image.
    pub(super) fn any_gradient(&self, list: &[u32]) -> bool {
        !self.gradients.is_empty()
            && list
                .iter()
                .any(|&s| self.shapes[s as usize].gradient.is_some())
    }

    /// The mean composite of `visible` (with masks evaluated from
    /// `covered`) over the convex polygon `poly`, and a bound on its error:
    /// exact where at most one layer varies (the composite is affine in each
    /// layer) and that layer is a linear gradient or an image outside
    /// blended groups; otherwise within the width of the composite's range.
    pub(super) fn composite_over(
        &self,
        visible: &[u32],
        covered: &[u32],
        poly: &[Point],
    ) -> ([f64; 4], f64) {
        let mut means: Vec<(u32, [f64; 4])> = Vec::new();
        let mut error: f64 = 0.0;
        // Mask content counts too: a varying mask multiplies what it masks.
        for &s in covered {
            let shape = &self.shapes[s as usize];
            if let Some(g) = shape.gradient
                && (shape.mask_of.is_some() || visible.binary_search(&s).is_ok())
            {
                let (mean, e) = self.gradients[g as usize].mean_over(poly);
                means.push((s, mean));
                error = error.max(e);
            }
        }
        let colour = self.composite_by(visible, 0, covered, &|s| {
            means
                .iter()
                .find(|m| m.0 == s)
                .map_or(self.shapes[s as usize].colour, |m| m.1)
        });
        let blended = || {
            visible.iter().any(|&s| {
                self.shapes[s as usize]
                    .groups
                    .iter()
                    .any(|&g| self.group_blend[g as usize] != BlendMode::Normal)
            })
        };
        // A varying mask's coverage is not affine in its content's colour.
        let in_mask = || {
            means
                .iter()
                .any(|m| self.shapes[m.0 as usize].mask_of.is_some())
        };
        // Two varying layers, or one under a blend mode or in a mask: not affine any more.
        if means.len() >= 2 || (!means.is_empty() && (blended() || in_mask())) {
            error = range_width(&self.composite_range(visible, 0, covered, poly));
        }
        (colour, error)
    }

    /// When exactly one layer of the point's composite varies (as seen by
    /// [`VectorArt::composite_over`]), and it is a linear gradient outside
    /// masks and blend modes: its gradient and the composite as
    /// `offset + matrix·g`, `g` the gradient's colour (*over* and group
    /// opacity are affine in each layer; checked at one more colour).
    pub(super) fn affine_in_gradient(
        &self,
        visible: &[u32],
        covered: &[u32],
    ) -> Option<(u32, [f64; 4], [[f64; 4]; 4])> {
        let mut varying = covered.iter().copied().filter(|&s| {
            let shape = &self.shapes[s as usize];
            shape.gradient.is_some()
                && (shape.mask_of.is_some() || visible.binary_search(&s).is_ok())
        });
        let s = varying.next()?;
        if varying.next().is_some() {
            return None;
        }
        let shape = &self.shapes[s as usize];
        let gradient = shape.gradient?;
        if shape.mask_of.is_some()
            || !matches!(&self.gradients[gradient as usize], Varying::Gradient(g) if g.is_linear())
        {
            return None;
        }
        let blended = visible.iter().any(|&v| {
            self.shapes[v as usize]
                .groups
                .iter()
                .any(|&g| self.group_blend[g as usize] != BlendMode::Normal)
        });
        if blended {
            return None;
        }
        let at = |g: [f64; 4]| {
            self.composite_by(visible, 0, covered, &|t| {
                if t == s {
                    g
                } else {
                    self.shapes[t as usize].colour
                }
            })
        };
        let offset = at([0.0; 4]);
        let mut matrix = [[0.0; 4]; 4];
        for k in 0..4 {
            let mut e = [0.0; 4];
            e[k] = 1.0;
            let column = at(e);
            for c in 0..4 {
                matrix[c][k] = column[c] - offset[c];
            }
        }
        let probe = [0.3, 0.2, 0.1, 0.45];
        let seen = at(probe);
        let affine = (0..4).all(|c| {
            let predicted = offset[c] + (0..4).map(|k| matrix[c][k] * probe[k]).sum::<f64>();
            (predicted - seen[c]).abs() <= 1e-12
        });
        affine.then_some((gradient, offset, matrix))
    }

    /// Per channel `[lo, hi]` of the composite of `list` over the convex
    /// polygon `poly`: interval arithmetic through the *over* operator.
    pub(super) fn composite_range(
        &self,
        list: &[u32],
        depth: usize,
        covered: &[u32],
        poly: &[Point],
    ) -> [[f64; 2]; 4] {
        let mut out = [[0.0; 2]; 4];
        let mut i = 0;
        while i < list.len() {
            let shape = &self.shapes[list[i] as usize];
            let (range, next) = match shape.groups.get(depth) {
                Some(&g) => {
                    let j = self.group_end(list, i, depth, g);
                    let inner = self.composite_range(&list[i..j], depth + 1, covered, poly);
                    let o = self.group_opacity[g as usize];
                    let mut factor = [o, o];
                    for &m in &self.group_masks[g as usize] {
                        let r = self.mask_range(m, covered, poly);
                        factor = [factor[0] * r[0], factor[1] * r[1]];
                    }
                    let inner = inner.map(|r| [r[0] * factor[0], r[1] * factor[1]]);
                    let mode = self.group_blend[g as usize];
                    if mode != BlendMode::Normal {
                        out = blend_range(mode, out, inner);
                        i = j;
                        continue;
                    }
                    (inner, j)
                }
                None => match shape.gradient {
                    Some(g) => (self.gradients[g as usize].range_over(poly), i + 1),
                    None => (shape.colour.map(|v| [v, v]), i + 1),
                },
            };
            let alpha = range[3];
            for (o, c) in out.iter_mut().zip(range) {
                *o = [
                    c[0] + (1.0 - alpha[1]) * o[0],
                    c[1] + (1.0 - alpha[0]) * o[1],
                ];
            }
            i = next;
        }
        out
    }

    /// The painted shapes of `covered` (ascending shape indices, members
    /// included) that their clip regions let through, into `out`.
    pub(super) fn visible(&self, covered: &[u32], out: &mut Vec<u32>) {
        out.clear();
        if self.clips.is_empty() && self.masks.is_empty() {
            out.extend_from_slice(covered);
            return;
        }
        out.extend(covered.iter().copied().filter(|&s| {
            let shape = &self.shapes[s as usize];
            !shape.member && shape.clip.is_none_or(|c| self.clip_covers(c, covered))
        }));
    }

    /// The content of mask `m` that shows where `covered` cover.
    pub(super) fn mask_content(&self, m: u32, covered: &[u32]) -> Vec<u32> {
        covered
            .iter()
            .copied()
            .filter(|&s| {
                let shape = &self.shapes[s as usize];
                shape.mask_of == Some(m) && shape.clip.is_none_or(|c| self.clip_covers(c, covered))
            })
            .collect()
    }

    /// Mask `m`'s coverage where `covered` cover, shapes coloured `colour(s)`.
    pub(super) fn mask_value(
        &self,
        m: u32,
        covered: &[u32],
        colour: &dyn Fn(u32) -> [f64; 4],
    ) -> f64 {
        let content = self.mask_content(m, covered);
        let c = self.composite_by(&content, 0, covered, colour);
        mask_coverage(
            self.masks[m as usize].kind,
            c[..3].try_into().unwrap_or([0.0; 3]),
            c[3],
        )
    }

    /// `[lo, hi]` of mask `m`'s coverage over the convex polygon `poly`.
    pub(super) fn mask_range(&self, m: u32, covered: &[u32], poly: &[Point]) -> [f64; 2] {
        let content = self.mask_content(m, covered);
        let r = self.composite_range(&content, 0, covered, poly);
        // Coverage grows with every channel and with alpha (see `mask_coverage`).
        let kind = self.masks[m as usize].kind;
        [
            mask_coverage(kind, [r[0][0], r[1][0], r[2][0]], r[3][0]),
            mask_coverage(kind, [r[0][1], r[1][1], r[2][1]], r[3][1]),
        ]
    }

    /// True when clip region `clip` covers the point whose covering shapes
    /// are `covered` (ascending).
    pub(super) fn clip_covers(&self, clip: u32, covered: &[u32]) -> bool {
        let c = &self.clips[clip as usize];
        c.within.iter().all(|&w| self.clip_covers(w, covered))
            && c.members.iter().any(|&(m, inner)| {
                covered.binary_search(&m).is_ok()
                    && inner.is_none_or(|i| self.clip_covers(i, covered))
            })
    }

    /// One past the last shape of `list` from `i` on that lies in group `g`
    /// at depth `depth` (groups are contiguous in paint order).
    pub(super) fn group_end(&self, list: &[u32], i: usize, depth: usize, g: u32) -> usize {
        i + 1
            + list[i + 1..]
                .iter()
                .take_while(|&&s| self.shapes[s as usize].groups.get(depth) == Some(&g))
                .count()
    }

    /// Composite of the solid shapes `list` (paint order) at group depth
    /// `depth`, masks evaluated from `covered`.
    pub(super) fn composite(&self, list: &[u32], depth: usize, covered: &[u32]) -> [f64; 4] {
        self.composite_by(list, depth, covered, &|s| self.shapes[s as usize].colour)
    }

    /// Composite of the shapes `list`, shape `s` having colour `colour(s)`,
    /// masks evaluated from `covered` (every shape covering the point).
    pub(super) fn composite_by(
        &self,
        list: &[u32],
        depth: usize,
        covered: &[u32],
        colour: &dyn Fn(u32) -> [f64; 4],
    ) -> [f64; 4] {
        let mut out = [0.0; 4];
        let mut i = 0;
        while i < list.len() {
            let shape = &self.shapes[list[i] as usize];
            let (colour, next) = match shape.groups.get(depth) {
                Some(&g) => {
                    let j = self.group_end(list, i, depth, g);
                    let inner = self.composite_by(&list[i..j], depth + 1, covered, colour);
                    let mut o = self.group_opacity[g as usize];
                    for &m in &self.group_masks[g as usize] {
                        o *= self.mask_value(m, covered, colour);
                    }
                    let mode = self.group_blend[g as usize];
                    if mode != BlendMode::Normal {
                        out = blend(mode, out, inner.map(|v| v * o));
                        i = j;
                        continue;
                    }
                    (inner.map(|v| v * o), j)
                }
                None => (colour(list[i]), i + 1),
            };
            let keep = 1.0 - colour[3];
            for (o, c) in out.iter_mut().zip(colour) {
                *o = c + *o * keep;
            }
            i = next;
        }
        out
    }

    /// True when shape `s` hides everything below it where it covers.
    pub(super) fn is_opaque(&self, s: u32) -> bool {
        let shape = &self.shapes[s as usize];
        let opaque = match shape.gradient {
            Some(g) => self.gradients[g as usize].is_opaque(),
            None => shape.colour[3] >= 1.0,
        };
        opaque && shape.groups.is_empty() && shape.clip.is_none() && !shape.member
    }
}

/// A mask's coverage from a linear premultiplied colour `rgb`, `alpha`
/// ([`MaskKind`]). Nondecreasing in each channel and in alpha: with
/// `e = srgb_encode`, concave with `e(0) = 0`, `a·e(c/a)` grows with `c` and
/// with `a` (its `a`-derivative is `e(x) − x·e'(x) ≥ 0`), so the ends of a
/// colour range give the ends of the coverage's range.
pub(super) fn mask_coverage(kind: MaskKind, rgb: [f64; 3], alpha: f64) -> f64 {
    let a = alpha.clamp(0.0, 1.0);
    match kind {
        MaskKind::Alpha => a,
        MaskKind::Luminance if a <= 0.0 => 0.0,
        MaskKind::Luminance => {
            let e = |c: f64| crate::colour::srgb_encode((c / a).clamp(0.0, 1.0)) * a;
            (0.2125 * e(rgb[0]) + 0.7154 * e(rgb[1]) + 0.0721 * e(rgb[2])).clamp(0.0, 1.0)
        }
    }
}

/// A range of linear premultiplied colour in sRGB-encoded units (colour
/// channels encoded, alpha as is; encoding is monotone).
pub(super) fn encoded(range: [[f64; 2]; 4]) -> [[f64; 2]; 4] {
    let mut out = range;
    for r in &mut out[..3] {
        *r = r.map(crate::colour::srgb_encode);
    }
    out
}

/// The largest channel width of a range.
pub(super) fn range_width(range: &[[f64; 2]; 4]) -> f64 {
    range.iter().map(|r| r[1] - r[0]).fold(0.0, f64::max)
}
