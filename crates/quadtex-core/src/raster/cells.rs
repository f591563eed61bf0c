//! The finest cells as the packer reads them: 16-bit colours or half
//! floats, and the per-square statistics of the bottom-up pass.

use super::builder::{Builder, Kind};
use crate::Error;
use crate::colour::{ColourEncoding, Unorm16Rgba};

/// A finest cell as the packer reads it: its stored colour, and how the
/// bottom-up pass sums squares of them.
pub(crate) trait Cell: Copy + Send + Sync {
    /// Per-square statistics of the bottom-up pass.
    type Stats: Copy + Send;
    /// How the tree stores the colours made of these cells.
    const ENCODING: ColourEncoding;
    /// The stored colour of a terminal cell.
    fn stored(self) -> Unorm16Rgba;
    /// The statistics of one cell.
    fn stats(self) -> Self::Stats;
    /// The stats of the parts present (`None` when none is).
    fn merge(parts: [Option<Self::Stats>; 4]) -> Option<Self::Stats>;
    /// The rounded mean over `cells` cells (at least one), as stored.
    fn mean(s: &Self::Stats, cells: u64) -> Unorm16Rgba;
    /// Largest deviation of any cell from the stored `mean`, per channel,
    /// in full-scale units (`1` = an LDR channel's range).
    fn deviation(s: &Self::Stats, mean: Unorm16Rgba) -> f64;
    /// The tolerance as the pass compares it: unorm16 rounds it down to
    /// whole steps.
    fn tolerance(t: f64) -> f64;
    /// Square `(level, ix, iz)` as a whole tile ([`QuadTree::from_tiles`]).
    fn tile(
        b: &mut Builder<'_, Self>,
        level: u8,
        ix: usize,
        iz: usize,
    ) -> Result<(Self::Stats, Unorm16Rgba, Kind), Error>;
}

/// Sums, minima and maxima of unorm16 cells.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct Stats {
    pub(super) sum: [u64; 4],
    pub(super) min: [u16; 4],
    pub(super) max: [u16; 4],
}

impl Cell for Unorm16Rgba {
    type Stats = Stats;
    const ENCODING: ColourEncoding = ColourEncoding::Unorm16;
    fn stored(self) -> Unorm16Rgba {
        self
    }
    fn stats(self) -> Stats {
        Stats {
            sum: self.0.map(u64::from),
            min: self.0,
            max: self.0,
        }
    }
    fn merge(parts: [Option<Stats>; 4]) -> Option<Stats> {
        let mut present = parts.into_iter().flatten();
        let mut s = present.next()?;
        for p in present {
            for ch in 0..4 {
                s.sum[ch] += p.sum[ch];
                s.min[ch] = s.min[ch].min(p.min[ch]);
                s.max[ch] = s.max[ch].max(p.max[ch]);
            }
        }
        Some(s)
    }
    fn mean(s: &Stats, cells: u64) -> Unorm16Rgba {
        let n = cells.max(1);
        Unorm16Rgba(s.sum.map(|v| ((v + n / 2) / n) as u16))
    }
    fn deviation(s: &Stats, mean: Unorm16Rgba) -> f64 {
        let steps = (0..4)
            .map(|ch| (s.max[ch] - mean.0[ch]).max(mean.0[ch] - s.min[ch]))
            .max()
            .unwrap_or(0);
        f64::from(steps) / 65535.0
    }
    fn tolerance(t: f64) -> f64 {
        (t * 65535.0).floor().min(65535.0) / 65535.0
    }
    fn tile(
        b: &mut Builder<'_, Self>,
        level: u8,
        ix: usize,
        iz: usize,
    ) -> Result<(Stats, Unorm16Rgba, Kind), Error> {
        b.tile(level, ix, iz)
    }
}

/// A cell of an HDR texture: four half floats (linear, premultiplied,
/// unclamped colour, alpha in `[0, 1]`), as the tree stores them.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub(crate) struct HalfRgba(pub(crate) [u16; 4]);

/// Sums, minima and maxima of half-float cells, in `f64`.
#[derive(Clone, Copy)]
pub(crate) struct HalfStats {
    sum: [f64; 4],
    min: [f64; 4],
    max: [f64; 4],
}

impl Cell for HalfRgba {
    type Stats = HalfStats;
    const ENCODING: ColourEncoding = ColourEncoding::Half;
    fn stored(self) -> Unorm16Rgba {
        Unorm16Rgba(self.0)
    }
    fn stats(self) -> HalfStats {
        let v = ColourEncoding::Half.decode_colour(Unorm16Rgba(self.0));
        HalfStats {
            sum: v,
            min: v,
            max: v,
        }
    }
    fn merge(parts: [Option<HalfStats>; 4]) -> Option<HalfStats> {
        let mut present = parts.into_iter().flatten();
        let mut s = present.next()?;
        for p in present {
            for ch in 0..4 {
                s.sum[ch] += p.sum[ch];
                s.min[ch] = s.min[ch].min(p.min[ch]);
                s.max[ch] = s.max[ch].max(p.max[ch]);
            }
        }
        Some(s)
    }
    fn mean(s: &HalfStats, cells: u64) -> Unorm16Rgba {
        // Sums of halves over at most 2^60 cells: exact enough in f64.
        let n = cells.max(1) as f64;
        Unorm16Rgba(s.sum.map(|v| ColourEncoding::Half.encode(v / n)))
    }
    fn deviation(s: &HalfStats, mean: Unorm16Rgba) -> f64 {
        let m = ColourEncoding::Half.decode_colour(mean);
        (0..4)
            .map(|ch| (s.max[ch] - m[ch]).max(m[ch] - s.min[ch]))
            .fold(0.0, f64::max)
    }
    fn tolerance(t: f64) -> f64 {
        t
    }
    fn tile(
        _: &mut Builder<'_, Self>,
        _: u8,
        _: usize,
        _: usize,
    ) -> Result<(HalfStats, Unorm16Rgba, Kind), Error> {
        Err(Error::MalformedTree(
            "HDR textures are not packed from tiles".into(),
        ))
    }
}
