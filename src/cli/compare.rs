//! `quadtex compare SCENE.toml -o DIR`: the comparison
//! ([`super::comparison`]) on a scene file.

use std::path::PathBuf;

use super::Result;
use super::common::{MemoryArgs, ResourcesArgs, in_range};
use super::comparison::{CompareArgs, Settings, compare_scene};

/// Compare every filter against a converged reference on a scene (report.html).
///
/// Renders the scene with every contender filter and with a converged
/// supersampled reference, in the same process, and writes into DIR:
/// report.html, grid.png, plot.svg, results.csv, results.md and frames/
/// (see docs/compare.md).
#[derive(Debug, clap::Args)]
pub struct Args {
    /// The scene to compare the filters on.
    #[arg(value_name = "SCENE.toml")]
    scene: PathBuf,
    /// The directory to write the report into (created if missing).
    #[arg(short, long, value_name = "DIR")]
    output: PathBuf,
    /// Frame width in pixels, in 16..=3840 (the height keeps the camera's aspect).
    #[arg(
        long,
        value_name = "W",
        default_value_t = Settings::default().width,
        value_parser = in_range("--width", 16, 3840)
    )]
    width: u32,
    #[command(flatten)]
    options: CompareArgs,
    #[command(flatten)]
    memory: MemoryArgs,
    #[command(flatten)]
    resources: ResourcesArgs,
}

/// Runs `quadtex compare`.
pub fn run(args: Args) -> Result<()> {
    let settings = args.options.settings(args.width, &args.memory.limits())?;
    let scene =
        quadtex_render::load_scene(&args.scene, &args.resources.apply(args.memory.limits()))?;
    let name = args
        .scene
        .file_stem()
        .map_or_else(|| "scene".into(), |s| s.to_string_lossy().into_owned());
    compare_scene(&scene, &name, &args.output, &settings)
}
