//! The leaf sections after the colours: gradient leaves and contour
//! leaves (`docs/format.md`), and the little-endian reader they share.

use std::path::Path;

use quadtex_core::{ContourLeaves, GradientLeaves, LeafGroup, LeafPaint, LeafPiece, QuadTree};
use quadtex_core::{Gradient, Interpolation, Spread, Stop};

use crate::error::Error;

/// Header byte 31, bit 0: a gradient-leaf section follows the colours.
pub(super) const LEAF_KIND_GRADIENT: u8 = 1;
/// Header byte 31, bit 1: a contour-leaf section follows (after the
/// gradient-leaf section, if any).
pub(super) const LEAF_KIND_CONTOUR: u8 = 2;

/// Bytes of one contour-leaf piece, leaf and group.
pub(super) const PIECE_BYTES: usize = 48;
pub(super) const LEAF_BYTES: usize = 16;
pub(super) const GROUP_BYTES: usize = 16;

/// A contour leaf's piece or group outside any group.
pub(super) const NO_GROUP: u32 = u32::MAX;

/// The start of a leaf section's body: its `depth` and 7 reserved bytes.
pub(super) fn section_body(depth: u8, reserved: [u8; 7]) -> Vec<u8> {
    let mut body = vec![depth];
    body.extend(reserved);
    body
}

/// A leaf section: `body` behind its length.
pub(super) fn seal_section(body: Vec<u8>) -> Vec<u8> {
    let mut out = (body.len() as u64).to_le_bytes().to_vec();
    out.extend(body);
    out
}

/// Errors naming `field` of the file at `path`.
pub(super) fn section_error<'p>(
    path: &'p Path,
    field: &'static str,
) -> impl Fn(String) -> Error + 'p {
    move |message| Error::Format {
        path: path.to_path_buf(),
        field,
        message,
    }
}

/// Opens a leaf section (what [`seal_section`] wrote): checks its length
/// and that the reserved bytes after `used` are zero; the reader after
/// them, the section's depth and its first `used` reserved bytes.
pub(super) fn open_section<'a>(
    bytes: &'a [u8],
    used: usize,
    bad: &impl Fn(String) -> Error,
) -> Result<(Reader<'a>, u8, &'a [u8]), Error> {
    let mut r = Reader { bytes, at: 0 };
    let short = |what: &str| bad(format!("ends inside {what}"));
    let declared = r.u64().ok_or_else(|| short("its length"))?;
    if declared != bytes.len().saturating_sub(8) as u64 {
        return Err(bad(format!(
            "declares {declared} bytes, holds {}",
            bytes.len().saturating_sub(8)
        )));
    }
    let depth = r.u8().ok_or_else(|| short("the depth"))?;
    let reserved = r.take(7).ok_or_else(|| short("the depth"))?;
    if reserved[used..].iter().any(|&b| b != 0) {
        return Err(bad("reserved bytes are not zero".into()));
    }
    Ok((r, depth, &reserved[..used]))
}

/// The contour-leaf section (`docs/format.md`), empty without leaves.
pub(super) fn encode_contour_leaves(tree: &QuadTree) -> Vec<u8> {
    let Some(c) = tree.contour_leaves() else {
        return Vec::new();
    };
    let parts = c.parts();
    // The curve tolerance rides in the first reserved bytes (0: unstated),
    // rounded up to an f32 so the stated bound still holds.
    let tolerance = c.curve_tolerance().map_or(0.0, |t| {
        let f = t as f32;
        if f64::from(f) < t {
            f32::from_bits(f.to_bits() + 1)
        } else {
            f
        }
    });
    let mut reserved = [0u8; 7];
    reserved[..4].copy_from_slice(&tolerance.to_le_bytes());
    let mut body = section_body(c.depth(), reserved);
    let contours = parts.contour_points.len().saturating_sub(1);
    for count in [
        parts.nodes.len(),
        parts.groups.len(),
        parts.pieces.len(),
        contours,
        parts.points.len(),
    ] {
        body.extend((count as u64).to_le_bytes());
    }
    for ((node, first), first_group) in parts
        .nodes
        .iter()
        .zip(&parts.leaf_pieces)
        .zip(&parts.leaf_groups)
    {
        body.extend(node.to_le_bytes());
        body.extend(first.to_le_bytes());
        body.extend(first_group.to_le_bytes());
        body.extend([0u8; 4]);
    }
    for g in &parts.groups {
        body.extend(g.opacity.to_le_bytes());
        body.extend(g.parent.unwrap_or(NO_GROUP).to_le_bytes());
        body.extend([0u8; 4]);
    }
    for (piece, first) in parts.pieces.iter().zip(&parts.piece_contours) {
        for v in piece.colour {
            body.extend(v.to_le_bytes());
        }
        body.push(match piece.rule {
            quadtex_core::FillRule::NonZero => 0,
            quadtex_core::FillRule::EvenOdd => 1,
        });
        body.extend([0u8; 3]);
        body.extend(piece.base.to_le_bytes());
        body.extend(first.to_le_bytes());
        body.extend(piece.group.unwrap_or(NO_GROUP).to_le_bytes());
    }
    for first in &parts.contour_points[..contours] {
        body.extend(first.to_le_bytes());
    }
    for p in &parts.points {
        body.extend(p[0].to_le_bytes());
        body.extend(p[1].to_le_bytes());
    }
    seal_section(body)
}

/// The contour-leaf section `bytes` for a tree of `nodes` nodes.
pub(super) fn decode_contour_leaves(
    bytes: &[u8],
    nodes: u64,
    path: &Path,
) -> Result<ContourLeaves, Error> {
    let bad = section_error(path, "contour_leaves");
    let short = |what: &str| bad(format!("ends inside {what}"));
    let (mut r, depth, tolerance) = open_section(bytes, 4, &bad)?;
    let tolerance = f32::from_le_bytes([tolerance[0], tolerance[1], tolerance[2], tolerance[3]]);
    // Checked with the leaves (ContourLeaves::with_curve_tolerance).
    let curve_tolerance = (tolerance != 0.0).then(|| f64::from(tolerance));
    let mut counts = [0u64; 5];
    for c in &mut counts {
        *c = r.u64().ok_or_else(|| short("the counts"))?;
    }
    let [leaves, groups, pieces, contours, points] = counts;
    if leaves == 0 || leaves > nodes || counts[1..].iter().any(|&c| c >= u64::from(u32::MAX)) {
        return Err(bad(format!(
            "{leaves} leaves, {groups} groups, {pieces} pieces, {contours} contours, {points} points in a tree of {nodes} nodes"
        )));
    }
    let need = leaves * LEAF_BYTES as u64
        + groups * GROUP_BYTES as u64
        + pieces * PIECE_BYTES as u64
        + contours * 4
        + points * 16;
    if need != r.remaining() as u64 {
        return Err(bad(format!(
            "{leaves} leaves, {groups} groups, {pieces} pieces, {contours} contours and {points} points need {need} bytes, {} remain",
            r.remaining()
        )));
    }
    let mut parts = quadtex_core::ContourParts::default();
    for i in 0..leaves {
        let (Some(node), Some(first), Some(first_group), Some(reserved)) =
            (r.u32(), r.u32(), r.u32(), r.u32())
        else {
            return Err(short("the leaves"));
        };
        if reserved != 0 {
            return Err(bad(format!("leaf {i}: reserved bytes are not zero")));
        }
        parts.nodes.push(node);
        parts.leaf_pieces.push(first);
        parts.leaf_groups.push(first_group);
    }
    parts.leaf_pieces.push(pieces as u32);
    parts.leaf_groups.push(groups as u32);
    let group_ref = |v: u32| (v != NO_GROUP).then_some(v);
    for i in 0..groups {
        let (Some(opacity), Some(parent), Some(reserved)) = (r.f64(), r.u32(), r.u32()) else {
            return Err(short("the groups"));
        };
        if reserved != 0 {
            return Err(bad(format!("group {i}: reserved bytes are not zero")));
        }
        parts.groups.push(LeafGroup {
            opacity,
            parent: group_ref(parent),
        });
    }
    for i in 0..pieces {
        let colour = [(); 4].map(|_| r.f64().unwrap_or(f64::NAN));
        let head = r.take(4).ok_or_else(|| short("the pieces"))?;
        let rule = match head[0] {
            0 => quadtex_core::FillRule::NonZero,
            1 => quadtex_core::FillRule::EvenOdd,
            v => return Err(bad(format!("piece {i}: unknown fill rule {v}"))),
        };
        if head[1..] != [0, 0, 0] {
            return Err(bad(format!("piece {i}: reserved bytes are not zero")));
        }
        let (Some(base), Some(first), Some(group)) = (r.u32(), r.u32(), r.u32()) else {
            return Err(short("the pieces"));
        };
        parts.pieces.push(LeafPiece {
            colour,
            rule,
            base: base as i32,
            group: group_ref(group),
        });
        parts.piece_contours.push(first);
    }
    parts.piece_contours.push(contours as u32);
    for _ in 0..contours {
        parts
            .contour_points
            .push(r.u32().ok_or_else(|| short("the contours"))?);
    }
    parts.contour_points.push(points as u32);
    for _ in 0..points {
        let (Some(x), Some(z)) = (r.f64(), r.f64()) else {
            return Err(short("the points"));
        };
        parts.points.push([x, z]);
    }
    ContourLeaves::new(depth, parts)
        .and_then(|c| c.with_curve_tolerance(curve_tolerance))
        .map_err(|e| bad(e.to_string()))
}

/// Bytes of one stop, and of a paint besides its stops.
pub(super) const STOP_BYTES: usize = 40;
pub(super) const PAINT_BYTES: usize = 24 + 8 + 32 + 128;

/// The gradient-leaf section (`docs/format.md`), empty without leaves.
pub(super) fn encode_gradient_leaves(tree: &QuadTree) -> Vec<u8> {
    let Some(g) = tree.gradient_leaves() else {
        return Vec::new();
    };
    let mut body = section_body(g.depth(), [0; 7]);
    body.extend(g.tolerance().to_le_bytes());
    body.extend((g.paints().len() as u32).to_le_bytes());
    body.extend([0u8; 4]);
    body.extend((g.count() as u64).to_le_bytes());
    let f64s = |out: &mut Vec<u8>, vs: &[f64]| {
        for v in vs {
            out.extend(v.to_le_bytes());
        }
    };
    for p in g.paints() {
        let gr = p.gradient();
        f64s(&mut body, &gr.linear_parameter().unwrap_or([0.0; 3]));
        body.push(match gr.spread() {
            Spread::Pad => 0,
            Spread::Reflect => 1,
            Spread::Repeat => 2,
        });
        body.push(match gr.interpolation() {
            Interpolation::Srgb => 0,
            Interpolation::Linear => 1,
        });
        body.extend([0u8; 2]);
        body.extend((gr.stops().len() as u32).to_le_bytes());
        for s in gr.stops() {
            f64s(
                &mut body,
                &[s.offset, s.colour[0], s.colour[1], s.colour[2], s.opacity],
            );
        }
        f64s(&mut body, &p.offset());
        f64s(&mut body, p.matrix().as_flattened());
    }
    for (node, paint) in g.leaves() {
        body.extend(node.to_le_bytes());
        body.extend(paint.to_le_bytes());
    }
    seal_section(body)
}

/// The gradient-leaf section `bytes` (after the colours) for a tree of
/// `nodes` nodes.
pub(super) fn decode_gradient_leaves(
    bytes: &[u8],
    nodes: u64,
    path: &Path,
) -> Result<GradientLeaves, Error> {
    let bad = section_error(path, "gradient_leaves");
    let short = |what: &str| bad(format!("ends inside {what}"));
    let (mut r, depth, _) = open_section(bytes, 0, &bad)?;
    let tolerance = r.f64().ok_or_else(|| short("the tolerance"))?;
    let paint_count = r.u32().ok_or_else(|| short("the paint count"))?;
    let reserved = r.take(4).ok_or_else(|| short("the paint count"))?;
    let leaf_count = r.u64().ok_or_else(|| short("the leaf count"))?;
    if reserved.iter().any(|&b| b != 0) {
        return Err(bad("reserved bytes are not zero".into()));
    }
    if leaf_count > nodes || u64::from(paint_count) > leaf_count {
        return Err(bad(format!(
            "{leaf_count} leaves with {paint_count} paints in a tree of {nodes} nodes"
        )));
    }
    // Each paint takes at least PAINT_BYTES + one stop, each leaf 8 bytes.
    let least =
        (leaf_count * 8).saturating_add(u64::from(paint_count) * (PAINT_BYTES + STOP_BYTES) as u64);
    if least > r.remaining() as u64 {
        return Err(bad(format!(
            "{leaf_count} leaves and {paint_count} paints need at least {least} bytes, {} remain",
            r.remaining()
        )));
    }
    let mut paints = Vec::with_capacity(paint_count as usize);
    for i in 0..paint_count {
        let in_paint = |what: &str| bad(format!("paint {i}: ends inside {what}"));
        let g = [(); 3].map(|_| r.f64());
        let [Some(g0), Some(g1), Some(g2)] = g else {
            return Err(in_paint("its gradient"));
        };
        let head = r.take(4).ok_or_else(|| in_paint("its gradient"))?;
        let spread = match head[0] {
            0 => Spread::Pad,
            1 => Spread::Reflect,
            2 => Spread::Repeat,
            v => return Err(bad(format!("paint {i}: unknown spread {v}"))),
        };
        let interpolation = match head[1] {
            0 => Interpolation::Srgb,
            1 => Interpolation::Linear,
            v => return Err(bad(format!("paint {i}: unknown interpolation {v}"))),
        };
        if head[2..] != [0, 0] {
            return Err(bad(format!("paint {i}: reserved bytes are not zero")));
        }
        let stop_count = r.u32().ok_or_else(|| in_paint("its stop count"))? as usize;
        if stop_count == 0
            || stop_count > quadtex_core::MAX_STOPS
            || stop_count * STOP_BYTES > r.remaining()
        {
            return Err(bad(format!("paint {i}: {stop_count} stops")));
        }
        let mut stops = Vec::with_capacity(stop_count);
        for _ in 0..stop_count {
            let v = [(); 5].map(|_| r.f64().unwrap_or(f64::NAN));
            stops.push(Stop {
                offset: v[0],
                colour: [v[1], v[2], v[3]],
                opacity: v[4],
            });
        }
        let mut coefficients = [0.0; 20];
        for c in &mut coefficients {
            *c = r.f64().ok_or_else(|| in_paint("its coefficients"))?;
        }
        let offset = std::array::from_fn(|k| coefficients[k]);
        let matrix =
            std::array::from_fn(|row| std::array::from_fn(|k| coefficients[4 + 4 * row + k]));
        let gradient = Gradient::linear_from_parameter([g0, g1, g2], stops, spread, interpolation)
            .map_err(|e| bad(format!("paint {i}: {e}")))?;
        paints.push(
            LeafPaint::new(gradient, offset, matrix).map_err(|e| bad(format!("paint {i}: {e}")))?,
        );
    }
    if r.remaining() as u64 != leaf_count * 8 {
        return Err(bad(format!(
            "{} bytes left for {leaf_count} leaves of 8 bytes",
            r.remaining()
        )));
    }
    let mut leaves = Vec::with_capacity(leaf_count as usize);
    for _ in 0..leaf_count {
        let (Some(node), Some(paint)) = (r.u32(), r.u32()) else {
            return Err(short("the leaves"));
        };
        leaves.push((node, paint));
    }
    GradientLeaves::new(depth, tolerance, paints, &leaves).map_err(|e| bad(e.to_string()))
}

/// Little-endian fields off the front of a byte slice.
pub(super) struct Reader<'a> {
    bytes: &'a [u8],
    at: usize,
}

impl<'a> Reader<'a> {
    fn take(&mut self, n: usize) -> Option<&'a [u8]> {
        let s = self.bytes.get(self.at..self.at.checked_add(n)?)?;
        self.at += n;
        Some(s)
    }
    fn remaining(&self) -> usize {
        self.bytes.len() - self.at
    }
    fn u8(&mut self) -> Option<u8> {
        self.take(1).map(|b| b[0])
    }
    fn u32(&mut self) -> Option<u32> {
        self.take(4)
            .map(|b| u32::from_le_bytes(std::array::from_fn(|k| b[k])))
    }
    fn u64(&mut self) -> Option<u64> {
        self.take(8)
            .map(|b| u64::from_le_bytes(std::array::from_fn(|k| b[k])))
    }
    fn f64(&mut self) -> Option<f64> {
        self.u64().map(f64::from_bits)
    }
}
