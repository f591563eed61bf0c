use super::*;

/// Pixels answered by their span come out as they do one by one: the
/// demo (the sign's shadow on the ground, the runway's uniform
/// asphalt, the checker up close, the sky) with a sphere and an
/// untextured quad casting shadows, a second plane the sun lies beyond
/// and a few mesh triangles in the sky, under every
/// pixel filter, lit and unlit. Equal to the last bit with the box;
/// within rounding of the filter's weight otherwise. The spans must
/// also have answered most textured pixels (a test they never enter
/// would pass).
#[test]
fn spans_give_each_pixel_what_it_gets_alone() {
    use crate::math::Vec3;
    use crate::options::PixelFilter;
    use crate::scene::{Geometry, Lighting, Surface, UvTransform};
    let mut scene = crate::demo_scene().unwrap();
    let white = quadtex_core::Rgba::opaque(0.9, 0.8, 0.7);
    let extra = |geometry| Surface {
        geometry,
        texture: None,
        colour: white,
        uv_transform: UvTransform::default(),
        wrap: quadtex_core::Wrap::CLAMP,
    };
    scene.surfaces.push(extra(Geometry::Sphere {
        centre: Vec3::new(-20.0, 6.0, 40.0),
        radius: 4.0,
    }));
    // A canopy whose shadow falls at the right end of the ground's
    // runs (where a run's light taken from its left part would be wrong).
    scene.surfaces.push(extra(Geometry::Quad {
        origin: Vec3::new(95.0, 3.0, -60.0),
        edge_u: Vec3::new(20.0, 0.0, 0.0),
        edge_v: Vec3::new(0.0, 0.0, -40.0),
    }));
    scene.surfaces.push(extra(Geometry::Quad {
        origin: Vec3::new(20.0, 2.0, 60.0),
        edge_u: Vec3::new(6.0, 0.0, 1.0),
        edge_v: Vec3::new(0.0, 5.0, 0.0),
    }));
    // Far behind the camera's view, on the sun's side of nothing
    // visible: shadow rays from the ground never reach it.
    scene.surfaces.push(extra(Geometry::Plane {
        point: Vec3::new(0.0, -50.0, 0.0),
        normal: Vec3::new(0.0, 1.0, 0.0),
        u_axis: Vec3::new(1.0, 0.0, 0.0),
        v_axis: Vec3::new(0.0, 0.0, -1.0),
    }));
    // A small mesh in the sky: sky spans must see its triangles.
    let corner = |x: f64, y: f64| Vec3::new(x, y, -60.0);
    let triangles = (0..6)
        .filter_map(|i| {
            let x = -30.0 + 9.0 * f64::from(i);
            crate::scene::Triangle::new(
                [
                    corner(x, 20.0),
                    corner(x + 3.0, 20.5),
                    corner(x + 1.0, 23.0),
                ],
                [[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]],
            )
        })
        .collect();
    let mesh = crate::scene::Mesh::new(triangles).unwrap();
    scene
        .surfaces
        .push(extra(Geometry::Mesh(std::sync::Arc::new(mesh))));
    let unlit = Scene {
        lighting: Lighting::Unlit,
        ..scene.clone()
    };
    for (scene, pixel_filter, width) in [
        (&scene, PixelFilter::Box, 480),
        (&scene, PixelFilter::Tent, 480),
        (&scene, PixelFilter::Mitchell, 480),
        (&unlit, PixelFilter::Box, 320),
    ] {
        let options = RenderOptions {
            width: Some(width),
            height: None,
            filter: TextureFilter::default(),
            pixel_filter,
            seed: 0,
        };
        let go = |spans| {
            let mut image = LinearImage::default();
            let summary =
                render_with(scene, &options, &|_, _| (), spans, &mut image, None).unwrap();
            (image, summary)
        };
        let (shared, alone) = (go(Spans::NoSharedCuts), go(Spans::EachPixel));
        let mut worst = 0f32;
        for (a, b) in shared.0.pixels.iter().zip(&alone.0.pixels) {
            for (u, v) in a.to_array().iter().zip(b.to_array()) {
                worst = worst.max((u - v).abs());
            }
        }
        let tolerance = if pixel_filter == PixelFilter::Box {
            0.0
        } else {
            1e-6
        };
        assert!(worst <= tolerance, "{pixel_filter:?}: off by {worst}");
        let queries = |s: &RenderSummary| s.filter.traversal.queries as f64;
        // A box pixel's support is smallest, so more of its spans hold.
        // A span's own lookup counts as one query (measured: box 0.51
        // lit at 480 and 0.61 unlit at 320, tent 0.60, Mitchell 0.73).
        let most = if pixel_filter == PixelFilter::Box {
            0.7
        } else {
            0.85
        };
        assert!(
            queries(&shared.1) < most * queries(&alone.1),
            "{pixel_filter:?}: spans answered too few pixels ({} against {} queries)",
            queries(&shared.1),
            queries(&alone.1)
        );
        assert_eq!(shared.1.textured_pixels, alone.1.textured_pixels);
        assert_eq!(shared.1.filter.fragments, alone.1.filter.fragments);
    }
}

/// A reused buffer gives what a fresh one does: one the frame's size
/// full of stale pixels (every pixel must be overwritten), a larger
/// one and a smaller one; and a frame that fails leaves it untouched.
#[test]
fn rendering_into_a_used_image_is_rendering_afresh() {
    let scene = crate::demo_scene().unwrap();
    let options = |width| RenderOptions {
        width: Some(width),
        height: None,
        ..RenderOptions::default()
    };
    let (fresh, summary) = render(&scene, &options(96), &|_, _| ()).unwrap();
    let stale = Rgba::opaque(0.25, 0.5, 0.75);
    for len in [fresh.pixels.len(), 3 * fresh.pixels.len(), 7] {
        let mut image = LinearImage {
            width: 3,
            height: 5,
            pixels: vec![stale; len],
        };
        let got = render_into(&scene, &options(96), &mut image, &|_, _| ()).unwrap();
        assert_eq!(image, fresh, "a buffer of {len} pixels");
        assert_eq!(got.textured_pixels, summary.textured_pixels);
    }
    let mut image = fresh.clone();
    let bad = RenderOptions {
        filter: TextureFilter::Supersample(0),
        ..options(96)
    };
    assert!(render_into(&scene, &bad, &mut image, &|_, _| ()).is_err());
    assert_eq!(image, fresh);
}

#[test]
fn runs_count_the_pixels_that_agree_from_each_on() {
    let u = [
        Some(3),
        Some(3),
        None,
        Some(0),
        Some(0),
        Some(5),
        Some(3),
        Some(3),
        Some(3),
    ];
    assert_eq!(runs_of_primitives(&u), vec![2, 1, 0, 0, 0, 1, 3, 2, 1]);
    assert!(runs_of_primitives(&[]).is_empty());
}

/// The one pass over columns and runs gives each pixel what comparing
/// its square of centres gives: random grids of few ids (so that
/// squares of one id are common, and change at every offset), reaches
/// 1 to 3, every row and pixel.
#[test]
fn a_rows_uniform_centres_are_its_squares() {
    let mut seed = 5u64;
    let mut next = |n: u64| {
        seed = seed
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1_442_695_040_888_963_407);
        (seed >> 33) % n
    };
    let (mut uniform, mut mixed) = (0, 0);
    for reach in 1..=3usize {
        let (width, height, pad) = (40usize, 12usize, 3usize);
        let (gw, gh) = (width + 2 * pad, height + 2 * pad);
        // Blocks of a few ids, a sprinkle of others.
        let block = 2 + next(6);
        let seen: Vec<Seen> = (0..gw * gh)
            .map(|i| {
                let (c, r) = ((i % gw) as u64, (i / gw) as u64);
                if next(40) == 0 {
                    next(3)
                } else {
                    (c / block + r / block) % 2
                }
            })
            .collect();
        for y in 0..height {
            let got = uniform_in_reach(&seen, gw, y + pad, pad, reach, width);
            assert_eq!(got.len(), width);
            for (x, &got) in got.iter().enumerate() {
                let (cx, cy) = (x + pad, y + pad);
                let first = seen[cy * gw + cx];
                let all = (cy - reach..=cy + reach)
                    .all(|r| (cx - reach..=cx + reach).all(|c| seen[r * gw + c] == first));
                assert_eq!(got, all.then_some(first), "reach {reach}, pixel ({x}, {y})");
                if all { uniform += 1 } else { mixed += 1 }
            }
        }
    }
    assert!(uniform > 100 && mixed > 100, "{uniform} {mixed}");
}

/// A thread keeps the views of mesh triangles from row to row of one
/// frame (`exact::ViewMemo`), never from one frame into the next: a
/// terrain rendered from one camera and then from another gives, the
/// second time, the image a pool of fresh threads gives that camera,
/// bit for bit, at each pixel filter. Both frames run on one pool of
/// two threads, so the second's rows find the first's views kept.
#[test]
fn kept_views_do_not_cross_frames() {
    use crate::options::PixelFilter;
    let dir = std::env::temp_dir().join(format!("quadtex-kept-{}", std::process::id()));
    let file = crate::terrain::write_terrain(&dir, 60, 160, 90).unwrap();
    let text = std::fs::read_to_string(&file).unwrap();
    let first = crate::parse_scene(&text, &file, &quadtex_io::Limits::default()).unwrap();
    let moved = text.replace("position = [30, 60, 600]", "position = [-40, 35, 420]");
    assert_ne!(moved, text);
    let second = crate::parse_scene(&moved, &file, &quadtex_io::Limits::default()).unwrap();
    std::fs::remove_dir_all(&dir).ok();
    let pool = || {
        rayon::ThreadPoolBuilder::new()
            .num_threads(2)
            .build()
            .unwrap()
    };
    let bits = |image: &LinearImage| -> Vec<u32> {
        (image.pixels.iter())
            .flat_map(|p| p.to_array().map(f32::to_bits))
            .collect()
    };
    for pixel_filter in [PixelFilter::Box, PixelFilter::Tent] {
        let options = RenderOptions {
            pixel_filter,
            ..RenderOptions::default()
        };
        let (after, textured) = pool().install(|| {
            let (_, summary) = render(&first, &options, &|_, _| {}).unwrap();
            (
                render(&second, &options, &|_, _| {}).unwrap().0,
                summary.textured_pixels,
            )
        });
        let (fresh, _) = pool().install(|| render(&second, &options, &|_, _| {}).unwrap());
        assert!(textured > 1000, "{textured}");
        assert!(bits(&after) == bits(&fresh), "{pixel_filter:?}");
    }
}

/// The screen bins serve the exact pixels alone: the visibility pass
/// files a mesh's triangles by screen tile for the quadtree filter and for
/// no other (`nearest` on the 1 M-triangle terrain at 1080p spent about a
/// tenth of its frame on them).
#[test]
fn only_the_quadtree_filter_bins_triangles_by_screen_tile() {
    let scene = crate::terrain::load_test_terrain("bins", 60, 160, 90);
    let frame = Frame::new(&scene);
    for (filter, binned) in [
        (TextureFilter::default(), true),
        (TextureFilter::Nearest, false),
        (
            TextureFilter::Ewa {
                max_anisotropy: 8.0,
            },
            false,
        ),
    ] {
        assert!(matches!(filter, TextureFilter::Quadtree(_)) == binned);
        let options = RenderOptions {
            filter,
            ..RenderOptions::default()
        };
        let mut views = SurfaceViews::new(&scene);
        let centres = CentreGrid::cast(&scene, &frame, &mut views, &options, (160, 90));
        assert!(centres.seen.iter().any(|&id| id != 0), "{filter:?}");
        assert_eq!(views.has_screen_bins(), binned, "{filter:?}");
    }
}

/// Shared cuts give each pixel what it gets cut alone, within the two
/// renders' bounds: a generated terrain (its far hills crowd pixels
/// with triangles, crests hiding slopes) and the runway's quad over it,
/// lit and unlit, and the demo (planes, quads, a sign's edges, shadows),
/// box filter. Each shared pixel's pieces tile it (its
/// weight is 1 to rounding), and the shared cuts must have answered many
/// pixels (a path never taken would pass): pixels whose colour is not
/// the same bits as alone.
#[test]
fn shared_cuts_give_each_pixel_what_it_gets_alone() {
    let (lit, unlit) = small_terrain("shared-cuts");
    // The bounds are in the texture's colour units: the sun and the
    // ambient light scale them by at most their sum's largest channel.
    let demo = crate::demo_scene().unwrap();
    for (scene, scale, least) in [(&unlit, 1.0, 100), (&lit, 1.5 + 0.5, 100), (&demo, 2.0, 10)] {
        let options = RenderOptions {
            width: Some(480),
            ..RenderOptions::default()
        };
        let (shared, alone) = (
            with_bounds(scene, &options, Spans::Shared),
            with_bounds(scene, &options, Spans::NoSharedCuts),
        );
        let (mut changed, mut worst) = (0, 0f64);
        for (i, (a, b)) in shared.0.pixels.iter().zip(&alone.0.pixels).enumerate() {
            // The walk's merge of close vertices moves a region's weight
            // by under 1e-5 of a pixel (limits.md), and the mean with it.
            let allowed = scale * (shared.1[i] + alone.1[i]) + 1e-5;
            for (u, v) in a.to_array().iter().zip(b.to_array()) {
                let off = f64::from((u - v).abs());
                worst = worst.max(off / allowed);
                assert!(
                    off <= allowed,
                    "pixel ({}, {}): {u} against {v}, bounds {} and {}",
                    i % 480,
                    i / 480,
                    shared.1[i],
                    alone.1[i]
                );
            }
            changed += usize::from(a != b);
        }
        eprintln!("{changed} pixels changed; worst {worst:.3} of the allowance");
        // Measured: 201 unlit, 226 lit, 61 on the demo.
        assert!(changed > least, "shared cuts answered {changed} pixels");
        assert!(
            shared.2.max_weight_error < 1e-6,
            "weight off by {}",
            shared.2.max_weight_error
        );
        assert_eq!(shared.2.textured_pixels, alone.2.textured_pixels);
    }
}

/// Crests no pixel centre sees are found: over a generated terrain whose
/// far ridges show as bands thinner than a pixel, between two rows of
/// centres, no pixel is off a supersampled render (12 × 12 stratified
/// samples a pixel, each the texel its ray meets) by more than that
/// render's noise can be, with shared cuts or pixels one by one. Without the search
/// for occluders ([`crate::exact`]), 105 pixels were off by more than 0.04
/// (up to 0.15) at this size, each with a bound near zero.
#[test]
fn crests_no_centre_sees_are_found() {
    let (_, scene) = small_terrain("crests");
    let run = |filter, spans| {
        let options = RenderOptions {
            width: Some(480),
            filter,
            ..RenderOptions::default()
        };
        let (image, bounds, _) = with_bounds(&scene, &options, spans);
        (image, bounds)
    };
    let (reference, _) = run(TextureFilter::Supersample(12), Spans::Shared);
    for spans in [Spans::Shared, Spans::NoSharedCuts] {
        let (image, bounds) = run(TextureFilter::default(), spans);
        let mut off: Vec<(usize, f32, f64)> = (image.pixels.iter().zip(&reference.pixels))
            .map(|(a, b)| {
                (a.to_array().iter().zip(b.to_array()))
                    .map(|(u, v)| (u - v).abs())
                    .fold(0.0, f32::max)
            })
            .enumerate()
            .filter(|&(i, d)| f64::from(d) > 0.06 + bounds[i])
            .map(|(i, d)| (i, d, bounds[i]))
            .collect();
        off.sort_by(|a, b| b.1.total_cmp(&a.1));
        off.truncate(8);
        let at: Vec<_> = off
            .iter()
            .map(|&(i, d, b)| (i % 480, i / 480, d, b))
            .collect();
        assert!(
            off.is_empty(),
            "{spans:?}: pixels off by more than 0.06 and their bound: {at:?}"
        );
    }
}

/// A generated terrain of 300 cells a side for 480 × 270, under its sun
/// and unlit (`name` keeps each test's folder apart).
fn small_terrain(name: &str) -> (Scene, Scene) {
    let lit = crate::terrain::load_test_terrain(name, 300, 480, 270);
    let unlit = Scene {
        lighting: crate::scene::Lighting::Unlit,
        ..lit.clone()
    };
    (lit, unlit)
}

/// `scene` rendered with each pixel's relative error bound.
fn with_bounds(
    scene: &Scene,
    options: &RenderOptions,
    spans: Spans,
) -> (LinearImage, Vec<f64>, RenderSummary) {
    let (mut image, mut bounds) = (LinearImage::default(), Vec::new());
    let summary = render_with(
        scene,
        options,
        &|_, _| (),
        spans,
        &mut image,
        Some(&mut bounds),
    )
    .unwrap();
    (image, bounds, summary)
}

/// A wire in front of a ball, thinner than a pixel and between two rows
/// of centres, is drawn where no centre sees it: the pixels whose centres
/// in reach all see the ball are tested for anything in front of it
/// (a quad here), and are within a 32 × 32 supersampled render's noise
/// plus their bound, under each pixel filter. Without the test the wire
/// was missing: the ball's colour where 15 % of each pixel of the two
/// rows is the wire's.
#[test]
fn a_wire_in_front_of_a_ball_between_two_rows_of_centres_is_drawn() {
    use crate::options::PixelFilter;
    // At 3 units from the camera a pixel is 0.0335 units: the wire, 0.01
    // high at the screen's middle row line (y = 24), lies between the
    // centres at 23.5 and 24.5.
    let text = "[camera]\nposition = [0, 0, -5]\nlook_at = [0, 0, 0]\nfov = 30\n\
                width = 64\nheight = 48\n\n[sky]\nhorizon = [0, 0, 0]\nzenith = [0, 0, 0]\n\n\
                [[shape]]\ntype = \"sphere\"\ncentre = [0, 0, 0]\nradius = 1\n\
                colour = [0.9, 0.9, 0.9]\n\n\
                [[shape]]\ntype = \"quad\"\norigin = [-0.5, -0.005, -2]\n\
                edge_u = [1, 0, 0]\nedge_v = [0, 0.01, 0]\ncolour = [0.05, 0.05, 0.05]\n";
    let scene = crate::parse_scene(
        text,
        std::path::Path::new("wire.toml"),
        &quadtex_io::Limits::default(),
    )
    .unwrap();
    for pixel_filter in [PixelFilter::Box, PixelFilter::Tent] {
        let run = |filter| {
            let options = RenderOptions {
                filter,
                pixel_filter,
                ..RenderOptions::default()
            };
            with_bounds(&scene, &options, Spans::Shared)
        };
        let (reference, _, _) = run(TextureFilter::Supersample(32));
        let (image, bounds, _) = run(TextureFilter::default());
        let at = |img: &LinearImage, x: usize, y: usize| img.pixels[y * 64 + x].to_array()[0];
        // The wire darkens rows 23 and 24 across its width.
        for x in 20..44 {
            for y in [23, 24] {
                let (want, got) = (at(&reference, x, y), at(&image, x, y));
                assert!(
                    want < 0.9 * at(&reference, x, 20),
                    "the reference shows no wire at ({x}, {y})"
                );
                assert!(
                    f64::from((got - want).abs()) < 0.03 + bounds[y * 64 + x],
                    "{pixel_filter:?} ({x}, {y}): {got} against {want}"
                );
            }
        }
    }
}
