use super::*;

/// A rolling 300 × 300 grid (180 000 triangles): every leaf within
/// [`LEAF_SIZE`], and a ray from above tests a dozen triangles, not
/// hundreds (an empty bin once made every split look infinitely
/// costly, leaving leaves of ~180 triangles).
#[test]
fn a_terrain_grid_gets_small_leaves_and_cheap_rays() {
    let n = 300;
    let mut tris = Vec::new();
    for i in 0..n {
        for j in 0..n {
            let (x, z) = (f64::from(i), f64::from(j));
            let h = |x: f64, z: f64| (x / 7.0).sin() * (z / 5.0).cos();
            let p = |dx: f64, dz: f64| Vec3::new(x + dx, h(x + dx, z + dz), z + dz);
            tris.push([p(0.0, 0.0), p(1.0, 0.0), p(1.0, 1.0)]);
            tris.push([p(0.0, 0.0), p(1.0, 1.0), p(0.0, 1.0)]);
        }
    }
    let bvh = Bvh::build(tris.len(), |i| {
        let mut b = Aabb::EMPTY;
        for p in &tris[i] {
            b.grow(*p);
        }
        b
    });
    assert!(bvh.nodes.iter().all(|n| n.count as usize <= LEAF_SIZE));
    // The hierarchy's share of a mesh's memory per triangle
    // (`MESH_BYTES_PER_TRIANGLE`).
    let per_triangle = bvh.memory_bytes() as f64 / tris.len() as f64;
    assert!(per_triangle <= 36.0, "{per_triangle} bytes a triangle");
    let mut calls = 0u64;
    let rays = 1000;
    for k in 0..rays {
        let origin = Vec3::new(150.0, 20.0, -50.0);
        let target = Vec3::new(f64::from(k % 300), 0.0, f64::from(k * 7 % 300));
        let ray = Ray {
            origin,
            direction: (target - origin).normalized().unwrap(),
        };
        bvh.nearest(&ray, |_, _| {
            calls += 1;
            None
        });
    }
    let per_ray = calls as f64 / f64::from(rays);
    assert!(per_ray < 40.0, "{per_ray} triangle tests per ray");
}
