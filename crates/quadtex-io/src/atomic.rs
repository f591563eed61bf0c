use std::fs::{self, File, OpenOptions};
use std::io::{self, BufWriter, ErrorKind, Write};
use std::path::{Path, PathBuf};

use crate::error::{Error, io};

/// Symbolic links followed before giving up (Linux's own limit).
const MAX_SYMLINK_HOPS: usize = 40;

/// Where the bytes written "to a path" really go.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(crate) enum Target {
    /// A regular file, existing or not, after following symbolic links: it is
    /// replaced atomically (temporary file in its directory, then a rename).
    Regular(PathBuf),
    /// An existing file that is not a regular file (character or block
    /// device, FIFO, socket): opened and written in place.
    Special(PathBuf),
}

/// Resolves `path` for writing. Symbolic links are followed, chains
/// included; a dangling link resolves to the file it names (to be created).
/// A directory is an error. Errors name `path`.
pub(crate) fn resolve(path: &Path) -> Result<Target, Error> {
    match fs::metadata(path) {
        Ok(meta) if meta.is_file() => {
            let is_link = fs::symlink_metadata(path)
                .map_err(io(path))?
                .file_type()
                .is_symlink();
            if is_link {
                // The real file (directories resolved too), so that the
                // temporary file and the rename happen next to it.
                Ok(Target::Regular(fs::canonicalize(path).map_err(io(path))?))
            } else {
                Ok(Target::Regular(path.to_path_buf()))
            }
        }
        Ok(meta) if meta.is_dir() => Err(Error::Io {
            path: path.to_path_buf(),
            source: io::Error::new(ErrorKind::IsADirectory, "is a directory"),
        }),
        // Devices, FIFOs, sockets; also "magic" links such as /dev/stdout →
        // /proc/self/fd/1 → pipe:[…], which only the kernel can follow.
        Ok(_) => Ok(Target::Special(path.to_path_buf())),
        Err(e) if e.kind() == ErrorKind::NotFound => follow_dangling(path).map(Target::Regular),
        Err(e) => Err(io(path)(e)),
    }
}

/// The file a path that does not resolve would create: the path itself, or,
/// for a (chain of) dangling symbolic link(s), the name the last link holds.
fn follow_dangling(path: &Path) -> Result<PathBuf, Error> {
    let mut current = path.to_path_buf();
    for _ in 0..MAX_SYMLINK_HOPS {
        match fs::symlink_metadata(&current) {
            Ok(meta) if meta.file_type().is_symlink() => {
                let next = fs::read_link(&current).map_err(io(path))?;
                current = match current.parent() {
                    Some(dir) if next.is_relative() => dir.join(next),
                    _ => next,
                };
            }
            // Missing (to be created), or appeared meanwhile: write there.
            _ => return Ok(current),
        }
    }
    Err(Error::Io {
        path: path.to_path_buf(),
        source: io::Error::other("too many levels of symbolic links"),
    })
}

/// Writes a file atomically: `write` fills a temporary file in the same
/// directory (`.NAME.tmp-PID`), which is flushed, synced and renamed over
/// `path`. On any error the temporary file is removed and `path` is untouched.
///
/// A process killed outright (SIGKILL, power loss) cannot clean up: it leaves
/// at most its hidden temporary file, never a partial `path`. The next write
/// of the same `path` removes such leftovers whose process no longer exists
/// (on Linux, where that can be checked through `/proc`).
///
/// What `path` names decides how it is written:
///
/// - a symbolic link (or a chain of them) is followed, and the file it
///   finally names is replaced as above, with the temporary file in *that*
///   file's directory: the link stays a link. A dangling link creates the
///   file it names.
/// - an existing file that is not a regular file (a character or block
///   device such as `/dev/null`, a FIFO, a socket, `/dev/stdout`) is opened
///   for writing and written in place: no temporary file, no rename, no
///   truncation. A failure (`ENOSPC` on `/dev/full`, `EPIPE` when a pipe's
///   reader has gone) is an error naming `path`; what was written before it
///   cannot be taken back.
/// - a directory is an error.
///
/// Errors name `path` as given.
pub fn write_atomically(
    path: &Path,
    write: impl FnOnce(&mut BufWriter<File>) -> Result<(), Error>,
) -> Result<(), Error> {
    match resolve(path)? {
        Target::Regular(real) => replace(path, &real, write),
        Target::Special(real) => write_in_place(path, &real, write),
    }
}

/// Replaces the regular file `real` (which `path` resolved to) atomically.
fn replace(
    path: &Path,
    real: &Path,
    write: impl FnOnce(&mut BufWriter<File>) -> Result<(), Error>,
) -> Result<(), Error> {
    let tmp = temp_path(real);
    remove_orphaned_temps(real);
    let result = (|| {
        let file = File::create(&tmp).map_err(io(path))?;
        let mut w = BufWriter::new(file);
        write(&mut w)?;
        let file = w.into_inner().map_err(|e| Error::Io {
            path: path.to_path_buf(),
            source: e.into_error(),
        })?;
        file.sync_all().map_err(io(path))?;
        fs::rename(&tmp, real).map_err(io(path))
    })();
    if result.is_err() {
        let _ = fs::remove_file(&tmp);
    }
    result
}

/// Writes to the device, FIFO or socket `real` (which `path` resolved to)
/// directly. Opening a FIFO waits for a reader, as a shell redirection does.
fn write_in_place(
    path: &Path,
    real: &Path,
    write: impl FnOnce(&mut BufWriter<File>) -> Result<(), Error>,
) -> Result<(), Error> {
    let file = OpenOptions::new()
        .write(true)
        .open(real)
        .map_err(io(path))?;
    let mut w = BufWriter::new(file);
    write(&mut w)?;
    // Not synced: fsync means nothing to (or fails on) pipes and most devices.
    w.into_inner().map(drop).map_err(|e| Error::Io {
        path: path.to_path_buf(),
        source: e.into_error(),
    })
}

fn temp_path(path: &Path) -> PathBuf {
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    path.with_file_name(format!(".{name}.tmp-{}", std::process::id()))
}

/// Removes `.NAME.tmp-PID` files next to `path` whose process has exited.
/// Best effort: anything unreadable is left alone.
fn remove_orphaned_temps(path: &Path) {
    if !cfg!(target_os = "linux") || !Path::new("/proc/self").exists() {
        return;
    }
    let Some(name) = path.file_name().map(|n| n.to_string_lossy().into_owned()) else {
        return;
    };
    let prefix = format!(".{name}.tmp-");
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    let Ok(entries) = fs::read_dir(dir) else {
        return;
    };
    for entry in entries.flatten() {
        let file_name = entry.file_name().to_string_lossy().into_owned();
        let Some(pid) = file_name
            .strip_prefix(&prefix)
            .and_then(|p| p.parse::<u32>().ok())
        else {
            continue;
        };
        if pid != std::process::id() && !Path::new(&format!("/proc/{pid}")).exists() {
            let _ = fs::remove_file(entry.path());
        }
    }
}

/// Writes all of `bytes` through `w`, naming `path` on failure.
pub(crate) fn put(w: &mut (impl Write + ?Sized), path: &Path, bytes: &[u8]) -> Result<(), Error> {
    w.write_all(bytes).map_err(io(path))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn failed_write_leaves_nothing() {
        let dir = std::env::temp_dir().join(format!("quadtex-atomic-{}", std::process::id()));
        fs::create_dir_all(&dir).unwrap();
        let target = dir.join("out.bin");
        let r = write_atomically(&target, |w| {
            put(w, &target, b"partial")?;
            Err(Error::UnsupportedExtension(target.clone()))
        });
        assert!(r.is_err());
        assert!(!target.exists());
        assert_eq!(
            fs::read_dir(&dir).unwrap().count(),
            0,
            "temporary file left behind"
        );
        write_atomically(&target, |w| put(w, &target, b"whole")).unwrap();
        assert_eq!(fs::read(&target).unwrap(), b"whole");
        // A leftover of a killed process (no such PID) goes on the next write;
        // files that merely look similar stay.
        let orphan = dir.join(".out.bin.tmp-4294967295");
        let unrelated = dir.join(".other.bin.tmp-4294967295");
        fs::write(&orphan, b"half").unwrap();
        fs::write(&unrelated, b"keep").unwrap();
        write_atomically(&target, |w| put(w, &target, b"again")).unwrap();
        if cfg!(target_os = "linux") {
            assert!(!orphan.exists(), "orphaned temporary file kept");
        }
        assert!(unrelated.exists());
        fs::remove_dir_all(&dir).unwrap();
    }

    /// A fresh directory for one test.
    fn fresh(case: &str) -> PathBuf {
        let dir =
            std::env::temp_dir().join(format!("quadtex-atomic-{}-{case}", std::process::id()));
        let _ = fs::remove_dir_all(&dir);
        fs::create_dir_all(&dir).unwrap();
        dir
    }

    /// Names in `dir`, sorted.
    fn listing(dir: &Path) -> Vec<String> {
        let mut names: Vec<String> = fs::read_dir(dir)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        names.sort();
        names
    }

    #[cfg(unix)]
    #[test]
    fn symlink_stays_a_link_and_its_target_is_replaced() {
        use std::os::unix::fs::symlink;
        let dir = fresh("link");
        let real_dir = dir.join("real");
        fs::create_dir(&real_dir).unwrap();
        let real = real_dir.join("out.bin");
        fs::write(&real, b"old").unwrap();
        // A relative link in another directory.
        let link = dir.join("link.bin");
        symlink("real/out.bin", &link).unwrap();
        write_atomically(&link, |w| put(w, &link, b"new")).unwrap();
        assert!(
            fs::symlink_metadata(&link)
                .unwrap()
                .file_type()
                .is_symlink()
        );
        assert_eq!(fs::read_link(&link).unwrap(), Path::new("real/out.bin"));
        assert_eq!(fs::read(&real).unwrap(), b"new");
        // The temporary file went next to the real file and is gone.
        assert_eq!(listing(&real_dir), ["out.bin"]);
        assert_eq!(listing(&dir), ["link.bin", "real"]);
        // A failed write leaves the target and the link alone.
        let r = write_atomically(&link, |w| {
            put(w, &link, b"partial")?;
            Err(Error::UnsupportedExtension(link.clone()))
        });
        assert!(r.is_err());
        assert_eq!(fs::read(&real).unwrap(), b"new");
        assert_eq!(listing(&real_dir), ["out.bin"]);
        fs::remove_dir_all(&dir).unwrap();
    }

    #[cfg(unix)]
    #[test]
    fn chains_of_links_and_dangling_links_are_followed() {
        use std::os::unix::fs::symlink;
        let dir = fresh("chain");
        let real = dir.join("real.bin");
        fs::write(&real, b"old").unwrap();
        // a -> b (absolute) -> real.bin (relative)
        let (a, b) = (dir.join("a"), dir.join("b"));
        symlink("real.bin", &b).unwrap();
        symlink(&b, &a).unwrap();
        write_atomically(&a, |w| put(w, &a, b"via chain")).unwrap();
        assert_eq!(fs::read(&real).unwrap(), b"via chain");
        for l in [&a, &b] {
            assert!(fs::symlink_metadata(l).unwrap().file_type().is_symlink());
        }
        // A dangling chain creates the file the last link names.
        let (c, d) = (dir.join("c"), dir.join("d"));
        symlink("d", &c).unwrap();
        symlink("sub/created.bin", &d).unwrap();
        fs::create_dir(dir.join("sub")).unwrap();
        write_atomically(&c, |w| put(w, &c, b"created")).unwrap();
        assert_eq!(fs::read(dir.join("sub/created.bin")).unwrap(), b"created");
        assert!(fs::symlink_metadata(&c).unwrap().file_type().is_symlink());
        assert!(fs::symlink_metadata(&d).unwrap().file_type().is_symlink());
        assert_eq!(listing(&dir.join("sub")), ["created.bin"]);
        // A loop is an error naming the path, not a hang.
        let (e, f) = (dir.join("e"), dir.join("f"));
        symlink("f", &e).unwrap();
        symlink("e", &f).unwrap();
        let err = write_atomically(&e, |w| put(w, &e, b"x")).unwrap_err();
        assert!(
            err.to_string().starts_with(&e.display().to_string()),
            "{err}"
        );
        // A directory is an error too, and is left alone.
        let err = write_atomically(&dir, |w| put(w, &dir, b"x")).unwrap_err();
        assert!(err.to_string().contains("directory"), "{err}");
        fs::remove_dir_all(&dir).unwrap();
    }

    #[cfg(unix)]
    #[test]
    fn fifo_is_written_in_place_and_stays_a_fifo() {
        use std::os::unix::fs::FileTypeExt;
        let dir = fresh("fifo");
        let fifo = dir.join("pipe");
        let made = std::process::Command::new("mkfifo").arg(&fifo).status();
        if !made.is_ok_and(|s| s.success()) {
            eprintln!("mkfifo unavailable: skipped");
            return;
        }
        let reader = {
            let fifo = fifo.clone();
            std::thread::spawn(move || fs::read(&fifo).unwrap())
        };
        let payload: Vec<u8> = (0..200_000u32).map(|i| (i % 251) as u8).collect();
        write_atomically(&fifo, |w| put(w, &fifo, &payload)).unwrap();
        assert_eq!(reader.join().unwrap(), payload);
        assert!(fs::symlink_metadata(&fifo).unwrap().file_type().is_fifo());
        assert_eq!(listing(&dir), ["pipe"], "no temporary file");
        fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn devices_are_written_in_place_and_errors_name_them() {
        let full = Path::new("/dev/full");
        if !full.exists() {
            return;
        }
        let err = write_atomically(full, |w| put(w, full, &[0u8; 100_000])).unwrap_err();
        let text = err.to_string();
        assert!(text.starts_with("/dev/full: "), "{text}");
        assert!(
            matches!(&err, Error::Io { source, .. } if source.raw_os_error() == Some(28)),
            "{err:?}"
        );
        // Still a device (run as root, a rename would have replaced it).
        assert!(!fs::metadata(full).unwrap().is_file());
        // A small write fails at the flush, and is reported the same way.
        let err = write_atomically(full, |w| put(w, full, b"x")).unwrap_err();
        assert!(err.to_string().starts_with("/dev/full: "), "{err}");
        let null = Path::new("/dev/null");
        write_atomically(null, |w| put(w, null, b"gone")).unwrap();
        assert!(!fs::metadata(null).unwrap().is_file());
        assert_eq!(resolve(null).unwrap(), Target::Special(null.to_path_buf()));
    }

    #[test]
    fn regular_paths_resolve_to_themselves() {
        let dir = fresh("plain");
        let p = dir.join("x.bin");
        assert_eq!(resolve(&p).unwrap(), Target::Regular(p.clone()));
        write_atomically(&p, |w| put(w, &p, b"one")).unwrap();
        assert_eq!(resolve(&p).unwrap(), Target::Regular(p.clone()));
        write_atomically(&p, |w| put(w, &p, b"two")).unwrap();
        assert_eq!(fs::read(&p).unwrap(), b"two");
        assert_eq!(listing(&dir), ["x.bin"]);
        // A missing directory is an error naming the path.
        let q = dir.join("missing").join("y.bin");
        let err = write_atomically(&q, |w| put(w, &q, b"x")).unwrap_err();
        assert!(
            err.to_string().starts_with(&q.display().to_string()),
            "{err}"
        );
        fs::remove_dir_all(&dir).unwrap();
    }
}
