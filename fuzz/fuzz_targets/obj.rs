//! Any bytes as a Wavefront OBJ mesh (the loader scenes use): an error
//! message, or a mesh within the triangle limit. Never a panic.
#![no_main]
use libfuzzer_sys::fuzz_target;
use quadtex_io::Limits;
use quadtex_render::parse_obj;

fuzz_target!(|data: &[u8]| {
    // A small triangle limit so the fuzzer reaches it cheaply.
    let limits = Limits { max_mesh_triangles: 256, ..Limits::default() };
    if let Ok(mesh) = parse_obj(data, &limits) {
        assert!(mesh.len() <= 256 && !mesh.is_empty());
    }
});
