//! Writes a synthetic `.qtx` file of about 4 GiB (530 million nodes), for
//! measuring how fast `map_qtx` opens a giant and what a query touches:
//!
//! ```text
//! cargo run --release -p quadtex-io --example giant_qtx -- /tmp/giant.qtx
//! quadtex info /tmp/giant.qtx
//! ```
//!
//! The tree is complete to level 14 and the first 43 million squares of
//! level 14 (in the file's breadth-first order) split once more into a
//! black-and-white checkerboard at level 15; every other square is the
//! checkerboard's mean grey. It is written directly from the format's
//! specification (`docs/format.md`, version 2), independently of
//! `write_qtx`, which would need the whole tree in memory first.

use std::io::Write;

const DEPTH: u8 = 15;
/// Squares of level 14 that split into level 15.
const SPLIT: u64 = 43_000_000;
const GREY: [u16; 4] = [32768, 32768, 32768, 65535];
const BLACK: [u16; 4] = [0, 0, 0, 65535];
const WHITE: [u16; 4] = [65535; 4];

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let path = std::env::args().nth(1).ok_or("usage: giant_qtx OUT.qtx")?;
    let complete = ((1u64 << (2 * 14)) - 1) / 3; // levels 0..=13, all inner
    let level14 = 1u64 << 28;
    let inner = complete + SPLIT;
    let nodes = 1 + 4 * inner;
    let bit_bytes = nodes.div_ceil(8);
    let payload = bit_bytes + 8 * nodes;

    let mut bits = vec![0u8; bit_bytes as usize];
    for i in 0..inner {
        // Inner nodes are the first `inner` in breadth-first order.
        bits[(i / 8) as usize] |= 1 << (i % 8);
    }
    let mut header = [0u8; 64];
    header[0..8].copy_from_slice(b"\x89QTX\r\n\x1a\n");
    header[8..12].copy_from_slice(&2u32.to_le_bytes());
    header[12..16].copy_from_slice(&64u32.to_le_bytes());
    header[16] = DEPTH;
    header[17] = 1; // unorm16 colours
    header[32..40].copy_from_slice(&nodes.to_le_bytes());
    header[40..48].copy_from_slice(&inner.to_le_bytes());
    header[48..56].copy_from_slice(&payload.to_le_bytes());
    let crc = crc32fast::hash(&header[..56]);
    header[56..60].copy_from_slice(&crc.to_le_bytes());
    let crc = crc32fast::hash(&bits);
    header[60..64].copy_from_slice(&crc.to_le_bytes());

    let tmp = format!("{path}.tmp");
    let mut out = std::io::BufWriter::with_capacity(1 << 20, std::fs::File::create(&tmp)?);
    let mut payload_crc = crc32fast::Hasher::new();
    out.write_all(&header)?;
    out.write_all(&bits)?;
    payload_crc.update(&bits);
    drop(bits);
    // Colours: grey down to level 14, then the checkerboard's leaves.
    let grey_nodes = complete + level14;
    let mut chunk = Vec::with_capacity(1 << 20);
    let mut emit = |colour: [u16; 4], chunk: &mut Vec<u8>| -> std::io::Result<()> {
        for v in colour {
            chunk.extend(v.to_le_bytes());
        }
        if chunk.len() >= 1 << 20 {
            out.write_all(chunk)?;
            payload_crc.update(chunk);
            chunk.clear();
        }
        Ok(())
    };
    for _ in 0..grey_nodes {
        emit(GREY, &mut chunk)?;
    }
    for _ in 0..SPLIT {
        // Children low-x low-z, high-x low-z, low-x high-z, high-x high-z.
        for colour in [BLACK, WHITE, WHITE, BLACK] {
            emit(colour, &mut chunk)?;
        }
    }
    out.write_all(&chunk)?;
    payload_crc.update(&chunk);
    out.write_all(&payload_crc.finalize().to_le_bytes())?;
    out.into_inner().map_err(|e| e.into_error())?.sync_all()?;
    std::fs::rename(&tmp, &path)?;
    println!(
        "{path}: {nodes} nodes ({inner} inner), depth {DEPTH}, {} bytes",
        64 + payload + 4
    );
    Ok(())
}
