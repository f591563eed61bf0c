#![allow(clippy::unwrap_used, clippy::expect_used)]
//! Exact pixels at the edges of geometry: every pixel a quad's outline or
//! a mesh's crease crosses is the sum, over the faces, of each face's
//! colour times the area of its projection inside the pixel, computed here
//! independently (projected corners, convex clipping).

use std::path::Path;

use quadtex_core::{ConvexPolygon, Rgba};
use quadtex_render::Vec3;
use quadtex_render::{RenderOptions, Scene, parse_scene, render};

/// Area of the projection of the convex planar polygon `world` (all in
/// front of the camera) inside pixel `(x, y)`.
fn coverage(scene: &Scene, world: &[Vec3], x: u32, y: u32) -> f64 {
    let projected: Vec<[f64; 2]> = world
        .iter()
        .map(|&p| scene.camera.project(p).expect("in front"))
        .collect();
    let face = ConvexPolygon::new(&projected).unwrap();
    let (x0, y0) = (f64::from(x), f64::from(y));
    face.clip_rect(x0, y0, x0 + 1.0, y0 + 1.0).area()
}

fn worst(scene: &Scene, faces: &[(Vec<Vec3>, Rgba)]) -> (f64, usize) {
    let (img, _) = render(scene, &RenderOptions::default(), &|_, _| {}).unwrap();
    let (w, h) = (scene.camera.width(), scene.camera.height());
    let mut worst = 0f64;
    let mut partial = 0;
    for y in 0..h {
        for x in 0..w {
            let mut expected = [0f64; 3];
            let mut covered = 0.0;
            for (world, colour) in faces {
                let a = coverage(scene, world, x, y);
                covered += a;
                for (e, c) in expected.iter_mut().zip(colour.to_array()) {
                    *e += a * f64::from(c);
                }
            }
            if covered > 1e-9 && covered < 1.0 - 1e-9 {
                partial += 1;
            }
            let got = img.pixels[(y * w + x) as usize].to_array();
            for (e, g) in expected.iter().zip(got) {
                worst = worst.max((e - f64::from(g)).abs());
            }
        }
    }
    (worst, partial)
}

/// A scene of mesh `obj` (written as `name.obj` into `dir`) textured with
/// the 2 × 2 checker under `camera` (a TOML table's lines) over a black
/// sky, and the checker's two colours at UVs `(0.25, 0.2)` and
/// `(0.75, 0.2)`.
fn checker_mesh(dir: &Path, name: &str, obj: &str, camera: &str) -> (Scene, [Rgba; 2]) {
    std::fs::write(dir.join(format!("{name}.obj")), obj).unwrap();
    let text = format!(
        "[camera]\n{camera}\n\n[sky]\ncolour = [0, 0, 0]\n\n\
         [[shape]]\ntype = \"mesh\"\nfile = \"{name}.obj\"\n\
         texture = \"builtin:checker\"\nwrap = \"clamp\"\n"
    );
    let scene = parse_scene(
        &text,
        &dir.join(format!("{name}.toml")),
        &quadtex_io::Limits::default(),
    )
    .unwrap();
    let surface = &scene.surfaces[0];
    let texture = surface.texture.as_ref().unwrap().texture(surface.wrap);
    let colour = |uv: [f64; 2]| texture.nearest(surface.uv_transform.apply(uv));
    let colours = [colour([0.25, 0.2]), colour([0.75, 0.2])];
    assert!(colours[0] != colours[1]);
    (scene, colours)
}

/// A flat-coloured quad at a slant over a black sky: every pixel is its
/// colour times the quad's exact coverage of the pixel.
#[test]
fn edge_pixels_are_colour_times_exact_coverage() {
    let text = r#"
[camera]
position = [0.3, 1.2, 4]
look_at = [0, 0, 0]
fov = 40
width = 48
height = 36

[sky]
colour = [0, 0, 0]

[[shape]]
type = "quad"
origin = [-1.3, -0.2, 0.4]
edge_u = [2.1, 0.3, -0.9]
edge_v = [0.4, 1.5, -0.6]
colour = [0.8, 0.5, 0.25]
"#;
    let scene = parse_scene(text, Path::new("edge.toml"), &quadtex_io::Limits::default()).unwrap();
    let o = Vec3::new(-1.3, -0.2, 0.4);
    let (u, v) = (Vec3::new(2.1, 0.3, -0.9), Vec3::new(0.4, 1.5, -0.6));
    let quad = vec![o, o + u, o + u + v, o + v];
    let (err, partial) = worst(&scene, &[(quad, Rgba::opaque(0.8, 0.5, 0.25))]);
    assert!(
        partial > 40,
        "the outline must cross many pixels: {partial}"
    );
    assert!(err < 1e-6, "edge pixels off by {err}");
}

/// Two triangles of one mesh folded at 90° along a shared edge, seen from
/// outside the fold, each showing one colour of the texture: pixels on the
/// crease are each face's colour times its own coverage (the tangent plane
/// of the centre's triangle is not extended across the crease).
#[test]
fn crease_pixels_on_a_folded_mesh_are_exact() {
    let dir = std::env::temp_dir().join(format!("quadtex-crease-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    // Floor triangle (y = 0) and wall triangle (z = 0), sharing the edge
    // from (-1,0,0) to (1,0,0); UVs inside two different checker cells.
    let obj = "v -1 0 0\nv 1 0 0\nv 0 0 1.5\nv 0 1.5 0\n\
         vt 0.1 0.1\nvt 0.4 0.1\nvt 0.25 0.4\nvt 0.6 0.1\nvt 0.9 0.1\nvt 0.75 0.4\n\
         f 1/1 2/2 3/3\nf 2/5 1/4 4/6\n";
    let camera =
        "position = [0.4, 2.0, 3.0]\nlook_at = [0, 0.3, 0.2]\nfov = 45\nwidth = 40\nheight = 30";
    let (scene, [floor_colour, wall_colour]) = checker_mesh(&dir, "fold", obj, camera);
    let floor = vec![
        Vec3::new(-1.0, 0.0, 0.0),
        Vec3::new(1.0, 0.0, 0.0),
        Vec3::new(0.0, 0.0, 1.5),
    ];
    let wall = vec![
        Vec3::new(1.0, 0.0, 0.0),
        Vec3::new(-1.0, 0.0, 0.0),
        Vec3::new(0.0, 1.5, 0.0),
    ];
    let (err, partial) = worst(&scene, &[(floor, floor_colour), (wall, wall_colour)]);
    std::fs::remove_dir_all(&dir).ok();
    assert!(
        partial > 40,
        "the outline and crease must cross many pixels: {partial}"
    );
    assert!(err < 1e-6, "crease and edge pixels off by {err}");
}

/// The camera over [`fine_grid`]: 28 × 20 pixels.
const FINE_CAMERA: &str =
    "position = [0.02, 1.2, 0.1]\nlook_at = [0, 0, 0]\nfov = 40\nwidth = 28\nheight = 20";

/// An `n × n` grid of cells over `[-1, 1]²` on the plane y = 0, two
/// triangles a cell, as OBJ text (its vertices first, shared between
/// faces; UVs 1–3 inside one checker cell, 4–6 inside the other), and its
/// faces with the checker cell each shows, like a checkerboard.
fn fine_grid(n: u32) -> (String, Vec<(Vec<Vec3>, u32)>) {
    let side = 2.0 / f64::from(n);
    let corner =
        |i: u32, j: u32| Vec3::new(-1.0 + f64::from(i) * side, 0.0, -1.0 + f64::from(j) * side);
    let mut obj = String::new();
    for j in 0..=n {
        for i in 0..=n {
            let p = corner(i, j);
            obj += &format!("v {} {} {}\n", p.x, p.y, p.z);
        }
    }
    // Two UV triangles, each inside one cell of the 2 × 2 checker.
    obj += "vt 0.1 0.1\nvt 0.4 0.1\nvt 0.25 0.4\nvt 0.6 0.1\nvt 0.9 0.1\nvt 0.75 0.4\n";
    let mut faces = Vec::new();
    for j in 0..n {
        for i in 0..n {
            let v = |di: u32, dj: u32| (j + dj) * (n + 1) + i + di + 1;
            for (k, tri) in [[(0, 0), (1, 0), (1, 1)], [(0, 0), (1, 1), (0, 1)]]
                .into_iter()
                .enumerate()
            {
                let cell = (i + j + k as u32) % 2;
                let [a, b, c] = tri.map(|(di, dj)| v(di, dj));
                let t = 3 * cell + 1;
                obj += &format!("f {a}/{t} {b}/{} {c}/{}\n", t + 1, t + 2);
                faces.push((tri.map(|(di, dj)| corner(i + di, j + dj)).to_vec(), cell));
            }
        }
    }
    (obj, faces)
}

/// A mesh of 12 800 triangles, each about a sixth of a pixel, in two
/// colours like a checkerboard, filling the view: a pixel holds more
/// triangles than the nine centres in its reach can see, and is still each
/// triangle's colour times its exact coverage, none of it the sky's (the
/// triangles are found from the seen ones' neighbours, or in the gaps
/// they leave).
#[test]
fn triangles_between_pixel_centres_are_found() {
    let dir = std::env::temp_dir().join(format!("quadtex-fine-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let (obj, faces) = fine_grid(80);
    let (scene, colours) = checker_mesh(&dir, "fine", &obj, FINE_CAMERA);
    // Some pixel overlaps more triangles than the 3 × 3 centres around it.
    let crowded = (0..scene.camera.width()).any(|x| {
        faces
            .iter()
            .filter(|(f, _)| coverage(&scene, f, x, 10) > 0.0)
            .count()
            > 9
    });
    assert!(crowded, "the triangles must be smaller than the pixels");
    let faces: Vec<(Vec<Vec3>, Rgba)> = faces
        .into_iter()
        .map(|(f, cell)| (f, colours[cell as usize]))
        .collect();
    let (err, partial) = worst(&scene, &faces);
    std::fs::remove_dir_all(&dir).ok();
    assert_eq!(partial, 0, "the mesh fills the view");
    assert!(err < 1e-6, "pixels off by {err}");
}

/// Two triangles of the same mesh, not joined to the fine grid below
/// them, form a diamond floating over it around a pixel corner: no centre
/// sees it, and the grid's triangles around the centres' would tile the
/// four pixels it reaches into without it. Those pixels are still the
/// diamond's colour times its coverage plus the grid's outside it: a ray
/// confirming a listed neighbour meets the diamond instead, and it joins
/// the list.
#[test]
fn an_occluder_no_centre_sees_hides_the_mesh_below_it() {
    let dir = std::env::temp_dir().join(format!("quadtex-occluder-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let (mut obj, faces) = fine_grid(80);
    let probe = parse_scene(
        &format!(
            "[camera]\n{FINE_CAMERA}\n\n[[shape]]\ntype = \"sphere\"\ncentre = [0, 0, 0]\nradius = 0.1\n"
        ),
        &dir.join("probe.toml"), &quadtex_io::Limits::default())
    .unwrap();
    // The point of the plane y = 0.3 seen at screen point (x, y).
    let above = |[x, y]: [f64; 2]| {
        let ray = probe.camera.ray(x, y);
        ray.origin + ray.direction * ((0.3 - ray.origin.y) / ray.direction.y)
    };
    let (cx, cy, r) = (15.0, 11.0, 0.45);
    let screen = [[cx - r, cy], [cx, cy - r], [cx + r, cy], [cx, cy + r]];
    let diamond: Vec<Vec3> = screen.iter().map(|&s| above(s)).collect();
    let first = 81 * 81 + 1;
    for p in &diamond {
        obj += &format!("v {} {} {}\n", p.x, p.y, p.z);
    }
    let [a, b, c, d] = [0, 1, 2, 3].map(|k| first + k);
    obj += &format!("f {a}/4 {b}/5 {c}/6\nf {a}/4 {c}/5 {d}/6\n");
    let (scene, colours) = checker_mesh(&dir, "occluder", &obj, FINE_CAMERA);
    let (img, _) = render(&scene, &RenderOptions::default(), &|_, _| {}).unwrap();
    std::fs::remove_dir_all(&dir).ok();
    let project = |world: &[Vec3]| {
        let p: Vec<[f64; 2]> = world
            .iter()
            .map(|&q| scene.camera.project(q).unwrap())
            .collect();
        ConvexPolygon::new(&p).unwrap()
    };
    let top = project(&diamond);
    let below: Vec<(ConvexPolygon, Rgba)> = (faces.iter())
        .map(|(f, cell)| (project(f), colours[*cell as usize]))
        .collect();
    let w = scene.camera.width();
    let mut worst = 0f64;
    for (x, y) in [(14, 10), (15, 10), (14, 11), (15, 11), (13, 10), (16, 11)] {
        let (x0, y0) = (f64::from(x), f64::from(y));
        let pixel = ConvexPolygon::rect(x0, y0, x0 + 1.0, y0 + 1.0);
        let hidden = top.intersect(&pixel);
        let mut expected = colours[1].to_array().map(|c| f64::from(c) * hidden.area());
        for (face, colour) in &below {
            let seen = face.intersect(&pixel);
            let area = seen.area() - seen.intersect(&top).area();
            for (e, c) in expected.iter_mut().zip(colour.to_array()) {
                *e += area * f64::from(c);
            }
        }
        let got = img.pixels[(y * w + x) as usize].to_array();
        for (e, g) in expected.iter().zip(got) {
            worst = worst.max((e - f64::from(g)).abs());
        }
    }
    assert!(worst < 1e-6, "pixels off by {worst}");
}

/// Needles of a mesh, each a fifth of a pixel wide and lying between two
/// columns of pixel centres, over a black sky: no centre sees them, and
/// every pixel is still their colour times their exact coverage (the
/// pixels around them find them by their frustum, not by a ray).
#[test]
fn needles_between_the_centres_are_found_against_the_sky() {
    let dir = std::env::temp_dir().join(format!("quadtex-needles-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let camera = FINE_CAMERA;
    let probe = parse_scene(
        &format!(
            "[camera]\n{camera}\n\n[[shape]]\ntype = \"sphere\"\ncentre = [0, 0, 0]\nradius = 0.1\n"
        ),
        &dir.join("probe.toml"),
        &quadtex_io::Limits::default(),
    )
    .unwrap();
    // The point of the plane y = 0 seen at screen point (x, y).
    let on_ground = |x: f64, y: f64| {
        let ray = probe.camera.ray(x, y);
        ray.origin + ray.direction * (-ray.origin.y / ray.direction.y)
    };
    let screen: Vec<[[f64; 2]; 3]> = (0..8)
        .map(|k| {
            let x = f64::from(2 + 3 * k);
            [
                [x + 0.6, 2.3],
                [x + 0.8, 2.3 + 0.1 * f64::from(k)],
                [x + 0.7, 17.6],
            ]
        })
        .collect();
    let inside = |t: &[[f64; 2]; 3], p: [f64; 2]| {
        let side = |a: [f64; 2], b: [f64; 2]| {
            (b[0] - a[0]) * (p[1] - a[1]) - (b[1] - a[1]) * (p[0] - a[0])
        };
        let s = [side(t[0], t[1]), side(t[1], t[2]), side(t[2], t[0])];
        s.iter().all(|&v| v >= 0.0) || s.iter().all(|&v| v <= 0.0)
    };
    for t in &screen {
        for y in 0..20 {
            for x in 0..28 {
                let c = [f64::from(x) + 0.5, f64::from(y) + 0.5];
                assert!(!inside(t, c), "a centre sees a needle");
            }
        }
    }
    let mut obj = String::from("vt 0.1 0.1\nvt 0.4 0.1\nvt 0.25 0.4\n");
    let mut faces = Vec::new();
    for (k, t) in screen.iter().enumerate() {
        let world = t.map(|[x, y]| on_ground(x, y));
        for p in &world {
            obj += &format!("v {} {} {}\n", p.x, p.y, p.z);
        }
        let v = 3 * k + 1;
        obj += &format!("f {v}/1 {}/2 {}/3\n", v + 1, v + 2);
        faces.push(world.to_vec());
    }
    let (scene, colours) = checker_mesh(&dir, "needles", &obj, camera);
    let faces: Vec<(Vec<Vec3>, Rgba)> = faces.into_iter().map(|f| (f, colours[0])).collect();
    let (err, partial) = worst(&scene, &faces);
    std::fs::remove_dir_all(&dir).ok();
    assert!(partial > 100, "the needles cross many pixels: {partial}");
    assert!(err < 1e-6, "pixels off by {err}");
}
