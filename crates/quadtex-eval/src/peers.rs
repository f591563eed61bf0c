//! Every pixel's lookup in OpenImageIO's conventions (see
//! `quadtex_io::footprints`), for the peer benchmark.

use quadtex_io::FootprintRecord;
use quadtex_render::Scene;

/// Every pixel's lookup at `width × height` (an untextured record where no
/// textured surface is seen), and for each texture index the records use
/// the first surface carrying that texture (as [`Scene::distinct_textures`]).
pub fn footprint_records(
    scene: &Scene,
    width: u32,
    height: u32,
) -> Result<(Vec<FootprintRecord>, Vec<usize>), quadtex_render::Error> {
    let mut records = vec![
        FootprintRecord {
            texture: None,
            st: [0.0; 2],
            derivatives: [0.0; 4],
            quad: [[0.0; 2]; 4],
        };
        (width as usize) * (height as usize)
    ];
    let distinct = scene.distinct_textures();
    let tree_index = |surface: usize| -> Option<u32> {
        let tree = &scene.surfaces[surface].texture.as_ref()?.tree;
        distinct
            .iter()
            .position(|(_, t)| std::sync::Arc::ptr_eq(&t.tree, tree))
            .map(|i| i as u32)
    };
    // OpenImageIO's t runs down: t = 1 − z, and its derivatives change sign.
    let st = |p: [f64; 2]| [p[0] as f32, (1.0 - p[1]) as f32];
    for p in quadtex_render::pixel_footprints(scene, width, height)? {
        let (d_dx, d_dy) = p.footprint.differentials();
        records[p.pixel] = FootprintRecord {
            texture: tree_index(p.surface),
            st: st(p.centre),
            derivatives: [
                d_dx[0] as f32,
                -d_dx[1] as f32,
                d_dy[0] as f32,
                -d_dy[1] as f32,
            ],
            quad: p.footprint.corners().map(st),
        };
    }
    let users = distinct.iter().map(|&(u, _)| u).collect();
    Ok((records, users))
}
