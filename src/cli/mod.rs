//! The command line: the [`Cli`] and its [`Command`]s, one module per
//! subcommand. Each module has an `Args` struct, whose doc comments are the
//! subcommand's `--help`, and a `run` that does the work.

mod bench;
mod compare;
mod diff;
mod footprints;
mod info;
mod output;
mod pack;
mod pack_tiles;
mod query;
mod render;
mod sample;

use std::path::Path;

use clap::{CommandFactory, Parser, Subcommand};
use quadtex_core::MAX_DEPTH;

/// What a subcommand returns; `main` prints the error after `Error: `.
pub type Result<T> = std::result::Result<T, Box<dyn std::error::Error>>;

/// Alias-free texture mapping with incomplete-quadtree textures.
///
/// Packs images and SVG art into quadtree textures (.qtx), inspects and
/// queries them, renders scenes with them and compares the result against
/// the filters users would otherwise pick. `quadtex help COMMAND` (or
/// `quadtex COMMAND --help`) describes each command.
///
/// Files named by `-o` are replaced atomically (written to a temporary file
/// next to them, then renamed); a symbolic link is followed and stays a
/// link; a device or FIFO (such as /dev/null) is written in place. `-o -`
/// writes to standard output (pack, render, demo, sample), and the summary
/// then goes to standard error.
#[derive(Debug, Parser)]
#[command(name = "quadtex", version)]
pub struct Cli {
    /// The subcommand; without one, the help is printed.
    #[command(subcommand)]
    command: Option<Command>,
}

/// The subcommands, in the order `--help` lists them; each one's help is
/// its `Args` struct's doc comment.
#[derive(Debug, Subcommand)]
enum Command {
    Pack(pack::Args),
    PackTiles(pack_tiles::Args),
    Info(info::Args),
    Query(query::Args),
    Render(render::Args),
    Demo(render::DemoArgs),
    Compare(compare::Args),
    Footprints(footprints::Args),
    Diff(diff::Args),
    Bench(bench::Args),
    Sample(sample::Args),
}

/// Runs the parsed command line; with no subcommand, prints the help.
pub fn run(cli: Cli) -> Result<()> {
    match cli.command {
        None => {
            use std::io::Write;
            let mut out = output::Text::stdout();
            write!(out, "{}", Cli::command().render_help())?;
            out.flush()?;
            Ok(())
        }
        Some(Command::Pack(args)) => pack::run(args),
        Some(Command::PackTiles(args)) => pack_tiles::run(args),
        Some(Command::Info(args)) => info::run(args),
        Some(Command::Query(args)) => query::run(args),
        Some(Command::Render(args)) => render::run(args),
        Some(Command::Demo(args)) => render::run_demo(args),
        Some(Command::Compare(args)) => compare::run(args),
        Some(Command::Footprints(args)) => footprints::run(args),
        Some(Command::Diff(args)) => diff::run(args),
        Some(Command::Bench(args)) => bench::run(args),
        Some(Command::Sample(args)) => sample::run(args),
    }
}

/// A value parser: a tree level no deeper than [`MAX_DEPTH`]; `flag` names
/// the option in the error.
fn level(
    flag: &'static str,
) -> impl Fn(&str) -> std::result::Result<u8, String> + Clone + Send + Sync + 'static {
    move |text| {
        let v = text.parse::<u32>().map_err(|e| e.to_string())?;
        if v > u32::from(MAX_DEPTH) {
            return Err(format!("{flag} {v} exceeds the maximum depth {MAX_DEPTH}"));
        }
        Ok(v as u8)
    }
}

/// A value parser: an integer in `lo..=hi`; `flag` names the option in the error.
fn in_range(
    flag: &'static str,
    lo: u32,
    hi: u32,
) -> impl Fn(&str) -> std::result::Result<u32, String> + Clone + Send + Sync + 'static {
    move |text| {
        let v = text.parse::<u32>().map_err(|e| e.to_string())?;
        if !(lo..=hi).contains(&v) {
            return Err(format!("{flag} must be in {lo}..={hi}, got {v}"));
        }
        Ok(v)
    }
}

/// The memory budget, shared (flattened) by every command that loads or
/// builds textures.
#[derive(Debug, Clone, Copy, clap::Args)]
pub struct MemoryArgs {
    /// Memory budget for reading, decoding and packing textures: a size
    /// such as 512M, 4G, 1.5GiB or plain bytes (units are binary: K = KiB =
    /// 1024 bytes). Each step estimates its peak first and stops with an
    /// error naming the estimate when it is above the budget, instead of
    /// running out of memory. Default: the smallest of the cgroup memory
    /// limit, the address space left under `ulimit -v` and 3/4 of physical
    /// memory.
    #[arg(long, value_name = "SIZE", value_parser = memory_size)]
    memory_limit: Option<u64>,
}

impl MemoryArgs {
    /// The file limits with this budget.
    fn limits(&self) -> quadtex_io::Limits {
        let mut limits = quadtex_io::Limits::default();
        if let Some(bytes) = self.memory_limit {
            limits.max_memory = bytes;
        }
        limits
    }

    /// The budget in bytes (given or detected).
    fn bytes(&self) -> u64 {
        self.limits().max_memory
    }
}

/// Gives every texture of `scene` the memory budget for its raster baselines.
fn budget_scene(scene: &mut quadtex_render::Scene, bytes: u64) {
    for s in &mut scene.surfaces {
        s.texture = s.texture.take().map(|t| t.with_memory_budget(bytes));
    }
}

/// A value parser: a size in bytes, `512M`, `4G`, `1.5GiB`, `100000` (binary
/// units; `B`, `K`/`KB`/`KiB`, `M`…, `G`…, `T`…, case-insensitive).
fn memory_size(text: &str) -> std::result::Result<u64, String> {
    let t = text.trim();
    let split = t
        .find(|c: char| !(c.is_ascii_digit() || c == '.'))
        .unwrap_or(t.len());
    let (number, unit) = t.split_at(split);
    let shift = match unit.trim().to_ascii_lowercase().as_str() {
        "" | "b" => 0,
        "k" | "kb" | "kib" => 10,
        "m" | "mb" | "mib" => 20,
        "g" | "gb" | "gib" => 30,
        "t" | "tb" | "tib" => 40,
        other => {
            return Err(format!(
                "--memory-limit: unknown unit `{other}` in `{text}` (use B, K, M, G or T)"
            ));
        }
    };
    let value: f64 = number.parse().map_err(|_| {
        format!("--memory-limit: `{text}` is not a size such as 512M, 4G or 1.5GiB")
    })?;
    let bytes = value * (1u64 << shift) as f64;
    if !(bytes >= 1.0 && bytes < 2f64.powi(63)) {
        return Err(format!(
            "--memory-limit: `{text}` must be at least one byte and below 8 EiB"
        ));
    }
    Ok(bytes.round() as u64)
}

/// Whether `path` names SVG art (by its extension).
fn is_svg(path: &Path) -> bool {
    path.extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("svg"))
}

/// Bytes of an RGBA8 raster and of the raster with its full mip pyramid.
fn raster_bytes(width: u32, height: u32) -> (u64, u64) {
    let raster = 4 * u64::from(width) * u64::from(height);
    let (mut w, mut h, mut mips) = (u64::from(width), u64::from(height), 0u64);
    loop {
        mips += 4 * w * h;
        if w == 1 && h == 1 {
            break;
        }
        w = (w / 2).max(1);
        h = (h / 2).max(1);
    }
    (raster, mips)
}

fn human_bytes(b: u64) -> String {
    match b {
        b if b >= 1 << 30 => format!("{:.2} GiB", b as f64 / f64::from(1u32 << 30)),
        b if b >= 1 << 20 => format!("{:.2} MiB", b as f64 / f64::from(1u32 << 20)),
        b if b >= 1 << 10 => format!("{:.1} KiB", b as f64 / 1024.0),
        b => format!("{b} B"),
    }
}

/// `" + N texel blocks of 4x4"` for a tree with texel blocks, else empty.
pub(crate) fn blocks_summary(tree: &quadtex_core::QuadTree) -> String {
    tree.texel_blocks().map_or_else(String::new, |b| {
        let side = 1u32 << b.log2_side();
        format!(" + {} texel blocks of {side}x{side}", b.count())
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn raster_and_mip_bytes() {
        assert_eq!(raster_bytes(4, 4), (64, 4 * (16 + 4 + 1)));
        assert_eq!(raster_bytes(4, 1), (16, 4 * (4 + 2 + 1)));
    }

    #[test]
    fn command_line_definition_is_consistent() {
        Cli::command().debug_assert();
    }

    /// The error (or help, or version) parsing `args` gives.
    fn parse_error(args: &[&str]) -> clap::Error {
        let all = std::iter::once("quadtex").chain(args.iter().copied());
        match Cli::try_parse_from(all) {
            Ok(cli) => panic!("{args:?} parsed: {cli:?}"),
            Err(e) => e,
        }
    }

    #[test]
    fn version_help_and_suggestions() {
        use clap::error::ErrorKind;
        let version = parse_error(&["--version"]);
        assert_eq!(version.kind(), ErrorKind::DisplayVersion);
        assert!(version.to_string().contains(env!("CARGO_PKG_VERSION")));
        let help = parse_error(&["pack", "--help"]).to_string();
        for needle in ["--output <OUT.qtx>", "--tolerance <T>", "--max-level <L>"] {
            assert!(help.contains(needle), "{needle} not in {help}");
        }
        let typo = parse_error(&["rendr"]);
        assert_eq!(typo.kind(), ErrorKind::InvalidSubcommand);
        assert!(typo.to_string().contains("render"), "{typo}");
        let flag = parse_error(&["render", "s.toml", "-o", "o.png", "--filtr", "ewa"]);
        assert!(flag.to_string().contains("--filter"), "{flag}");
    }

    #[test]
    fn no_subcommand_is_not_an_error() {
        assert!(Cli::try_parse_from(["quadtex"]).is_ok_and(|cli| cli.command.is_none()));
    }

    #[test]
    fn compare_options_of_demo_need_compare() {
        let e = parse_error(&["demo", "--frames", "3"]);
        assert_eq!(e.kind(), clap::error::ErrorKind::MissingRequiredArgument);
        assert!(e.to_string().contains("--compare"), "{e}");
        assert!(
            Cli::try_parse_from(["quadtex", "demo", "--compare", "--frames", "3", "-o", "d"])
                .is_ok()
        );
    }

    #[test]
    fn memory_sizes_parse() {
        assert_eq!(memory_size("512M"), Ok(512 << 20));
        assert_eq!(memory_size("4G"), Ok(4 << 30));
        assert_eq!(memory_size("4g"), Ok(4 << 30));
        assert_eq!(memory_size("1.5GiB"), Ok(3 << 29));
        assert_eq!(memory_size("2 GB"), Ok(2 << 30));
        assert_eq!(memory_size("100000"), Ok(100_000));
        assert_eq!(memory_size("64KiB"), Ok(64 << 10));
        assert_eq!(memory_size("1T"), Ok(1 << 40));
        for bad in ["", "G", "0", "0.1", "-1G", "4X", "1e3", "nanG", "1..5G"] {
            assert!(memory_size(bad).is_err(), "{bad} accepted");
        }
        assert!(memory_size("4X").is_err_and(|e| e.contains("unknown unit `x`")));
    }

    #[test]
    fn memory_limit_is_on_every_texture_command() {
        for cmd in [
            "pack",
            "info",
            "query",
            "render",
            "demo",
            "compare",
            "footprints",
            "bench",
        ] {
            let help = parse_error(&[cmd, "--help"]).to_string();
            assert!(help.contains("--memory-limit <SIZE>"), "{cmd}: {help}");
        }
    }

    #[test]
    fn level_and_range_parsers_name_the_option() {
        assert_eq!(level("--level")("30"), Ok(30));
        assert_eq!(
            level("--max-level")("99"),
            Err(format!(
                "--max-level 99 exceeds the maximum depth {MAX_DEPTH}"
            ))
        );
        assert!(level("--level")("x").is_err());
        assert_eq!(in_range("--width", 16, 3840)("16"), Ok(16));
        assert_eq!(
            in_range("--width", 16, 3840)("5"),
            Err("--width must be in 16..=3840, got 5".to_string())
        );
    }
}
