//! Any text as a `quadtex query` line: a fragment or a message, never a panic;
//! a parsed fragment integrates to finite values within colour × area bounds.
#![no_main]
use libfuzzer_sys::fuzz_target;
use quadtex_core::{synth, BuildOptions, QuadTree};
use std::sync::OnceLock;

static TREE: OnceLock<QuadTree> = OnceLock::new();

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else { return };
    let tree = TREE.get_or_init(|| {
        let g = synth::runway_art().rasterise(64, 64).unwrap();
        QuadTree::from_texels(&g, &BuildOptions::default()).unwrap().0
    });
    if let Ok(Some(f)) = quadtex_io::parse_query_line(text) {
        let w = tree.weighted_colour(&f, u8::MAX);
        let area = f.clip_to_unit().map_or(0.0, |c| c.area());
        for c in w.0 {
            assert!(c.is_finite() && c >= -1e-12 && c <= area * (1.0 + 1e-9) + 1e-12, "{f:?}: {w:?}");
        }
    }
});
