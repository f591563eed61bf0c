//! `quadtex sample`: built-in art as a PNG.

use std::path::PathBuf;

use super::{Result, in_range};

/// Write built-in art as a PNG (or EXR).
///
/// runway: runway markings and lettering, the vector-like art of `quadtex
/// bench`; checker: an 8×8 checkerboard of two greys.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// The art to write.
    #[arg(value_enum, value_name = "ART")]
    art: Art,
    /// The image to write.
    #[arg(short, long, value_name = "OUT.png")]
    output: PathBuf,
    /// Side in pixels, in 1..=32768.
    #[arg(long, value_name = "N", default_value_t = 1024, value_parser = in_range("--size", 1, 32768))]
    size: u32,
}

/// The built-in art.
#[derive(Debug, Clone, Copy, clap::ValueEnum)]
enum Art {
    /// Runway markings and lettering.
    Runway,
    /// An 8×8 checkerboard of two greys.
    Checker,
}

/// Runs `quadtex sample`.
pub fn run(args: Args) -> Result<()> {
    let Args { art, output, size } = args;
    let grid = match art {
        Art::Runway => quadtex_core::synth::runway_art().rasterise(size, size)?,
        Art::Checker => quadtex_core::synth::checkerboard(8, size)?,
    };
    let pixels = grid.texels().iter().map(|t| t.to_rgba()).collect();
    drop(grid);
    quadtex_io::save_image(
        &output,
        &quadtex_io::LinearImage {
            width: size,
            height: size,
            pixels,
        },
    )?;
    println!("wrote {} ({size}x{size})", output.display());
    Ok(())
}
