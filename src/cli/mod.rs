//! The command line: the [`Cli`] and its [`Command`]s, one module per
//! subcommand. Each module has an `Args` struct, whose doc comments are the
//! subcommand's `--help`, and a `run` that does the work.

mod bench;
mod common;
mod compare;
mod comparison;
mod diff;
mod footprints;
mod info;
mod output;
mod pack;
mod pack_tiles;
mod query;
mod rays;
mod render;
mod sample;

use clap::{CommandFactory, Parser, Subcommand};

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
    Rays(rays::Args),
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
        Some(Command::Rays(args)) => rays::run(args),
        Some(Command::Diff(args)) => diff::run(args),
        Some(Command::Bench(args)) => bench::run(args),
        Some(Command::Sample(args)) => sample::run(args),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

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
    fn memory_limit_is_on_every_texture_command() {
        for cmd in [
            "pack",
            "info",
            "query",
            "render",
            "demo",
            "compare",
            "footprints",
            "rays",
            "bench",
        ] {
            let help = parse_error(&[cmd, "--help"]).to_string();
            assert!(help.contains("--memory-limit <SIZE>"), "{cmd}: {help}");
        }
    }
}
