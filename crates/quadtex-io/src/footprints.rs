//! The footprint dump (`quadtex footprints`): for every pixel of a render,
//! what a texture lookup needs, in OpenImageIO's conventions, so a peer
//! filter can run on exactly the same footprints. Layout in
//! `docs/footprints.md`.
//!
//! Conventions: `s` runs right and `t` runs **down** the texture image
//! (OpenImageIO's), so `s = x` and `t = 1 − z` in quadtex's texture space
//! (`z` up). Derivatives are per pixel step to the right (`…dx`) and per
//! pixel step **down** the image (`…dy`), matching raster order. Coordinates
//! are not wrapped: a repeating texture's `s, t` may lie outside `[0, 1)`.

use std::io::Write;
use std::path::Path;

use crate::atomic::{put, write_atomically};
use crate::error::Error;

/// First eight bytes of a footprint dump.
pub const FOOTPRINT_MAGIC: &[u8; 8] = b"QTXFP001";

/// One pixel's lookup.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FootprintRecord {
    /// Index into [`FootprintDump::textures`], or `None` when the pixel's
    /// centre sees no textured surface.
    pub texture: Option<u32>,
    /// Texture coordinates of the centre hit (OpenImageIO convention).
    pub st: [f32; 2],
    /// `[dsdx, dtdx, dsdy, dtdy]`.
    pub derivatives: [f32; 4],
    /// The footprint quadrilateral's corners in `s, t`, in the order of the
    /// pixel corners top-left, top-right, bottom-right, bottom-left.
    pub quad: [[f32; 2]; 4],
}

/// How a dumped texture continues beyond `[0, 1)²`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum DumpWrap {
    /// Periodic.
    Repeat,
    /// Edge texels extend.
    Clamp,
    /// Transparent black outside.
    Black,
}

/// A texture named by the dump.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct DumpTexture {
    /// File the peer reads (an EXR raster of the texture, relative to the dump).
    pub file: String,
    /// Wrap mode.
    pub wrap: DumpWrap,
}

/// A whole dump: image size, textures, one record per pixel in raster order.
#[derive(Debug, Clone, PartialEq)]
pub struct FootprintDump {
    /// Image width.
    pub width: u32,
    /// Image height.
    pub height: u32,
    /// Textures, indexed by [`FootprintRecord::texture`].
    pub textures: Vec<DumpTexture>,
    /// `width × height` records, row 0 at the top.
    pub records: Vec<FootprintRecord>,
}

const NO_TEXTURE: u32 = u32::MAX;

/// Writes `dump` atomically.
pub fn write_footprints(path: &Path, dump: &FootprintDump) -> Result<(), Error> {
    if dump.records.len() as u64 != u64::from(dump.width) * u64::from(dump.height) {
        return Err(Error::Format {
            path: path.into(),
            field: "records",
            message: format!(
                "{} records for {}x{} pixels",
                dump.records.len(),
                dump.width,
                dump.height
            ),
        });
    }
    write_atomically(path, |w| {
        let mut head = Vec::new();
        head.extend_from_slice(FOOTPRINT_MAGIC);
        head.extend_from_slice(&dump.width.to_le_bytes());
        head.extend_from_slice(&dump.height.to_le_bytes());
        head.extend_from_slice(&(dump.textures.len() as u32).to_le_bytes());
        for t in &dump.textures {
            let wrap = match t.wrap {
                DumpWrap::Repeat => 0u8,
                DumpWrap::Clamp => 1,
                DumpWrap::Black => 2,
            };
            head.push(wrap);
            head.extend_from_slice(&(t.file.len() as u32).to_le_bytes());
            head.extend_from_slice(t.file.as_bytes());
        }
        put(w, path, &head)?;
        let mut rec = Vec::with_capacity(RECORD_BYTES);
        for r in &dump.records {
            rec.clear();
            rec.extend_from_slice(&r.texture.unwrap_or(NO_TEXTURE).to_le_bytes());
            for v in
                r.st.iter()
                    .chain(&r.derivatives)
                    .chain(r.quad.iter().flatten())
            {
                rec.extend_from_slice(&v.to_le_bytes());
            }
            put(w, path, &rec)?;
        }
        w.flush().map_err(|source| Error::Io {
            path: path.into(),
            source,
        })
    })
}

/// Bytes per record: texture index and 14 floats.
pub const RECORD_BYTES: usize = 4 + 4 * 14;

/// Reads a dump written by [`write_footprints`].
pub fn read_footprints(path: &Path) -> Result<FootprintDump, Error> {
    let bytes = std::fs::read(path).map_err(|source| Error::Io {
        path: path.into(),
        source,
    })?;
    let bad = |field: &'static str, message: String| Error::Format {
        path: path.into(),
        field,
        message,
    };
    let mut at = 0usize;
    let mut take = |n: usize, field: &'static str| -> Result<&[u8], Error> {
        let s = bytes
            .get(at..at + n)
            .ok_or_else(|| bad(field, format!("file ends at byte {}", bytes.len())))?;
        at += n;
        Ok(s)
    };
    let u32_of = |b: &[u8]| u32::from_le_bytes([b[0], b[1], b[2], b[3]]);
    if take(8, "magic")? != FOOTPRINT_MAGIC {
        return Err(bad("magic", "not a quadtex footprint dump".into()));
    }
    let width = u32_of(take(4, "width")?);
    let height = u32_of(take(4, "height")?);
    let count = u32_of(take(4, "texture_count")?);
    if count > 1 << 16 {
        return Err(bad("texture_count", format!("{count} textures")));
    }
    let mut textures = Vec::new();
    for _ in 0..count {
        let wrap = match take(1, "wrap")?[0] {
            0 => DumpWrap::Repeat,
            1 => DumpWrap::Clamp,
            2 => DumpWrap::Black,
            w => return Err(bad("wrap", format!("unknown wrap {w}"))),
        };
        let len = u32_of(take(4, "file_name_length")?) as usize;
        let name = std::str::from_utf8(take(len, "file_name")?)
            .map_err(|e| bad("file_name", e.to_string()))?
            .to_string();
        textures.push(DumpTexture { file: name, wrap });
    }
    let n = u64::from(width) * u64::from(height);
    let remaining = (bytes.len() - at) as u64;
    if remaining != n * RECORD_BYTES as u64 {
        return Err(bad(
            "records",
            format!("{remaining} bytes for {n} records of {RECORD_BYTES}"),
        ));
    }
    let mut records = Vec::with_capacity(n as usize);
    for chunk in bytes[at..].chunks_exact(RECORD_BYTES) {
        let index = u32_of(&chunk[..4]);
        let f = |i: usize| {
            let o = 4 + 4 * i;
            f32::from_le_bytes([chunk[o], chunk[o + 1], chunk[o + 2], chunk[o + 3]])
        };
        if index != NO_TEXTURE && index >= count {
            return Err(bad("texture", format!("index {index} of {count} textures")));
        }
        records.push(FootprintRecord {
            texture: (index != NO_TEXTURE).then_some(index),
            st: [f(0), f(1)],
            derivatives: [f(2), f(3), f(4), f(5)],
            quad: [[f(6), f(7)], [f(8), f(9)], [f(10), f(11)], [f(12), f(13)]],
        });
    }
    Ok(FootprintDump {
        width,
        height,
        textures,
        records,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn dump_round_trips_and_rejects_damage() {
        let dir = std::env::temp_dir().join(format!("quadtex-fp-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("fp.bin");
        let record = |i: u32| FootprintRecord {
            texture: (!i.is_multiple_of(3)).then_some(i % 2),
            st: [i as f32 * 0.5, -1.25],
            derivatives: [1e-3, -2e-4, 3e-5, f32::MIN_POSITIVE],
            quad: [[0.0, 1.0], [2.0, 3.0], [4.0, 5.0], [6.0, 7.5]],
        };
        let dump = FootprintDump {
            width: 3,
            height: 2,
            textures: vec![
                DumpTexture {
                    file: "texture-0.exr".into(),
                    wrap: DumpWrap::Repeat,
                },
                DumpTexture {
                    file: "texture-1.exr".into(),
                    wrap: DumpWrap::Clamp,
                },
            ],
            records: (0..6).map(record).collect(),
        };
        write_footprints(&path, &dump).unwrap();
        assert_eq!(read_footprints(&path).unwrap(), dump);
        let mut bytes = std::fs::read(&path).unwrap();
        bytes.pop();
        std::fs::write(&path, &bytes).unwrap();
        let e = read_footprints(&path).unwrap_err().to_string();
        assert!(e.contains("records"), "{e}");
        std::fs::write(&path, b"QTXFP00").unwrap();
        assert!(read_footprints(&path).is_err());
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
