//! `quadtex sample`: built-in art as a PNG.

use std::io::Write;

use super::Result;
use super::common::in_range;
use super::output::{FormatFlag, Output};

/// Write built-in art as a PNG (or EXR).
///
/// runway: runway markings and lettering, the vector-like art of `quadtex
/// bench`; checker: an 8×8 checkerboard of two greys.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// The art to write.
    #[arg(value_enum, value_name = "ART")]
    art: Art,
    /// The image to write (.png or .exr); `-` writes it to standard output
    /// (PNG unless `--format exr`; the summary then goes to standard error).
    #[arg(short, long, value_name = "OUT.png|-")]
    output: Output,
    /// Side in pixels, in 1..=32768.
    #[arg(long, value_name = "N", default_value_t = 1024, value_parser = in_range("--size", 1, 32768))]
    size: u32,
    #[command(flatten)]
    format: FormatFlag,
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
    let Args {
        art,
        output,
        size,
        format,
    } = args;
    let format = output.image_format(format.format)?;
    let grid = match art {
        Art::Runway => quadtex_core::synth::runway_art().rasterise(size, size)?,
        Art::Checker => quadtex_core::synth::checkerboard(8, size)?,
    };
    let pixels = grid.texels().iter().map(|t| t.to_rgba()).collect();
    drop(grid);
    output.save_image(
        &quadtex_io::LinearImage {
            width: size,
            height: size,
            pixels,
        },
        format,
    )?;
    let mut text = output.text();
    writeln!(text, "wrote {output} ({size}x{size})")?;
    text.flush()?;
    Ok(())
}
