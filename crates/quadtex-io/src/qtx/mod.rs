//! The `.qtx` file: a quadtree texture, byte layout in `docs/format.md`.

use std::fs::File;
use std::io::{Read, Write};
use std::path::Path;

use quadtex_core::BLOCK_LOG2_SIDE;
use quadtex_core::{
    Aspect, BlockFormat, ColourEncoding, ContourLeaves, GradientLeaves, LeafGroup, LeafPaint,
    LeafPiece, QuadTree, SharedBytes, TexelBlocks,
};
use quadtex_core::{Gradient, Interpolation, Spread, Stop};

use crate::atomic::{put, write_atomically};
use crate::error::{Error, io};
use crate::limits::Limits;

/// First eight bytes of every `.qtx` file (PNG-style: a high byte, a name,
/// and line endings that reveal text-mode corruption).
pub const MAGIC: [u8; 8] = *b"\x89QTX\r\n\x1a\n";
/// The newest version this library writes (files with gradient leaves);
/// it reads this one and every earlier one (version 1 lacks the structure
/// checksum, version 2 gradient leaves). Files without gradient leaves
/// are written as version 2, so older readers still read them.
pub const FORMAT_VERSION: u32 = 3;

/// The version of files without gradient leaves.
const PLAIN_VERSION: u32 = 2;
const HEADER_BYTES: usize = 64;

/// Facts about a `.qtx` file beyond the tree itself.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct QtxInfo {
    /// Width of the image the tree was packed from (0 when not a raster).
    pub source_width: u32,
    /// Height of the image the tree was packed from (0 when not a raster).
    pub source_height: u32,
    /// Size of the file in bytes.
    pub file_bytes: u64,
}

/// Writes `tree` to `path` atomically. `source` is the raster size it came
/// from, if any, kept for reports.
///
/// `path` is handled as [`write_atomically`] describes: a symbolic link is
/// followed and stays a link; a device, FIFO or socket is written in place.
pub fn write_qtx(path: &Path, tree: &QuadTree, source: Option<(u32, u32)>) -> Result<(), Error> {
    let parts = encode_qtx(tree, source);
    write_atomically(path, |w| {
        for part in &parts {
            put(w, path, part)?;
        }
        Ok(())
    })
}

/// Writes `tree` as a `.qtx` file to a stream (standard output, a pipe, a
/// socket…), then flushes it; `name` names the stream in errors (for
/// example `standard output`). The bytes are those [`write_qtx`] writes.
pub fn write_qtx_to(
    w: &mut dyn Write,
    name: &Path,
    tree: &QuadTree,
    source: Option<(u32, u32)>,
) -> Result<(), Error> {
    for part in encode_qtx(tree, source) {
        put(w, name, &part)?;
    }
    w.flush().map_err(io(name))
}

/// The file's parts: header, inner-node bits, colours, texel blocks
/// (empty without), payload CRC.
fn encode_qtx(tree: &QuadTree, source: Option<(u32, u32)>) -> [Vec<u8>; 5] {
    let n = tree.node_count();
    let bit_bytes = n.div_ceil(8) as usize;
    let mut bits = vec![0u8; bit_bytes];
    let mut colours = Vec::with_capacity(8 * n as usize);
    let mut inner = 0u64;
    for (i, (is_inner, c)) in tree.nodes().enumerate() {
        if is_inner {
            bits[i / 8] |= 1 << (i % 8);
            inner += 1;
        }
        for v in c.0 {
            colours.extend(v.to_le_bytes());
        }
    }
    let mut blocks = encode_blocks(tree);
    let mut gradient_section = encode_gradient_leaves(tree);
    let contour_section = encode_contour_leaves(tree);
    let kinds = u8::from(!gradient_section.is_empty()) * LEAF_KIND_GRADIENT
        + u8::from(!contour_section.is_empty()) * LEAF_KIND_CONTOUR;
    gradient_section.extend(contour_section);
    let version = if gradient_section.is_empty() {
        PLAIN_VERSION
    } else {
        FORMAT_VERSION
    };
    let (sw, sh) = source.unwrap_or((0, 0));
    let mut header = [0u8; HEADER_BYTES];
    header[0..8].copy_from_slice(&MAGIC);
    header[8..12].copy_from_slice(&version.to_le_bytes());
    header[12..16].copy_from_slice(&(HEADER_BYTES as u32).to_le_bytes());
    header[16] = tree.stored_depth();
    if !gradient_section.is_empty() {
        header[31] = kinds;
        // The two sections never meet: trees with texel blocks have no gradient leaves.
        blocks = gradient_section;
    }
    header[17] = tree.encoding().code();
    header[18..20].copy_from_slice(&tree.aspect().shrink());
    header[20..24].copy_from_slice(&sw.to_le_bytes());
    header[24..28].copy_from_slice(&sh.to_le_bytes());
    header[32..40].copy_from_slice(&n.to_le_bytes());
    header[40..48].copy_from_slice(&inner.to_le_bytes());
    if let Some(b) = tree.texel_blocks() {
        header[28] = b.format().code();
        header[29] = b.level();
        header[30] = b.log2_side();
    }
    header[48..56]
        .copy_from_slice(&((bit_bytes + colours.len() + blocks.len()) as u64).to_le_bytes());
    let header_crc = crc32fast::hash(&header[..56]);
    header[56..60].copy_from_slice(&header_crc.to_le_bytes());
    let mut hasher = crc32fast::Hasher::new();
    hasher.update(&bits);
    hasher.update(&blocks[..section_structure_bytes(&blocks, header[31])]);
    header[60..64].copy_from_slice(&hasher.finalize().to_le_bytes());
    let mut hasher = crc32fast::Hasher::new();
    hasher.update(&bits);
    hasher.update(&colours);
    hasher.update(&blocks);
    let payload_crc = hasher.finalize();
    [
        header.to_vec(),
        bits,
        colours,
        blocks,
        payload_crc.to_le_bytes().to_vec(),
    ]
}

/// The texel-block section (`docs/format.md`): nodes at the block level,
/// blocks, one flag bit per node of the level, the blocks' texels.
fn encode_blocks(tree: &QuadTree) -> Vec<u8> {
    let Some(b) = tree.texel_blocks() else {
        return Vec::new();
    };
    let level_nodes = tree
        .level_stats()
        .get(usize::from(b.level()))
        .map_or(0, |l| l.nodes);
    let flag_bytes = level_nodes.div_ceil(8) as usize;
    let mut out = Vec::with_capacity(16 + flag_bytes + b.data().len());
    out.extend(level_nodes.to_le_bytes());
    out.extend(b.count().to_le_bytes());
    let words: Vec<u64> = b.flag_words().collect();
    out.extend((0..flag_bytes).map(|i| (words[i / 8] >> (8 * (i % 8))) as u8));
    out.extend_from_slice(b.data());
    out
}

/// Header byte 31, bit 0: a gradient-leaf section follows the colours.
const LEAF_KIND_GRADIENT: u8 = 1;
/// Header byte 31, bit 1: a contour-leaf section follows (after the
/// gradient-leaf section, if any).
const LEAF_KIND_CONTOUR: u8 = 2;

/// Bytes of one contour-leaf piece, leaf and group.
const PIECE_BYTES: usize = 48;
const LEAF_BYTES: usize = 16;
const GROUP_BYTES: usize = 16;

/// A contour leaf's piece or group outside any group.
const NO_GROUP: u32 = u32::MAX;

/// The start of a leaf section's body: its `depth` and 7 reserved bytes.
fn section_body(depth: u8, reserved: [u8; 7]) -> Vec<u8> {
    let mut body = vec![depth];
    body.extend(reserved);
    body
}

/// A leaf section: `body` behind its length.
fn seal_section(body: Vec<u8>) -> Vec<u8> {
    let mut out = (body.len() as u64).to_le_bytes().to_vec();
    out.extend(body);
    out
}

/// Errors naming `field` of the file at `path`.
fn section_error<'p>(path: &'p Path, field: &'static str) -> impl Fn(String) -> Error + 'p {
    move |message| Error::Format {
        path: path.to_path_buf(),
        field,
        message,
    }
}

/// Opens a leaf section (what [`seal_section`] wrote): checks its length
/// and that the reserved bytes after `used` are zero; the reader after
/// them, the section's depth and its first `used` reserved bytes.
fn open_section<'a>(
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
fn encode_contour_leaves(tree: &QuadTree) -> Vec<u8> {
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
fn decode_contour_leaves(bytes: &[u8], nodes: u64, path: &Path) -> Result<ContourLeaves, Error> {
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
const STOP_BYTES: usize = 40;
const PAINT_BYTES: usize = 24 + 8 + 32 + 128;

/// The gradient-leaf section (`docs/format.md`), empty without leaves.
fn encode_gradient_leaves(tree: &QuadTree) -> Vec<u8> {
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
fn decode_gradient_leaves(bytes: &[u8], nodes: u64, path: &Path) -> Result<GradientLeaves, Error> {
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
struct Reader<'a> {
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

/// Reads and fully validates a `.qtx` file: both checksums, the structure
/// and every colour ([`QuadTree::verify`]), under `limits` (often
/// `&Limits::default()`). Every size is checked against
/// the file's real length and `limits` before anything is allocated. The
/// tree reads its colours in place from the file's bytes (no second copy).
pub fn read_qtx(path: &Path, limits: &Limits) -> Result<(QuadTree, QtxInfo), Error> {
    let (mut file, file_bytes, h, header) = open_checked(path, limits)?;
    check_read_memory(&h, path, limits)?;
    let mut bytes = header.to_vec();
    let body = (file_bytes as usize).saturating_sub(HEADER_BYTES);
    bytes
        .try_reserve_exact(body)
        .map_err(|_| out_of_memory(path, "file", body))?;
    file.read_to_end(&mut bytes).map_err(io(path))?;
    parse_shared(bytes.into(), path, limits, Check::Everything)
}

/// Opens a `.qtx` file by memory-mapping it: the tree reads its colours
/// and texels in place, so opening costs time and memory proportional to
/// the inner-node flags (1/64 of the file), not to the file, and a query
/// loads only the pages it touches.
///
/// Opening checks the header, its checksum, the structure checksum of a
/// version-2 file and the structure itself (levels, depth, block flags) as
/// [`read_qtx`] does; it does **not** read the colours, so
/// their checksum and invariants are left to [`QuadTree::verify`] (or to
/// [`read_qtx`]). A corrupt colour then gives a wrong colour,
/// never a panic. A version-1 file has no structure checksum: its whole
/// payload checksum is checked instead, which reads the file.
///
/// Memory mapping has one hazard no reader can check: another process
/// truncating the file while it is mapped makes later reads of the lost
/// pages fail with `SIGBUS`, and one rewriting it in place changes colours
/// under the tree. quadtex's writers never do either: they write a
/// temporary file and rename it over the old one, which leaves a mapped
/// file intact.
pub fn map_qtx(path: &Path, limits: &Limits) -> Result<(QuadTree, QtxInfo), Error> {
    let (file, file_bytes, h, _) = open_checked(path, limits)?;
    check_map_memory(&h, path, limits)?;
    let map = map_file(&file).map_err(io(path))?;
    // Opening reads the inner flags front to back: read them ahead. Queries
    // then touch a few scattered colours each: read ahead nothing there, so
    // memory holds what is read. (Advice only; a refusal changes nothing.)
    #[cfg(unix)]
    {
        let flags = HEADER_BYTES + h.nodes.div_ceil(8) as usize;
        let _ = map.advise(memmap2::Advice::Random);
        let _ = map.advise_range(memmap2::Advice::Sequential, 0, flags.min(map.len()));
    }
    if map.len() as u64 != file_bytes {
        return Err(Error::Format {
            path: path.to_path_buf(),
            field: "length",
            message: format!(
                "file changed while opening: {} bytes, then {}",
                file_bytes,
                map.len()
            ),
        });
    }
    parse_shared(SharedBytes::from_owner(map), path, limits, Check::Structure)
}

/// Opens `path` and checks its header (and its size against the limits)
/// before anything sized by it is read, so a hostile size field costs
/// nothing: the file positioned after the header, its length, the header
/// parsed and its bytes.
fn open_checked(
    path: &Path,
    limits: &Limits,
) -> Result<(File, u64, Header, [u8; HEADER_BYTES]), Error> {
    let mut file = File::open(path).map_err(io(path))?;
    let file_bytes = file.metadata().map_err(io(path))?.len();
    let mut header = [0u8; HEADER_BYTES];
    let got = read_up_to(&mut file, &mut header).map_err(io(path))?;
    let h = check_header(&header[..got], file_bytes, path, limits)?;
    Ok((file, file_bytes, h, header))
}

/// Maps `file` read-only.
#[allow(unsafe_code)]
fn map_file(file: &File) -> std::io::Result<memmap2::Mmap> {
    // SAFETY: `Mmap::map` is unsafe because the mapped bytes may change or
    // vanish if another process modifies or truncates the file. The map is
    // read-only and every read through it is bounds-checked against the
    // length fixed here, so a hostile *content* is just input (validated
    // like any other); the remaining hazard, a concurrent truncation or
    // in-place rewrite, is documented on `map_qtx` and never done by
    // quadtex's own writers (temporary file + rename).
    unsafe { memmap2::Mmap::map(file) }
}

/// Refuses a read whose peak, [`crate::QTX_READ_BYTES_PER_NODE`] a node,
/// exceeds the memory budget.
fn check_read_memory(h: &Header, path: &Path, limits: &Limits) -> Result<(), Error> {
    limits.check_memory(
        path,
        || format!("reading a tree of {} nodes", h.nodes),
        h.nodes
            .saturating_mul(crate::limits::QTX_READ_BYTES_PER_NODE),
        "raise --memory-limit, or repack at a lower --max-level",
    )
}

/// Refuses a mapping whose inner flags' rank counters (a quarter byte a
/// node) exceed the memory budget.
fn check_map_memory(h: &Header, path: &Path, limits: &Limits) -> Result<(), Error> {
    limits.check_memory(
        path,
        || format!("mapping a tree of {} nodes", h.nodes),
        h.nodes.div_ceil(4),
        "raise --memory-limit",
    )
}

/// The error for an allocation of `bytes` for `what` the allocator refused.
fn out_of_memory(path: &Path, what: &str, bytes: usize) -> Error {
    crate::error::core(path)(quadtex_core::Error::AllocationFailed {
        what: format!("reading {what}"),
        bytes: bytes as u64,
    })
}

fn read_up_to(file: &mut File, buf: &mut [u8]) -> std::io::Result<usize> {
    let mut filled = 0;
    while filled < buf.len() {
        match file.read(&mut buf[filled..])? {
            0 => break,
            n => filled += n,
        }
    }
    Ok(filled)
}

/// Parses and fully validates a whole `.qtx` file held in memory (copied
/// once); `path` only names the source in errors.
pub fn parse_qtx(bytes: &[u8], path: &Path, limits: &Limits) -> Result<(QuadTree, QtxInfo), Error> {
    let h = check_header(bytes, bytes.len() as u64, path, limits)?;
    check_read_memory(&h, path, limits)?;
    parse_shared(bytes.to_vec().into(), path, limits, Check::Everything)
}

/// As [`parse_qtx`], checking only what [`map_qtx`] checks: the tree reads
/// its colours in place from `bytes` and they are not read here.
pub fn parse_qtx_structure(
    bytes: SharedBytes,
    path: &Path,
    limits: &Limits,
) -> Result<(QuadTree, QtxInfo), Error> {
    let h = check_header(&bytes, bytes.len() as u64, path, limits)?;
    check_map_memory(&h, path, limits)?;
    parse_shared(bytes, path, limits, Check::Structure)
}

/// How much of a file is read when it is opened.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Check {
    /// Both checksums, the structure and every colour.
    Everything,
    /// The header, the structure checksum (the payload checksum for a
    /// version-1 file) and the structure; colours are read on demand.
    Structure,
}

/// Parses a file whose header `check_header` accepts: checksums as `check`
/// asks, the inner flags, the texel blocks and the leaf sections, then the
/// tree (verified too under [`Check::Everything`]).
fn parse_shared(
    all: SharedBytes,
    path: &Path,
    limits: &Limits,
    check: Check,
) -> Result<(QuadTree, QtxInfo), Error> {
    let file_bytes = all.len() as u64;
    let header = check_header(&all, file_bytes, path, limits)?;
    let bad = |field: &'static str, message: String| format_error(path, field, message);
    let payload = HEADER_BYTES..HEADER_BYTES + header.payload as usize;
    let data = &all[payload.clone()];
    let nodes = header.nodes as usize;
    let (bits, rest) = data.split_at(nodes.div_ceil(8));
    let block_section = &rest[8 * nodes..];
    if checksums_enforced() {
        let crc = &all[payload.end..];
        check_checksums(&header, data, bits, block_section, crc, check, path)?;
    }
    check_inner_flags(bits, nodes, header.inner, path)?;
    let colour_start = payload.start + bits.len();
    let shared = |range: std::ops::Range<usize>| {
        all.slice(range)
            .ok_or_else(|| bad("payload_bytes", "section outside the file".into()))
    };
    let colours = shared(colour_start..colour_start + 8 * nodes)?;
    let texel_blocks = match header.blocks {
        None => None,
        Some((format, level)) => Some(decode_blocks(
            &all,
            colour_start + 8 * nodes..payload.end,
            format,
            level,
            path,
        )?),
    };
    let (gradient_leaves, contour_leaves) =
        decode_leaf_sections(block_section, &header, path, limits)?;
    let tree = QuadTree::from_shared_parts(
        header.depth,
        header.aspect,
        header.encoding,
        bits,
        colours,
        texel_blocks,
    )
    .and_then(|t| match contour_leaves {
        Some(c) => t.with_contour_leaves(c),
        None => Ok(t),
    })
    .and_then(|t| match gradient_leaves {
        Some(g) => t.with_gradient_leaves(g),
        None => Ok(t),
    })
    .and_then(|t| {
        if check == Check::Everything {
            t.verify()?;
        }
        Ok(t)
    })
    .map_err(|e| match e {
        quadtex_core::Error::AllocationFailed { .. } => crate::error::core(path)(e),
        e => bad("nodes", e.to_string()),
    })?;
    Ok((
        tree,
        QtxInfo {
            source_width: header.source_width,
            source_height: header.source_height,
            file_bytes,
        },
    ))
}

/// A malformed `field` of file `path`.
fn format_error(path: &Path, field: &'static str, message: String) -> Error {
    Error::Format {
        path: path.to_path_buf(),
        field,
        message,
    }
}

/// Checks the structure checksum (over the inner flags `bits` and the
/// structure of `block_section`) when the file has one, and the payload
/// checksum `crc` over `data` when `check` reads everything or the file
/// has no structure checksum (version 1).
fn check_checksums(
    header: &Header,
    data: &[u8],
    bits: &[u8],
    block_section: &[u8],
    crc: &[u8],
    check: Check,
    path: &Path,
) -> Result<(), Error> {
    if let Some(expected) = header.structure_crc {
        let mut hasher = crc32fast::Hasher::new();
        hasher.update(bits);
        hasher.update(&block_section[..section_structure_bytes(block_section, header.leaf_kinds)]);
        if hasher.finalize() != expected {
            return Err(format_error(
                path,
                "structure_crc",
                "structure checksum mismatch (corrupt inner flags or block flags)".into(),
            ));
        }
    }
    if (check == Check::Everything || header.structure_crc.is_none())
        && crc32fast::hash(data) != u32::from_le_bytes([crc[0], crc[1], crc[2], crc[3]])
    {
        return Err(format_error(
            path,
            "payload_crc",
            "payload checksum mismatch (corrupt node data)".into(),
        ));
    }
    Ok(())
}

/// Checks that the inner flags of `nodes` nodes number `inner`.
fn check_inner_flags(bits: &[u8], nodes: usize, inner: u64, path: &Path) -> Result<(), Error> {
    // Flags past the last node must be clear, or the count below would lie.
    if !nodes.is_multiple_of(8) && bits.last().is_some_and(|&b| b >> (nodes % 8) != 0) {
        return Err(format_error(
            path,
            "inner_bits",
            "flags set beyond the last node".into(),
        ));
    }
    let counted: u64 = bits.iter().map(|b| u64::from(b.count_ones())).sum();
    if counted != inner {
        return Err(format_error(
            path,
            "inner_bits",
            format!("{counted} inner flags set, header says {inner}"),
        ));
    }
    Ok(())
}

/// Decodes the leaf sections the header's kinds announce, from `sections`
/// (what follows the colours): the gradient-leaf section, then the
/// contour-leaf section, each opening with its own length; refuses bytes
/// after them and leaves deeper than [`Limits::max_depth`].
fn decode_leaf_sections(
    mut sections: &[u8],
    header: &Header,
    path: &Path,
    limits: &Limits,
) -> Result<(Option<GradientLeaves>, Option<ContourLeaves>), Error> {
    let kind = header.leaf_kinds;
    let mut next_section = |present: bool| -> Result<Option<&[u8]>, Error> {
        if !present {
            return Ok(None);
        }
        let len = sections
            .get(..8)
            .map(|b| u64::from_le_bytes(std::array::from_fn(|k| b[k])))
            .and_then(|l| usize::try_from(l).ok())
            .and_then(|l| l.checked_add(8))
            .filter(|&l| l <= sections.len())
            .ok_or_else(|| {
                format_error(
                    path,
                    "payload_bytes",
                    "a leaf section overruns the payload".into(),
                )
            })?;
        let (here, rest) = sections.split_at(len);
        sections = rest;
        Ok(Some(here))
    };
    let gradient_leaves = match next_section(kind & LEAF_KIND_GRADIENT != 0)? {
        Some(b) => Some(decode_gradient_leaves(b, header.nodes, path)?),
        None => None,
    };
    let contour_leaves = match next_section(kind & LEAF_KIND_CONTOUR != 0)? {
        Some(b) => Some(decode_contour_leaves(b, header.nodes, path)?),
        None => None,
    };
    if kind != 0 && !sections.is_empty() {
        return Err(format_error(
            path,
            "payload_bytes",
            format!("{} bytes after the leaf sections", sections.len()),
        ));
    }
    let leaf_depth = gradient_leaves
        .as_ref()
        .map(GradientLeaves::depth)
        .max(contour_leaves.as_ref().map(ContourLeaves::depth));
    if let Some(d) = leaf_depth
        && d > limits.max_depth
    {
        return Err(Error::Limit {
            path: path.to_path_buf(),
            limit: "max_depth",
            value: d.into(),
            max: limits.max_depth.into(),
        });
    }
    Ok((gradient_leaves, contour_leaves))
}

/// Bytes of the section after the colours that the structure checksum
/// covers: all of a gradient-leaf section (header byte 31 `kind`), the
/// counts and flags of a texel-block section.
fn section_structure_bytes(section: &[u8], kind: u8) -> usize {
    match kind {
        k if k != 0 => section.len(),
        _ => structure_bytes(section),
    }
}

/// Bytes of the texel-block section the structure checksum covers: its
/// counts and flags (all of it, if shorter: the structure checks then
/// refuse it).
fn structure_bytes(section: &[u8]) -> usize {
    let Some(counts) = section.get(..8) else {
        return section.len();
    };
    let level_nodes = u64::from_le_bytes(std::array::from_fn(|k| counts[k]));
    usize::try_from(level_nodes.div_ceil(8).saturating_add(16))
        .unwrap_or(usize::MAX)
        .min(section.len())
}

/// The texel-block section `all[range]` after the colours: `level_nodes`
/// and `count` (u64 each), `ceil(level_nodes/8)` flag bytes, `count`
/// blocks of texels (read in place, not checked here).
fn decode_blocks(
    all: &SharedBytes,
    range: std::ops::Range<usize>,
    format: BlockFormat,
    level: u8,
    path: &Path,
) -> Result<TexelBlocks, Error> {
    let bad = |message: String| Error::Format {
        path: path.to_path_buf(),
        field: "texel_blocks",
        message,
    };
    let bytes = &all[range.clone()];
    if bytes.len() < 16 {
        return Err(bad(format!(
            "{} bytes, shorter than its 16-byte counts",
            bytes.len()
        )));
    }
    let u64_at = |o: usize| u64::from_le_bytes(std::array::from_fn(|k| bytes[o + k]));
    let (level_nodes, count) = (u64_at(0), u64_at(8));
    let block = (format.bytes_per_texel() as u64) << (2 * BLOCK_LOG2_SIDE);
    let expected = level_nodes
        .div_ceil(8)
        .checked_add(count.saturating_mul(block))
        .and_then(|v| v.checked_add(16));
    if expected != Some(bytes.len() as u64) || count > level_nodes {
        return Err(bad(format!(
            "{count} blocks over {level_nodes} nodes do not fill its {} bytes",
            bytes.len()
        )));
    }
    let flag_bytes = &bytes[16..16 + level_nodes.div_ceil(8) as usize];
    let mut words = Vec::new();
    words
        .try_reserve_exact(flag_bytes.len().div_ceil(8))
        .map_err(|_| out_of_memory(path, "texel block flags", flag_bytes.len()))?;
    words.extend(
        flag_bytes
            .chunks(8)
            .map(|c| u64::from_le_bytes(std::array::from_fn(|k| c.get(k).copied().unwrap_or(0)))),
    );
    let data_start = range.start + 16 + flag_bytes.len();
    let data = all
        .slice(data_start..range.end)
        .ok_or_else(|| bad("texels outside the file".into()))?;
    TexelBlocks::from_shared(level, format, words, data).map_err(|e| bad(e.to_string()))
}

/// Checksums are skipped only in fuzzing builds (`--cfg fuzzing`), so the
/// fuzzer reaches the structural checks behind them instead of stalling on
/// random CRC mismatches.
const fn checksums_enforced() -> bool {
    !cfg!(fuzzing)
}

struct Header {
    depth: u8,
    encoding: ColourEncoding,
    aspect: Aspect,
    /// Texel blocks: their format and level.
    blocks: Option<(BlockFormat, u8)>,
    nodes: u64,
    inner: u64,
    payload: u64,
    /// The structure checksum (version 2 and later).
    structure_crc: Option<u32>,
    /// Which leaf sections follow the colours (version 3; header byte 31).
    leaf_kinds: u8,
    source_width: u32,
    source_height: u32,
}

/// Validates the 64-byte header of a file of `file_bytes` bytes; `h` may be
/// shorter than 64 bytes (a truncated file).
fn check_header(h: &[u8], file_bytes: u64, path: &Path, limits: &Limits) -> Result<Header, Error> {
    let bad = |field: &'static str, message: String| Error::Format {
        path: path.to_path_buf(),
        field,
        message,
    };
    let limit = |limit: &'static str, value: u64, max: u64| Error::Limit {
        path: path.to_path_buf(),
        limit,
        value,
        max,
    };
    limits.check_file_size(path, file_bytes)?;
    if h.len() < HEADER_BYTES {
        if h.len() >= 8 && h[0..8] != MAGIC {
            return Err(bad(
                "magic",
                "not a quadtex .qtx file (wrong magic bytes)".into(),
            ));
        }
        return Err(bad(
            "header",
            format!("file is {file_bytes} bytes, shorter than the {HEADER_BYTES}-byte header"),
        ));
    }
    if h[0..8] != MAGIC {
        return Err(bad(
            "magic",
            "not a quadtex .qtx file (wrong magic bytes)".into(),
        ));
    }
    let u32_at = |o: usize| u32::from_le_bytes([h[o], h[o + 1], h[o + 2], h[o + 3]]);
    let u64_at = |o: usize| u64::from(u32_at(o)) | u64::from(u32_at(o + 4)) << 32;
    let version = u32_at(8);
    if !(1..=FORMAT_VERSION).contains(&version) {
        return Err(bad(
            "version",
            format!("version {version} is not supported (this build reads 1 to {FORMAT_VERSION})"),
        ));
    }
    if checksums_enforced() && crc32fast::hash(&h[..56]) != u32_at(56) {
        return Err(bad(
            "header_crc",
            "header checksum mismatch (corrupt header)".into(),
        ));
    }
    if version == 1 && h[60..64] != [0; 4] {
        return Err(bad("reserved", "reserved header bytes are not zero".into()));
    }
    let leaf_kinds = match h[31] {
        0 => 0,
        v @ 1..=3 if version >= 3 && h[28] == 0 => v,
        v => {
            return Err(bad(
                "leaf_kinds",
                format!(
                    "leaf kinds {v} in a version-{version} file{} (version 3 defines bits 1, gradient leaves, and 2, contour leaves, without texel blocks)",
                    if h[28] != 0 { " with texel blocks" } else { "" }
                ),
            ));
        }
    };
    let structure_crc = (version >= 2).then(|| u32_at(60));
    if u32_at(12) as usize != HEADER_BYTES {
        return Err(bad(
            "header_bytes",
            format!("{} (expected {HEADER_BYTES})", u32_at(12)),
        ));
    }
    let depth = h[16];
    if depth > limits.max_depth {
        return Err(limit("max_depth", depth.into(), limits.max_depth.into()));
    }
    let aspect = Aspect::new(h[18], h[19]).map_err(|e| bad("aspect", e.to_string()))?;
    let blocks = match h[28] {
        0 if h[29..31] == [0, 0] => None,
        0 => {
            return Err(bad(
                "block_format",
                "no texel blocks, but a block level or side".into(),
            ));
        }
        code => {
            let format = BlockFormat::from_code(code)
                .ok_or_else(|| bad("block_format", format!("unknown texel block format {code}")))?;
            if h[30] != BLOCK_LOG2_SIDE || h[29] > depth {
                return Err(bad(
                    "block_level",
                    format!(
                        "blocks of 2^{} texels at level {} in a tree of depth {depth} (blocks are 2^{BLOCK_LOG2_SIDE} a side)",
                        h[30], h[29]
                    ),
                ));
            }
            Some((format, h[29]))
        }
    };
    let encoding = ColourEncoding::from_code(h[17])
        .ok_or_else(|| bad("colour_format", format!("unknown colour format {}", h[17])))?;
    let nodes = u64_at(32);
    let inner = u64_at(40);
    if nodes > limits.max_nodes {
        return Err(limit("max_nodes", nodes, limits.max_nodes));
    }
    if nodes == 0 || inner.checked_mul(4).and_then(|x| x.checked_add(1)) != Some(nodes) {
        return Err(bad(
            "node_count",
            format!("{nodes} nodes cannot hold {inner} inner nodes of four children each"),
        ));
    }
    let nodes_payload = nodes.div_ceil(8) + 8 * nodes;
    // Texel blocks follow the nodes: at least their 16 bytes of counts.
    let payload = u64_at(48);
    let fits = match (blocks, leaf_kinds) {
        (None, 0) => payload == nodes_payload,
        (None, _) => payload >= nodes_payload + 8,
        (Some(_), _) => payload >= nodes_payload + 16,
    };
    if !fits {
        return Err(bad(
            "payload_bytes",
            format!("{payload} declared, {nodes_payload} implied by node_count"),
        ));
    }
    let expected = HEADER_BYTES as u64 + payload + 4;
    if file_bytes != expected {
        return Err(bad(
            "length",
            format!(
                "file is {file_bytes} bytes, the header implies {expected} (truncated or trailing data)"
            ),
        ));
    }
    Ok(Header {
        depth,
        encoding,
        aspect,
        blocks,
        nodes,
        inner,
        payload,
        structure_crc,
        leaf_kinds,
        source_width: u32_at(20),
        source_height: u32_at(24),
    })
}

#[cfg(test)]
mod tests;
