//! The Rust side of `bench/python/filter_bench.py`: times
//! [`Texture::filter_batch`] alone over footprints read from a file, so the
//! Python bindings can be compared with the same calls made from Rust.
//!
//! ```text
//! cargo run --release -p quadtex-eval --example filter_batch -- TEXTURE.qtx QUADS.bin [--repeat N] [--out COLOURS.bin] [--budget N] [--weighting texture]
//! ```
//!
//! `QUADS.bin` holds `N×4×2` little-endian `f64`: each footprint's corners
//! (the texture-space images of pixel corners (0,0), (1,0), (1,1), (0,1)).
//! Options are the defaults of both APIs: repeat wrap, screen weighting,
//! error bound 1/512, no square budget; `--budget N` sets one (64 is what
//! the renderer and, before issue 62, the library used) and `--weighting
//! texture` weights by texture area. Reading, parsing and building the
//! `Vec<Footprint>` happen before the clock starts; one untimed warm-up call
//! precedes `--repeat` timed calls (default 1), each printed as
//! `seconds=…`. `--out` writes the colours (`N×4` little-endian `f32`) after
//! timing, for checking against the Python result.

use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Instant;

use quadtex_core::{FilterOptions, Footprint, Texture, Weighting, Wrap};

fn main() -> ExitCode {
    match run() {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("filter_batch: {e}");
            ExitCode::FAILURE
        }
    }
}

fn run() -> Result<(), String> {
    let mut args = std::env::args().skip(1);
    let (mut positional, mut repeat, mut out) = (Vec::new(), 1usize, None::<PathBuf>);
    let mut options = FilterOptions::default();
    while let Some(arg) = args.next() {
        match arg.as_str() {
            "--repeat" => {
                let v = args.next().ok_or("--repeat needs a value")?;
                repeat = v.parse().map_err(|e| format!("--repeat {v}: {e}"))?;
            }
            "--out" => out = Some(args.next().ok_or("--out needs a path")?.into()),
            "--budget" => {
                let v = args.next().ok_or("--budget needs a value")?;
                let n = v.parse().map_err(|e| format!("--budget {v}: {e}"))?;
                options = options.with_budget(n).map_err(|e| e.to_string())?;
            }
            "--weighting" => match args.next().as_deref() {
                Some("texture") => options = options.with_weighting(Weighting::Texture),
                Some("screen") => options = options.with_weighting(Weighting::Screen),
                other => return Err(format!("--weighting {other:?}: expected screen or texture")),
            },
            "-h" | "--help" => {
                println!(
                    "usage: filter_batch TEXTURE.qtx QUADS.bin [--repeat N] [--out COLOURS.bin] [--budget N] [--weighting screen|texture]"
                );
                return Ok(());
            }
            _ => positional.push(PathBuf::from(arg)),
        }
    }
    let [texture_path, quads_path] = <[PathBuf; 2]>::try_from(positional)
        .map_err(|_| "expected TEXTURE.qtx QUADS.bin (see --help)")?;

    let tree = quadtex_io::read_qtx(&texture_path, &quadtex_io::Limits::default())
        .map_err(|e| e.to_string())?
        .0;
    let texture = Texture::new(tree, Wrap::REPEAT);
    let bytes = std::fs::read(&quads_path).map_err(|e| format!("{}: {e}", quads_path.display()))?;
    if bytes.len() % 64 != 0 {
        return Err(format!(
            "{}: {} bytes is not a whole number of footprints (64 bytes each)",
            quads_path.display(),
            bytes.len()
        ));
    }
    let footprints = bytes
        .chunks_exact(64)
        .enumerate()
        .map(|(i, q)| {
            let v = |k: usize| {
                let mut b = [0u8; 8];
                b.copy_from_slice(&q[8 * k..8 * k + 8]);
                f64::from_le_bytes(b)
            };
            let corners = [0, 1, 2, 3].map(|c| [v(2 * c), v(2 * c + 1)]);
            Footprint::from_corners(corners).map_err(|e| format!("footprint {i}: {e}"))
        })
        .collect::<Result<Vec<_>, _>>()?;
    let mut colours = texture.filter_batch(&footprints, &options);
    for _ in 0..repeat {
        let start = Instant::now();
        colours = texture.filter_batch(&footprints, &options);
        let seconds = start.elapsed().as_secs_f64();
        println!("seconds={seconds:.6} footprints={}", footprints.len());
    }
    if let Some(out) = out {
        let raw: Vec<u8> = colours
            .iter()
            .flat_map(|c| c.to_array())
            .flat_map(f32::to_le_bytes)
            .collect();
        std::fs::write(&out, raw).map_err(|e| format!("{}: {e}", out.display()))?;
    }
    Ok(())
}
