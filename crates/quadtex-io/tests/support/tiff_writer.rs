//! A small TIFF writer for tests (shared by `quadtex-io`'s unit tests and
//! the command line's, through `#[path]`): any layout the reader takes
//! (stripped or tiled, chunky or planar, TIFF or BigTIFF, uncompressed, LZW
//! or Deflate) and some it refuses, with optional GeoTIFF tags. The `tiff`
//! crate's encoder writes only stripped images; tiles are laid out here and
//! written through its directory encoder.
#![allow(dead_code, clippy::unwrap_used, clippy::expect_used)]

use std::io::Cursor;

use tiff::encoder::compression::{CompressionAlgorithm, Deflate, Lzw};
use tiff::encoder::{DirectoryEncoder, TiffEncoder, TiffKind};
use tiff::tags::Tag;

/// What to write. `samples` holds `width × height × samples_per_pixel`
/// values, chunky, row-major from the top; each is written in `bits` bits
/// (8 or 16, or 32 with `sample_format` 3 for floats, the value cast).
#[derive(Debug, Clone)]
pub struct Spec {
    pub width: u32,
    pub height: u32,
    pub bits: u16,
    pub samples_per_pixel: u16,
    /// 0 WhiteIsZero, 1 BlackIsZero, 2 RGB, 3 palette, 5 CMYK, 6 YCbCr.
    pub photometric: u16,
    /// `ExtraSamples` (1 associated alpha, 2 unassociated), if any.
    pub extra_samples: Vec<u16>,
    /// Tile width and height; `None` writes strips of `rows_per_strip`.
    pub tile: Option<(u32, u32)>,
    pub rows_per_strip: u32,
    /// 1 none, 5 LZW, 8 Deflate (others are written uncompressed, tagged
    /// as asked).
    pub compression: u16,
    pub big: bool,
    pub planar: bool,
    pub sample_format: Option<u16>,
    pub samples: Vec<u16>,
    /// `ModelPixelScaleTag`, `ModelTiepointTag` and `GeoKeyDirectoryTag`.
    pub geo: Option<([f64; 3], [f64; 6], Vec<u16>)>,
    /// The `ImageWidth` and `ImageLength` to write instead of the real ones
    /// (a lying header).
    pub declared_size: Option<(u32, u32)>,
}

impl Spec {
    /// An 8-bit RGB image of `samples`, in one uncompressed strip.
    pub fn rgb8(width: u32, height: u32, samples: Vec<u16>) -> Spec {
        Spec {
            width,
            height,
            bits: 8,
            samples_per_pixel: 3,
            photometric: 2,
            extra_samples: Vec::new(),
            tile: None,
            rows_per_strip: height,
            compression: 1,
            big: false,
            planar: false,
            sample_format: None,
            samples,
            geo: None,
            declared_size: None,
        }
    }

    /// The file's bytes.
    pub fn write(&self) -> Vec<u8> {
        let mut out = Cursor::new(Vec::new());
        if self.big {
            self.write_with(TiffEncoder::new_big(&mut out).unwrap());
        } else {
            self.write_with(TiffEncoder::new(&mut out).unwrap());
        }
        out.into_inner()
    }

    fn write_with<K: TiffKind>(&self, mut encoder: TiffEncoder<&mut Cursor<Vec<u8>>, K>) {
        let mut dir = encoder.image_directory().unwrap();
        let spp = usize::from(self.samples_per_pixel);
        let (cw, ch) = self.tile.unwrap_or((self.width, self.rows_per_strip));
        let across = self.width.div_ceil(cw);
        let down = self.height.div_ceil(ch);
        let planes: Vec<Option<usize>> = if self.planar {
            (0..spp).map(Some).collect()
        } else {
            vec![None]
        };
        let mut offsets = Vec::new();
        let mut counts = Vec::new();
        for plane in &planes {
            for unit in 0..across * down {
                let (x0, y0) = ((unit % across) * cw, (unit / across) * ch);
                // Tiles are whole (padded with zeros); the last strip is cut short.
                let rows = if self.tile.is_some() {
                    ch
                } else {
                    ch.min(self.height - y0)
                };
                let mut raw = Vec::new();
                for y in y0..y0 + rows {
                    for x in x0..x0 + cw {
                        let inside = x < self.width && y < self.height;
                        let at = (y as usize * self.width as usize + x as usize) * spp;
                        let take: Vec<usize> = match plane {
                            Some(p) => vec![*p],
                            None => (0..spp).collect(),
                        };
                        for k in take {
                            let v = if inside { self.samples[at + k] } else { 0 };
                            match self.bits {
                                1 | 8 => raw.push(v as u8),
                                16 => raw.extend(v.to_le_bytes()),
                                _ => raw.extend((f32::from(v) / 65535.0).to_le_bytes()),
                            }
                        }
                    }
                }
                let mut packed = Vec::new();
                match self.compression {
                    5 => {
                        Lzw.write_to(&mut packed, &raw).unwrap();
                    }
                    8 => {
                        Deflate::default().write_to(&mut packed, &raw).unwrap();
                    }
                    _ => packed = raw,
                }
                offsets.push(dir.write_data(packed.as_slice()).unwrap());
                counts.push(packed.len() as u64);
            }
        }
        let (width, height) = self.declared_size.unwrap_or((self.width, self.height));
        dir.write_tag(Tag::ImageWidth, width).unwrap();
        dir.write_tag(Tag::ImageLength, height).unwrap();
        dir.write_tag(Tag::BitsPerSample, vec![self.bits; spp].as_slice())
            .unwrap();
        dir.write_tag(Tag::Compression, self.compression).unwrap();
        dir.write_tag(Tag::PhotometricInterpretation, self.photometric)
            .unwrap();
        dir.write_tag(Tag::SamplesPerPixel, self.samples_per_pixel)
            .unwrap();
        dir.write_tag(Tag::PlanarConfiguration, if self.planar { 2u16 } else { 1 })
            .unwrap();
        if !self.extra_samples.is_empty() {
            dir.write_tag(Tag::ExtraSamples, self.extra_samples.as_slice())
                .unwrap();
        }
        if let Some(f) = self.sample_format {
            dir.write_tag(Tag::SampleFormat, vec![f; spp].as_slice())
                .unwrap();
        }
        let (offsets_tag, counts_tag) = match self.tile {
            Some((tw, th)) => {
                dir.write_tag(Tag::TileWidth, tw).unwrap();
                dir.write_tag(Tag::TileLength, th).unwrap();
                (Tag::TileOffsets, Tag::TileByteCounts)
            }
            None => {
                dir.write_tag(Tag::RowsPerStrip, self.rows_per_strip)
                    .unwrap();
                (Tag::StripOffsets, Tag::StripByteCounts)
            }
        };
        write_u64s(&mut dir, offsets_tag, &offsets, self.big);
        write_u64s(&mut dir, counts_tag, &counts, self.big);
        if let Some((scale, tiepoint, keys)) = &self.geo {
            dir.write_tag(Tag::ModelPixelScaleTag, scale.as_slice())
                .unwrap();
            dir.write_tag(Tag::ModelTiepointTag, tiepoint.as_slice())
                .unwrap();
            dir.write_tag(Tag::GeoKeyDirectoryTag, keys.as_slice())
                .unwrap();
        }
        dir.finish().unwrap();
    }
}

/// Offsets and byte counts: LONG8 in a BigTIFF, LONG otherwise.
fn write_u64s<K: TiffKind>(
    dir: &mut DirectoryEncoder<'_, &mut Cursor<Vec<u8>>, K>,
    tag: Tag,
    values: &[u64],
    big: bool,
) {
    if big {
        dir.write_tag(tag, values).unwrap();
    } else {
        let v: Vec<u32> = values.iter().map(|&v| v as u32).collect();
        dir.write_tag(tag, v.as_slice()).unwrap();
    }
}

/// GeoKeys of a UTM zone 33N image (EPSG:32633), pixel-is-area.
pub fn utm33_keys() -> Vec<u16> {
    vec![
        1, 1, 0, 3, // version 1.1.0, three keys
        1024, 0, 1, 1, // GTModelTypeGeoKey: projected
        1025, 0, 1, 1, // GTRasterTypeGeoKey: pixel is area
        3072, 0, 1, 32633, // ProjectedCSTypeGeoKey
    ]
}
