//! The memory budget (`--memory-limit`, `Limits::max_memory`): work whose
//! estimated peak is above the budget stops up front with an error naming
//! the estimate, the budget and the knobs, exit status 1 and no output.
#![allow(clippy::unwrap_used, clippy::expect_used)]

mod common;

use std::path::Path;
use std::time::{Duration, Instant};

use common::{run, temp_dir};
use quadtex_core::Rgba;
use quadtex_io::{LinearImage, save_image};

fn star() -> String {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("samples/star.svg")
        .to_string_lossy()
        .into_owned()
}

/// Runs `args`, expects exit status 1 with the budget error and returns stderr.
fn refused(args: &[&str]) -> String {
    let start = Instant::now();
    let out = run(args, "");
    let elapsed = start.elapsed();
    let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
    assert_eq!(out.status.code(), Some(1), "{args:?}: {stderr}");
    assert!(
        stderr.contains("needs an estimated") && stderr.contains("above the memory budget of"),
        "{stderr}"
    );
    assert!(
        !stderr.contains("panicked") && !stderr.contains("backtrace"),
        "{stderr}"
    );
    // Refused before any large allocation: well within a generous bound even in debug builds.
    assert!(
        elapsed < Duration::from_secs(30),
        "{args:?} took {elapsed:?}"
    );
    stderr
}

#[test]
fn deep_svg_pack_is_refused_up_front() {
    let dir = temp_dir("mem-star");
    let out = dir.join("x.qtx");
    let stderr = refused(&[
        "pack",
        &star(),
        "--max-level",
        "20",
        "--memory-limit",
        "1G",
        "-o",
        out.to_str().unwrap(),
    ]);
    assert!(stderr.contains("star.svg: packing at level 20"), "{stderr}");
    assert!(
        stderr.contains("above the memory budget of 1.0 GiB"),
        "{stderr}"
    );
    assert!(
        stderr.contains("--max-level") && stderr.contains("--memory-limit"),
        "{stderr}"
    );
    assert!(!out.exists());
    assert_eq!(
        std::fs::read_dir(&dir).unwrap().count(),
        0,
        "no temporary files left"
    );
}

/// Without `--max-level`, SVG art whose default level does not fit the
/// budget packs at the deepest level that does, and the summary says which
/// and why; `--max-level 12` under the same budget is refused. With
/// `--contour-leaves` the summary states the default level and the
/// estimate within the budget.
#[test]
fn default_svg_level_is_lowered_to_fit_and_said() {
    let dir = temp_dir("mem-fit");
    let out = dir.join("star.qtx");
    let packed = run(
        &[
            "pack",
            &star(),
            "--memory-limit",
            "20M",
            "-o",
            out.to_str().unwrap(),
        ],
        "",
    );
    let stdout = String::from_utf8_lossy(&packed.stdout);
    assert!(
        packed.status.success(),
        "{}",
        String::from_utf8_lossy(&packed.stderr)
    );
    assert!(
        stdout.contains("depth 10")
            && stdout.contains("level 10 chosen to fit the memory budget of 20.0 MiB")
            && stdout.contains("the default, level 12, needs an estimated 57.1 MiB"),
        "{stdout}"
    );
    std::fs::remove_file(&out).unwrap();
    let stderr = refused(&[
        "pack",
        &star(),
        "--max-level",
        "12",
        "--memory-limit",
        "20M",
        "-o",
        out.to_str().unwrap(),
    ]);
    assert!(
        stderr.contains("star.svg: packing at level 12 needs an estimated 57.1 MiB"),
        "{stderr}"
    );
    assert!(!out.exists());
    let contour = run(
        &[
            "pack",
            &star(),
            "--contour-leaves",
            "-o",
            out.to_str().unwrap(),
        ],
        "",
    );
    let stdout = String::from_utf8_lossy(&contour.stdout);
    assert!(
        contour.status.success()
            && stdout.contains(
                "level 20 (default) with contour leaves of up to 16 edges, estimated peak"
            )
            && stdout.contains("within the memory budget of"),
        "{stdout}"
    );
}

/// A 1×20000 column packs on its own 1×20000 texels (no square around it,
/// no resampling): within a 50 MB budget; a budget that holds the texels
/// but not the tree refuses while building, and one below the decoded
/// image refuses before decoding.
#[test]
fn tall_png_packs_in_its_own_cells() {
    let dir = temp_dir("mem-tall");
    let png = dir.join("tall.png");
    let image = LinearImage {
        width: 1,
        height: 20000,
        pixels: (0..20000)
            .map(|i| Rgba::opaque((i % 256) as f32 / 255.0, 0.5, 0.25))
            .collect(),
    };
    save_image(&png, &image).unwrap();
    let out = dir.join("tall.qtx");
    let packed = run(
        &[
            "pack",
            png.to_str().unwrap(),
            "--memory-limit",
            "50M",
            "-o",
            out.to_str().unwrap(),
        ],
        "",
    );
    assert!(
        packed.status.success(),
        "{}",
        String::from_utf8_lossy(&packed.stderr)
    );
    std::fs::remove_file(&out).unwrap();
    // The texels (160 000 B) are the cells: nothing else up front, so a
    // budget that holds the decoded image refuses only as the tree grows.
    let stderr = refused(&[
        "pack",
        png.to_str().unwrap(),
        "--memory-limit",
        "256K",
        "-o",
        out.to_str().unwrap(),
    ]);
    assert!(
        stderr.contains("packing at level 15 (stopped after"),
        "{stderr}"
    );
    let stderr = refused(&[
        "pack",
        png.to_str().unwrap(),
        "--memory-limit",
        "128K",
        "-o",
        out.to_str().unwrap(),
    ]);
    assert!(
        stderr.contains("decoding 1x20000 texels needs an estimated 234.4 KiB"),
        "{stderr}"
    );
    assert!(!out.exists());
}

#[test]
fn small_work_fits_a_small_budget_and_tiny_budgets_refuse_reading() {
    let dir = temp_dir("mem-small");
    let qtx = dir.join("star.qtx");
    let out = run(
        &[
            "pack",
            &star(),
            "--max-level",
            "8",
            "--memory-limit",
            "64M",
            "-o",
            qtx.to_str().unwrap(),
        ],
        "",
    );
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let info = run(
        &["info", qtx.to_str().unwrap(), "--memory-limit", "64M"],
        "",
    );
    assert!(
        info.status.success(),
        "{}",
        String::from_utf8_lossy(&info.stderr)
    );
    // Read whole (9 bytes a node) it needs more than 64 KiB; mapped, only
    // the inner flags' rank counters (a quarter byte a node), so it opens
    // under 64 KiB and is refused under 1 KiB.
    let stderr = refused(&[
        "info",
        qtx.to_str().unwrap(),
        "--verify",
        "--memory-limit",
        "64K",
    ]);
    assert!(stderr.contains("reading a tree of"), "{stderr}");
    let stderr = refused(&[
        "query",
        qtx.to_str().unwrap(),
        "--verify",
        "--memory-limit",
        "64K",
    ]);
    assert!(stderr.contains("raise --memory-limit"), "{stderr}");
    let mapped = run(
        &["info", qtx.to_str().unwrap(), "--memory-limit", "64K"],
        "",
    );
    assert!(
        mapped.status.success(),
        "{}",
        String::from_utf8_lossy(&mapped.stderr)
    );
    let stderr = refused(&["query", qtx.to_str().unwrap(), "--memory-limit", "1K"]);
    assert!(stderr.contains("mapping a tree of"), "{stderr}");
}

#[test]
fn bad_sizes_are_usage_errors() {
    let out = run(
        &["pack", &star(), "-o", "x.qtx", "--memory-limit", "4X"],
        "",
    );
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("unknown unit"));
}
