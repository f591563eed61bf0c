//! `quadtex`: pack textures into incomplete quadtrees, inspect and query them,
//! benchmark the fragment integral, and render scenes.
//!
//! The command line is in [`cli`], one module per subcommand.

mod cli;

use std::io::Write;
use std::process::ExitCode;

use clap::Parser;

fn main() -> ExitCode {
    // Usage errors, `--help` and `--version` end here, as clap formats them.
    let args = cli::Cli::parse();
    match cli::run(args) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            // Not `eprintln!`, which panics when standard error is closed.
            let _ = writeln!(std::io::stderr(), "Error: {e}");
            ExitCode::FAILURE
        }
    }
}
