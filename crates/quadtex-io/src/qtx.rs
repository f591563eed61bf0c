//! The `.qtx` file: a quadtree texture, byte layout in `docs/format.md`.

use std::fs::File;
use std::io::{Read, Write};
use std::path::Path;

use quadtex_core::texel_block::BLOCK_LOG2_SIDE;
use quadtex_core::{Aspect, BlockFormat, ColourEncoding, QuadTree, TexelBlocks, Unorm16Rgba};

use crate::atomic::{put, write_atomically};
use crate::error::{Error, io};
use crate::limits::Limits;

/// First eight bytes of every `.qtx` file (PNG-style: a high byte, a name,
/// and line endings that reveal text-mode corruption).
pub const MAGIC: [u8; 8] = *b"\x89QTX\r\n\x1a\n";
/// The version this library writes and reads.
pub const FORMAT_VERSION: u32 = 1;
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
    let blocks = encode_blocks(tree);
    let (sw, sh) = source.unwrap_or((0, 0));
    let mut header = [0u8; HEADER_BYTES];
    header[0..8].copy_from_slice(&MAGIC);
    header[8..12].copy_from_slice(&FORMAT_VERSION.to_le_bytes());
    header[12..16].copy_from_slice(&(HEADER_BYTES as u32).to_le_bytes());
    header[16] = tree.depth();
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

/// Reads a `.qtx` file under the default [`Limits`].
pub fn read_qtx(path: &Path) -> Result<QuadTree, Error> {
    read_qtx_with_limits(path, &Limits::default()).map(|(t, _)| t)
}

/// Reads and fully validates a `.qtx` file. Every size is checked against
/// the file's real length and `limits` before anything is allocated.
pub fn read_qtx_with_limits(path: &Path, limits: &Limits) -> Result<(QuadTree, QtxInfo), Error> {
    let mut file = File::open(path).map_err(io(path))?;
    let file_bytes = file.metadata().map_err(io(path))?.len();
    // Check the header (and the file's size against the limits) before reading the body, so a hostile size field
    // costs nothing.
    let mut header = [0u8; HEADER_BYTES];
    let got = read_up_to(&mut file, &mut header).map_err(io(path))?;
    check_header(&header[..got], file_bytes, path, limits)?;
    let mut bytes = header.to_vec();
    let body = (file_bytes as usize).saturating_sub(HEADER_BYTES);
    bytes
        .try_reserve_exact(body)
        .map_err(|_| out_of_memory(path, "file", body))?;
    file.read_to_end(&mut bytes).map_err(io(path))?;
    parse_qtx(&bytes, path, limits)
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

/// Parses and validates a whole `.qtx` file held in memory; `path` only
/// names the source in errors.
pub fn parse_qtx(bytes: &[u8], path: &Path, limits: &Limits) -> Result<(QuadTree, QtxInfo), Error> {
    let file_bytes = bytes.len() as u64;
    let header = check_header(bytes, file_bytes, path, limits)?;
    let bad = |field: &'static str, message: String| Error::Format {
        path: path.to_path_buf(),
        field,
        message,
    };
    let body = &bytes[HEADER_BYTES..];
    let (data, crc) = body.split_at(header.payload as usize);
    if checksums_enforced()
        && crc32fast::hash(data) != u32::from_le_bytes([crc[0], crc[1], crc[2], crc[3]])
    {
        return Err(bad(
            "payload_crc",
            "payload checksum mismatch (corrupt node data)".into(),
        ));
    }
    let nodes = header.nodes;
    let (bits, colour_bytes) = data.split_at(nodes.div_ceil(8) as usize);
    let n_words = nodes.div_ceil(64) as usize;
    let mut words = Vec::new();
    words
        .try_reserve_exact(n_words)
        .map_err(|_| out_of_memory(path, "inner flags", 8 * n_words))?;
    words.resize(n_words, 0u64);
    for (i, &b) in bits.iter().enumerate() {
        words[i / 8] |= u64::from(b) << (8 * (i % 8));
    }
    // Bits past the last node must be clear, or the count below would lie.
    if let Some(last) = words.last().filter(|_| nodes % 64 != 0)
        && last >> (nodes % 64) != 0
    {
        return Err(bad("inner_bits", "flags set beyond the last node".into()));
    }
    let counted: u64 = words.iter().map(|w| u64::from(w.count_ones())).sum();
    if counted != header.inner {
        return Err(bad(
            "inner_bits",
            format!("{counted} inner flags set, header says {}", header.inner),
        ));
    }
    let (colour_bytes, block_bytes) = colour_bytes.split_at(8 * nodes as usize);
    let mut colours = Vec::new();
    colours
        .try_reserve_exact(nodes as usize)
        .map_err(|_| out_of_memory(path, "colours", 8 * nodes as usize))?;
    colours.extend(colour_bytes.chunks_exact(8).map(|c| {
        Unorm16Rgba(std::array::from_fn(|k| {
            u16::from_le_bytes([c[2 * k], c[2 * k + 1]])
        }))
    }));
    let texel_blocks = match header.blocks {
        None => None,
        Some((format, level)) => Some(decode_blocks(block_bytes, format, level, path)?),
    };
    let tree = QuadTree::from_parts_with_blocks(
        header.depth,
        header.aspect,
        header.encoding,
        &words,
        colours,
        texel_blocks,
    )
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

/// The texel-block section after the colours: `level_nodes` and `count`
/// (u64 each), `ceil(level_nodes/8)` flag bytes, `count` blocks of texels.
fn decode_blocks(
    bytes: &[u8],
    format: BlockFormat,
    level: u8,
    path: &Path,
) -> Result<TexelBlocks, Error> {
    let bad = |message: String| Error::Format {
        path: path.to_path_buf(),
        field: "texel_blocks",
        message,
    };
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
    let mut words = vec![0u64; flag_bytes.len().div_ceil(8)];
    for (i, &b) in flag_bytes.iter().enumerate() {
        words[i / 8] |= u64::from(b) << (8 * (i % 8));
    }
    let data = bytes[16 + flag_bytes.len()..].to_vec();
    TexelBlocks::new(level, format, words, data).map_err(|e| bad(e.to_string()))
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
    if version != FORMAT_VERSION {
        return Err(bad(
            "version",
            format!("version {version} is not supported (this build reads {FORMAT_VERSION})"),
        ));
    }
    if checksums_enforced() && crc32fast::hash(&h[..56]) != u32_at(56) {
        return Err(bad(
            "header_crc",
            "header checksum mismatch (corrupt header)".into(),
        ));
    }
    if h[31] != 0 || h[60..64] != [0; 4] {
        return Err(bad("reserved", "reserved header bytes are not zero".into()));
    }
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
    let fits = match blocks {
        None => payload == nodes_payload,
        Some(_) => payload >= nodes_payload + 16,
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
    limits.check_memory(
        path,
        || format!("reading a tree of {nodes} nodes"),
        nodes.saturating_mul(crate::limits::QTX_READ_BYTES_PER_NODE),
        "raise --memory-limit, or repack at a lower --max-level",
    )?;
    Ok(Header {
        depth,
        encoding,
        aspect,
        blocks,
        nodes,
        inner,
        payload,
        source_width: u32_at(20),
        source_height: u32_at(24),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use quadtex_core::BuildOptions;
    use quadtex_core::synth;

    fn sample() -> QuadTree {
        let g = synth::runway_art().rasterise(64, 64).unwrap();
        QuadTree::from_texels(&g, &BuildOptions::default())
            .unwrap()
            .0
    }

    fn temp(name: &str) -> std::path::PathBuf {
        std::env::temp_dir().join(format!("quadtex-qtx-{}-{name}", std::process::id()))
    }

    #[test]
    fn round_trips() {
        let t = sample();
        let p = temp("rt.qtx");
        write_qtx(&p, &t, Some((64, 64))).unwrap();
        let (back, info) = read_qtx_with_limits(&p, &Limits::default()).unwrap();
        assert_eq!(back, t);
        assert_eq!((info.source_width, info.source_height), (64, 64));
        std::fs::remove_file(&p).unwrap();
    }

    /// A strip keeps its aspect through the file; a header claiming both
    /// axes shrunk is refused by name.
    #[test]
    fn strips_round_trip_with_their_aspect() {
        let g = synth::runway_art().rasterise(64, 8).unwrap();
        let (t, _) = QuadTree::from_texels(&g, &BuildOptions::default()).unwrap();
        assert_eq!(t.aspect().shrink(), [0, 3]);
        let mut bytes = Vec::new();
        write_qtx_to(&mut bytes, Path::new("strip"), &t, Some((64, 8))).unwrap();
        let (back, _) = parse_qtx(&bytes, Path::new("strip"), &Limits::default()).unwrap();
        assert_eq!(back, t);
        assert_eq!(back.aspect(), t.aspect());
        bytes[18] = 2;
        let crc = crc32fast::hash(&bytes[..56]);
        bytes[56..60].copy_from_slice(&crc.to_le_bytes());
        let e = parse_qtx(&bytes, Path::new("strip"), &Limits::default()).unwrap_err();
        assert!(e.to_string().contains("aspect"), "{e}");
    }

    /// A photograph-like 8-bit grid: most of its bottom in texel blocks.
    fn photo_sample() -> QuadTree {
        let bytes = (0..32u32 * 32)
            .map(|i| {
                let h = i.wrapping_mul(2_654_435_761);
                [
                    (h >> 8) as u8,
                    (h >> 16) as u8,
                    (h >> 24) as u8,
                    255 - (i % 3) as u8,
                ]
            })
            .collect();
        let g = quadtex_core::TexelGrid::from_srgb8(32, 32, bytes).unwrap();
        QuadTree::from_texels(&g, &BuildOptions::default())
            .unwrap()
            .0
    }

    /// Texel blocks round-trip; their section is checked structurally
    /// (checksums skipped, as under fuzzing): counts that lie, flags for
    /// the wrong nodes and a block that disowns its node's mean are refused
    /// by name.
    #[test]
    fn texel_blocks_round_trip_and_lies_are_refused() {
        let t = photo_sample();
        let blocks = t.texel_blocks().expect("blocks");
        assert_eq!(blocks.format(), BlockFormat::Srgb8Rgba);
        assert!(blocks.count() > 32, "{}", blocks.count());
        let mut bytes = Vec::new();
        write_qtx_to(&mut bytes, Path::new("photo"), &t, Some((32, 32))).unwrap();
        let (back, _) = parse_qtx(&bytes, Path::new("photo"), &Limits::default()).unwrap();
        assert_eq!(back, t);
        let reseal = |b: &mut Vec<u8>| {
            let crc = crc32fast::hash(&b[..56]);
            b[56..60].copy_from_slice(&crc.to_le_bytes());
            let end = b.len() - 4;
            let crc = crc32fast::hash(&b[64..end]);
            b[end..].copy_from_slice(&crc.to_le_bytes());
        };
        let n = t.node_count() as usize;
        let section = 64 + n.div_ceil(8) + 8 * n;
        let refused = |b: &[u8]| {
            parse_qtx(b, Path::new("photo"), &Limits::default())
                .unwrap_err()
                .to_string()
        };
        // The block count one too high.
        let mut lie = bytes.clone();
        lie[section + 8] += 1;
        reseal(&mut lie);
        assert!(refused(&lie).contains("texel_blocks"), "{}", refused(&lie));
        // Flags changed: the blocks no longer match their texels or nodes.
        for flip in [0b1u8, 0b11, 0b1000_0000] {
            let mut lie = bytes.clone();
            lie[section + 16] ^= flip;
            reseal(&mut lie);
            let e = refused(&lie);
            assert!(e.contains("texel block"), "{e}");
        }
        // A texel changed: its block no longer averages to its node.
        let mut lie = bytes.clone();
        let first_texel = section
            + 16
            + (t.level_stats()[usize::from(blocks.level())].nodes as usize).div_ceil(8);
        lie[first_texel] ^= 0xff;
        reseal(&mut lie);
        let e = refused(&lie);
        assert!(e.contains("texel block averages"), "{e}");
        // An unknown block format.
        let mut lie = bytes.clone();
        lie[28] = 9;
        reseal(&mut lie);
        assert!(refused(&lie).contains("block_format"), "{}", refused(&lie));
    }

    #[test]
    fn every_single_byte_flip_and_truncation_is_an_error() {
        let p = temp("flip.qtx");
        let q = temp("flip-bad.qtx");
        for tree in [sample(), photo_sample()] {
            write_qtx(&p, &tree, None).unwrap();
            let good = std::fs::read(&p).unwrap();
            for i in (0..good.len()).step_by(7) {
                let mut bytes = good.clone();
                bytes[i] ^= 0x10;
                std::fs::write(&q, &bytes).unwrap();
                assert!(read_qtx(&q).is_err(), "flip at byte {i} accepted");
            }
            for len in [0, 10, 63, 64, good.len() / 2, good.len() - 1] {
                std::fs::write(&q, &good[..len]).unwrap();
                let e = read_qtx(&q).unwrap_err().to_string();
                assert!(e.contains("flip-bad.qtx"), "{e}");
            }
        }
        std::fs::remove_file(&p).unwrap();
        std::fs::remove_file(&q).unwrap();
    }

    #[test]
    fn absurd_sizes_are_refused_before_allocating() {
        let p = temp("huge.qtx");
        write_qtx(&p, &sample(), None).unwrap();
        let mut bytes = std::fs::read(&p).unwrap();
        // Claim 2^40 nodes with a valid header checksum.
        bytes[32..40].copy_from_slice(&(1u64 << 40).to_le_bytes());
        let crc = crc32fast::hash(&bytes[..56]);
        bytes[56..60].copy_from_slice(&crc.to_le_bytes());
        std::fs::write(&p, &bytes).unwrap();
        let e = read_qtx(&p).unwrap_err();
        assert!(
            matches!(
                e,
                Error::Limit {
                    limit: "max_nodes",
                    ..
                }
            ),
            "{e}"
        );
        std::fs::remove_file(&p).unwrap();
    }
}
