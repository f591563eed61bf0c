//! Any bytes as an SVG file, packed at level 4 under tight limits (deeper
//! levels only repeat the same code per square, and cost the fuzzer
//! executions; queries still reach level 30; the sweep's budget is small):
//! an error naming the problem, or a valid tree. Never a panic.
//!
//! One exception, by design: a panic inside the SVG parser's own crates
//! (usvg, tiny-skia; found by this target) is caught by
//! `quadtex_io::parse_svg` and returned as the file's error. libfuzzer-sys's
//! panic hook aborts before any unwinding, so it would report those caught
//! panics as crashes; [`let_third_party_panics_unwind`] lets them unwind to
//! the library's catch, and keeps the abort for every other panic (a panic
//! that escapes the target is still a crash: libfuzzer-sys aborts on it).
#![no_main]
use libfuzzer_sys::fuzz_target;
use quadtex_core::{QuadTree, VectorOptions};
use quadtex_io::Limits;
use std::path::Path;
use std::sync::Once;

/// Installs, once, a panic hook that stays silent for panics raised in
/// crates.io dependencies (their source lives under Cargo's registry) and
/// hands every other panic to libfuzzer-sys's hook (print, then abort).
fn let_third_party_panics_unwind() {
    static INSTALL: Once = Once::new();
    INSTALL.call_once(|| {
        let abort_hook = std::panic::take_hook();
        std::panic::set_hook(Box::new(move |info| {
            let in_dependency = info.location().is_some_and(|l| {
                let file = l.file();
                file.contains("/registry/src/") || file.contains("\\registry\\src\\")
            });
            if !in_dependency {
                abort_hook(info);
            }
        }));
    });
}

fuzz_target!(|data: &[u8]| {
    let_third_party_panics_unwind();
    let limits = Limits { max_svg_elements: 2_000, max_nodes: 100_000, ..Limits::default() };
    let level = 4;
    let Ok(art) = quadtex_io::parse_svg(data, Path::new("fuzz.svg"), level, &limits) else { return };
    // A coarse smooth-colour tolerance: gradients split less (the checks
    // below hold at any tolerance), so more inputs run per second.
    // Every other input also keeps contour leaves (budget 3 to 18 edges).
    let contour_leaves = (data.len() % 2 == 1).then(|| 3 + data.len() % 16);
    // A sweep budget of 2^20 steps (tens of milliseconds): art beyond it
    // (dashes piled on a point) is refused with `Error::SweepWork`, a clear
    // error, instead of taking the fuzzer's time.
    let options = VectorOptions {
        max_level: level,
        max_nodes: limits.max_nodes,
        tolerance: 1.0 / 64.0,
        contour_leaves,
        max_sweep_work: 1 << 20,
        ..VectorOptions::default()
    };
    if let Ok((tree, _)) = QuadTree::from_vector(&art, &options) {
        let c = tree.average().to_array();
        assert!(c.iter().all(|v| v.is_finite() && *v >= 0.0 && *v <= 1.0), "{c:?}");
        assert!(c[0] <= c[3] && c[1] <= c[3] && c[2] <= c[3], "{c:?}");
        // Gradient leaves (and every other node) hold what the packer
        // claims, and fragment integrals over them stay finite.
        tree.verify().expect("a packed tree verifies");
        for f in [(0.1, 0.2, 0.7, 0.9), (0.3, 0.3, 0.3 + 1e-9, 0.3 + 1e-9), (-0.5, 0.4, 1.5, 0.45)] {
            let f = quadtex_core::Fragment::new(f.0, f.1, f.2, f.3).expect("fragment");
            let w = tree.weighted_colour(&f, 30).0;
            assert!(w.iter().all(|v| v.is_finite()), "{w:?}");
        }
    }
});
