//! `quadtex diff`: RMSE and FLIP of one image against another.

use std::io::Write;
use std::path::PathBuf;

use super::Result;
use super::comparison::flip;
use super::output::Text;

/// RMSE and FLIP of one image against another.
///
/// Prints `rmse R flip F` on one line: the RMSE over linear RGB and the mean
/// FLIP (LDR, sRGB 8-bit). The images (EXR, PNG, ...) must be the same size.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// The reference image.
    #[arg(value_name = "REFERENCE")]
    reference: PathBuf,
    /// The image to measure against it.
    #[arg(value_name = "TEST")]
    test: PathBuf,
}

/// Runs `quadtex diff`.
pub fn run(args: Args) -> Result<()> {
    let Args { reference, test } = args;
    let a = quadtex_io::load_linear_image(&reference)?;
    let b = quadtex_io::load_linear_image(&test)?;
    let rmse = quadtex_eval::metrics::rmse(&a, &b).ok_or_else(|| {
        format!(
            "{} is {}x{} but {} is {}x{}",
            reference.display(),
            a.width,
            a.height,
            test.display(),
            b.width,
            b.height
        )
    })?;
    let flip = flip(&a, &b);
    let mut out = Text::stdout();
    writeln!(out, "rmse {rmse:.6} flip {flip:.6}")?;
    out.flush()?;
    Ok(())
}
