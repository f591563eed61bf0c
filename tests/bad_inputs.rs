//! The catalogue of bad inputs: one hostile input per test, run through the
//! `quadtex` binary. Each must exit non-zero, name the problem (file, and
//! field or line where one applies) on stderr after `Error: `, never panic,
//! and leave no output file behind. An option value the command line itself
//! rejects (out of range, say) is a usage error instead: clap's
//! `error: invalid value …` naming the problem, exit status 2. The inputs are
//! generated here from a valid file, so they stay in step with the format.
#![allow(clippy::unwrap_used, clippy::expect_used)]

mod common;

use std::path::{Path, PathBuf};

use common::{run, temp_dir};

use quadtex_core::{BuildOptions, QuadTree, synth};

fn dir(case: &str) -> common::TempDir {
    temp_dir(&format!("bad-{case}"))
}

/// A small valid `.qtx` file's bytes.
fn valid_qtx(d: &Path) -> Vec<u8> {
    let g = synth::runway_art().rasterise(32, 32).unwrap();
    let (t, _) = QuadTree::from_texels(&g, &BuildOptions::default()).unwrap();
    let p = d.join("valid.qtx");
    quadtex_io::write_qtx(&p, &t, Some((32, 32))).unwrap();
    std::fs::read(&p).unwrap()
}

fn reseal_header(b: &mut [u8]) {
    let crc = crc32(&b[..56]);
    b[56..60].copy_from_slice(&crc.to_le_bytes());
}

/// Recomputes the structure checksum (inner flags and the texel-block
/// section's counts and flags) and the payload checksum.
fn reseal_payload(b: &mut [u8]) {
    let len = b.len();
    let nodes = u64::from_le_bytes(b[32..40].try_into().unwrap()) as usize;
    let bits = 64..64 + nodes.div_ceil(8);
    let section = bits.end + 8 * nodes..len - 4;
    let flags = match b.get(section.start..section.start + 8) {
        Some(counts) => {
            let level_nodes = u64::from_le_bytes(counts.try_into().unwrap()) as usize;
            16 + level_nodes.div_ceil(8)
        }
        None => 0,
    };
    let mut structure = b[bits].to_vec();
    structure.extend_from_slice(&b[section.start..section.start + flags]);
    let crc = crc32(&structure);
    b[60..64].copy_from_slice(&crc.to_le_bytes());
    let crc = crc32(&b[64..len - 4]);
    b[len - 4..].copy_from_slice(&crc.to_le_bytes());
}

fn crc32(data: &[u8]) -> u32 {
    let mut crc = !0u32;
    for &byte in data {
        crc ^= u32::from(byte);
        for _ in 0..8 {
            crc = if crc & 1 == 1 {
                (crc >> 1) ^ 0xEDB8_8320
            } else {
                crc >> 1
            };
        }
    }
    !crc
}

/// Runs `quadtex args…` with `stdin`; asserts failure, `Error: ` with every
/// needle on stderr, no panic, and that `must_not_exist` was not created.
fn expect_failure(args: &[&str], stdin: &str, needles: &[&str], must_not_exist: Option<&Path>) {
    let out = run(args, stdin);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success(), "{args:?} succeeded; stderr: {err}");
    assert_eq!(out.status.code(), Some(1), "{args:?}: {err}");
    assert!(
        err.starts_with("Error: ") && !err.contains("panicked"),
        "{args:?}: {err}"
    );
    for n in needles {
        assert!(err.contains(n), "{args:?}: `{n}` not in: {err}");
    }
    if let Some(p) = must_not_exist {
        assert!(!p.exists(), "{} was written", p.display());
    }
}

/// Runs `quadtex args…`; asserts a usage error (exit status 2) rejecting an
/// option's value with every needle on stderr, no panic, and that
/// `must_not_exist` was not created.
fn expect_usage_error(args: &[&str], needles: &[&str], must_not_exist: Option<&Path>) {
    let out = run(args, "");
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{args:?}: {err}");
    assert!(
        err.starts_with("error: invalid value ") && !err.contains("panicked"),
        "{args:?}: {err}"
    );
    for n in needles {
        assert!(err.contains(n), "{args:?}: `{n}` not in: {err}");
    }
    if let Some(p) = must_not_exist {
        assert!(!p.exists(), "{} was written", p.display());
    }
}

/// A `.qtx` case: mutate the valid bytes, run `info` and `query` on them
/// (memory-mapped, the default, and with `--verify`).
fn qtx_case(case: &str, mutate: impl FnOnce(&mut Vec<u8>), field: &str) {
    qtx_case_with(case, mutate, field, &[&[], &["--verify"]]);
}

/// A `.qtx` case in the colours with valid checksums (crafted, not
/// damaged): mapped, `info` and `query` do not check the colours'
/// invariants (and must not crash); `--verify` refuses them by name.
fn qtx_colour_case(case: &str, mutate: impl Fn(&mut Vec<u8>), field: &str) {
    qtx_case_with(case, &mutate, field, &[&["--verify"]]);
    qtx_answers_unchecked(case, mutate, &[]);
}

/// Runs `quadtex query args…` on the valid file mutated by `mutate`;
/// asserts it answers both fragments.
fn qtx_answers_unchecked(case: &str, mutate: impl Fn(&mut Vec<u8>), args: &[&str]) {
    let d = dir(&format!("{case}-mapped"));
    let mut bytes = valid_qtx(&d);
    mutate(&mut bytes);
    let p = d.join(format!("{case}.qtx"));
    std::fs::write(&p, &bytes).unwrap();
    let mut query = vec!["query", p.to_str().unwrap()];
    query.extend_from_slice(args);
    let out = run(&query, "0 0 1 1\n0.1 0.2 0.3 0.9\n");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert_eq!(String::from_utf8_lossy(&out.stdout).lines().count(), 2);
    std::fs::remove_dir_all(&d).unwrap();
}

fn qtx_case_with(case: &str, mutate: impl FnOnce(&mut Vec<u8>), field: &str, modes: &[&[&str]]) {
    let d = dir(case);
    let mut bytes = valid_qtx(&d);
    mutate(&mut bytes);
    let p = d.join(format!("{case}.qtx"));
    std::fs::write(&p, &bytes).unwrap();
    let name = format!("{case}.qtx");
    for mode in modes {
        let mut info = vec!["info", p.to_str().unwrap()];
        info.extend_from_slice(mode);
        expect_failure(&info, "", &[&name, field], None);
        let mut query = vec!["query", p.to_str().unwrap()];
        query.extend_from_slice(mode);
        expect_failure(&query, "0 0 1 1\n", &[&name, field], None);
    }
    std::fs::remove_dir_all(&d).unwrap();
}

macro_rules! qtx_cases {
    ($($name:ident: $field:expr, $mutate:expr;)*) => {$(
        #[test]
        fn $name() {
            qtx_case(stringify!($name), $mutate, $field);
        }
    )*};
}

macro_rules! qtx_colour_cases {
    ($($name:ident: $field:expr, $mutate:expr;)*) => {$(
        #[test]
        fn $name() {
            qtx_colour_case(stringify!($name), $mutate, $field);
        }
    )*};
}

qtx_cases! {
    qtx_empty: "header", |b| b.clear();
    qtx_truncated_header: "header", |b| b.truncate(40);
    qtx_truncated_body: "length", |b| { let n = b.len(); b.truncate(n - 20); };
    qtx_trailing_garbage: "length", |b| b.extend_from_slice(b"extra");
    qtx_wrong_magic: "magic", |b| b[1] = b'P';
    qtx_text_file: "magic", |b| { *b = b"x0 z0 x1 z1\n0 0 1 1\n".repeat(5); };
    qtx_future_version: "version", |b| { b[8] = 5; reseal_header(b); };
    qtx_structure_bit_flip: "structure_crc", |b| b[64] ^= 0x02;
    qtx_header_bit_flip: "header_crc", |b| b[33] ^= 0x04;
    qtx_terabyte_node_count: "max_nodes", |b| { b[32..40].copy_from_slice(&(1u64 << 40).to_le_bytes()); reseal_header(b); };
    qtx_inconsistent_inner_count: "node_count", |b| { let inner = u64::from_le_bytes(b[40..48].try_into().unwrap()); b[40..48].copy_from_slice(&(inner + 1).to_le_bytes()); reseal_header(b); };
    qtx_payload_size_lie: "payload_bytes", |b| { b[48..56].copy_from_slice(&1u64.to_le_bytes()); reseal_header(b); };
    qtx_payload_size_off_by_eight: "length", |b| { b[48] ^= 0x08; reseal_header(b); };
    qtx_absurd_depth: "max_depth", |b| { b[16] = 200; reseal_header(b); };
    qtx_unknown_colour_format: "colour_format", |b| { b[17] = 7; reseal_header(b); };
    qtx_reserved_bytes_set: "reserved", |b| { b[31] = 1; reseal_header(b); };
    qtx_unknown_block_format: "block_format", |b| { b[28] = 9; reseal_header(b); };
    qtx_block_level_below_the_tree: "block_level", |b| { b[29] = 31; reseal_header(b); };
    qtx_wrong_header_size: "header_bytes", |b| { b[12] = 128; reseal_header(b); };
    qtx_inner_flags_cleared: "inner_bits", |b| { b[64] = 0; reseal_payload(b); };
    qtx_payload_bit_flip: "payload_crc", |b| { let n = b.len(); b[n - 9] ^= 0x01; };
}

/// A damaged colour is refused by default (above), and answered as it is
/// with `--no-verify`, which gives up that promise for trusted files.
#[test]
fn qtx_payload_bit_flip_answers_with_no_verify() {
    qtx_answers_unchecked(
        "qtx_payload_bit_flip_no_verify",
        |b| {
            let n = b.len();
            b[n - 9] ^= 0x01;
        },
        &["--no-verify"],
    );
}

/// One to three bits flipped at random in the colours of 24 copies of a
/// packed file: `quadtex query` (mapped, the default) refuses every copy,
/// exit status 1, naming the file and the payload checksum.
#[test]
fn qtx_random_colour_bit_flips_are_refused_by_query() {
    let d = dir("qtx-random-flips");
    let good = valid_qtx(&d);
    let nodes = u64::from_le_bytes(good[32..40].try_into().unwrap()) as usize;
    let colours = 64 + nodes.div_ceil(8);
    let mut rng = 0x2545_F491_4F6C_DD1D_u64;
    for copy in 0..24 {
        let mut bytes = good.clone();
        for _ in 0..1 + copy % 3 {
            rng ^= rng << 13;
            rng ^= rng >> 7;
            rng ^= rng << 17;
            let bit = (rng % (64 * nodes as u64)) as usize;
            bytes[colours + bit / 8] ^= 1 << (bit % 8);
        }
        if bytes == good {
            continue; // the same bit flipped twice
        }
        let name = format!("copy-{copy}.qtx");
        let p = d.join(&name);
        std::fs::write(&p, &bytes).unwrap();
        expect_failure(
            &["query", p.to_str().unwrap()],
            "0 0 1 1\n",
            &[&name, "payload_crc", "colours (bytes"],
            None,
        );
    }
    std::fs::remove_dir_all(&d).unwrap();
}

qtx_colour_cases! {
    qtx_not_premultiplied: "premultiplied", |b| {
        // Node 0's red channel (first colour, after the inner bits) above its alpha.
        let n = u64::from_le_bytes(b[32..40].try_into().unwrap()) as usize;
        let c = 64 + n.div_ceil(8);
        b[c..c + 2].copy_from_slice(&u16::MAX.to_le_bytes());
        b[c + 6..c + 8].copy_from_slice(&1u16.to_le_bytes());
        reseal_payload(b);
    };
    qtx_inner_colour_not_average: "children average", |b| {
        let n = u64::from_le_bytes(b[32..40].try_into().unwrap()) as usize;
        let c = 64 + n.div_ceil(8);
        b[c..c + 2].copy_from_slice(&0u16.to_le_bytes());
        b[c + 2..c + 4].copy_from_slice(&0u16.to_le_bytes());
        b[c + 4..c + 6].copy_from_slice(&0u16.to_le_bytes());
        reseal_payload(b);
    };
}

/// A PNG whose IHDR declares `w × h` (valid chunk CRCs) followed by an
/// empty IDAT and IEND: the decoder sees the dimensions, the data is absent.
fn png_header_only(w: u32, h: u32) -> Vec<u8> {
    let mut ihdr = b"IHDR".to_vec();
    ihdr.extend(w.to_be_bytes());
    ihdr.extend(h.to_be_bytes());
    ihdr.extend([8, 6, 0, 0, 0]);
    let mut png = b"\x89PNG\r\n\x1a\n".to_vec();
    png.extend(13u32.to_be_bytes());
    png.extend(&ihdr);
    png.extend(crc32(&ihdr).to_be_bytes());
    for chunk in [b"IDAT", b"IEND"] {
        png.extend(0u32.to_be_bytes());
        png.extend(chunk);
        png.extend(crc32(chunk).to_be_bytes());
    }
    png
}

fn pack_case(case: &str, file_name: &str, bytes: &[u8], extra: &[&str], needles: &[&str]) {
    let d = dir(case);
    let input = d.join(file_name);
    std::fs::write(&input, bytes).unwrap();
    let out = d.join("out.qtx");
    let mut args = vec!["pack", input.to_str().unwrap(), "-o", out.to_str().unwrap()];
    args.extend(extra);
    expect_failure(&args, "", needles, Some(&out));
    assert_eq!(
        std::fs::read_dir(&d).unwrap().count(),
        1,
        "temporary files left in {}",
        d.display()
    );
    std::fs::remove_dir_all(&d).unwrap();
}

#[test]
fn image_zero_by_zero() {
    pack_case(
        "zero",
        "zero.png",
        &png_header_only(0, 0),
        &[],
        &["zero.png"],
    );
}

#[test]
fn image_declares_100000_squared() {
    pack_case(
        "huge",
        "huge.png",
        &png_header_only(100_000, 100_000),
        &[],
        &["huge.png", "max_dimension"],
    );
}

#[test]
fn image_truncated_png() {
    let d = dir("trunc-src");
    let p = d.join("ok.png");
    let pixels = vec![quadtex_core::Rgba::opaque(0.5, 0.2, 0.1); 64 * 64];
    quadtex_io::save_image(
        &p,
        &quadtex_io::LinearImage {
            width: 64,
            height: 64,
            pixels,
        },
    )
    .unwrap();
    let bytes = std::fs::read(&p).unwrap();
    std::fs::remove_dir_all(&d).unwrap();
    pack_case(
        "trunc",
        "trunc.png",
        &bytes[..bytes.len() / 2],
        &[],
        &["trunc.png"],
    );
}

#[test]
fn image_not_an_image() {
    pack_case(
        "text",
        "notes.png",
        b"these are not pixels",
        &[],
        &["notes.png"],
    );
}

#[test]
fn image_empty_file() {
    pack_case("empty", "empty.jpg", b"", &[], &["empty.jpg"]);
}

#[test]
fn image_missing_file() {
    let d = dir("missing");
    let out = d.join("out.qtx");
    expect_failure(
        &[
            "pack",
            d.join("absent.png").to_str().unwrap(),
            "-o",
            out.to_str().unwrap(),
        ],
        "",
        &["absent.png"],
        Some(&out),
    );
    std::fs::remove_dir_all(&d).unwrap();
}

fn valid_png(d: &Path) -> PathBuf {
    let p = d.join("ok.png");
    let pixels = vec![quadtex_core::Rgba::opaque(0.5, 0.2, 0.1); 16];
    quadtex_io::save_image(
        &p,
        &quadtex_io::LinearImage {
            width: 4,
            height: 4,
            pixels,
        },
    )
    .unwrap();
    p
}

/// Packs a valid PNG with `extra` arguments; `usage`: the command line
/// rejects them (see [`expect_usage_error`]), else the pack fails.
fn pack_arg_case(case: &str, extra: &[&str], usage: bool, needle: &str) {
    let d = dir(case);
    let png = valid_png(&d);
    let out = d.join("out.qtx");
    let mut args = vec!["pack", png.to_str().unwrap(), "-o", out.to_str().unwrap()];
    args.extend(extra);
    if usage {
        expect_usage_error(&args, &[needle], Some(&out));
    } else {
        expect_failure(&args, "", &[needle], Some(&out));
    }
    std::fs::remove_dir_all(&d).unwrap();
}

#[test]
fn pack_level_beyond_limit() {
    pack_arg_case(
        "level99",
        &["--max-level", "99"],
        true,
        "--max-level 99 exceeds",
    );
}

#[test]
fn pack_level_beyond_raster_grid() {
    pack_arg_case(
        "level20",
        &["--max-level", "20"],
        false,
        "exceeds the limit 15",
    );
}

#[test]
fn pack_negative_tolerance() {
    pack_arg_case(
        "tolneg",
        &["--tolerance", "-1"],
        true,
        "--tolerance must be in [0, 1]",
    );
}

#[test]
fn pack_nan_tolerance() {
    pack_arg_case(
        "tolnan",
        &["--tolerance", "NaN"],
        true,
        "--tolerance must be in [0, 1]",
    );
}

fn query_case(case: &str, line: &str, needle: &str) {
    let d = dir(case);
    let p = d.join("ok.qtx");
    std::fs::write(&p, valid_qtx(&d)).unwrap();
    let input = format!("0 0 0.5 0.5\n{line}\n0 0 1 1\n");
    expect_failure(
        &["query", p.to_str().unwrap()],
        &input,
        &["stdin line 2", needle],
        None,
    );
    std::fs::remove_dir_all(&d).unwrap();
}

macro_rules! query_cases {
    ($($name:ident: $line:expr => $needle:expr;)*) => {$(
        #[test]
        fn $name() {
            query_case(stringify!($name), $line, $needle);
        }
    )*};
}

query_cases! {
    query_nan: "0 NaN 1 1" => "z0 is not finite";
    query_infinity: "0 0 inf 1" => "x1 is not finite";
    query_negative_infinity: "-inf 0 1 1" => "x0 is not finite";
    query_overflowing_literal: "0 0 1 1e400" => "z1 is not finite";
    query_reversed_x: "0.75 0 0.25 1" => "reversed bounds on x";
    query_reversed_z: "0 0.75 1 0.25" => "reversed bounds on z";
    query_non_numeric: "0 0 one 1" => "x1: `one` is not a number";
    query_too_few_fields: "0 0 1" => "missing z1";
    query_too_many_fields: "0 0 1 1 1" => "found 5";
    query_hex_float: "0x1p-3 0 1 1" => "x0: `0x1p-3` is not a number";
}

#[test]
fn query_level_beyond_limit() {
    let d = dir("qlevel");
    let p = d.join("ok.qtx");
    std::fs::write(&p, valid_qtx(&d)).unwrap();
    expect_usage_error(
        &["query", p.to_str().unwrap(), "--level", "300"],
        &["--level 300 exceeds the maximum depth"],
        None,
    );
    std::fs::remove_dir_all(&d).unwrap();
}

/// A scene case: the good scene with one substitution must fail naming `needles`.
fn scene_case(case: &str, from: &str, to: &str, needles: &[&str]) {
    let d = dir(case);
    let good = "[camera]\nposition = [0, 2, -10]\nlook_at = [0, 0, 10]\nfov = 50\nwidth = 16\nheight = 8\n\n[[shape]]\ntype = \"plane\"\npoint = [0, 0, 0]\nnormal = [0, 1, 0]\ntexture = \"builtin:checker\"\n";
    assert!(good.contains(from), "{from}");
    let scene = d.join(format!("{case}.toml"));
    std::fs::write(&scene, good.replace(from, to)).unwrap();
    let out = d.join("out.png");
    let mut all = vec![format!("{case}.toml")];
    all.extend(needles.iter().map(|n| n.to_string()));
    let refs: Vec<&str> = all.iter().map(String::as_str).collect();
    expect_failure(
        &[
            "render",
            scene.to_str().unwrap(),
            "-o",
            out.to_str().unwrap(),
        ],
        "",
        &refs,
        Some(&out),
    );
    std::fs::remove_dir_all(&d).unwrap();
}

macro_rules! scene_cases {
    ($($name:ident: $from:expr => $to:expr, [$($needle:expr),*];)*) => {$(
        #[test]
        fn $name() {
            scene_case(stringify!($name), $from, $to, &[$($needle),*]);
        }
    )*};
}

scene_cases! {
    scene_nan_coordinate: "position = [0, 2, -10]" => "position = [0, nan, -10]", [":2:", "camera.position", "finite"];
    scene_infinite_coordinate: "point = [0, 0, 0]" => "point = [0, inf, 0]", [":10:", "shape[0].point", "finite"];
    scene_huge_coordinate: "look_at = [0, 0, 10]" => "look_at = [0, 0, 1e300]", [":3:", "camera.look_at", "limit"];
    scene_zero_resolution: "width = 16" => "width = 0", [":5:", "camera.width"];
    scene_degenerate_camera: "look_at = [0, 0, 10]" => "look_at = [0, 2, -10]", ["camera.look_at", "coincides"];
    scene_unknown_key: "fov = 50" => "fov = 50\nzoom = 3", [":5:", "camera.zoom", "unknown key"];
    scene_missing_texture_file: "builtin:checker" => "nowhere.qtx", ["shape[0].texture", "nowhere.qtx"];
    scene_syntax_error: "[[shape]]" => "[[shape]", ["syntax"];
}

#[test]
fn scene_file_missing() {
    let d = dir("scene-missing");
    let out = d.join("out.png");
    expect_failure(
        &[
            "render",
            d.join("absent.toml").to_str().unwrap(),
            "-o",
            out.to_str().unwrap(),
        ],
        "",
        &["absent.toml"],
        Some(&out),
    );
    std::fs::remove_dir_all(&d).unwrap();
}

/// An SVG case: pack `text` as `NAME.svg` with `extra` arguments; the error
/// must name the file and contain `needle`; no `.qtx` appears.
fn svg_case(case: &str, text: &str, extra: &[&str], needle: &str) {
    let d = dir(case);
    let svg = d.join(format!("{case}.svg"));
    std::fs::write(&svg, text).unwrap();
    let out = d.join("out.qtx");
    let mut args = vec!["pack", svg.to_str().unwrap(), "-o", out.to_str().unwrap()];
    args.extend_from_slice(extra);
    expect_failure(&args, "", &[&format!("{case}.svg"), needle], Some(&out));
}

const SVG_HEAD: &str = r#"<svg xmlns="http://www.w3.org/2000/svg" xmlns:xlink="http://www.w3.org/1999/xlink" viewBox="0 0 10 10">"#;

#[test]
fn svg_malformed_xml() {
    svg_case(
        "svg-malformed",
        &format!("{SVG_HEAD}<rect width=\"5\" height=\"5\"></svg>"),
        &[],
        "invalid SVG",
    );
}

#[test]
fn svg_not_svg_at_all() {
    svg_case("svg-text", "hello, world", &[], "invalid SVG");
}

#[test]
fn svg_pattern_with_too_many_tiles() {
    svg_case(
        "svg-pattern",
        &format!(
            "{SVG_HEAD}<pattern id=\"p\" width=\"0.1\" height=\"0.1\" patternUnits=\"userSpaceOnUse\"><rect width=\"0.05\" height=\"0.05\"/></pattern><rect id=\"sky\" width=\"10\" height=\"10\" fill=\"url(#p)\"/></svg>"
        ),
        &[],
        "unsupported: pattern repeated over more than 4096 tiles (id \"sky\")",
    );
}

#[test]
fn svg_gif_image_is_unsupported() {
    svg_case(
        "svg-image",
        &format!(
            "{SVG_HEAD}<image id=\"photo\" width=\"10\" height=\"10\" href=\"data:image/gif;base64,R0lGODlhAQABAIAAAP///wAAACH5BAEAAAAALAAAAAABAAEAAAICRAEAOw==\"/></svg>"
        ),
        &[],
        "unsupported: image in GIF format",
    );
}

#[test]
fn svg_image_file_missing() {
    svg_case(
        "svg-image-missing",
        &format!("{SVG_HEAD}<image width=\"10\" height=\"10\" href=\"runway.png\"/></svg>"),
        &[],
        "image \"runway.png\" could not be read",
    );
}

#[test]
fn svg_image_data_corrupt() {
    svg_case(
        "svg-image-corrupt",
        &format!(
            "{SVG_HEAD}<image width=\"10\" height=\"10\" href=\"data:image/png;base64,iVBORw0KGgoAAAANSUhEUgAAAAIAAAACCAIAAAD91Jpz\"/></svg>"
        ),
        &[],
        "image",
    );
}

#[test]
fn svg_filter_is_unsupported() {
    svg_case(
        "svg-filter",
        &format!(
            "{SVG_HEAD}<filter id=\"f\"><feGaussianBlur stdDeviation=\"2\"/></filter><rect id=\"r\" width=\"10\" height=\"10\" filter=\"url(#f)\"/></svg>"
        ),
        &[],
        "unsupported: filter (id \"f\")",
    );
}

#[test]
fn svg_use_bomb_is_refused_before_expansion() {
    // Ten levels of ten `use` each: 10^10 elements once expanded.
    let mut s = format!("{SVG_HEAD}<defs><rect id=\"l0\" width=\"1\" height=\"1\"/>");
    for level in 1..=10 {
        s.push_str(&format!("<g id=\"l{level}\">"));
        for _ in 0..10 {
            s.push_str(&format!("<use xlink:href=\"#l{}\"/>", level - 1));
        }
        s.push_str("</g>");
    }
    s.push_str("</defs><use xlink:href=\"#l10\"/></svg>");
    svg_case("svg-use-bomb", &s, &[], "max_svg_elements exceeded");
}

#[test]
fn svg_use_cycle() {
    svg_case(
        "svg-use-cycle",
        &format!(
            "{SVG_HEAD}<g id=\"a\"><use xlink:href=\"#b\"/></g><g id=\"b\"><use xlink:href=\"#a\"/></g></svg>"
        ),
        &[],
        "cycle",
    );
}

#[test]
fn svg_level_beyond_limit() {
    svg_case(
        "svg-level",
        &format!("{SVG_HEAD}<rect width=\"5\" height=\"5\"/></svg>"),
        &["--max-level", "25"],
        "exceeds the limit 24",
    );
}

#[test]
fn svg_radial_gradient_with_focal_outside() {
    svg_case(
        "svg-focal",
        &format!(
            "{SVG_HEAD}<radialGradient id=\"g\" cx=\"0.5\" r=\"0.2\" fx=\"0.5\" fr=\"0.4\"><stop offset=\"0\" stop-color=\"red\"/><stop offset=\"1\" stop-color=\"blue\"/></radialGradient><rect id=\"sky\" width=\"10\" height=\"10\" fill=\"url(#g)\"/></svg>"
        ),
        &[],
        "unsupported: radialGradient with the focal circle not inside the end circle (id \"sky\")",
    );
}

#[test]
fn svg_zero_size() {
    svg_case(
        "svg-zero-size",
        r#"<svg xmlns="http://www.w3.org/2000/svg" width="0" height="0"><rect width="5" height="5"/></svg>"#,
        &[],
        "invalid SVG",
    );
}

#[test]
fn compare_width_out_of_range() {
    let d = dir("compare-width");
    let out = d.join("report");
    let scene = concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/checker.toml");
    expect_usage_error(
        &[
            "compare",
            scene,
            "-o",
            out.to_str().unwrap(),
            "--width",
            "5",
        ],
        &["--width must be in 16..=3840"],
        Some(&out),
    );
}

#[test]
fn compare_missing_scene() {
    let d = dir("compare-missing");
    let out = d.join("report");
    let scene = d.join("nope.toml");
    expect_failure(
        &[
            "compare",
            scene.to_str().unwrap(),
            "-o",
            out.to_str().unwrap(),
        ],
        "",
        &["nope.toml"],
        Some(&out),
    );
}

#[test]
fn diff_of_images_of_different_sizes() {
    let d = dir("diff-sizes");
    let (a, b) = (d.join("a.exr"), d.join("b.exr"));
    for (p, w) in [(&a, 4u32), (&b, 5)] {
        let img = quadtex_io::LinearImage {
            width: w,
            height: 2,
            pixels: vec![quadtex_core::Rgba::opaque(0.5, 0.5, 0.5); (w * 2) as usize],
        };
        quadtex_io::save_image(p, &img).unwrap();
    }
    expect_failure(
        &["diff", a.to_str().unwrap(), b.to_str().unwrap()],
        "",
        &["a.exr is 4x2 but", "b.exr is 5x2"],
        None,
    );
}

#[test]
fn footprints_of_a_scene_with_nan() {
    let d = dir("footprints-nan");
    let scene = d.join("nan.toml");
    std::fs::write(
        &scene,
        "[camera]\nposition = [0, nan, 0]\nlook_at = [0, 0, 1]\nfov = 40\nwidth = 64\nheight = 32\n[[shape]]\ntype = \"plane\"\npoint = [0, 0, 0]\nnormal = [0, 1, 0]\n",
    )
    .unwrap();
    let out = d.join("fp");
    expect_failure(
        &[
            "footprints",
            scene.to_str().unwrap(),
            "-o",
            out.to_str().unwrap(),
        ],
        "",
        &["nan.toml:2", "camera.position"],
        Some(&out),
    );
}

/// A unit square in the y = 0 plane, two triangles, with texture coordinates:
/// the valid OBJ the mesh cases start from.
const GOOD_OBJ: &str = "v 0 0 0\nv 1 0 0\nv 1 0 1\nv 0 0 1\nvt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nf 1/1 2/2 3/3\nf 1/1 3/3 4/4\n";

/// Writes `NAME.obj` (`obj` bytes) and a scene `NAME.toml` whose one shape
/// is that mesh, renders it; `None`: the render must succeed, else it must
/// fail naming the scene, `shape[0].file`, the OBJ and every needle.
fn mesh_run(case: &str, obj: &[u8], needles: Option<&[&str]>) {
    let d = dir(case);
    let obj_name = format!("{case}.obj");
    std::fs::write(d.join(&obj_name), obj).unwrap();
    let scene = d.join(format!("{case}.toml"));
    std::fs::write(
        &scene,
        format!(
            "[camera]\nposition = [0.5, 2, -1]\nlook_at = [0.5, 0, 0.5]\nfov = 50\nwidth = 16\nheight = 8\n\n[[shape]]\ntype = \"mesh\"\nfile = \"{obj_name}\"\ntexture = \"builtin:checker\"\n"
        ),
    )
    .unwrap();
    let out = d.join("out.png");
    let args = [
        "render",
        scene.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
    ];
    match needles {
        None => {
            let o = run(&args, "");
            assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
            assert!(out.exists());
        }
        Some(needles) => {
            let mut all = vec![format!("{case}.toml"), "shape[0].file".into(), obj_name];
            all.extend(needles.iter().map(|n| n.to_string()));
            let refs: Vec<&str> = all.iter().map(String::as_str).collect();
            expect_failure(&args, "", &refs, Some(&out));
        }
    }
    std::fs::remove_dir_all(&d).unwrap();
}

/// The good OBJ with one line replaced (or, when `from` is empty, `to`
/// appended).
fn obj_with(from: &str, to: &str) -> Vec<u8> {
    if from.is_empty() {
        return format!("{GOOD_OBJ}{to}").into_bytes();
    }
    assert!(GOOD_OBJ.contains(from), "{from}");
    GOOD_OBJ.replacen(from, to, 1).into_bytes()
}

#[test]
fn obj_control_good_mesh_renders() {
    // Not a bad input: the base the OBJ cases alter renders.
    mesh_run("obj-good", GOOD_OBJ.as_bytes(), None);
}

macro_rules! obj_cases {
    ($($name:ident: $bytes:expr => [$($needle:expr),*];)*) => {$(
        #[test]
        fn $name() {
            mesh_run(stringify!($name), &$bytes, Some(&[$($needle),*]));
        }
    )*};
}

obj_cases! {
    obj_nan_vertex: obj_with("v 1 0 0", "v nan 0 0") => ["non-finite vertex"];
    obj_infinite_vertex: obj_with("v 1 0 1", "v 1 inf 1") => ["non-finite vertex"];
    obj_overflowing_vertex: obj_with("v 0 0 1", "v 0 0 1e39") => ["non-finite vertex"];
    obj_nan_texture_coordinate: obj_with("vt 1 1", "vt NaN 1") => ["texture coordinate"];
    obj_face_index_out_of_range: obj_with("f 1/1 3/3 4/4", "f 1/1 3/3 9/4") => ["face vertex index out of bounds"];
    obj_texcoord_index_out_of_range: obj_with("f 1/1 3/3 4/4", "f 1/1 3/3 4/9") => ["face texcoord index out of bounds"];
    obj_zero_index: obj_with("f 1/1 2/2 3/3", "f 0/1 2/2 3/3") => ["face vertex index out of bounds"];
    obj_negative_index_before_first: obj_with("f 1/1 3/3 4/4", "f -9/1 3/3 4/4") => ["face vertex index out of bounds"];
    obj_huge_negative_texcoord_index: obj_with("f 1/1 3/3 4/4", "f 1/-4611686018427387905 3/3 4/4") => ["line 10: index -4611686018427387905 out of range"];
    obj_index_beyond_64_bits: obj_with("f 1/1 3/3 4/4", "f 1/1 3/3 99999999999999999999/4") => ["face parse error"];
    // OBJ has no header: a face naming vertex 10^8 declares a mesh of at least
    // 10^8 vertices, which the file does not hold.
    obj_face_declares_1e8_vertices: obj_with("f 1/1 3/3 4/4", "f 1/1 3/3 100000000/4") => ["line 10: index 100000000 out of range"];
    obj_missing_vt: b"v 0 0 0\nv 1 0 0\nv 1 0 1\nf 1 2 3\n".as_slice() => ["no texture coordinates (vt)"];
    obj_some_corners_without_vt: obj_with("f 1/1 3/3 4/4", "f 1/1 3 4/4") => ["some face corners have no texture coordinate"];
    obj_truncated_vertex_line: obj_with("", "v 1 2") => ["position parse error"];
    obj_truncated_texcoord_line: obj_with("vt 0 1", "vt 0") => ["texcoord parse error"];
    obj_truncated_mid_file: GOOD_OBJ.as_bytes()[..GOOD_OBJ.find("v 1 0 1").unwrap() + 4] => ["position parse error"];
    obj_non_numeric_coordinate: obj_with("v 1 0 0", "v one 0 0") => ["position parse error"];
    obj_zero_w: obj_with("v 1 0 0", "v 1 0 0 0") => ["scaling (w) by zero"];
    obj_binary_garbage: (0..4096u32).map(|i| (i.wrapping_mul(2_654_435_761) >> 13) as u8).collect::<Vec<u8>>() => ["read error"];
    obj_empty_file: Vec::<u8>::new() => ["no usable triangles"];
    obj_only_degenerate_triangles: b"v 0 0 0\nv 1 0 0\nv 2 0 0\nvt 0 0\nvt 1 0\nvt 1 1\nf 1/1 2/2 3/3\n".as_slice() => ["no usable triangles"];
}

#[test]
fn obj_missing_file() {
    let d = dir("obj-missing");
    let scene = d.join("absent-mesh.toml");
    std::fs::write(
        &scene,
        "[camera]\nposition = [0, 2, -1]\nlook_at = [0, 0, 1]\nfov = 50\nwidth = 16\nheight = 8\n\n[[shape]]\ntype = \"mesh\"\nfile = \"absent.obj\"\n",
    )
    .unwrap();
    let out = d.join("out.png");
    expect_failure(
        &[
            "render",
            scene.to_str().unwrap(),
            "-o",
            out.to_str().unwrap(),
        ],
        "",
        &["absent-mesh.toml", "shape[0].file", "absent.obj"],
        Some(&out),
    );
    std::fs::remove_dir_all(&d).unwrap();
}

/// A small valid OpenEXR (32-bit float RGBA, `w × h`) written by quadtex.
fn exr_bytes(w: u32, h: u32, pixel: impl Fn(u32) -> quadtex_core::Rgba) -> Vec<u8> {
    static N: std::sync::atomic::AtomicUsize = std::sync::atomic::AtomicUsize::new(0);
    let n = N.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    let d = dir(&format!("exr-src-{w}x{h}-{n}"));
    let p = d.join("ok.exr");
    let img = quadtex_io::LinearImage {
        width: w,
        height: h,
        pixels: (0..w * h).map(pixel).collect(),
    };
    quadtex_io::save_image(&p, &img).unwrap();
    let bytes = std::fs::read(&p).unwrap();
    std::fs::remove_dir_all(&d).unwrap();
    bytes
}

fn valid_exr() -> Vec<u8> {
    exr_bytes(8, 8, |i| {
        quadtex_core::Rgba::opaque((i % 8) as f32 / 8.0, 0.5, (i / 8) as f32 / 8.0)
    })
}

/// Offset of the `dataWindow` attribute's value (four little-endian `i32`:
/// x_min, y_min, x_max, y_max).
fn exr_data_window(b: &[u8]) -> usize {
    let key = b"dataWindow\0box2i\0";
    let at = b.windows(key.len()).position(|w| w == key).unwrap();
    at + key.len() + 4
}

/// The end of the EXR header (the byte after the attribute list's NUL), where
/// the offset table starts.
fn exr_header_end(b: &[u8]) -> usize {
    // Attributes: name\0 type\0 size(i32) value; the list ends with a NUL.
    let mut at = 8;
    while b[at] != 0 {
        let name_end = at + b[at..].iter().position(|&c| c == 0).unwrap();
        let type_end = name_end + 1 + b[name_end + 1..].iter().position(|&c| c == 0).unwrap();
        let size = i32::from_le_bytes(b[type_end + 1..type_end + 5].try_into().unwrap());
        at = type_end + 5 + size as usize;
    }
    at + 1
}

fn set_data_window(b: &mut [u8], window: [i32; 4]) {
    let at = exr_data_window(b);
    for (k, v) in window.iter().enumerate() {
        b[at + 4 * k..at + 4 * k + 4].copy_from_slice(&v.to_le_bytes());
    }
}

#[test]
fn exr_control_valid_file_packs() {
    // Not a bad input: the base the EXR cases alter packs.
    let d = dir("exr-good");
    let p = d.join("good.exr");
    std::fs::write(&p, valid_exr()).unwrap();
    let out = d.join("out.qtx");
    let o = run(
        &["pack", p.to_str().unwrap(), "-o", out.to_str().unwrap()],
        "",
    );
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    std::fs::remove_dir_all(&d).unwrap();
}

macro_rules! exr_cases {
    ($($name:ident: $mutate:expr => [$($needle:expr),*];)*) => {$(
        #[test]
        fn $name() {
            let mut bytes = valid_exr();
            #[allow(clippy::redundant_closure_call)]
            ($mutate)(&mut bytes);
            let file = format!("{}.exr", stringify!($name));
            pack_case(stringify!($name), &file, &bytes, &[], &[&file, $($needle),*]);
        }
    )*};
}

exr_cases! {
    exr_magic_only: |b: &mut Vec<u8>| b.truncate(4) => [];
    exr_truncated_in_header: |b: &mut Vec<u8>| { let n = exr_data_window(b); b.truncate(n + 6); } => [];
    exr_truncated_after_header: |b: &mut Vec<u8>| { let n = exr_header_end(b); b.truncate(n); } => [];
    exr_truncated_in_offset_table: |b: &mut Vec<u8>| { let n = exr_header_end(b); b.truncate(n + 12); } => [];
    exr_truncated_in_pixels: |b: &mut Vec<u8>| { let n = b.len(); b.truncate(n - n / 3); } => [];
    exr_one_byte_short: |b: &mut Vec<u8>| { b.pop(); } => [];
    exr_garbage_after_magic: |b: &mut Vec<u8>| {
        let n = b.len();
        for (i, v) in b[4..n].iter_mut().enumerate() {
            *v = (i as u32).wrapping_mul(2_654_435_761).to_be_bytes()[0];
        }
    } => [];
    exr_declares_100000_squared: |b: &mut Vec<u8>| set_data_window(b, [0, 0, 99_999, 99_999]) => ["OpenExr", "chunk count not matching data size"];
    exr_declares_2_pow_31_wide: |b: &mut Vec<u8>| set_data_window(b, [i32::MIN, 0, i32::MAX, 7]) => [];
    exr_inverted_data_window: |b: &mut Vec<u8>| set_data_window(b, [0, 0, -5, 7]) => [];
    exr_declares_30000_squared_without_pixels: |b: &mut Vec<u8>| { set_data_window(b, [0, 0, 29_999, 29_999]); let n = exr_header_end(b); b.truncate(n + 64); } => [];
    exr_offset_table_points_outside: |b: &mut Vec<u8>| {
        let n = exr_header_end(b);
        b[n..n + 8].copy_from_slice(&u64::MAX.to_le_bytes());
    } => [];
}

/// HDR texels must be finite: an EXR with a NaN or infinite texel is
/// refused, naming the file, the texel and the channel; nothing is written.
fn exr_non_finite_is_refused(case: &str, pixel: quadtex_core::Rgba, channel: &str) {
    let d = dir(case);
    let p = d.join(format!("{case}.exr"));
    let bytes = exr_bytes(4, 4, |i| {
        if i % 3 == 0 {
            pixel
        } else {
            quadtex_core::Rgba::opaque(0.25, 0.5, 0.75)
        }
    });
    std::fs::write(&p, bytes).unwrap();
    let out = d.join("out.qtx");
    let name = format!("{case}.exr");
    let needle = format!("texel (0, 0) has {channel} = ");
    expect_failure(
        &["pack", p.to_str().unwrap(), "-o", out.to_str().unwrap()],
        "",
        &[&name, &needle, "HDR texels must be finite"],
        Some(&out),
    );
    std::fs::remove_dir_all(&d).unwrap();
}

#[test]
fn exr_nan_texels_are_refused() {
    exr_non_finite_is_refused(
        "exr-nan",
        quadtex_core::Rgba::new(f32::NAN, 0.5, f32::NAN, 1.0),
        "r",
    );
}

#[test]
fn exr_nan_alpha_is_refused() {
    exr_non_finite_is_refused(
        "exr-nan-alpha",
        quadtex_core::Rgba::new(0.5, 0.5, 0.5, f32::NAN),
        "a",
    );
}

#[test]
fn exr_infinite_texels_are_refused() {
    exr_non_finite_is_refused(
        "exr-inf",
        quadtex_core::Rgba::new(f32::INFINITY, f32::NEG_INFINITY, 0.5, f32::INFINITY),
        "r",
    );
}

/// A Radiance `.hdr` packs as an HDR texture; one cut short in its pixels
/// is an error naming it.
#[test]
fn hdr_radiance_packs_and_truncated_is_refused() {
    let d = dir("hdr");
    let p = d.join("sky.hdr");
    let mut bytes = b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y 2 +X 2\n".to_vec();
    bytes.extend([128u8, 64, 32, 131].repeat(4));
    std::fs::write(&p, &bytes).unwrap();
    let out = d.join("sky.qtx");
    let o = run(
        &["pack", p.to_str().unwrap(), "-o", out.to_str().unwrap()],
        "",
    );
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let q = run(&["query", out.to_str().unwrap()], "0 0 1 1\n");
    let got: Vec<f64> = String::from_utf8_lossy(&q.stdout)
        .split_whitespace()
        .map(|v| v.parse().unwrap())
        .collect();
    assert!(
        (got[0] - 4.0).abs() < 0.05 && (got[2] - 1.0).abs() < 0.02,
        "{got:?}"
    );
    bytes.truncate(bytes.len() - 6);
    pack_case("hdr-short", "short.hdr", &bytes, &[], &["short.hdr"]);
    std::fs::remove_dir_all(&d).unwrap();
}

#[test]
fn gif_is_unsupported() {
    let mut bytes = b"GIF89a".to_vec();
    bytes.extend([2, 0, 2, 0, 0, 0, 0, 0x3b]);
    pack_case(
        "gif",
        "anim.gif",
        &bytes,
        &[],
        &["anim.gif", "not supported"],
    );
}

#[test]
fn bmp_is_unsupported() {
    let mut bytes = b"BM".to_vec();
    bytes.extend([0u8; 52]);
    pack_case("bmp", "old.bmp", &bytes, &[], &["old.bmp", "not supported"]);
}

/// A PNG chunk: length, type, data, CRC.
fn png_chunk(kind: &[u8; 4], data: &[u8]) -> Vec<u8> {
    let mut body = kind.to_vec();
    body.extend(data);
    let mut c = (data.len() as u32).to_be_bytes().to_vec();
    c.extend(&body);
    c.extend(crc32(&body).to_be_bytes());
    c
}

#[test]
fn png_ihdr_checksum_wrong() {
    let mut png = png_header_only(4, 4);
    png[29] ^= 0xff; // the IHDR CRC
    pack_case("png-crc", "crc.png", &png, &[], &["crc.png"]);
}

#[test]
fn png_invalid_bit_depth() {
    let mut png = b"\x89PNG\r\n\x1a\n".to_vec();
    let mut ihdr = 4u32.to_be_bytes().to_vec();
    ihdr.extend(4u32.to_be_bytes());
    ihdr.extend([3, 6, 0, 0, 0]); // 3-bit RGBA does not exist
    png.extend(png_chunk(b"IHDR", &ihdr));
    png.extend(png_chunk(b"IEND", &[]));
    pack_case("png-depth", "depth.png", &png, &[], &["depth.png"]);
}

#[test]
fn png_one_by_100000() {
    pack_case(
        "png-tall",
        "tall.png",
        &png_header_only(1, 100_000),
        &[],
        &["tall.png", "max_dimension"],
    );
}

#[test]
fn png_declares_30000_squared_without_pixels() {
    // Within max_dimension: the decoder must fail on the missing data
    // without first committing 3.6 GB.
    pack_case(
        "png-big-empty",
        "big.png",
        &png_header_only(30_000, 30_000),
        &[],
        &["big.png"],
    );
}

#[test]
fn png_corrupt_idat() {
    let mut png = b"\x89PNG\r\n\x1a\n".to_vec();
    let mut ihdr = 4u32.to_be_bytes().to_vec();
    ihdr.extend(4u32.to_be_bytes());
    ihdr.extend([8, 6, 0, 0, 0]);
    png.extend(png_chunk(b"IHDR", &ihdr));
    png.extend(png_chunk(
        b"IDAT",
        b"\x78\x9c this is not deflate data at all",
    ));
    png.extend(png_chunk(b"IEND", &[]));
    pack_case("png-idat", "idat.png", &png, &[], &["idat.png"]);
}

/// A baseline JPEG start: SOI, then a SOF0 declaring `w × h`, three components.
fn jpeg_sof(w: u16, h: u16) -> Vec<u8> {
    let mut j = vec![0xff, 0xd8, 0xff, 0xc0, 0, 17, 8];
    j.extend(h.to_be_bytes());
    j.extend(w.to_be_bytes());
    j.extend([3, 1, 0x11, 0, 2, 0x11, 1, 3, 0x11, 1]);
    j
}

#[test]
fn jpeg_declares_65535_squared_without_scan() {
    // Refused while reading the headers, before anything is allocated.
    pack_case(
        "jpeg-huge",
        "huge.jpg",
        &[jpeg_sof(65_535, 65_535), vec![0xff, 0xd9]].concat(),
        &[],
        &["huge.jpg", "Jpeg", "Premature End"],
    );
}

#[test]
fn jpeg_header_without_scan() {
    let mut j = jpeg_sof(16, 16);
    j.extend([0xff, 0xd9]);
    pack_case("jpeg-noscan", "noscan.jpg", &j, &[], &["noscan.jpg"]);
}

#[test]
fn jpeg_soi_then_eoi() {
    pack_case(
        "jpeg-empty",
        "empty.jpeg",
        &[0xff, 0xd8, 0xff, 0xd9],
        &[],
        &["empty.jpeg"],
    );
}

/// Renders a tiny valid scene along camera path text `path_text` with
/// `extra` arguments; expects failure naming every needle and no frames
/// directory.
fn path_case(case: &str, path_text: &str, extra: &[&str], needles: &[&str]) {
    let d = dir(case);
    let scene = d.join("scene.toml");
    std::fs::write(
        &scene,
        "[camera]\nposition = [0, 2, -10]\nlook_at = [0, 0, 10]\nfov = 50\nwidth = 16\nheight = 8\n\n[[shape]]\ntype = \"plane\"\npoint = [0, 0, 0]\nnormal = [0, 1, 0]\ntexture = \"builtin:checker\"\n",
    )
    .unwrap();
    let path = d.join(format!("{case}.path.toml"));
    std::fs::write(&path, path_text).unwrap();
    let frames = d.join("frames");
    let mut args = vec![
        "render",
        scene.to_str().unwrap(),
        "--path",
        path.to_str().unwrap(),
        "-o",
        frames.to_str().unwrap(),
    ];
    args.extend_from_slice(extra);
    expect_failure(&args, "", needles, Some(&frames));
}

const KEY_A: &str = "[[key]]\nposition = [0, 2, -10]\nlook_at = [0, 0, 10]\n";

#[test]
fn path_without_keys() {
    path_case(
        "path-empty",
        "# nothing\n",
        &["--frames", "4"],
        &["path-empty.path.toml", "key", "no [[key]]"],
    );
}

#[test]
fn path_with_times_going_back() {
    path_case(
        "path-time",
        &format!(
            "{KEY_A}time = 5\n\n[[key]]\ntime = 2\nposition = [0, 3, -5]\nlook_at = [0, 0, 10]\n"
        ),
        &["--frames", "4"],
        &[
            "path-time.path.toml:7:",
            "key[1].time: 2 does not come after key[0].time 5",
        ],
    );
}

#[test]
fn path_with_nan_and_unknown_keys() {
    path_case(
        "path-nan",
        "[[key]]\nposition = [0, nan, -10]\nlook_at = [0, 0, 10]\n",
        &["--frames", "4"],
        &["path-nan.path.toml:2:", "key[0].position", "finite"],
    );
    path_case(
        "path-zoom",
        &format!("{KEY_A}zoom = 2\n"),
        &["--frames", "4"],
        &["path-zoom.path.toml:4:", "key[0].zoom", "unknown key"],
    );
}

#[test]
fn path_with_a_degenerate_frame() {
    // The camera flies to where it looked and looks back: half-way its
    // position meets the point it looks at.
    path_case(
        "path-degenerate",
        "[[key]]\nposition = [0, 2, 0]\nlook_at = [0, 2, 10]\n\n[[key]]\nposition = [0, 2, 10]\nlook_at = [0, 2, 0]\n",
        &["--frames", "3"],
        &["camera path: frame 1 (time 0.5)", "degenerate"],
    );
}

#[test]
fn path_to_standard_output() {
    let d = dir("path-stdout");
    let path = d.join("p.path.toml");
    std::fs::write(&path, KEY_A).unwrap();
    expect_failure(
        &[
            "render",
            "scenes/checker.toml",
            "--path",
            path.to_str().unwrap(),
            "--frames",
            "2",
            "-o",
            "-",
        ],
        "",
        &["-o - is not possible"],
        None,
    );
    // --frames without --path, and zero frames, are usage errors.
    let out = run(
        &[
            "render",
            "scenes/checker.toml",
            "--frames",
            "2",
            "-o",
            "x.png",
        ],
        "",
    );
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(
        err.contains("required arguments") && err.contains("--path"),
        "{err}"
    );
    expect_usage_error(
        &[
            "render",
            "scenes/checker.toml",
            "--path",
            path.to_str().unwrap(),
            "--frames",
            "0",
            "-o",
            "frames",
        ],
        &["--frames"],
        None,
    );
}

/// A mesh beyond the memory budget: refused before its triangles are built.
fn mesh_over_budget(case: &str, obj: &[u8], memory_limit: &str, needles: &[&str]) {
    let d = dir(case);
    std::fs::write(d.join("m.obj"), obj).unwrap();
    let scene = d.join("scene.toml");
    std::fs::write(
        &scene,
        "[camera]\nposition = [0.5, 2, -1]\nlook_at = [0.5, 0, 0.5]\nfov = 50\nwidth = 16\nheight = 8\n\n[[shape]]\ntype = \"mesh\"\nfile = \"m.obj\"\ntexture = \"builtin:checker\"\n",
    )
    .unwrap();
    let out = d.join("out.png");
    expect_failure(
        &[
            "render",
            scene.to_str().unwrap(),
            "--memory-limit",
            memory_limit,
            "-o",
            out.to_str().unwrap(),
        ],
        "",
        needles,
        Some(&out),
    );
    std::fs::remove_dir_all(&d).unwrap();
}

#[test]
fn obj_many_faces_over_the_memory_budget() {
    // 25 000 identical faces, 0.3 MB of text: 8.8 MB of triangles, hierarchy and neighbours.
    mesh_over_budget(
        "obj-many-faces",
        &obj_with("", &"f 1/1 2/2 3/3\n".repeat(25_000)),
        "4M",
        &[
            "shape[0].file",
            "m.obj",
            "25002 triangles need about 8 MiB",
            "raise --memory-limit",
        ],
    );
    // One polygon of 10^6 corners, 4 MB of text: a fan of 10^6 triangles.
    mesh_over_budget(
        "obj-million-corners",
        &obj_with("", &format!("f 1/1{}\n", " 2/2 3/3 4/4".repeat(333_334))),
        "64M",
        &["m.obj", "triangles need about 335 MiB"],
    );
}

#[test]
fn gltf_malformed_and_out_of_range() {
    let d = dir("gltf");
    let good = d.join("good.glb");
    quadtex_render::write_glb(
        &good,
        &[[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 0.0, 1.0]],
        &[[0.0, 1.0], [1.0, 1.0], [1.0, 0.0]],
        &[0, 1, 2],
        None,
    )
    .unwrap();
    let bytes = std::fs::read(&good).unwrap();
    let n = bytes.len();
    let mut out_of_range = bytes.clone();
    out_of_range[n - 4..].copy_from_slice(&9u32.to_le_bytes());
    for (name, data, needle) in [
        (
            "truncated.glb",
            bytes[..n - 10].to_vec(),
            "not a valid glTF",
        ),
        (
            "index.glb",
            out_of_range,
            "index 9 out of range (3 vertices)",
        ),
    ] {
        std::fs::write(d.join(name), data).unwrap();
        let scene = d.join(format!("{name}.toml"));
        std::fs::write(
            &scene,
            format!("[camera]\nposition = [0.5, 2, -1]\nlook_at = [0.5, 0, 0.5]\nwidth = 16\nheight = 8\n\n[[shape]]\ntype = \"gltf\"\nfile = \"{name}\"\n"),
        )
        .unwrap();
        let out = d.join("out.png");
        expect_failure(
            &[
                "render",
                scene.to_str().unwrap(),
                "-o",
                out.to_str().unwrap(),
            ],
            "",
            &[&format!("{name}.toml:"), "shape[0].file", name, needle],
            Some(&out),
        );
    }
    std::fs::remove_dir_all(&d).unwrap();
}

/// Writes a `side × side` grey PNG tile at `dir/name`.
fn tile_png(dir: &Path, name: &str, side: u32) {
    let image = quadtex_io::LinearImage {
        width: side,
        height: side,
        pixels: vec![quadtex_core::Rgba::opaque(0.5, 0.5, 0.5); (side * side) as usize],
    };
    quadtex_io::save_image(&dir.join(name), &image).unwrap();
}

/// A 2×2 grid of 8×8 tiles, changed by `spoil`; `pack-tiles` must fail
/// naming every needle and write nothing.
fn tiles_case(case: &str, spoil: impl FnOnce(&Path), needles: &[&str]) {
    let d = dir(case);
    let tiles = d.join("tiles");
    std::fs::create_dir_all(&tiles).unwrap();
    for name in ["0_0.png", "0_1.png", "1_0.png", "1_1.png"] {
        tile_png(&tiles, name, 8);
    }
    spoil(&tiles);
    let out = d.join("out.qtx");
    expect_failure(
        &[
            "pack-tiles",
            tiles.to_str().unwrap(),
            "-o",
            out.to_str().unwrap(),
        ],
        "",
        needles,
        Some(&out),
    );
    std::fs::remove_dir_all(&d).unwrap();
}

#[test]
fn tiles_missing_duplicate_mismatched_and_corrupt() {
    tiles_case(
        "tiles-missing",
        |t| std::fs::remove_file(t.join("1_0.png")).unwrap(),
        &["1_0.png", "missing: a 2x2 grid needs every tile"],
    );
    tiles_case(
        "tiles-duplicate",
        |t| {
            std::fs::copy(t.join("0_1.png"), t.join("0_1.jpg"))
                .map(|_| ())
                .unwrap()
        },
        &["tile 0_1 is also"],
    );
    tiles_case(
        "tiles-size",
        |t| tile_png(t, "1_1.png", 16),
        &["1_1.png", "16x16 texels, but the first tile is 8x8"],
    );
    tiles_case(
        "tiles-corrupt",
        |t| std::fs::write(t.join("0_1.png"), b"\x89PNG\r\n\x1a\nnot really").unwrap(),
        &["0_1.png"],
    );
    tiles_case(
        "tiles-three",
        |t| tile_png(t, "2_2.png", 8),
        &["3 tiles a side: the grid must be 1, 2, 4, 8"],
    );
    tiles_case(
        "tiles-odd-side",
        |t| {
            for name in ["0_0.png", "0_1.png", "1_0.png", "1_1.png"] {
                tile_png(t, name, 6);
            }
        },
        &[
            "0_0.png",
            "6x6 texels: tiles must be squares of a power of two",
        ],
    );
    tiles_case(
        "tiles-none",
        |t| {
            for name in ["0_0.png", "0_1.png", "1_0.png", "1_1.png"] {
                std::fs::remove_file(t.join(name)).unwrap();
            }
        },
        &["no tiles named ROW_COL.png"],
    );
}

/// A valid 16x16 8-bit RGB TIFF (one LZW strip) as `spoil` leaves it.
fn tiff_bytes(spoil: impl FnOnce(&mut common::tiff_writer::Spec)) -> Vec<u8> {
    let mut spec = common::tiff_writer::Spec {
        compression: 5,
        ..common::tiff_writer::Spec::rgb8(16, 16, (0..16 * 16 * 3).map(|i| i % 251).collect())
    };
    spoil(&mut spec);
    spec.write()
}

#[test]
fn tiff_truncated() {
    let bytes = tiff_bytes(|_| {});
    pack_case(
        "tiff-trunc",
        "cut.tif",
        &bytes[..bytes.len() - 100],
        &[],
        &["cut.tif: TIFF", "the file ends early (truncated?)"],
    );
}

#[test]
fn tiff_magic_then_garbage() {
    pack_case(
        "tiff-magic",
        "garbage.tif",
        b"II*\0\xff\xff\xff\x7fnot an image file directory",
        &[],
        &["garbage.tif: TIFF header"],
    );
    // A wrong magic number: not recognised as TIFF at all.
    pack_case(
        "tiff-wrong-magic",
        "wrong.tif",
        b"II\x2a\x01 twenty-three bytes more",
        &[],
        &["wrong.tif"],
    );
}

#[test]
fn tiff_float_samples_are_unsupported() {
    let bytes = tiff_bytes(|s| {
        s.bits = 32;
        s.sample_format = Some(3);
    });
    pack_case(
        "tiff-float",
        "float.tif",
        &bytes,
        &[],
        &[
            "float.tif",
            "TIFF SampleFormat: floating-point samples are not supported",
        ],
    );
}

#[test]
fn tiff_bilevel_is_unsupported() {
    let bytes = tiff_bytes(|s| {
        s.bits = 1;
        s.samples_per_pixel = 1;
        s.photometric = 1;
    });
    pack_case(
        "tiff-bilevel",
        "fax.tif",
        &bytes,
        &[],
        &["fax.tif", "1-bit samples (bilevel) are not supported"],
    );
}

#[test]
fn tiff_declares_100000_columns() {
    let bytes = tiff_bytes(|s| s.declared_size = Some((100_000, 16)));
    pack_case(
        "tiff-huge",
        "huge.tif",
        &bytes,
        &[],
        &["huge.tif", "max_dimension"],
    );
}

/// `pack-tiles` on a TIFF it cannot read tile by tile (tiles that are not
/// square powers of two, an image within half a tile, strips): refused
/// naming the file, pointing to `pack`.
#[test]
fn tiff_tiles_not_a_mosaic() {
    for (case, w, h, tile, needle) in [
        ("rect", 64, 32, (32, 16), "TIFF tiles of 32x16 texels"),
        ("odd", 48, 48, (24, 24), "TIFF tiles of 24x24 texels"),
        ("tiny", 8, 7, (16, 16), "no larger than half a tile"),
        ("strips", 32, 32, (0, 0), "a stripped TIFF"),
    ] {
        let d = dir(&format!("tiff-mosaic-{case}"));
        let tif = d.join(format!("{case}.tif"));
        std::fs::write(
            &tif,
            tiff_bytes(|s| {
                (s.width, s.height) = (w, h);
                s.samples = vec![7; (w * h * 3) as usize];
                s.rows_per_strip = h;
                s.tile = (tile.0 > 0).then_some(tile);
            }),
        )
        .unwrap();
        let out = d.join("out.qtx");
        expect_failure(
            &[
                "pack-tiles",
                tif.to_str().unwrap(),
                "-o",
                out.to_str().unwrap(),
            ],
            "",
            &[&format!("{case}.tif"), needle, "`quadtex pack`"],
            Some(&out),
        );
        std::fs::remove_dir_all(&d).unwrap();
    }
}

/// `pack-tiles` on a file that is not a TIFF (a PNG): neither a folder of
/// tiles nor a tiled TIFF.
#[test]
fn tiles_of_a_single_png() {
    let d = dir("tiles-png-file");
    let png = valid_png(&d);
    let out = d.join("out.qtx");
    expect_failure(
        &[
            "pack-tiles",
            png.to_str().unwrap(),
            "-o",
            out.to_str().unwrap(),
        ],
        "",
        &[
            "ok.png",
            "neither a folder of ROW_COL tiles nor a tiled TIFF",
            "`quadtex pack`",
        ],
        Some(&out),
    );
    std::fs::remove_dir_all(&d).unwrap();
}

/// An SVG in `sub/` drawing `../outside.png`, or the same image by its
/// absolute path, is refused by default naming the SVG and the reference,
/// packs with `--resources anywhere`; `--resources none` refuses even an
/// image beside the SVG.
#[test]
fn svg_image_outside_its_folder() {
    let d = dir("svg-image-outside");
    let sub = d.join("sub");
    std::fs::create_dir_all(&sub).unwrap();
    let png = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/tests/resvg-suite/resources/image.png"
    );
    std::fs::copy(png, d.join("outside.png")).unwrap();
    std::fs::copy(png, sub.join("beside.png")).unwrap();
    let absolute = d.join("outside.png").to_str().unwrap().to_string();
    let out = d.join("out.qtx");
    for href in ["../outside.png", absolute.as_str()] {
        let svg = sub.join("a.svg");
        std::fs::write(
            &svg,
            format!("{SVG_HEAD}<image width=\"10\" height=\"10\" href=\"{href}\"/></svg>"),
        )
        .unwrap();
        let args = [
            "pack",
            svg.to_str().unwrap(),
            "-o",
            out.to_str().unwrap(),
            "--max-level",
            "4",
        ];
        expect_failure(
            &args,
            "",
            &[
                "a.svg",
                &format!("external resource \"{href}\" refused"),
                "--resources anywhere",
            ],
            Some(&out),
        );
        let mut wide = args.to_vec();
        wide.extend(["--resources", "anywhere"]);
        let ok = run(&wide, "");
        assert!(
            ok.status.success(),
            "{}",
            String::from_utf8_lossy(&ok.stderr)
        );
        assert!(out.exists());
        std::fs::remove_file(&out).unwrap();
    }
    let svg = sub.join("beside.svg");
    std::fs::write(
        &svg,
        format!("{SVG_HEAD}<image width=\"10\" height=\"10\" href=\"beside.png\"/></svg>"),
    )
    .unwrap();
    let args = [
        "pack",
        svg.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
        "--max-level",
        "4",
    ];
    let ok = run(&args, "");
    assert!(
        ok.status.success(),
        "{}",
        String::from_utf8_lossy(&ok.stderr)
    );
    std::fs::remove_file(&out).unwrap();
    let mut none = args.to_vec();
    none.extend(["--resources", "none"]);
    expect_failure(
        &none,
        "",
        &["beside.svg", "\"beside.png\" refused"],
        Some(&out),
    );
    expect_usage_error(
        &[&args[..], &["--resources", "everywhere"]].concat(),
        &["--resources", "same-folder, anywhere, none"],
        Some(&out),
    );
}
