//! Any bytes as a `.qtx` file: an error or a valid tree, never a panic, and
//! never an allocation beyond the limits. Both ways of opening: fully
//! checked, and structure only (as a mapped file is), whose unchecked
//! colours must still answer queries and `verify` without panicking.
#![no_main]
use libfuzzer_sys::fuzz_target;
use quadtex_core::Fragment;
use quadtex_io::{parse_qtx, parse_qtx_structure, Limits};

fuzz_target!(|data: &[u8]| {
    let limits = Limits { max_nodes: 1 << 16, max_file_bytes: 1 << 20, ..Limits::default() };
    let path = std::path::Path::new("fuzz.qtx");
    let f = Fragment::new(0.1, 0.2, 0.7, 0.9).unwrap();
    let full = parse_qtx(data, path, &limits);
    if let Ok((tree, _)) = &full {
        let w = tree.weighted_colour(&f, tree.depth());
        assert!(w.0.iter().all(|c| c.is_finite()));
    }
    if let Ok((tree, _)) = parse_qtx_structure(data.to_vec().into(), path, &limits) {
        // Unchecked half floats may be infinite or NaN: only no panic here.
        let _ = tree.weighted_colour(&f, tree.depth());
        let _ = tree.uniform_colour(&f);
        let verified = tree.verify().is_ok();
        // Checksums are off under fuzzing, so the two differ only by the
        // colour checks.
        assert_eq!(verified, full.is_ok());
    }
});
