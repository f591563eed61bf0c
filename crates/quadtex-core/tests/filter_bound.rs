#![allow(clippy::unwrap_used, clippy::expect_used)]
//! Default filter calls keep their bound: on random textures (photo-like
//! blocks, rasterised vector art, HDR values above 1) and random footprints
//! from 1e-4 to 4 texture units wide, projective (convex quads) and affine
//! (parallelograms), [`Texture::filter_with_bound`] under
//! [`FilterOptions::default`] is within the bound it reports of a slow,
//! obvious reference (every terminal square of the tree, in every tile the
//! footprint reaches, clipped against the quad, weighted by its area), and
//! that bound is at most the default target. Also: what huge, self-crossing
//! and zero-coverage footprints give.

mod common;

use common::coefficients;
use quadtex_core::synth::Art;
use quadtex_core::{
    BuildOptions, ColourEncoding, ConvexPolygon, FilterOptions, FilterStats, Footprint,
    MAX_TEXTURE_COORDINATE, QuadTree, Rgba, TexelGrid, Texture, Weighting, Wrap, WrapMode,
};

/// SplitMix64: a small, seeded generator (reproducible cases).
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// Uniform in `[lo, hi)`.
    fn range(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * (self.next() >> 11) as f64 / (1u64 << 53) as f64
    }
}

fn srgb_decode(v: f64) -> f32 {
    (if v <= 0.04045 {
        v / 12.92
    } else {
        ((v + 0.055) / 1.055).powf(2.4)
    }) as f32
}

/// The texture: 64×64 texels of random sRGB colours (random per
/// texel, so the tree is 6 levels deep: 4×4-texel blocks of one colour
/// would give a depth-4 tree, scanned cell by cell, exactly).
fn photo_like(rng: &mut Rng) -> TexelGrid {
    let colours: Vec<Rgba> = (0..64 * 64)
        .map(|_| {
            Rgba::opaque(
                srgb_decode(rng.range(0.0, 1.0)),
                srgb_decode(rng.range(0.0, 1.0)),
                srgb_decode(rng.range(0.0, 1.0)),
            )
        })
        .collect();
    TexelGrid::from_fn(64, 64, |c, r| colours[(r * 64 + c) as usize]).unwrap()
}

/// Vector art (rectangles and lettering from `synth`), rasterised.
fn vector_art() -> TexelGrid {
    let mut art = Art::new(Rgba::opaque(0.9, 0.9, 0.85));
    art.rect(0.1, 0.1, 0.7, 0.35, Rgba::opaque(0.1, 0.2, 0.8));
    art.rect(0.33, 0.21, 0.95, 0.9, Rgba::new(0.4, 0.0, 0.1, 0.5));
    art.text("QT 62", 0.05, 0.55, 0.03, Rgba::opaque(0.0, 0.0, 0.0));
    art.rasterise(64, 64).unwrap()
}

/// HDR: 32×32 texels with values up to 8 (half floats).
fn hdr(rng: &mut Rng) -> TexelGrid {
    let texels: Vec<[f32; 4]> = (0..32 * 32)
        .map(|_| {
            [
                rng.range(0.0, 8.0) as f32,
                rng.range(0.0, 1.0) as f32,
                rng.range(0.0, 3.0) as f32,
                1.0,
            ]
        })
        .collect();
    TexelGrid::from_linear_f32(32, 32, &texels).unwrap()
}

/// A photo-like texture of an odd size, `w × h` random texels: the tree
/// spans part of its square and blocks cross the texture's edge.
fn odd_photo(rng: &mut Rng, w: u32, h: u32) -> TexelGrid {
    let bytes: Vec<[u8; 4]> = (0..w * h)
        .map(|_| {
            let v = rng.next();
            [v as u8, (v >> 8) as u8, (v >> 16) as u8, 255]
        })
        .collect();
    TexelGrid::from_srgb8(w, h, bytes).unwrap()
}

/// The tree's uniform squares in texture space (tree squares over the
/// texture's extent, clipped to it).
fn leaves(tree: &QuadTree) -> Vec<([f64; 4], [f64; 4])> {
    let mut out = Vec::new();
    let [ex, ez] = tree.aspect().scale();
    tree.for_each_leaf(tree.depth(), |level, ix, iz, colour| {
        let s = 0.5f64.powi(i32::from(level));
        let (x, z) = (f64::from(ix) * s, f64::from(iz) * s);
        let r = [
            x / ex,
            z / ez,
            ((x + s) / ex).min(1.0),
            ((z + s) / ez).min(1.0),
        ];
        out.push((r, colour));
    });
    out
}

/// The exact mean over the quad under repeat (or mirror): every leaf in
/// every tile the quad's box reaches, clipped against it.
fn reference(leaves: &[([f64; 4], [f64; 4])], quad: &ConvexPolygon, mirror: bool) -> [f64; 4] {
    let (lo, hi) = quad.bounds();
    let mut acc = [0.0; 4];
    let mut area = 0.0;
    for tz in lo[1].floor() as i64..=hi[1].floor() as i64 {
        for tx in lo[0].floor() as i64..=hi[0].floor() as i64 {
            let (ox, oz) = (tx as f64, tz as f64);
            let flip = |a: f64, b: f64, t: i64| {
                if mirror && t.rem_euclid(2) == 1 {
                    (1.0 - b, 1.0 - a)
                } else {
                    (a, b)
                }
            };
            for (r, colour) in leaves {
                let ((x0, x1), (z0, z1)) = (flip(r[0], r[2], tx), flip(r[1], r[3], tz));
                let [x0, z0, x1, z1] = [x0 + ox, z0 + oz, x1 + ox, z1 + oz];
                if x1 <= lo[0] || x0 >= hi[0] || z1 <= lo[1] || z0 >= hi[1] {
                    continue;
                }
                let a = quad.clip_rect(x0, z0, x1, z1).area();
                area += a;
                for (s, c) in acc.iter_mut().zip(colour) {
                    *s += a * c;
                }
            }
        }
    }
    acc.map(|s| s / area)
}

/// A random footprint `width` wide around a point of the unit square:
/// a parallelogram (affine) or a convex quad (projective).
fn random_quad(rng: &mut Rng, width: f64, affine: bool) -> [[f64; 2]; 4] {
    let c = [rng.range(0.0, 1.0), rng.range(0.0, 1.0)];
    let angle = rng.range(0.0, std::f64::consts::TAU);
    let (s, co) = angle.sin_cos();
    let aspect = rng.range(0.05, 1.0);
    let shear = rng.range(-0.8, 0.8);
    let (w, h) = (width, width * aspect);
    let local: [[f64; 2]; 4] = if affine {
        [
            [-w / 2.0 - shear * h / 2.0, -h / 2.0],
            [w / 2.0 - shear * h / 2.0, -h / 2.0],
            [w / 2.0 + shear * h / 2.0, h / 2.0],
            [-w / 2.0 + shear * h / 2.0, h / 2.0],
        ]
    } else {
        // A trapezoid of a grazing view (far side up to 6 times the near).
        let far = rng.range(1.0, 6.0);
        let near = w / far;
        [
            [-near / 2.0, -h / 2.0],
            [near / 2.0, -h / 2.0],
            [w / 2.0, h / 2.0],
            [-w / 2.0, h / 2.0],
        ]
    };
    local.map(|p| [c[0] + co * p[0] - s * p[1], c[1] + s * p[0] + co * p[1]])
}

#[test]
fn default_calls_keep_their_bound_on_random_textures_and_footprints() {
    let mut rng = Rng(0x5EED_0062);
    let grids = [
        ("photo-like", photo_like(&mut rng), Wrap::REPEAT),
        ("vector art", vector_art(), Wrap::REPEAT),
        ("HDR", hdr(&mut rng), Wrap::REPEAT),
        (
            "photo-like 37x23",
            odd_photo(&mut rng, 37, 23),
            Wrap::REPEAT,
        ),
        (
            "photo-like 19x50",
            odd_photo(&mut rng, 19, 50),
            Wrap::MIRROR,
        ),
    ];
    let target = 1.0 / 512.0;
    for (name, grid, wrap) in grids {
        let (tree, _) = QuadTree::from_texels(&grid, &BuildOptions::default()).unwrap();
        if name == "HDR" {
            assert_eq!(tree.encoding(), ColourEncoding::Half);
        }
        if name == "photo-like" {
            assert_eq!(tree.depth(), 6);
        }
        // Stored means are rounded to the colour encoding (a 16-bit step,
        // or a half float's 11 bits), and colours come back as f32.
        let rounding = match tree.encoding() {
            ColourEncoding::Unorm16 => 1.0 / 65535.0,
            _ => 8.0 * 2f64.powi(-11),
        };
        let leaves = leaves(&tree);
        let texture = Texture::new(tree, wrap);
        let scale = texture.bound_scale();
        let mirror = wrap == Wrap::MIRROR;
        let mut worst = 0.0f64;
        for case in 0..300 {
            let width = 10f64.powf(rng.range(-4.0, 4f64.log10()));
            let affine = case % 2 == 0;
            let corners = random_quad(&mut rng, width, affine);
            let footprint = Footprint::from_corners(corners).unwrap();
            let exact = reference(&leaves, &ConvexPolygon::hull(&corners), mirror);
            // Texture weighting always; screen weighting too on
            // parallelograms, where the two agree.
            let weightings: &[Weighting] = if affine {
                &[Weighting::Texture, Weighting::Screen]
            } else {
                &[Weighting::Texture]
            };
            for &weighting in weightings {
                let options = FilterOptions::default().with_weighting(weighting);
                let mut stats = FilterStats::default();
                let (colour, bound) = texture.filter_with_bound(&footprint, &options, &mut stats);
                assert!(
                    bound <= target,
                    "{name}, case {case} ({weighting:?}, width {width:.3e}): bound {bound:e} above the target"
                );
                assert_eq!(stats.over_target, 0);
                for (ch, (got, want)) in colour.to_array().into_iter().zip(exact).enumerate() {
                    let error = (f64::from(got) - want).abs();
                    let allowed = bound * scale + rounding + 1e-6 * want.abs();
                    worst = worst.max(error / scale);
                    assert!(
                        error <= allowed,
                        "{name}, case {case} ({weighting:?}, width {width:.3e}, {corners:?}), channel {ch}: {got} vs exact {want}, error {error:e} above {allowed:e}"
                    );
                }
            }
        }
        assert!(worst <= target + rounding, "{name}: worst {worst:e}");
    }
}

/// Under clamp and border, footprints reaching up to a thousand texture
/// widths past the edges keep their bound within the target: the
/// stretched edge cells are taken whole only where the region's own
/// boundary pays for them, however far the stripe reaches. Under mirror
/// (and repeat), texture-weighted footprints too; screen-weighted ones up
/// to ten widths (a hundred tiles: beyond a few thousand, projective ones
/// can reach the square cap and report a bound above the target, see
/// `docs/limits.md`).
#[test]
fn far_reaching_footprints_keep_the_bound_under_every_wrap() {
    let mut rng = Rng(0x5EED_0063);
    let grid = photo_like(&mut rng);
    let (tree, _) = QuadTree::from_texels(&grid, &BuildOptions::default()).unwrap();
    let target = 1.0 / 512.0;
    for (wrap, weighting, widest) in [
        (Wrap::CLAMP, Weighting::Screen, 1000.0f64),
        (
            Wrap::border(Rgba::opaque(0.0, 1.0, 0.0)).unwrap(),
            Weighting::Screen,
            1000.0,
        ),
        (Wrap::MIRROR, Weighting::Texture, 1000.0),
        (Wrap::MIRROR, Weighting::Screen, 1000.0),
        (Wrap::REPEAT, Weighting::Screen, 1000.0),
    ] {
        let texture = Texture::new(tree.clone(), wrap);
        let options = FilterOptions::default().with_weighting(weighting);
        let mut worst = 0.0f64;
        for case in 0..60 {
            let width = 10f64.powf(rng.range(0.0, widest.log10()));
            let corners = random_quad(&mut rng, width, case % 2 == 0);
            let footprint = Footprint::from_corners(corners).unwrap();
            let mut stats = FilterStats::default();
            let (_, bound) = texture.filter_with_bound(&footprint, &options, &mut stats);
            worst = worst.max(bound);
            assert!(
                bound <= target,
                "{wrap:?} {weighting:?}, case {case} (width {width:.3e}, {corners:?}): bound {bound:e} above the target"
            );
        }
        assert!(
            worst > 0.0 || wrap != Wrap::CLAMP,
            "{wrap:?}: nothing approximated"
        );
    }
}

/// The exact screen-weighted (box) mean over the quad under repeat: every
/// leaf in every tile, clipped against the quad, weighted by the area of
/// its image in the pixel square (the inverse of the square-to-quad map).
fn screen_reference(leaves: &[([f64; 4], [f64; 4])], corners: [[f64; 2]; 4]) -> [f64; 4] {
    let [a, b, c, d, e, f, g, h] = coefficients(corners);
    let m = [[a, b, c], [d, e, f], [g, h, 1.0]];
    // The inverse by cofactors (its scale cancels in the homogeneous divide).
    let inv = [
        [
            m[1][1] * m[2][2] - m[1][2] * m[2][1],
            m[0][2] * m[2][1] - m[0][1] * m[2][2],
            m[0][1] * m[1][2] - m[0][2] * m[1][1],
        ],
        [
            m[1][2] * m[2][0] - m[1][0] * m[2][2],
            m[0][0] * m[2][2] - m[0][2] * m[2][0],
            m[0][2] * m[1][0] - m[0][0] * m[1][2],
        ],
        [
            m[1][0] * m[2][1] - m[1][1] * m[2][0],
            m[0][1] * m[2][0] - m[0][0] * m[2][1],
            m[0][0] * m[1][1] - m[0][1] * m[1][0],
        ],
    ];
    let to_screen = |t: [f64; 2]| {
        let w = inv[2][0] * t[0] + inv[2][1] * t[1] + inv[2][2];
        [
            (inv[0][0] * t[0] + inv[0][1] * t[1] + inv[0][2]) / w,
            (inv[1][0] * t[0] + inv[1][1] * t[1] + inv[1][2]) / w,
        ]
    };
    let quad = ConvexPolygon::hull(&corners);
    let (lo, hi) = quad.bounds();
    let mut acc = [0.0; 4];
    let mut area = 0.0;
    for tz in lo[1].floor() as i64..=hi[1].floor() as i64 {
        for tx in lo[0].floor() as i64..=hi[0].floor() as i64 {
            let (ox, oz) = (tx as f64, tz as f64);
            for (r, colour) in leaves {
                let piece = quad.clip_rect(r[0] + ox, r[1] + oz, r[2] + ox, r[3] + oz);
                if piece.is_empty() {
                    continue;
                }
                let v: Vec<[f64; 2]> = piece.vertices().iter().map(|&t| to_screen(t)).collect();
                let n = v.len();
                let a: f64 = (0..n)
                    .map(|i| v[i][0] * v[(i + 1) % n][1] - v[(i + 1) % n][0] * v[i][1])
                    .sum::<f64>()
                    .abs()
                    / 2.0;
                area += a;
                for (s, c) in acc.iter_mut().zip(colour) {
                    *s += a * c;
                }
            }
        }
    }
    acc.map(|s| s / area)
}

/// Screen-weighted (the default) projective footprints over thousands of
/// repeated tiles: the colour is within the reported bound of the exact
/// screen-weighted mean, and the bound meets the target. Whole tiles are
/// weighed at the tile's mean; the density bends across each, which the
/// walk bounds by the texture's second moments.
#[test]
fn screen_weighted_footprints_over_many_tiles_are_within_their_bound() {
    let mut rng = Rng(0x5EED_0064);
    let colours: Vec<Rgba> = (0..64)
        .map(|_| {
            Rgba::opaque(
                rng.range(0.0, 1.0) as f32,
                rng.range(0.0, 1.0) as f32,
                rng.range(0.0, 1.0) as f32,
            )
        })
        .collect();
    let grid = TexelGrid::from_fn(8, 8, |c, r| colours[(r * 8 + c) as usize]).unwrap();
    let (tree, _) = QuadTree::from_texels(&grid, &BuildOptions::default()).unwrap();
    let leaves = leaves(&tree);
    let texture = Texture::new(tree, Wrap::REPEAT);
    let target = 1.0 / 512.0;
    for case in 0..24 {
        let width = 10f64.powf(rng.range(0.5, 2.0));
        let corners = random_quad(&mut rng, width, false);
        let footprint = Footprint::from_corners(corners).unwrap();
        let mut stats = FilterStats::default();
        let (colour, bound) =
            texture.filter_with_bound(&footprint, &FilterOptions::default(), &mut stats);
        assert!(
            bound <= target,
            "case {case} (width {width:.3e}): bound {bound:e}"
        );
        let exact = screen_reference(&leaves, corners);
        for (ch, (got, want)) in colour.to_array().into_iter().zip(exact).enumerate() {
            let error = (f64::from(got) - want).abs();
            assert!(
                error <= bound + 1.0 / 65535.0 + 1e-6,
                "case {case} (width {width:.3e}, {corners:?}), channel {ch}: {got} vs exact {want}, error {error:e} above the bound {bound:e}"
            );
        }
    }
}

/// With a budget (opt-in), a large footprint stops short and says so;
/// without, it meets the bound. (An HDR texture: no texel blocks, so no
/// cell-by-cell scan that is exact whatever the budget.)
#[test]
fn a_budget_is_opt_in_and_a_call_it_stops_says_so() {
    let grid = hdr(&mut Rng(7));
    let (tree, _) = QuadTree::from_texels(&grid, &BuildOptions::default()).unwrap();
    let texture = Texture::new(tree, Wrap::REPEAT);
    // A rotated square most of the texture wide.
    let footprint =
        Footprint::from_corners([[0.5, 0.02], [0.97, 0.45], [0.55, 0.96], [0.06, 0.52]]).unwrap();
    let texture_weighting = FilterOptions::default().with_weighting(Weighting::Texture);
    let mut stats = FilterStats::default();
    let (_, bound) = texture.filter_with_bound(&footprint, &texture_weighting, &mut stats);
    assert!(bound <= 1.0 / 512.0, "{bound}");
    assert_eq!(stats.over_target, 0);
    let budgeted = texture_weighting.with_budget(1).unwrap();
    let (_, bound) = texture.filter_with_bound(&footprint, &budgeted, &mut stats);
    assert!(bound > 1.0 / 512.0, "{bound}");
    assert_eq!(stats.over_target, 1);
}

fn mean(grid: &TexelGrid) -> [f64; 4] {
    let mut acc = [0.0; 4];
    for t in grid.texels() {
        for (s, v) in acc.iter_mut().zip(t.to_rgba().to_array()) {
            *s += f64::from(v);
        }
    }
    acc.map(|s| s / grid.texels().len() as f64)
}

/// Huge footprints: up to `MAX_TEXTURE_COORDINATE` the answer is right
/// under every wrap (repeat: the texture's mean; clamp, mirror: the limit
/// the exact mean tends to, the mean colour; border: the border colour),
/// within the reported bound; beyond it the footprint is refused.
#[test]
fn huge_footprints_are_right_or_refused() {
    let grid = photo_like(&mut Rng(3));
    let (tree, _) = QuadTree::from_texels(&grid, &BuildOptions::default()).unwrap();
    let mean = mean(&grid);
    let border = Rgba::new(0.2, 0.1, 0.05, 0.5);
    for half in [1e3, 1e9, 1e15] {
        let footprint =
            Footprint::from_corners([[-half, -half], [half, -half], [half, half], [-half, half]])
                .unwrap();
        for (mode, want) in [
            (WrapMode::Repeat, mean),
            (WrapMode::Mirror, mean),
            (WrapMode::Border, border.to_array().map(f64::from)),
        ] {
            let wrap = Wrap::new(mode, mode, border).unwrap();
            let texture = Texture::new(tree.clone(), wrap);
            let mut stats = FilterStats::default();
            let (colour, bound) =
                texture.filter_with_bound(&footprint, &FilterOptions::default(), &mut stats);
            assert!(bound <= 1.0 / 512.0, "{mode:?} at {half:e}: bound {bound}");
            for (got, want) in colour.to_array().into_iter().zip(want) {
                assert!(
                    (f64::from(got) - want).abs() <= bound + 1e-4,
                    "{mode:?} at {half:e}: {:?} vs {want:?}",
                    colour.to_array()
                );
            }
        }
        // Clamp over a huge footprint: the edge texels stretched out; the
        // mean tends to the mean of the four corner texels... weighted by
        // the quadrants, here each a quarter.
        let texture = Texture::new(tree.clone(), Wrap::CLAMP);
        let colour = texture.filter(&footprint, &FilterOptions::default());
        let corner = |c: u32, r: u32| grid.texels()[(r * 64 + c) as usize].to_rgba().to_array();
        let want: Vec<f64> = (0..4)
            .map(|ch| {
                0.25 * [corner(0, 0), corner(63, 0), corner(0, 63), corner(63, 63)]
                    .iter()
                    .map(|t| f64::from(t[ch]))
                    .sum::<f64>()
            })
            .collect();
        for (got, want) in colour.to_array().into_iter().zip(want) {
            assert!(
                (f64::from(got) - want).abs() <= 1.0 / 512.0 + 1e-4,
                "clamp at {half:e}: {:?}",
                colour.to_array()
            );
        }
    }
    for far in [1e20, 1e300] {
        let e =
            Footprint::from_corners([[0.0, 0.0], [far, 0.0], [far, 1.0], [0.0, 1.0]]).unwrap_err();
        assert!(e.to_string().contains("MAX_TEXTURE_COORDINATE"), "{e}");
    }
    const { assert!(MAX_TEXTURE_COORDINATE >= 1e15) };
}

/// No channel of an LDR texture's filtered colour is negative (rounding in
/// the sums used to leave -2e-20 where the mean is 0).
#[test]
fn ldr_channels_are_never_negative() {
    let grid = TexelGrid::from_fn(64, 64, |c, r| {
        if (c / 8 + r / 8) % 2 == 0 {
            Rgba::opaque(0.0, 1.0, 0.0)
        } else {
            Rgba::new(0.0, 0.0, 0.5, 0.5)
        }
    })
    .unwrap();
    let (tree, _) = QuadTree::from_texels(&grid, &BuildOptions::default()).unwrap();
    let mut rng = Rng(11);
    for wrap in [Wrap::REPEAT, Wrap::CLAMP] {
        let texture = Texture::new(tree.clone(), wrap);
        for case in 0..400 {
            let width = 10f64.powf(rng.range(-3.0, 0.5));
            let quad = random_quad(&mut rng, width, case % 2 == 0);
            let colour = texture.filter(
                &Footprint::from_corners(quad).unwrap(),
                &FilterOptions::default(),
            );
            assert!(
                colour.to_array().iter().all(|&v| v >= 0.0),
                "{quad:?}: {:?}",
                colour.to_array()
            );
        }
    }
}
