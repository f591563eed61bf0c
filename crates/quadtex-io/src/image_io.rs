//! Raster input (PNG, JPEG, OpenEXR, Radiance HDR, and TIFF through
//! `tiff_io` → linear premultiplied texels) and rendered-image output (PNG
//! in sRGB 8-bit, OpenEXR in linear 32-bit float).
//!
//! Input colour is taken to be sRGB (gamma chunks and ICC profiles are
//! ignored) with straight alpha; it is decoded to linear light and then
//! premultiplied, so later averaging is physically meaningful.

use std::io::Write;
use std::path::Path;
use std::sync::OnceLock;

use image::{DynamicImage, ImageReader};
use quadtex_core::{Rgba, TexelGrid, Unorm16Rgba};

use crate::atomic::{Target, put, resolve, write_atomically};
use crate::error::{Error, io};
use crate::limits::Limits;
use crate::tiff_io::GeoReference;

/// A rendered image: linear light, premultiplied alpha, row 0 at the top.
/// The default is the empty 0 × 0 image (a buffer for
/// `quadtex_render::render_into` to size).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct LinearImage {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// `width × height` pixels, row-major from the top.
    pub pixels: Vec<Rgba>,
}

impl LinearImage {
    /// The `width × height` image whose pixel in column `x` of row `y`
    /// (from the top) is `pixel(x, y)`, called row by row.
    pub fn from_fn(
        width: u32,
        height: u32,
        mut pixel: impl FnMut(u32, u32) -> Rgba,
    ) -> LinearImage {
        let pixels = (0..height)
            .flat_map(|y| (0..width).map(move |x| (x, y)))
            .map(|(x, y)| pixel(x, y))
            .collect();
        LinearImage {
            width,
            height,
            pixels,
        }
    }
}

use quadtex_core::{srgb_decode_f32, srgb_encode};

/// The 8-bit sRGB code of linear `v` in `[0, 1]`: `⌊255·srgb(v) + ½⌋`, the
/// transfer function evaluated exactly (in `f64`, where [`srgb_encode_f32`]'s
/// `f32` power may round a value at a code's edge the other way); 0 for
/// NaN and below 0, 255 above 1. A table lookup: every pixel of every
/// written PNG takes three.
pub fn linear_to_srgb8(v: f32) -> u8 {
    if v.is_nan() || v <= 0.0 {
        return 0;
    }
    if v >= 1.0 {
        return 255;
    }
    let table = srgb8_encode_table();
    // `v · 2¹²` is exact (a power of two), so its floor is the bucket.
    let mut code = usize::from(table.bucket_code[(v * SRGB8_BUCKETS as f32) as usize]);
    let x = f64::from(v);
    while code < 255 && x >= table.threshold[code + 1] {
        code += 1;
    }
    code as u8
}

/// The bytes a PNG written by [`save_image`] stores for linear,
/// premultiplied `pixels`: four a pixel (R, G, B, A), sRGB-encoded with
/// straight alpha. Each colour channel is divided by alpha (a pixel whose
/// alpha is not above 0 gets colour 0) and encoded by [`linear_to_srgb8`];
/// alpha is `⌊255·clamp(a, 0, 1) + ½⌋` (0 for NaN).
pub fn srgb8_from_linear(pixels: &[Rgba]) -> Vec<u8> {
    let mut bytes = Vec::with_capacity(4 * pixels.len());
    for p in pixels {
        let inv = if p.a > 0.0 { 1.0 / p.a } else { 0.0 };
        let enc = |c: f32| linear_to_srgb8(c * inv);
        bytes.extend([
            enc(p.r),
            enc(p.g),
            enc(p.b),
            (p.a.clamp(0.0, 1.0) * 255.0 + 0.5) as u8,
        ]);
    }
    bytes
}

/// Buckets of `[0, 1)` in [`linear_to_srgb8`]'s table: fine enough that a
/// bucket spans at most about one code (the curve's steepest slope is
/// 255 · 12.92 codes per unit).
const SRGB8_BUCKETS: usize = 4096;

struct Srgb8Table {
    /// `threshold[k]`: the least linear value whose code is at least `k`.
    threshold: [f64; 256],
    /// The code of each bucket's lower end.
    bucket_code: Vec<u8>,
}

fn srgb8_encode_table() -> &'static Srgb8Table {
    static TABLE: OnceLock<Srgb8Table> = OnceLock::new();
    TABLE.get_or_init(|| {
        let code = |x: f64| (255.0 * srgb_encode(x) + 0.5).floor();
        let mut threshold = [0.0; 256];
        for (k, t) in threshold.iter_mut().enumerate().skip(1) {
            // Bisection on the (monotone) encoding to the last f64 bit.
            let (mut lo, mut hi) = (0.0f64, 1.0f64);
            while hi - lo > f64::EPSILON * hi {
                let mid = 0.5 * (lo + hi);
                if code(mid) >= k as f64 {
                    hi = mid;
                } else {
                    lo = mid;
                }
            }
            *t = hi;
        }
        let bucket_code = (0..SRGB8_BUCKETS)
            .map(|b| {
                let x = b as f64 / SRGB8_BUCKETS as f64;
                threshold.iter().skip(1).filter(|&&t| t <= x).count() as u8
            })
            .collect();
        Srgb8Table {
            threshold,
            bucket_code,
        }
    })
}

/// sRGB-encoded 16-bit value → linear, for every value (8-bit input is
/// widened by ×257 first, which maps it onto the same curve exactly).
pub(crate) fn decode_table() -> &'static [f32] {
    static TABLE: OnceLock<Vec<f32>> = OnceLock::new();
    TABLE.get_or_init(|| {
        (0..=u16::MAX)
            .map(|v| srgb_decode_f32(f32::from(v) / 65535.0))
            .collect()
    })
}

/// Straight-alpha sRGB-encoded 16-bit RGBA → the tree's linear,
/// premultiplied texel (`lut` is [`decode_table`]).
#[inline]
pub(crate) fn srgb16_texel(lut: &[f32], p: [u16; 4]) -> Unorm16Rgba {
    let a = f32::from(p[3]) / 65535.0;
    Rgba::new(
        lut[usize::from(p[0])] * a,
        lut[usize::from(p[1])] * a,
        lut[usize::from(p[2])] * a,
        a,
    )
    .to_unorm16()
}

/// Decodes a PNG, JPEG or TIFF (8- or 16-bit; grey, grey+alpha, RGB, RGBA),
/// or an OpenEXR or Radiance HDR image, into linear, premultiplied texels;
/// `limits` (often `&Limits::default()`) are checked before decoding. TIFF
/// and BigTIFF (stripped or tiled) are recognised by their first bytes,
/// whatever the name; see [`load_texels_with_georeference`] for a
/// GeoTIFF's georeferencing.
pub fn load_texels(path: &Path, limits: &Limits) -> Result<TexelGrid, Error> {
    load_texels_with_georeference(path, limits).map(|(grid, _)| grid)
}

/// As [`load_texels`], with the georeferencing of a GeoTIFF that has it
/// (GeoKeys, tiepoints, pixel scale, transformation); `None` for other
/// files and for TIFFs without it.
pub fn load_texels_with_georeference(
    path: &Path,
    limits: &Limits,
) -> Result<(TexelGrid, Option<GeoReference>), Error> {
    limits.check_file_size(path, std::fs::metadata(path).map_err(io(path))?.len())?;
    if crate::tiff_io::file_is_tiff(path) {
        let file = std::fs::File::open(path).map_err(io(path))?;
        return crate::tiff_io::decode(std::io::BufReader::new(file), path, limits);
    }
    let open = || {
        ImageReader::open(path)
            .map_err(io(path))?
            .with_guessed_format()
            .map_err(io(path))
    };
    decode_texels(open, path, limits).map(|grid| (grid, None))
}

/// As [`load_texels`] for a file already in memory; `path`
/// only names it in errors.
pub fn load_texels_from_bytes(
    bytes: &[u8],
    path: &Path,
    limits: &Limits,
) -> Result<TexelGrid, Error> {
    limits.check_file_size(path, bytes.len() as u64)?;
    if crate::tiff_io::is_tiff(bytes) {
        return crate::tiff_io::decode(std::io::Cursor::new(bytes), path, limits)
            .map(|(grid, _)| grid);
    }
    let open = || {
        ImageReader::new(std::io::Cursor::new(bytes))
            .with_guessed_format()
            .map_err(io(path))
    };
    decode_texels(open, path, limits)
}

/// Reads the dimensions from one reader `open` gives, checks them against
/// `limits`, then decodes from a second.
fn decode_texels<R: std::io::BufRead + std::io::Seek>(
    open: impl Fn() -> Result<ImageReader<R>, Error>,
    path: &Path,
    limits: &Limits,
) -> Result<TexelGrid, Error> {
    let image_err = |e: image::ImageError| Error::Image {
        path: path.to_path_buf(),
        message: e.to_string(),
    };
    let decoder = open()?.into_decoder().map_err(image_err)?;
    let (w, h) = image::ImageDecoder::dimensions(&decoder);
    let decoded_bytes = image::ImageDecoder::total_bytes(&decoder);
    drop(decoder);
    limits.check_dimensions(path, w, h)?;
    let mut reader = open()?;
    // The decoder's buffer and the texels (8 bytes each) live together.
    let texel_bytes = 8 * u64::from(w) * u64::from(h);
    limits.check_memory(
        path,
        || format!("decoding {w}x{h} texels"),
        decoded_bytes.saturating_add(texel_bytes),
        "use a smaller image, or raise --memory-limit",
    )?;
    let mut il = image::Limits::default();
    il.max_image_width = Some(limits.max_dimension);
    il.max_image_height = Some(limits.max_dimension);
    il.max_alloc = Some(
        limits
            .max_file_bytes
            .max(1 << 30)
            .saturating_mul(8)
            .min(limits.max_memory),
    );
    reader.limits(il);
    let decoded = reader.decode().map_err(image_err)?;
    texels_from_image(decoded).map_err(crate::error::core(path))
}

fn texels_from_image(image: DynamicImage) -> Result<TexelGrid, quadtex_core::Error> {
    let lut = decode_table();
    let (w, h) = (image.width(), image.height());
    // 8-bit images keep their bytes: the packer stores them as they are in
    // texel blocks (`quadtex_core::texel_block`).
    if matches!(
        image,
        DynamicImage::ImageLuma8(_)
            | DynamicImage::ImageLumaA8(_)
            | DynamicImage::ImageRgb8(_)
            | DynamicImage::ImageRgba8(_)
    ) {
        let mut bytes = Vec::new();
        bytes
            .try_reserve_exact(w as usize * h as usize)
            .map_err(|_| quadtex_core::Error::AllocationFailed {
                what: format!("decoding {w}x{h} 8-bit texels"),
                bytes: 4 * u64::from(w) * u64::from(h),
            })?;
        match image {
            DynamicImage::ImageRgb8(buf) => {
                bytes.extend(buf.pixels().map(|p| [p[0], p[1], p[2], 255]));
            }
            DynamicImage::ImageRgba8(buf) => bytes.extend(buf.pixels().map(|p| p.0)),
            other => bytes.extend(other.to_rgba8().pixels().map(|p| p.0)),
        }
        return TexelGrid::from_srgb8(w, h, bytes);
    }
    let mut texels = Vec::new();
    texels
        .try_reserve_exact(w as usize * h as usize)
        .map_err(|_| quadtex_core::Error::AllocationFailed {
            what: format!("decoding {w}x{h} texels"),
            bytes: 8 * u64::from(w) * u64::from(h),
        })?;
    let to_texel = |p: [u16; 4]| srgb16_texel(lut, p);
    match image {
        // Float images (OpenEXR, Radiance) are HDR: linear, premultiplied
        // already, kept unclamped; NaN or infinite texels are refused.
        DynamicImage::ImageRgba32F(buf) => {
            let texels: Vec<[f32; 4]> = buf.pixels().map(|p| p.0).collect();
            return TexelGrid::from_linear_f32(w, h, &texels);
        }
        DynamicImage::ImageRgb32F(buf) => {
            let texels: Vec<[f32; 4]> = buf.pixels().map(|p| [p[0], p[1], p[2], 1.0]).collect();
            return TexelGrid::from_linear_f32(w, h, &texels);
        }
        other => texels.extend(other.to_rgba16().pixels().map(|p| to_texel(p.0))),
    }
    TexelGrid::new(w, h, texels)
}

/// An image file's width and height from its header (TIFF included).
pub(crate) fn image_dimensions(path: &Path) -> Result<(u32, u32), Error> {
    if crate::tiff_io::file_is_tiff(path) {
        return crate::tiff_io::dimensions(path);
    }
    image::image_dimensions(path).map_err(image_error(path))
}

/// Reads an image as a linear, premultiplied [`LinearImage`] without
/// quantising: OpenEXR as stored, 8- and 16-bit formats decoded from sRGB.
pub fn load_linear_image(path: &Path) -> Result<LinearImage, Error> {
    if crate::tiff_io::file_is_tiff(path) {
        let grid = load_texels(path, &Limits::default())?;
        return Ok(LinearImage {
            width: grid.width(),
            height: grid.height(),
            pixels: grid.texels().iter().map(|t| t.to_rgba()).collect(),
        });
    }
    let image_err = |e: image::ImageError| Error::Image {
        path: path.to_path_buf(),
        message: e.to_string(),
    };
    let decoded = ImageReader::open(path)
        .map_err(io(path))?
        .with_guessed_format()
        .map_err(io(path))?
        .decode()
        .map_err(image_err)?;
    let (width, height) = (decoded.width(), decoded.height());
    let pixels = match decoded {
        DynamicImage::ImageRgba32F(buf) => buf
            .pixels()
            .map(|p| Rgba::new(p[0], p[1], p[2], p[3]))
            .collect(),
        DynamicImage::ImageRgb32F(buf) => buf
            .pixels()
            .map(|p| Rgba::opaque(p[0], p[1], p[2]))
            .collect(),
        other => texels_from_image(other)
            .map_err(|source| Error::Core {
                path: path.into(),
                source,
            })?
            .texels()
            .iter()
            .map(|t| t.to_rgba())
            .collect(),
    };
    Ok(LinearImage {
        width,
        height,
        pixels,
    })
}

/// The file format of a rendered image.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum ImageFormat {
    /// PNG: sRGB-encoded, straight alpha, 8 bits per channel.
    Png,
    /// OpenEXR: linear, premultiplied, 32-bit float RGBA.
    Exr,
}

impl ImageFormat {
    /// The format a file name's extension selects: `.png` or `.exr` (any case).
    pub fn from_path(path: &Path) -> Option<ImageFormat> {
        let ext = path.extension()?.to_str()?.to_ascii_lowercase();
        match ext.as_str() {
            "png" => Some(ImageFormat::Png),
            "exr" => Some(ImageFormat::Exr),
            _ => None,
        }
    }

    /// The format's usual extension, without the dot.
    pub fn extension(self) -> &'static str {
        match self {
            ImageFormat::Png => "png",
            ImageFormat::Exr => "exr",
        }
    }

    fn encoder_format(self) -> image::ImageFormat {
        match self {
            ImageFormat::Png => image::ImageFormat::Png,
            ImageFormat::Exr => image::ImageFormat::OpenExr,
        }
    }
}

/// Writes a rendered image atomically; the format follows the extension:
/// `.png` (sRGB-encoded, straight alpha, 8 bits per channel) or `.exr`
/// (linear, premultiplied, 32-bit float RGBA).
///
/// `path` is handled as [`write_atomically`] describes: a symbolic link is
/// followed and stays a link; a device, FIFO or socket is written in place.
pub fn save_image(path: &Path, image: &LinearImage) -> Result<(), Error> {
    let format =
        ImageFormat::from_path(path).ok_or_else(|| Error::UnsupportedExtension(path.into()))?;
    save_image_as(path, image, format)
}

/// As [`save_image`], in `format` whatever the extension (for a device or
/// FIFO, say, whose name has none).
pub fn save_image_as(path: &Path, image: &LinearImage, format: ImageFormat) -> Result<(), Error> {
    let dynamic = to_dynamic(path, image, format)?;
    if matches!(resolve(path), Ok(Target::Regular(_))) {
        // A seekable temporary file: the encoder streams into it.
        write_atomically(path, |w| {
            dynamic
                .write_to(w, format.encoder_format())
                .map_err(image_error(path))
        })
    } else {
        // Encoded whole first: a pipe cannot seek (which the EXR encoder
        // needs), and an encoder error then writes nothing.
        let bytes = encode(path, &dynamic, format)?;
        write_atomically(path, |w| put(w, path, &bytes))
    }
}

/// Encodes `image` as `format` and writes it to a stream (standard output,
/// a pipe, a socket…), then flushes it; `name` names the stream in errors
/// (for example `standard output`). The image is encoded in memory first,
/// so an encoder error writes nothing, and EXR (whose encoder seeks) works
/// on streams that cannot seek.
pub fn write_image(
    w: &mut dyn Write,
    name: &Path,
    image: &LinearImage,
    format: ImageFormat,
) -> Result<(), Error> {
    let bytes = encode(name, &to_dynamic(name, image, format)?, format)?;
    put(w, name, &bytes)?;
    w.flush().map_err(io(name))
}

fn image_error(path: &Path) -> impl Fn(image::ImageError) -> Error + '_ {
    move |e| Error::Image {
        path: path.to_path_buf(),
        message: e.to_string(),
    }
}

/// The whole encoded file in memory.
fn encode(path: &Path, dynamic: &DynamicImage, format: ImageFormat) -> Result<Vec<u8>, Error> {
    let mut bytes = std::io::Cursor::new(Vec::new());
    dynamic
        .write_to(&mut bytes, format.encoder_format())
        .map_err(image_error(path))?;
    Ok(bytes.into_inner())
}

/// `image` in the encoder's pixel layout for `format`.
fn to_dynamic(
    path: &Path,
    image: &LinearImage,
    format: ImageFormat,
) -> Result<DynamicImage, Error> {
    let n = image.width as usize * image.height as usize;
    let wrong_size = || Error::Image {
        path: path.into(),
        message: format!(
            "{} pixels for a {}x{} image",
            image.pixels.len(),
            image.width,
            image.height
        ),
    };
    if image.pixels.len() != n {
        return Err(wrong_size());
    }
    let dynamic = match format {
        ImageFormat::Png => {
            image::RgbaImage::from_raw(image.width, image.height, srgb8_from_linear(&image.pixels))
                .map(DynamicImage::ImageRgba8)
        }
        ImageFormat::Exr => {
            let floats = image.pixels.iter().flat_map(|p| p.to_array()).collect();
            image::Rgba32FImage::from_raw(image.width, image.height, floats)
                .map(DynamicImage::ImageRgba32F)
        }
    };
    dynamic.ok_or_else(wrong_size)
}

#[cfg(test)]
mod tests {
    use super::*;
    use quadtex_core::srgb_encode_f32;

    fn temp(name: &str) -> std::path::PathBuf {
        std::env::temp_dir().join(format!("quadtex-img-{}-{name}", std::process::id()))
    }

    #[test]
    fn reads_jpeg_and_16_bit_png_files() {
        // 16-bit grey PNG: exact values survive.
        let p = temp("g16.png");
        let buf: image::ImageBuffer<image::Luma<u16>, Vec<u16>> =
            image::ImageBuffer::from_fn(4, 2, |x, _| image::Luma([if x < 2 { 0 } else { 65535 }]));
        buf.save(&p).unwrap();
        let g = load_texels(&p, &Limits::default()).unwrap();
        assert_eq!((g.width(), g.height()), (4, 2));
        assert_eq!(g.texel(0, 0).0, [0, 0, 0, 65535]);
        assert_eq!(g.texel(3, 1).0, [65535; 4]);
        std::fs::remove_file(&p).unwrap();
        // JPEG (lossy): a flat mid-grey decodes near sRGB 128, i.e. linear ~0.216.
        let p = temp("grey.jpg");
        image::RgbImage::from_pixel(16, 16, image::Rgb([128, 128, 128]))
            .save(&p)
            .unwrap();
        let t = load_texels(&p, &Limits::default())
            .unwrap()
            .texel(5, 5)
            .to_rgba();
        assert!((t.g - 0.2158).abs() < 0.01 && t.a == 1.0, "{t:?}");
        std::fs::remove_file(&p).unwrap();
        // Not an image at all: an error naming the file, no panic.
        let p = temp("junk.png");
        std::fs::write(&p, b"not a png").unwrap();
        let e = load_texels(&p, &Limits::default()).unwrap_err().to_string();
        assert!(e.contains("junk.png"), "{e}");
        std::fs::remove_file(&p).unwrap();
    }

    #[test]
    fn exr_keeps_linear_floats_and_png_encodes_srgb() {
        let pixels = vec![
            Rgba::new(0.25, 2.5, 0.0, 1.0),
            Rgba::new(0.1, 0.05, 0.0, 0.5),
        ];
        let image = LinearImage {
            width: 2,
            height: 1,
            pixels,
        };
        let exr = temp("out.exr");
        save_image(&exr, &image).unwrap();
        let back = image::open(&exr).unwrap().to_rgba32f();
        assert_eq!(
            back.get_pixel(0, 0).0,
            [0.25, 2.5, 0.0, 1.0],
            "EXR stays linear, unclamped"
        );
        assert_eq!(
            back.get_pixel(1, 0).0,
            [0.1, 0.05, 0.0, 0.5],
            "EXR stays premultiplied"
        );
        let png = temp("out.png");
        save_image(&png, &image).unwrap();
        let back = image::open(&png).unwrap().to_rgba8();
        // Linear 0.25 is sRGB 137; premultiplied 0.1 at alpha 0.5 is straight 0.2 → 124.
        assert_eq!(back.get_pixel(0, 0).0, [137, 255, 0, 255]);
        assert_eq!(back.get_pixel(1, 0).0[0], 124);
        // The PNG holds exactly the bytes `srgb8_from_linear` gives.
        assert_eq!(back.into_raw(), srgb8_from_linear(&image.pixels));
        assert_eq!(
            srgb8_from_linear(&[Rgba::new(0.5, f32::NAN, 2.0, 0.0)]),
            [0, 0, 0, 0],
            "no alpha, no colour"
        );
        assert!(matches!(
            save_image(&temp("out.bmp"), &image),
            Err(Error::UnsupportedExtension(_))
        ));
        std::fs::remove_file(&exr).unwrap();
        std::fs::remove_file(&png).unwrap();
    }

    #[test]
    fn float_texels_stay_unclamped_and_nan_or_infinite_ones_are_refused() {
        let float = |v: Vec<f32>| {
            DynamicImage::ImageRgba32F(image::ImageBuffer::from_raw(4, 1, v).unwrap())
        };
        let g = texels_from_image(float(vec![
            500.0, -2.0, 0.5, 1.0, 0.25, 0.5, 0.75, 0.5, 0.1, 0.2, 0.3, 1.5, 0.0, 0.0, 0.0, 0.0,
        ]))
        .unwrap();
        assert!(g.is_hdr());
        let (tree, _) = quadtex_core::QuadTree::from_texels(&g, &Default::default()).unwrap();
        let f = |x0: f64| quadtex_core::Fragment::new(x0, 0.0, x0 + 0.25, 1.0).unwrap();
        let first = tree.weighted_colour(&f(0.0), 30).0.map(|v| v * 4.0);
        assert!(
            (first[0] - 500.0).abs() < 0.25 && (first[1] + 2.0).abs() < 1e-3,
            "{first:?}"
        );
        // Alpha is clamped to [0, 1] (stated in `TexelGrid::from_linear_f32`).
        let third = tree.weighted_colour(&f(0.5), 30).0.map(|v| v * 4.0);
        assert!((third[3] - 1.0).abs() < 1e-3, "{third:?}");
        for bad in [f32::NAN, f32::INFINITY, f32::NEG_INFINITY] {
            let e = texels_from_image(float(vec![
                0.5, 0.5, 0.5, 1.0, 2.0, 0.5, bad, 1.0, 0.1, 0.2, 0.3, 1.0, 0.0, 0.0, 0.0, 0.0,
            ]))
            .unwrap_err();
            assert!(e.to_string().starts_with("texel (1, 0) has b = "), "{e}");
        }
    }

    #[test]
    fn streams_and_fifos_get_whole_encoded_files() {
        let image = LinearImage {
            width: 3,
            height: 2,
            pixels: vec![Rgba::new(0.5, 0.25, 0.0, 1.0); 6],
        };
        for format in [ImageFormat::Png, ImageFormat::Exr] {
            let mut out = Vec::new();
            write_image(&mut out, Path::new("standard output"), &image, format).unwrap();
            let back = image::load_from_memory(&out).unwrap();
            assert_eq!((back.width(), back.height()), (3, 2), "{format:?}");
        }
        assert_eq!(
            ImageFormat::from_path(Path::new("a/B.EXR")),
            Some(ImageFormat::Exr)
        );
        assert_eq!(ImageFormat::from_path(Path::new("a/b")), None);
        // EXR into a FIFO (which cannot seek): encoded in memory, then written.
        let fifo = temp("pipe");
        let _ = std::fs::remove_file(&fifo);
        let made = std::process::Command::new("mkfifo").arg(&fifo).status();
        if !made.is_ok_and(|s| s.success()) {
            return;
        }
        let reader = {
            let fifo = fifo.clone();
            std::thread::spawn(move || std::fs::read(&fifo).unwrap())
        };
        save_image_as(&fifo, &image, ImageFormat::Exr).unwrap();
        let bytes = reader.join().unwrap();
        let back = image::load_from_memory(&bytes).unwrap().to_rgba32f();
        assert_eq!(back.get_pixel(2, 1).0, [0.5, 0.25, 0.0, 1.0]);
        // A FIFO's name has no extension: save_image cannot pick a format.
        assert!(matches!(
            save_image(&fifo, &image),
            Err(Error::UnsupportedExtension(_))
        ));
        std::fs::remove_file(&fifo).unwrap();
    }

    /// The table's code is the transfer function's, exactly: bisection's
    /// thresholds against the `f64` formula on a dense sweep of `f32`
    /// values (every 997th below 1, both sides of each threshold); the
    /// `f32` formula agrees but within a hair of a code's edge.
    #[test]
    fn srgb8_codes_are_the_exact_transfer_function() {
        let exact = |v: f32| {
            let x = f64::from(v.clamp(0.0, 1.0));
            (255.0 * srgb_encode(x) + 0.5).floor() as u8
        };
        let (mut checked, mut f32_differs) = (0, 0);
        let mut check = |v: f32| {
            let code = linear_to_srgb8(v);
            assert_eq!(code, exact(v), "{v:e}");
            let scaled = 255.0 * srgb_encode(f64::from(v)) + 0.5;
            if code != (srgb_encode_f32(v) * 255.0 + 0.5) as u8 {
                f32_differs += 1;
                assert!((scaled - scaled.round()).abs() < 1e-4, "{v:e}: {scaled}");
            }
            checked += 1;
        };
        for bits in (0..1.0f32.to_bits()).step_by(997) {
            check(f32::from_bits(bits));
        }
        for t in srgb8_encode_table().threshold.iter().skip(1) {
            let v = *t as f32;
            check(v);
            check(f32::from_bits(v.to_bits() - 1));
            check(f32::from_bits(v.to_bits() + 1));
        }
        for v in [f32::NAN, -1.0, -0.0, 0.0, 1.0, 2.0, f32::INFINITY] {
            check(v);
        }
        assert!(checked > 1_000_000 && f32_differs < checked / 1000);
    }

    #[test]
    fn srgb_round_trips_every_8_bit_code() {
        for v in 0..=255u8 {
            let lin = srgb_decode_f32(f32::from(v) / 255.0);
            assert_eq!((srgb_encode_f32(lin) * 255.0 + 0.5) as u8, v);
            assert_eq!(linear_to_srgb8(lin), v);
        }
    }

    #[test]
    fn decodes_grey_alpha_16_bit_and_premultiplies() {
        let img = DynamicImage::ImageLumaA16(
            image::ImageBuffer::from_raw(1, 1, vec![65535u16, 32768]).unwrap(),
        );
        let g = texels_from_image(img).unwrap();
        let t = g.texel(0, 0).to_rgba();
        assert!(
            (t.a - 0.5).abs() < 1e-4 && (t.r - 0.5).abs() < 1e-4,
            "{t:?}"
        );
        // sRGB mid-grey 128 is ~0.216 in linear light.
        let img = DynamicImage::ImageRgb8(
            image::ImageBuffer::from_raw(1, 1, vec![128u8, 128, 128]).unwrap(),
        );
        let t = texels_from_image(img).unwrap().texel(0, 0).to_rgba();
        assert!((t.r - 0.2158).abs() < 1e-3, "{t:?}");
    }
}
