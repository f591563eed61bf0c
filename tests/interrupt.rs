//! A render or pack killed at any moment leaves either no output or a whole
//! one, never a partial file; a later run cleans up the killed process's
//! hidden temporary file.
#![allow(clippy::unwrap_used, clippy::expect_used)]

mod common;

use std::path::Path;
use std::process::{Command, Stdio};
use std::time::Instant;

fn temps_for(dir: &Path, name: &str) -> Vec<String> {
    std::fs::read_dir(dir)
        .unwrap()
        .filter_map(|e| {
            let n = e.unwrap().file_name().to_string_lossy().into_owned();
            n.starts_with(&format!(".{name}.tmp-")).then_some(n)
        })
        .collect()
}

/// Runs `args` to completion once (timing it), then kills fresh runs at
/// spread-out moments of that span, with SIGKILL and SIGINT alternately.
/// After each kill `check(out)` must hold if `out` exists.
fn kill_at_many_moments(args: &[&str], out: &Path, check: &dyn Fn(&Path)) {
    let exe = env!("CARGO_BIN_EXE_quadtex");
    let start = Instant::now();
    let status = Command::new(exe)
        .args(args)
        .stderr(Stdio::null())
        .status()
        .unwrap();
    assert!(status.success(), "{args:?}");
    let full = start.elapsed();
    std::fs::remove_file(out).unwrap();
    let name = out.file_name().unwrap().to_string_lossy().into_owned();
    let dir = out.parent().unwrap();
    for i in 0..12u32 {
        let mut child = Command::new(exe)
            .args(args)
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .unwrap();
        // Moments from early start-up to just past the usual finish, so some
        // kills land while the file is being written.
        std::thread::sleep(full.mul_f64(f64::from(i) / 10.0));
        if i % 2 == 0 {
            let _ = child.kill();
        } else {
            let _ = Command::new("kill")
                .args(["-INT", &child.id().to_string()])
                .status();
        }
        let _ = child.wait().unwrap();
        if out.exists() {
            check(out);
            std::fs::remove_file(out).unwrap();
        }
    }
    // A complete run afterwards leaves the whole file and no temporaries.
    let status = Command::new(exe)
        .args(args)
        .stderr(Stdio::null())
        .status()
        .unwrap();
    assert!(status.success());
    check(out);
    assert_eq!(temps_for(dir, &name), Vec::<String>::new());
}

#[test]
fn killed_render_leaves_no_partial_image() {
    let dir = common::temp_dir("kill-render");
    let out = dir.join("frame.png");
    let scene = concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/checker.toml");
    kill_at_many_moments(
        &[
            "render",
            scene,
            "-o",
            out.to_str().unwrap(),
            "--width",
            "320",
        ],
        &out,
        &|p| {
            let image = quadtex_io::load_texels(p, &quadtex_io::Limits::default())
                .expect("a written image decodes whole");
            assert_eq!(image.width(), 320);
        },
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn killed_pack_leaves_no_partial_tree() {
    let dir = common::temp_dir("kill-pack");
    let png = dir.join("art.png");
    let status = Command::new(env!("CARGO_BIN_EXE_quadtex"))
        .args([
            "sample",
            "runway",
            "-o",
            png.to_str().unwrap(),
            "--size",
            "1024",
        ])
        .status()
        .unwrap();
    assert!(status.success());
    let out = dir.join("art.qtx");
    kill_at_many_moments(
        &["pack", png.to_str().unwrap(), "-o", out.to_str().unwrap()],
        &out,
        &|p| {
            quadtex_io::read_qtx(p, &quadtex_io::Limits::default())
                .expect("a written tree reads whole, checksums and all");
        },
    );
    std::fs::remove_dir_all(&dir).unwrap();
}
