//! What vector art is: shapes in paint order, their paints, groups,
//! masks and clip regions ([`VectorArt`]), and the limits on it.

use crate::Error;
use crate::colour::Rgba;
use crate::geometry::FillRule;
use crate::memory::BUILD_BYTES_PER_NODE;
use crate::vector::blend::BlendMode;
use crate::vector::gradient::Gradient;
use crate::vector::image_paint::ImagePaint;

/// Deepest level the vector packer accepts: `2^24` squares a side. (Input
/// coordinates in `f32`, as SVG parsers give them, carry no more precision.)
pub const MAX_VECTOR_LEVEL: u8 = 24;

/// Largest coordinate magnitude accepted (far outside the unit square, where
/// art is clipped off anyway; keeps clipping arithmetic finite).
pub const MAX_VECTOR_COORDINATE: f64 = 1e12;

/// Most polygon vertices one [`VectorArt`] may hold.
pub const MAX_VECTOR_POINTS: usize = 1 << 24;

/// A translucent group (see [`VectorArt::group`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct GroupId(u32);

/// A clip region (see [`VectorArt::clip_region`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ClipId(u32);

/// Deepest nesting of clip regions (a region within a region, or clipped
/// by one, adds a level), so evaluating one stays shallow.
pub const MAX_CLIP_DEPTH: usize = 32;

/// A mask (see [`VectorArt::begin_mask`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct MaskId(u32);

/// How a mask's content becomes a coverage in `[0,1]`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum MaskKind {
    /// Luminance times alpha, as SVG's default `mask-type`: the
    /// unpremultiplied colour is sRGB-encoded, weighted
    /// `0.2125 R + 0.7154 G + 0.0721 B` and multiplied by alpha (the
    /// coefficients and the encoded space resvg and browsers use).
    Luminance,
    /// Alpha alone (`mask-type: alpha`).
    Alpha,
}

/// Deepest nesting of masks (a mask drawn inside another's content), so
/// evaluating one stays shallow.
pub const MAX_MASK_DEPTH: usize = 32;

#[derive(Debug, Clone)]
pub(super) struct Mask {
    pub(super) kind: MaskKind,
    /// Still taking content (see [`VectorArt::end_mask`]).
    pub(super) open: bool,
}

/// One filled shape, or one member shape of a clip region.
#[derive(Debug, Clone)]
pub(super) struct Shape {
    pub(super) contours: Vec<Contour>,
    pub(super) rule: FillRule,
    pub(super) colour: [f64; 4],
    /// Enclosing translucent groups, outermost first.
    pub(super) groups: Vec<u32>,
    /// The clip region the shape is painted within.
    pub(super) clip: Option<u32>,
    /// True for a clip region's member: it is never painted, only tested.
    pub(super) member: bool,
    /// The gradient it is painted with (index into `VectorArt::gradients`);
    /// `None` for the solid `colour`.
    pub(super) gradient: Option<u32>,
    /// The mask whose content it is (then it is a member: painted only
    /// into that mask).
    pub(super) mask_of: Option<u32>,
}

/// What a shape is filled with.
#[derive(Debug, Clone, PartialEq)]
pub enum Paint {
    /// One linear premultiplied colour.
    Solid(Rgba),
    /// A gradient (its stops carry the opacity).
    Gradient(Gradient),
    /// A raster image (its texels carry the opacity).
    Image(ImagePaint),
}

/// A paint whose colour varies over a shape.
#[derive(Debug, Clone)]
pub(super) enum Varying {
    Gradient(Gradient),
    Image(ImagePaint),
}

impl Varying {
    pub(super) fn colour_at(&self, p: Point) -> [f64; 4] {
        match self {
            Varying::Gradient(g) => g.colour_at(p),
            Varying::Image(i) => i.colour_at(p),
        }
    }

    pub(super) fn mean_over(&self, poly: &[Point]) -> ([f64; 4], f64) {
        match self {
            Varying::Gradient(g) => g.mean_over(poly),
            Varying::Image(i) => i.mean_over(poly),
        }
    }

    pub(super) fn range_over(&self, poly: &[Point]) -> [[f64; 2]; 4] {
        match self {
            Varying::Gradient(g) => g.range_over(poly),
            Varying::Image(i) => i.range_over(poly),
        }
    }

    pub(super) fn is_opaque(&self) -> bool {
        match self {
            Varying::Gradient(g) => g.is_opaque(),
            Varying::Image(i) => i.is_opaque(),
        }
    }
}

/// A clip region: the union of its member shapes (each within its own
/// clip, if any), intersected with every region of `within`.
#[derive(Debug, Clone)]
pub(super) struct Clip {
    /// `(member shape, the clip it is restricted to)`.
    pub(super) members: Vec<(u32, Option<u32>)>,
    pub(super) within: Vec<u32>,
    /// 1 + the deepest region this one refers to.
    pub(super) depth: usize,
}

pub(super) type Point = [f64; 2];

#[derive(Debug, Clone)]
pub(super) struct Contour {
    pub(super) points: Vec<Point>,
    /// `[x_min, z_min, x_max, z_max]`.
    pub(super) bounds: [f64; 4],
}

/// Filled polygons in paint order, ready to pack (see the module docs).
#[derive(Debug, Clone, Default)]
pub struct VectorArt {
    pub(super) shapes: Vec<Shape>,
    pub(super) clips: Vec<Clip>,
    /// Gradients and images, the paints that vary over a shape.
    pub(super) gradients: Vec<Varying>,
    /// The painted shape added last (clip members do not count).
    pub(super) last_painted: Option<usize>,
    pub(super) group_opacity: Vec<f64>,
    pub(super) group_blend: Vec<BlendMode>,
    /// The masks each group is multiplied by.
    pub(super) group_masks: Vec<Vec<u32>>,
    pub(super) masks: Vec<Mask>,
    /// Masks taking content, innermost last, with the painted shape added
    /// last outside each (group contiguity is checked per content).
    pub(super) open_masks: Vec<(u32, Option<usize>)>,
    /// Groups closed by a later shape outside them (groups are contiguous).
    pub(super) group_closed: Vec<bool>,
    pub(super) points: usize,
    /// How far flattened curves may lie from the true ones, if stated.
    pub(super) curve_tolerance: Option<f64>,
}

impl VectorArt {
    /// Empty (transparent) art.
    pub fn new() -> VectorArt {
        VectorArt::default()
    }

    /// States that the art's curves were flattened to within `tolerance`
    /// (texture-space units: the texture's longer side is 1) of the true
    /// curves; contour leaves keep it, and `quadtex info` states it.
    /// Ignored unless finite and positive.
    pub fn set_curve_tolerance(&mut self, tolerance: f64) {
        self.curve_tolerance = (tolerance.is_finite() && tolerance > 0.0).then_some(tolerance);
    }

    /// The tolerance stated by [`VectorArt::set_curve_tolerance`].
    pub fn curve_tolerance(&self) -> Option<f64> {
        self.curve_tolerance
    }

    /// A new translucent group with `opacity ∈ [0,1]`. Its shapes are
    /// composited together first, then faded; they must be added one after
    /// the other (a group cannot be reopened once a shape outside it follows).
    pub fn group(&mut self, opacity: f64) -> Result<GroupId, Error> {
        self.blended_group(opacity, BlendMode::Normal)
    }

    /// As [`VectorArt::group`], blended onto what lies below it (within the
    /// enclosing group) by `blend` (see [`crate::vector::blend`]).
    pub fn blended_group(&mut self, opacity: f64, blend: BlendMode) -> Result<GroupId, Error> {
        self.masked_group(opacity, blend, &[])
    }

    /// As [`VectorArt::blended_group`], the group's composite multiplied by
    /// the coverage of each of `masks` (finished masks, see
    /// [`VectorArt::begin_mask`]) before it is faded and blended.
    pub fn masked_group(
        &mut self,
        opacity: f64,
        blend: BlendMode,
        masks: &[MaskId],
    ) -> Result<GroupId, Error> {
        for m in masks {
            match self.masks.get(m.0 as usize) {
                None => return Err(Error::BadVector(format!("unknown mask {}", m.0))),
                Some(mask) if mask.open => {
                    return Err(Error::BadVector(format!(
                        "mask {} is used before its content ends",
                        m.0
                    )));
                }
                Some(_) => {}
            }
        }
        if !(0.0..=1.0).contains(&opacity) {
            return Err(Error::BadVector(format!(
                "group opacity {opacity} is outside [0,1]"
            )));
        }
        let id = u32::try_from(self.group_opacity.len())
            .map_err(|_| Error::BadVector("too many groups".into()))?;
        self.group_opacity.push(opacity);
        self.group_blend.push(blend);
        self.group_masks.push(masks.iter().map(|m| m.0).collect());
        self.group_closed.push(false);
        Ok(GroupId(id))
    }

    /// Adds a filled shape on top of what is there. `contours` are closed
    /// polygons (the last point joins the first); `colour` is linear and
    /// premultiplied; `groups` lists the enclosing groups, outermost first.
    /// Contours with fewer than three points cover nothing and are dropped.
    pub fn fill(
        &mut self,
        contours: Vec<Vec<[f64; 2]>>,
        rule: FillRule,
        colour: Rgba,
        groups: &[GroupId],
    ) -> Result<(), Error> {
        self.fill_clipped(contours, rule, colour, groups, None)
    }

    /// Starts the content of a new mask: shapes (and groups, clip regions,
    /// masks) added until [`VectorArt::end_mask`] are painted, composited in
    /// isolation, into the mask, not onto the art. A group made with
    /// [`VectorArt::masked_group`] is then multiplied, point by point, by the
    /// mask's coverage ([`MaskKind`]): exact where the mask's content is flat
    /// colour, within the stated bound where it is a gradient or an image
    /// (see [`VectorReport::max_mean_error`]). Masks nest up to
    /// [`MAX_MASK_DEPTH`].
    pub fn begin_mask(&mut self, kind: MaskKind) -> Result<MaskId, Error> {
        if self.open_masks.len() >= MAX_MASK_DEPTH {
            return Err(Error::BadVector(format!(
                "masks nested deeper than {MAX_MASK_DEPTH}"
            )));
        }
        let id = u32::try_from(self.masks.len())
            .map_err(|_| Error::BadVector("too many masks".into()))?;
        self.masks.push(Mask { kind, open: true });
        self.open_masks.push((id, self.last_painted.take()));
        Ok(MaskId(id))
    }

    /// Ends the content of `mask`, the innermost mask begun.
    pub fn end_mask(&mut self, mask: MaskId) -> Result<(), Error> {
        match self.open_masks.last() {
            Some(&(m, outer)) if m == mask.0 => {
                self.open_masks.pop();
                self.masks[m as usize].open = false;
                self.last_painted = outer;
                Ok(())
            }
            _ => Err(Error::BadVector(format!(
                "mask {} is not the innermost mask begun",
                mask.0
            ))),
        }
    }

    /// A new clip region, empty until [`VectorArt::add_to_clip`] adds
    /// shapes to it, and restricted to the intersection of `within`.
    ///
    /// A shape painted within a region shows only where the region covers,
    /// with exact geometry: clipping is binary (a point is in or out), so
    /// it commutes with compositing and translucent groups.
    pub fn clip_region(&mut self, within: &[ClipId]) -> Result<ClipId, Error> {
        let mut depth = 1;
        for w in within {
            depth = depth.max(1 + self.clip(w.0)?.depth);
        }
        self.new_clip(Clip {
            members: Vec::new(),
            within: within.iter().map(|w| w.0).collect(),
            depth,
        })
    }

    /// Adds the shape `contours` (filled by `rule`) to the union that makes
    /// region `region`; with `clip`, only its part within that region.
    pub fn add_to_clip(
        &mut self,
        region: ClipId,
        contours: Vec<Vec<[f64; 2]>>,
        rule: FillRule,
        clip: Option<ClipId>,
    ) -> Result<(), Error> {
        self.clip(region.0)?;
        let mut depth = 1;
        if let Some(c) = clip {
            depth = 1 + self.clip(c.0)?.depth;
            if self.reaches(c.0, region.0) {
                return Err(Error::BadVector(format!(
                    "clip region {} would be clipped by itself",
                    region.0
                )));
            }
        }
        let kept = self.contours(contours)?;
        let shape = u32::try_from(self.shapes.len())
            .map_err(|_| Error::BadVector("too many shapes".into()))?;
        self.shapes.push(Shape {
            contours: kept,
            rule,
            colour: [0.0; 4],
            groups: Vec::new(),
            clip: clip.map(|c| c.0),
            member: true,
            gradient: None,
            mask_of: None,
        });
        let r = &mut self.clips[region.0 as usize];
        r.members.push((shape, clip.map(|c| c.0)));
        r.depth = r.depth.max(depth);
        // A region's depth only grows; regions built on it were checked when smaller.
        if r.depth > MAX_CLIP_DEPTH {
            return Err(Error::BadVector(format!(
                "clip regions nested deeper than {MAX_CLIP_DEPTH}"
            )));
        }
        Ok(())
    }

    /// True when region `from` refers, directly or not, to region `target`.
    fn reaches(&self, from: u32, target: u32) -> bool {
        let mut seen = vec![false; self.clips.len()];
        let mut stack = vec![from];
        while let Some(c) = stack.pop() {
            if c == target {
                return true;
            }
            if std::mem::replace(&mut seen[c as usize], true) {
                continue;
            }
            let r = &self.clips[c as usize];
            stack.extend(&r.within);
            stack.extend(r.members.iter().filter_map(|m| m.1));
        }
        false
    }

    fn clip(&self, id: u32) -> Result<&Clip, Error> {
        self.clips
            .get(id as usize)
            .ok_or_else(|| Error::BadVector(format!("unknown clip region {id}")))
    }

    fn new_clip(&mut self, clip: Clip) -> Result<ClipId, Error> {
        if clip.depth > MAX_CLIP_DEPTH {
            return Err(Error::BadVector(format!(
                "clip regions nested deeper than {MAX_CLIP_DEPTH}"
            )));
        }
        let id = u32::try_from(self.clips.len())
            .map_err(|_| Error::BadVector("too many clip regions".into()))?;
        self.clips.push(clip);
        Ok(ClipId(id))
    }

    /// As [`VectorArt::fill`], painted only within the region `clip`.
    pub fn fill_clipped(
        &mut self,
        contours: Vec<Vec<[f64; 2]>>,
        rule: FillRule,
        colour: Rgba,
        groups: &[GroupId],
        clip: Option<ClipId>,
    ) -> Result<(), Error> {
        self.fill_paint(contours, rule, Paint::Solid(colour), groups, clip)
    }

    /// Adds a shape filled with `paint` (see [`VectorArt::fill`]), within
    /// the region `clip` if given.
    pub fn fill_paint(
        &mut self,
        contours: Vec<Vec<[f64; 2]>>,
        rule: FillRule,
        paint: Paint,
        groups: &[GroupId],
        clip: Option<ClipId>,
    ) -> Result<(), Error> {
        if let Some(c) = clip {
            self.clip(c.0)?;
        }
        let (c, varying) = match paint {
            Paint::Solid(colour) => (colour.to_array().map(f64::from), None),
            // A varying shape's `colour` is unused beyond "visible".
            Paint::Gradient(g) => ([0.0, 0.0, 0.0, 1.0], Some(Varying::Gradient(g))),
            Paint::Image(i) => ([0.0, 0.0, 0.0, 1.0], Some(Varying::Image(i))),
        };
        let gradient = match varying {
            Some(v) => {
                let id = u32::try_from(self.gradients.len())
                    .map_err(|_| Error::BadVector("too many gradients and images".into()))?;
                self.gradients.push(v);
                Some(id)
            }
            None => None,
        };
        if c.iter().any(|v| !v.is_finite() || *v < 0.0)
            || c[3] > 1.0
            || c[..3].iter().any(|&v| v > c[3] + 1e-6)
        {
            return Err(Error::BadVector(format!(
                "colour {c:?} is not premultiplied RGBA in [0,1]"
            )));
        }
        for g in groups {
            if g.0 as usize >= self.group_opacity.len() {
                return Err(Error::BadVector(format!("unknown group {}", g.0)));
            }
        }
        // Groups must be contiguous in paint order: a group left behind stays closed.
        let previous: &[u32] = self.last_painted.map_or(&[], |i| &self.shapes[i].groups);
        let common = previous
            .iter()
            .zip(groups)
            .take_while(|(a, b)| **a == b.0)
            .count();
        for &closed in &previous[common..] {
            self.group_closed[closed as usize] = true;
        }
        if let Some(g) = groups[common..]
            .iter()
            .find(|g| self.group_closed[g.0 as usize])
        {
            return Err(Error::BadVector(format!(
                "group {} reopened after a shape outside it",
                g.0
            )));
        }
        let kept = self.contours(contours)?;
        self.last_painted = Some(self.shapes.len());
        let clip = clip.map(|c| c.0);
        let mask_of = self.open_masks.last().map(|m| m.0);
        if c[3] == 0.0 || kept.is_empty() {
            // Invisible; group bookkeeping above still applies.
            self.shapes.push(Shape {
                contours: Vec::new(),
                rule,
                colour: c,
                groups: groups.iter().map(|g| g.0).collect(),
                clip,
                member: mask_of.is_some(),
                gradient,
                mask_of,
            });
            return Ok(());
        }
        self.shapes.push(Shape {
            contours: kept,
            rule,
            colour: c,
            groups: groups.iter().map(|g| g.0).collect(),
            clip,
            member: mask_of.is_some(),
            gradient,
            mask_of,
        });
        Ok(())
    }

    /// Validated contours with their bounds; contours of fewer than three
    /// points are dropped.
    fn contours(&mut self, contours: Vec<Vec<[f64; 2]>>) -> Result<Vec<Contour>, Error> {
        let mut kept = Vec::with_capacity(contours.len());
        for points in contours {
            if let Some(p) = points.iter().find(|p| {
                !(p[0].abs() <= MAX_VECTOR_COORDINATE && p[1].abs() <= MAX_VECTOR_COORDINATE)
            }) {
                return Err(Error::BadVector(format!(
                    "point {p:?} is not finite or beyond ±{MAX_VECTOR_COORDINATE:e}"
                )));
            }
            if points.len() < 3 {
                continue;
            }
            self.points += points.len();
            if self.points > MAX_VECTOR_POINTS {
                return Err(Error::BadVector(format!(
                    "more than {MAX_VECTOR_POINTS} polygon points"
                )));
            }
            let mut bounds = [
                f64::INFINITY,
                f64::INFINITY,
                f64::NEG_INFINITY,
                f64::NEG_INFINITY,
            ];
            for p in &points {
                bounds = [
                    bounds[0].min(p[0]),
                    bounds[1].min(p[1]),
                    bounds[2].max(p[0]),
                    bounds[3].max(p[1]),
                ];
            }
            kept.push(Contour { points, bounds });
        }
        Ok(kept)
    }

    /// Shapes added so far.
    pub fn len(&self) -> usize {
        self.shapes.len()
    }

    /// True when no shape was added.
    pub fn is_empty(&self) -> bool {
        self.shapes.is_empty()
    }

    /// Polygon vertices held.
    pub fn point_count(&self) -> usize {
        self.points
    }

    /// An upper estimate of the nodes [`QuadTree::from_vector`] builds at
    /// `max_level`, per level (entry `L` counts the nodes of level `L`),
    /// without building anything; its cost is the number of points times
    /// the number of levels.
    ///
    /// A square splits only where an edge passes through its interior. At
    /// level `L` a contour visits at most one square more than the grid
    /// lines (spaced `2^-L`) its edges cross, so the squares split at level
    /// `L` are at most the sum of that over all contours (and at most
    /// `4^L`); each split square has four children. Edges lying on a grid
    /// line split nothing and are not counted. It overestimates where
    /// shapes overlap or are hidden by opaque shapes; for a single outline
    /// it is close (the star of `samples/` at levels 8–16: within 10%).
    pub fn estimate_level_nodes(&self, max_level: u8) -> Vec<u64> {
        let max_level = max_level.min(MAX_VECTOR_LEVEL);
        let mut nodes = vec![1u64];
        for level in 0..max_level {
            let n = 1i64 << level;
            let scale = n as f64;
            let cell = |v: f64| ((v.clamp(0.0, 1.0) * scale) as i64).min(n - 1);
            let on_grid = |v: f64| {
                let g = v.clamp(0.0, 1.0) * scale;
                g == g.floor()
            };
            let mut split = 0u64;
            for contour in self.shapes.iter().flat_map(|s| &s.contours) {
                let b = contour.bounds;
                if b[2] < 0.0 || b[0] > 1.0 || b[3] < 0.0 || b[1] > 1.0 {
                    continue;
                }
                let pts = &contour.points;
                let Some(&last) = pts.last() else { continue };
                let (mut px, mut pz) = (cell(last[0]), cell(last[1]));
                let mut prev = last;
                let mut visits = 1u64;
                for &p in pts {
                    let (x, z) = (cell(p[0]), cell(p[1]));
                    let along_grid =
                        (p[0] == prev[0] && on_grid(p[0])) || (p[1] == prev[1] && on_grid(p[1]));
                    if along_grid {
                        // Splits nothing; the next edge may start in a square not yet counted.
                        visits += u64::from((x, z) != (px, pz));
                    } else {
                        visits += (x - px).unsigned_abs() + (z - pz).unsigned_abs();
                    }
                    (px, pz, prev) = (x, z, p);
                }
                split = split.saturating_add(visits);
            }
            nodes.push(4 * split.min(1u64 << (2 * level)));
        }
        nodes
    }

    /// An upper estimate of the peak bytes [`QuadTree::from_vector`] holds
    /// at `max_level` beyond the art itself: [`VectorArt::estimate_level_nodes`]
    /// summed, at [`crate::memory::BUILD_BYTES_PER_NODE`] a node.
    pub fn estimate_build_bytes(&self, max_level: u8) -> u64 {
        self.estimate_level_nodes(max_level)
            .iter()
            .fold(0u64, |a, &n| a.saturating_add(n))
            .saturating_mul(BUILD_BYTES_PER_NODE)
    }
}
