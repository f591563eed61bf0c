//! Vector art packed straight into a quadtree, with exact coverage and no
//! raster in between.
//!
//! [`VectorArt`] is a list of filled polygonal shapes in paint order (back to
//! front), each with a fill rule, a [`Paint`] (a linear premultiplied colour,
//! a [`Gradient`] or an [`ImagePaint`]), the translucent groups it belongs
//! to (each possibly blended and masked) and the clip region it is painted
//! within. Coordinates are texture space (`x` right,
//! `z` up, see the crate conventions); art outside `[0,1)²` is clipped off and
//! uncovered parts are transparent. Curves are the caller's to flatten (the
//! SVG packer states its tolerance).
//!
//! ## How the tree is built
//!
//! Recursive subdivision from the root. Each square carries, per shape that
//! may cover it, the shape's contours **clipped to the square**
//! (Sutherland–Hodgman against its four sides). Clipping to a convex window
//! keeps the winding number of every interior point (the parts outside are
//! replaced by runs along the window's border), so the clipped contours
//! describe the shape exactly inside the square. A contour that no longer
//! enters the interior (all its edges lie on the border) is replaced by the
//! constant winding it contributes (its signed area over the square's).
//!
//! * If no shape has an edge inside the square, every shape either covers it
//!   entirely or not at all: the square is **terminal**, with the composite of
//!   the covering shapes. An opaque shape covering the square hides all the
//!   shapes below it, whose edges then do not split the square.
//! * At the maximum level a square is a **leaf**: its colour is the exact
//!   area-weighted composite of the regions inside it, found by a trapezoid
//!   sweep (slabs between all vertex and crossing heights; within a slab the
//!   edges do not cross, each gap between neighbouring edges is a trapezoid
//!   covered by a known set of shapes).
//! * Otherwise the square splits and its colour is the exact mean of its
//!   children, rounded once to 16 bits.
//!
//! **Gradients.** A square no edge enters but a gradient paints is terminal
//! when every point of it lies within [`VectorOptions::tolerance`] of its
//! one colour, the exact mean (see [`crate::vector::gradient`]); otherwise it splits
//! like an edge square, down to the maximum level. So smooth colour costs
//! squares in proportion to its area times (slope / tolerance)², not `4^L`. At a
//! leaf the trapezoid sweep takes each trapezoid's mean the same way.
//! Means are exact where at most one varying layer shows and it is a linear
//! gradient (compositing is affine in each layer); otherwise they carry a
//! bound, reported in [`VectorReport::max_mean_error`].
//!
//! **Clip regions** ([`VectorArt::clip_region`]) are carried the same way:
//! their member shapes are clipped to every square like painted shapes (so
//! their edges split squares too) but never painted. Wherever the square's
//! or the trapezoid's set of covering shapes is known, a painted shape counts
//! only if its region covers too, evaluated from that same set; clipping is
//! as exact as coverage.
//!
//! **Masks** ([`VectorArt::begin_mask`]) are carried the same way: their
//! content shapes travel through the subdivision as members, and wherever
//! the covering set is known, a masked group's composite is multiplied by
//! the composite of its mask's content there, turned into a coverage
//! ([`MaskKind`]). On flat content that is exact; where a gradient or an
//! image varies inside a mask, the mean carries the bound of the coverage's
//! range (interval arithmetic, as for gradients).
//!
//! Memory and time grow with the length of the edges times `2^L` (the squares
//! an edge crosses), never with `4^L`. Compositing is the premultiplied
//! *over* operator in **linear light**; browsers composite in sRGB, so
//! translucent overlaps differ from a browser's rendering (opaque art does
//! not). A translucent group is composited in isolation and then faded by
//! its opacity, as SVG specifies.
//!
//! ## Limits
//!
//! Besides nodes ([`VectorOptions::max_nodes`]) and memory
//! ([`VectorOptions::max_bytes`]), the trapezoid sweep's **work** is
//! budgeted ([`VectorOptions::max_sweep_work`]): per swept square, the
//! pairs of edges tested for a crossing plus, over its slabs, the edges
//! spanning each. It grows with the edges alive at once times the heights
//! where they end or cross, so a few kilobytes of SVG whose dashes pile
//! on one point can need billions of steps (minutes). The packer counts a
//! square's steps before sweeping it and refuses with [`Error::SweepWork`]
//! when the total would pass the budget; [`VectorReport::sweep_work`] is
//! what a packing used.

pub(crate) mod blend;
pub(crate) mod contour_leaf;
pub(crate) mod gradient;
pub(crate) mod gradient_leaf;
pub(crate) mod image_paint;

use crate::Error;
use crate::colour::{Rgba, Unorm16Rgba};
use crate::geometry::FillRule;
use crate::geometry::{
    SlabScratch, SweepEdge, clip_to_rect, for_each_slab, on_rect_border, signed_area, winding,
};
use crate::memory::{BUILD_BYTES_PER_NODE, check_budget, try_push};
use crate::tree::{self, MAX_DEPTH, MAX_NODES, QuadTree};
use crate::vector::blend::{BlendMode, blend, blend_range};
use crate::vector::contour_leaf::{
    ContourLeaves, ContourParts, LeafGroup, LeafPiece, MAX_LEAF_GROUP_DEPTH,
};
use crate::vector::gradient::Gradient;
use crate::vector::gradient_leaf::{GradientLeaves, LeafPaint};
use crate::vector::image_paint::ImagePaint;

/// The settings that shrink a vector build, for [`Error::MemoryBudget`].
const VECTOR_KNOBS: &str = "lower --max-level, or raise --memory-limit";

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
struct Mask {
    kind: MaskKind,
    /// Still taking content (see [`VectorArt::end_mask`]).
    open: bool,
}

/// One filled shape, or one member shape of a clip region.
#[derive(Debug, Clone)]
struct Shape {
    contours: Vec<Contour>,
    rule: FillRule,
    colour: [f64; 4],
    /// Enclosing translucent groups, outermost first.
    groups: Vec<u32>,
    /// The clip region the shape is painted within.
    clip: Option<u32>,
    /// True for a clip region's member: it is never painted, only tested.
    member: bool,
    /// The gradient it is painted with (index into `VectorArt::gradients`);
    /// `None` for the solid `colour`.
    gradient: Option<u32>,
    /// The mask whose content it is (then it is a member: painted only
    /// into that mask).
    mask_of: Option<u32>,
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
enum Varying {
    Gradient(Gradient),
    Image(ImagePaint),
}

impl Varying {
    fn colour_at(&self, p: Point) -> [f64; 4] {
        match self {
            Varying::Gradient(g) => g.colour_at(p),
            Varying::Image(i) => i.colour_at(p),
        }
    }

    fn mean_over(&self, poly: &[Point]) -> ([f64; 4], f64) {
        match self {
            Varying::Gradient(g) => g.mean_over(poly),
            Varying::Image(i) => i.mean_over(poly),
        }
    }

    fn range_over(&self, poly: &[Point]) -> [[f64; 2]; 4] {
        match self {
            Varying::Gradient(g) => g.range_over(poly),
            Varying::Image(i) => i.range_over(poly),
        }
    }

    fn is_opaque(&self) -> bool {
        match self {
            Varying::Gradient(g) => g.is_opaque(),
            Varying::Image(i) => i.is_opaque(),
        }
    }
}

/// A clip region: the union of its member shapes (each within its own
/// clip, if any), intersected with every region of `within`.
#[derive(Debug, Clone)]
struct Clip {
    /// `(member shape, the clip it is restricted to)`.
    members: Vec<(u32, Option<u32>)>,
    within: Vec<u32>,
    /// 1 + the deepest region this one refers to.
    depth: usize,
}

type Point = [f64; 2];

#[derive(Debug, Clone)]
struct Contour {
    points: Vec<Point>,
    /// `[x_min, z_min, x_max, z_max]`.
    bounds: [f64; 4],
}

/// Filled polygons in paint order, ready to pack (see the module docs).
#[derive(Debug, Clone, Default)]
pub struct VectorArt {
    shapes: Vec<Shape>,
    clips: Vec<Clip>,
    /// Gradients and images, the paints that vary over a shape.
    gradients: Vec<Varying>,
    /// The painted shape added last (clip members do not count).
    last_painted: Option<usize>,
    group_opacity: Vec<f64>,
    group_blend: Vec<BlendMode>,
    /// The masks each group is multiplied by.
    group_masks: Vec<Vec<u32>>,
    masks: Vec<Mask>,
    /// Masks taking content, innermost last, with the painted shape added
    /// last outside each (group contiguity is checked per content).
    open_masks: Vec<(u32, Option<usize>)>,
    /// Groups closed by a later shape outside them (groups are contiguous).
    group_closed: Vec<bool>,
    points: usize,
    /// How far flattened curves may lie from the true ones, if stated.
    curve_tolerance: Option<f64>,
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
    fn paint_at(&self, s: u32, p: Point) -> [f64; 4] {
        let shape = &self.shapes[s as usize];
        match shape.gradient {
            Some(g) => self.gradients[g as usize].colour_at(p),
            None => shape.colour,
        }
    }

    /// True when a shape of `list` is painted with a gradient or an image.
    fn any_gradient(&self, list: &[u32]) -> bool {
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
    fn composite_over(&self, visible: &[u32], covered: &[u32], poly: &[Point]) -> ([f64; 4], f64) {
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
    fn affine_in_gradient(
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
    fn composite_range(
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
    fn visible(&self, covered: &[u32], out: &mut Vec<u32>) {
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
    fn mask_content(&self, m: u32, covered: &[u32]) -> Vec<u32> {
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
    fn mask_value(&self, m: u32, covered: &[u32], colour: &dyn Fn(u32) -> [f64; 4]) -> f64 {
        let content = self.mask_content(m, covered);
        let c = self.composite_by(&content, 0, covered, colour);
        mask_coverage(
            self.masks[m as usize].kind,
            c[..3].try_into().unwrap_or([0.0; 3]),
            c[3],
        )
    }

    /// `[lo, hi]` of mask `m`'s coverage over the convex polygon `poly`.
    fn mask_range(&self, m: u32, covered: &[u32], poly: &[Point]) -> [f64; 2] {
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
    fn clip_covers(&self, clip: u32, covered: &[u32]) -> bool {
        let c = &self.clips[clip as usize];
        c.within.iter().all(|&w| self.clip_covers(w, covered))
            && c.members.iter().any(|&(m, inner)| {
                covered.binary_search(&m).is_ok()
                    && inner.is_none_or(|i| self.clip_covers(i, covered))
            })
    }

    /// One past the last shape of `list` from `i` on that lies in group `g`
    /// at depth `depth` (groups are contiguous in paint order).
    fn group_end(&self, list: &[u32], i: usize, depth: usize, g: u32) -> usize {
        i + 1
            + list[i + 1..]
                .iter()
                .take_while(|&&s| self.shapes[s as usize].groups.get(depth) == Some(&g))
                .count()
    }

    /// Composite of the solid shapes `list` (paint order) at group depth
    /// `depth`, masks evaluated from `covered`.
    fn composite(&self, list: &[u32], depth: usize, covered: &[u32]) -> [f64; 4] {
        self.composite_by(list, depth, covered, &|s| self.shapes[s as usize].colour)
    }

    /// Composite of the shapes `list`, shape `s` having colour `colour(s)`,
    /// masks evaluated from `covered` (every shape covering the point).
    fn composite_by(
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
    fn is_opaque(&self, s: u32) -> bool {
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
fn mask_coverage(kind: MaskKind, rgb: [f64; 3], alpha: f64) -> f64 {
    let a = alpha.clamp(0.0, 1.0);
    match kind {
        MaskKind::Alpha => a,
        MaskKind::Luminance if a <= 0.0 => 0.0,
        MaskKind::Luminance => {
            let e = |c: f64| crate::vector::gradient::srgb_encode((c / a).clamp(0.0, 1.0)) * a;
            (0.2125 * e(rgb[0]) + 0.7154 * e(rgb[1]) + 0.0721 * e(rgb[2])).clamp(0.0, 1.0)
        }
    }
}

/// A range of linear premultiplied colour in sRGB-encoded units (colour
/// channels encoded, alpha as is; encoding is monotone).
fn encoded(range: [[f64; 2]; 4]) -> [[f64; 2]; 4] {
    let mut out = range;
    for r in &mut out[..3] {
        *r = r.map(crate::vector::gradient::srgb_encode);
    }
    out
}

/// The largest channel width of a range.
fn range_width(range: &[[f64; 2]; 4]) -> f64 {
    range.iter().map(|r| r[1] - r[0]).fold(0.0, f64::max)
}

/// Edges above which a leaf is swept quadrant by quadrant (see
/// `VectorBuilder::sweep_split`).
const SWEEP_EDGES: usize = 256;

/// Deepest a leaf is split for its sweep while it holds more than
/// [`SWEEP_EDGES`] edges: `4^6` sub-squares. Below, a square is swept
/// whatever its edges (coincident edges never separate, so splitting
/// further would not pay), unless it holds more than [`SWEEP_HUGE`].
const SWEEP_SPLITS: u8 = 6;

/// Edges above which a square keeps splitting past [`SWEEP_SPLITS`]:
/// sweeping them whole could take minutes (thousands of edges crossing
/// each other at as many heights, as dashed strokes piled on a point).
/// Measured: splitting on by the sweep's estimated work instead, or from
/// 64 edges, made such art slower still, or made coincident edges (which
/// never separate) split to the floor.
const SWEEP_HUGE: usize = 1024;

/// Deepest a leaf is split for its sweep at all; a square there still
/// holding more than [`SWEEP_HUGE`] edges takes its centre's colour (see
/// `VectorBuilder::sweep_split`), at most `4^-20` of the leaf's area each.
const SWEEP_FLOOR: u8 = 20;

/// Options of [`QuadTree::from_vector`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct VectorOptions {
    /// Deepest level (leaf squares of side `2^-max_level`), at most
    /// [`MAX_VECTOR_LEVEL`].
    pub max_level: u8,
    /// Refuse to build trees with more nodes than this.
    pub max_nodes: u64,
    /// Memory budget in bytes (`None`: no budget). Before building, the
    /// packer refuses with [`Error::MemoryBudget`] when
    /// [`VectorArt::estimate_build_bytes`] exceeds it (in a time
    /// proportional to the points times the levels); while building, when
    /// [`crate::memory::BUILD_BYTES_PER_NODE`] per node so far does.
    pub max_bytes: Option<u64>,
    /// Largest per-channel deviation between any point of a square painted
    /// by gradients and the square's one colour (its exact mean) for the
    /// square to be terminal; squares beyond it are split, down to
    /// `max_level`. Measured on the **sRGB-encoded** premultiplied colour
    /// channels (alpha as is), full scale 1, so that the default
    /// [`DEFAULT_SMOOTH_TOLERANCE`], a quarter of an 8-bit step, is a quarter
    /// of a step of 8-bit output at every brightness (a linear measure would
    /// be 13× too loose near black and 9× too strict near white). The
    /// deviation is bounded by the colour's range over the square (interval
    /// arithmetic through the compositing). Flat colour and edges are exact
    /// regardless.
    pub tolerance: f64,
    /// Keep squares painted by one linear gradient (and flat colour) whole,
    /// with their paint, instead of splitting them to the tolerance
    /// ([`crate::vector::gradient_leaf`]). On by default.
    pub gradient_leaves: bool,
    /// Keep a square of flat art crossed by at most this many edges whole,
    /// with its contours, instead of splitting it further
    /// ([`crate::vector::contour_leaf`]): the art is then exact at any
    /// magnification, and the tree answers down to level 30. Only squares
    /// whose shapes are solid fills outside clip paths and masks, in groups
    /// of plain opacity (at most [`crate::vector::contour_leaf::MAX_LEAF_GROUP_DEPTH`]
    /// deep) or none, qualify. Squares at `max_level` that qualify keep
    /// their contours up to 256 edges (or the budget, if larger), so flat
    /// art is exact at any magnification everywhere but where more edges
    /// crowd one square of `max_level` (a query would sweep them all).
    /// Off (`None`) by default.
    pub contour_leaves: Option<usize>,
    /// How close to the true curves a reader of SVG (`quadtex_io`)
    /// flattens them, in texture-space units (the texture's longer side is
    /// 1); the packer itself takes art already flattened. `None`: see
    /// [`VectorOptions::curve_tolerance_or_default`].
    pub curve_tolerance: Option<f64>,
    /// Budget of the exact trapezoid sweep over the whole packing, in its
    /// steps (pairs of edges tested for a crossing, plus each edge handed
    /// to each slab: see the module's *Limits*). Art that needs more is
    /// refused with [`Error::SweepWork`] before the square that would pass
    /// it is swept, instead of packing for minutes. The default,
    /// [`DEFAULT_MAX_SWEEP_WORK`], is about a minute on one core.
    pub max_sweep_work: u64,
}

/// The default [`VectorOptions::max_sweep_work`]: 2³¹ steps, about 70 s
/// of one core where steps are dearest (measured: a fuzzed dashed star,
/// 3.9 × 10⁸ steps in 13 s). The resvg test suite needs at most
/// 6.6 × 10⁷ in one file (a pattern of strokes), 1/32 of it (its test
/// checks the margin).
pub const DEFAULT_MAX_SWEEP_WORK: u64 = 1 << 31;

/// Max level of trees with contour leaves when none is given (callers
/// that pick a level for SVG art use it): squares split only while they
/// hold more edges than the budget, so a deeper limit costs only where
/// edges crowd (curves flattened finely, small text, stroke joins).
pub const CONTOUR_MAX_LEVEL: u8 = 20;

/// Curve flattening of trees with contour leaves, unless stated:
/// 2⁻²² of the texture's side (2.4e-7; 0.24 mm on a 1 km texture): a
/// quarter of a pixel when the texture spans 10⁶ pixels, and four times
/// the `f32` resolution of the coordinates SVG readers hand over, so the
/// bound is not lost in their rounding. A circle of radius 0.1 takes
/// about 1 400 segments.
pub const CONTOUR_CURVE_TOLERANCE: f64 = 1.0 / (1u64 << 22) as f64;

impl VectorOptions {
    /// [`VectorOptions::curve_tolerance`], or by default
    /// [`CONTOUR_CURVE_TOLERANCE`] with contour leaves (exact at any
    /// magnification, so the curves must not show their segments) and
    /// `2^-(max_level + 4)`, a sixteenth of a square at `max_level`,
    /// without them.
    pub fn curve_tolerance_or_default(&self) -> f64 {
        self.curve_tolerance
            .unwrap_or(if self.contour_leaves.is_some() {
                CONTOUR_CURVE_TOLERANCE
            } else {
                (-(f64::from(self.max_level) + 4.0)).exp2()
            })
    }
}

/// A quarter of an 8-bit step: the default [`VectorOptions::tolerance`].
pub const DEFAULT_SMOOTH_TOLERANCE: f64 = 0.25 / 255.0;

impl Default for VectorOptions {
    fn default() -> Self {
        VectorOptions {
            max_level: 12,
            max_nodes: MAX_NODES,
            max_bytes: None,
            tolerance: DEFAULT_SMOOTH_TOLERANCE,
            gradient_leaves: true,
            contour_leaves: None,
            curve_tolerance: None,
            max_sweep_work: DEFAULT_MAX_SWEEP_WORK,
        }
    }
}

/// What vector packing did.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct VectorReport {
    /// Leaves at the maximum level whose colour came from the trapezoid sweep.
    pub swept_leaves: u64,
    /// Most edges inside one swept leaf.
    pub max_leaf_edges: usize,
    /// Steps of the trapezoid sweep, counted against
    /// [`VectorOptions::max_sweep_work`].
    pub sweep_work: u64,
    /// Largest deviation (per channel, sRGB-encoded, bounded as for
    /// [`VectorOptions::tolerance`]) between a point of a terminal square
    /// painted by gradients and the square's one colour. At most the
    /// tolerance, except in squares at the maximum level.
    pub max_smooth_deviation: f64,
    /// Bound on the error of any stored mean, linear (0 when every mean is
    /// exact: flat colour, and linear gradients not overlapping other
    /// gradients).
    pub max_mean_error: f64,
    /// Terminal squares kept as gradient leaves ([`crate::vector::gradient_leaf`]).
    pub gradient_leaves: u64,
    /// Distinct paints of those leaves.
    pub gradient_leaf_paints: u64,
    /// Terminal squares kept as contour leaves ([`crate::vector::contour_leaf`]).
    pub contour_leaves: u64,
    /// Points their contours hold.
    pub contour_leaf_points: u64,
}

/// The part of one shape inside a square: its contours are
/// `Pieces::contours[contours]`.
#[derive(Debug, Clone)]
struct Piece {
    shape: u32,
    /// Winding contributed by contours that no longer enter the square.
    base: i32,
    /// Clipped contours that still have edges inside the square.
    contours: std::ops::Range<usize>,
}

/// The pieces of one square, flat: headers, contour ranges and points in
/// three vectors that are cleared and refilled square after square (one
/// per level), so the build allocates per level, not per square.
#[derive(Debug, Default)]
struct Pieces {
    pieces: Vec<Piece>,
    contours: Vec<std::ops::Range<usize>>,
    points: Vec<Point>,
}

impl Pieces {
    fn clear(&mut self) {
        self.pieces.clear();
        self.contours.clear();
        self.points.clear();
    }

    fn contours_of(&self, piece: &Piece) -> impl Iterator<Item = &[Point]> + '_ {
        self.contours[piece.contours.clone()]
            .iter()
            .map(|r| &self.points[r.clone()])
    }
}

#[derive(Debug, Clone, Copy)]
struct Square {
    x0: f64,
    z0: f64,
    side: f64,
}

impl Square {
    fn x1(&self) -> f64 {
        self.x0 + self.side
    }
    fn z1(&self) -> f64 {
        self.z0 + self.side
    }
    /// The corners, counter-clockwise.
    fn corners(&self) -> [Point; 4] {
        let (x1, z1) = (self.x1(), self.z1());
        [[self.x0, self.z0], [x1, self.z0], [x1, z1], [self.x0, z1]]
    }

    fn child(&self, k: usize) -> Square {
        let h = self.side / 2.0;
        Square {
            x0: self.x0 + if k & 1 == 1 { h } else { 0.0 },
            z0: self.z0 + if k & 2 == 2 { h } else { 0.0 },
            side: h,
        }
    }
}

struct VectorBuilder<'a> {
    art: &'a VectorArt,
    max_level: u8,
    tolerance: f64,
    max_nodes: u64,
    max_bytes: Option<u64>,
    nodes: u64,
    levels: Vec<Vec<(bool, Unorm16Rgba)>>,
    report: VectorReport,
    /// Whether squares may become gradient leaves.
    gradient_leaves: bool,
    /// Paints of gradient leaves, and the index of each by its gradient
    /// and coefficients' bits.
    leaf_paints: Vec<LeafPaint>,
    leaf_paint_index: std::collections::HashMap<(u32, [u64; 20]), u32>,
    /// `(level, index in level, paint)` of each gradient leaf.
    leaves: Vec<(u8, usize, u32)>,
    /// The edge budget of contour leaves, if they are made.
    contour_budget: Option<usize>,
    /// Each contour leaf's groups, and its pieces (paint order) with their
    /// contours.
    contour_leaves: Vec<ContourLeaf>,
    /// `(level, index in level, contour leaf)` of each contour leaf.
    contour_nodes: Vec<(u8, usize, usize)>,
    /// The leaf [`VectorBuilder::square`] just made of its square.
    made_leaf: Option<Made>,
    /// Clipping buffers.
    scratch: [Vec<Point>; 2],
    /// The pieces of the square being built at each level.
    work: Vec<Pieces>,
    /// Scratch of the trapezoid sweep.
    sweep: SweepScratch,
    /// [`VectorOptions::max_sweep_work`] (the steps so far are
    /// [`VectorReport::sweep_work`]).
    max_sweep_work: u64,
}

/// Buffers of [`VectorBuilder::sweep`], kept between leaves.
#[derive(Debug, Default)]
struct SweepScratch {
    edges: Vec<SweepEdge>,
    slabs: SlabScratch,
    winding: Vec<i32>,
    /// `(x at mid-slab, piece, winding step, x at slab bottom, x at slab top)`.
    crossings: Vec<(f64, usize, i32, f64, f64)>,
    covered: Vec<u32>,
    visible: Vec<u32>,
    memo: FlatColours,
}

/// The flat colours of the last few covered sets a sweep met: gaps
/// between a dashed stroke's dashes alternate between two sets, and
/// compositing is the sweep's dearest step after sorting.
#[derive(Debug, Default)]
struct FlatColours {
    /// Each set's shapes, one after the other.
    shapes: Vec<u32>,
    /// Each set's end in `shapes`, and its colour.
    sets: Vec<(usize, [f64; 4])>,
}

impl FlatColours {
    /// Sets kept; one past them starts the memo afresh.
    const SETS: usize = 8;

    fn clear(&mut self) {
        self.shapes.clear();
        self.sets.clear();
    }

    fn get(&self, covered: &[u32]) -> Option<[f64; 4]> {
        let mut start = 0;
        for &(end, colour) in &self.sets {
            if self.shapes[start..end] == *covered {
                return Some(colour);
            }
            start = end;
        }
        None
    }

    fn put(&mut self, covered: &[u32], colour: [f64; 4]) {
        if self.sets.len() == Self::SETS {
            self.clear();
        }
        self.shapes.extend_from_slice(covered);
        self.sets.push((self.shapes.len(), colour));
    }
}

impl QuadTree {
    /// Packs vector art (see the [module documentation](crate::vector)).
    pub fn from_vector(
        art: &VectorArt,
        options: &VectorOptions,
    ) -> Result<(QuadTree, VectorReport), Error> {
        if options.max_level > MAX_VECTOR_LEVEL {
            return Err(Error::DepthTooLarge {
                depth: options.max_level.into(),
                max: MAX_VECTOR_LEVEL.into(),
            });
        }
        if !(options.tolerance.is_finite() && options.tolerance >= 0.0) {
            return Err(Error::BadTolerance(options.tolerance));
        }
        if options.max_bytes.is_some() {
            let level = options.max_level;
            check_budget(
                || format!("packing at level {level}"),
                art.estimate_build_bytes(level),
                options.max_bytes,
                VECTOR_KNOBS,
            )?;
        }
        let mut b = VectorBuilder {
            art,
            max_level: options.max_level,
            tolerance: options.tolerance,
            max_nodes: options.max_nodes.min(MAX_NODES),
            max_bytes: options.max_bytes,
            nodes: 1,
            levels: vec![Vec::new(); usize::from(options.max_level) + 1],
            report: VectorReport::default(),
            gradient_leaves: options.gradient_leaves,
            leaf_paints: Vec::new(),
            leaf_paint_index: std::collections::HashMap::new(),
            leaves: Vec::new(),
            contour_budget: options.contour_leaves,
            contour_leaves: Vec::new(),
            contour_nodes: Vec::new(),
            made_leaf: None,
            scratch: [Vec::new(), Vec::new()],
            work: (0..=options.max_level).map(|_| Pieces::default()).collect(),
            sweep: SweepScratch::default(),
            max_sweep_work: options.max_sweep_work,
        };
        let root = Square {
            x0: 0.0,
            z0: 0.0,
            side: 1.0,
        };
        let mut top = Pieces::default();
        for (s, shape) in art.shapes.iter().enumerate() {
            b.clip_piece_into(
                s as u32,
                0,
                shape
                    .contours
                    .iter()
                    .map(|c| (c.points.as_slice(), Some(c.bounds))),
                root,
                &mut top,
            );
        }
        b.work[0] = top;
        let (_, colour, terminal) = b.square(0, root)?;
        b.levels[0].push((!terminal, colour));
        let made = b.made_leaf.take();
        b.record(made, 0, 0);
        while b.levels.last().is_some_and(Vec::is_empty) {
            b.levels.pop();
        }
        let mut level_start = vec![0usize];
        for l in &b.levels {
            level_start.push(level_start.last().copied().unwrap_or(0) + l.len());
        }
        let mut tree = tree::from_levels(b.levels, tree::Aspect::SQUARE)?;
        if !b.contour_nodes.is_empty() {
            let mut order: Vec<(u32, usize)> = b
                .contour_nodes
                .iter()
                .map(|&(level, i, leaf)| ((level_start[usize::from(level)] + i) as u32, leaf))
                .collect();
            order.sort_unstable();
            let mut parts = ContourParts::default();
            for (node, leaf) in order {
                let (groups, pieces) = std::mem::take(&mut b.contour_leaves[leaf]);
                parts.push_leaf(
                    node,
                    &groups,
                    pieces.iter().map(|(piece, contours)| {
                        (*piece, contours.iter().map(Vec::as_slice).collect())
                    }),
                );
            }
            b.report.contour_leaves = parts.nodes.len() as u64;
            let leaves = ContourLeaves::new(MAX_DEPTH, parts)?
                .with_curve_tolerance(art.curve_tolerance())?;
            b.report.contour_leaf_points = leaves.point_count() as u64;
            tree = tree.with_contour_leaves(leaves)?;
        }
        if b.leaves.is_empty() {
            return Ok((tree, b.report));
        }
        let mut leaves: Vec<(u32, u32)> = b
            .leaves
            .iter()
            .map(|&(level, i, paint)| ((level_start[usize::from(level)] + i) as u32, paint))
            .collect();
        leaves.sort_unstable();
        b.report.gradient_leaves = leaves.len() as u64;
        b.report.gradient_leaf_paints = b.leaf_paints.len() as u64;
        let leaves = GradientLeaves::new(
            options.max_level,
            options.tolerance.min(1.0),
            b.leaf_paints,
            &leaves,
        )?;
        Ok((tree.with_gradient_leaves(leaves)?, b.report))
    }
}

fn quantise(c: [f64; 4]) -> Unorm16Rgba {
    let q = c.map(|v| (v * 65535.0 + 0.5).clamp(0.0, 65535.0) as u16);
    let a = q[3];
    Unorm16Rgba([q[0].min(a), q[1].min(a), q[2].min(a), a])
}

impl VectorBuilder<'_> {
    /// Returns the square's exact mean colour, its stored colour and whether
    /// it is terminal; pushes its children's nodes. Its pieces are in
    /// `self.work[level]`.
    fn square(&mut self, level: u8, sq: Square) -> Result<([f64; 4], Unorm16Rgba, bool), Error> {
        let mut here = std::mem::take(&mut self.work[usize::from(level)]);
        let result = self.square_with(level, sq, &mut here);
        self.work[usize::from(level)] = here;
        result
    }

    fn square_with(
        &mut self,
        level: u8,
        sq: Square,
        here: &mut Pieces,
    ) -> Result<([f64; 4], Unorm16Rgba, bool), Error> {
        self.cull(&mut here.pieces);
        if here.pieces.iter().all(|p| p.contours.is_empty()) {
            let covered = &mut self.sweep.covered;
            covered.clear();
            covered.extend(here.pieces.iter().map(|p| p.shape));
            let visible = &mut self.sweep.visible;
            self.art.visible(covered, visible);
            if !self.art.any_gradient(covered) {
                let mean = self.art.composite(visible, 0, covered);
                return Ok((mean, quantise(mean), true));
            }
            let poly = sq.corners();
            let range = encoded(self.art.composite_range(visible, 0, covered, &poly));
            // A point lies within `deviation` of the mean, which cannot be
            // below half the range: only then is the mean worth computing.
            if range_width(&range) <= 2.0 * self.tolerance || level == self.max_level {
                let (mean, error) = self.art.composite_over(visible, covered, &poly);
                let m = encoded(mean.map(|v| [v, v]));
                let deviation = (0..4)
                    .map(|c| (range[c][1] - m[c][0]).max(m[c][0] - range[c][0]))
                    .fold(0.0, f64::max);
                if deviation <= self.tolerance || level == self.max_level {
                    let r = &mut self.report;
                    r.max_smooth_deviation = r.max_smooth_deviation.max(deviation);
                    r.max_mean_error = r.max_mean_error.max(error);
                    return Ok((mean, quantise(mean), true));
                }
            }
            if self.gradient_leaves
                && level < self.max_level
                && let Some((mean, paint)) = self.leaf_paint(&poly)
            {
                self.made_leaf = Some(Made::Gradient(paint));
                return Ok((mean, quantise(mean), true));
            }
            // Smooth colour that varies too much: split like an edge would.
        }
        if let Some(budget) = self.contour_budget
            && self.plain(here)
            && edge_count(here)
                <= if level == self.max_level {
                    budget.max(SWEEP_EDGES)
                } else {
                    budget
                }
        {
            let mean = self.sweep(here, sq)?;
            // The leaf's groups, parents first, by their global ids.
            let mut local: Vec<(u32, LeafGroup)> = Vec::new();
            let pieces = here
                .pieces
                .iter()
                .map(|p| {
                    let shape = &self.art.shapes[p.shape as usize];
                    let mut parent = None;
                    for &g in &shape.groups {
                        let k = match local.iter().position(|(id, _)| *id == g) {
                            Some(k) => k,
                            None => {
                                let opacity = self.art.group_opacity[g as usize];
                                local.push((g, LeafGroup { opacity, parent }));
                                local.len() - 1
                            }
                        };
                        parent = Some(k as u32);
                    }
                    let piece = LeafPiece {
                        colour: shape.colour,
                        rule: shape.rule,
                        base: p.base,
                        group: parent,
                    };
                    (piece, here.contours_of(p).map(<[Point]>::to_vec).collect())
                })
                .collect();
            let groups = local.into_iter().map(|(_, g)| g).collect();
            self.contour_leaves.push((groups, pieces));
            self.made_leaf = Some(Made::Contour(self.contour_leaves.len() - 1));
            return Ok((mean, quantise(mean), true));
        }
        if level == self.max_level {
            let (mean, bound) = self.sweep_split(here, sq, 0)?;
            self.report.max_mean_error = self.report.max_mean_error.max(bound);
            return Ok((mean, quantise(mean), true));
        }
        self.nodes += 4;
        if self.nodes > self.max_nodes {
            return Err(Error::TooManyNodes {
                nodes: self.nodes,
                max: self.max_nodes,
            });
        }
        let (nodes, max_level) = (self.nodes, self.max_level);
        check_budget(
            || format!("packing at level {max_level} (stopped after {nodes} nodes)"),
            nodes * BUILD_BYTES_PER_NODE,
            self.max_bytes,
            VECTOR_KNOBS,
        )?;
        let mut children = [(Unorm16Rgba::default(), true, None); 4];
        let mut sum = [0.0; 4];
        let next = usize::from(level) + 1;
        for (k, child) in children.iter_mut().enumerate() {
            let csq = sq.child(k);
            let mut below = std::mem::take(&mut self.work[next]);
            below.clear();
            for p in &here.pieces {
                self.clip_piece_into(
                    p.shape,
                    p.base,
                    here.contours_of(p).map(|c| (c, None)),
                    csq,
                    &mut below,
                );
            }
            self.work[next] = below;
            let (mean, colour, terminal) = self.square(level + 1, csq)?;
            for (s, m) in sum.iter_mut().zip(mean) {
                *s += m / 4.0;
            }
            *child = (colour, terminal, self.made_leaf.take());
        }
        for (c, terminal, made) in children {
            let index = self.levels[next].len();
            self.record(made, level + 1, index);
            try_push(&mut self.levels[next], (!terminal, c), "tree level")?;
        }
        Ok((sum, quantise(sum), false))
    }

    /// Notes the leaf made of the square at `index` of `level`.
    fn record(&mut self, made: Option<Made>, level: u8, index: usize) {
        match made {
            Some(Made::Gradient(paint)) => self.leaves.push((level, index, paint)),
            Some(Made::Contour(leaf)) => self.contour_nodes.push((level, index, leaf)),
            None => {}
        }
    }

    /// True when every piece is a solid fill outside clip paths and masks,
    /// in groups (if any) of plain opacity: what a contour leaf can hold.
    fn plain(&self, pieces: &Pieces) -> bool {
        pieces.pieces.iter().all(|p| {
            let shape = &self.art.shapes[p.shape as usize];
            let plain_group = |&g: &u32| {
                self.art.group_blend[g as usize] == BlendMode::Normal
                    && self.art.group_masks[g as usize].is_empty()
            };
            shape.gradient.is_none()
                && shape.groups.len() <= MAX_LEAF_GROUP_DEPTH
                && shape.groups.iter().all(plain_group)
                && shape.clip.is_none()
                && !shape.member
                && shape.mask_of.is_none()
        })
    }

    /// The square `poly`'s mean and the index of its gradient-leaf paint,
    /// when its shapes (in `self.sweep`: none has an edge inside) make a
    /// colour affine in one linear gradient whose mean over it is exact.
    fn leaf_paint(&mut self, poly: &[Point; 4]) -> Option<([f64; 4], u32)> {
        let (covered, visible) = (&self.sweep.covered, &self.sweep.visible);
        let (gradient, offset, matrix) = self.art.affine_in_gradient(visible, covered)?;
        let (mean, error) = self.art.composite_over(visible, covered, poly);
        if error != 0.0 {
            return None;
        }
        let mut key = [0u64; 20];
        for (k, v) in offset.iter().chain(matrix.iter().flatten()).enumerate() {
            key[k] = v.to_bits();
        }
        if let Some(&index) = self.leaf_paint_index.get(&(gradient, key)) {
            return Some((mean, index));
        }
        let Varying::Gradient(g) = &self.art.gradients[gradient as usize] else {
            return None;
        };
        // A paint beyond the leaves' limits (an absurdly steep gradient) splits instead.
        let paint = LeafPaint::new(g.clone(), offset, matrix).ok()?;
        let index = self.leaf_paints.len() as u32;
        self.leaf_paints.push(paint);
        self.leaf_paint_index.insert((gradient, key), index);
        Some((mean, index))
    }

    /// Drops shapes that do not reach the square and shapes hidden by an
    /// opaque shape covering all of it.
    fn cull(&self, pieces: &mut Vec<Piece>) {
        pieces.retain(|p| {
            !p.contours.is_empty() || self.art.shapes[p.shape as usize].rule.covers(p.base)
        });
        if let Some(top) = pieces
            .iter()
            .rposition(|p| p.contours.is_empty() && self.art.is_opaque(p.shape))
        {
            if self.art.clips.is_empty() && self.art.masks.is_empty() {
                pieces.drain(..top);
            } else {
                // Clip and mask members below stay: shapes above may be clipped or masked by them.
                let mut i = 0;
                pieces.retain(|p| {
                    i += 1;
                    i > top || self.art.shapes[p.shape as usize].member
                });
            }
        }
    }

    /// Appends to `out` the piece of shape `shape` (winding `base` from
    /// contours no longer inside, and `contours` with their bounds when
    /// known) clipped to `sq`, unless it no longer reaches `sq` (winding 0
    /// and no edges).
    fn clip_piece_into<'c>(
        &mut self,
        shape: u32,
        base: i32,
        contours: impl Iterator<Item = (&'c [Point], Option<[f64; 4]>)>,
        sq: Square,
        out: &mut Pieces,
    ) {
        let first = out.contours.len();
        let mut base = base;
        for (contour, bounds) in contours {
            let b = bounds.unwrap_or_else(|| bounds_of(contour));
            if b[2] < sq.x0 || b[0] > sq.x1() || b[3] < sq.z0 || b[1] > sq.z1() {
                continue; // wholly outside: winds 0 around every interior point
            }
            let start = out.points.len();
            clip_to_square(contour, sq, &mut self.scratch, &mut out.points);
            let clipped = &out.points[start..];
            if clipped.len() < 3 {
                out.points.truncate(start);
                continue;
            }
            if on_border(clipped, sq) {
                let w = signed_area(clipped) / (sq.side * sq.side);
                base += w.round() as i32;
                out.points.truncate(start);
            } else {
                out.contours.push(start..out.points.len());
            }
        }
        let contours = first..out.contours.len();
        if base != 0 || !contours.is_empty() {
            out.pieces.push(Piece {
                shape,
                base,
                contours,
            });
        }
    }

    /// Mean colour of a leaf: the trapezoid sweep, run on its quadrants
    /// instead (recursively, [`SWEEP_SPLITS`] deep) while it holds more
    /// than [`SWEEP_EDGES`] edges, and deeper while more than
    /// [`SWEEP_HUGE`]. The sweep's cost grows with the edges alive at once
    /// times the heights where they end or cross (a dashed stroke packed
    /// at a low level put 5 000 in one leaf: 4 s; a fuzzed star of dashed
    /// spokes 13 000 meeting in one point: minutes); the mean stays exact,
    /// the average of the quadrants' exact means. Where more than
    /// [`SWEEP_HUGE`] edges still meet in a square [`SWEEP_FLOOR`] levels
    /// below the leaf (they converge on a point), that square takes the
    /// colour at its centre, and its share of the leaf's area (at most
    /// `4^-SWEEP_FLOOR` each) goes into [`VectorReport::max_mean_error`].
    /// Returns the mean and that bound.
    fn sweep_split(
        &mut self,
        pieces: &Pieces,
        sq: Square,
        depth: u8,
    ) -> Result<([f64; 4], f64), Error> {
        let edges = edge_count(pieces);
        if edges <= SWEEP_EDGES || (depth >= SWEEP_SPLITS && edges <= SWEEP_HUGE) {
            return Ok((self.sweep(pieces, sq)?, 0.0));
        }
        if depth >= SWEEP_FLOOR {
            return Ok((self.colour_at_centre(pieces, sq), 1.0));
        }
        let mut sum = [0.0; 4];
        let mut bound = 0.0;
        let mut below = Pieces::default();
        for k in 0..4 {
            let csq = sq.child(k);
            below.clear();
            for p in &pieces.pieces {
                self.clip_piece_into(
                    p.shape,
                    p.base,
                    pieces.contours_of(p).map(|c| (c, None)),
                    csq,
                    &mut below,
                );
            }
            self.cull(&mut below.pieces);
            let (mean, b) = self.sweep_split(&below, csq, depth + 1)?;
            for (s, m) in sum.iter_mut().zip(mean) {
                *s += m / 4.0;
            }
            bound += b / 4.0;
        }
        Ok((sum, bound))
    }

    /// The composite at the centre of `sq` (each piece's winding there).
    fn colour_at_centre(&mut self, pieces: &Pieces, sq: Square) -> [f64; 4] {
        let centre = [sq.x0 + 0.5 * sq.side, sq.z0 + 0.5 * sq.side];
        let covered = &mut self.sweep.covered;
        covered.clear();
        for p in &pieces.pieces {
            let w = p.base
                + pieces
                    .contours_of(p)
                    .map(|c| winding(c, centre))
                    .sum::<i32>();
            if self.art.shapes[p.shape as usize].rule.covers(w) {
                covered.push(p.shape);
            }
        }
        let visible = &mut self.sweep.visible;
        self.art.visible(covered, visible);
        let h = 1e-9 * sq.side;
        let dot = [
            [centre[0] - h, centre[1] - h],
            [centre[0] + h, centre[1] - h],
            [centre[0] + h, centre[1] + h],
            [centre[0] - h, centre[1] + h],
        ];
        if self.art.any_gradient(covered) {
            self.art.composite_over(visible, covered, &dot).0
        } else {
            self.art.composite(visible, 0, covered)
        }
    }

    /// Exact mean colour of a leaf by the trapezoid sweep, or
    /// [`Error::SweepWork`] when it would pass the packing's budget.
    fn sweep(&mut self, pieces: &Pieces, sq: Square) -> Result<[f64; 4], Error> {
        let SweepScratch {
            edges,
            slabs,
            winding,
            crossings,
            covered,
            visible,
            memo,
        } = &mut self.sweep;
        memo.clear();
        edges.clear();
        for (pi, piece) in pieces.pieces.iter().enumerate() {
            for c in pieces.contours_of(piece) {
                for i in 0..c.len() {
                    edges.extend(SweepEdge::new(c[i], c[(i + 1) % c.len()], pi));
                }
            }
        }
        let mean_error = &mut self.report.max_mean_error;
        self.report.swept_leaves += 1;
        self.report.max_leaf_edges = self.report.max_leaf_edges.max(edges.len());
        let mut total = [0.0; 4];
        let art = self.art;
        let (x0, x1) = (sq.x0, sq.x1());
        let (done, max) = (self.report.sweep_work, self.max_sweep_work);
        let slab = |z0: f64, z1: f64, edges: &[SweepEdge], active: &[usize]| {
            let h = z1 - z0;
            let zm = 0.5 * (z0 + z1);
            crossings.clear();
            for &k in active {
                let e = &edges[k];
                let x_at = |z: f64| e.x_at(z).clamp(x0, x1);
                crossings.push((x_at(zm), e.piece, e.step, x_at(z0), x_at(z1)));
            }
            // Stable: consecutive slabs' orders differ little, and runs sort fast.
            crossings.sort_by(|a, b| a.0.total_cmp(&b.0));
            winding.clear();
            winding.extend(pieces.pieces.iter().map(|p| p.base));
            // The colour of flat art between crossings changes only where
            // a piece's coverage does: kept until then.
            let mut flat: Option<[f64; 4]> = None;
            // A boundary of a gap: x at the slab's middle, bottom and top.
            let mut left = [x0; 3];
            let mut gap = |left: [f64; 3],
                           right: [f64; 3],
                           winding: &[i32],
                           flat: &mut Option<[f64; 4]>,
                           total: &mut [f64; 4]| {
                let width = right[0] - left[0];
                if width <= 0.0 {
                    return;
                }
                let c = match *flat {
                    Some(c) => c,
                    None => {
                        covered.clear();
                        for (p, w) in pieces.pieces.iter().zip(winding) {
                            if art.shapes[p.shape as usize].rule.covers(*w) {
                                covered.push(p.shape);
                            }
                        }
                        if let Some(c) = memo.get(covered) {
                            *flat = Some(c);
                            c
                        } else {
                            art.visible(covered, visible);
                            if art.any_gradient(covered) {
                                let trapezoid =
                                    [[left[1], z0], [right[1], z0], [right[2], z1], [left[2], z1]];
                                let (mean, error) =
                                    art.composite_over(visible, covered, &trapezoid);
                                *mean_error = mean_error.max(error);
                                mean
                            } else {
                                let c = art.composite(visible, 0, covered);
                                memo.put(covered, c);
                                *flat = Some(c);
                                c
                            }
                        }
                    }
                };
                for (t, v) in total.iter_mut().zip(c) {
                    *t += v * width * h;
                }
            };
            for &(x, piece, step, x_lo, x_hi) in crossings.iter() {
                let right = [x, x_lo, x_hi];
                gap(left, right, winding, &mut flat, &mut total);
                let rule = art.shapes[pieces.pieces[piece].shape as usize].rule;
                let before = rule.covers(winding[piece]);
                winding[piece] += step;
                if rule.covers(winding[piece]) != before {
                    flat = None;
                }
                left = right;
            }
            gap(left, [x1; 3], winding, &mut flat, &mut total);
        };
        match for_each_slab(edges, sq.z0, sq.z1(), slabs, max.saturating_sub(done), slab) {
            Ok(work) => self.report.sweep_work = done + work,
            Err(work) => {
                return Err(Error::SweepWork {
                    needed: done.saturating_add(work),
                    max,
                });
            }
        }
        let area = sq.side * sq.side;
        Ok(total.map(|t| t / area))
    }
}

/// A contour leaf being built: its groups, and its pieces with their
/// contours.
type ContourLeaf = (Vec<LeafGroup>, Vec<(LeafPiece, Vec<Vec<Point>>)>);

/// The leaf a square was made into.
#[derive(Debug, Clone, Copy)]
enum Made {
    /// A gradient leaf of this paint.
    Gradient(u32),
    /// A contour leaf, by its index in `VectorBuilder::contour_leaves`.
    Contour(usize),
}

/// Edges of the pieces' clipped contours.
fn edge_count(pieces: &Pieces) -> usize {
    pieces
        .pieces
        .iter()
        .flat_map(|p| &pieces.contours[p.contours.clone()])
        .map(|r| r.len())
        .sum()
}

fn bounds_of(points: &[Point]) -> [f64; 4] {
    let mut b = [
        f64::INFINITY,
        f64::INFINITY,
        f64::NEG_INFINITY,
        f64::NEG_INFINITY,
    ];
    for p in points {
        b = [
            b[0].min(p[0]),
            b[1].min(p[1]),
            b[2].max(p[0]),
            b[3].max(p[1]),
        ];
    }
    b
}

/// True when every edge of the (clipped) contour runs along the square's border.
fn on_border(points: &[Point], sq: Square) -> bool {
    on_rect_border(points, [sq.x0, sq.z0, sq.x1(), sq.z1()])
}

/// Sutherland–Hodgman clipping of a closed polygon to `sq`, appended to
/// `out`; points on the border are set to the border's coordinate exactly,
/// consecutive duplicates removed. `scratch` holds the passes.
fn clip_to_square(
    points: &[Point],
    sq: Square,
    scratch: &mut [Vec<Point>; 2],
    out: &mut Vec<Point>,
) {
    clip_to_rect(points, [sq.x0, sq.z0, sq.x1(), sq.z1()], scratch, out);
}

#[cfg(test)]
mod tests {
    use super::*;

    fn rect(x0: f64, z0: f64, x1: f64, z1: f64) -> Vec<[f64; 2]> {
        vec![[x0, z0], [x1, z0], [x1, z1], [x0, z1]]
    }

    fn clipped(points: &[Point], sq: Square) -> Vec<Point> {
        let mut out = vec![[9.0, 9.0]];
        clip_to_square(points, sq, &mut [Vec::new(), Vec::new()], &mut out);
        // Appended after what `out` held.
        assert_eq!(out[0], [9.0, 9.0]);
        out.split_off(1)
    }

    #[test]
    fn winding_of_counter_clockwise_square_is_one() {
        let r = rect(0.0, 0.0, 1.0, 1.0);
        assert_eq!(winding(&r, [0.5, 0.5]), 1);
        assert_eq!(winding(&r, [1.5, 0.5]), 0);
        let mut cw = r.clone();
        cw.reverse();
        assert_eq!(winding(&cw, [0.5, 0.5]), -1);
        assert!(signed_area(&r) > 0.0);
    }

    #[test]
    fn clipping_keeps_the_winding_inside() {
        let sq = Square {
            x0: 0.25,
            z0: 0.25,
            side: 0.25,
        };
        // A big square around `sq` clips to `sq`'s border: winding 1.
        let c = clipped(&rect(0.0, 0.0, 1.0, 1.0), sq);
        assert!(on_border(&c, sq));
        assert_eq!((signed_area(&c) / (0.25 * 0.25)).round(), 1.0);
        // A triangle whose hypotenuse is the square's diagonal keeps inner edges.
        let sq = Square {
            x0: 0.375,
            z0: 0.375,
            side: 0.25,
        };
        let t = vec![[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]];
        let c = clipped(&t, sq);
        assert!(!on_border(&c, sq));
        assert!((signed_area(&c) - 0.25 * 0.25 / 2.0).abs() < 1e-15);
    }

    fn disc(cx: f64, cz: f64, r: f64, n: usize) -> Vec<[f64; 2]> {
        (0..n)
            .map(|i| {
                let a = std::f64::consts::TAU * i as f64 / n as f64;
                [cx + r * a.cos(), cz + r * a.sin()]
            })
            .collect()
    }

    /// The estimate bounds the nodes built from above, and closely (within
    /// 1.6× for these outlines); the byte estimate is within 6× of the
    /// finished tree's `memory_bytes` (30 bytes a node for the build's peak
    /// against ~8.3 for the tree).
    #[test]
    fn node_estimate_bounds_the_tree_closely() {
        let mut art = VectorArt::new();
        let white = Rgba::opaque(1.0, 1.0, 1.0);
        // A full-canvas background (its edges lie on grid lines: no splits), a
        // disc, a triangle and a translucent square partly outside the canvas.
        art.fill(
            vec![rect(0.0, 0.0, 1.0, 1.0)],
            FillRule::NonZero,
            Rgba::opaque(0.2, 0.2, 0.2),
            &[],
        )
        .unwrap();
        art.fill(
            vec![disc(0.4, 0.5, 0.3, 400)],
            FillRule::NonZero,
            white,
            &[],
        )
        .unwrap();
        art.fill(
            vec![vec![[0.1, 0.1], [0.9, 0.2], [0.5, 0.95]]],
            FillRule::EvenOdd,
            white,
            &[],
        )
        .unwrap();
        let g = art.group(0.5).unwrap();
        art.fill(
            vec![rect(0.7, -0.2, 1.3, 0.4)],
            FillRule::NonZero,
            white,
            &[g],
        )
        .unwrap();
        for level in [4u8, 8, 10, 12] {
            let (tree, _) = QuadTree::from_vector(
                &art,
                &VectorOptions {
                    max_level: level,
                    ..VectorOptions::default()
                },
            )
            .unwrap();
            let built: Vec<u64> = tree.level_stats().iter().map(|l| l.nodes).collect();
            let estimate = art.estimate_level_nodes(level);
            for (l, (&b, &e)) in built.iter().zip(&estimate).enumerate() {
                assert!(e >= b, "level {l} of {level}: estimate {e} < built {b}");
            }
            let (b, e) = (
                tree.node_count() as f64,
                estimate.iter().sum::<u64>() as f64,
            );
            assert!(e <= 1.6 * b, "level {level}: estimate {e} vs {b} nodes");
            let bytes = art.estimate_build_bytes(level) as f64;
            let tree_bytes = tree.memory_bytes() as f64;
            assert!(
                bytes >= tree_bytes && bytes <= 6.0 * tree_bytes,
                "level {level}: {bytes} vs {tree_bytes}"
            );
        }
    }

    #[test]
    fn budget_refuses_before_building() {
        let mut art = VectorArt::new();
        art.fill(
            vec![disc(0.5, 0.5, 0.4, 1000)],
            FillRule::NonZero,
            Rgba::opaque(1.0, 0.0, 0.0),
            &[],
        )
        .unwrap();
        let options = VectorOptions {
            max_level: 24,
            max_bytes: Some(1 << 30),
            ..VectorOptions::default()
        };
        let start = std::time::Instant::now();
        let e = QuadTree::from_vector(&art, &options).unwrap_err();
        assert!(start.elapsed() < std::time::Duration::from_secs(5));
        let Error::MemoryBudget {
            estimate, budget, ..
        } = &e
        else {
            panic!("{e}")
        };
        // The disc's outline, 2.5 units long, crosses ~2.5 · 2^24 squares at level 24 alone.
        assert!(*estimate > 4 * 30 * (2 << 24), "{e}");
        assert_eq!(*budget, 1 << 30);
        assert!(
            e.to_string()
                .starts_with("packing at level 24 needs an estimated"),
            "{e}"
        );
        // A budget the estimate fits builds.
        let fits = VectorOptions {
            max_level: 8,
            max_bytes: Some(art.estimate_build_bytes(8)),
            ..VectorOptions::default()
        };
        assert!(QuadTree::from_vector(&art, &fits).is_ok());
    }

    #[test]
    fn half_covered_leaf_is_half_the_colour() {
        let mut art = VectorArt::new();
        art.fill(
            vec![vec![[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]]],
            FillRule::NonZero,
            Rgba::opaque(1.0, 1.0, 1.0),
            &[],
        )
        .unwrap();
        let (t, report) = QuadTree::from_vector(
            &art,
            &VectorOptions {
                max_level: 3,
                ..VectorOptions::default()
            },
        )
        .unwrap();
        assert_eq!(report.swept_leaves, 8, "the diagonal crosses 8 leaves");
        let a = t.average().to_array();
        assert!((f64::from(a[3]) - 0.5).abs() < 1e-4, "{a:?}");
    }

    /// 1600 wedges meeting in the centre of the square: no split separates
    /// them there, so the squares at the sweep's floor around that point
    /// take their centre's colour and report their share as the bound.
    #[test]
    fn edges_converging_on_a_point_stop_at_the_sweep_floor_with_a_bound() {
        let (n, r) = (1600, 0.4);
        let period = std::f64::consts::TAU / f64::from(n);
        let wedges = (0..n)
            .map(|i| {
                let a = f64::from(i) * period;
                let b = a + 0.5 * period;
                vec![
                    [0.5, 0.5],
                    [0.5 + r * a.cos(), 0.5 + r * a.sin()],
                    [0.5 + r * b.cos(), 0.5 + r * b.sin()],
                ]
            })
            .collect();
        let mut art = VectorArt::new();
        art.fill(wedges, FillRule::NonZero, Rgba::opaque(1.0, 1.0, 1.0), &[])
            .unwrap();
        let (t, report) = QuadTree::from_vector(
            &art,
            &VectorOptions {
                max_level: 0,
                ..VectorOptions::default()
            },
        )
        .unwrap();
        let exact = f64::from(n) * 0.5 * r * r * (0.5 * period).sin();
        let a = f64::from(t.average().to_array()[3]);
        assert!((a - exact).abs() <= 1.0 / 65535.0, "{a} vs {exact}");
        // Floor squares near the centre only, 4^-20 of the leaf each.
        let floor = 64.0 * 0.25f64.powi(i32::from(SWEEP_FLOOR));
        assert!(
            report.max_mean_error > 0.0 && report.max_mean_error <= floor * (1.0 + 1e-9),
            "{} against {floor}",
            report.max_mean_error
        );
    }

    #[test]
    fn sweep_work_is_counted_and_its_budget_refuses_art_beyond_it() {
        // Thin slanted bars crossing each other in one leaf: a sweep with
        // many crossings.
        let bars = (0..40)
            .map(|i| {
                let x = 0.1 + 0.02 * f64::from(i);
                let lean = if i % 2 == 0 { 0.3 } else { -0.3 };
                vec![
                    [x, 0.1],
                    [x + 0.01, 0.1],
                    [x + 0.01 + lean, 0.9],
                    [x + lean, 0.9],
                ]
            })
            .collect();
        let mut art = VectorArt::new();
        art.fill(bars, FillRule::NonZero, Rgba::opaque(0.2, 0.6, 1.0), &[])
            .unwrap();
        let options = |max_sweep_work| VectorOptions {
            max_level: 1,
            max_sweep_work,
            ..VectorOptions::default()
        };
        let (tree, report) = QuadTree::from_vector(&art, &options(u64::MAX)).unwrap();
        let needed = report.sweep_work;
        assert!(needed > 1000, "{needed}");
        let (same, again) = QuadTree::from_vector(&art, &options(needed)).unwrap();
        assert_eq!(again.sweep_work, needed);
        assert_eq!(same.average(), tree.average());
        match QuadTree::from_vector(&art, &options(needed - 1)) {
            Err(
                e @ Error::SweepWork {
                    needed: at_least,
                    max,
                },
            ) => {
                assert_eq!(max, needed - 1);
                assert!(at_least > max && at_least <= needed, "{at_least}");
                assert!(e.to_string().contains("max sweep work"), "{e}");
            }
            other => panic!("{other:?}"),
        }
    }
}
