//! TIFF and BigTIFF input through the `tiff` crate: the first image of the
//! file (IFD 0; overviews, masks and other images are ignored), stripped or
//! tiled, chunky or planar, 8- or 16-bit unsigned samples; grey (either
//! photometric sense), grey + alpha, RGB, RGBA, and JPEG-compressed YCbCr;
//! uncompressed, LZW, Deflate, PackBits or JPEG. Decoded one strip or tile
//! at a time, straight into the texels, so decoding holds the texels and
//! one chunk; [`TiffTiles`] reads a tiled TIFF's tiles one at a time for
//! `pack-tiles`.
//!
//! Samples are taken as sRGB with straight alpha, as PNG's are; associated
//! (premultiplied) alpha is divided out first, and JPEG's YCbCr is turned
//! into RGB with the JFIF equations. 8-bit images keep their bytes (texel
//! blocks store them as they are), 16-bit ones go the 16-bit PNG's way.
//! Everything else (float, signed, 1-, 4-, 12- or 32-bit samples, palette,
//! CMYK, Lab, other compressions) is refused with an error naming the
//! field. GeoTIFF tags, when present, are kept as metadata
//! ([`GeoReference`]); they are never required.

use std::fmt;
use std::fs::File;
use std::io::{BufReader, Read, Seek};
use std::path::{Path, PathBuf};
use std::sync::Mutex;

use quadtex_core::{Mosaic, TexelGrid, Unorm16Rgba};
use tiff::decoder::{ChunkType, Decoder, DecodingResult};
use tiff::tags::Tag;
use tiff::{TiffError, TiffFormatError};

use crate::error::{Error, io};
use crate::limits::Limits;

/// What lowers a decoding estimate or raises the budget.
const KNOBS: &str = "use a smaller image, `pack-tiles` for a tiled TIFF, or raise --memory-limit";

/// Whether `head` (a file's first bytes) starts a TIFF (`II*\0`, `MM\0*`)
/// or BigTIFF (`II+\0`, `MM\0+`).
pub(crate) fn is_tiff(head: &[u8]) -> bool {
    matches!(
        head.get(..4),
        Some(b"II*\0" | b"MM\0*" | b"II+\0" | b"MM\0+")
    )
}

/// Whether the file at `path` starts like a TIFF (false if it cannot be read).
pub(crate) fn file_is_tiff(path: &Path) -> bool {
    let mut head = [0u8; 4];
    File::open(path)
        .and_then(|mut f| f.read_exact(&mut head))
        .is_ok()
        && is_tiff(&head)
}

/// The georeferencing of a GeoTIFF, kept as metadata: the `.qtx` format has
/// no place for it, so `quadtex pack` and `pack-tiles` print it in their
/// summary. Present when any of the GeoTIFF tags (or GDAL's no-data tag)
/// is; never required. A tag present but malformed is left out and named
/// in [`GeoReference::ignored`] rather than refusing the image.
#[derive(Debug, Clone, PartialEq, Default)]
#[non_exhaustive]
pub struct GeoReference {
    /// `ModelTiepointTag`: raster point `(I, J, K)` ↔ model point `(X, Y, Z)`,
    /// as `[I, J, K, X, Y, Z]` each.
    pub tiepoints: Vec<[f64; 6]>,
    /// `ModelPixelScaleTag`: `(ScaleX, ScaleY, ScaleZ)`, model units a texel.
    pub pixel_scale: Option<[f64; 3]>,
    /// `ModelTransformationTag`: the raster-to-model matrix, 4 × 4 row-major.
    pub transformation: Option<[f64; 16]>,
    /// `GeoKeyDirectoryTag`'s keys, `[KeyID, TIFFTagLocation, Count,
    /// Value_Offset]` each (the header dropped).
    pub geo_keys: Vec<[u16; 4]>,
    /// `GeoDoubleParamsTag`: the doubles keys refer to.
    pub geo_doubles: Vec<f64>,
    /// `GeoAsciiParamsTag`: the text keys refer to.
    pub geo_ascii: Option<String>,
    /// GDAL's `GDAL_NODATA` tag: the no-data value, as written.
    pub nodata: Option<String>,
    /// Tags that were present but malformed, by name; left out above.
    pub ignored: Vec<&'static str>,
}

impl GeoReference {
    /// The short value of GeoKey `id` stored in the directory itself
    /// (`TIFFTagLocation` 0), if present.
    pub fn geo_key(&self, id: u16) -> Option<u16> {
        self.geo_keys
            .iter()
            .find(|k| k[0] == id && k[1] == 0)
            .map(|k| k[3])
    }

    /// The EPSG code of the model's coordinate system:
    /// `ProjectedCSTypeGeoKey` (3072), else `GeographicTypeGeoKey` (2048);
    /// none when absent or user-defined (32767).
    pub fn epsg(&self) -> Option<u16> {
        [3072, 2048]
            .into_iter()
            .filter_map(|id| self.geo_key(id))
            .find(|&code| code != 0 && code != 32767)
    }

    /// Reads the tags from the decoder's current image; `None` when there
    /// are none.
    fn read<R: Read + Seek>(d: &mut Decoder<R>) -> Option<GeoReference> {
        let mut t = TagFetch {
            d,
            any: false,
            ignored: Vec::new(),
        };
        let mut g = GeoReference::default();
        if let Some(v) = t.doubles(Tag::ModelTiepointTag) {
            if v.len() % 6 == 0 && !v.is_empty() {
                g.tiepoints = v
                    .chunks_exact(6)
                    .map(|c| [c[0], c[1], c[2], c[3], c[4], c[5]])
                    .collect();
            } else {
                t.ignore(Tag::ModelTiepointTag);
            }
        }
        if let Some(v) = t.doubles(Tag::ModelPixelScaleTag) {
            match <[f64; 3]>::try_from(v.as_slice()) {
                Ok(s) => g.pixel_scale = Some(s),
                Err(_) => t.ignore(Tag::ModelPixelScaleTag),
            }
        }
        if let Some(v) = t.doubles(Tag::ModelTransformationTag) {
            match <[f64; 16]>::try_from(v.as_slice()) {
                Ok(m) => g.transformation = Some(m),
                Err(_) => t.ignore(Tag::ModelTransformationTag),
            }
        }
        if let Some(v) = t.doubles(Tag::GeoDoubleParamsTag) {
            g.geo_doubles = v;
        }
        if let Some(v) = t.value(Tag::GeoKeyDirectoryTag) {
            match v.into_u16_vec() {
                // Header: version 1, revision, minor revision, key count.
                Ok(v) if v.len() >= 4 && v[0] == 1 && v.len() >= 4 + 4 * usize::from(v[3]) => {
                    g.geo_keys = v[4..4 + 4 * usize::from(v[3])]
                        .chunks_exact(4)
                        .map(|k| [k[0], k[1], k[2], k[3]])
                        .collect();
                }
                _ => t.ignore(Tag::GeoKeyDirectoryTag),
            }
        }
        g.geo_ascii = t.text(Tag::GeoAsciiParamsTag);
        g.nodata = t.text(Tag::GdalNodata);
        g.ignored = t.ignored;
        t.any.then_some(g)
    }
}

/// Reads optional tags, noting whether any was present and which were
/// malformed.
struct TagFetch<'a, R: Read + Seek> {
    d: &'a mut Decoder<R>,
    any: bool,
    ignored: Vec<&'static str>,
}

impl<R: Read + Seek> TagFetch<'_, R> {
    fn ignore(&mut self, tag: Tag) {
        self.ignored.push(tag_name(tag));
    }

    fn value(&mut self, tag: Tag) -> Option<tiff::decoder::ifd::Value> {
        match self.d.find_tag(tag) {
            Ok(Some(v)) => {
                self.any = true;
                Some(v)
            }
            Ok(None) => None,
            Err(_) => {
                self.any = true;
                self.ignore(tag);
                None
            }
        }
    }

    /// A tag's doubles, all finite.
    fn doubles(&mut self, tag: Tag) -> Option<Vec<f64>> {
        match self.value(tag)?.into_f64_vec() {
            Ok(v) if v.iter().all(|x| x.is_finite()) => Some(v),
            _ => {
                self.ignore(tag);
                None
            }
        }
    }

    /// A tag's text, without the trailing NUL (and GeoTIFF's `|`).
    fn text(&mut self, tag: Tag) -> Option<String> {
        match self.value(tag)?.into_string() {
            Ok(s) => Some(s.trim_end_matches(['\0', '|']).to_string()),
            Err(_) => {
                self.ignore(tag);
                None
            }
        }
    }
}

fn tag_name(tag: Tag) -> &'static str {
    match tag {
        Tag::ModelTiepointTag => "ModelTiepointTag",
        Tag::ModelPixelScaleTag => "ModelPixelScaleTag",
        Tag::ModelTransformationTag => "ModelTransformationTag",
        Tag::GeoKeyDirectoryTag => "GeoKeyDirectoryTag",
        Tag::GeoDoubleParamsTag => "GeoDoubleParamsTag",
        Tag::GeoAsciiParamsTag => "GeoAsciiParamsTag",
        Tag::GdalNodata => "GDAL_NODATA",
        _ => "tag",
    }
}

/// `EPSG:32633, tiepoint (0, 0, 0) -> (500000, 4650000, 0), pixel scale
/// (10, 10, 0)`: what the `pack` summaries print after `georeferenced: `.
impl fmt::Display for GeoReference {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let mut parts = Vec::new();
        if let Some(code) = self.epsg() {
            parts.push(format!("EPSG:{code}"));
        } else if !self.geo_keys.is_empty() {
            parts.push(format!("{} GeoKeys", self.geo_keys.len()));
        }
        if let Some(t) = self.tiepoints.first() {
            let more = match self.tiepoints.len() {
                1 => String::new(),
                n => format!(" (first of {n})"),
            };
            parts.push(format!(
                "tiepoint ({}, {}, {}) -> ({}, {}, {}){more}",
                t[0], t[1], t[2], t[3], t[4], t[5]
            ));
        }
        if let Some([x, y, z]) = self.pixel_scale {
            parts.push(format!("pixel scale ({x}, {y}, {z})"));
        }
        if let Some(m) = self.transformation {
            parts.push(format!(
                "transformation [{} {} {} {}; {} {} {} {}; …]",
                m[0], m[1], m[2], m[3], m[4], m[5], m[6], m[7]
            ));
        }
        if let Some(nodata) = &self.nodata {
            parts.push(format!("no-data {nodata}"));
        }
        if !self.ignored.is_empty() {
            parts.push(format!("malformed {} ignored", self.ignored.join(", ")));
        }
        if parts.is_empty() {
            parts.push("GeoTIFF tags without values".into());
        }
        write!(f, "{}", parts.join(", "))
    }
}

/// How the samples of a pixel make its colour.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Colour {
    Grey,
    Rgb,
    /// JPEG-compressed YCbCr (8-bit), turned into RGB.
    YCbCr,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Alpha {
    Opaque,
    Straight,
    /// Associated alpha: colour premultiplied, divided out on reading.
    Premultiplied,
}

/// The first image's layout, checked: what [`Layout::read_chunk`] decodes
/// and how its samples become texels.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(crate) struct Layout {
    pub(crate) width: u32,
    pub(crate) height: u32,
    /// Bits a sample: 8 or 16.
    bits: u8,
    colour: Colour,
    alpha: Alpha,
    /// Samples a decoded pixel holds, and alpha's place among them.
    stride: usize,
    alpha_at: usize,
    /// Samples a pixel has in the file.
    samples: u16,
    /// The sample planes read, for a planar image; empty when chunky.
    planes: Vec<u16>,
    pub(crate) tiled: bool,
    /// A chunk's (strip's or tile's) width and height; a strip's height is
    /// at most the image's.
    pub(crate) chunk: (u32, u32),
    /// Chunks across and down (in one plane).
    pub(crate) across: u32,
    pub(crate) down: u32,
    /// A JPEG-compressed image's chunks, `(offset, bytes)` each: their
    /// frame sizes are checked before the JPEG decoder allocates for them.
    jpeg_chunks: Vec<(u64, u64)>,
}

/// One chunk's samples, `stride` a pixel, row-major.
enum Samples {
    U8(Vec<u8>),
    U16(Vec<u16>),
}

/// A file's TIFF problem in `field`: an [`Error::Image`] naming both.
fn bad(path: &Path, field: &str, problem: impl fmt::Display) -> Error {
    Error::Image {
        path: path.to_path_buf(),
        message: format!("TIFF {field}: {problem}"),
    }
}

/// The decoder's error, said plainly; `what` names the part read.
fn decode_error(path: &Path, what: &str, e: TiffError) -> Error {
    let problem = match e {
        TiffError::IoError(e) if e.kind() == std::io::ErrorKind::UnexpectedEof => {
            "the file ends early (truncated?)".to_string()
        }
        TiffError::FormatError(TiffFormatError::TiffSignatureNotFound)
        | TiffError::FormatError(TiffFormatError::TiffSignatureInvalid) => {
            "not a TIFF file (bad signature)".to_string()
        }
        TiffError::FormatError(e) => format!("malformed: {e}"),
        TiffError::UnsupportedError(e) => format!("not supported: {e}"),
        TiffError::LimitsExceeded => {
            "a chunk or tag is larger than the decoder's limits allow".to_string()
        }
        e => e.to_string(),
    };
    bad(path, what, problem)
}

/// Runs `body`, turning a panic inside the decoder (hostile input the
/// `tiff` crate does not foresee) into the file's error.
fn guarded<T>(
    path: &Path,
    what: &str,
    body: impl FnOnce() -> Result<T, Error>,
) -> Result<T, Error> {
    std::panic::catch_unwind(std::panic::AssertUnwindSafe(body)).unwrap_or_else(|panic| {
        let message = panic
            .downcast_ref::<&str>()
            .map(|s| (*s).to_string())
            .or_else(|| panic.downcast_ref::<String>().cloned())
            .unwrap_or_else(|| "a panic".to_string());
        Err(bad(
            path,
            what,
            format!("the decoder (tiff crate) failed: {message}"),
        ))
    })
}

/// A decoder on `reader` with the decoding buffers bounded by `limits`'
/// memory budget (the tag tables keep the crate's 1 MiB bound).
fn open_decoder<R: Read + Seek>(
    reader: R,
    path: &Path,
    limits: &Limits,
) -> Result<Decoder<R>, Error> {
    guarded(path, "header", || {
        let decoder = Decoder::new(reader).map_err(|e| decode_error(path, "header", e))?;
        let mut tl = tiff::decoder::Limits::default();
        let budget = usize::try_from(limits.max_memory).unwrap_or(usize::MAX);
        tl.decoding_buffer_size = budget;
        tl.intermediate_buffer_size = budget;
        Ok(decoder.with_limits(tl))
    })
}

impl Layout {
    /// Reads and checks the current image's tags: every unsupported kind
    /// of sample is refused here, before anything is allocated.
    fn read<R: Read + Seek>(d: &mut Decoder<R>, path: &Path) -> Result<Layout, Error> {
        let err = |field: &'static str| move |e: TiffError| decode_error(path, field, e);
        let (width, height) = d.dimensions().map_err(err("ImageWidth"))?;
        let formats = d
            .find_tag_unsigned_vec::<u16>(Tag::SampleFormat)
            .map_err(err("SampleFormat"))?
            .unwrap_or_default();
        if let Some(&f) = formats.iter().find(|&&f| f != 1) {
            let what = match f {
                2 => "signed integer".to_string(),
                3 => "floating-point".to_string(),
                4 => "undefined".to_string(),
                other => format!("code {other}"),
            };
            return Err(bad(
                path,
                "SampleFormat",
                format!("{what} samples are not supported (unsigned integers are)"),
            ));
        }
        let bits = d
            .find_tag_unsigned_vec::<u16>(Tag::BitsPerSample)
            .map_err(err("BitsPerSample"))?
            .and_then(|b| b.first().copied())
            .unwrap_or(1);
        if bits != 8 && bits != 16 {
            let kind = if bits == 1 { " (bilevel)" } else { "" };
            return Err(bad(
                path,
                "BitsPerSample",
                format!("{bits}-bit samples{kind} are not supported (8- and 16-bit are)"),
            ));
        }
        let compression = d
            .find_tag_unsigned::<u16>(Tag::Compression)
            .map_err(err("Compression"))?
            .unwrap_or(1);
        if !matches!(compression, 1 | 5 | 7 | 8 | 32773 | 32946) {
            let name = match compression {
                2 => "CCITT RLE".to_string(),
                3 => "CCITT Group 3 fax".to_string(),
                4 => "CCITT Group 4 fax".to_string(),
                6 => "old-style JPEG".to_string(),
                34887 => "LERC".to_string(),
                34925 => "LZMA".to_string(),
                50000 => "Zstandard".to_string(),
                50001 => "WebP".to_string(),
                other => format!("code {other}"),
            };
            return Err(bad(
                path,
                "Compression",
                format!("{name} is not supported (none, LZW, Deflate, PackBits and JPEG are)"),
            ));
        }
        let photometric = d
            .find_tag_unsigned::<u16>(Tag::PhotometricInterpretation)
            .map_err(err("PhotometricInterpretation"))?
            .ok_or_else(|| bad(path, "PhotometricInterpretation", "missing"))?;
        let samples = d
            .find_tag_unsigned::<u16>(Tag::SamplesPerPixel)
            .map_err(err("SamplesPerPixel"))?
            .unwrap_or(1);
        let extras = d
            .find_tag_unsigned_vec::<u16>(Tag::ExtraSamples)
            .map_err(err("ExtraSamples"))?
            .unwrap_or_default();
        let colour_samples = usize::from(samples)
            .checked_sub(extras.len())
            .filter(|&n| n > 0)
            .ok_or_else(|| {
                bad(
                    path,
                    "ExtraSamples",
                    format!("{} extra samples of {samples}", extras.len()),
                )
            })?;
        let planar = d
            .find_tag_unsigned::<u16>(Tag::PlanarConfiguration)
            .map_err(err("PlanarConfiguration"))?
            == Some(2);
        let unsupported = |what: &str| {
            Err(bad(
                path,
                "PhotometricInterpretation",
                format!("{what} is not supported (grey, RGB, and JPEG YCbCr are)"),
            ))
        };
        let mut alpha = match extras.first() {
            Some(1) => Alpha::Premultiplied,
            Some(2) => Alpha::Straight,
            _ => Alpha::Opaque,
        };
        let colour = match photometric {
            0 | 1 if colour_samples == 1 => {
                if photometric == 0 && samples > 1 {
                    return unsupported("WhiteIsZero grey with extra samples");
                }
                Colour::Grey
            }
            0 | 1 => return unsupported(&format!("grey with {colour_samples} samples a pixel")),
            2 if colour_samples == 3 => Colour::Rgb,
            // Four samples and no ExtraSamples: the fourth taken as alpha.
            2 if colour_samples == 4 && extras.is_empty() => {
                alpha = Alpha::Straight;
                Colour::Rgb
            }
            2 => return unsupported(&format!("RGB with {colour_samples} samples a pixel")),
            6 if compression == 7 && samples == 3 && bits == 8 => Colour::YCbCr,
            6 => return unsupported("YCbCr other than 8-bit JPEG-compressed"),
            3 => return unsupported("palette colour"),
            4 => return unsupported("a transparency mask"),
            5 => return unsupported("CMYK"),
            8..=10 => return unsupported("CIE L*a*b*"),
            other => return unsupported(&format!("photometric interpretation {other}")),
        };
        let colours = if colour == Colour::Grey { 1 } else { 3 };
        let (stride, alpha_at, planes) = if planar {
            let mut planes: Vec<u16> = (0..colours as u16).collect();
            if alpha != Alpha::Opaque {
                planes.push(colour_samples as u16);
            }
            (planes.len(), colours, planes)
        } else {
            // As the decoder lays chunky pixels out: grey keeps every
            // sample, RGB drops the extras after alpha.
            let stride = match colour {
                Colour::Grey => usize::from(samples),
                _ if alpha == Alpha::Opaque => 3,
                _ => 4,
            };
            (stride, colours, Vec::new())
        };
        let tiled = d.get_chunk_type() == ChunkType::Tile;
        let (cw, ch) = d.chunk_dimensions();
        let chunk = if tiled {
            (cw, ch)
        } else {
            (width, ch.min(height))
        };
        if chunk.0 == 0 || chunk.1 == 0 {
            let field = if tiled { "TileWidth" } else { "RowsPerStrip" };
            return Err(bad(path, field, "zero"));
        }
        let jpeg_chunks = if compression == 7 {
            let (offsets, counts) = if tiled {
                (Tag::TileOffsets, Tag::TileByteCounts)
            } else {
                (Tag::StripOffsets, Tag::StripByteCounts)
            };
            let offsets = d.get_tag_u64_vec(offsets).map_err(err("chunk offsets"))?;
            let counts = d
                .get_tag_u64_vec(counts)
                .map_err(err("chunk byte counts"))?;
            offsets.into_iter().zip(counts).collect()
        } else {
            Vec::new()
        };
        Ok(Layout {
            width,
            height,
            bits: bits as u8,
            colour,
            alpha,
            stride,
            alpha_at,
            samples,
            planes,
            tiled,
            chunk,
            across: width.div_ceil(chunk.0),
            down: height.div_ceil(chunk.1),
            jpeg_chunks,
        })
    }

    /// Estimated peak bytes to decode one chunk: its samples as stored
    /// and as read out.
    fn chunk_bytes(&self) -> u64 {
        let samples = u64::from(self.samples.max(self.stride as u16));
        (u64::from(self.chunk.0) * u64::from(self.chunk.1))
            .saturating_mul(2 * samples * u64::from(self.bits / 8))
    }

    /// Bytes a texel takes once decoded: the 8-bit bytes and the grid's
    /// unorm16 texels, or the unorm16 texels alone.
    fn texel_bytes(&self) -> u64 {
        if self.bits == 8 { 12 } else { 8 }
    }

    /// Chunk `unit` (row-major, one plane's numbering) as `(x0, y0, w, h)`.
    fn chunk_rect(&self, unit: u32) -> (u32, u32, u32, u32) {
        let (x0, y0) = (
            (unit % self.across) * self.chunk.0,
            (unit / self.across) * self.chunk.1,
        );
        (
            x0,
            y0,
            self.chunk.0.min(self.width - x0),
            self.chunk.1.min(self.height - y0),
        )
    }

    /// What a chunk is called in errors.
    fn chunk_name(&self, unit: u32) -> String {
        if self.tiled {
            format!(
                "tile (row {}, col {})",
                unit / self.across,
                unit % self.across
            )
        } else {
            format!("strip {unit}")
        }
    }

    /// Decodes chunk `unit`: `stride` samples a pixel, `w × h` pixels.
    fn read_chunk<R: Read + Seek>(
        &self,
        d: &mut Decoder<R>,
        unit: u32,
        path: &Path,
    ) -> Result<Samples, Error> {
        let name = self.chunk_name(unit);
        let (_, _, w, h) = self.chunk_rect(unit);
        let pixels = w as usize * h as usize;
        guarded(path, &name, || {
            let wrong = |len: usize| {
                bad(
                    path,
                    &name,
                    format!("decoded to {len} samples, not the {w}x{h} pixels' worth"),
                )
            };
            let read = |d: &mut Decoder<R>, index: u32, per_pixel: usize| {
                self.check_jpeg_frame(d, index, path, &name)?;
                let samples = match d.read_chunk(index) {
                    Ok(DecodingResult::U8(v)) if self.bits == 8 => Samples::U8(v),
                    Ok(DecodingResult::U16(v)) if self.bits == 16 => Samples::U16(v),
                    Ok(_) => return Err(bad(path, &name, "decoded to an unexpected sample type")),
                    Err(e) => return Err(decode_error(path, &name, e)),
                };
                let len = match &samples {
                    Samples::U8(v) => v.len(),
                    Samples::U16(v) => v.len(),
                };
                if len < pixels * per_pixel {
                    return Err(wrong(len));
                }
                Ok(samples)
            };
            if self.planes.is_empty() {
                return read(d, unit, self.stride);
            }
            let per_plane = self.across * self.down;
            let mut out = match self.bits {
                8 => Samples::U8(vec![0; pixels * self.stride]),
                _ => Samples::U16(vec![0; pixels * self.stride]),
            };
            for (k, &plane) in self.planes.iter().enumerate() {
                let index = u32::from(plane)
                    .checked_mul(per_plane)
                    .and_then(|i| i.checked_add(unit))
                    .ok_or_else(|| bad(path, &name, "plane index out of range"))?;
                match (read(d, index, 1)?, &mut out) {
                    (Samples::U8(p), Samples::U8(o)) => interleave(&p, o, k, self.stride),
                    (Samples::U16(p), Samples::U16(o)) => interleave(&p, o, k, self.stride),
                    _ => return Err(bad(path, &name, "planes of different sample types")),
                }
            }
            Ok(out)
        })
    }

    /// Refuses a JPEG chunk whose frame is larger than the chunk (rounded
    /// up to JPEG's 16-texel blocks): the JPEG decoder would allocate the
    /// frame, up to 16384² texels, whatever the TIFF says.
    fn check_jpeg_frame<R: Read + Seek>(
        &self,
        d: &mut Decoder<R>,
        index: u32,
        path: &Path,
        name: &str,
    ) -> Result<(), Error> {
        let Some(&(offset, len)) = self.jpeg_chunks.get(index as usize) else {
            return Ok(());
        };
        // An unreadable frame is left to the decoder to report.
        if let Ok(Some((w, h))) = jpeg_frame(d.inner(), offset, len) {
            let (cw, ch) = (
                self.chunk.0.div_ceil(16) * 16,
                self.chunk.1.div_ceil(16) * 16,
            );
            if w > cw || h > ch {
                return Err(bad(
                    path,
                    name,
                    format!(
                        "its JPEG frame is {w}x{h} texels, larger than the {}x{} chunk",
                        self.chunk.0, self.chunk.1
                    ),
                ));
            }
        }
        Ok(())
    }

    /// One row of 8-bit samples as straight sRGB bytes; the common
    /// layouts copied directly.
    fn row_to_srgb8(&self, input: &[u8], out: &mut [[u8; 4]]) {
        let pixels = out.iter_mut().zip(input.chunks_exact(self.stride));
        match (self.colour, self.alpha) {
            (Colour::Rgb, Alpha::Opaque) => {
                pixels.for_each(|(o, i)| *o = [i[0], i[1], i[2], 255]);
            }
            (Colour::Rgb, Alpha::Straight) => {
                pixels.for_each(|(o, i)| *o = [i[0], i[1], i[2], i[3]]);
            }
            (Colour::Grey, Alpha::Opaque) => {
                pixels.for_each(|(o, i)| *o = [i[0], i[0], i[0], 255]);
            }
            (Colour::Grey, Alpha::Straight) => {
                pixels.for_each(|(o, i)| *o = [i[0], i[0], i[0], i[1]]);
            }
            _ => pixels.for_each(|(o, i)| *o = self.straight(i, 255).map(|v| v as u8)),
        }
    }

    /// One pixel's samples (`stride` of them) as straight-alpha RGBA in
    /// `[0, max]`.
    #[inline]
    fn straight<T: Copy + Into<u32>>(&self, p: &[T], max: u32) -> [u32; 4] {
        let a = match self.alpha {
            Alpha::Opaque => max,
            _ => p[self.alpha_at].into(),
        };
        let mut c = match self.colour {
            Colour::Grey => [p[0].into(); 3],
            Colour::Rgb => [p[0].into(), p[1].into(), p[2].into()],
            Colour::YCbCr => ycbcr_to_rgb(p[0].into(), p[1].into(), p[2].into()),
        };
        if self.alpha == Alpha::Premultiplied {
            for v in &mut c {
                *v = if a == 0 {
                    0
                } else {
                    ((u64::from(*v) * u64::from(max) + u64::from(a / 2)) / u64::from(a))
                        .min(u64::from(max)) as u32
                };
            }
        }
        [c[0], c[1], c[2], a]
    }

    /// Decodes the chunks `units` one at a time and calls `row(output
    /// range, samples, first sample)` for each of their rows' parts inside
    /// the rectangle `(x0, y0, w, h)`: the range in the row-major `w`-wide
    /// output whose top-left texel is `(x0, y0)`.
    fn for_each_row<R: Read + Seek>(
        &self,
        d: &mut Decoder<R>,
        path: &Path,
        (x0, y0, w, h): (u32, u32, u32, u32),
        units: impl Iterator<Item = u32>,
        mut row: impl FnMut(std::ops::Range<usize>, &Samples, usize),
    ) -> Result<(), Error> {
        for unit in units {
            let samples = self.read_chunk(d, unit, path)?;
            let (cx, cy, cw, ch) = self.chunk_rect(unit);
            // The chunk's part inside the rectangle.
            let (xs, xe) = (cx.max(x0), (cx + cw).min(x0 + w));
            let (ys, ye) = (cy.max(y0), (cy + ch).min(y0 + h));
            if xs >= xe || ys >= ye {
                continue;
            }
            let width = (xe - xs) as usize;
            for y in ys..ye {
                let start = (y - y0) as usize * w as usize + (xs - x0) as usize;
                let first = ((y - cy) as usize * cw as usize + (xs - cx) as usize) * self.stride;
                row(start..start + width, &samples, first);
            }
        }
        Ok(())
    }

    /// The texels of the rectangle `(x0, y0, w, h)`, from the chunks `units`
    /// (those that overlap it), decoded one at a time.
    fn texels<R: Read + Seek>(
        &self,
        d: &mut Decoder<R>,
        path: &Path,
        (x0, y0, w, h): (u32, u32, u32, u32),
        units: impl Iterator<Item = u32>,
    ) -> Result<TexelGrid, Error> {
        let n = w as usize * h as usize;
        let refused = || {
            crate::error::core(path)(quadtex_core::Error::AllocationFailed {
                what: format!("decoding {w}x{h} texels"),
                bytes: self.texel_bytes() * n as u64,
            })
        };
        if self.bits == 8 {
            let mut bytes: Vec<[u8; 4]> = Vec::new();
            bytes.try_reserve_exact(n).map_err(|_| refused())?;
            bytes.resize(n, [0; 4]);
            self.for_each_row(d, path, (x0, y0, w, h), units, |out, samples, first| {
                if let Samples::U8(v) = samples {
                    let input = &v[first..first + out.len() * self.stride];
                    self.row_to_srgb8(input, &mut bytes[out]);
                }
            })?;
            TexelGrid::from_srgb8(w, h, bytes).map_err(crate::error::core(path))
        } else {
            let lut = crate::image_io::decode_table();
            let mut texels: Vec<Unorm16Rgba> = Vec::new();
            texels.try_reserve_exact(n).map_err(|_| refused())?;
            texels.resize(n, Unorm16Rgba::default());
            self.for_each_row(d, path, (x0, y0, w, h), units, |out, samples, first| {
                if let Samples::U16(v) = samples {
                    let input = &v[first..first + out.len() * self.stride];
                    for (o, i) in texels[out].iter_mut().zip(input.chunks_exact(self.stride)) {
                        *o = crate::image_io::srgb16_texel(
                            lut,
                            self.straight(i, 65535).map(|v| v as u16),
                        );
                    }
                }
            })?;
            TexelGrid::new(w, h, texels).map_err(crate::error::core(path))
        }
    }
}

fn interleave<T: Copy>(plane: &[T], out: &mut [T], k: usize, stride: usize) {
    for (o, &v) in out.chunks_exact_mut(stride).zip(plane) {
        o[k] = v;
    }
}

/// The `(width, height)` of the JPEG stream of `len` bytes at `offset`,
/// from its start-of-frame marker; `None` if it has none before its scan.
fn jpeg_frame<R: Read + Seek>(
    r: &mut R,
    offset: u64,
    len: u64,
) -> std::io::Result<Option<(u32, u32)>> {
    r.seek(std::io::SeekFrom::Start(offset))?;
    let mut r = r.take(len);
    let mut byte = || -> std::io::Result<u8> {
        let mut b = [0u8; 1];
        r.read_exact(&mut b)?;
        Ok(b[0])
    };
    if (byte()?, byte()?) != (0xFF, 0xD8) {
        return Ok(None);
    }
    loop {
        if byte()? != 0xFF {
            return Ok(None);
        }
        let mut marker = byte()?;
        while marker == 0xFF {
            marker = byte()?;
        }
        match marker {
            0x01 | 0xD0..=0xD8 => continue,
            0xD9 | 0xDA => return Ok(None),
            _ => {}
        }
        let length = u16::from_be_bytes([byte()?, byte()?]);
        if matches!(marker, 0xC0..=0xC3 | 0xC5..=0xC7 | 0xC9..=0xCB | 0xCD..=0xCF) {
            let _precision = byte()?;
            let h = u16::from_be_bytes([byte()?, byte()?]);
            let w = u16::from_be_bytes([byte()?, byte()?]);
            return Ok(Some((u32::from(w), u32::from(h))));
        }
        for _ in 2..length {
            byte()?;
        }
    }
}

/// JFIF's YCbCr → RGB (full range, ITU-R BT.601 weights), rounded and clamped.
fn ycbcr_to_rgb(y: u32, cb: u32, cr: u32) -> [u32; 3] {
    let (y, cb, cr) = (y as f32, cb as f32 - 128.0, cr as f32 - 128.0);
    let q = |v: f32| (v + 0.5).clamp(0.0, 255.0) as u32;
    [
        q(y + 1.402 * cr),
        q(y - 0.344_136 * cb - 0.714_136 * cr),
        q(y + 1.772 * cb),
    ]
}

/// Decodes a whole TIFF from `reader` (the file at `path`, which names it
/// in errors), checking `limits` before allocating the texels; with its
/// georeferencing, if any.
pub(crate) fn decode<R: Read + Seek>(
    reader: R,
    path: &Path,
    limits: &Limits,
) -> Result<(TexelGrid, Option<GeoReference>), Error> {
    let mut d = open_decoder(reader, path, limits)?;
    let layout = Layout::read(&mut d, path)?;
    let (w, h) = (layout.width, layout.height);
    limits.check_dimensions(path, w, h)?;
    limits.check_memory(
        path,
        || format!("decoding {w}x{h} texels"),
        layout
            .chunk_bytes()
            .saturating_add(layout.texel_bytes() * u64::from(w) * u64::from(h)),
        KNOBS,
    )?;
    let geo = GeoReference::read(&mut d);
    let grid = layout.texels(&mut d, path, (0, 0, w, h), 0..layout.across * layout.down)?;
    Ok((grid, geo))
}

/// The dimensions of the TIFF at `path`, from its first image's tags.
pub(crate) fn dimensions(path: &Path) -> Result<(u32, u32), Error> {
    let file = File::open(path).map_err(io(path))?;
    let mut d = open_decoder(BufReader::new(file), path, &Limits::default())?;
    d.dimensions()
        .map_err(|e| decode_error(path, "ImageWidth", e))
}

/// A tiled TIFF read as a mosaic ([`Mosaic`]): square tiles of a power of
/// two texels, any image size; a tree tile read from the one or two TIFF
/// tiles it overlaps.
pub(crate) struct TiffTiles {
    path: PathBuf,
    layout: Layout,
    /// How the image is cut into tree tiles.
    mosaic: Mosaic,
    georeference: Option<GeoReference>,
    /// Open decoders not in use: a call takes one (or opens another, so
    /// calls on several threads do not wait for each other) and puts it
    /// back.
    spare: Mutex<Vec<Decoder<BufReader<File>>>>,
}

impl TiffTiles {
    /// Opens `path` and checks that its tiles form a mosaic `pack-tiles`
    /// can pack (an [`Error::Tiles`] saying why not, pointing to `quadtex
    /// pack` otherwise), and that one tile fits `limits`.
    pub(crate) fn open(path: &Path, limits: &Limits) -> Result<TiffTiles, Error> {
        limits.check_file_size(path, std::fs::metadata(path).map_err(io(path))?.len())?;
        let (d, layout) = Self::open_decoder(path, limits)?;
        let mosaic = |message: String| Error::Tiles {
            path: path.to_path_buf(),
            message: format!("{message}; `quadtex pack` reads any TIFF whose texels fit in memory"),
        };
        let (w, h) = (layout.width, layout.height);
        let (tw, th) = layout.chunk;
        if !layout.tiled {
            return Err(mosaic(format!(
                "a stripped TIFF ({w}x{h}, {} rows a strip): pack-tiles reads a tiled TIFF's tiles",
                layout.chunk.1
            )));
        }
        if tw != th || !tw.is_power_of_two() || tw < 4 {
            return Err(mosaic(format!(
                "TIFF tiles of {tw}x{th} texels: pack-tiles needs square tiles of a power of two texels, at least 4"
            )));
        }
        let tree_tiles = Mosaic::of_texture(w, h, tw)
            .map_err(|e| mosaic(format!("{w}x{h} texels in tiles of {tw}x{th}: {e}")))?;
        limits.check_dimensions(path, tw, th)?;
        Self::check_tile_memory(path, &layout, limits)?;
        let mut d = d;
        let georeference = GeoReference::read(&mut d);
        Ok(TiffTiles {
            path: path.to_path_buf(),
            layout,
            mosaic: tree_tiles,
            georeference,
            spare: Mutex::new(vec![d]),
        })
    }

    fn open_decoder(
        path: &Path,
        limits: &Limits,
    ) -> Result<(Decoder<BufReader<File>>, Layout), Error> {
        let file = File::open(path).map_err(io(path))?;
        let mut d = open_decoder(BufReader::new(file), path, limits)?;
        let layout = Layout::read(&mut d, path)?;
        Ok((d, layout))
    }

    fn check_tile_memory(path: &Path, layout: &Layout, limits: &Limits) -> Result<(), Error> {
        let (tw, th) = layout.chunk;
        limits.check_memory(
            path,
            || format!("decoding a {tw}x{th} tile"),
            layout
                .chunk_bytes()
                .saturating_add(layout.texel_bytes() * u64::from(tw) * u64::from(th)),
            KNOBS,
        )
    }

    /// How the image is cut into tree tiles.
    pub(crate) fn mosaic(&self) -> Mosaic {
        self.mosaic
    }

    pub(crate) fn georeference(&self) -> Option<&GeoReference> {
        self.georeference.as_ref()
    }

    /// The texels of the rectangle `rect = (x0, y0, w, h)` of the image (row
    /// 0 at the top), no larger than a tile: a tree tile, read from the TIFF
    /// tiles it overlaps, one at a time.
    pub(crate) fn load_rect(
        &self,
        (x0, y0, w, h): (u32, u32, u32, u32),
        limits: &Limits,
    ) -> Result<TexelGrid, Error> {
        Self::check_tile_memory(&self.path, &self.layout, limits)?;
        let taken = self.spare.lock().unwrap_or_else(|p| p.into_inner()).pop();
        let mut d = match taken {
            Some(d) => d,
            None => {
                let (d, layout) = Self::open_decoder(&self.path, limits)?;
                if layout != self.layout {
                    return Err(Error::Tiles {
                        path: self.path.clone(),
                        message: "the file changed since it was opened".into(),
                    });
                }
                d
            }
        };
        let (tw, th) = self.layout.chunk;
        let across = self.layout.across;
        let units = (y0 / th..(y0 + h).div_ceil(th))
            .flat_map(|r| (x0 / tw..(x0 + w).div_ceil(tw)).map(move |c| r * across + c));
        let grid = self
            .layout
            .texels(&mut d, &self.path, (x0, y0, w, h), units)?;
        self.spare.lock().unwrap_or_else(|p| p.into_inner()).push(d);
        Ok(grid)
    }
}

impl fmt::Debug for TiffTiles {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("TiffTiles")
            .field("path", &self.path)
            .field("layout", &self.layout)
            .field("georeference", &self.georeference)
            .finish_non_exhaustive()
    }
}

/// A clone opens its own decoders when it needs them.
impl Clone for TiffTiles {
    fn clone(&self) -> TiffTiles {
        TiffTiles {
            path: self.path.clone(),
            layout: self.layout.clone(),
            mosaic: self.mosaic,
            georeference: self.georeference.clone(),
            spare: Mutex::new(Vec::new()),
        }
    }
}

/// The same file read the same way (the georeferencing follows from them).
impl PartialEq for TiffTiles {
    fn eq(&self, other: &TiffTiles) -> bool {
        self.path == other.path && self.layout == other.layout
    }
}

impl Eq for TiffTiles {}

#[cfg(test)]
#[path = "../tests/support/tiff_writer.rs"]
pub(crate) mod tiff_writer;

#[cfg(test)]
mod tests {
    use super::tiff_writer::{Spec, utm33_keys};
    use super::*;
    use crate::{load_texels, load_texels_from_bytes, load_texels_with_georeference};
    use quadtex_core::{BuildOptions, QuadTree};

    fn temp(name: &str) -> PathBuf {
        let d = std::env::temp_dir().join(format!("quadtex-tiff-{}", std::process::id()));
        std::fs::create_dir_all(&d).unwrap();
        d.join(name)
    }

    /// Deterministic samples in `[0, max]`, with flat patches (so trees
    /// have uniform squares as well as texel blocks).
    fn samples(n: usize, max: u32, seed: u32) -> Vec<u16> {
        let mut x = seed.wrapping_mul(2_654_435_761).wrapping_add(12345);
        (0..n)
            .map(|i| {
                x ^= x << 13;
                x ^= x >> 17;
                x ^= x << 5;
                if (i / 97) % 3 == 0 {
                    (max / 3) as u16
                } else {
                    (x % (max + 1)) as u16
                }
            })
            .collect()
    }

    /// The same samples as a PNG (grey, grey+alpha, RGB or RGBA; 8 or 16
    /// bits).
    fn png(path: &Path, w: u32, h: u32, spp: u16, bits: u16, s: &[u16]) {
        use image::DynamicImage as D;
        let v8 = || s.iter().map(|&v| v as u8).collect::<Vec<u8>>();
        let v16 = || s.to_vec();
        let image = match (spp, bits) {
            (1, 8) => D::ImageLuma8(image::ImageBuffer::from_raw(w, h, v8()).unwrap()),
            (2, 8) => D::ImageLumaA8(image::ImageBuffer::from_raw(w, h, v8()).unwrap()),
            (3, 8) => D::ImageRgb8(image::ImageBuffer::from_raw(w, h, v8()).unwrap()),
            (4, 8) => D::ImageRgba8(image::ImageBuffer::from_raw(w, h, v8()).unwrap()),
            (1, 16) => D::ImageLuma16(image::ImageBuffer::from_raw(w, h, v16()).unwrap()),
            (2, 16) => D::ImageLumaA16(image::ImageBuffer::from_raw(w, h, v16()).unwrap()),
            (3, 16) => D::ImageRgb16(image::ImageBuffer::from_raw(w, h, v16()).unwrap()),
            (4, 16) => D::ImageRgba16(image::ImageBuffer::from_raw(w, h, v16()).unwrap()),
            _ => unreachable!(),
        };
        image.save(path).unwrap();
    }

    fn spec(w: u32, h: u32, spp: u16, bits: u16, seed: u32) -> Spec {
        let max = if bits == 8 { 255 } else { 65535 };
        Spec {
            bits,
            samples_per_pixel: spp,
            photometric: if spp < 3 { 1 } else { 2 },
            extra_samples: if matches!(spp, 2 | 4) {
                vec![2]
            } else {
                Vec::new()
            },
            ..Spec::rgb8(
                w,
                h,
                samples((w * h) as usize * usize::from(spp), max, seed),
            )
        }
    }

    /// `spec` written as a TIFF and its samples as a PNG decode to the
    /// same texels, and pack to the same tree.
    fn same_as_png(name: &str, s: &Spec) {
        let tif = temp(&format!("{name}.tif"));
        std::fs::write(&tif, s.write()).unwrap();
        let png_path = temp(&format!("{name}.png"));
        png(
            &png_path,
            s.width,
            s.height,
            s.samples_per_pixel,
            s.bits,
            &s.samples,
        );
        let limits = Limits::default();
        let a = load_texels(&tif, &limits).unwrap();
        let b = load_texels(&png_path, &limits).unwrap();
        assert_eq!(a, b, "{name}");
        let options = BuildOptions::default();
        let (ta, _) = QuadTree::from_texels(&a, &options).unwrap();
        let (tb, _) = QuadTree::from_texels(&b, &options).unwrap();
        assert!(ta == tb, "{name}: trees differ");
        // From bytes as from the file.
        let bytes = std::fs::read(&tif).unwrap();
        assert_eq!(load_texels_from_bytes(&bytes, &tif, &limits).unwrap(), a);
        std::fs::remove_file(&tif).unwrap();
        std::fs::remove_file(&png_path).unwrap();
    }

    #[test]
    fn every_layout_decodes_to_the_png_texels() {
        // 8-bit RGB, stripped (5 rows a strip, the last one short), LZW.
        same_as_png(
            "rgb8-strips-lzw",
            &Spec {
                rows_per_strip: 5,
                compression: 5,
                ..spec(23, 17, 3, 8, 1)
            },
        );
        // 16-bit grey, Deflate.
        same_as_png(
            "grey16-deflate",
            &Spec {
                compression: 8,
                ..spec(16, 16, 1, 16, 2)
            },
        );
        // RGBA (straight alpha), 8-bit and 16-bit; grey + alpha.
        same_as_png("rgba8", &spec(20, 12, 4, 8, 3));
        same_as_png(
            "rgba16-lzw",
            &Spec {
                compression: 5,
                ..spec(9, 14, 4, 16, 4)
            },
        );
        same_as_png("grey-alpha8", &spec(8, 8, 2, 8, 5));
        same_as_png("grey8", &spec(31, 3, 1, 8, 6));
        // BigTIFF, tiled with partial edge tiles, Deflate.
        same_as_png(
            "bigtiff-tiled-edges",
            &Spec {
                big: true,
                tile: Some((16, 16)),
                compression: 8,
                ..spec(40, 24, 3, 8, 7)
            },
        );
        // Planar (one plane a sample), tiled, RGBA 16-bit.
        same_as_png(
            "planar-rgba16-tiled",
            &Spec {
                planar: true,
                tile: Some((16, 16)),
                ..spec(32, 32, 4, 16, 8)
            },
        );
        // Planar strips.
        same_as_png(
            "planar-rgb8-strips",
            &Spec {
                planar: true,
                rows_per_strip: 3,
                compression: 5,
                ..spec(10, 10, 3, 8, 9)
            },
        );
    }

    #[test]
    fn associated_alpha_is_divided_out_and_white_is_zero_inverted() {
        // Premultiplied 8-bit RGBA: (100, 50, 0) at alpha 128 is straight
        // (199, 100, 0); alpha 0 leaves colour 0.
        let s = Spec {
            samples_per_pixel: 4,
            extra_samples: vec![1],
            ..Spec::rgb8(2, 1, vec![100, 50, 0, 128, 7, 7, 7, 0])
        };
        let g = load_texels_from_bytes(&s.write(), Path::new("a.tif"), &Limits::default()).unwrap();
        let straight = TexelGrid::from_srgb8(2, 1, vec![[199, 100, 0, 128], [0, 0, 0, 0]]).unwrap();
        assert_eq!(g, straight);
        // WhiteIsZero grey: 0 is white.
        let s = Spec {
            samples_per_pixel: 1,
            photometric: 0,
            ..Spec::rgb8(2, 1, vec![0, 255])
        };
        let g = load_texels_from_bytes(&s.write(), Path::new("w.tif"), &Limits::default()).unwrap();
        let expected =
            TexelGrid::from_srgb8(2, 1, vec![[255, 255, 255, 255], [0, 0, 0, 255]]).unwrap();
        assert_eq!(g, expected);
    }

    /// JPEG-compressed YCbCr written by libtiff (through Pillow), against
    /// libjpeg's own RGB decode of it (`ycbcr-jpeg.png`): within a few
    /// 8-bit steps (the two JPEG decoders round differently).
    #[test]
    fn libtiff_jpeg_ycbcr_decodes_as_libjpeg_does() {
        let data = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data");
        let limits = Limits::default();
        let a = load_texels(&data.join("ycbcr-jpeg.tif"), &limits).unwrap();
        let b = load_texels(&data.join("ycbcr-jpeg.png"), &limits).unwrap();
        assert_eq!((a.width(), a.height()), (32, 32));
        let srgb = |t: Unorm16Rgba| {
            let c = t.to_rgba();
            [c.r, c.g, c.b].map(|v| i32::from(crate::linear_to_srgb8(v)))
        };
        let worst = a
            .texels()
            .iter()
            .zip(b.texels())
            .flat_map(|(&x, &y)| {
                let (x, y) = (srgb(x), srgb(y));
                (0..3).map(move |k| (x[k] - y[k]).abs())
            })
            .max()
            .unwrap();
        assert!(worst <= 3, "{worst}");
        // A frame header claiming 16000² texels in the 32² strip is refused
        // before the JPEG decoder allocates for it.
        let mut bomb = std::fs::read(data.join("ycbcr-jpeg.tif")).unwrap();
        let sof = bomb.windows(2).position(|w| w == [0xFF, 0xC0]).unwrap();
        bomb[sof + 5..sof + 9].copy_from_slice(&[0x3E, 0x80, 0x3E, 0x80]);
        refused(
            "jpeg-bomb.tif",
            &bomb,
            &limits,
            &["TIFF strip 0: its JPEG frame is 16000x16000 texels, larger than the 32x32 chunk"],
        );
    }

    #[test]
    fn ycbcr_grey_stays_grey() {
        for v in [0, 1, 77, 128, 254, 255] {
            assert_eq!(ycbcr_to_rgb(v, 128, 128), [v; 3]);
        }
        // Pure red through JFIF's forward transform comes back red.
        assert_eq!(ycbcr_to_rgb(76, 85, 255), [254, 0, 0]);
    }

    /// `bytes` as `name` must be refused with an error naming the file and
    /// every needle, without a panic.
    fn refused(name: &str, bytes: &[u8], limits: &Limits, needles: &[&str]) {
        let path = temp(name);
        std::fs::write(&path, bytes).unwrap();
        let e = load_texels(&path, limits).unwrap_err().to_string();
        assert!(e.contains(name), "{e}");
        for n in needles {
            assert!(e.contains(n), "`{n}` not in: {e}");
        }
        let from_bytes = load_texels_from_bytes(bytes, &path, limits)
            .unwrap_err()
            .to_string();
        assert_eq!(from_bytes, e);
        std::fs::remove_file(&path).unwrap();
    }

    #[test]
    fn bad_tiffs_are_errors_naming_file_and_field() {
        let limits = Limits::default();
        let valid = spec(16, 16, 3, 8, 1).write();
        refused(
            "truncated.tif",
            &valid[..valid.len() / 2],
            &limits,
            &["TIFF", "truncated"],
        );
        refused("magic-only.tif", b"II*\0", &limits, &["TIFF header"]);
        let mut bad_ifd = valid.clone();
        bad_ifd[4..8].copy_from_slice(&0x7fff_fff0u32.to_le_bytes());
        refused("bad-ifd.tif", &bad_ifd, &limits, &["TIFF header"]);
        let float = Spec {
            bits: 32,
            sample_format: Some(3),
            ..spec(4, 4, 3, 16, 1)
        };
        refused(
            "float.tif",
            &float.write(),
            &limits,
            &["TIFF SampleFormat: floating-point samples are not supported"],
        );
        let signed = Spec {
            sample_format: Some(2),
            ..spec(4, 4, 1, 16, 1)
        };
        refused("signed.tif", &signed.write(), &limits, &["signed integer"]);
        let bilevel = Spec {
            bits: 1,
            samples_per_pixel: 1,
            photometric: 1,
            ..Spec::rgb8(8, 1, vec![1; 8])
        };
        refused(
            "bilevel.tif",
            &bilevel.write(),
            &limits,
            &["TIFF BitsPerSample: 1-bit samples (bilevel) are not supported"],
        );
        let palette = Spec {
            samples_per_pixel: 1,
            photometric: 3,
            ..spec(4, 4, 1, 8, 1)
        };
        refused(
            "palette.tif",
            &palette.write(),
            &limits,
            &["palette colour is not supported"],
        );
        let cmyk = Spec {
            samples_per_pixel: 4,
            photometric: 5,
            ..spec(4, 4, 4, 8, 1)
        };
        refused(
            "cmyk.tif",
            &cmyk.write(),
            &limits,
            &["CMYK is not supported"],
        );
        let fax = Spec {
            compression: 4,
            ..spec(4, 4, 1, 8, 1)
        };
        refused(
            "fax.tif",
            &fax.write(),
            &limits,
            &["TIFF Compression: CCITT Group 4 fax is not supported"],
        );
        // A lying header: 40000 texels wide, checked before decoding.
        let wide = Spec {
            declared_size: Some((40000, 16)),
            ..spec(16, 16, 3, 8, 1)
        };
        refused("wide.tif", &wide.write(), &limits, &["max_dimension"]);
        // The memory budget, before decoding.
        let tight = Limits {
            max_memory: 1024,
            ..Limits::default()
        };
        refused(
            "budget.tif",
            &valid,
            &tight,
            &["decoding 16x16 texels needs an estimated", "memory budget"],
        );
        // A strip's offset beyond the end of the file.
        let mut far = valid.clone();
        let ifd = u32::from_le_bytes(far[4..8].try_into().unwrap()) as usize;
        let entries = u16::from_le_bytes(far[ifd..ifd + 2].try_into().unwrap()) as usize;
        for e in 0..entries {
            let at = ifd + 2 + 12 * e;
            if u16::from_le_bytes(far[at..at + 2].try_into().unwrap()) == 273 {
                far[at + 8..at + 12].copy_from_slice(&0x00ff_0000u32.to_le_bytes());
            }
        }
        refused("far.tif", &far, &limits, &["TIFF strip 0"]);
    }

    /// Every prefix and many single-byte corruptions of valid TIFFs (tiled
    /// LZW RGBA, planar Deflate BigTIFF, libtiff's JPEG YCbCr) are decoded
    /// or refused naming the file, never a panic.
    #[test]
    fn damaged_tiffs_never_panic() {
        let data = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data");
        let files = [
            Spec {
                tile: Some((16, 16)),
                compression: 5,
                ..spec(40, 20, 4, 8, 11)
            }
            .write(),
            Spec {
                big: true,
                planar: true,
                compression: 8,
                rows_per_strip: 4,
                ..spec(12, 10, 3, 16, 12)
            }
            .write(),
            std::fs::read(data.join("ycbcr-jpeg.tif")).unwrap(),
        ];
        let path = Path::new("damaged.tif");
        let limits = Limits::default();
        let mut x = 99u32;
        for valid in &files {
            for len in 0..valid.len() {
                let _ = load_texels_from_bytes(&valid[..len], path, &limits);
            }
            for _ in 0..2000 {
                x ^= x << 13;
                x ^= x >> 17;
                x ^= x << 5;
                let mut bytes = valid.clone();
                let at = x as usize % bytes.len();
                bytes[at] = (x >> 8) as u8;
                if let Err(e) = load_texels_from_bytes(&bytes, path, &limits) {
                    assert!(e.to_string().starts_with("damaged.tif: "), "{e}");
                }
            }
        }
    }

    #[test]
    fn georeferencing_is_kept_as_metadata() {
        let s = Spec {
            geo: Some((
                [10.0, 10.0, 0.0],
                [0.0, 0.0, 0.0, 500_000.0, 4_650_000.0, 0.0],
                utm33_keys(),
            )),
            ..spec(8, 8, 3, 8, 1)
        };
        let path = temp("geo.tif");
        std::fs::write(&path, s.write()).unwrap();
        let (_, geo) = load_texels_with_georeference(&path, &Limits::default()).unwrap();
        let geo = geo.unwrap();
        assert_eq!(geo.pixel_scale, Some([10.0, 10.0, 0.0]));
        assert_eq!(
            geo.tiepoints,
            vec![[0.0, 0.0, 0.0, 500_000.0, 4_650_000.0, 0.0]]
        );
        assert_eq!(geo.epsg(), Some(32633));
        assert_eq!(geo.geo_key(1025), Some(1));
        assert!(geo.ignored.is_empty());
        assert_eq!(
            geo.to_string(),
            "EPSG:32633, tiepoint (0, 0, 0) -> (500000, 4650000, 0), pixel scale (10, 10, 0)"
        );
        // Without the tags: none, and not required.
        std::fs::write(&path, spec(8, 8, 3, 8, 1).write()).unwrap();
        let (_, geo) = load_texels_with_georeference(&path, &Limits::default()).unwrap();
        assert!(geo.is_none());
        // A malformed key directory is named, not fatal.
        let s = Spec {
            geo: Some(([1.0, 1.0, 0.0], [0.0; 6], vec![2, 1, 0, 9])),
            ..spec(8, 8, 3, 8, 1)
        };
        std::fs::write(&path, s.write()).unwrap();
        let (_, geo) = load_texels_with_georeference(&path, &Limits::default()).unwrap();
        let geo = geo.unwrap();
        assert_eq!(geo.ignored, vec!["GeoKeyDirectoryTag"]);
        assert!(
            geo.to_string()
                .ends_with("malformed GeoKeyDirectoryTag ignored"),
            "{geo}"
        );
        std::fs::remove_file(&path).unwrap();
    }
}
