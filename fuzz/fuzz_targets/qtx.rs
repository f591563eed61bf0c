//! Any bytes as a `.qtx` file: an error or a valid tree, never a panic, and
//! never an allocation beyond the limits.
#![no_main]
use libfuzzer_sys::fuzz_target;
use quadtex_core::Fragment;
use quadtex_io::{parse_qtx, Limits};

fuzz_target!(|data: &[u8]| {
    let limits = Limits { max_nodes: 1 << 16, max_file_bytes: 1 << 20, ..Limits::default() };
    if let Ok((tree, _)) = parse_qtx(data, std::path::Path::new("fuzz.qtx"), &limits) {
        let f = Fragment::new(0.1, 0.2, 0.7, 0.9).unwrap();
        let w = tree.weighted_colour(&f, tree.depth());
        assert!(w.0.iter().all(|c| c.is_finite()));
    }
});
