//! End-to-end tests of the `quadtex` binary: pack → query against a
//! brute-force sum over texels, query errors, info. Hostile inputs are in
//! `bad_inputs.rs`.
#![allow(clippy::unwrap_used, clippy::expect_used)]

mod common;

use std::path::{Path, PathBuf};

use common::{run, temp_dir};

use quadtex_core::reference::texel_sum;
use quadtex_core::synth::{Art, Shape};
use quadtex_core::{Fragment, Rgba};
use quadtex_io::{Limits, LinearImage, load_texels, save_image};

/// A packed sample in a fresh directory: `(dir, png, qtx)`.
fn packed_shapes(case: &str, extra: &[&str]) -> (common::TempDir, PathBuf, PathBuf) {
    let dir = temp_dir(case);
    let png = dir.join("shapes.png");
    let qtx = dir.join("shapes.qtx");
    shapes_png(&png);
    let mut args = vec!["pack", png.to_str().unwrap(), "-o", qtx.to_str().unwrap()];
    args.extend(extra);
    let out = run(&args, "");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    (dir, png, qtx)
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
    let out = run(
        &["pack", png.to_str().unwrap(), "-o", qtx.to_str().unwrap()],
        "",
    );
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
    let grid = load_texels(&png, &Limits::default()).unwrap();
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
    let out = run(&["query", qtx.to_str().unwrap(), "--level", "8"], &input);
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

/// The committed photographs (`samples/photos`), and crops of one to sizes
/// that are not powers of two, pack losslessly on their own texels into
/// less than an RGBA8 raster and its mips, their bottoms in 8-bit texel
/// blocks, and answer queries exactly: against the sum over the PNG's texels.
#[test]
fn photographs_pack_below_a_mip_pyramid_and_stay_exact() {
    let dir = temp_dir("photos");
    let samples = Path::new(env!("CARGO_MANIFEST_DIR")).join("samples/photos");
    let astronaut = load_texels(&samples.join("astronaut.png"), &Limits::default()).unwrap();
    for (w, h) in [(500u32, 333u32), (300, 77)] {
        let pixels = (0..h)
            .flat_map(|r| (0..w).map(move |c| (c, r)))
            .map(|(c, r)| astronaut.texel(c + 7, r + 11).to_rgba())
            .collect();
        let image = LinearImage {
            width: w,
            height: h,
            pixels,
        };
        save_image(&dir.join(format!("crop{w}x{h}.png")), &image).unwrap();
    }
    for (name, blocks) in [
        ("astronaut", "8-bit sRGB RGB"),
        ("brick", "8-bit sRGB grey"),
        ("grass", "8-bit sRGB grey"),
        ("crop500x333", "8-bit sRGB RGB"),
        ("crop300x77", "8-bit sRGB RGB"),
    ] {
        let png = if name.starts_with("crop") {
            dir.join(format!("{name}.png"))
        } else {
            samples.join(format!("{name}.png"))
        };
        let qtx = dir.join(format!("{name}.qtx"));
        let out = run(
            &["pack", png.to_str().unwrap(), "-o", qtx.to_str().unwrap()],
            "",
        );
        let summary = String::from_utf8_lossy(&out.stdout).into_owned();
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        let ratio: f64 = summary
            .split("raster+mips / tree = ")
            .nth(1)
            .and_then(|r| r.split(';').next())
            .and_then(|r| r.parse().ok())
            .unwrap_or_else(|| panic!("{summary}"));
        assert!(
            ratio >= 1.0 && summary.contains("lossless") && !summary.contains("resampled"),
            "{summary}"
        );
        let info = run(&["info", qtx.to_str().unwrap()], "");
        let info = String::from_utf8_lossy(&info.stdout).into_owned();
        assert!(info.contains(&format!("stored as {blocks}")), "{info}");

        let grid = load_texels(&png, &Limits::default()).unwrap();
        let fragments: Vec<Fragment> = (0..2000u32)
            .map(|i| {
                let h = |k: u32| {
                    f64::from(i.wrapping_mul(2_654_435_761).rotate_left(k) % 10_000) / 10_000.0
                };
                let (x, z, w) = (h(0), h(7), h(13) * 0.05);
                Fragment::new(x, z, x + w, z + w * h(21)).unwrap()
            })
            .collect();
        let input: String = fragments
            .iter()
            .map(|f| format!("{} {} {} {}\n", f.x0(), f.z0(), f.x1(), f.z1()))
            .collect();
        let out = run(&["query", qtx.to_str().unwrap()], &input);
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        let text = String::from_utf8(out.stdout).unwrap();
        let mut worst = 0f64;
        for (f, line) in fragments.iter().zip(text.lines()) {
            let got: Vec<f64> = line.split(' ').map(|v| v.parse().unwrap()).collect();
            let want = texel_sum(&grid, f);
            let area = f.clip_to_unit().map_or(0.0, |c| c.area());
            if area > 0.0 {
                for (g, w) in got.iter().zip(&want.0) {
                    worst = worst.max((g - w).abs() / area);
                }
            }
        }
        // Exact but for inner means rounded once to 16 bits.
        assert!(worst < 2e-5, "{name}: mean colour off by {worst}");
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

/// An EXR with values up to 1000 and below 0 round-trips through `pack` →
/// `query` within half-float precision; `info` names the storage; an EXR
/// with a NaN texel is refused, naming the file and the texel, and nothing
/// is written.
#[test]
fn hdr_exr_round_trips_to_half_precision() {
    let dir = temp_dir("hdr");
    let (w, h) = (16u32, 8u32);
    let value = |c: u32, r: u32| {
        let k = (c * 7 + r * 13) % 16;
        let v = match k % 3 {
            0 => 1000.0 - k as f32,
            1 => -(k as f32) / 4.0,
            _ => k as f32 / 100.0,
        };
        Rgba::new(v, v * 0.5, 2.0, if k == 5 { 0.5 } else { 1.0 })
    };
    let image = LinearImage::from_fn(w, h, value);
    let exr = dir.join("hdr.exr");
    save_image(&exr, &image).unwrap();
    let qtx = dir.join("hdr.qtx");
    let out = run(
        &["pack", exr.to_str().unwrap(), "-o", qtx.to_str().unwrap()],
        "",
    );
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let info = run(&["info", qtx.to_str().unwrap()], "");
    let info = String::from_utf8_lossy(&info.stdout).into_owned();
    assert!(info.contains("half-float"), "{info}");
    let input: String = (0..h)
        .flat_map(|r| (0..w).map(move |c| (c, r)))
        .map(|(c, r)| {
            let (x0, z1) = (
                f64::from(c) / f64::from(w),
                1.0 - f64::from(r) / f64::from(h),
            );
            format!(
                "{x0} {} {} {z1}\n",
                z1 - 1.0 / f64::from(h),
                x0 + 1.0 / f64::from(w)
            )
        })
        .collect();
    let out = run(&["query", qtx.to_str().unwrap()], &input);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let area = 1.0 / f64::from(w * h);
    for (i, line) in String::from_utf8(out.stdout).unwrap().lines().enumerate() {
        let (c, r) = (i as u32 % w, i as u32 / w);
        let want = value(c, r).to_array();
        for (got, want) in line
            .split(' ')
            .map(|v| v.parse::<f64>().unwrap() / area)
            .zip(want)
        {
            // Half floats: 11 significant bits.
            let tol = f64::from(want).abs() / 1024.0 + 1e-6;
            assert!(
                (got - f64::from(want)).abs() <= tol,
                "texel ({c}, {r}): {line} vs {want:?}"
            );
        }
    }
    let mut bad = image.clone();
    bad.pixels[3 * w as usize + 2].g = f32::NAN;
    let nan = dir.join("nan.exr");
    save_image(&nan, &bad).unwrap();
    let none = dir.join("nan.qtx");
    let out = run(
        &["pack", nan.to_str().unwrap(), "-o", none.to_str().unwrap()],
        "",
    );
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    assert!(
        stderr.contains("nan.exr") && stderr.contains("texel (2, 3) has g = NaN"),
        "{stderr}"
    );
    assert!(!none.exists());
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn bad_query_lines_name_the_line_and_fail() {
    let (dir, _, qtx) = packed_shapes("query", &[]);
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
        let out = run(&["query", qtx.to_str().unwrap()], input);
        assert!(!out.status.success());
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(
            err.starts_with("Error: ") && err.contains(needle),
            "{input:?}: {err}"
        );
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

/// `pack --tolerance` on SVG art bounds how far a gradient square's colour
/// is from the art; a coarser tolerance gives fewer nodes.
#[test]
fn svg_gradients_pack_to_the_tolerance() {
    let dir = common::temp_dir("svg-gradient");
    let svg = dir.join("ramp.svg");
    std::fs::write(
        &svg,
        r#"<svg xmlns="http://www.w3.org/2000/svg" viewBox="0 0 10 10">
        <linearGradient id="g"><stop offset="0" stop-color="navy"/><stop offset="1" stop-color="gold"/></linearGradient>
        <rect width="10" height="10" fill="url(#g)"/></svg>"#,
    )
    .unwrap();
    let mut nodes = Vec::new();
    for tolerance in ["0.001", "0.01"] {
        let qtx = dir.join(format!("ramp-{tolerance}.qtx"));
        let out = common::run(
            &[
                "pack",
                svg.to_str().unwrap(),
                "-o",
                qtx.to_str().unwrap(),
                "--tolerance",
                tolerance,
                "--no-gradient-leaves",
            ],
            "",
        );
        let text = String::from_utf8_lossy(&out.stdout).to_string();
        assert!(
            out.status.success(),
            "{text}{}",
            String::from_utf8_lossy(&out.stderr)
        );
        let deviation: f64 = text
            .split("every point within ")
            .nth(1)
            .and_then(|r| r.split(' ').next())
            .and_then(|v| v.parse().ok())
            .unwrap_or_else(|| panic!("no deviation in {text}"));
        assert!(deviation <= tolerance.parse::<f64>().unwrap(), "{text}");
        assert!(
            text.contains("means within 0.00e0"),
            "linear means are exact: {text}"
        );
        let n: u64 = text
            .split(": ")
            .nth(1)
            .unwrap()
            .split(' ')
            .next()
            .unwrap()
            .parse()
            .unwrap();
        nodes.push(n);
    }
    assert!(
        nodes[1] * 10 < nodes[0],
        "ten times the tolerance: {nodes:?}"
    );
    // With gradient leaves (the default) the whole ramp is one leaf, in a
    // version-3 file that reads back to the same answers.
    let qtx = dir.join("ramp-leaf.qtx");
    let out = common::run(
        &["pack", svg.to_str().unwrap(), "-o", qtx.to_str().unwrap()],
        "",
    );
    let text = String::from_utf8_lossy(&out.stdout).to_string();
    assert!(
        out.status.success() && text.contains(": 1 nodes") && text.contains("1 gradient leaves"),
        "{text}"
    );
    let bytes = std::fs::read(&qtx).unwrap();
    assert_eq!(bytes[8], 3);
    let out = common::run(&["info", "--verify", qtx.to_str().unwrap()], "");
    let text = String::from_utf8_lossy(&out.stdout).to_string();
    assert!(
        out.status.success() && text.contains("gradient:    1 leaves"),
        "{text}"
    );
}

#[test]
fn info_reports_levels_and_ratios() {
    let (dir, _, qtx) = packed_shapes("info", &["--tolerance", "0.01"]);
    let out = run(&["info", qtx.to_str().unwrap()], "");
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

#[test]
fn compare_writes_report_grid_plot_and_tables() {
    let dir = temp_dir("compare");
    let scene = concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/checker.toml");
    let out = run(
        &[
            "compare",
            scene,
            "-o",
            dir.to_str().unwrap(),
            "--width",
            "64",
            "--reference-spp",
            "64",
            "--frames",
            "3",
        ],
        "",
    );
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    for f in [
        "report.html",
        "grid.png",
        "plot.svg",
        "results.csv",
        "results.md",
        "frames/reference.png",
        "frames/quadtree.png",
        "frames/ewa-aniso-8.png",
    ] {
        assert!(dir.join(f).is_file(), "{f} missing");
    }
    let csv = std::fs::read_to_string(dir.join("results.csv")).unwrap();
    let rows: Vec<Vec<&str>> = csv
        .lines()
        .skip(1)
        .map(|l| l.split(',').collect())
        .collect();
    let rmse = |label: &str| -> f64 {
        rows.iter().find(|r| r[0] == label).unwrap()[1]
            .parse()
            .unwrap()
    };
    // The headline holds even at this tiny size.
    assert!(
        rmse("quadtree") < rmse("trilinear") && rmse("quadtree") < rmse("EWA aniso 8"),
        "{csv}"
    );
    for r in &rows {
        // FLIP and shimmer were measured for every contender, and the
        // closed form (a single unlit plane) for every box-filtered one.
        assert!(!r[4].is_empty() && !r[5].is_empty(), "{r:?}");
        assert_eq!(r[3].is_empty(), r[0].contains("tent"), "{r:?}");
    }
    // Every row carries its provenance: threads, profile, commit, date.
    let header: Vec<&str> = csv.lines().next().unwrap().split(',').collect();
    assert_eq!(
        header[header.len() - 4..],
        ["threads", "profile", "commit", "date"]
    );
    // The binary under test is built with the tests' own profile.
    let profile = if cfg!(debug_assertions) {
        "debug"
    } else {
        "release"
    };
    for line in csv.lines().skip(1) {
        let f: Vec<&str> = line.rsplitn(5, ',').collect();
        assert!(f[0].len() == 10 && f[0].starts_with("20"), "date in {line}");
        assert!(
            !f[1].is_empty() && f[2] == profile && f[3].parse::<usize>().is_ok(),
            "{line}"
        );
    }
    let html = std::fs::read_to_string(dir.join("report.html")).unwrap();
    assert!(html.contains("<img src=\"plot.svg\"") && html.contains("EWA aniso 32"));
    assert!(
        html.contains(&format!("worker threads, {profile} build of commit")),
        "provenance missing"
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn footprint_dump_round_trips_through_the_cli() {
    let dir = temp_dir("footprints");
    let scene = concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/checker.toml");
    let out = run(
        &[
            "footprints",
            scene,
            "-o",
            dir.to_str().unwrap(),
            "--width",
            "32",
            "--passes",
            "1",
            "--reference-spp",
            "1024",
        ],
        "",
    );
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let dump = quadtex_io::read_footprints(&dir.join("footprints.bin")).unwrap();
    assert_eq!((dump.width, dump.height), (32, 18));
    assert_eq!(dump.textures.len(), 1);
    assert!(dir.join(&dump.textures[0].file).is_file());
    let textured: Vec<_> = dump
        .records
        .iter()
        .filter(|r| r.texture.is_some())
        .collect();
    assert!(
        textured.len() > 32 * 18 / 3,
        "{} textured pixels",
        textured.len()
    );
    for r in textured {
        // The centre lies inside its footprint's bounding box, and the
        // derivatives span the quad (t runs down, as in OpenImageIO).
        let (lo, hi) = r
            .quad
            .iter()
            .fold(([f32::MAX; 2], [f32::MIN; 2]), |(lo, hi), p| {
                (
                    [lo[0].min(p[0]), lo[1].min(p[1])],
                    [hi[0].max(p[0]), hi[1].max(p[1])],
                )
            });
        let slack = 1e-3 * (1.0 + r.st[0].abs() + r.st[1].abs());
        assert!(
            r.st[0] >= lo[0] - slack && r.st[0] <= hi[0] + slack,
            "{r:?}"
        );
        assert!(
            r.st[1] >= lo[1] - slack && r.st[1] <= hi[1] + slack,
            "{r:?}"
        );
        let dsdx = 0.5 * (r.quad[1][0] - r.quad[0][0] + r.quad[2][0] - r.quad[3][0]);
        assert!(
            (dsdx - r.derivatives[0]).abs() <= 1e-4 * (1.0 + dsdx.abs()),
            "{r:?}"
        );
    }
    // `diff` reads the EXRs back: quadtex against the reference is close.
    let out = run(
        &[
            "diff",
            dir.join("reference.exr").to_str().unwrap(),
            dir.join("quadtex-quadtree.exr").to_str().unwrap(),
        ],
        "",
    );
    let text = String::from_utf8_lossy(&out.stdout).to_string();
    let rmse: f64 = text.split_whitespace().nth(1).unwrap().parse().unwrap();
    assert!(rmse < 0.05, "{text}");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn render_along_a_camera_path_writes_numbered_frames() {
    let d = temp_dir("camera-path");
    let frames = d.join("frames");
    let out = run(
        &[
            "render",
            "scenes/runway.toml",
            "--path",
            "scenes/runway-approach.path.toml",
            "--frames",
            "3",
            "--width",
            "48",
            "--filter",
            "nearest",
            "-o",
            frames.to_str().unwrap(),
        ],
        "",
    );
    let text = String::from_utf8_lossy(&out.stdout).to_string();
    assert!(
        out.status.success(),
        "{text}{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(text.contains("wrote 3 frames"), "{text}");
    let images: Vec<quadtex_io::LinearImage> = (0..3)
        .map(|i| quadtex_io::load_linear_image(&frames.join(format!("frame_{i:04}.png"))).unwrap())
        .collect();
    assert!(!frames.join("frame_0003.png").exists());
    for image in &images {
        assert_eq!((image.width, image.height), (48, 27));
    }
    // The camera moves: consecutive frames differ.
    for pair in images.windows(2) {
        assert_ne!(pair[0].pixels, pair[1].pixels);
    }
    // The first frame is the first key's view: the same as rendering a
    // scene whose camera is that key.
    let scene = std::fs::read_to_string("scenes/runway.toml").unwrap();
    let moved = scene.replace("position = [4, 25, 300]", "position = [4, 150, 1500]");
    assert_ne!(scene, moved);
    let first = d.join("first.toml");
    std::fs::write(&first, moved).unwrap();
    let png = d.join("first.png");
    let out = run(
        &[
            "render",
            first.to_str().unwrap(),
            "--width",
            "48",
            "--filter",
            "nearest",
            "-o",
            png.to_str().unwrap(),
        ],
        "",
    );
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert_eq!(
        quadtex_io::load_linear_image(&png).unwrap().pixels,
        images[0].pixels
    );
    std::fs::remove_dir_all(&d).unwrap();
}

/// `quadtex render scenes/runway.toml` along the approach path, 4 frames
/// 48 pixels wide with the quadtree filter, into `dir`, with `extra`
/// arguments (`--range …`); returns standard output, asserting success.
fn render_approach(dir: &Path, extra: &[&str]) -> String {
    let mut args = vec![
        "render",
        "scenes/runway.toml",
        "--path",
        "scenes/runway-approach.path.toml",
        "--frames",
        "4",
        "--width",
        "48",
        "-o",
        dir.to_str().unwrap(),
    ];
    args.extend_from_slice(extra);
    let out = run(&args, "");
    let text = String::from_utf8_lossy(&out.stdout).to_string();
    assert!(
        out.status.success(),
        "{args:?}: {text}{}",
        String::from_utf8_lossy(&out.stderr)
    );
    text
}

/// Every file in `dir` (hidden ones included), by name, with its bytes.
fn files_of(dir: &Path) -> Vec<(String, Vec<u8>)> {
    let mut files: Vec<(String, Vec<u8>)> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| {
            let e = e.unwrap();
            (
                e.file_name().to_string_lossy().into_owned(),
                std::fs::read(e.path()).unwrap(),
            )
        })
        .collect();
    files.sort();
    files
}

#[test]
fn render_ranges_split_a_camera_path_into_the_same_frames() {
    let d = temp_dir("path-ranges");
    let whole = d.join("whole");
    render_approach(&whole, &[]);
    let expected = files_of(&whole);
    let names: Vec<&str> = expected.iter().map(|(n, _)| n.as_str()).collect();
    assert_eq!(
        names,
        [
            "frame_0000.png",
            "frame_0001.png",
            "frame_0002.png",
            "frame_0003.png"
        ]
    );
    // Split two ways, in and out of order, one frame alone: the same
    // names and bytes, and nothing else left in the directory.
    for (case, ranges) in [
        ("halves", &["0-1", "2-3"][..]),
        ("single", &["3", "0-0", "1-2"][..]),
        ("whole-range", &["0-3"][..]),
    ] {
        let split = d.join(case);
        for range in ranges {
            let text = render_approach(&split, &["--range", range]);
            let (first, last) = range.split_once('-').unwrap_or((range, range));
            let count = last.parse::<u32>().unwrap() - first.parse::<u32>().unwrap() + 1;
            // The summary writes a one-frame range as its frame.
            let shown = if first == last { first } else { range };
            assert!(
                text.contains(&format!("wrote {count} frames to {}", split.display()))
                    && text.contains(&format!(
                        "--range {shown} of 4: {count} rendered, 0 skipped as already complete"
                    )),
                "{case} {range}: {text}"
            );
        }
        assert!(files_of(&split) == expected, "{case}");
    }
}

#[test]
fn render_range_skips_frames_whose_file_exists() {
    let d = temp_dir("path-resume");
    let frames = d.join("frames");
    std::fs::create_dir_all(&frames).unwrap();
    // Completeness is judged by the file's existence alone (frames are
    // renamed into place whole): a file under a frame's final name, whatever
    // it holds, is kept.
    let sentinel = frames.join("frame_0001.png");
    std::fs::write(&sentinel, b"not a png: left alone").unwrap();
    let text = render_approach(&frames, &["--range", "0-2"]);
    assert!(
        text.contains("wrote 2 frames")
            && text.contains("(frame_0000.png … frame_0002.png)")
            && text.contains("--range 0-2 of 4: 2 rendered, 1 skipped as already complete")
            && text.contains("frame time:"),
        "{text}"
    );
    assert_eq!(std::fs::read(&sentinel).unwrap(), b"not a png: left alone");
    assert!(!frames.join("frame_0003.png").exists());
    // Run again, a frame more: only the missing one is rendered.
    let before = files_of(&frames);
    let text = render_approach(&frames, &["--range", "0-3"]);
    assert!(
        text.contains("wrote 1 frames")
            && text.contains("(frame_0003.png … frame_0003.png)")
            && text.contains("--range 0-3 of 4: 1 rendered, 3 skipped as already complete"),
        "{text}"
    );
    let after = files_of(&frames);
    assert_eq!(after.len(), 4);
    assert!(before.iter().all(|f| after.contains(f)));
    // Nothing left to do: no frame time.
    let text = render_approach(&frames, &["--range", "1-3"]);
    assert_eq!(
        text,
        format!(
            "wrote 0 frames to {}; --range 1-3 of 4: 0 rendered, 3 skipped as already complete\n",
            frames.display()
        )
    );
    assert!(files_of(&frames) == after);
    // Without --range every frame is rendered and replaced, the sentinel too.
    let text = render_approach(&frames, &[]);
    assert!(
        text.contains("wrote 4 frames") && !text.contains("skipped"),
        "{text}"
    );
    assert_ne!(std::fs::read(&sentinel).unwrap(), b"not a png: left alone");
    quadtex_io::load_linear_image(&sentinel).unwrap();
}

#[test]
fn render_refuses_bad_ranges_naming_the_option() {
    let d = temp_dir("path-bad-range");
    let frames = d.join("frames");
    let path_args = [
        "--path",
        "scenes/runway-approach.path.toml",
        "--frames",
        "4",
    ];
    for (range, with_path, needle) in [
        (
            "3-2",
            true,
            "--range 3-2: the last frame 2 comes before the first 3",
        ),
        (
            "0-4",
            true,
            "--range 0-4: frame 4 is past the last of --frames 4 (frames are numbered 0 to 3)",
        ),
        (
            "4",
            true,
            "--range 4: frame 4 is past the last of --frames 4",
        ),
        ("x", true, "--range x: expected A-B"),
        ("1-", true, "--range 1-: expected A-B"),
        ("-1", true, "--range -1: expected A-B"),
        ("0..3", true, "--range 0..3: expected A-B"),
        ("1-2-3", true, "--range 1-2-3: expected A-B"),
        (
            "0-1",
            false,
            "--range 0-1 picks frames of a camera path: it needs --path PATH.toml and --frames N",
        ),
    ] {
        let range_arg = format!("--range={range}");
        let mut args = vec!["render", "scenes/runway.toml", "--width", "48"];
        if with_path {
            args.extend_from_slice(&path_args);
        }
        args.extend_from_slice(&[range_arg.as_str(), "-o", frames.to_str().unwrap()]);
        let out = run(&args, "");
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(
            matches!(out.status.code(), Some(1 | 2)),
            "{range}: {:?} {err}",
            out.status
        );
        assert!(
            err.contains(needle) && !err.contains("panicked"),
            "{range}: {err}"
        );
        assert!(!frames.exists(), "{range}");
    }
}

#[test]
fn compare_measures_shimmer_along_a_camera_path() {
    let d = temp_dir("compare-path");
    let out = d.join("report");
    let o = run(
        &[
            "compare",
            "scenes/runway.toml",
            "--width",
            "32",
            "--reference-spp",
            "1",
            "--frames",
            "2",
            "--no-flip",
            "--path",
            "scenes/runway-approach.path.toml",
            "-o",
            out.to_str().unwrap(),
        ],
        "",
    );
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let html = std::fs::read_to_string(out.join("report.html")).unwrap();
    assert!(
        html.contains("2 frames at 16x9 along the camera path"),
        "{html}"
    );
    std::fs::remove_dir_all(&d).unwrap();
}

/// The runway art rasterised `side × side`, and cut into `tiles × tiles`
/// PNG tiles named `ROW_COL.png` in `dir`.
fn write_tiles(dir: &Path, side: u32, tiles: u32) -> LinearImage {
    let grid = quadtex_core::synth::runway_art()
        .rasterise(side, side)
        .unwrap();
    let whole = LinearImage {
        width: side,
        height: side,
        pixels: grid.texels().iter().map(|t| t.to_rgba()).collect(),
    };
    let t = side / tiles;
    for row in 0..tiles {
        for col in 0..tiles {
            let pixels = (0..t * t)
                .map(|k| whole.pixels[((row * t + k / t) * side + col * t + k % t) as usize])
                .collect();
            let tile = LinearImage {
                width: t,
                height: t,
                pixels,
            };
            save_image(&dir.join(format!("{row}_{col}.png")), &tile).unwrap();
        }
    }
    whole
}

#[test]
fn pack_tiles_builds_the_tree_of_the_whole_mosaic() {
    let d = temp_dir("pack-tiles");
    let tiles = d.join("tiles");
    std::fs::create_dir_all(&tiles).unwrap();
    let whole = write_tiles(&tiles, 256, 4);
    // A file that is not a tile is ignored.
    std::fs::write(tiles.join("README.txt"), "tiles of the runway").unwrap();
    let png = d.join("whole.png");
    save_image(&png, &whole).unwrap();
    let (a, b) = (d.join("tiled.qtx"), d.join("whole.qtx"));
    let out = run(
        &[
            "pack-tiles",
            tiles.to_str().unwrap(),
            "-o",
            a.to_str().unwrap(),
        ],
        "",
    );
    let text = String::from_utf8_lossy(&out.stdout).to_string();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(text.contains("packed 4x4 tiles of 64x64"), "{text}");
    let out = run(
        &["pack", png.to_str().unwrap(), "-o", b.to_str().unwrap()],
        "",
    );
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    // The same tree, byte for byte (the header records 256x256 for both).
    assert_eq!(std::fs::read(&a).unwrap(), std::fs::read(&b).unwrap());
    std::fs::remove_dir_all(&d).unwrap();
}

/// `image`'s bytes as the PNG encoder writes them: straight sRGB RGBA8.
fn srgb8_samples(image: &LinearImage) -> Vec<u16> {
    image
        .pixels
        .iter()
        .flat_map(|p| {
            let inv = if p.a > 0.0 { 1.0 / p.a } else { 0.0 };
            let enc = |c: f32| u16::from(quadtex_io::linear_to_srgb8(c * inv));
            [
                enc(p.r),
                enc(p.g),
                enc(p.b),
                (p.a.clamp(0.0, 1.0) * 255.0 + 0.5) as u16,
            ]
        })
        .collect()
}

/// `pack` reads a TIFF as it reads the PNG of the same texels, and
/// `pack-tiles` reads a tiled TIFF (4x4 tiles of 16x16, LZW) as the folder
/// of its tiles as PNGs: byte-identical `.qtx` files. The GeoTIFF tags are
/// printed in the summaries.
#[test]
fn tiff_packs_as_png_and_tiled_tiff_as_its_tiles() {
    use common::tiff_writer::{Spec, utm33_keys};
    let d = temp_dir("tiff");
    let tiles = d.join("tiles");
    std::fs::create_dir_all(&tiles).unwrap();
    let whole = write_tiles(&tiles, 64, 4);
    let png = d.join("whole.png");
    save_image(&png, &whole).unwrap();
    let spec = Spec {
        samples_per_pixel: 4,
        extra_samples: vec![2],
        tile: Some((16, 16)),
        compression: 5,
        geo: Some((
            [2.0, 2.0, 0.0],
            [0.0, 0.0, 0.0, 440_000.0, 5_080_000.0, 0.0],
            utm33_keys(),
        )),
        ..Spec::rgb8(64, 64, srgb8_samples(&whole))
    };
    let tif = d.join("mosaic.tif");
    std::fs::write(&tif, spec.write()).unwrap();
    let stripped = d.join("stripped.tif");
    let strips = Spec {
        tile: None,
        rows_per_strip: 7,
        compression: 8,
        geo: None,
        ..spec.clone()
    };
    std::fs::write(&stripped, strips.write()).unwrap();
    let pack = |command: &str, input: &Path, name: &str| {
        let qtx = d.join(name);
        let out = run(
            &[
                command,
                input.to_str().unwrap(),
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
        (
            std::fs::read(&qtx).unwrap(),
            String::from_utf8_lossy(&out.stdout).to_string(),
        )
    };
    let (folder, _) = pack("pack-tiles", &tiles, "folder.qtx");
    let (tiled, summary) = pack("pack-tiles", &tif, "tiled.qtx");
    assert_eq!(tiled, folder);
    assert!(
        summary.contains("packed 4x4 tiles of 16x16 from ")
            && summary.contains(
                "georeferenced (not kept in the .qtx): EPSG:32633, tiepoint (0, 0, 0) -> (440000, 5080000, 0), pixel scale (2, 2, 0)"
            ),
        "{summary}"
    );
    let (from_png, summary) = pack("pack", &png, "png.qtx");
    assert!(!summary.contains("georeferenced"), "{summary}");
    assert_eq!(from_png, folder);
    let (from_tif, summary) = pack("pack", &tif, "tif.qtx");
    assert_eq!(from_tif, folder);
    assert!(summary.contains("georeferenced"), "{summary}");
    let (from_strips, _) = pack("pack", &stripped, "strips.qtx");
    assert_eq!(from_strips, folder);
    // A Cloud-Optimized GeoTIFF's layout: 56x40 texels in 16x16 tiles, so
    // partial tiles on the right and bottom edges and a 4x3 grid.
    // `pack-tiles` reads it tile by tile, on one thread or two, into the
    // file `pack` writes from the whole image.
    let full = srgb8_samples(&whole);
    let (w, h) = (56usize, 40usize);
    let cropped = (0..h)
        .flat_map(|y| full[y * 64 * 4..(y * 64 + w) * 4].to_vec())
        .collect();
    let cog = d.join("cog.tif");
    let cog_spec = Spec {
        samples_per_pixel: 4,
        extra_samples: vec![2],
        tile: Some((16, 16)),
        compression: 8,
        ..Spec::rgb8(w as u32, h as u32, cropped)
    };
    std::fs::write(&cog, cog_spec.write()).unwrap();
    let (whole_cog, _) = pack("pack", &cog, "cog-whole.qtx");
    let (tiled_cog, summary) = pack("pack-tiles", &cog, "cog-tiles.qtx");
    assert_eq!(tiled_cog, whole_cog);
    assert!(
        summary.contains("packed 4x3 tiles of 16x16 from ") && summary.contains(": 56x40 texels,"),
        "{summary}"
    );
    let one_thread = d.join("cog-1.qtx");
    let out = run(
        &[
            "pack-tiles",
            cog.to_str().unwrap(),
            "--threads",
            "1",
            "-o",
            one_thread.to_str().unwrap(),
        ],
        "",
    );
    assert!(out.status.success());
    assert_eq!(std::fs::read(&one_thread).unwrap(), whole_cog);
}

/// Art whose exact sweep would take seconds (a fuzzed star whose dashes pile
/// on its centre) is refused under `--max-sweep-work`, naming the limit,
/// and leaves no file behind; under the default it packs and the summary
/// states the steps.
#[test]
fn svg_sweep_work_has_a_stated_limit() {
    let dir = common::temp_dir("svg-sweep-work");
    let slow = Path::new(env!("CARGO_MANIFEST_DIR")).join("fuzz/slow/dashed-star-15s.svg");
    let qtx = dir.join("star.qtx");
    let out = run(
        &[
            "pack",
            slow.to_str().unwrap(),
            "--max-level",
            "4",
            "--max-sweep-work",
            "1000000",
            "-o",
            qtx.to_str().unwrap(),
        ],
        "",
    );
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    assert!(
        stderr.starts_with("Error: ")
            && stderr.contains("dashed-star-15s.svg")
            && stderr.contains("above the limit of 1000000 (max sweep work)"),
        "{stderr}"
    );
    assert!(!qtx.exists());
    let star = Path::new(env!("CARGO_MANIFEST_DIR")).join("samples/star.svg");
    let out = run(
        &["pack", star.to_str().unwrap(), "-o", qtx.to_str().unwrap()],
        "",
    );
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success() && stdout.contains(" sweep steps)"),
        "{stdout}"
    );
    std::fs::remove_dir_all(&dir).unwrap();
}
