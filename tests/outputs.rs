//! Output targets of the `quadtex` binary: `-o -` (standard output, with
//! summaries moved to standard error), symbolic links, FIFOs, and readers
//! that close the pipe early (an error, never a panic).
#![allow(clippy::unwrap_used, clippy::expect_used)]

mod common;

use std::io::Read;
use std::path::Path;
use std::process::{Command, Stdio};

use common::{run, temp_dir};

const PNG_SIGNATURE: &[u8] = b"\x89PNG\r\n\x1a\n";

fn scene() -> String {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("scenes/checker.toml")
        .to_string_lossy()
        .into_owned()
}

fn stderr(out: &std::process::Output) -> String {
    String::from_utf8_lossy(&out.stderr).into_owned()
}

#[test]
fn render_to_stdout_is_a_png_and_the_summary_goes_to_stderr() {
    let out = run(&["render", &scene(), "--width", "64", "-o", "-"], "");
    assert!(out.status.success(), "{}", stderr(&out));
    assert!(out.stdout.starts_with(PNG_SIGNATURE), "not a PNG");
    // IHDR: width and height, big-endian, right after the chunk header.
    let width = u32::from_be_bytes(out.stdout[16..20].try_into().unwrap());
    assert_eq!(width, 64);
    let err = stderr(&out);
    assert!(err.contains("wrote standard output"), "{err}");
    assert!(err.contains("regions"), "summary missing: {err}");
    // It decodes.
    let dir = temp_dir("stdout-png");
    let file = dir.join("out.png");
    std::fs::write(&file, &out.stdout).unwrap();
    let image = quadtex_io::load_linear_image(&file).unwrap();
    assert_eq!(image.width, 64);
    // The same bytes as rendering into a file.
    let named = dir.join("named.png");
    let to_file = run(
        &[
            "render",
            &scene(),
            "--width",
            "64",
            "-o",
            named.to_str().unwrap(),
        ],
        "",
    );
    assert!(to_file.status.success(), "{}", stderr(&to_file));
    assert!(String::from_utf8_lossy(&to_file.stdout).contains("wrote"));
    assert_eq!(std::fs::read(&named).unwrap(), out.stdout);
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn exr_to_stdout_needs_format_and_decodes() {
    let out = run(
        &[
            "render",
            &scene(),
            "--width",
            "32",
            "-o",
            "-",
            "--format",
            "exr",
        ],
        "",
    );
    assert!(out.status.success(), "{}", stderr(&out));
    let dir = temp_dir("stdout-exr");
    let file = dir.join("out.exr");
    std::fs::write(&file, &out.stdout).unwrap();
    let image = quadtex_io::load_linear_image(&file).unwrap();
    assert_eq!(image.width, 32);
    std::fs::remove_dir_all(&dir).unwrap();
    // A contradiction between --format and the extension is a usage error.
    let out = run(
        &[
            "render",
            &scene(),
            "--width",
            "32",
            "-o",
            "x.png",
            "--format",
            "exr",
        ],
        "",
    );
    assert!(!out.status.success());
    assert!(stderr(&out).contains("contradicts"), "{}", stderr(&out));
}

#[test]
fn pack_and_sample_to_stdout() {
    let dir = temp_dir("stdout-pack");
    let png = dir.join("checker.png");
    let out = run(&["sample", "checker", "--size", "64", "-o", "-"], "");
    assert!(out.status.success(), "{}", stderr(&out));
    assert!(out.stdout.starts_with(PNG_SIGNATURE));
    assert!(stderr(&out).contains("wrote standard output (64x64)"));
    std::fs::write(&png, &out.stdout).unwrap();
    let packed = run(&["pack", png.to_str().unwrap(), "-o", "-"], "");
    assert!(packed.status.success(), "{}", stderr(&packed));
    assert!(stderr(&packed).contains("packed"), "{}", stderr(&packed));
    let (tree, info) = quadtex_io::parse_qtx(
        &packed.stdout,
        Path::new("stdout"),
        &quadtex_io::Limits::default(),
    )
    .unwrap();
    assert_eq!((info.source_width, info.source_height), (64, 64));
    // Byte for byte what `-o FILE` writes.
    let qtx = dir.join("checker.qtx");
    let to_file = run(
        &["pack", png.to_str().unwrap(), "-o", qtx.to_str().unwrap()],
        "",
    );
    assert!(to_file.status.success(), "{}", stderr(&to_file));
    assert_eq!(std::fs::read(&qtx).unwrap(), packed.stdout);
    assert_eq!(
        quadtex_io::read_qtx(&qtx, &quadtex_io::Limits::default())
            .unwrap()
            .0,
        tree
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn demo_to_stdout_and_compare_refuses_it() {
    let out = run(&["demo", "--width", "32", "-o", "-"], "");
    assert!(out.status.success(), "{}", stderr(&out));
    assert!(out.stdout.starts_with(PNG_SIGNATURE));
    let out = run(&["demo", "--compare", "-o", "-"], "");
    assert!(!out.status.success());
    assert!(
        stderr(&out).contains("-o - is not possible"),
        "{}",
        stderr(&out)
    );
}

#[cfg(unix)]
#[test]
fn links_are_kept_and_fifos_written_in_place() {
    use std::os::unix::fs::{FileTypeExt, symlink};
    let dir = temp_dir("targets");
    let real = dir.join("real.png");
    let link = dir.join("link.png");
    symlink("real.png", &link).unwrap();
    // Dangling: creates real.png; the link stays.
    let out = run(
        &[
            "sample",
            "checker",
            "--size",
            "8",
            "-o",
            link.to_str().unwrap(),
        ],
        "",
    );
    assert!(out.status.success(), "{}", stderr(&out));
    assert!(std::fs::symlink_metadata(&link).unwrap().is_symlink());
    assert_eq!(quadtex_io::load_linear_image(&real).unwrap().width, 8);
    // Existing: replaced through the link.
    let out = run(
        &[
            "sample",
            "checker",
            "--size",
            "16",
            "-o",
            link.to_str().unwrap(),
        ],
        "",
    );
    assert!(out.status.success(), "{}", stderr(&out));
    assert!(std::fs::symlink_metadata(&link).unwrap().is_symlink());
    assert_eq!(quadtex_io::load_linear_image(&real).unwrap().width, 16);
    // A FIFO: its reader gets the image; it stays a FIFO.
    let fifo = dir.join("pipe");
    if Command::new("mkfifo")
        .arg(&fifo)
        .status()
        .is_ok_and(|s| s.success())
    {
        let reader = {
            let fifo = fifo.clone();
            std::thread::spawn(move || std::fs::read(&fifo).unwrap())
        };
        let out = run(
            &[
                "sample",
                "checker",
                "--size",
                "16",
                "--format",
                "png",
                "-o",
                fifo.to_str().unwrap(),
            ],
            "",
        );
        assert!(out.status.success(), "{}", stderr(&out));
        let bytes = reader.join().unwrap();
        assert!(bytes.starts_with(PNG_SIGNATURE));
        assert!(
            std::fs::symlink_metadata(&fifo)
                .unwrap()
                .file_type()
                .is_fifo()
        );
    }
    let mut names: Vec<_> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .collect();
    names.sort();
    assert!(
        names.iter().all(|n| !n.to_string_lossy().contains(".tmp-")),
        "temporary file left: {names:?}"
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

/// Runs `quadtex args…` with standard output a pipe whose reader takes at
/// most `keep` bytes and then closes it; returns (status, stderr).
fn run_with_early_close(args: &[&str], keep: usize) -> (std::process::ExitStatus, String) {
    let mut child = Command::new(env!("CARGO_BIN_EXE_quadtex"))
        .args(args)
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut stdout = child.stdout.take().unwrap();
    if keep > 0 {
        let mut buf = vec![0u8; keep];
        let _ = stdout.read(&mut buf);
    }
    drop(stdout);
    let mut err = String::new();
    child
        .stderr
        .take()
        .unwrap()
        .read_to_string(&mut err)
        .unwrap();
    (child.wait().unwrap(), err)
}

#[test]
fn a_reader_closing_early_is_an_error_not_a_panic() {
    // The image is written after the pipe is closed: always EPIPE.
    let (status, err) = run_with_early_close(&["render", &scene(), "--width", "256", "-o", "-"], 0);
    assert!(!status.success());
    assert!(!err.contains("panicked"), "{err}");
    assert!(err.contains("Error: standard output: Broken pipe"), "{err}");
    // Text: `info … | head -c 1`. The reader may close before or after the
    // last line: success or a named error, never a panic.
    let dir = temp_dir("epipe");
    let png = dir.join("checker.png");
    let qtx = dir.join("checker.qtx");
    assert!(
        run(
            &[
                "sample",
                "checker",
                "--size",
                "64",
                "-o",
                png.to_str().unwrap()
            ],
            ""
        )
        .status
        .success()
    );
    assert!(
        run(
            &["pack", png.to_str().unwrap(), "-o", qtx.to_str().unwrap()],
            ""
        )
        .status
        .success()
    );
    for keep in [0, 1] {
        let (status, err) = run_with_early_close(&["info", qtx.to_str().unwrap()], keep);
        assert!(!err.contains("panicked"), "{err}");
        if !status.success() {
            assert!(err.contains("standard output: Broken pipe"), "{err}");
        }
    }
    let (status, err) = run_with_early_close(&["pack", png.to_str().unwrap(), "-o", "-"], 1);
    assert!(!err.contains("panicked"), "{err}");
    if !status.success() {
        assert!(err.contains("standard output: Broken pipe"), "{err}");
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn bench_with_few_queries_does_not_panic() {
    let out = run(
        &["bench", "--size", "64", "--queries", "10", "--runs", "1"],
        "",
    );
    assert!(out.status.success(), "{}", stderr(&out));
    assert!(String::from_utf8_lossy(&out.stdout).contains("| 256 |"));
    let out = run(&["bench", "--queries", "0"], "");
    assert!(!out.status.success());
    assert!(
        stderr(&out).contains("--queries must be at least 1"),
        "{}",
        stderr(&out)
    );
}
