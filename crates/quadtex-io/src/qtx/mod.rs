//! The `.qtx` file: a quadtree texture, byte layout in `docs/format.md`.

use std::fs::File;
use std::io::{Read, Write};
use std::path::Path;

use quadtex_core::BLOCK_LOG2_SIDE;
use quadtex_core::{
    Aspect, BlockFormat, ColourEncoding, ContourLeaves, GradientLeaves, QuadTree, SharedBytes,
    TexelBlocks,
};

use crate::atomic::{put, write_atomically};
use crate::error::{Error, io};
use crate::limits::Limits;

mod leaves;
use leaves::*;

/// First eight bytes of every `.qtx` file (PNG-style: a high byte, a name,
/// and line endings that reveal text-mode corruption).
pub const MAGIC: [u8; 8] = *b"\x89QTX\r\n\x1a\n";
/// The newest version this library writes (textures whose extent is not
/// a power of two, [`Aspect`]); it reads this one and every earlier one
/// (version 1 lacks the structure checksum, version 2 gradient leaves,
/// version 3 other extents). Each file is written in the oldest version
/// that holds it, so older readers still read every other file.
pub const FORMAT_VERSION: u32 = 4;

/// The version of files with gradient or contour leaves.
const LEAVES_VERSION: u32 = 3;
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
    let aspect = tree.aspect();
    // Version 4 keeps an extent that is not a power of two as the source
    // size (`source_width × source_height` texels of their natural depth,
    // reduced as `Aspect::from_extent` does); shrink bytes are then zero.
    let shrink = aspect.shrink();
    let version = match (shrink, gradient_section.is_empty()) {
        (None, _) => FORMAT_VERSION,
        (Some(_), true) => PLAIN_VERSION,
        (Some(_), false) => LEAVES_VERSION,
    };
    let (sw, sh) = match (shrink, source) {
        (Some(_), source) => source.unwrap_or((0, 0)),
        (None, Some((w, h))) if extent_of_source(w, h) == Some(aspect) => (w, h),
        (None, _) => (aspect.cells()[0], aspect.cells()[1]),
    };
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
    header[18..20].copy_from_slice(&shrink.unwrap_or([0, 0]));
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
/// and texels in place, so opening takes memory proportional to the
/// inner-node flags (1/32 of the file), not to the file.
///
/// Opening checks the header, its checksum, the structure checksum and
/// the structure itself (levels, depth, block flags) as [`read_qtx`] does,
/// **and the payload checksum over every byte after the header**: one pass
/// over the file at memory speed (CRC-32, several GB/s), so a damaged
/// colour or texel is refused on opening with an error naming the file and
/// the damaged bytes ([`Error::Format`], field `payload_crc`), never
/// answered from. The colours' own invariants (premultiplied, each parent
/// the mean of its children) are not checked; [`QuadTree::verify`] (or
/// [`read_qtx`]) checks them. [`map_qtx_unverified`] skips the payload
/// checksum for trusted files, giving up that promise for an open in time
/// proportional to the flags.
///
/// Memory mapping has one hazard no reader can check: another process
/// truncating the file while it is mapped makes later reads of the lost
/// pages fail with `SIGBUS`, and one rewriting it in place changes colours
/// under the tree (after the checksum was checked). quadtex's writers never
/// do either: they write a temporary file and rename it over the old one,
/// which leaves a mapped file intact.
pub fn map_qtx(path: &Path, limits: &Limits) -> Result<(QuadTree, QtxInfo), Error> {
    map_checked(path, limits, Check::Payload)
}

/// As [`map_qtx`] without the payload checksum, for trusted files: opening
/// reads only the header and the structure (the inner flags, 1/64 of the
/// file; a version-1 file, which has no structure checksum, is still read
/// whole), so a giant opens in milliseconds and a query loads only the
/// pages it touches. **This gives up the promise that a damaged file is
/// refused:** a corrupt colour or texel then gives a wrong colour (never a
/// panic) until [`QuadTree::verify`] is asked.
pub fn map_qtx_unverified(path: &Path, limits: &Limits) -> Result<(QuadTree, QtxInfo), Error> {
    map_checked(path, limits, Check::Structure)
}

/// [`map_qtx`] and [`map_qtx_unverified`]: maps `path`, checking what
/// `check` asks.
fn map_checked(path: &Path, limits: &Limits, check: Check) -> Result<(QuadTree, QtxInfo), Error> {
    let (file, file_bytes, h, _) = open_checked(path, limits)?;
    check_map_memory(&h, path, limits)?;
    let map = map_file(&file).map_err(io(path))?;
    // Opening without the payload checksum reads the inner flags front to
    // back: read them ahead. Queries then touch a few scattered colours
    // each: read ahead nothing there, so memory holds what is read. The
    // payload checksum reads the whole file once: the kernel's default
    // read-ahead serves it. (Advice only; a refusal changes nothing.)
    #[cfg(unix)]
    if check == Check::Structure {
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
    parse_shared(SharedBytes::from_owner(map), path, limits, check)
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

/// As [`parse_qtx`], checking only what [`map_qtx_unverified`] checks: the
/// tree reads its colours in place from `bytes` and they are not read here
/// (nor is their checksum: a damaged colour gives a wrong colour).
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
    /// Both checksums and the structure; the colours' invariants are left
    /// to [`QuadTree::verify`].
    Payload,
    /// The header, the structure checksum (the payload checksum for a
    /// version-1 file) and the structure; colours are read on demand.
    Structure,
}

/// Parses a file whose header `check_header` accepts: checksums as `check`
/// asks, the inner flags, the texel blocks and the leaf sections, then the
/// tree (verified too under [`Check::Everything`]). A payload checksum
/// mismatch is reported naming the bytes it can be in, and the first node
/// the colour checks refuse, if any.
fn parse_shared(
    all: SharedBytes,
    path: &Path,
    limits: &Limits,
    check: Check,
) -> Result<(QuadTree, QtxInfo), Error> {
    let file_bytes = all.len() as u64;
    let header = check_header(&all, file_bytes, path, limits)?;
    let payload = HEADER_BYTES..HEADER_BYTES + header.payload as usize;
    let data = &all[payload.clone()];
    let nodes = header.nodes as usize;
    let (bits, rest) = data.split_at(nodes.div_ceil(8));
    let block_section = &rest[8 * nodes..];
    if !checksums_enforced() {
        return build_tree(&all, &header, path, limits, check == Check::Everything);
    }
    let crc = &all[payload.end..];
    check_structure_crc(&header, bits, block_section, path)?;
    let payload_checked = check != Check::Structure || header.structure_crc.is_none();
    if !payload_checked
        || crc32fast::hash(data) == u32::from_le_bytes([crc[0], crc[1], crc[2], crc[3]])
    {
        return build_tree(&all, &header, path, limits, check == Check::Everything);
    }
    // Damaged: where the bytes the structure checksum leaves are, and what
    // the colour checks find there (a hint; the checksum decides).
    let colours = payload.start + bits.len()..payload.start + bits.len() + 8 * nodes;
    let region = match header.structure_crc {
        None => format!("the payload (bytes {}..{})", payload.start, payload.end),
        Some(_) if header.blocks.is_some() => format!(
            "the colours (bytes {}..{}) or the texel blocks' texels (bytes {}..{})",
            colours.start,
            colours.end,
            colours.end + structure_bytes(block_section),
            payload.end
        ),
        Some(_) => format!("the colours (bytes {}..{})", colours.start, colours.end),
    };
    let hint = build_tree(&all, &header, path, limits, false)
        .ok()
        .and_then(|(t, _)| t.verify().err())
        .map_or(String::new(), |e| format!("; the colour checks find {e}"));
    Err(format_error(
        path,
        "payload_crc",
        format!("payload checksum mismatch: {region} are damaged{hint}"),
    ))
}

/// The tree of a file whose header and checksums are checked: its inner
/// flags, texel blocks and leaf sections checked and decoded, and every
/// colour checked too when `verify` is set.
fn build_tree(
    all: &SharedBytes,
    header: &Header,
    path: &Path,
    limits: &Limits,
    verify: bool,
) -> Result<(QuadTree, QtxInfo), Error> {
    let file_bytes = all.len() as u64;
    let bad = |field: &'static str, message: String| format_error(path, field, message);
    let payload = HEADER_BYTES..HEADER_BYTES + header.payload as usize;
    let data = &all[payload.clone()];
    let nodes = header.nodes as usize;
    let (bits, rest) = data.split_at(nodes.div_ceil(8));
    let block_section = &rest[8 * nodes..];
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
            all,
            colour_start + 8 * nodes..payload.end,
            format,
            level,
            path,
        )?),
    };
    let (gradient_leaves, contour_leaves) =
        decode_leaf_sections(block_section, header, path, limits)?;
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
        if verify {
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
/// structure of `block_section`) when the file has one (version 2 and
/// later).
fn check_structure_crc(
    header: &Header,
    bits: &[u8],
    block_section: &[u8],
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

/// The extent of a `width × height` raster at its natural depth
/// (`⌈log2 max(width, height)⌉`); `None` for a zero or too large side.
fn extent_of_source(width: u32, height: u32) -> Option<Aspect> {
    let long = width.max(height);
    let level = (32 - long.checked_sub(1)?.leading_zeros()) as u8;
    Aspect::from_extent(width, height, level).ok()
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
    let aspect = if version >= 4 {
        if h[18..20] != [0, 0] {
            return Err(bad(
                "aspect",
                "a version-4 file keeps its extent as its source size; shrink bytes must be zero"
                    .into(),
            ));
        }
        extent_of_source(u32_at(20), u32_at(24)).ok_or_else(|| {
            bad(
                "source_size",
                format!(
                    "extent {}x{} is not a texture size (1 to 2^30 texels a side)",
                    u32_at(20),
                    u32_at(24)
                ),
            )
        })?
    } else {
        Aspect::new(h[18], h[19]).map_err(|e| bad("aspect", e.to_string()))?
    };
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
