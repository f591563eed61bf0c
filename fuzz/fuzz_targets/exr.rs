//! Any bytes as an image file (OpenEXR seeds; the decoder guesses the
//! format from the content, as `quadtex pack` does): an error naming the
//! problem, or texels within the dimension limit. Never a panic.
#![no_main]
use libfuzzer_sys::fuzz_target;
use quadtex_io::{Limits, load_texels_from_bytes};
use std::path::Path;

fuzz_target!(|data: &[u8]| {
    // Small images only, so each execution stays fast and bounded.
    let limits = Limits { max_dimension: 256, ..Limits::default() };
    if let Ok(grid) = load_texels_from_bytes(data, Path::new("fuzz.exr"), &limits) {
        assert!(grid.width() <= 256 && grid.height() <= 256);
        assert_eq!(grid.texels().len(), grid.width() as usize * grid.height() as usize);
    }
});
