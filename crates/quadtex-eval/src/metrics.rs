//! Error metrics against a reference, on **linear** RGB (alpha ignored;
//! rendered frames are opaque): RMSE over all pixels and channels, PSNR =
//! `20·log10(1/RMSE)` (peak 1), and *temporal shimmer*: over a sequence of
//! frames of a slow camera move, the RMS over pixels and frame pairs of the
//! change of the error, `(img_t − ref_t) − (img_{t−1} − ref_{t−1})`. A filter
//! whose error is steady (a constant blur) scores low; one whose error crawls
//! and flickers from frame to frame (aliasing) scores high.

use quadtex_core::Rgba;
use quadtex_io::LinearImage;

/// Root-mean-square difference of linear RGB over all pixels and channels.
/// `None` when the sizes differ.
pub fn rmse(a: &LinearImage, b: &LinearImage) -> Option<f64> {
    if a.width != b.width || a.height != b.height || a.pixels.is_empty() {
        return None;
    }
    let mut sum = 0.0;
    for (p, q) in a.pixels.iter().zip(&b.pixels) {
        for (x, y) in [(p.r, q.r), (p.g, q.g), (p.b, q.b)] {
            let d = f64::from(x) - f64::from(y);
            sum += d * d;
        }
    }
    Some((sum / (3 * a.pixels.len()) as f64).sqrt())
}

/// Peak signal-to-noise ratio in dB for peak 1 (infinite for identical images).
pub fn psnr(rmse: f64) -> f64 {
    -20.0 * rmse.log10()
}

/// Temporal shimmer of `frames` against `references` (see the module docs);
/// `None` with fewer than two frames or mismatched sizes.
pub fn shimmer(frames: &[LinearImage], references: &[LinearImage]) -> Option<f64> {
    if frames.len() < 2 || frames.len() != references.len() {
        return None;
    }
    let mut sum = 0.0;
    let mut count = 0usize;
    for t in 1..frames.len() {
        let (a, b, ra, rb) = (
            &frames[t],
            &frames[t - 1],
            &references[t],
            &references[t - 1],
        );
        let n = a.pixels.len();
        if [b.pixels.len(), ra.pixels.len(), rb.pixels.len()] != [n, n, n] {
            return None;
        }
        for i in 0..n {
            let (p, q, r, s) = (a.pixels[i], b.pixels[i], ra.pixels[i], rb.pixels[i]);
            for ch in 0..3 {
                let v = |c: Rgba| f64::from(c.to_array()[ch]);
                let d = (v(p) - v(r)) - (v(q) - v(s));
                sum += d * d;
            }
            count += 3;
        }
    }
    Some((sum / count.max(1) as f64).sqrt())
}

/// A false-colour map of `|a − b|` (mean over RGB): black at 0 through red
/// and yellow to white at `full_scale` and above.
pub fn error_map(a: &LinearImage, b: &LinearImage, full_scale: f32) -> LinearImage {
    let pixels = a
        .pixels
        .iter()
        .zip(&b.pixels)
        .map(|(p, q)| {
            let e = ((p.r - q.r).abs() + (p.g - q.g).abs() + (p.b - q.b).abs()) / 3.0;
            let t = (e / full_scale).clamp(0.0, 1.0);
            // Linear-light ramp, so the sRGB PNG reads black → red → yellow → white.
            let r = (3.0 * t).min(1.0);
            let g = (3.0 * t - 1.0).clamp(0.0, 1.0);
            let bl = (3.0 * t - 2.0).clamp(0.0, 1.0);
            Rgba::opaque(r * r, g * g, bl * bl)
        })
        .collect();
    LinearImage {
        width: a.width,
        height: a.height,
        pixels,
    }
}

/// RMSE of `img` against the closed form over the pixels where it is defined,
/// and the fraction of pixels defined.
pub fn rmse_where_defined(img: &LinearImage, exact: &[Option<Rgba>]) -> Option<(f64, f64)> {
    if exact.len() != img.pixels.len() {
        return None;
    }
    let (mut sum, mut n) = (0.0, 0usize);
    for (p, e) in img.pixels.iter().zip(exact) {
        if let Some(e) = e {
            for (a, b) in [(p.r, e.r), (p.g, e.g), (p.b, e.b)] {
                let d = f64::from(a) - f64::from(b);
                sum += d * d;
            }
            n += 1;
        }
    }
    (n > 0).then(|| ((sum / (3 * n) as f64).sqrt(), n as f64 / exact.len() as f64))
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    fn image(values: &[f32]) -> LinearImage {
        LinearImage {
            width: values.len() as u32,
            height: 1,
            pixels: values.iter().map(|&v| Rgba::opaque(v, v, v)).collect(),
        }
    }

    #[test]
    fn rmse_and_psnr() {
        let a = image(&[0.0, 0.5]);
        let b = image(&[0.1, 0.5]);
        let r = rmse(&a, &b).unwrap();
        assert!((r - (0.01f64 / 2.0).sqrt()).abs() < 1e-7);
        assert!((psnr(0.1) - 20.0).abs() < 1e-9);
        assert!(rmse(&a, &image(&[0.0])).is_none());
    }

    #[test]
    fn steady_error_does_not_shimmer_but_flicker_does() {
        let refs = vec![image(&[0.5, 0.5]); 4];
        let blurred = vec![image(&[0.4, 0.6]); 4];
        assert_eq!(shimmer(&blurred, &refs), Some(0.0));
        let flicker: Vec<_> = (0..4)
            .map(|t| {
                if t % 2 == 0 {
                    image(&[0.4, 0.6])
                } else {
                    image(&[0.6, 0.4])
                }
            })
            .collect();
        assert!((shimmer(&flicker, &refs).unwrap() - 0.2).abs() < 1e-6);
    }
}
