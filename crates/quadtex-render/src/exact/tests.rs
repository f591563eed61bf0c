use std::rc::Rc;

use quadtex_core::{ConvexPolygon, FilterOptions, PixelFilter, Rgba};

use crate::frame::{Frame, sky};
use crate::math::Vec3;
use crate::scene::{Geometry, Lighting, Scene};
use crate::view::View;

use super::GAP_AREA;
use super::cutting::{Cut, Order, overlap_bound};
use super::lighting::{apply_light, light_region, uniform_light};
use super::sky::{
    SkySpan, Whole, level_line, second_moment, sky_at_centre, sky_bound_under, sky_clear_above,
    sky_contrast, sky_integral, sky_step, sky_tolerance, views_miss,
};
use super::views::{ViewMemo, ViewRef};

use super::*;

/// The built-in demo scene with its camera at `width × height`.
fn demo_at(width: u32, height: u32) -> Scene {
    let demo = crate::demo_scene().unwrap();
    Scene {
        camera: demo.camera.with_size(width, height),
        ..demo
    }
}

/// A thread's kept views come back for the frame they were built
/// for, and for no other.
#[test]
fn a_memo_is_kept_for_its_frame_alone() {
    let view = Rc::new(View::facing_at(1.0));
    let mut memo = ViewMemo::take_for(7);
    memo.slots.resize(ViewMemo::SLOTS, (0, None));
    memo.slots[ViewMemo::slot(42)] = (42, Some(view));
    memo.keep();
    let again = ViewMemo::take_for(7);
    assert!(matches!(
        again.slots.get(ViewMemo::slot(42)),
        Some((42, Some(_)))
    ));
    again.keep();
    let other = ViewMemo::take_for(8);
    assert_eq!(other.frame, 8);
    assert!((other.slots.iter()).all(|(id, view)| *id == 0 && view.is_none()));
    // Taken, the memo is the row's: the thread keeps nothing meanwhile.
    assert_eq!(ViewMemo::take_for(7).slots.len(), 0);
}

/// A triangle's uniform light, where it is shown, is what each of its
/// regions' own shadow ray gives ([`light_region`]), bit for bit: the
/// triangles of a generated terrain (hills above the runway decal,
/// the flat ground 0.3 m below it, which the decal shadows in part),
/// at points spread over each (corners and edges included), under the
/// scene's sun, a low one (hills shadowing hills), and the scene's sun
/// with an infinite plane through the hills at 8 m (what lies below it
/// is in its shadow). Both answers occur, and lit triangles among those
/// shown.
#[test]
fn a_uniform_light_is_what_each_point_gets() {
    let scene = crate::terrain::load_test_terrain("light", 400, 320, 180);
    let Lighting::Lambert {
        colour, ambient, ..
    } = scene.lighting
    else {
        panic!("the terrain is lit");
    };
    let low = Scene {
        lighting: Lighting::Lambert {
            direction: Vec3::new(-0.8, 0.08, 0.55).normalized().unwrap(),
            colour,
            ambient,
        },
        ..scene.clone()
    };
    let mut plane = (scene.surfaces.iter())
        .find(|s| matches!(s.geometry, Geometry::Quad { .. }))
        .unwrap()
        .clone();
    plane.geometry = Geometry::Plane {
        point: Vec3::new(0.0, 8.0, 0.0),
        normal: Vec3::new(0.0, 1.0, 0.0),
        u_axis: Vec3::new(1.0, 0.0, 0.0),
        v_axis: Vec3::new(0.0, 0.0, 1.0),
    };
    let mut sliced = scene.clone();
    sliced.surfaces.push(plane);
    for scene in [scene, low, sliced] {
        check_uniform_light(&scene);
    }
}

fn check_uniform_light(scene: &Scene) {
    let frame = Frame::new(scene);
    let (surface, mesh) = (scene.surfaces.iter().enumerate())
        .find_map(|(i, s)| match &s.geometry {
            Geometry::Mesh(m) => Some((i, m.clone())),
            _ => None,
        })
        .unwrap();
    let (mut shown, mut lit, mut varies) = (0, 0, 0);
    // Every triangle within 150 m of the runway (10 m cells: some
    // wholly under it, some across its sides), every 7th elsewhere.
    let near_runway = |t: u32| {
        (mesh.corners(t as usize).unwrap())
            .iter()
            .any(|p| p.x.abs() < 150.0 && (-1950.0..150.0).contains(&p.z))
    };
    for t in (0..mesh.len() as u32).filter(|&t| t % 7 == 0 || near_runway(t)) {
        let Some(view) = scene.surfaces[surface]
            .geometry
            .planar(t)
            .and_then(|p| View::new(scene, surface, &p))
        else {
            continue;
        };
        let Some(k) = uniform_light(&frame, &view) else {
            varies += 1;
            continue;
        };
        shown += 1;
        let [a, b, c] = mesh.corners(t as usize).unwrap();
        let points = [
            (0.2, 0.2),
            (0.6, 0.2),
            (0.2, 0.6),
            (0.45, 0.1),
            (0.05, 0.9),
            (0.0, 0.0),
            (1.0, 0.0),
            (0.0, 1.0),
            (0.5, 0.5),
            (0.3, 0.0),
        ];
        for (u, v) in points {
            let p = a + (b - a) * u + (c - a) * v;
            let Some(s) = scene.camera.project(p) else {
                continue;
            };
            // A region whose centroid is `s`.
            let region = ConvexPolygon::new(&[
                [s[0] - 1e-4, s[1] - 1e-4],
                [s[0] + 2e-4, s[1] - 1e-4],
                [s[0] - 1e-4, s[1] + 2e-4],
            ])
            .unwrap();
            let mut own = [1.0; 4];
            light_region(&frame, &view, &region, &mut own);
            let mut uniform = [1.0; 4];
            apply_light(&mut uniform, k);
            assert_eq!(own, uniform, "triangle {t} at {u}, {v}");
        }
        lit += usize::from(k != crate::frame::lit_factor(&scene.lighting, 0.0));
    }
    assert!(
        shown > 500 && varies > 500 && lit > 200,
        "{shown} {varies} {lit}"
    );
}

/// RMS over every 7th pixel of row `y` of `scenes/checker.toml` at
/// 960×540: default options against the finished integral.
fn row_rms(y: f64) -> f64 {
    let mut scene = crate::load_scene(
        std::path::Path::new("../../scenes/checker.toml"),
        &quadtex_io::Limits::default(),
    )
    .unwrap();
    scene.camera = scene.camera.with_size(960, 540);
    let surface = &scene.surfaces[0];
    let view = View::new(&scene, 0, &surface.geometry.planar(0).unwrap()).unwrap();
    let texture = surface.texture.as_ref().unwrap().texture(surface.wrap);
    let finished = FilterOptions::RENDER
        .with_error_bound(1e-6)
        .and_then(|o| o.with_budget(1 << 18))
        .unwrap();
    let (mut sum, mut n) = (0.0, 0);
    for px in (0..960).step_by(7) {
        let x = f64::from(px);
        let support = ConvexPolygon::rect(x, y, x + 1.0, y + 1.0);
        let centre = [x + 0.5, y + 0.5];
        let get = |o: &FilterOptions| {
            view.texture_integral(&texture, &support, PixelFilter::Box, centre, o)
        };
        let (quick, exact) = (get(&FilterOptions::RENDER), get(&finished));
        assert!(exact.error_bound < 1e-4 * exact.weight, "{exact:?}");
        let d = quick.mean().unwrap().r - exact.mean().unwrap().r;
        assert!(f64::from(d.abs()) <= quick.error_bound / quick.weight + 1e-4);
        sum += f64::from(d * d);
        n += 1;
    }
    (sum / f64::from(n)).sqrt()
}

/// The sky taken at a pixel's centre is within its stated bound of
/// the pixel's mean (a 64 × 64 midpoint grid, itself far closer), on
/// every row of a small frame (coarse pixels: the loosest case); the
/// bound is not vacuous (some pixel comes close to it) and refuses the
/// rows at the level line.
/// Each view's area in a cut, by view index.
fn areas_by_view(cut: &Cut, regions: &[ConvexPolygon], views: usize) -> Vec<f64> {
    let mut areas = vec![0.0; views];
    for (v, region) in cut.visible(regions) {
        areas[v] += region.area();
    }
    areas
}

/// The cut of `support` among `regions` when they tile it.
fn tiling(regions: &[ConvexPolygon], support: &ConvexPolygon) -> Option<Cut> {
    let mut cut = Cut {
        sliver_area: GAP_AREA * support.area(),
        ..Cut::default()
    };
    cut.tiling(regions, support).then_some(cut)
}

#[test]
fn regions_that_tile_the_support_are_taken_whole() {
    let support = ConvexPolygon::rect(10.0, 20.0, 11.0, 21.0);
    let sliver = GAP_AREA * support.area();
    let tri = |v: &[[f64; 2]]| ConvexPolygon::new(v).unwrap();
    // Fans around random inner points: four triangles that tile the
    // pixel, each taken whole, as cutting them one by one gives.
    let mut seed = 7u64;
    let mut next = || {
        seed = seed.wrapping_mul(6_364_136_223_846_793_005).wrapping_add(1);
        0.05 + 0.9 * ((seed >> 11) as f64 / (1u64 << 53) as f64)
    };
    let corners = [[10.0, 20.0], [11.0, 20.0], [11.0, 21.0], [10.0, 21.0]];
    for _ in 0..200 {
        let p = [10.0 + next(), 20.0 + next()];
        let fan: Vec<ConvexPolygon> = (0..4)
            .map(|i| tri(&[corners[i], corners[(i + 1) % 4], p]))
            .collect();
        let whole = tiling(&fan, &support).expect("a fan tiles the pixel");
        assert!(whole.whole == fan.len() && whole.visible_regions.is_empty());
        assert_eq!(whole.visible(&fan).count(), 4);
        assert!(whole.remaining.is_empty() && whole.slivers.is_empty());
        assert!(whole.unaccounted <= 3.0 * sliver, "{}", whole.unaccounted);
        let mut cut = Cut {
            remaining: vec![support.clone()],
            sliver_area: sliver,
            ..Cut::default()
        };
        for (v, region) in fan.iter().enumerate() {
            cut.take(v, region);
        }
        for (a, b) in areas_by_view(&whole, &fan, 4)
            .iter()
            .zip(areas_by_view(&cut, &fan, 4))
        {
            assert!((a - b).abs() < 1e-12, "{a} vs {b}");
        }
    }
    // A repeated vertex (a clip through a corner) separates nothing:
    // overlapping halves that leave a gap of the same area are still
    // not a tiling.
    let left =
        ConvexPolygon::new(&[[10.0, 20.0], [10.5, 20.0], [10.5, 21.0], [10.0, 21.0]]).unwrap();
    let twice = |p: [f64; 2]| [p, p];
    let right = [[10.4, 20.0], [10.9, 20.0], [10.9, 21.0], [10.4, 21.0]]
        .into_iter()
        .flat_map(twice)
        .collect::<Vec<_>>();
    let right = ConvexPolygon::new(&right).unwrap();
    let boxes = (left.bounds(), right.bounds());
    assert_eq!(overlap_bound((&left, boxes.0), (&right, boxes.1)), None);
    assert_eq!(overlap_bound((&right, boxes.1), (&left, boxes.0)), None);
    assert!(tiling(&[left, right], &support).is_none());
    // A gap: not a tiling.
    let lower = tri(&[[10.0, 20.0], [11.0, 20.0], [11.0, 21.0]]);
    assert!(tiling(std::slice::from_ref(&lower), &support).is_none());
    // Areas that add up to the pixel's, but overlap (and leave a gap).
    let left = ConvexPolygon::rect(10.0, 20.0, 10.5, 21.0);
    let right = ConvexPolygon::rect(10.4, 20.0, 10.9, 21.0);
    assert!((left.area() + right.area() - support.area()).abs() < 1e-12);
    assert!(tiling(&[left, right], &support).is_none());
}

/// Regions that lie apart but leave gaps (a fan with triangles left
/// out): each is taken whole, and what is left of the support, the
/// gaps, is what cutting them one by one leaves; regions that overlap
/// are not taken so.
#[test]
fn regions_apart_with_gaps_are_taken_whole() {
    let support = ConvexPolygon::rect(10.0, 20.0, 11.0, 21.0);
    let sliver = GAP_AREA * support.area();
    let tri = |v: &[[f64; 2]]| ConvexPolygon::new(v).unwrap();
    let mut seed = 11u64;
    let mut next = || {
        seed = seed.wrapping_mul(6_364_136_223_846_793_005).wrapping_add(1);
        0.05 + 0.9 * ((seed >> 11) as f64 / (1u64 << 53) as f64)
    };
    let corners = [[10.0, 20.0], [11.0, 20.0], [11.0, 21.0], [10.0, 21.0]];
    let new_cut = || Cut {
        sliver_area: sliver,
        ..Cut::default()
    };
    for k in 0..200 {
        let p = [10.0 + next(), 20.0 + next()];
        // One to three of the fan's four triangles, and an empty region.
        let fan: Vec<ConvexPolygon> = (0..4)
            .filter(|i| (k >> i) % 2 == 1 || *i == k % 4)
            .map(|i| tri(&[corners[i], corners[(i + 1) % 4], p]))
            .take(3)
            .chain([ConvexPolygon::empty()])
            .collect();
        let mut whole = new_cut();
        assert!(whole.taken_whole(&fan, &support));
        assert_eq!(whole.whole, fan.len());
        assert!(whole.visible_regions.is_empty());
        assert_eq!(whole.visible(&fan).count(), fan.len() - 1);
        let mut cut = Cut {
            remaining: vec![support.clone()],
            ..new_cut()
        };
        for (v, region) in fan.iter().enumerate() {
            cut.take(v, region);
        }
        for (a, b) in areas_by_view(&whole, &fan, fan.len())
            .iter()
            .zip(areas_by_view(&cut, &fan, fan.len()))
        {
            assert!((a - b).abs() < 1e-12, "{a} vs {b}");
        }
        let left = |c: &Cut| c.remaining.iter().map(ConvexPolygon::area).sum::<f64>();
        let covered: f64 = fan.iter().map(ConvexPolygon::area).sum();
        assert!((left(&whole) - (support.area() - covered)).abs() < 1e-12);
        assert!((left(&whole) - left(&cut)).abs() < 1e-12);
        assert!(whole.unaccounted <= 2.0 * sliver, "{}", whole.unaccounted);
        // Cut again with a region over the others: as cut front to
        // back from the start.
        let over = ConvexPolygon::rect(10.2, 20.2, 10.6, 20.7);
        let mut regions = fan.clone();
        regions.push(over);
        whole.visible_from_whole(&regions);
        assert_eq!(whole.whole, 0);
        assert_eq!(whole.visible_regions.len(), fan.len() - 1);
    }
    // Overlapping regions that cover less than the support: cut.
    let left = ConvexPolygon::rect(10.0, 20.0, 10.5, 21.0);
    let right = ConvexPolygon::rect(10.4, 20.0, 10.8, 21.0);
    let mut cut = new_cut();
    assert!(!cut.taken_whole(&[left, right], &support));
    assert_eq!(cut.whole, 0);
    assert!(cut.remaining.is_empty());
}

/// Triangles of a fan that share an edge, one of them with its inner
/// corner moved a hair across it (as rounding leaves clipped regions):
/// the bound holds the overlap and is of the hair's size; moved a
/// visible amount across, no bound (the overlap is measured); moved
/// away, none at all.
#[test]
fn a_hair_across_a_shared_edge_is_bounded_not_clipped() {
    let tri = |v: &[[f64; 2]]| ConvexPolygon::new(v).unwrap();
    let mut seed = 5u64;
    let mut next = || {
        seed = seed.wrapping_mul(6_364_136_223_846_793_005).wrapping_add(1);
        (seed >> 11) as f64 / (1u64 << 53) as f64
    };
    for _ in 0..500 {
        let (x, y) = (1000.0 * next(), 1000.0 * next());
        let p = [x + 0.1 + 0.8 * next(), y + 0.1 + 0.8 * next()];
        let (a, b, c) = ([x, y], [x + 1.0, y], [x + 1.0, y + 1.0]);
        let left = tri(&[a, b, p]);
        // The shared edge is b–p; `right` is beyond it.
        // Some twenty ulps of the coordinates: rounding's size.
        let hair = 2e-15 * (x + y + 1.0);
        for (shift, expect) in [(hair, Some(())), (1e-3, None), (-1e-6, Some(()))] {
            // Moved along the normal of b–p, into `left`.
            let (dx, dy) = (p[0] - b[0], p[1] - b[1]);
            let n = (dx * dx + dy * dy).sqrt();
            let q = [p[0] - dy / n * shift, p[1] + dx / n * shift];
            let right = tri(&[b, c, q]);
            let bound = overlap_bound((&left, left.bounds()), (&right, right.bounds()));
            match expect {
                Some(()) => {
                    let bound = bound.expect("a hair's overlap is bounded");
                    // The overlap's area, measured near the origin (the
                    // same polygons, moved exactly: Sterbenz), where
                    // its rounding is far below the hair's.
                    let moved = |t: &ConvexPolygon| {
                        let v: Vec<[f64; 2]> =
                            t.vertices().iter().map(|&[u, v]| [u - x, v - y]).collect();
                        ConvexPolygon::new(&v).unwrap()
                    };
                    let overlap = moved(&left).intersect(&moved(&right)).area();
                    assert!(bound >= overlap && bound < 1e-9, "{bound} {overlap}");
                    if shift < 0.0 {
                        assert_eq!(bound, 0.0);
                    }
                }
                None => assert_eq!(bound, None),
            }
        }
    }
}

/// Views inserted one by one into a cut that left a gap
/// ([`Cut::insert`]) give each view the area cutting the support again
/// with every view front to back gives it, and leave the same area
/// uncovered: a fan that tiles the pixel, one triangle of it missing
/// at first, and random triangles over and under it (planes facing
/// the camera, each at its own depth).
#[test]
fn inserting_views_gives_what_cutting_again_gives() {
    let support = ConvexPolygon::rect(10.0, 20.0, 11.0, 21.0);
    let sliver = GAP_AREA * support.area();
    let mut seed = 5u64;
    let mut next = || {
        seed = seed.wrapping_mul(6_364_136_223_846_793_005).wrapping_add(1);
        (seed >> 11) as f64 / (1u64 << 53) as f64
    };
    let view_at = |depth: f64| ViewRef::Built(Rc::new(View::facing_at(depth)));
    let corners = [[10.0, 20.0], [11.0, 20.0], [11.0, 21.0], [10.0, 21.0]];
    let (mut carved, mut hidden) = (0, 0);
    for round in 0..300 {
        let p = [10.05 + 0.9 * next(), 20.05 + 0.9 * next()];
        let mut regions: Vec<ConvexPolygon> = (0..4)
            .map(|i| ConvexPolygon::new(&[corners[i], corners[(i + 1) % 4], p]).unwrap())
            .collect();
        let mut views: Vec<ViewRef<'_>> = (0..4).map(|_| view_at(10.0)).collect();
        for _ in 0..1 + round % 4 {
            let v: Vec<[f64; 2]> = (0..3)
                .map(|_| [9.8 + 1.4 * next(), 19.8 + 1.4 * next()])
                .collect();
            let t = ConvexPolygon::hull(&v).intersect(&support);
            if !t.is_empty() {
                regions.push(t);
                views.push(view_at(5.0 + 10.0 * next()));
            }
        }
        let (listed, n) = (3 + round % 2, regions.len());
        let mut order = Order::default();
        let mut cut = Cut {
            remaining: vec![support.clone()],
            sliver_area: sliver,
            ..Cut::default()
        };
        order.front_to_back(&views[..listed], &regions[..listed], 0.0);
        for &v in &order.order {
            cut.take(v, &regions[v]);
        }
        for v in listed..n {
            cut.insert(v, &views, &regions);
        }
        let mut again = Cut::default();
        again.among(&views, &regions, &support, &mut order);
        let a = areas_by_view(&cut, &regions, n);
        for (v, (&a, b)) in a.iter().zip(areas_by_view(&again, &regions, n)).enumerate() {
            assert!((a - b).abs() < 1e-12, "round {round}, view {v}: {a} vs {b}");
            carved += usize::from(v < listed && a < regions[v].area() - 1e-6);
            hidden += usize::from(v >= listed && a < regions[v].area() - 1e-6);
        }
        let left = |c: &Cut| c.remaining.iter().map(ConvexPolygon::area).sum::<f64>();
        assert!((left(&cut) - left(&again)).abs() < 1e-12, "round {round}");
    }
    // Both ways happen: views listed first lose area to views inserted
    // in front of them, and inserted views to views in front of them.
    assert!(carved > 100 && hidden > 100, "{carved} {hidden}");
}

/// The sky over the part of a pixel above the level line (where the
/// gradient's square root has an unbounded derivative), by the graded
/// rows of [`sky_integral`], is within the sky's tolerance (a quarter of
/// the default error bound) of a dense midpoint sum (16 columns × 4096
/// rows, itself within about 1e-8 there), at two resolutions (the
/// coarser one has the steeper gradient per pixel). Measured: 8.7e-5
/// at 960×540 and 2.7e-4 at 96×54 (its coarsest graded rows; eight
/// halvings or twenty differ by under 1e-6).
#[test]
fn the_sky_at_the_level_line_matches_a_dense_sum() {
    for (width, height) in [(960, 540), (96, 54)] {
        let scene = demo_at(width, height);
        let mut worst = 0.0f64;
        for x in (0..width).step_by(width as usize / 7) {
            let x = f64::from(x);
            let yh = level_line(&scene, x + 0.5).unwrap();
            let y0 = yh.floor();
            if yh - y0 < 1e-3 {
                continue;
            }
            let region = ConvexPolygon::rect(x, y0, x + 1.0, yh);
            let (c, w) = sky_integral(
                &scene,
                &region,
                Whole::Unknown,
                PixelFilter::Box,
                [x + 0.5, y0 + 0.5],
                sky_tolerance(&FilterOptions::RENDER),
            );
            let (nx, ny) = (16, 4096);
            let (dx, dy) = (1.0 / f64::from(nx), (yh - y0) / f64::from(ny));
            let mut dense = [0.0; 4];
            for j in 0..ny {
                for i in 0..nx {
                    let s = [
                        x + (f64::from(i) + 0.5) * dx,
                        y0 + (f64::from(j) + 0.5) * dy,
                    ];
                    let v = sky(&scene, &scene.camera.ray(s[0], s[1])).to_array();
                    for (d, v) in dense.iter_mut().zip(v) {
                        *d += f64::from(v) * dx * dy;
                    }
                }
            }
            // The rectangle's area exactly (`ConvexPolygon::area`'s
            // shoelace over coordinates near 10³ is off by up to 10⁻¹¹).
            assert!((w - (yh - y0)).abs() < 1e-12, "{w} vs {}", yh - y0);
            let error = (0..4)
                .map(|k| (c[k] - dense[k]).abs() / w)
                .fold(0.0, f64::max);
            worst = worst.max(error);
            assert!(
                error <= sky_tolerance(&FilterOptions::RENDER),
                "{width}x{height}, pixel x {x}: off by {error}"
            );
        }
        eprintln!("{width}x{height}: the level line's sky off by {worst} at most");
    }
}

/// The sky's cells over a tent's or Mitchell's support cut by the ground
/// (random half-planes, one or two) add up to the filter's exact weight
/// over the region: a cell taken whole where it crosses the region's
/// edge (the run of inside corners along a row line found from each end)
/// would add its outside part, a sixteenth of a pixel times the filter's
/// weight there. And the colour is a mean of the sky's.
#[test]
fn the_skys_cells_weigh_what_the_region_does() {
    let scene = demo_at(960, 540);
    let mut seed = 11u64;
    let mut next = || {
        seed = seed.wrapping_mul(6_364_136_223_846_793_005).wrapping_add(1);
        (seed >> 11) as f64 / (1u64 << 53) as f64
    };
    let (mut cases, mut crossed) = (0, 0);
    for case in 0..400 {
        let filter = [PixelFilter::Tent, PixelFilter::Mitchell][case % 2];
        let centre = [
            (100.0 + 700.0 * next()).floor() + 0.5,
            (150.0 + 200.0 * next()).floor() + 0.5,
        ];
        let r = filter.radius();
        let mut region = filter.support(centre);
        for _ in 0..1 + case % 2 {
            // A line through a point of the support, at any angle, keeping
            // the side that holds the point above it.
            let p = [
                centre[0] + r * (2.0 * next() - 1.0),
                centre[1] + r * (2.0 * next() - 1.0),
            ];
            let angle = std::f64::consts::TAU * next();
            let (a, b) = (angle.cos(), angle.sin());
            region = region.clip(a, b, -(a * p[0] + b * p[1]));
        }
        if region.area() < 1e-3 {
            continue;
        }
        cases += 1;
        crossed += usize::from(region.area() < filter.support(centre).area() - 1e-9);
        let (c, w) = sky_integral(
            &scene,
            &region,
            Whole::Unknown,
            filter,
            centre,
            sky_tolerance(&FilterOptions::RENDER),
        );
        let exact = filter.integral(&region, centre);
        assert!(
            (w - exact).abs() <= 1e-9,
            "case {case}, {filter:?}: weight {w} against {exact}"
        );
        if exact.abs() > 1e-3 {
            for (k, v) in c.iter().enumerate() {
                let mean = v / w;
                assert!(
                    mean.is_finite() && mean > -0.5 && mean < 2.0,
                    "case {case}, channel {k}: mean {mean}"
                );
            }
        }
    }
    assert!(cases > 300 && crossed > 300, "{cases} {crossed}");
}

/// Above [`sky_clear_above`], [`sky_at_centre`] always accepts its
/// value (bound within the tolerance), so the sky pixel's shortcut
/// gives what it would: every pixel of two frames, the default and a
/// tight tolerance, under each pixel filter (the support's lowest ray
/// `√2·r·g` below the centre's). Most sky pixels take the shortcut, and
/// the height is not far above where the bound reaches the tolerance.
#[test]
fn the_sky_shortcut_takes_only_pixels_the_bound_accepts() {
    for filter in [PixelFilter::Box, PixelFilter::Tent, PixelFilter::Mitchell] {
        for (width, height) in [(192, 108), (1920, 1080)] {
            let scene = demo_at(width, height);
            for tolerance in [sky_tolerance(&FilterOptions::RENDER), 1e-7] {
                let clear = sky_clear_above(&scene, tolerance, filter);
                let g = sky_step(&scene);
                let reach = std::f64::consts::SQRT_2 * filter.radius() * g;
                let (mut shortcut, mut sky_rows) = (0, 0);
                for y in (0..height).step_by(height as usize / 54) {
                    for x in (0..width).step_by(width as usize / 24) {
                        let centre = [f64::from(x) + 0.5, f64::from(y) + 0.5];
                        let ray = scene.camera.ray(centre[0], centre[1]);
                        let y_min = ray.direction.y - reach;
                        if y_min > 0.0 {
                            sky_rows += 1;
                        }
                        if y_min >= clear {
                            shortcut += 1;
                            let (c, bound) = sky_at_centre(&scene, centre, filter).unwrap();
                            assert!(
                                bound <= tolerance,
                                "{filter:?}: {bound} > {tolerance} at {centre:?}"
                            );
                            assert_eq!(c, sky(&scene, &ray).to_array().map(f64::from));
                        }
                    }
                }
                assert!(
                    tolerance < 1e-6 || (clear.is_finite() && 2 * shortcut > sky_rows),
                    "{filter:?}, {width}x{height}: {shortcut} of {sky_rows} sky samples"
                );
                // A percent below the height the bound is past half the
                // tolerance: the bisection found the height, not a loose one.
                let crate::scene::Sky::Gradient { horizon, zenith } = scene.sky else {
                    panic!("the demo's sky is a gradient");
                };
                let contrast = sky_contrast(horizon, zenith);
                let at = if clear.is_finite() { clear * 0.99 } else { 1.0 };
                assert!(sky_bound_under(g, contrast, at, filter) > 0.5 * tolerance);
            }
        }
    }
}

/// The largest channel difference between `c` and the sky's `k`-weighted
/// mean over the support of `filter` at `centre`, by the midpoint rule on
/// an `n × n` grid.
fn off_from_dense_sky(
    scene: &Scene,
    centre: [f64; 2],
    filter: PixelFilter,
    c: [f64; 4],
    n: u32,
) -> f64 {
    let r = filter.radius();
    let (mut dense, mut total) = ([0.0; 4], 0.0);
    for j in 0..n {
        for i in 0..n {
            let d = [
                -r + 2.0 * r * (f64::from(i) + 0.5) / f64::from(n),
                -r + 2.0 * r * (f64::from(j) + 0.5) / f64::from(n),
            ];
            let w = filter.weight(d[0], d[1]);
            let s = [centre[0] + d[0], centre[1] + d[1]];
            let v = sky(scene, &scene.camera.ray(s[0], s[1])).to_array();
            for (a, v) in dense.iter_mut().zip(v) {
                *a += f64::from(v) * w;
            }
            total += w;
        }
    }
    c.iter()
        .zip(dense)
        .map(|(a, b)| (a - b / total).abs())
        .fold(0.0, f64::max)
}

/// Each filter's second moment `∫∫ |δ|²·|k(δ)|` is at least a dense sum's
/// (and within 10⁻³ of it: the bounds using it are not loose).
#[test]
fn second_moments_hold_the_filters() {
    for filter in [PixelFilter::Box, PixelFilter::Tent, PixelFilter::Mitchell] {
        let r = filter.radius();
        let n = 200_000;
        let h = 2.0 * r / f64::from(n);
        let (mut a0, mut a2) = (0.0, 0.0);
        for i in 0..n {
            let x = -r + (f64::from(i) + 0.5) * h;
            let k = filter.k1(x).abs();
            a0 += k * h;
            a2 += x * x * k * h;
        }
        let dense = 2.0 * a0 * a2;
        let m2 = second_moment(filter);
        assert!(
            m2 >= dense - 1e-9 && m2 - dense < 1e-3,
            "{filter:?}: {m2} against {dense}"
        );
    }
}

/// Over a whole box, tent or Mitchell support clear of the level line,
/// the sky's centre value is within its bound of a dense `k`-weighted
/// sum; supports reaching the level line are refused; and the bound is
/// not vacuous (approached to a twentieth of itself for the box, a fiftieth
/// for the wider filters).
#[test]
fn the_sky_at_a_supports_centre_is_within_its_bound() {
    let scene = demo_at(96, 54);
    for (filter, n, near) in [
        (PixelFilter::Box, 64, 0.05),
        (PixelFilter::Tent, 96, 0.02),
        (PixelFilter::Mitchell, 96, 0.02),
    ] {
        let (mut refused, mut closest) = (0, 0.0f64);
        for y in 0..54 {
            for x in (0..96).step_by(13) {
                let centre = [f64::from(x) + 0.5, f64::from(y) + 0.5];
                let Some((c, bound)) = sky_at_centre(&scene, centre, filter) else {
                    refused += 1;
                    continue;
                };
                let error = off_from_dense_sky(&scene, centre, filter, c, n);
                assert!(
                    error <= bound * 1.001 + 1e-6,
                    "{filter:?} at {centre:?}: off by {error}, bound {bound}"
                );
                if bound > 1e-4 {
                    closest = closest.max(error / bound);
                }
            }
        }
        assert!(
            refused > 0,
            "{filter:?}: no support at the level line was refused"
        );
        eprintln!("{filter:?}: closest approach to the bound {closest}");
        assert!(
            closest > near,
            "{filter:?}: the bound is vacuous: at most {closest} of it"
        );
    }
}

/// The corner decisions agree with the clip they stand in for: over
/// the demo's planes and quads and every 5th pixel of a 192×108 frame
/// (box and Mitchell supports), `misses` is the clipped region's
/// emptiness and `region` is the clip itself, and each of the three
/// placements occurs.
#[test]
fn corner_decisions_agree_with_clipping() {
    let scene = demo_at(192, 108);
    let views = SurfaceViews::new(&scene);
    let mut seen = [0usize; 3];
    for view in views.views.iter().flatten() {
        for y in (0..108).step_by(5) {
            for x in (0..192).step_by(5) {
                let centre = [f64::from(x) + 0.5, f64::from(y) + 0.5];
                for filter in [PixelFilter::Box, PixelFilter::Mitchell] {
                    let support = filter.support(centre);
                    let clipped = support.clip_lines(view.lines());
                    assert_eq!(view.misses(&support), clipped.is_empty());
                    assert_eq!(*view.region(&support), clipped);
                    seen[view.placement(&support) as usize] += 1;
                }
            }
        }
    }
    assert!(seen.iter().all(|&n| n > 0), "placements seen: {seen:?}");
}

/// Pixels just below the checker plane's horizon see thin needles
/// crossing tens of tiles: row 248 (14 tiles, 0.1 tile wide) is
/// scanned cell by cell, exactly (the walk, cut short by its budget,
/// was off there by RMS 0.044 before the fallback and 0.009 with it).
/// Row 243, hundreds of tiles long, has too many cells: the walk and
/// its coarse fallback answer, within their bound.
#[test]
fn horizon_needles_are_scanned_or_fall_back() {
    let scanned = row_rms(248.0);
    assert!(scanned < 1e-6, "row 248: RMS {scanned}");
    let walked = row_rms(243.0);
    eprintln!("row 243: RMS {walked}");
    assert!(walked < 0.01, "row 243: RMS {walked}");
}

/// A span's one test answers every pixel of it as the pixel's own test
/// would: over the demo's sky with 300 small quads scattered in it
/// (their corners poking into spans anywhere, at the span's ends too),
/// box and Mitchell supports, row by row, pixel by pixel.
#[test]
fn a_sky_span_answers_each_pixel_as_its_own_test() {
    let mut scene = demo_at(320, 180);
    let mut seed = 17u64;
    let mut next = || crate::math::unit_random(&mut seed);
    for _ in 0..300 {
        let size = 0.5 + 6.0 * next();
        scene.surfaces.push(crate::scene::Surface {
            geometry: Geometry::Quad {
                origin: Vec3::new(
                    -150.0 + 300.0 * next(),
                    16.0 + 60.0 * next(),
                    -350.0 + 400.0 * next(),
                ),
                edge_u: Vec3::new(size, 0.0, size * (next() - 0.5)),
                edge_v: Vec3::new(0.0, size, 0.0),
            },
            texture: None,
            colour: Rgba::opaque(1.0, 1.0, 1.0),
            uv_transform: crate::scene::UvTransform::default(),
            wrap: quadtex_core::Wrap::CLAMP,
        });
    }
    let cache = SurfaceViews::new(&scene);
    for filter in [PixelFilter::Box, PixelFilter::Mitchell] {
        let (mut clear, mut missed, mut hit) = (0, 0, 0);
        for y in 0..180 {
            let mut span = SkySpan::default();
            for x in 0..320 {
                let support = filter.support([f64::from(x) + 0.5, f64::from(y) + 0.5]);
                let own = cache.views.iter().flatten().all(|v| v.misses(&support));
                let spanned = views_miss(&cache, &mut span, filter, (x, y), &support);
                assert_eq!(spanned, own, "{filter:?} pixel ({x}, {y})");
                clear += usize::from(span.clear);
                if own { missed += 1 } else { hit += 1 }
            }
        }
        // Both outcomes, and spans that failed among pixels that miss.
        assert!(
            clear > 1000 && hit > 1000 && missed > clear,
            "{clear} {missed} {hit}"
        );
    }
}

/// A piece split along a row's pixel sides ([`pixel::by_column`]):
/// the parts lie in their columns (to rounding), their areas add up to
/// the piece's, a piece within one column is given whole, and parts past
/// the row's ends (rounding, or a piece that pokes out) go to the end
/// columns.
#[test]
fn pieces_split_by_column_tile_the_piece() {
    let mut seed = 5u64;
    let mut next = || crate::math::unit_random(&mut seed);
    let mut buffers = Default::default();
    let (mut split, mut whole) = (0, 0);
    for _ in 0..2000 {
        let columns = 1 + (next() * 8.0) as usize;
        let left = (next() * 100.0).floor();
        let points: Vec<[f64; 2]> = (0..6)
            .map(|_| [left - 0.3 + next() * (columns as f64 + 0.6), 3.0 + next()])
            .collect();
        let piece = ConvexPolygon::hull(&points);
        let mut total = 0.0;
        let mut parts = 0;
        pixel::by_column(&piece, left, columns, &mut buffers, |c, part| {
            assert!(c < columns);
            let (lo, hi) = part.bounds();
            let (x0, x1) = (left + c as f64, left + c as f64 + 1.0);
            if c > 0 {
                assert!(lo[0] >= x0 - 1e-9, "column {c}: {lo:?}");
            }
            if c + 1 < columns {
                assert!(hi[0] <= x1 + 1e-9, "column {c}: {hi:?}");
            }
            total += part.area();
            parts += 1;
        });
        assert!(
            (total - piece.area()).abs() <= 1e-12 * piece.area().max(1.0),
            "{total} against {}",
            piece.area()
        );
        if parts == 1 { whole += 1 } else { split += 1 }
    }
    assert!(split > 1000 && whole > 100, "{split} split, {whole} whole");
}

/// Where an order front to back exists, cutting each view's region by
/// the regions of the views in front of it
/// ([`Cut::each_behind_those_in_front`], what a cyclic support takes)
/// gives each view the area the cut front to back gives it, and leaves
/// the same area uncovered: random triangles over a pixel, each a plane
/// facing the camera at its own depth, overlapping and not.
#[test]
fn views_cut_by_those_in_front_match_the_order() {
    let support = ConvexPolygon::rect(10.0, 20.0, 11.0, 21.0);
    let sliver = GAP_AREA * support.area();
    let mut seed = 9u64;
    let mut next = || crate::math::unit_random(&mut seed);
    let view_at = |depth: f64| ViewRef::Built(Rc::new(View::facing_at(depth)));
    let mut overlapping = 0;
    for round in 0..300 {
        let (mut regions, mut views) = (Vec::new(), Vec::new());
        for _ in 0..2 + round % 7 {
            let v: Vec<[f64; 2]> = (0..3)
                .map(|_| [9.7 + 1.6 * next(), 19.7 + 1.6 * next()])
                .collect();
            regions.push(ConvexPolygon::hull(&v).intersect(&support));
            views.push(view_at(1.0 + 10.0 * next()));
        }
        let n = regions.len();
        let mut ordered = Cut::default();
        let mut order = Order::default();
        ordered.among(&views, &regions, &support, &mut order);
        let mut pairwise = Cut {
            remaining: vec![support.clone()],
            sliver_area: sliver,
            ..Cut::default()
        };
        order.front_to_back(&views, &regions, sliver);
        assert!(!order.cyclic, "round {round}");
        pairwise.each_behind_those_in_front(&regions, &order, support.area());
        // Nothing lost: the pieces, the parts left and the slivers tile
        // the support.
        assert!(
            pairwise.unaccounted < 1e-12,
            "round {round}: {}",
            pairwise.unaccounted
        );
        let (a, b) = (
            areas_by_view(&ordered, &regions, n),
            areas_by_view(&pairwise, &regions, n),
        );
        for (v, (a, b)) in a.iter().zip(&b).enumerate() {
            assert!((a - b).abs() < 1e-12, "round {round}, view {v}: {a} vs {b}");
        }
        let left = |c: &Cut| c.remaining.iter().map(ConvexPolygon::area).sum::<f64>();
        assert!(
            (left(&ordered) - left(&pairwise)).abs() < 1e-12,
            "round {round}"
        );
        let total: f64 = regions.iter().map(ConvexPolygon::area).sum();
        overlapping += usize::from(a.iter().sum::<f64>() < total - 1e-6);
    }
    assert!(
        overlapping > 100,
        "{overlapping} rounds with views hidden in part"
    );
}
