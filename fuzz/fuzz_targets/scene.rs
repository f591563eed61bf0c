//! Any text as a scene file: an error naming the problem, or a scene that
//! renders a tiny image with finite, non-negative pixels. Never a panic.
#![no_main]
use libfuzzer_sys::fuzz_target;
use quadtex_render::{RenderOptions, parse_scene, render};
use std::path::Path;

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else { return };
    // Paths resolve against a folder that does not exist, so the target never
    // reads files a fuzzer happens to name.
    let Ok(scene) = parse_scene(text, Path::new("/nonexistent/fuzz.toml")) else { return };
    let options = RenderOptions { width: Some(4), height: Some(3), ..RenderOptions::default() };
    if let Ok((image, _)) = render(&scene, &options, &|_, _| {}) {
        for p in &image.pixels {
            for c in p.to_array() {
                assert!(c.is_finite() && c >= 0.0, "{p:?}");
            }
        }
    }
});
