#![allow(clippy::unwrap_used, clippy::expect_used)]
use super::*;
use std::path::Path;

fn scene(name: &str) -> Scene {
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../scenes")
        .join(name);
    quadtex_render::load_scene(&path, &quadtex_io::Limits::default()).unwrap()
}

/// Dense midpoint sampling of pixel `(px, py)` on an `n × n` grid: each
/// sample intersects the surface directly (its own plane/quad maths),
/// looks up the checker cell colour by `floor`, or takes the sky.
fn brute(scene: &Scene, w: u32, h: u32, px: u32, py: u32, n: u32) -> C4 {
    let camera = scene.camera.with_size(w, h);
    let s = &scene.surfaces[0];
    let tree = &s.texture.as_ref().unwrap().tree;
    let cells = 1u32 << tree.depth();
    let cell = 1.0 / f64::from(cells);
    let colour = |t: [f64; 2]| -> C4 {
        let (i, j) = ((t[0] / cell).floor(), (t[1] / cell).floor());
        let (i, j) = (
            i.rem_euclid(f64::from(cells)) as u32,
            j.rem_euclid(f64::from(cells)) as u32,
        );
        let f = quadtex_core::Fragment::new(
            f64::from(i) * cell,
            f64::from(j) * cell,
            f64::from(i + 1) * cell,
            f64::from(j + 1) * cell,
        )
        .unwrap();
        let c = c4(tree.weighted_colour(&f, u8::MAX).mean_over(f.area()));
        let k = c4(s.colour);
        [c[0] * k[0], c[1] * k[1], c[2] * k[2], c[3] * k[3]]
    };
    let mut lut = std::collections::HashMap::new();
    let mut acc = [0.0; 4];
    for sj in 0..n {
        for si in 0..n {
            let x = f64::from(px) + (f64::from(si) + 0.5) / f64::from(n);
            let y = f64::from(py) + (f64::from(sj) + 0.5) / f64::from(n);
            let ray = camera.ray(x, y);
            let uv = match s.geometry {
                Geometry::Plane {
                    point,
                    normal,
                    u_axis,
                    v_axis,
                } => {
                    let t = (point - ray.origin).dot(normal) / ray.direction.dot(normal);
                    (t > 0.0).then(|| {
                        let rel = ray.origin + ray.direction * t - point;
                        [rel.dot(u_axis), rel.dot(v_axis)]
                    })
                }
                Geometry::Quad {
                    origin,
                    edge_u,
                    edge_v,
                } => {
                    let normal = edge_u.cross(edge_v);
                    let t = (origin - ray.origin).dot(normal) / ray.direction.dot(normal);
                    let rel = ray.origin + ray.direction * t - origin;
                    // Axis-aligned quads in the test scenes: solve per axis.
                    let uv = [
                        rel.dot(edge_u) / edge_u.dot(edge_u),
                        rel.dot(edge_v) / edge_v.dot(edge_v),
                    ];
                    (t > 0.0 && (0.0..=1.0).contains(&uv[0]) && (0.0..=1.0).contains(&uv[1]))
                        .then_some(uv)
                }
                _ => unreachable!(),
            };
            let c = match uv {
                Some(uv) => {
                    let t = s.uv_transform.apply(uv);
                    let key = (
                        ((t[0] / cell).floor() as i64).rem_euclid(i64::from(cells)),
                        ((t[1] / cell).floor() as i64).rem_euclid(i64::from(cells)),
                    );
                    *lut.entry(key).or_insert_with(|| colour(t))
                }
                None => match scene.sky {
                    Sky::Solid(c) => c4(c),
                    Sky::Gradient { horizon, zenith } => {
                        let t = ray.direction.y.clamp(0.0, 1.0).sqrt();
                        let (a, b) = (c4(horizon), c4(zenith));
                        add(a, add(b, a, -1.0), t)
                    }
                },
            };
            acc = add(acc, c, 1.0);
        }
    }
    acc.map(|v| v / f64::from(n * n))
}

/// The old method for a pixel that sees only the surface: every finest
/// cell under its footprint projected to the screen (via the camera's
/// own `project`) and clipped against the pixel square.
fn cells_clipped(scene: &Scene, w: u32, h: u32, px: u32, py: u32) -> (C4, f64) {
    let camera = scene.camera.with_size(w, h);
    let s = &scene.surfaces[0];
    let tree = &s.texture.as_ref().unwrap().tree;
    let cells = 1u32 << tree.depth();
    let cell = 1.0 / f64::from(cells);
    let world = |t: [f64; 2]| {
        let uv = s.uv_transform.invert(t);
        match s.geometry {
            Geometry::Plane {
                point,
                u_axis,
                v_axis,
                ..
            } => point + u_axis * uv[0] + v_axis * uv[1],
            Geometry::Quad {
                origin,
                edge_u,
                edge_v,
            } => origin + edge_u * uv[0] + edge_v * uv[1],
            _ => unreachable!(),
        }
    };
    // Footprint bounds from dense edge samples of the pixel.
    let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
    let setup = Setup::new(scene, w, h).unwrap();
    for k in 0..=64 {
        let f = f64::from(k) / 64.0;
        for (x, y) in [(f, 0.0), (f, 1.0), (0.0, f), (1.0, f)] {
            let (x, y) = (f64::from(px) + x, f64::from(py) + y);
            let t = [setup.x_at(x, y), setup.z_at(y)];
            for a in 0..2 {
                lo[a] = lo[a].min(t[a]);
                hi[a] = hi[a].max(t[a]);
            }
        }
    }
    let pixel = [
        [f64::from(px), f64::from(py)],
        [f64::from(px) + 1.0, f64::from(py)],
        [f64::from(px) + 1.0, f64::from(py) + 1.0],
        [f64::from(px), f64::from(py) + 1.0],
    ];
    let (mut acc, mut area) = ([0.0; 4], 0.0);
    for j in (lo[1] / cell).floor() as i64 - 1..=(hi[1] / cell).ceil() as i64 {
        for i in (lo[0] / cell).floor() as i64 - 1..=(hi[0] / cell).ceil() as i64 {
            let (x0, z0) = (i as f64 * cell, j as f64 * cell);
            let quad: Vec<[f64; 2]> = [
                [x0, z0],
                [x0 + cell, z0],
                [x0 + cell, z0 + cell],
                [x0, z0 + cell],
            ]
            .iter()
            .map(|&t| camera.project(world(t)).unwrap())
            .collect();
            let mut poly = pixel.to_vec();
            let sgn = signed_area(&quad).signum();
            for k in 0..4 {
                let (a, b) = (quad[k], quad[(k + 1) % 4]);
                poly = clip_halfplane(
                    &poly,
                    [
                        -sgn * (b[1] - a[1]),
                        sgn * (b[0] - a[0]),
                        sgn * ((b[1] - a[1]) * a[0] - (b[0] - a[0]) * a[1]),
                    ],
                );
            }
            if poly.len() >= 3 {
                let a = signed_area(&poly).abs();
                let (ci, cj) = (
                    i.rem_euclid(i64::from(cells)) as usize,
                    j.rem_euclid(i64::from(cells)) as usize,
                );
                acc = add(acc, setup.colour[cj][ci], a);
                area += a;
            }
        }
    }
    (acc, area)
}

/// A pixel wholly on the surface agrees with the old cell-clipping
/// method to rounding.
#[test]
fn inner_pixels_match_cell_clipping() {
    for (name, px, py) in [
        ("checker.toml", 5, 50),
        ("checker.toml", 40, 35),
        ("checker_quad.toml", 27, 40),
        ("checker_quad.toml", 50, 30),
    ] {
        let sc = scene(name);
        let c = closed_form(&sc, 96, 54).unwrap();
        let exact = c.pixels[(py * 96 + px) as usize].unwrap();
        let (old, area) = cells_clipped(&sc, 96, 54, px, py);
        let d = max_diff(old, exact);
        eprintln!("{name} ({px},{py}): covered {area:.12}, diff {d:.2e}");
        assert!(
            (area - 1.0).abs() < 1e-9 && d < 1e-6,
            "{name} ({px},{py}): {d}"
        );
    }
}

fn max_diff(a: C4, b: Rgba) -> f64 {
    let b = c4(b);
    (0..4).map(|i| (a[i] - b[i]).abs()).fold(0.0, f64::max)
}

/// Full-size run time (release: `cargo test --release -p quadtex-eval
/// --lib full_size -- --ignored --nocapture`).
#[test]
#[ignore]
fn full_size_timing() {
    for name in ["checker.toml", "checker_quad.toml"] {
        let sc = scene(name);
        let t = std::time::Instant::now();
        let c = closed_form(&sc, 960, 540).unwrap();
        eprintln!(
            "{name} 960x540: {:.2} s, coverage {}, max bound {:.2e}",
            t.elapsed().as_secs_f64(),
            c.coverage(),
            c.max_bound()
        );
    }
}

/// Every pixel of both scenes is covered at 96×54, within a bound ≤ 1e-6.
#[test]
fn covers_every_pixel_of_both_scenes() {
    for name in ["checker.toml", "checker_quad.toml"] {
        let sc = scene(name);
        let c = closed_form(&sc, 96, 54).expect(name);
        assert_eq!(c.coverage(), 1.0, "{name}");
        assert!(c.max_bound() <= 1e-6, "{name}: bound {}", c.max_bound());
        for p in c.pixels.iter().flatten() {
            assert!(
                p.to_array()
                    .iter()
                    .all(|v| v.is_finite() && *v >= -1e-6 && *v <= 1.0 + 1e-6)
            );
        }
        eprintln!("{name}: coverage 100%, max bound {:.2e}", c.max_bound());
    }
}

/// Horizon, far-edge and side-edge pixels against dense supersampling:
/// the difference is within the sampling error (estimated from the
/// sampling's own change from n/2 to n), and the closed form is far
/// closer to the n-sample value than n/2 samples are.
#[test]
fn agrees_with_dense_supersampling() {
    let (w, h) = (96u32, 54u32);
    for (name, pixels) in [
        (
            "checker.toml",
            vec![(48, 24), (10, 24), (70, 25), (30, 23), (5, 50)],
        ),
        (
            "checker_quad.toml",
            vec![(48, 24), (30, 25), (60, 25), (27, 40), (68, 40)],
        ),
    ] {
        let sc = scene(name);
        let c = closed_form(&sc, w, h).unwrap();
        for (px, py) in pixels {
            let exact = c.pixels[(py * w + px) as usize].unwrap();
            let fine = brute(&sc, w, h, px, py, 2048);
            let coarse = brute(&sc, w, h, px, py, 1024);
            let d = max_diff(fine, exact);
            let sampling = (0..4)
                .map(|i| (fine[i] - coarse[i]).abs())
                .fold(0.0, f64::max);
            eprintln!(
                "{name} ({px},{py}): exact {:?} 2048² {fine:?} diff {d:.2e}, 1024²→2048² {sampling:.2e}",
                exact.to_array()
            );
            assert!(
                d <= 3.0 * sampling + 2e-4,
                "{name} ({px},{py}): {d} vs {sampling}"
            );
        }
    }
}
