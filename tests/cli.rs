//! End-to-end tests of the `quadtex` binary: pack → query against a
//! brute-force sum over texels, and hostile `.qtx` files.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};

use quadtex_core::reference::texel_sum;
use quadtex_core::synth::{Art, Shape};
use quadtex_core::{Fragment, Rgba};
use quadtex_io::{LinearImage, load_texels, save_image};

fn bin() -> Command {
    Command::new(env!("CARGO_BIN_EXE_quadtex"))
}

fn temp_dir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("quadtex-cli-{}-{name}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn run_with_stdin(args: &[&str], stdin: &str) -> Output {
    let mut child = bin()
        .args(args)
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    // Feed stdin from a thread: the child's output would fill its pipe otherwise.
    let mut pipe = child.stdin.take().unwrap();
    let input = stdin.to_owned();
    let feeder = std::thread::spawn(move || {
        // The child may exit early on a bad line; a broken pipe is expected then.
        let _ = pipe.write_all(input.as_bytes());
    });
    let out = child.wait_with_output().unwrap();
    feeder.join().unwrap();
    out
}

/// A 256×256 PNG of flat-coloured shapes (with antialiased disc edges).
fn shapes_png(path: &Path) {
    let mut art = Art::new(Rgba::opaque(0.1, 0.3, 0.05));
    art.rect(0.1, 0.1, 0.6, 0.4, Rgba::opaque(0.9, 0.9, 0.9));
    art.rect(0.3, 0.5, 0.95, 0.9, Rgba::opaque(0.8, 0.1, 0.1));
    art.push(
        Shape::Disc {
            cx: 0.7,
            cz: 0.3,
            r: 0.15,
        },
        Rgba::opaque(0.1, 0.2, 0.9),
    );
    art.text("QTX 27", 0.05, 0.75, 0.02, Rgba::opaque(0.95, 0.8, 0.1));
    let grid = art.rasterise(256, 256).unwrap();
    let pixels = grid.texels().iter().map(|t| t.to_rgba()).collect();
    save_image(
        path,
        &LinearImage {
            width: 256,
            height: 256,
            pixels,
        },
    )
    .unwrap();
}

#[test]
fn packed_png_queries_match_the_brute_force_box_integral() {
    let dir = temp_dir("pack");
    let png = dir.join("shapes.png");
    let qtx = dir.join("shapes.qtx");
    shapes_png(&png);
    let out = bin()
        .args(["pack", png.to_str().unwrap(), "-o", qtx.to_str().unwrap()])
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let summary = String::from_utf8_lossy(&out.stdout);
    assert!(
        summary.contains("nodes") && summary.contains("lossless"),
        "{summary}"
    );

    // Reference: the same PNG decoded to linear texels, summed texel by texel.
    let grid = load_texels(&png).unwrap();
    let mut state = 12345u64;
    let mut rand = move |lo: f64, hi: f64| {
        state = state
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        lo + (hi - lo) * ((state >> 11) as f64 / (1u64 << 53) as f64)
    };
    let mut fragments = Vec::new();
    for i in 0..3000 {
        // Inside, across the border, and wholly outside the unit square.
        let (lo, hi) = match i % 3 {
            0 => (0.0, 1.0),
            1 => (-0.5, 1.5),
            _ => (1.0, 3.0),
        };
        let (x, z) = (rand(lo, hi), rand(lo, hi));
        let (w, h) = (rand(0.0, 0.3), rand(0.0, 0.3));
        fragments.push(Fragment::new(x, z, x + w, z + h).unwrap());
    }
    let input: String = fragments
        .iter()
        .map(|f| format!("{} {} {} {}\n", f.x0(), f.z0(), f.x1(), f.z1()))
        .collect();
    let out = run_with_stdin(&["query", qtx.to_str().unwrap(), "--level", "8"], &input);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = String::from_utf8(out.stdout).unwrap();
    let lines: Vec<&str> = text.lines().collect();
    assert_eq!(lines.len(), fragments.len());
    let (mut outside, mut worst) = (0, 0f64);
    for (f, line) in fragments.iter().zip(lines) {
        let got: Vec<f64> = line.split(' ').map(|v| v.parse().unwrap()).collect();
        let want = texel_sum(&grid, f);
        let area = f.clip_to_unit().map_or(0.0, |c| c.area());
        if area == 0.0 {
            outside += 1;
            assert!(got.iter().all(|&v| v == 0.0), "{f:?}: {line}");
            continue;
        }
        for (g, w) in got.iter().zip(&want.0) {
            worst = worst.max((g - w).abs() / area);
        }
    }
    assert!(
        outside > 900,
        "the test must cover fragments outside the unit square"
    );
    assert!(worst < 1e-3, "mean colour off by {worst}");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn bad_query_lines_name_the_line_and_fail() {
    let dir = temp_dir("query");
    let png = dir.join("s.png");
    let qtx = dir.join("s.qtx");
    shapes_png(&png);
    assert!(
        bin()
            .args(["pack", png.to_str().unwrap(), "-o", qtx.to_str().unwrap()])
            .output()
            .unwrap()
            .status
            .success()
    );
    for (input, needle) in [
        (
            "0 0 1 1\n0 0 1\n",
            "line 2: expected 4 numbers `x0 z0 x1 z1`, missing z1",
        ),
        ("0 0 1 NaN\n", "line 1: coordinate z1 is not finite"),
        ("0.5 0 0.25 1\n", "line 1: reversed bounds on x"),
        (
            "# c\n0 0 1 1\nzero 0 1 1\n",
            "line 3: x0: `zero` is not a number",
        ),
    ] {
        let out = run_with_stdin(&["query", qtx.to_str().unwrap()], input);
        assert!(!out.status.success());
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(
            err.starts_with("Error: ") && err.contains(needle),
            "{input:?}: {err}"
        );
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn corrupt_qtx_files_fail_cleanly() {
    let dir = temp_dir("corrupt");
    let png = dir.join("s.png");
    let qtx = dir.join("s.qtx");
    shapes_png(&png);
    assert!(
        bin()
            .args(["pack", png.to_str().unwrap(), "-o", qtx.to_str().unwrap()])
            .output()
            .unwrap()
            .status
            .success()
    );
    let good = std::fs::read(&qtx).unwrap();
    let bad = dir.join("bad.qtx");
    let mut huge = good.clone();
    huge[32..40].copy_from_slice(&u64::MAX.to_le_bytes());
    let mut cases: Vec<(&str, Vec<u8>, &str)> = vec![
        ("truncated", good[..good.len() - 9].to_vec(), "length"),
        ("empty", Vec::new(), "header"),
        (
            "wrong magic",
            [b"PNG".as_slice(), &good[3..]].concat(),
            "magic",
        ),
        ("absurd size", huge, "header_crc"),
    ];
    let mut flipped = good.clone();
    flipped[good.len() / 2] ^= 0xFF;
    cases.push(("flipped byte", flipped, "payload_crc"));
    let mut future = good.clone();
    future[8] = 9;
    cases.push(("future version", future, "version"));
    for (what, bytes, field) in cases {
        std::fs::write(&bad, bytes).unwrap();
        let out = bin()
            .args(["info", bad.to_str().unwrap()])
            .output()
            .unwrap();
        assert!(!out.status.success(), "{what}");
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(
            err.contains("bad.qtx") && err.contains(field) && !err.contains("panicked"),
            "{what}: {err}"
        );
    }
    let out = bin()
        .args([
            "pack",
            dir.join("missing.png").to_str().unwrap(),
            "-o",
            dir.join("x.qtx").to_str().unwrap(),
        ])
        .output()
        .unwrap();
    assert!(!out.status.success() && !dir.join("x.qtx").exists());
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn info_reports_levels_and_ratios() {
    let dir = temp_dir("info");
    let png = dir.join("s.png");
    let qtx = dir.join("s.qtx");
    shapes_png(&png);
    assert!(
        bin()
            .args([
                "pack",
                png.to_str().unwrap(),
                "-o",
                qtx.to_str().unwrap(),
                "--tolerance",
                "0.01"
            ])
            .output()
            .unwrap()
            .status
            .success()
    );
    let out = bin()
        .args(["info", qtx.to_str().unwrap()])
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success());
    assert!(
        text.contains("depth:       8")
            && text.contains("bytes/node")
            && text.contains("raster+mips"),
        "{text}"
    );
    std::fs::remove_dir_all(&dir).unwrap();
}
