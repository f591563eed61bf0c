//! Rendering against references: a grazing checkerboard against a supersampled
//! box-filtered reference, averages of uniform regions, the horizon, and
//! determinism across thread counts.
#![allow(clippy::unwrap_used, clippy::expect_used)]

#[path = "common/scenes.rs"]
mod scenes;

use std::path::Path;

use quadtex_render::{PixelFilter, RenderOptions, Scene, TextureFilter, parse_scene, render};
use scenes::{grazing, render_with};

/// RMSE of the red channel over rows `from..` (row-major images of equal size).
fn rmse(a: &[quadtex_core::Rgba], b: &[quadtex_core::Rgba], width: usize, from: usize) -> f64 {
    let (a, b) = (&a[from * width..], &b[from * width..]);
    let s: f64 = a
        .iter()
        .zip(b)
        .map(|(p, q)| f64::from(p.r - q.r).powi(2))
        .sum();
    (s / a.len() as f64).sqrt()
}

#[test]
fn grazing_checkerboard_matches_a_supersampled_box_reference() {
    let scene = grazing(48, 32, 1.5);
    let options = |filter| RenderOptions {
        filter,
        ..RenderOptions::default()
    };
    let (exact, _) = render(&scene, &options(TextureFilter::default()), &|_, _| {}).unwrap();
    // 32×32 = 1024 stratified samples per pixel: the same box pixel filter.
    let (reference, _) =
        render(&scene, &options(TextureFilter::Supersample(32)), &|_, _| {}).unwrap();
    let (nearest, _) = render(&scene, &options(TextureFilter::Nearest), &|_, _| {}).unwrap();
    // Compare texture filtering where pixels lie wholly on the plane: the row
    // straddling the horizon (y = 16·(1 − tan(atan(1.5/40))/tan 15°) = 13.76)
    // is part sky, a silhouette the texture filter does not handle.
    let horizon = 16.0 * (1.0 - (1.5f64 / 40.0) / 15f64.to_radians().tan());
    let first = horizon.floor() as usize + 1;
    assert_eq!(first, 14);
    let e = rmse(&exact.pixels, &reference.pixels, 48, first);
    let n = rmse(&nearest.pixels, &reference.pixels, 48, first);
    // Tolerance: the reference's own noise (1024 samples per pixel of a
    // two-level texture: σ ≤ 0.5·0.55/32 ≈ 0.0086 per pixel) plus the
    // quadtree's own error against a 4096-sample reference (≈ 0.007: density
    // taken constant within a strip, strips' area mismatch).
    assert!(e < 0.013, "quadtree vs reference RMSE {e}");
    assert!(
        n > 3.0 * e,
        "point sampling should alias far more: nearest {n} vs quadtree {e}"
    );
}

#[test]
fn horizon_converges_to_the_mean_grey() {
    let scene = grazing(64, 48, 1.0);
    let converged = RenderOptions {
        filter: quadtex_render::TextureFilter::Quadtree(
            quadtex_core::FilterOptions::default()
                .with_error_bound(1e-4)
                .unwrap()
                .with_budget(1 << 16)
                .unwrap(),
        ),
        ..RenderOptions::default()
    };
    let (img, summary) = render(&scene, &converged, &|_, _| {}).unwrap();
    let (fast, _) = render(&scene, &RenderOptions::default(), &|_, _| {}).unwrap();
    assert!(summary.textured_pixels > 0);
    // The horizon is at row 21.8 (pitch 1.43° below level, 15° half field of
    // view). The two rows below it see footprints many squares long and wide,
    // so they show the mean (0.6 + 0.05)/2, not moiré: within 0.025 (the
    // exact box over a footprint a few squares wide keeps up to 0.021 of
    // the checker, measured), and within 0.05 of that at the default
    // budget of squares (measured up to 0.042: these pixels spend all of
    // it; `--budget 1024` brings it under 0.005).
    let mean = (0.6 + 0.05) / 2.0;
    for row in [22, 23] {
        for x in 0..64 {
            let p = img.pixels[row * 64 + x];
            assert!(
                (f64::from(p.r) - mean).abs() < 0.025,
                "pixel ({x},{row}) = {}",
                p.r
            );
            let q = fast.pixels[row * 64 + x];
            assert!(
                (p.r - q.r).abs() < 0.05,
                "pixel ({x},{row}): {} at the default budget vs {}",
                q.r,
                p.r
            );
        }
    }
}

fn panel_scene(shape: &str) -> Scene {
    let dir = concat!(env!("CARGO_MANIFEST_DIR"), "/../../scenes");
    let text = format!(
        "[camera]\nposition = [3, 5, 20]\nlook_at = [0, 2, 0]\nfov = 50\nwidth = 96\nheight = 48\n\n[[shape]]\n{shape}\ntexture = \"builtin:sign\"\nwrap = \"clamp\"\n"
    );
    parse_scene(
        &text,
        &Path::new(dir).join("panel.toml"),
        &quadtex_io::Limits::default(),
    )
    .unwrap()
}

#[test]
fn obj_mesh_renders_like_the_same_quad() {
    let mesh = panel_scene("type = \"mesh\"\nfile = \"sign.obj\"");
    let quad = panel_scene(
        "type = \"quad\"\norigin = [-8, 0, 0]\nedge_u = [16, 0, 0]\nedge_v = [0, 4, 0]\nuv_scale = [1, 0.25]",
    );
    // Both converged (the seam splits a pixel into two regions, each with
    // its own budget, so at the default budget the two differ within their
    // reported bounds: measured up to 0.01).
    let options = RenderOptions {
        filter: quadtex_render::TextureFilter::Quadtree(
            quadtex_core::FilterOptions::default()
                .with_error_bound(1e-6)
                .unwrap()
                .with_budget(1 << 20)
                .unwrap(),
        ),
        ..RenderOptions::default()
    };
    let (a, sa) = render(&mesh, &options, &|_, _| {}).unwrap();
    let (b, _) = render(&quad, &options, &|_, _| {}).unwrap();
    assert!(
        sa.textured_pixels > 200,
        "the panel must fill part of the frame: {}",
        sa.textured_pixels
    );
    let worst = a
        .pixels
        .iter()
        .zip(&b.pixels)
        .map(|(p, q)| (p.r - q.r).abs().max((p.g - q.g).abs()))
        .fold(0f32, f32::max);
    assert!(worst < 1e-3, "mesh and quad differ by {worst}");
}

#[test]
fn bad_meshes_name_the_problem() {
    let dir = std::env::temp_dir().join(format!("quadtex-mesh-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::write(dir.join("nouv.obj"), "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n").unwrap();
    let text = "[camera]\nposition = [0, 0, 5]\nlook_at = [0, 0, 0]\nwidth = 8\nheight = 8\n\n[[shape]]\ntype = \"mesh\"\nfile = \"nouv.obj\"\n";
    let e = parse_scene(text, &dir.join("s.toml"), &quadtex_io::Limits::default())
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("shape[0].file") && e.contains("no texture coordinates"),
        "{e}"
    );
    let e = parse_scene(
        &text.replace("nouv.obj", "absent.obj"),
        &dir.join("s.toml"),
        &quadtex_io::Limits::default(),
    )
    .unwrap_err()
    .to_string();
    assert!(
        e.contains("shape[0].file") && e.contains("absent.obj"),
        "{e}"
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn tent_pixel_filter_matches_a_tent_weighted_supersampled_reference() {
    let scene = grazing(48, 32, 1.5);
    let options = |filter| RenderOptions {
        filter,
        pixel_filter: PixelFilter::Tent,
        ..RenderOptions::default()
    };
    let (tent, _) = render(&scene, &options(TextureFilter::default()), &|_, _| {}).unwrap();
    // 64×64 samples: tent weights leave ~45% effective samples, so 1024 would
    // be as noisy (σ ≈ 0.016) as the error we want to bound.
    let (reference, _) =
        render(&scene, &options(TextureFilter::Supersample(64)), &|_, _| {}).unwrap();
    let (boxed, _) = render(&scene, &RenderOptions::default(), &|_, _| {}).unwrap();
    // Rows whose 2×2-pixel support lies wholly below the horizon (y = 13.76).
    let e = rmse(&tent.pixels, &reference.pixels, 48, 15);
    assert!(e < 0.011, "tent vs tent reference RMSE {e}");
    // The tent is a different filter: it must not simply equal the box.
    let d = rmse(&tent.pixels, &boxed.pixels, 48, 15);
    assert!(d > 0.005, "tent and box images should differ, RMSE {d}");
}

#[test]
fn quadtree_beats_trilinear_and_ewa_at_a_grazing_angle() {
    let scene = grazing(48, 32, 1.5);
    let go = |filter| render_with(&scene, filter);
    let reference = go(TextureFilter::Supersample(32));
    let error = |filter| rmse(&go(filter).pixels, &reference.pixels, 48, 14);
    let quadtree = error(TextureFilter::default());
    let trilinear = error(TextureFilter::Trilinear);
    let ewa = error(TextureFilter::Ewa {
        max_anisotropy: 8.0,
    });
    let sat = error(TextureFilter::Sat(
        quadtex_core::baseline::StripOptions::default(),
    ));
    assert!(
        quadtree < trilinear && quadtree < ewa,
        "quadtree {quadtree}, trilinear {trilinear}, EWA {ewa}"
    );
    // The SAT integrates strips that over-cover the footprint; the exact
    // polygon integral must not lose to it (measured: 0.0036 against
    // 0.0066 here).
    assert!(quadtree < sat, "SAT {sat} vs quadtree {quadtree}");
    eprintln!(
        "RMSE vs 1024-sample reference: quadtree {quadtree:.4}, SAT {sat:.4}, trilinear {trilinear:.4}, EWA {ewa:.4}"
    );
}

/// The render summary's figures on cases with known answers: looking
/// straight down at a magnified checker, every textured pixel is one region
/// integrated exactly (bound 0), and the summary says nothing of bounds;
/// the summed-area baseline's strips over a square footprint over-cover it
/// by exactly 0; on a grazing view the mean bound is at most the largest.
#[test]
fn summary_figures_have_known_values() {
    let down = r#"
[camera]
position = [0.3, 4, 0.2]
look_at = [0.3, 0, 0.2001]
fov = 30
width = 40
height = 30

[[shape]]
type = "plane"
point = [0, 0, 0]
normal = [0, 1, 0]
texture = "builtin:checker"
uv_scale = [0.5, 0.5]
"#;
    let scene = parse_scene(down, Path::new("down.toml"), &quadtex_io::Limits::default()).unwrap();
    let (_, s) = render(&scene, &RenderOptions::default(), &|_, _| {}).unwrap();
    assert_eq!(s.textured_pixels, 40 * 30);
    assert_eq!(s.filter.fragments, 40 * 30, "one region per pixel");
    assert_eq!(s.filter.max_error_bound, 0.0);
    let text = s.to_string();
    assert!(
        text.contains("1.00 regions") && !text.contains("bound") && !text.contains("mismatch"),
        "{text}"
    );

    let sat = RenderOptions {
        filter: TextureFilter::Sat(quadtex_core::baseline::StripOptions::default()),
        ..RenderOptions::default()
    };
    let (_, s) = render(&scene, &sat, &|_, _| {}).unwrap();
    // Looking straight down, footprints are squares up to the perspective
    // of a 30° field of view on a flat plane: trapezoids a hair off square
    // (measured excess 8.7e-6), where a diagonal footprint's strips
    // over-cover by up to 25 %.
    assert!(
        s.filter.max_mismatch < 1e-4,
        "square footprints: {}",
        s.filter.max_mismatch
    );

    let (_, s) = render(&grazing(64, 48, 1.0), &RenderOptions::default(), &|_, _| {}).unwrap();
    let mean = s.filter.sum_error_bound / s.textured_pixels as f64;
    assert!(mean > 0.0 && mean <= s.filter.max_error_bound, "{s:?}");
    assert!(s.to_string().contains("error bound per textured pixel"));
}

/// Tent and Mitchell, converged (a tight bound and a large budget), against
/// two 4096-sample filter-weighted references drawn from different streams:
/// within the references' own noise (their difference over √2). Measured:
/// tent 0.00166–0.00174 against noise 0.00167; Mitchell 0.0038–0.0040
/// against 0.0040. At the default budget the rows next to the horizon add
/// their unrefined error (tent 0.0051).
#[test]
fn tent_and_mitchell_converge_within_reference_noise() {
    let scene = grazing(48, 32, 1.5);
    let converged = TextureFilter::Quadtree(
        quadtex_core::FilterOptions::default()
            .with_budget(1 << 16)
            .unwrap()
            .with_error_bound(1e-4)
            .unwrap(),
    );
    for (pf, first) in [(PixelFilter::Tent, 15), (PixelFilter::Mitchell, 16)] {
        let options = |filter, seed| RenderOptions {
            filter,
            pixel_filter: pf,
            seed,
            ..RenderOptions::default()
        };
        let (exact, _) = render(&scene, &options(converged, 0), &|_, _| {}).unwrap();
        let (r1, _) = render(
            &scene,
            &options(TextureFilter::Supersample(64), 11),
            &|_, _| {},
        )
        .unwrap();
        let (r2, _) = render(
            &scene,
            &options(TextureFilter::Supersample(64), 22),
            &|_, _| {},
        )
        .unwrap();
        let noise = rmse(&r1.pixels, &r2.pixels, 48, first) / 2f64.sqrt();
        for r in [&r1, &r2] {
            let e = rmse(&exact.pixels, &r.pixels, 48, first);
            assert!(e < 1.3 * noise, "{pf:?}: {e} against noise {noise}");
        }
    }
}

/// A 4×2 PNG (8-bit RGB), row 0 at the top.
fn small_png() -> Vec<u8> {
    let texels: Vec<quadtex_core::Rgba> = (0..8)
        .map(|i| {
            let c = [
                [1.0, 0.0, 0.0],
                [0.0, 1.0, 0.0],
                [0.0, 0.0, 1.0],
                [1.0, 1.0, 1.0],
                [0.2, 0.2, 0.2],
                [1.0, 1.0, 0.0],
                [0.0, 1.0, 1.0],
                [1.0, 0.0, 1.0],
            ][i];
            quadtex_core::Rgba::opaque(c[0], c[1], c[2])
        })
        .collect();
    let image = quadtex_io::LinearImage {
        width: 4,
        height: 2,
        pixels: texels,
    };
    let mut bytes = Vec::new();
    quadtex_io::write_image(
        &mut bytes,
        Path::new("small.png"),
        &image,
        quadtex_io::ImageFormat::Png,
    )
    .unwrap();
    bytes
}

#[test]
fn gltf_mesh_renders_like_the_same_quad() {
    let dir = std::env::temp_dir().join(format!("quadtex-gltf-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let png = small_png();
    std::fs::write(dir.join("small.png"), &png).unwrap();
    // The sign panel's quad as two triangles; glTF's v runs down the image.
    quadtex_render::write_glb(
        &dir.join("panel.glb"),
        &[
            [-8.0, 0.0, 0.0],
            [8.0, 0.0, 0.0],
            [8.0, 4.0, 0.0],
            [-8.0, 4.0, 0.0],
        ],
        &[[0.0, 1.0], [1.0, 1.0], [1.0, 0.0], [0.0, 0.0]],
        &[0, 1, 2, 0, 2, 3],
        Some(&png),
    )
    .unwrap();
    let scene = |shape: &str| {
        let text = format!(
            "[camera]\nposition = [3, 5, 20]\nlook_at = [0, 2, 0]\nfov = 50\nwidth = 96\nheight = 48\n\n[[shape]]\n{shape}\n"
        );
        parse_scene(&text, &dir.join("s.toml"), &quadtex_io::Limits::default()).unwrap()
    };
    let gltf = scene("type = \"gltf\"\nfile = \"panel.glb\"");
    let quad = scene(
        "type = \"quad\"\norigin = [-8, 0, 0]\nedge_u = [16, 0, 0]\nedge_v = [0, 4, 0]\ntexture = \"small.png\"\nwrap = \"clamp\"",
    );
    assert_eq!(gltf.surfaces.len(), 1);
    let options = RenderOptions {
        filter: quadtex_render::TextureFilter::Quadtree(
            quadtex_core::FilterOptions::default()
                .with_error_bound(1e-6)
                .unwrap()
                .with_budget(1 << 20)
                .unwrap(),
        ),
        ..RenderOptions::default()
    };
    let (a, sa) = render(&gltf, &options, &|_, _| {}).unwrap();
    let (b, _) = render(&quad, &options, &|_, _| {}).unwrap();
    assert!(sa.textured_pixels > 200, "{}", sa.textured_pixels);
    let worst = a
        .pixels
        .iter()
        .zip(&b.pixels)
        .map(|(p, q)| {
            (p.r - q.r)
                .abs()
                .max((p.g - q.g).abs())
                .max((p.b - q.b).abs())
        })
        .fold(0f32, f32::max);
    assert!(worst < 1e-3, "glTF and quad differ by {worst}");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn bad_gltf_files_name_the_problem() {
    let dir = std::env::temp_dir().join(format!("quadtex-badgltf-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let good = dir.join("good.glb");
    quadtex_render::write_glb(
        &good,
        &[[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 1.0, 0.0]],
        &[[0.0, 1.0], [1.0, 1.0], [1.0, 0.0]],
        &[0, 1, 2],
        None,
    )
    .unwrap();
    let bytes = std::fs::read(&good).unwrap();
    let check = |name: &str, data: &[u8], needle: &str| {
        std::fs::write(dir.join(name), data).unwrap();
        let text = format!(
            "[camera]\nposition = [0, 0, 5]\nlook_at = [0, 0, 0]\nwidth = 8\nheight = 8\n\n[[shape]]\ntype = \"gltf\"\nfile = \"{name}\"\n"
        );
        let e = parse_scene(&text, &dir.join("s.toml"), &quadtex_io::Limits::default())
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("shape[0].file") && e.contains(name) && e.contains(needle),
            "{name}: {e}"
        );
    };
    check(
        "truncated.glb",
        &bytes[..bytes.len() / 2],
        "not a valid glTF",
    );
    check(
        "garbage.glb",
        b"glTF\x02\x00\x00\x00garbage",
        "not a valid glTF",
    );
    // Index 7 of a 3-vertex mesh: the last 4 bytes of the binary chunk.
    let mut bad_index = bytes.clone();
    let n = bad_index.len();
    bad_index[n - 4..].copy_from_slice(&7u32.to_le_bytes());
    check("index.glb", &bad_index, "index 7 out of range");
    // A NaN vertex: the first position's x.
    let json_len = u32::from_le_bytes(bytes[12..16].try_into().unwrap()) as usize;
    let bin = 20 + json_len + 8;
    let mut nan = bytes.clone();
    nan[bin..bin + 4].copy_from_slice(&f32::NAN.to_le_bytes());
    check("nan.glb", &nan, "non-finite vertex");
    // A buffer declared longer than the binary chunk holds.
    let text = String::from_utf8_lossy(&bytes[20..20 + json_len]).to_string();
    let declared = text
        .split("\"byteLength\":")
        .nth(1)
        .unwrap()
        .split('}')
        .next()
        .unwrap();
    let longer = text.replacen(
        &format!("\"buffers\":[{{\"byteLength\":{declared}}}]"),
        &format!(
            "\"buffers\":[{{\"byteLength\":{}}}]",
            4096 + declared.parse::<usize>().unwrap()
        ),
        1,
    );
    assert_ne!(longer, text);
    // Rebuilt with the JSON chunk padded to 4 bytes and the header's lengths updated.
    let mut json = longer.into_bytes();
    while json.len() % 4 != 0 {
        json.push(b' ');
    }
    let mut rebuilt = Vec::new();
    rebuilt.extend_from_slice(&bytes[..8]);
    let total = 12 + 8 + json.len() + (bytes.len() - 20 - json_len);
    rebuilt.extend_from_slice(&(total as u32).to_le_bytes());
    rebuilt.extend_from_slice(&(json.len() as u32).to_le_bytes());
    rebuilt.extend_from_slice(b"JSON");
    rebuilt.extend_from_slice(&json);
    rebuilt.extend_from_slice(&bytes[20 + json_len..]);
    check("short.glb", &rebuilt, "the model declares");
    // A buffer in a missing file beside the model.
    let external = text.replacen(
        &format!("\"buffers\":[{{\"byteLength\":{declared}}}]"),
        &format!("\"buffers\":[{{\"byteLength\":{declared},\"uri\":\"absent.bin\"}}]"),
        1,
    );
    check("external.gltf", external.as_bytes(), "absent.bin");
    std::fs::remove_dir_all(&dir).unwrap();
}

/// The quadtree filter's self-check over a generated terrain (a glTF mesh
/// under a runway decal, ridges in front of slopes, triangles smaller
/// than a pixel towards the horizon): the pieces each pixel is cut into
/// carry its whole weight, to 1e-6 (box and tent). Regions a rounding
/// wiggle put outside the walk's half-planes once lost all of a piece's
/// weight, and sliver-thin edges up to 4.5e-5 of a pixel's.
#[test]
fn a_terrains_pixels_keep_their_whole_weight() {
    let dir = std::env::temp_dir().join(format!("quadtex-weight-{}", std::process::id()));
    let file = quadtex_render::write_terrain(&dir, 300, 480, 270).unwrap();
    let scene = quadtex_render::load_scene(&file, &quadtex_io::Limits::default()).unwrap();
    std::fs::remove_dir_all(&dir).ok();
    for pixel_filter in [PixelFilter::Box, PixelFilter::Tent] {
        let options = RenderOptions {
            pixel_filter,
            ..RenderOptions::default()
        };
        let (_, s) = render(&scene, &options, &|_, _| {}).unwrap();
        assert!(s.max_weight_error < 1e-6, "{pixel_filter:?}: {s}");
        assert!(s.to_string().contains("pixel weight off by"), "{s}");
    }
}
