use std::fs::{self, File};
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};

use crate::error::{Error, io};

/// Writes a file atomically: `write` fills a temporary file in the same
/// directory (`.NAME.tmp-PID`), which is flushed, synced and renamed over
/// `path`. On any error the temporary file is removed and `path` is untouched.
///
/// A process killed outright (SIGKILL, power loss) cannot clean up: it leaves
/// at most its hidden temporary file, never a partial `path`. The next write
/// of the same `path` removes such leftovers whose process no longer exists
/// (on Linux, where that can be checked through `/proc`).
pub fn write_atomically(
    path: &Path,
    write: impl FnOnce(&mut BufWriter<File>) -> Result<(), Error>,
) -> Result<(), Error> {
    let tmp = temp_path(path);
    remove_orphaned_temps(path);
    let result = (|| {
        let file = File::create(&tmp).map_err(io(path))?;
        let mut w = BufWriter::new(file);
        write(&mut w)?;
        let file = w.into_inner().map_err(|e| Error::Io {
            path: path.to_path_buf(),
            source: e.into_error(),
        })?;
        file.sync_all().map_err(io(path))?;
        fs::rename(&tmp, path).map_err(io(path))
    })();
    if result.is_err() {
        let _ = fs::remove_file(&tmp);
    }
    result
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
pub(crate) fn put(w: &mut impl Write, path: &Path, bytes: &[u8]) -> Result<(), Error> {
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
}
