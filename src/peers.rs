//! `quadtex footprints` (dump every pixel's lookup for a peer filter, with
//! quadtex's own lookups timed on the same footprints) and `quadtex diff`
//! (RMSE and FLIP of one image against another). Used by
//! `bench/peers/run.sh`; see `docs/footprints.md`.

use std::path::PathBuf;

use lexopt::prelude::*;
use quadtex_io::LinearImage;
use quadtex_io::footprints::{DumpTexture, DumpWrap, FootprintDump, write_footprints};
use quadtex_render::scene::WrapMode;
use quadtex_render::{Filter, PixelFilter, RenderOptions};

type Result<T> = std::result::Result<T, Box<dyn std::error::Error>>;

/// `quadtex footprints SCENE.toml -o DIR [--width W] [--passes P] [--reference-spp N]`.
pub fn footprints(parser: &mut lexopt::Parser) -> Result<()> {
    let (mut scene_path, mut dir) = (None::<PathBuf>, None::<PathBuf>);
    let (mut width, mut passes, mut grid) = (480u32, 5u32, 32u32);
    while let Some(arg) = parser.next()? {
        match arg {
            Short('o') | Long("output") => dir = Some(parser.value()?.into()),
            Long("width") => {
                width = parser
                    .value()?
                    .parse()
                    .map_err(|e| format!("--width: {e}"))?
            }
            Long("passes") => {
                passes = parser
                    .value()?
                    .parse()
                    .map_err(|e| format!("--passes: {e}"))?
            }
            Long("reference-spp") => {
                let spp: u32 = parser
                    .value()?
                    .parse()
                    .map_err(|e| format!("--reference-spp: {e}"))?;
                grid = (f64::from(spp.clamp(1, 4096)).sqrt().round() as u32).max(1);
            }
            Value(v) if scene_path.is_none() => scene_path = Some(v.into()),
            other => return Err(other.unexpected().into()),
        }
    }
    if !(16..=3840).contains(&width) || !(1..=100).contains(&passes) {
        return Err("--width must be in 16..=3840 and --passes in 1..=100".into());
    }
    let path = scene_path.ok_or("footprints: missing SCENE.toml")?;
    let dir = dir.ok_or("footprints: missing -o DIR")?;
    let scene = quadtex_render::load_scene(&path)?;
    std::fs::create_dir_all(&dir).map_err(|e| format!("{}: {e}", dir.display()))?;
    let height = scene.camera.height_for_width(width);
    let (records, users) = quadtex_render::footprint_records(&scene, width, height)?;
    let mut textures = Vec::new();
    for (i, &u) in users.iter().enumerate() {
        let surface = &scene.surfaces[u];
        let Some(texture) = &surface.texture else {
            continue;
        };
        let tree = &texture.tree;
        // The peer gets the same raster the in-project baselines use.
        let level = quadtex_render::scene::baseline_level(tree.depth());
        let grid = tree.rasterise(level)?;
        let image = LinearImage {
            width: grid.width(),
            height: grid.height(),
            pixels: grid.texels().iter().map(|t| t.to_rgba()).collect(),
        };
        let file = format!("texture-{i}.exr");
        quadtex_io::save_image(&dir.join(&file), &image)?;
        textures.push(DumpTexture {
            file,
            wrap: match surface.wrap {
                WrapMode::Repeat => DumpWrap::Repeat,
                WrapMode::Clamp => DumpWrap::Clamp,
                WrapMode::Border(_) => DumpWrap::Black,
            },
        });
    }
    write_footprints(
        &dir.join("footprints.bin"),
        &FootprintDump {
            width,
            height,
            textures,
            records,
        },
    )?;
    // The reference: the scene's textures alone, supersampled.
    let (reference, _) = quadtex_render::render(
        &quadtex_render::texture_only(&scene),
        &RenderOptions {
            width: Some(width),
            height: Some(height),
            filter: Filter::Supersample(grid),
            pixel_filter: PixelFilter::Box,
        },
        &|_, _| {},
    )?;
    quadtex_io::save_image(&dir.join("reference.exr"), &reference)?;
    let mut table = String::from("method\tns_per_lookup\ttexture_bytes\tfile\n");
    let runs: [(&str, &str, Filter); 3] = [
        ("quadtex quadtree", "quadtex-quadtree", Filter::default()),
        (
            "quadtex EWA 8 (pbrt-v4 style)",
            "quadtex-ewa8",
            Filter::Ewa {
                max_anisotropy: 8.0,
            },
        ),
        (
            "quadtex trilinear (pbrt-v4 style)",
            "quadtex-trilinear",
            Filter::Trilinear,
        ),
    ];
    for (label, stem, filter) in runs {
        let t = quadtex_render::time_lookups(&scene, width, height, filter, passes)?;
        let file = format!("{stem}.exr");
        quadtex_io::save_image(&dir.join(&file), &t.image)?;
        let bytes = crate::compare::texture_bytes(&scene, filter);
        table.push_str(&format!(
            "{label}\t{:.1}\t{bytes}\t{file}\n",
            t.ns_per_lookup
        ));
        eprintln!(
            "{label}: {:.1} ns per lookup over {} lookups (median of {passes}, one thread)",
            t.ns_per_lookup, t.lookups
        );
    }
    quadtex_io::write_atomically(&dir.join("quadtex.tsv"), |w| {
        std::io::Write::write_all(w, table.as_bytes()).map_err(|source| quadtex_io::Error::Io {
            path: dir.join("quadtex.tsv"),
            source,
        })
    })?;
    println!(
        "wrote {}: footprints.bin ({width}x{height}), texture-*.exr, reference.exr ({} spp), quadtex.tsv and images",
        dir.display(),
        grid * grid
    );
    Ok(())
}

/// `quadtex diff REFERENCE TEST`: `rmse <linear RGB> flip <mean>` on one line.
pub fn diff(parser: &mut lexopt::Parser) -> Result<()> {
    let mut paths = Vec::new();
    while let Some(arg) = parser.next()? {
        match arg {
            Value(v) if paths.len() < 2 => paths.push(PathBuf::from(v)),
            other => return Err(other.unexpected().into()),
        }
    }
    let [reference, test] = paths.as_slice() else {
        return Err("diff: expected REFERENCE and TEST images".into());
    };
    let a = quadtex_io::load_linear_image(reference)?;
    let b = quadtex_io::load_linear_image(test)?;
    let rmse = quadtex_render::compare::rmse(&a, &b).ok_or_else(|| {
        format!(
            "{} is {}x{} but {} is {}x{}",
            reference.display(),
            a.width,
            a.height,
            test.display(),
            b.width,
            b.height
        )
    })?;
    println!("rmse {rmse:.6} flip {:.6}", crate::compare::flip(&a, &b));
    Ok(())
}
