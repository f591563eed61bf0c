//! The closed-form reference: the exact box-filtered image of an unlit
//! textured plane, independent of every contender.

use quadtex_core::{Rgba, WrapMode};
use quadtex_render::Scene;
use quadtex_render::math::Vec3;
use quadtex_render::scene::{Geometry, Lighting};

/// The closed-form box-filtered image of a scene made of one unlit,
/// textured, repeating **plane**: each pixel is the exact integral of the
/// texture over the part of the pixel square that sees the plane. For every
/// cell of the tree's finest grid (a texel of the checker) under the pixel's
/// footprint, the cell is mapped to the screen (a convex quadrilateral, the
/// projective image of a square) and clipped against the pixel square; the
/// pixel is `Σ colour × area`. Pixels that see the sky, or whose footprint
/// covers more than `max_cells` cells, are `None` (excluded). Returns `None`
/// for scenes of any other kind.
pub fn closed_form_plane(
    scene: &Scene,
    width: u32,
    height: u32,
    max_cells: u64,
) -> Option<Vec<Option<Rgba>>> {
    let [surface] = scene.surfaces.as_slice() else {
        return None;
    };
    let (
        Geometry::Plane {
            point,
            normal,
            u_axis,
            v_axis,
        },
        Some(texture),
        Lighting::Unlit,
        (WrapMode::Repeat, WrapMode::Repeat),
    ) = (
        &surface.geometry,
        &surface.texture,
        scene.lighting,
        (surface.wrap.x, surface.wrap.z),
    )
    else {
        return None;
    };
    let tree = &texture.tree;
    if tree.depth() > 12 {
        return None;
    }
    let cells_per_unit = 1u32 << tree.depth();
    let cell = 1.0 / f64::from(cells_per_unit);
    // Colour of every finest cell of one tile.
    let mut colours = Vec::with_capacity((cells_per_unit * cells_per_unit) as usize);
    for j in 0..cells_per_unit {
        for i in 0..cells_per_unit {
            let f = quadtex_core::Fragment::new(
                f64::from(i) * cell,
                f64::from(j) * cell,
                f64::from(i + 1) * cell,
                f64::from(j + 1) * cell,
            )
            .ok()?;
            let c = tree.weighted_colour(&f, u8::MAX).mean_over(f.area());
            colours.push(Rgba::new(
                c.r * surface.colour.r,
                c.g * surface.colour.g,
                c.b * surface.colour.b,
                c.a * surface.colour.a,
            ));
        }
    }
    let camera = scene.camera.with_size(width, height);
    let project = |p: Vec3| camera.project(p);
    let to_texture = |sx: f64, sy: f64| -> Option<[f64; 2]> {
        let ray = camera.ray(sx, sy);
        let denom = ray.direction.dot(*normal);
        if denom.abs() < 1e-12 {
            return None;
        }
        let t = (*point - ray.origin).dot(*normal) / denom;
        if !(t > 0.0 && t.is_finite()) {
            return None;
        }
        let rel = ray.origin + ray.direction * t - *point;
        Some(
            surface
                .uv_transform
                .apply([rel.dot(*u_axis), rel.dot(*v_axis)]),
        )
    };
    let to_world = |t: [f64; 2]| {
        let uv = surface.uv_transform.invert(t);
        *point + *u_axis * uv[0] + *v_axis * uv[1]
    };
    let mut out = Vec::with_capacity((width * height) as usize);
    for y in 0..height {
        for x in 0..width {
            let (x0, y0) = (f64::from(x), f64::from(y));
            let corners = [
                (x0, y0),
                (x0 + 1.0, y0),
                (x0 + 1.0, y0 + 1.0),
                (x0, y0 + 1.0),
            ];
            let tex: Option<Vec<[f64; 2]>> =
                corners.iter().map(|&(sx, sy)| to_texture(sx, sy)).collect();
            let Some(tex) = tex else {
                out.push(None);
                continue;
            };
            let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
            for p in &tex {
                for a in 0..2 {
                    lo[a] = lo[a].min(p[a]);
                    hi[a] = hi[a].max(p[a]);
                }
            }
            let (i0, i1) = ((lo[0] / cell).floor(), (hi[0] / cell).ceil());
            let (j0, j1) = ((lo[1] / cell).floor(), (hi[1] / cell).ceil());
            if (i1 - i0) * (j1 - j0) > max_cells as f64 {
                out.push(None);
                continue;
            }
            let pixel = vec![
                [x0, y0],
                [x0 + 1.0, y0],
                [x0 + 1.0, y0 + 1.0],
                [x0, y0 + 1.0],
            ];
            let mut acc = [0f64; 4];
            let mut covered = 0.0;
            let mut ok = true;
            let mut j = j0;
            while j < j1 && ok {
                let mut i = i0;
                while i < i1 {
                    let quad: Option<Vec<[f64; 2]>> = [
                        [i * cell, j * cell],
                        [(i + 1.0) * cell, j * cell],
                        [(i + 1.0) * cell, (j + 1.0) * cell],
                        [i * cell, (j + 1.0) * cell],
                    ]
                    .iter()
                    .map(|&t| project(to_world(t)))
                    .collect();
                    let Some(quad) = quad else {
                        ok = false;
                        break;
                    };
                    let area = clip_convex_area(&pixel, &quad);
                    if area > 0.0 {
                        let ci = (i.rem_euclid(f64::from(cells_per_unit))) as usize;
                        let cj = (j.rem_euclid(f64::from(cells_per_unit))) as usize;
                        let c = colours[cj * cells_per_unit as usize + ci].to_array();
                        for (a, v) in acc.iter_mut().zip(c) {
                            *a += area * f64::from(v);
                        }
                        covered += area;
                    }
                    i += 1.0;
                }
                j += 1.0;
            }
            // The cells must tile the pixel (it sees only the plane).
            if !ok || (covered - 1.0).abs() > 1e-6 {
                out.push(None);
                continue;
            }
            out.push(Some(Rgba::new(
                acc[0] as f32,
                acc[1] as f32,
                acc[2] as f32,
                acc[3] as f32,
            )));
        }
    }
    Some(out)
}

/// Area of the intersection of convex polygon `subject` with convex polygon
/// `clip` (either orientation), by Sutherland–Hodgman.
fn clip_convex_area(subject: &[[f64; 2]], clip: &[[f64; 2]]) -> f64 {
    let signed = |p: &[[f64; 2]]| {
        let n = p.len();
        (0..n)
            .map(|i| p[i][0] * p[(i + 1) % n][1] - p[(i + 1) % n][0] * p[i][1])
            .sum::<f64>()
            * 0.5
    };
    let orientation = signed(clip).signum();
    let mut poly = subject.to_vec();
    let n = clip.len();
    for k in 0..n {
        let (a, b) = (clip[k], clip[(k + 1) % n]);
        let side = |p: [f64; 2]| {
            orientation * ((b[0] - a[0]) * (p[1] - a[1]) - (b[1] - a[1]) * (p[0] - a[0]))
        };
        let mut next = Vec::with_capacity(poly.len() + 2);
        for i in 0..poly.len() {
            let (p, q) = (poly[i], poly[(i + 1) % poly.len()]);
            let (sp, sq) = (side(p), side(q));
            if sp >= 0.0 {
                next.push(p);
            }
            if (sp >= 0.0) != (sq >= 0.0) {
                let t = sp / (sp - sq);
                next.push([p[0] + t * (q[0] - p[0]), p[1] + t * (q[1] - p[1])]);
            }
        }
        poly = next;
        if poly.len() < 3 {
            return 0.0;
        }
    }
    signed(&poly).abs()
}
