//! `quadtex query`: fragments on stdin, their integrated colours on stdout.

use std::io::{BufRead, BufWriter, Write};
use std::path::PathBuf;

use super::Result;
use super::common::{MemoryArgs, level};
use super::output::Text;

/// Answer fragments from stdin with their integrated colour.
///
/// Reads one fragment `x0 z0 x1 z1` per line on stdin (texture space, the
/// texture is the unit square; blank lines and lines starting with `#` are
/// skipped) and writes one line `r g b a` per fragment: the integral of
/// linear, premultiplied colour over the fragment's overlap with the unit
/// square (divide by that area for the mean colour).
#[derive(Debug, clap::Args)]
pub struct Args {
    /// The .qtx file to query.
    #[arg(value_name = "FILE.qtx")]
    path: PathBuf,
    /// Integrate at this level (default: the tree's depth, exact).
    #[arg(short = 'k', long, value_name = "K", value_parser = level("--level"))]
    level: Option<u8>,
    /// Read the file whole and verify every colour before answering
    /// (default: memory-map it, check its structure and its payload
    /// checksum, one pass at memory speed, then read only the nodes the
    /// fragments touch).
    #[arg(long, conflicts_with = "no_verify")]
    verify: bool,
    /// For trusted files: map the file without checking its payload
    /// checksum (opens in time proportional to its structure, 1/64 of the
    /// file). Gives up the promise that a damaged file is refused: a
    /// corrupt colour is answered as it is.
    #[arg(long)]
    no_verify: bool,
    #[command(flatten)]
    memory: MemoryArgs,
}

/// Runs `quadtex query`.
pub fn run(args: Args) -> Result<()> {
    let limits = args.memory.limits();
    let (tree, _) = if args.verify {
        quadtex_io::read_qtx(&args.path, &limits)?
    } else if args.no_verify {
        quadtex_io::map_qtx_unverified(&args.path, &limits)?
    } else {
        quadtex_io::map_qtx(&args.path, &limits)?
    };
    let k = args.level.unwrap_or(tree.depth());
    let stdin = std::io::stdin().lock();
    let mut out = BufWriter::new(Text::stdout());
    for (i, line) in stdin.lines().enumerate() {
        let line = line.map_err(|e| format!("stdin line {}: {e}", i + 1))?;
        let Some(fragment) = quadtex_io::parse_query_line(&line)
            .map_err(|e| format!("stdin line {}: {e}", i + 1))?
        else {
            continue;
        };
        let w = tree.weighted_colour(&fragment, k);
        writeln!(out, "{} {} {} {}", w.0[0], w.0[1], w.0[2], w.0[3])?;
    }
    out.flush()?;
    Ok(())
}
