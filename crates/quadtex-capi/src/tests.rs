//! The C API called as C would call it: through the exported functions,
//! with raw pointers, checking statuses and `qtx_last_error`.
#![allow(
    unsafe_code,
    clippy::undocumented_unsafe_blocks,
    clippy::multiple_unsafe_ops_per_block
)]

use std::ffi::{CStr, CString, c_char, c_int};
use std::path::{Path, PathBuf};
use std::ptr::{null, null_mut};

use quadtex_core::{BuildOptions, QuadTree, Rgba, TexelGrid};

use super::*;

fn last_error() -> Option<String> {
    let p = qtx_last_error();
    (!p.is_null()).then(|| unsafe { CStr::from_ptr(p) }.to_string_lossy().into_owned())
}

/// The last error, which must exist and contain every one of `parts`.
fn assert_error(parts: &[&str]) {
    let message = last_error().unwrap_or_default();
    for part in parts {
        assert!(
            message.contains(part),
            "error `{message}` should mention `{part}`"
        );
    }
}

fn temp_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("quadtex-capi-{}-{name}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn c_path(path: &Path) -> CString {
    CString::new(path.as_os_str().as_encoded_bytes()).unwrap()
}

fn sample(name: &str) -> CString {
    c_path(
        &Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../../samples")
            .join(name),
    )
}

/// A 2×2 black and white checkerboard (mean 0.5 grey).
fn checker_tree() -> QuadTree {
    let grid = TexelGrid::from_fn(2, 2, |c, r| {
        if (c + r) % 2 == 0 {
            Rgba::opaque(1.0, 1.0, 1.0)
        } else {
            Rgba::opaque(0.0, 0.0, 0.0)
        }
    })
    .unwrap();
    QuadTree::from_texels(&grid, &BuildOptions::default())
        .unwrap()
        .0
}

/// A texture owned by C conventions (release with `qtx_free`).
fn checker() -> *mut QtxTexture {
    ptr::into_raw(QtxTexture::new(checker_tree()))
}

/// An axis-aligned footprint `[x0, x1] × [z0, z1]`, corners in pixel order
/// (screen y down is texture z down).
fn rect(x0: f64, z0: f64, x1: f64, z1: f64) -> [f64; 8] {
    [x0, z1, x1, z1, x1, z0, x0, z0]
}

fn filter_one(texture: *const QtxTexture, quad: [f64; 8], options: &QtxFilterOptions) -> [f32; 4] {
    let mut out = [f32::NAN; 4];
    let status = unsafe { qtx_filter(texture, quad.as_ptr(), 1, options, out.as_mut_ptr()) };
    assert_eq!(status, QtxStatus::Ok, "{:?}", last_error());
    out
}

fn close(a: [f32; 4], b: [f32; 4], tolerance: f32) -> bool {
    a.iter().zip(b).all(|(x, y)| (x - y).abs() <= tolerance)
}

#[test]
fn constants_match_the_core() {
    assert_eq!(QTX_MAX_DEPTH, c_int::from(quadtex_core::MAX_DEPTH));
    assert_eq!(
        QTX_MAX_SVG_LEVEL,
        c_int::from(quadtex_core::MAX_VECTOR_LEVEL)
    );
    let d = qtx_filter_options_default();
    let (wrap, options, threads) = ops::convert_options(&d).unwrap();
    assert_eq!(threads, quadtex_core::Threads::EveryCore);
    assert_eq!(wrap, quadtex_core::Wrap::REPEAT);
    assert_eq!(options, quadtex_core::FilterOptions::default());
}

#[test]
fn null_pointers_are_refused() {
    let path = sample("threshold.svg");
    let mut out: *mut QtxTexture = std::ptr::NonNull::dangling().as_ptr();
    assert_eq!(
        unsafe { qtx_open(null(), &mut out) },
        QtxStatus::InvalidArgument
    );
    assert_error(&["path is NULL"]);
    assert!(out.is_null(), "out is cleared on failure");
    assert_eq!(
        unsafe { qtx_open(path.as_ptr(), null_mut()) },
        QtxStatus::InvalidArgument
    );
    assert_error(&["out is NULL"]);
    assert_eq!(
        unsafe { qtx_pack(null(), 0.0, 4, 0, &mut out) },
        QtxStatus::InvalidArgument
    );
    assert_error(&["path is NULL"]);
    assert_eq!(
        unsafe { qtx_pack(path.as_ptr(), 0.0, 4, 0, null_mut()) },
        QtxStatus::InvalidArgument
    );

    let texture = checker();
    let quad = rect(0.0, 0.0, 1.0, 1.0);
    let mut rgba = [0.0f32; 4];
    let filter = |t: *const QtxTexture, q: *const f64, n: usize, o: *mut f32| unsafe {
        qtx_filter(t, q, n, null(), o)
    };
    assert_eq!(
        filter(null(), quad.as_ptr(), 1, rgba.as_mut_ptr()),
        QtxStatus::InvalidArgument
    );
    assert_error(&["texture is NULL"]);
    assert_eq!(
        filter(texture, null(), 1, rgba.as_mut_ptr()),
        QtxStatus::InvalidArgument
    );
    assert_error(&["quads is NULL"]);
    assert_eq!(
        filter(texture, quad.as_ptr(), 1, null_mut()),
        QtxStatus::InvalidArgument
    );
    assert_error(&["out_rgba is NULL"]);
    // No quads: NULL buffers are fine.
    assert_eq!(filter(texture, null(), 0, null_mut()), QtxStatus::Ok);
    assert_eq!(last_error(), None);

    let mut info = std::mem::MaybeUninit::<QtxTextureInfo>::uninit();
    assert_eq!(
        unsafe { qtx_texture_info(null(), info.as_mut_ptr()) },
        QtxStatus::InvalidArgument
    );
    assert_error(&["texture is NULL"]);
    assert_eq!(
        unsafe { qtx_texture_info(texture, null_mut()) },
        QtxStatus::InvalidArgument
    );
    assert_error(&["out is NULL"]);
    unsafe {
        qtx_free(texture);
        qtx_free(null_mut());
    }
}

#[test]
fn non_finite_corners_name_the_quad_and_field() {
    let texture = checker();
    let mut quads = [rect(0.0, 0.0, 0.5, 0.5); 3];
    quads[1][5] = f64::NAN; // quad 1, corner 2, z
    let mut out = [7.0f32; 12];
    let status = unsafe { qtx_filter(texture, quads.as_ptr().cast(), 3, null(), out.as_mut_ptr()) };
    assert_eq!(status, QtxStatus::InvalidArgument);
    assert_error(&["quad 1", "corner[2].z", "NaN"]);
    assert!(out.iter().all(|&v| v == 7.0), "out untouched on failure");

    quads[1][5] = 0.5;
    quads[2][0] = f64::NEG_INFINITY; // quad 2, corner 0, x
    let status = unsafe { qtx_filter(texture, quads.as_ptr().cast(), 3, null(), out.as_mut_ptr()) };
    assert_eq!(status, QtxStatus::InvalidArgument);
    assert_error(&["quad 2", "corner[0].x", "inf"]);
    unsafe { qtx_free(texture) };
}

#[test]
fn bad_options_name_the_field() {
    let texture = checker();
    let quad = rect(0.0, 0.0, 1.0, 1.0);
    let d = qtx_filter_options_default();
    let cases: [(QtxFilterOptions, &str); 9] = [
        (QtxFilterOptions { wrap_x: 4, ..d }, "options.wrap_x"),
        (QtxFilterOptions { wrap_z: -1, ..d }, "options.wrap_z"),
        (
            QtxFilterOptions {
                border: [0.0, 0.0, f32::NAN, 1.0],
                ..d
            },
            "options.border[2]",
        ),
        (QtxFilterOptions { weighting: 2, ..d }, "options.weighting"),
        (
            QtxFilterOptions {
                error_bound: f64::NAN,
                ..d
            },
            "error bound",
        ),
        (
            QtxFilterOptions {
                error_bound: 0.0,
                ..d
            },
            "error bound",
        ),
        (QtxFilterOptions { level: 31, ..d }, "options.level"),
        (QtxFilterOptions { level: -2, ..d }, "options.level"),
        (QtxFilterOptions { threads: -1, ..d }, "options.threads"),
    ];
    for (options, field) in cases {
        let mut out = [0.0f32; 4];
        let status = unsafe { qtx_filter(texture, quad.as_ptr(), 1, &options, out.as_mut_ptr()) };
        assert_eq!(status, QtxStatus::InvalidArgument, "{field}");
        assert_error(&[field]);
    }
    // In range: accepted.
    for options in [
        QtxFilterOptions {
            level: 0,
            weighting: QtxWeighting::Texture as c_int,
            ..d
        },
        QtxFilterOptions {
            wrap_x: QtxWrapMode::Mirror as c_int,
            wrap_z: QtxWrapMode::Clamp as c_int,
            level: QTX_MAX_DEPTH,
            ..d
        },
    ] {
        filter_one(texture, quad, &options);
    }
    unsafe { qtx_free(texture) };
}

#[test]
fn overlapping_and_misaligned_buffers_are_refused() {
    let texture = checker();
    let mut quads = [rect(0.0, 0.0, 1.0, 1.0); 2];
    let base: *mut f64 = quads.as_mut_ptr().cast();
    // The colours would overwrite the second quad while it is read.
    let out = unsafe { base.add(8) }.cast::<f32>();
    assert_eq!(
        unsafe { qtx_filter(texture, base, 2, null(), out) },
        QtxStatus::InvalidArgument
    );
    assert_error(&["overlap"]);

    let bytes = [0u64; 9];
    let misaligned = unsafe { bytes.as_ptr().cast::<u8>().add(1) }.cast::<f64>();
    let mut rgba = [0.0f32; 4];
    assert_eq!(
        unsafe { qtx_filter(texture, misaligned, 1, null(), rgba.as_mut_ptr()) },
        QtxStatus::InvalidArgument
    );
    assert_error(&["quads", "aligned"]);
    // A count whose buffers cannot exist.
    assert_eq!(
        unsafe { qtx_filter(texture, base, usize::MAX / 4, null(), rgba.as_mut_ptr()) },
        QtxStatus::InvalidArgument
    );
    assert_error(&["do not fit in memory"]);
    unsafe { qtx_free(texture) };
}

#[test]
fn filtering_matches_the_texture() {
    let texture = checker();
    let d = qtx_filter_options_default();
    let mut info = std::mem::MaybeUninit::<QtxTextureInfo>::uninit();
    assert_eq!(
        unsafe { qtx_texture_info(texture, info.as_mut_ptr()) },
        QtxStatus::Ok
    );
    let info = unsafe { info.assume_init() };
    assert_eq!(info.depth, 1);
    assert!(close(info.mean, [0.5, 0.5, 0.5, 1.0], 1e-4));
    // Many whole tiles of a repeating texture: its mean.
    let many = filter_one(texture, rect(-3.0, 2.0, 13.0, 18.0), &d);
    assert!(close(many, info.mean, 1e-5), "{many:?}");
    // One texel (top-left is white: row 0 is the top, z near 1).
    let white = filter_one(texture, rect(0.0, 0.5, 0.5, 1.0), &d);
    assert!(close(white, [1.0; 4], 1e-6), "{white:?}");
    // A projective footprint inside the black texel (bottom-left).
    let black = filter_one(texture, [0.1, 0.4, 0.4, 0.45, 0.45, 0.05, 0.05, 0.1], &d);
    assert!(close(black, [0.0, 0.0, 0.0, 1.0], 1e-6), "{black:?}");
    // Border wrap: beyond the unit square, the border colour.
    let border = QtxFilterOptions {
        wrap_x: QtxWrapMode::Border as c_int,
        wrap_z: QtxWrapMode::Border as c_int,
        border: [0.1, 0.2, 0.3, 0.5],
        ..d
    };
    let outside = filter_one(texture, rect(2.0, 2.0, 3.0, 3.0), &border);
    assert!(close(outside, [0.1, 0.2, 0.3, 0.5], 1e-6), "{outside:?}");
    // Several at once, in order.
    let quads = [rect(0.0, 0.5, 0.5, 1.0), rect(0.0, 0.0, 0.5, 0.5)];
    let mut out = [0.0f32; 8];
    let status = unsafe { qtx_filter(texture, quads.as_ptr().cast(), 2, null(), out.as_mut_ptr()) };
    assert_eq!(status, QtxStatus::Ok);
    assert_eq!(out, [1.0, 1.0, 1.0, 1.0, 0.0, 0.0, 0.0, 1.0]);
    // A batch on one thread, on every core and on three: the same bits.
    let many: Vec<[f64; 8]> = (0..1000)
        .map(|i| {
            let (x, z, s) = (
                f64::from(i % 37) * 0.11,
                f64::from(i / 37) * 0.07,
                0.01 + f64::from(i % 11) * 0.3,
            );
            [
                x,
                z,
                x + s,
                z + 0.1 * s,
                x + 1.2 * s,
                z + s,
                x - 0.1 * s,
                z + 0.8 * s,
            ]
        })
        .collect();
    let batch = |threads: c_int| {
        let options = QtxFilterOptions { threads, ..d };
        let mut out = vec![0.0f32; 4 * many.len()];
        let status = unsafe {
            qtx_filter(
                texture,
                many.as_ptr().cast(),
                many.len(),
                &options,
                out.as_mut_ptr(),
            )
        };
        assert_eq!(status, QtxStatus::Ok);
        out.iter().map(|v| v.to_bits()).collect::<Vec<_>>()
    };
    let one = batch(1);
    assert_eq!(batch(0), one);
    assert_eq!(batch(3), one);
    unsafe { qtx_free(texture) };
}

#[test]
fn open_reads_qtx_files_and_reports_bad_ones() {
    let dir = temp_dir("open");
    let file = dir.join("checker.qtx");
    quadtex_io::write_qtx(&file, &checker_tree(), Some((2, 2))).unwrap();
    let mut texture = null_mut();
    assert_eq!(
        unsafe { qtx_open(c_path(&file).as_ptr(), &mut texture) },
        QtxStatus::Ok
    );
    assert!(!texture.is_null());
    assert_eq!(last_error(), None);
    let white = filter_one(
        texture,
        rect(0.0, 0.5, 0.5, 1.0),
        &qtx_filter_options_default(),
    );
    assert!(close(white, [1.0; 4], 1e-6));
    unsafe { qtx_free(texture) };

    let missing = dir.join("missing.qtx");
    assert_eq!(
        unsafe { qtx_open(c_path(&missing).as_ptr(), &mut texture) },
        QtxStatus::Io
    );
    assert_error(&["missing.qtx"]);
    assert!(texture.is_null());

    let garbage = dir.join("garbage.qtx");
    std::fs::write(&garbage, b"not a quadtree at all, just some bytes........").unwrap();
    assert_eq!(
        unsafe { qtx_open(c_path(&garbage).as_ptr(), &mut texture) },
        QtxStatus::Format
    );
    assert_error(&["garbage.qtx", "magic"]);

    let empty = CString::default();
    assert_eq!(
        unsafe { qtx_open(empty.as_ptr(), &mut texture) },
        QtxStatus::InvalidArgument
    );
    assert_error(&["path is empty"]);
    std::fs::remove_dir_all(&dir).unwrap();
}

#[cfg(unix)]
#[test]
fn non_utf8_paths_are_file_names_on_unix() {
    use std::os::unix::ffi::OsStrExt;
    let dir = temp_dir("non-utf8");
    let file = dir.join(std::ffi::OsStr::from_bytes(b"tex-\xff.qtx"));
    quadtex_io::write_qtx(&file, &checker_tree(), Some((2, 2))).unwrap();
    let mut texture = null_mut();
    assert_eq!(
        unsafe { qtx_open(c_path(&file).as_ptr(), &mut texture) },
        QtxStatus::Ok
    );
    unsafe { qtx_free(texture) };
    let missing = dir.join(std::ffi::OsStr::from_bytes(b"gone-\xfe.qtx"));
    assert_eq!(
        unsafe { qtx_open(c_path(&missing).as_ptr(), &mut texture) },
        QtxStatus::Io
    );
    assert_error(&["gone-\u{fffd}.qtx"]);
    std::fs::remove_dir_all(&dir).unwrap();
}

/// `memory_limit` (and `QtxSvgOptions::memory_limit`) is the budget
/// `--memory-limit` sets: 1 KiB refuses a 512×512 image, SVG art at level
/// 9 and a mosaic with `QTX_STATUS_LIMIT` naming the budget; 0 is the
/// detected budget, under which they pack.
#[test]
fn pack_memory_limit_refuses_work_above_it() {
    let dir = temp_dir("capi-memory-limit");
    let png = dir.join("big.png");
    let image = quadtex_io::LinearImage {
        width: 512,
        height: 512,
        pixels: (0..512 * 512)
            .map(|i| Rgba::opaque((i % 512) as f32 / 511.0, (i / 512) as f32 / 511.0, 0.5))
            .collect(),
    };
    quadtex_io::save_image(&png, &image).unwrap();
    let tiles = dir.join("tiles");
    std::fs::create_dir_all(&tiles).unwrap();
    quadtex_io::save_image(&tiles.join("0_0.png"), &image).unwrap();
    let (png, tiles, svg) = (c_path(&png), c_path(&tiles), sample("threshold.svg"));
    let mut texture = null_mut();
    for limit in [1024, 0] {
        let want = if limit == 0 {
            QtxStatus::Ok
        } else {
            QtxStatus::Limit
        };
        let status = unsafe { qtx_pack(png.as_ptr(), 0.0, -1, limit, &mut texture) };
        assert_eq!(status, want, "raster, limit {limit}: {:?}", last_error());
        if limit > 0 {
            assert_error(&["big.png", "memory budget of 1.0 KiB"]);
        }
        unsafe { qtx_free(texture) };
        let status = unsafe { qtx_pack(svg.as_ptr(), 0.0, 9, limit, &mut texture) };
        assert_eq!(status, want, "SVG, limit {limit}: {:?}", last_error());
        if limit > 0 {
            assert_error(&["threshold.svg", "memory budget of 1.0 KiB"]);
        }
        unsafe { qtx_free(texture) };
        let options = QtxSvgOptions {
            max_level: 9,
            memory_limit: limit,
            ..qtx_svg_options_default()
        };
        let status = unsafe { qtx_pack_svg(svg.as_ptr(), &options, &mut texture) };
        assert_eq!(
            status,
            want,
            "qtx_pack_svg, limit {limit}: {:?}",
            last_error()
        );
        unsafe { qtx_free(texture) };
        let status = unsafe { qtx_pack_tiles(tiles.as_ptr(), 0.0, limit, &mut texture) };
        assert_eq!(status, want, "tiles, limit {limit}: {:?}", last_error());
        if limit > 0 {
            assert_error(&["memory budget of 1.0 KiB"]);
            assert!(texture.is_null());
        }
        unsafe { qtx_free(texture) };
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

/// `QTX_LEVEL_AUTO` packs SVG art as `quadtex pack` without `--max-level`:
/// under a budget level 12 does not fit, the deepest level that fits is
/// taken; level 12 given is refused. The same through `qtx_pack_svg`.
#[test]
fn auto_svg_level_is_lowered_to_fit_the_memory_budget() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../samples/threshold.svg");
    let art = quadtex_io::load_svg(&path, &quadtex_io::SvgOptions::at_level(12)).unwrap();
    let estimates = art.estimate_bytes_per_level(12, None, None);
    let budget = estimates[10];
    assert!(estimates[11] > budget, "{estimates:?}");
    let svg = sample("threshold.svg");
    let depth = |texture: *mut QtxTexture| {
        let mut info = std::mem::MaybeUninit::<QtxTextureInfo>::uninit();
        assert_eq!(
            unsafe { qtx_texture_info(texture, info.as_mut_ptr()) },
            QtxStatus::Ok
        );
        unsafe { info.assume_init() }.depth
    };
    let mut texture = null_mut();
    let status = unsafe {
        qtx_pack(
            svg.as_ptr(),
            0.0,
            QtxLevel::Auto as c_int,
            budget,
            &mut texture,
        )
    };
    assert_eq!(status, QtxStatus::Ok, "{:?}", last_error());
    assert_eq!(depth(texture), 10);
    unsafe { qtx_free(texture) };
    let options = QtxSvgOptions {
        memory_limit: budget,
        ..qtx_svg_options_default()
    };
    let status = unsafe { qtx_pack_svg(svg.as_ptr(), &options, &mut texture) };
    assert_eq!(status, QtxStatus::Ok, "{:?}", last_error());
    assert_eq!(depth(texture), 10);
    unsafe { qtx_free(texture) };
    let status = unsafe { qtx_pack(svg.as_ptr(), 0.0, 12, budget, &mut texture) };
    assert_eq!(status, QtxStatus::Limit);
    assert_error(&["threshold.svg: packing at level 12 needs an estimated"]);
    assert!(texture.is_null());
}

#[test]
fn pack_checks_its_arguments() {
    let dir = temp_dir("pack");
    let png = dir.join("checker.png");
    quadtex_io::save_image(
        &png,
        &quadtex_io::LinearImage {
            width: 4,
            height: 4,
            pixels: (0..16)
                .map(|i| {
                    let v = ((i % 4 + i / 4) % 2) as f32;
                    Rgba::opaque(v, v, v)
                })
                .collect(),
        },
    )
    .unwrap();
    let png = c_path(&png);
    let svg = sample("threshold.svg");
    let mut texture = null_mut();
    let cases: [(&CString, f64, c_int, &str); 6] = [
        (&svg, 0.1, 4, "SVG art packs exactly"),
        (&svg, 0.0, 25, "max_level 25"),
        (&png, 2.0, -1, "tolerance must be in [0, 1]"),
        (&png, f64::NAN, -1, "tolerance must be in [0, 1]"),
        (&png, 0.0, 31, "max_level 31"),
        (&png, -0.5, 3, "tolerance"),
    ];
    for (path, tolerance, level, message) in cases {
        assert_eq!(
            unsafe { qtx_pack(path.as_ptr(), tolerance, level, 0, &mut texture) },
            QtxStatus::InvalidArgument,
            "{message}"
        );
        assert_error(&[message]);
        assert!(texture.is_null());
    }

    // A raster image, lossless at its natural depth and capped.
    assert_eq!(
        unsafe { qtx_pack(png.as_ptr(), 0.0, QtxLevel::Auto as c_int, 0, &mut texture) },
        QtxStatus::Ok
    );
    let mut info = std::mem::MaybeUninit::<QtxTextureInfo>::uninit();
    assert_eq!(
        unsafe { qtx_texture_info(texture, info.as_mut_ptr()) },
        QtxStatus::Ok
    );
    let info = unsafe { info.assume_init() };
    assert_eq!(info.depth, 2);
    assert_eq!((info.columns, info.rows), (4, 4));
    assert_eq!(info.colour_format, 1);
    assert!(
        close(info.mean, [0.5, 0.5, 0.5, 1.0], 1e-4),
        "{:?}",
        info.mean
    );
    unsafe { qtx_free(texture) };

    // SVG the exact packer refuses.
    let masked = dir.join("filter.svg");
    std::fs::write(
        &masked,
        r#"<svg xmlns="http://www.w3.org/2000/svg" viewBox="0 0 10 10">
             <filter id="f"><feGaussianBlur stdDeviation="2"/></filter>
             <rect id="r" width="10" height="10" filter="url(#f)"/></svg>"#,
    )
    .unwrap();
    assert_eq!(
        unsafe { qtx_pack(c_path(&masked).as_ptr(), 0.0, 4, 0, &mut texture) },
        QtxStatus::Unsupported
    );
    assert_error(&["filter.svg"]);
    // Not an image at all.
    let text = dir.join("notes.png");
    std::fs::write(&text, "hello").unwrap();
    assert_eq!(
        unsafe { qtx_pack(c_path(&text).as_ptr(), 0.0, -1, 0, &mut texture) },
        QtxStatus::Format
    );
    assert_error(&["notes.png"]);
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn pack_svg_sample() {
    let mut texture = null_mut();
    let svg = sample("threshold.svg");
    assert_eq!(
        unsafe { qtx_pack(svg.as_ptr(), 0.0, 6, 0, &mut texture) },
        QtxStatus::Ok,
        "{:?}",
        last_error()
    );
    let mut info = std::mem::MaybeUninit::<QtxTextureInfo>::uninit();
    assert_eq!(
        unsafe { qtx_texture_info(texture, info.as_mut_ptr()) },
        QtxStatus::Ok
    );
    assert!(unsafe { info.assume_init() }.depth <= 6);
    // Grass (#4a6b34) covers x < 21/90 from top to bottom.
    let grass = filter_one(
        texture,
        rect(0.02, 0.1, 0.2, 0.9),
        &qtx_filter_options_default(),
    );
    let lin = |v: u8| quadtex_core::srgb_decode_f32(f32::from(v) / 255.0);
    assert!(
        close(grass, [lin(0x4a), lin(0x6b), lin(0x34), 1.0], 1e-4),
        "{grass:?}"
    );
    unsafe { qtx_free(texture) };
}

/// `depth` of a texture from `qtx_texture_info`.
fn depth_of(texture: *const QtxTexture) -> u32 {
    let mut info = std::mem::MaybeUninit::<QtxTextureInfo>::uninit();
    assert_eq!(
        unsafe { qtx_texture_info(texture, info.as_mut_ptr()) },
        QtxStatus::Ok
    );
    unsafe { info.assume_init() }.depth
}

#[test]
fn pack_svg_takes_its_options_and_names_the_one_at_fault() {
    let svg = sample("threshold.svg");
    let pack = |options: Option<&QtxSvgOptions>| {
        let mut texture = null_mut();
        let options = options.map_or(std::ptr::null(), |o| o as *const QtxSvgOptions);
        let status = unsafe { qtx_pack_svg(svg.as_ptr(), options, &mut texture) };
        (status, texture)
    };
    // NULL options: as qtx_pack at QTX_LEVEL_AUTO (level 12).
    let (status, texture) = pack(None);
    assert_eq!(status, QtxStatus::Ok, "{:?}", last_error());
    assert_eq!(depth_of(texture), 12);
    unsafe { qtx_free(texture) };
    // Contour leaves answer down to level 30.
    let mut options = qtx_svg_options_default();
    options.contour_leaves = 16;
    let (status, texture) = pack(Some(&options));
    assert_eq!(status, QtxStatus::Ok, "{:?}", last_error());
    assert_eq!(depth_of(texture), 30);
    unsafe { qtx_free(texture) };
    // Each field out of range is refused by name, `out` left NULL.
    let defaults = qtx_svg_options_default();
    for (options, field) in [
        (
            QtxSvgOptions {
                contour_leaves: 2,
                ..defaults
            },
            "options.contour_leaves",
        ),
        (
            QtxSvgOptions {
                max_level: 25,
                ..defaults
            },
            "options.max_level",
        ),
        (
            QtxSvgOptions {
                max_sweep_work: 0,
                ..defaults
            },
            "options.max_sweep_work",
        ),
        (
            QtxSvgOptions {
                resources: 3,
                ..defaults
            },
            "options.resources",
        ),
    ] {
        let (status, texture) = pack(Some(&options));
        assert_eq!(status, QtxStatus::InvalidArgument, "{field}");
        assert!(texture.is_null());
        assert_error(&[field]);
    }
    // Art beyond the sweep budget: a limit, naming it (dashes piled on a
    // point, 3.9e8 steps at the default level).
    let slow =
        c_path(&Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fuzz/slow/dashed-star-15s.svg"));
    let mut texture = null_mut();
    let tight = QtxSvgOptions {
        max_sweep_work: 1_000_000,
        ..defaults
    };
    assert_eq!(
        unsafe { qtx_pack_svg(slow.as_ptr(), &tight, &mut texture) },
        QtxStatus::Limit
    );
    assert!(texture.is_null());
    assert_error(&[
        "dashed-star-15s.svg",
        "above the limit of 1000000 (max sweep work)",
    ]);
    // Not SVG.
    let png = sample("photos/astronaut.png");
    assert_eq!(
        unsafe { qtx_pack_svg(png.as_ptr(), null(), &mut texture) },
        QtxStatus::InvalidArgument
    );
    assert_error(&["astronaut.png", "qtx_pack"]);
}

/// An SVG drawing `../outside.png`: refused by default (`qtx_pack` and
/// `qtx_pack_svg`) as a limit naming the reference, packed with
/// `QTX_RESOURCES_ANYWHERE`; `QTX_RESOURCES_NONE` refuses an image beside it.
#[test]
fn pack_svg_reads_images_only_from_its_folder_by_default() {
    let dir = std::env::temp_dir().join(format!("quadtex-capi-resources-{}", std::process::id()));
    let sub = dir.join("sub");
    std::fs::create_dir_all(&sub).unwrap();
    let png =
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../../tests/resvg-suite/resources/image.png");
    std::fs::copy(&png, dir.join("outside.png")).unwrap();
    std::fs::copy(&png, sub.join("beside.png")).unwrap();
    let write = |name: &str, href: &str| {
        let file = sub.join(name);
        std::fs::write(
            &file,
            format!(
                r#"<svg xmlns="http://www.w3.org/2000/svg" viewBox="0 0 10 10"><image width="10" height="10" href="{href}"/></svg>"#
            ),
        )
        .unwrap();
        c_path(&file)
    };
    let outside = write("out.svg", "../outside.png");
    let beside = write("in.svg", "beside.png");
    let mut texture = null_mut();
    assert_eq!(
        unsafe { qtx_pack(outside.as_ptr(), 0.0, 4, 0, &mut texture) },
        QtxStatus::Limit
    );
    assert!(texture.is_null());
    assert_error(&["out.svg", "\"../outside.png\" refused"]);
    let options = |resources: QtxResources| QtxSvgOptions {
        max_level: 4,
        resources: resources as c_int,
        ..qtx_svg_options_default()
    };
    let same = options(QtxResources::SameFolder);
    assert_eq!(
        unsafe { qtx_pack_svg(outside.as_ptr(), &same, &mut texture) },
        QtxStatus::Limit
    );
    assert_eq!(
        unsafe { qtx_pack_svg(beside.as_ptr(), &same, &mut texture) },
        QtxStatus::Ok,
        "{:?}",
        last_error()
    );
    unsafe { qtx_free(texture) };
    let anywhere = options(QtxResources::Anywhere);
    assert_eq!(
        unsafe { qtx_pack_svg(outside.as_ptr(), &anywhere, &mut texture) },
        QtxStatus::Ok,
        "{:?}",
        last_error()
    );
    unsafe { qtx_free(texture) };
    let none = options(QtxResources::None);
    assert_eq!(
        unsafe { qtx_pack_svg(beside.as_ptr(), &none, &mut texture) },
        QtxStatus::Limit
    );
    assert_error(&["in.svg", "\"beside.png\" refused"]);
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn panics_become_internal_errors() {
    let status = error::guard(|| panic!("boom"));
    assert_eq!(status, QtxStatus::Internal);
    assert_error(&["internal error", "boom"]);
    // Messages with NUL bytes survive as C strings.
    let status = error::guard(|| Err(Failure::invalid("a\0b")));
    assert_eq!(status, QtxStatus::InvalidArgument);
    assert_eq!(last_error().as_deref(), Some("a?b"));
}

#[test]
fn last_error_is_per_call_and_per_thread() {
    let mut texture = null_mut();
    assert_eq!(
        unsafe { qtx_open(null::<c_char>(), &mut texture) },
        QtxStatus::InvalidArgument
    );
    assert!(last_error().is_some());
    std::thread::spawn(|| assert_eq!(last_error(), None))
        .join()
        .unwrap();
    // qtx_free keeps it; a successful call clears it.
    unsafe { qtx_free(null_mut()) };
    assert!(last_error().is_some());
    let t = checker();
    filter_one(t, rect(0.0, 0.0, 1.0, 1.0), &qtx_filter_options_default());
    assert_eq!(last_error(), None);
    unsafe { qtx_free(t) };
}

// The C entry points' share of the bad-input catalogue (tests/bad_inputs.rs
// holds the command line's): each hostile input is a status and a message
// naming the file and the problem, never a crash, and `out` stays NULL.

/// Packs `bytes` written as `dir/name` and expects `status` with every one of
/// `parts` (and the file's name) in the message.
fn pack_bytes_fails(case: &str, name: &str, bytes: &[u8], status: QtxStatus, parts: &[&str]) {
    let dir = temp_dir(case);
    let file = dir.join(name);
    std::fs::write(&file, bytes).unwrap();
    let mut texture: *mut QtxTexture = std::ptr::NonNull::dangling().as_ptr();
    assert_eq!(
        unsafe { qtx_pack(c_path(&file).as_ptr(), 0.0, -1, 0, &mut texture) },
        status,
        "{:?}",
        last_error()
    );
    assert!(texture.is_null(), "out is cleared on failure");
    assert_error(&[name]);
    assert_error(parts);
    std::fs::remove_dir_all(&dir).unwrap();
}

/// A valid `.qtx` file's bytes (the checkerboard).
fn checker_qtx_bytes(case: &str) -> Vec<u8> {
    let dir = temp_dir(case);
    let file = dir.join("ok.qtx");
    quadtex_io::write_qtx(&file, &checker_tree(), Some((2, 2))).unwrap();
    let bytes = std::fs::read(&file).unwrap();
    std::fs::remove_dir_all(&dir).unwrap();
    bytes
}

fn open_bytes_fails(case: &str, bytes: &[u8], status: QtxStatus, parts: &[&str]) {
    let dir = temp_dir(case);
    let file = dir.join(format!("{case}.qtx"));
    std::fs::write(&file, bytes).unwrap();
    let mut texture: *mut QtxTexture = std::ptr::NonNull::dangling().as_ptr();
    assert_eq!(
        unsafe { qtx_open(c_path(&file).as_ptr(), &mut texture) },
        status,
        "{:?}",
        last_error()
    );
    assert!(texture.is_null(), "out is cleared on failure");
    assert_error(&[&format!("{case}.qtx")]);
    assert_error(parts);
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn open_truncated_qtx_at_every_length() {
    let bytes = checker_qtx_bytes("trunc-src");
    for n in 0..bytes.len() {
        open_bytes_fails(
            "truncated",
            &bytes[..n],
            QtxStatus::Format,
            &["invalid .qtx"],
        );
    }
}

#[test]
fn open_bit_flipped_qtx() {
    let mut bytes = checker_qtx_bytes("flip-src");
    let n = bytes.len();
    bytes[n - 6] ^= 0x10;
    open_bytes_fails("flipped", &bytes, QtxStatus::Format, &["payload_crc"]);
    let mut bytes = checker_qtx_bytes("flip-src2");
    bytes[20] ^= 0x01;
    open_bytes_fails("flipped-header", &bytes, QtxStatus::Format, &["header_crc"]);
}

#[test]
fn open_a_directory() {
    let dir = temp_dir("open-dir");
    let mut texture: *mut QtxTexture = std::ptr::NonNull::dangling().as_ptr();
    let status = unsafe { qtx_open(c_path(&dir).as_ptr(), &mut texture) };
    assert_ne!(status, QtxStatus::Ok);
    assert_ne!(status, QtxStatus::Internal);
    assert!(texture.is_null());
    assert_error(&["open-dir"]);
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn pack_missing_file() {
    let dir = temp_dir("pack-missing");
    let mut texture: *mut QtxTexture = std::ptr::NonNull::dangling().as_ptr();
    let missing = dir.join("absent.png");
    assert_eq!(
        unsafe { qtx_pack(c_path(&missing).as_ptr(), 0.0, -1, 0, &mut texture) },
        QtxStatus::Io
    );
    assert!(texture.is_null());
    assert_error(&["absent.png"]);
    std::fs::remove_dir_all(&dir).unwrap();
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

/// A PNG whose IHDR declares `w × h`, then an empty IDAT and IEND.
fn png_header_only(w: u32, h: u32) -> Vec<u8> {
    let chunk = |kind: &[u8], data: &[u8]| {
        let mut body = kind.to_vec();
        body.extend(data);
        let mut c = (data.len() as u32).to_be_bytes().to_vec();
        c.extend(&body);
        c.extend(crc32(&body).to_be_bytes());
        c
    };
    let mut ihdr = w.to_be_bytes().to_vec();
    ihdr.extend(h.to_be_bytes());
    ihdr.extend([8, 6, 0, 0, 0]);
    let mut png = b"\x89PNG\r\n\x1a\n".to_vec();
    png.extend(chunk(b"IHDR", &ihdr));
    png.extend(chunk(b"IDAT", &[]));
    png.extend(chunk(b"IEND", &[]));
    png
}

#[test]
fn pack_png_declaring_100000_squared() {
    pack_bytes_fails(
        "pack-huge",
        "huge.png",
        &png_header_only(100_000, 100_000),
        QtxStatus::Limit,
        &["max_dimension"],
    );
}

#[test]
fn pack_png_without_pixels() {
    pack_bytes_fails(
        "pack-empty-idat",
        "empty.png",
        &png_header_only(4, 4),
        QtxStatus::Format,
        &[],
    );
}

#[test]
fn pack_truncated_png() {
    let dir = temp_dir("pack-trunc-src");
    let png = dir.join("ok.png");
    quadtex_io::save_image(
        &png,
        &quadtex_io::LinearImage {
            width: 32,
            height: 32,
            pixels: vec![Rgba::opaque(0.2, 0.4, 0.6); 1024],
        },
    )
    .unwrap();
    let bytes = std::fs::read(&png).unwrap();
    std::fs::remove_dir_all(&dir).unwrap();
    // (Cut inside IEND, the image is whole: that decodes.)
    for n in [
        8,
        20,
        33,
        bytes.len() / 4,
        bytes.len() / 2,
        bytes.len() * 3 / 4,
    ] {
        pack_bytes_fails(
            "pack-trunc",
            "trunc.png",
            &bytes[..n],
            QtxStatus::Format,
            &[],
        );
    }
}

#[test]
fn pack_radiance_hdr_packs_unclamped() {
    let dir = temp_dir("pack-hdr");
    let file = dir.join("sky.hdr");
    // RGBE (128, 64, 32, 131): 4.0, 2.0, 1.0, above 1 and kept.
    let mut bytes = b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y 2 +X 2\n".to_vec();
    bytes.extend([128u8, 64, 32, 131].repeat(4));
    std::fs::write(&file, bytes).unwrap();
    let mut texture = null_mut();
    assert_eq!(
        unsafe { qtx_pack(c_path(&file).as_ptr(), 0.0, -1, 0, &mut texture) },
        QtxStatus::Ok,
        "{:?}",
        last_error()
    );
    let mut info = std::mem::MaybeUninit::<QtxTextureInfo>::uninit();
    assert_eq!(
        unsafe { qtx_texture_info(texture, info.as_mut_ptr()) },
        QtxStatus::Ok
    );
    assert_eq!(unsafe { info.assume_init() }.colour_format, 2);
    let c = filter_one(
        texture,
        rect(0.0, 0.0, 1.0, 1.0),
        &qtx_filter_options_default(),
    );
    assert!(close(c, [4.0, 2.0, 1.0, 1.0], 2e-2), "{c:?}");
    unsafe { qtx_free(texture) };
    std::fs::remove_dir_all(&dir).unwrap();
}

/// HDR texels must be finite: a NaN or infinite one is refused, naming the
/// file and the texel (never clamped into the texture).
#[test]
fn pack_exr_with_non_finite_texels_is_refused() {
    let dir = temp_dir("pack-exr-nan");
    let exr = dir.join("nan.exr");
    let pixels = (0..16)
        .map(|i| match i {
            5 => Rgba::new(0.5, f32::NAN, 0.5, 1.0),
            _ => Rgba::opaque(0.25, 0.5, 0.75),
        })
        .collect();
    quadtex_io::save_image(
        &exr,
        &quadtex_io::LinearImage {
            width: 4,
            height: 4,
            pixels,
        },
    )
    .unwrap();
    let mut texture: *mut QtxTexture = std::ptr::NonNull::dangling().as_ptr();
    assert_eq!(
        unsafe { qtx_pack(c_path(&exr).as_ptr(), 0.0, -1, 0, &mut texture) },
        QtxStatus::Format
    );
    assert!(texture.is_null());
    assert_error(&["nan.exr", "texel (1, 1) has g = NaN"]);
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn pack_empty_path_and_no_image() {
    let mut texture: *mut QtxTexture = std::ptr::NonNull::dangling().as_ptr();
    let empty = CString::default();
    assert_eq!(
        unsafe { qtx_pack(empty.as_ptr(), 0.0, -1, 0, &mut texture) },
        QtxStatus::InvalidArgument
    );
    assert_error(&["path is empty"]);
    assert!(texture.is_null());
    pack_bytes_fails("pack-empty", "empty.png", b"", QtxStatus::Format, &[]);
}

#[test]
fn filter_rejects_every_non_finite_coordinate() {
    let texture = checker();
    for field in 0..8 {
        for bad in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
            let mut quads = [rect(0.0, 0.0, 0.5, 0.5); 2];
            quads[1][field] = bad;
            let mut out = [7.0f32; 8];
            let status =
                unsafe { qtx_filter(texture, quads.as_ptr().cast(), 2, null(), out.as_mut_ptr()) };
            assert_eq!(status, QtxStatus::InvalidArgument);
            let axis = if field % 2 == 0 { "x" } else { "z" };
            assert_error(&["quad 1", &format!("corner[{}].{axis}", field / 2)]);
            assert!(out.iter().all(|&v| v == 7.0), "out untouched on failure");
        }
    }
    unsafe { qtx_free(texture) };
}

/// `qtx_filter_with_bounds` gives each quad's bound (at most the error
/// bound asked for under the defaults); bow ties and coordinates beyond
/// 1e15 are invalid arguments naming the quad; overlapping outputs too.
#[test]
fn filter_with_bounds_reports_each_bound_and_refuses_bow_ties() {
    let texture = checker();
    let quads = [
        rect(0.1, 0.1, 0.9, 0.8),
        [0.1, 0.4, 0.4, 0.45, 0.45, 0.05, 0.05, 0.1],
        rect(-1e15, -1e15, 1e15, 1e15),
    ];
    let (mut out, mut bounds) = ([f32::NAN; 12], [f64::NAN; 3]);
    let status = unsafe {
        qtx_filter_with_bounds(
            texture,
            quads.as_ptr().cast(),
            3,
            null(),
            out.as_mut_ptr(),
            bounds.as_mut_ptr(),
        )
    };
    assert_eq!(status, QtxStatus::Ok, "{:?}", last_error());
    assert!(
        bounds.iter().all(|&b| (0.0..=1.0 / 512.0).contains(&b)),
        "{bounds:?}"
    );
    // The same colours as `qtx_filter`.
    let mut plain = [f32::NAN; 12];
    let status = unsafe {
        qtx_filter(
            texture,
            quads.as_ptr().cast(),
            3,
            null(),
            plain.as_mut_ptr(),
        )
    };
    assert_eq!(status, QtxStatus::Ok);
    assert_eq!(out, plain);
    // The whole plane: the checker's mean.
    assert!(
        close(out[8..].try_into().unwrap(), [0.5, 0.5, 0.5, 1.0], 1e-4),
        "{out:?}"
    );
    for (bad, words) in [
        ([0.0, 0.0, 1.0, 0.0, 0.0, 1.0, 1.0, 1.0], "bow tie"),
        (rect(0.0, 0.0, 1e20, 1.0), "MAX_TEXTURE_COORDINATE"),
    ] {
        let quads = [rect(0.0, 0.0, 0.5, 0.5), bad];
        let mut out = [7.0f32; 8];
        let status = unsafe {
            qtx_filter_with_bounds(
                texture,
                quads.as_ptr().cast(),
                2,
                null(),
                out.as_mut_ptr(),
                bounds.as_mut_ptr(),
            )
        };
        assert_eq!(status, QtxStatus::InvalidArgument);
        assert_error(&["quad 1", words]);
        assert!(out.iter().all(|&v| v == 7.0), "out untouched on failure");
    }
    let mut shared = [0.0f64; 8];
    let status = unsafe {
        qtx_filter_with_bounds(
            texture,
            quads.as_ptr().cast(),
            1,
            null(),
            shared.as_mut_ptr().cast(),
            shared.as_mut_ptr().wrapping_add(1),
        )
    };
    assert_eq!(status, QtxStatus::InvalidArgument);
    assert_error(&["out_rgba and out_bounds overlap"]);
    unsafe { qtx_free(texture) };
}

#[test]
fn texture_info_and_filter_after_failed_open_are_refused() {
    // What C code that ignores the status would do: use the NULL `out`.
    let mut texture: *mut QtxTexture = std::ptr::NonNull::dangling().as_ptr();
    let missing = CString::new("/nonexistent/quadtex/none.qtx").unwrap();
    assert_eq!(
        unsafe { qtx_open(missing.as_ptr(), &mut texture) },
        QtxStatus::Io
    );
    assert!(texture.is_null());
    let mut info = std::mem::MaybeUninit::<QtxTextureInfo>::uninit();
    assert_eq!(
        unsafe { qtx_texture_info(texture, info.as_mut_ptr()) },
        QtxStatus::InvalidArgument
    );
    assert_error(&["texture is NULL"]);
    let quad = rect(0.0, 0.0, 1.0, 1.0);
    let mut rgba = [0.0f32; 4];
    assert_eq!(
        unsafe { qtx_filter(texture, quad.as_ptr(), 1, null(), rgba.as_mut_ptr()) },
        QtxStatus::InvalidArgument
    );
    assert_error(&["texture is NULL"]);
    unsafe { qtx_free(texture) };
}

#[test]
fn tiles_pack_like_the_whole_mosaic_and_bad_tiles_are_named() {
    let dir = temp_dir("capi-tiles");
    let tiles = dir.join("tiles");
    std::fs::create_dir_all(&tiles).unwrap();
    // An 8×8 mosaic of 4×4 tiles: a colour per texel.
    let colour = |x: u32, y: u32| quadtex_core::Rgba::opaque(x as f32 / 7.0, y as f32 / 7.0, 0.5);
    let whole = quadtex_io::LinearImage {
        width: 8,
        height: 8,
        pixels: (0..64).map(|k| colour(k % 8, k / 8)).collect(),
    };
    quadtex_io::save_image(&dir.join("whole.png"), &whole).unwrap();
    for row in 0..2 {
        for col in 0..2 {
            let tile = quadtex_io::LinearImage {
                width: 4,
                height: 4,
                pixels: (0..16)
                    .map(|k| colour(4 * col + k % 4, 4 * row + k / 4))
                    .collect(),
            };
            quadtex_io::save_image(&tiles.join(format!("{row}_{col}.png")), &tile).unwrap();
        }
    }
    let (mut a, mut b) = (null_mut(), null_mut());
    assert_eq!(
        unsafe { qtx_pack_tiles(c_path(&tiles).as_ptr(), 0.0, 0, &mut a) },
        QtxStatus::Ok,
        "{:?}",
        last_error()
    );
    assert_eq!(
        unsafe { qtx_pack(c_path(&dir.join("whole.png")).as_ptr(), 0.0, -1, 0, &mut b) },
        QtxStatus::Ok
    );
    let options = qtx_filter_options_default();
    for r in [
        rect(0.0, 0.0, 1.0, 1.0),
        rect(0.1, 0.3, 0.6, 0.9),
        rect(0.5, 0.0, 0.75, 0.25),
    ] {
        assert_eq!(filter_one(a, r, &options), filter_one(b, r, &options));
    }
    unsafe {
        qtx_free(a);
        qtx_free(b);
    }
    std::fs::remove_file(tiles.join("1_0.png")).unwrap();
    let mut t: *mut QtxTexture = std::ptr::NonNull::dangling().as_ptr();
    assert_eq!(
        unsafe { qtx_pack_tiles(c_path(&tiles).as_ptr(), 0.0, 0, &mut t) },
        QtxStatus::Format
    );
    assert!(t.is_null());
    assert_error(&["1_0.png", "missing"]);
    assert_eq!(
        unsafe { qtx_pack_tiles(null(), 0.0, 0, &mut t) },
        QtxStatus::InvalidArgument
    );
    assert_eq!(
        unsafe { qtx_pack_tiles(c_path(&tiles).as_ptr(), 1.5, 0, &mut t) },
        QtxStatus::InvalidArgument
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

/// A mapped texture filters as an opened one; a corrupt colour is refused
/// mapped, opens mapped unverified but fails `qtx_verify`; NULL is refused.
#[test]
fn mapped_open_and_verify() {
    let dir = temp_dir("mapped");
    let file = dir.join("checker.qtx");
    quadtex_io::write_qtx(&file, &checker_tree(), Some((2, 2))).unwrap();
    let mut texture = null_mut();
    assert_eq!(
        unsafe { qtx_open_mapped(c_path(&file).as_ptr(), &mut texture) },
        QtxStatus::Ok
    );
    assert_eq!(unsafe { qtx_verify(texture) }, QtxStatus::Ok);
    let white = filter_one(
        texture,
        rect(0.0, 0.5, 0.5, 1.0),
        &qtx_filter_options_default(),
    );
    assert!(close(white, [1.0; 4], 1e-6));
    unsafe { qtx_free(texture) };

    // The root's alpha zeroed (node 0's colour is the first 8 colour bytes).
    let mut bytes = std::fs::read(&file).unwrap();
    let nodes = u64::from_le_bytes(bytes[32..40].try_into().unwrap()) as usize;
    let root = 64 + nodes.div_ceil(8);
    bytes[root + 6..root + 8].fill(0);
    std::fs::write(&file, &bytes).unwrap();
    assert_eq!(
        unsafe { qtx_open_mapped(c_path(&file).as_ptr(), &mut texture) },
        QtxStatus::Format
    );
    assert!(texture.is_null());
    assert_error(&["checker.qtx", "payload_crc", "colours (bytes"]);
    assert_eq!(
        unsafe { qtx_open_mapped_unverified(c_path(&file).as_ptr(), &mut texture) },
        QtxStatus::Ok
    );
    assert_eq!(unsafe { qtx_verify(texture) }, QtxStatus::Format);
    assert_error(&["node 0"]);
    unsafe { qtx_free(texture) };
    assert_eq!(unsafe { qtx_verify(null()) }, QtxStatus::InvalidArgument);
    assert_eq!(
        unsafe { qtx_open(c_path(&file).as_ptr(), &mut texture) },
        QtxStatus::Format
    );
    assert_error(&["checker.qtx", "payload_crc"]);
    std::fs::remove_dir_all(&dir).unwrap();
}

/// One to three bits flipped at random in the colours of 50 copies of a
/// packed file: `qtx_open` and `qtx_open_mapped` refuse every copy, the
/// message naming the file and the payload checksum.
#[test]
fn flipped_colour_bits_are_refused_by_every_open() {
    let dir = temp_dir("flips");
    let good_file = dir.join("good.qtx");
    let g = quadtex_core::synth::runway_art().rasterise(32, 32).unwrap();
    let (tree, _) = QuadTree::from_texels(&g, &BuildOptions::default()).unwrap();
    quadtex_io::write_qtx(&good_file, &tree, None).unwrap();
    let good = std::fs::read(&good_file).unwrap();
    let nodes = tree.node_count() as usize;
    let colours = 64 + nodes.div_ceil(8);
    let mut rng = 0x9E37_79B9_7F4A_7C15_u64;
    for copy in 0..50 {
        let mut bytes = good.clone();
        let mut flipped = Vec::new();
        while flipped.len() < 1 + copy % 3 {
            rng ^= rng << 13;
            rng ^= rng >> 7;
            rng ^= rng << 17;
            let bit = (rng % (64 * nodes as u64)) as usize;
            if !flipped.contains(&bit) {
                flipped.push(bit);
                bytes[colours + bit / 8] ^= 1 << (bit % 8);
            }
        }
        let name = format!("flip{copy}.qtx");
        let file = dir.join(&name);
        std::fs::write(&file, &bytes).unwrap();
        for open in [qtx_open, qtx_open_mapped] {
            let mut texture = null_mut();
            assert_eq!(
                unsafe { open(c_path(&file).as_ptr(), &mut texture) },
                QtxStatus::Format,
                "{name}: {flipped:?}"
            );
            assert!(texture.is_null());
            assert_error(&[&name, "payload_crc"]);
        }
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn memory_refusals_are_limits() {
    use quadtex_core::Error as E;
    let budget = E::MemoryBudget {
        what: "packing at level 20".into(),
        estimate: 10 << 30,
        budget: 4 << 30,
        knobs: "lower max_level",
    };
    let refused = E::AllocationFailed {
        what: "the node array".into(),
        bytes: 1 << 40,
    };
    for e in [budget, refused] {
        let message = e.to_string();
        let failure = Failure::from(e);
        assert_eq!(failure.status, QtxStatus::Limit, "{message}");
        assert_eq!(failure.message, message);
    }
    // Other refusals keep their own status.
    let bad = quadtex_core::Error::BadTolerance(f64::NAN);
    assert_eq!(Failure::from(bad).status, QtxStatus::InvalidArgument);
}
