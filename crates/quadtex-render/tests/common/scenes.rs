//! Test scenes shared by the renderer's tests and the evaluation's
//! (included by path from both test crates).
#![allow(dead_code, clippy::unwrap_used)]

use std::path::Path;

use quadtex_render::{RenderOptions, Scene, TextureFilter, parse_scene, render};

/// A checkerboard plane (1 m squares) seen at a grazing angle, unlit.
pub fn grazing(width: u32, height: u32, eye_height: f64) -> Scene {
    let text = format!(
        r#"
[camera]
position = [0, {eye_height}, 0]
look_at = [0, 0, 40]
fov = 30
width = {width}
height = {height}

[sky]
colour = [0, 0, 0]

[[shape]]
type = "plane"
point = [0, 0, 0]
normal = [0, 1, 0]
texture = "builtin:checker"
uv_scale = [0.5, 0.5]
"#
    );
    parse_scene(
        &text,
        Path::new("grazing.toml"),
        &quadtex_io::Limits::default(),
    )
    .unwrap()
}

/// `scene` rendered with `filter` and otherwise default options.
pub fn render_with(scene: &Scene, filter: TextureFilter) -> quadtex_io::LinearImage {
    render(
        scene,
        &RenderOptions {
            filter,
            ..RenderOptions::default()
        },
        &|_, _| {},
    )
    .unwrap()
    .0
}
