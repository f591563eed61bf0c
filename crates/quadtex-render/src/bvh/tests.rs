use super::*;

use crate::math::unit_random as rng;

/// Triangles as (a, b, c).
fn soup(n: usize, seed: &mut u64) -> Vec<[Vec3; 3]> {
    (0..n)
        .map(|_| {
            let c = Vec3::new(rng(seed) * 10.0, rng(seed) * 10.0, rng(seed) * 10.0);
            let mut p = || Vec3::new(rng(seed) - 0.5, rng(seed) - 0.5, rng(seed) - 0.5);
            [c + p(), c + p(), c + p()]
        })
        .collect()
}

fn crossing(t: &[Vec3; 3], ray: &Ray) -> Option<f64> {
    let (e1, e2) = (t[1] - t[0], t[2] - t[0]);
    let p = ray.direction.cross(e2);
    let det = e1.dot(p);
    if det.abs() < 1e-14 {
        return None;
    }
    let s = ray.origin - t[0];
    let b1 = s.dot(p) / det;
    let q = s.cross(e1);
    let b2 = ray.direction.dot(q) / det;
    let d = e2.dot(q) / det;
    ((0.0..=1.0).contains(&b1) && b2 >= 0.0 && b1 + b2 <= 1.0 && d > 1e-9).then_some(d)
}

/// A ray parallel to a slab and lying in its plane (an origin on a
/// box's face, a direction with a zero there) is inside that slab:
/// `0·∞` is NaN there, which must keep the interval, on either face and
/// for either sign of zero.
#[test]
fn rays_in_a_face_plane_enter_the_box() {
    let b = Aabb {
        lo: Vec3::new(12.0, 0.0, 44.0),
        hi: Vec3::new(13.0, 1.0, 45.0),
    };
    for (x, z) in [(12.0, 44.0), (13.0, 44.5), (12.5, 45.0), (13.0, 45.0)] {
        for d in [Vec3::new(0.0, 1.0, 0.0), Vec3::new(-0.0, 1.0, -0.0)] {
            let inv = Vec3::new(1.0 / d.x, 1.0 / d.y, 1.0 / d.z);
            let origin = Vec3::new(x, -1.0, z);
            assert_eq!(
                b.entry(origin, inv, f64::INFINITY),
                Some(1.0),
                "{origin:?} {d:?}"
            );
            // Beside the face, it misses.
            let out = |v: f64, lo: f64, hi: f64| match v {
                v if v == lo => v - 1e-9,
                v if v == hi => v + 1e-9,
                v => v,
            };
            let beside = if x == 12.0 || x == 13.0 {
                Vec3::new(out(x, 12.0, 13.0), -1.0, z)
            } else {
                Vec3::new(x, -1.0, out(z, 44.0, 45.0))
            };
            assert_eq!(b.entry(beside, inv, f64::INFINITY), None, "{beside:?}");
        }
    }
}

fn bounds(t: &[Vec3; 3]) -> Aabb {
    let mut b = Aabb::EMPTY;
    for p in t {
        b.grow(*p);
    }
    b
}

/// The build as first written, kept as the slow, obvious reference: each
/// node's bounds from a pass over its primitives, each split's cost
/// from a union over its bins, recursively.
fn reference_partition(boxes: &[Aabb], order: &mut [u32], depth: usize) -> (Aabb, Option<usize>) {
    let centre = |i: u32| {
        let b = &boxes[i as usize];
        (b.lo + b.hi) * 0.5
    };
    let mut bounds = Aabb::EMPTY;
    let mut centres = Aabb::EMPTY;
    for &i in order.iter() {
        bounds.union(&boxes[i as usize]);
        centres.grow(centre(i));
    }
    let extent = centres.hi - centres.lo;
    let axis = if extent.x >= extent.y && extent.x >= extent.z {
        0
    } else if extent.y >= extent.z {
        1
    } else {
        2
    };
    let along = |v: Vec3| [v.x, v.y, v.z][axis];
    let (c0, width) = (along(centres.lo), along(extent));
    if order.len() <= LEAF_SIZE || depth >= MAX_DEPTH || width.is_nan() || width <= 0.0 {
        return (bounds, None);
    }
    let bin_of = |i: u32| (((along(centre(i)) - c0) / width * BINS as f64) as usize).min(BINS - 1);
    let mut bin_bounds = [Aabb::EMPTY; BINS];
    let mut bin_counts = [0usize; BINS];
    for &i in order.iter() {
        let b = bin_of(i);
        bin_bounds[b].union(&boxes[i as usize]);
        bin_counts[b] += 1;
    }
    let mut best = (f64::INFINITY, 0usize);
    for split in 1..BINS {
        let (mut left, mut right) = (Aabb::EMPTY, Aabb::EMPTY);
        let (mut nl, mut nr) = (0, 0);
        for b in 0..split {
            left.union(&bin_bounds[b]);
            nl += bin_counts[b];
        }
        for b in split..BINS {
            right.union(&bin_bounds[b]);
            nr += bin_counts[b];
        }
        if nl == 0 || nr == 0 {
            continue;
        }
        let cost = left.area() * nl as f64 + right.area() * nr as f64;
        if cost < best.0 {
            best = (cost, split);
        }
    }
    if best.1 == 0 {
        return (bounds, None);
    }
    let (mut i, mut j) = (0, order.len());
    while i < j {
        if bin_of(order[i]) < best.1 {
            i += 1;
        } else {
            j -= 1;
            order.swap(i, j);
        }
    }
    (bounds, Some(i))
}

fn reference_subtree(
    boxes: &[Aabb],
    order: &mut [u32],
    base: usize,
    depth: usize,
    nodes: &mut Vec<Node>,
) -> usize {
    let index = nodes.len();
    let (bounds, split) = reference_partition(boxes, order, depth);
    nodes.push(Node {
        bounds,
        start: base as u32,
        count: order.len() as u32,
    });
    if let Some(mid) = split {
        let (left, right) = order.split_at_mut(mid);
        let children = nodes.len();
        nodes.push(nodes[index]);
        nodes.push(nodes[index]);
        let mut sub = Vec::new();
        let l = reference_subtree(boxes, left, base, depth + 1, &mut sub);
        let r = reference_subtree(boxes, right, base + mid, depth + 1, &mut sub);
        let offset = nodes.len();
        let moved = |n: Node| Node {
            start: if n.count > 0 {
                n.start
            } else {
                n.start + offset as u32
            },
            ..n
        };
        nodes[children] = moved(sub[l]);
        nodes[children + 1] = moved(sub[r]);
        nodes.extend(sub.into_iter().map(moved));
        nodes[index].start = children as u32;
        nodes[index].count = 0;
    }
    index
}

/// Whether the subtrees at `a` in `x` and `b` in `y` are the same
/// hierarchy (bounds, shapes, the primitives in each leaf), whatever
/// the nodes' numbering.
fn same_tree(x: &Bvh, a: usize, y: &Bvh, b: usize) -> bool {
    let (m, n) = (&x.nodes[a], &y.nodes[b]);
    if m.bounds != n.bounds || m.count != n.count {
        return false;
    }
    // No primitives: the root is a leaf of none.
    if m.count > 0 || x.order.is_empty() {
        let (s, t) = (m.start as usize, n.start as usize);
        let k = m.count as usize;
        return x.order[s..s + k] == y.order[t..t + k];
    }
    same_tree(x, m.start as usize, y, n.start as usize)
        && same_tree(x, m.start as usize + 1, y, n.start as usize + 1)
}

/// The build (spans from the bins, the costs swept once, the top built
/// on two threads) makes the reference's hierarchy exactly: random
/// soups, a terrain-like grid with ties, identical triangles.
#[test]
fn the_build_matches_the_reference_build() {
    let mut seed = 11;
    let mut grid = Vec::new();
    for i in 0..60 {
        for j in 0..50 {
            let (x, z) = (f64::from(i), f64::from(j));
            let p = |dx: f64, dz: f64| Vec3::new(x + dx, ((x + dx) * 0.3).sin(), z + dz);
            grid.push([p(0.0, 0.0), p(1.0, 0.0), p(1.0, 1.0)]);
            grid.push([p(0.0, 0.0), p(1.0, 1.0), p(0.0, 1.0)]);
        }
    }
    let cases = [
        soup(0, &mut seed),
        soup(1, &mut seed),
        soup(5, &mut seed),
        soup(300, &mut seed),
        soup(70_000, &mut seed),
        grid,
        vec![soup(1, &mut seed)[0]; 50],
    ];
    for tris in &cases {
        let n = tris.len();
        let built = Bvh::build(n, |i| bounds(&tris[i]));
        let boxes: Vec<Aabb> = tris.iter().map(bounds).collect();
        let mut order: Vec<u32> = (0..n as u32).collect();
        let mut nodes = Vec::new();
        reference_subtree(&boxes, &mut order, 0, 0, &mut nodes);
        let reference = Bvh { nodes, order };
        // (The reference keeps unreachable copies: count what a walk reaches.)
        let reached = |bvh: &Bvh| {
            let (mut stack, mut count) = (vec![0usize], 0);
            while let Some(k) = stack.pop() {
                count += 1;
                let node = &bvh.nodes[k];
                if node.count == 0 && !bvh.order.is_empty() {
                    stack.extend([node.start as usize, node.start as usize + 1]);
                }
            }
            count
        };
        assert_eq!(built.nodes.len(), reached(&reference), "n = {n}");
        assert!(same_tree(&built, 0, &reference, 0), "n = {n}");
    }
}

#[test]
fn nearest_hits_match_a_brute_force_scan() {
    let mut seed = 7;
    // 70 000 triangles: built on two threads at the top (PARALLEL_RANGE).
    for n in [1, 3, 50, 2000, 70_000] {
        let tris = soup(n, &mut seed);
        let bvh = Bvh::build(n, |i| bounds(&tris[i]));
        assert!(bvh.node_count() <= 2 * n);
        // The same hierarchy over the triangles moved into leaf order.
        let (mut leaf_bvh, mut leaf) = (bvh.clone(), tris.clone());
        let moved = leaf_bvh.reorder_to_leaves(&mut leaf);
        let mut seen = vec![false; n];
        for (k, &from) in moved.iter().enumerate() {
            assert_eq!(leaf[k], tris[from as usize]);
            assert!(!std::mem::replace(&mut seen[from as usize], true));
        }
        let mut hits = 0;
        let rays = if n > 10_000 { 400 } else { 2000 };
        for k in 0..rays {
            let origin = Vec3::new(
                rng(&mut seed) * 14.0 - 2.0,
                rng(&mut seed) * 14.0 - 2.0,
                -5.0,
            );
            // Every other ray aims at a triangle's centroid, so many hit.
            let target = if k % 2 == 0 {
                let t = &tris[(rng(&mut seed) * n as f64) as usize];
                (t[0] + t[1] + t[2]) * (1.0 / 3.0)
            } else {
                Vec3::new(
                    rng(&mut seed) * 10.0,
                    rng(&mut seed) * 10.0,
                    rng(&mut seed) * 10.0,
                )
            };
            let ray = Ray {
                origin,
                direction: (target - origin).normalized().unwrap(),
            };
            let brute = tris
                .iter()
                .filter_map(|t| crossing(t, &ray))
                .fold(None, |b: Option<f64>, t| Some(b.map_or(t, |b| b.min(t))));
            let found = bvh.nearest(&ray, |i, _| crossing(&tris[i as usize], &ray));
            assert_eq!(found.map(|f| f.1), brute, "n = {n}");
            let in_leaf_order = leaf_bvh.nearest(&ray, |i, _| crossing(&leaf[i as usize], &ray));
            assert_eq!(in_leaf_order.map(|f| f.1), brute, "n = {n}, leaf order");
            // Bounded just above a known hit (here the nearest, or a
            // random triangle's hit behind it): the same hit, the same
            // triangle; bounded at the nearest hit itself, none.
            let t = &tris[(rng(&mut seed) * n as f64) as usize];
            let known = [found.map(|f| f.1), crossing(t, &ray)];
            for t_known in known.into_iter().flatten() {
                let bounded = bvh.nearest_below(&ray, t_known * (1.0 + 1e-9), |i, _| {
                    crossing(&tris[i as usize], &ray)
                });
                assert_eq!(bounded, found, "n = {n}, bounded at {t_known}");
            }
            if let Some((_, t_near)) = found {
                let below =
                    bvh.nearest_below(&ray, t_near, |i, _| crossing(&tris[i as usize], &ray));
                assert_eq!(below, None, "n = {n}");
            }
            // Any hit (shadow rays) exactly when there is a nearest one.
            let any = bvh.any(&ray, |i| crossing(&tris[i as usize], &ray).is_some());
            assert_eq!(any, brute.is_some(), "n = {n}");
            hits += usize::from(brute.is_some());
        }
        assert!(
            hits >= rays * 45 / 100,
            "too few hits to mean anything: {hits}"
        );
    }
}

/// Every box is a conservative test: the frustum query visits every
/// primitive whose vertices are not all outside one plane (the
/// brute-force set), and stops at the first `visit` that says so.
/// The ranges hold each primitive of a leaf the predicate reaches, as
/// the depth-first walk over the same boxes finds them, once, in
/// increasing runs; a predicate that keeps every box gives all.
#[test]
fn leaf_ranges_list_what_the_walk_reaches() {
    let mut seed = 5u64;
    for n in [1, 7, 90, 1500] {
        let mut tris = soup(n, &mut seed);
        let mut bvh = Bvh::build(n, |i| bounds(&tris[i]));
        bvh.reorder_to_leaves(&mut tris);
        assert_eq!(bvh.leaf_ranges(|_| true), vec![0..n]);
        for _ in 0..30 {
            let c = Vec3::new(rng(&mut seed), rng(&mut seed), rng(&mut seed)) * 10.0;
            let r = 0.5 + 3.0 * rng(&mut seed);
            let near = |b: &Aabb| {
                let d = |lo: f64, hi: f64, v: f64| (lo - v).max(v - hi).max(0.0);
                d(b.lo.x, b.hi.x, c.x)
                    .hypot(d(b.lo.y, b.hi.y, c.y))
                    .hypot(d(b.lo.z, b.hi.z, c.z))
                    <= r
            };
            let ranges = bvh.leaf_ranges(near);
            assert!(
                ranges.windows(2).all(|w| w[0].end < w[1].start),
                "runs not increasing, apart"
            );
            let listed: Vec<u32> = ranges
                .iter()
                .flat_map(|r| r.start as u32..r.end as u32)
                .collect();
            let mut walked = Vec::new();
            bvh.first_in(near, |i| {
                walked.push(i);
                false
            });
            walked.sort_unstable();
            assert_eq!(listed, walked, "n = {n}");
            // Every primitive whose own box passes is in a leaf that does.
            for (i, t) in tris.iter().enumerate() {
                if near(&bounds(t)) {
                    assert!(listed.binary_search(&(i as u32)).is_ok(), "{i} missed");
                }
            }
        }
    }
}

#[test]
fn frustum_queries_miss_no_primitive_a_scan_keeps() {
    let mut seed = 11u64;
    for n in [1, 5, 60, 900] {
        let tris = soup(n, &mut seed);
        let bvh = Bvh::build(n, |i| bounds(&tris[i]));
        for _ in 0..40 {
            // Four planes through a random apex around a random axis,
            // and one across it: a pyramid-like frustum.
            let apex = Vec3::new(rng(&mut seed), rng(&mut seed), rng(&mut seed)) * 14.0
                - Vec3::new(2.0, 2.0, 2.0);
            let aim = Vec3::new(5.0, 5.0, 5.0) - apex;
            let spread = 0.05 + rng(&mut seed);
            let axis = aim.normalized().unwrap();
            let side = axis.cross(Vec3::new(0.3, 1.0, 0.1)).normalized().unwrap();
            let up = axis.cross(side);
            let mut planes = vec![[axis.x, axis.y, axis.z, -axis.dot(apex)]];
            for e in [side, -side, up, -up] {
                let n = axis * spread - e;
                planes.push([n.x, n.y, n.z, -n.dot(apex)]);
            }
            let outside = |t: &[Vec3; 3]| {
                planes
                    .iter()
                    .any(|&[x, y, z, d]| t.iter().all(|p| x * p.x + y * p.y + z * p.z + d < 0.0))
            };
            let kept: Vec<u32> = (0..n as u32)
                .filter(|&i| !outside(&tris[i as usize]))
                .collect();
            let mut visited = Vec::new();
            assert!(!bvh.overlapping(
                &planes,
                |_, _| true,
                |i| {
                    visited.push(i);
                    false
                }
            ));
            visited.sort_unstable();
            assert!(visited.windows(2).all(|w| w[0] < w[1]), "visited twice");
            assert!(
                kept.iter().all(|i| visited.binary_search(i).is_ok()),
                "n = {n}"
            );
            if let Some(&first) = kept.first() {
                let mut calls = 0;
                assert!(bvh.overlapping(
                    &planes,
                    |_, _| true,
                    |i| {
                        calls += 1;
                        i == first
                    }
                ));
                assert!(calls <= visited.len());
            }
        }
    }
}

#[test]
fn rays_along_axes_and_flat_meshes_still_hit() {
    // A flat grid in z = 0 (zero-thickness boxes) hit straight down and
    // along an axis-parallel direction (infinite inverse components).
    let mut tris = Vec::new();
    for i in 0..20 {
        for j in 0..20 {
            let (x, y) = (f64::from(i), f64::from(j));
            let p = |dx: f64, dy: f64| Vec3::new(x + dx, y + dy, 0.0);
            tris.push([p(0.0, 0.0), p(1.0, 0.0), p(1.0, 1.0)]);
            tris.push([p(0.0, 0.0), p(1.0, 1.0), p(0.0, 1.0)]);
        }
    }
    let bvh = Bvh::build(tris.len(), |i| bounds(&tris[i]));
    let ray = Ray {
        origin: Vec3::new(7.3, 4.6, 3.0),
        direction: Vec3::new(0.0, 0.0, -1.0),
    };
    let hit = bvh.nearest(&ray, |i, _| crossing(&tris[i as usize], &ray));
    assert_eq!(hit.map(|h| h.1), Some(3.0));
    // Identical triangles (every centroid equal): one leaf, still found.
    let same = vec![tris[0]; 100];
    let bvh = Bvh::build(same.len(), |i| bounds(&same[i]));
    let ray = Ray {
        origin: Vec3::new(0.7, 0.2, 1.0),
        direction: Vec3::new(0.0, 0.0, -1.0),
    };
    assert!(
        bvh.nearest(&ray, |i, _| crossing(&same[i as usize], &ray))
            .is_some()
    );
}
