//! Blend modes of translucent groups (CSS Compositing and Blending Level 1,
//! as SVG's `mix-blend-mode` uses them).
//!
//! A blended group's source `s` meets the backdrop `b` below it (both
//! premultiplied, linear light) as
//! `co = (1 − ab)·cs + (1 − as)·cb + as·ab·B(Cb, Cs)`, `ao = as + ab·(1 − as)`,
//! where `B` is the mode's function of the *unpremultiplied* colours. `B` is
//! evaluated on **sRGB-encoded** channels and decoded, as browsers and
//! resvg blend (so an opaque multiply matches them exactly); the weights
//! around it are linear, like every other composite in quadtex.
//!
//! [`BlendMode::PlusLighter`] is a compositing operator rather than a
//! blend: the sum of the two premultiplied colours, clamped to 1, taken on
//! sRGB-encoded premultiplied channels as browsers and resvg add them.

use crate::colour::{srgb_decode, srgb_encode};

/// How a group's colour combines with what lies below it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum BlendMode {
    /// Source over backdrop.
    #[default]
    Normal,
    /// `Cb·Cs`.
    Multiply,
    /// `Cb + Cs − Cb·Cs`.
    Screen,
    /// Hard light with the layers swapped.
    Overlay,
    /// `min(Cb, Cs)`.
    Darken,
    /// `max(Cb, Cs)`.
    Lighten,
    /// Brightens the backdrop by the source.
    ColorDodge,
    /// Darkens the backdrop by the source.
    ColorBurn,
    /// Multiply or screen, by the source.
    HardLight,
    /// A softer hard light.
    SoftLight,
    /// `|Cb − Cs|`.
    Difference,
    /// `Cb + Cs − 2·Cb·Cs`.
    Exclusion,
    /// The source's hue with the backdrop's saturation and luminosity.
    Hue,
    /// The source's saturation.
    Saturation,
    /// The source's hue and saturation.
    Color,
    /// The source's luminosity.
    Luminosity,
    /// `min(1, cs + cb)` and `min(1, as + ab)` on premultiplied colours
    /// (see the module docs).
    PlusLighter,
}

fn separable(mode: BlendMode, b: f64, s: f64) -> f64 {
    match mode {
        BlendMode::Normal => s,
        BlendMode::Multiply => b * s,
        BlendMode::Screen => b + s - b * s,
        BlendMode::Overlay => separable(BlendMode::HardLight, s, b),
        BlendMode::Darken => b.min(s),
        BlendMode::Lighten => b.max(s),
        BlendMode::ColorDodge => {
            if b == 0.0 {
                0.0
            } else if s >= 1.0 {
                1.0
            } else {
                (b / (1.0 - s)).min(1.0)
            }
        }
        BlendMode::ColorBurn => {
            if b >= 1.0 {
                1.0
            } else if s <= 0.0 {
                0.0
            } else {
                1.0 - ((1.0 - b) / s).min(1.0)
            }
        }
        BlendMode::HardLight => {
            if s <= 0.5 {
                b * 2.0 * s
            } else {
                let t = 2.0 * s - 1.0;
                b + t - b * t
            }
        }
        BlendMode::SoftLight => {
            if s <= 0.5 {
                b - (1.0 - 2.0 * s) * b * (1.0 - b)
            } else {
                let d = if b <= 0.25 {
                    ((16.0 * b - 12.0) * b + 4.0) * b
                } else {
                    b.sqrt()
                };
                b + (2.0 * s - 1.0) * (d - b)
            }
        }
        BlendMode::Difference => (b - s).abs(),
        BlendMode::Exclusion => b + s - 2.0 * b * s,
        BlendMode::Hue
        | BlendMode::Saturation
        | BlendMode::Color
        | BlendMode::Luminosity
        | BlendMode::PlusLighter => s,
    }
}

fn lum(c: [f64; 3]) -> f64 {
    0.3 * c[0] + 0.59 * c[1] + 0.11 * c[2]
}

fn clip_colour(c: [f64; 3]) -> [f64; 3] {
    let l = lum(c);
    let n = c[0].min(c[1]).min(c[2]);
    let x = c[0].max(c[1]).max(c[2]);
    let mut c = c;
    if n < 0.0 {
        c = c.map(|v| l + (v - l) * l / (l - n));
    }
    if x > 1.0 {
        c = c.map(|v| l + (v - l) * (1.0 - l) / (x - l));
    }
    c
}

fn set_lum(c: [f64; 3], l: f64) -> [f64; 3] {
    let d = l - lum(c);
    clip_colour(c.map(|v| v + d))
}

fn sat(c: [f64; 3]) -> f64 {
    c[0].max(c[1]).max(c[2]) - c[0].min(c[1]).min(c[2])
}

fn set_sat(c: [f64; 3], s: f64) -> [f64; 3] {
    let (mx, mn) = (c[0].max(c[1]).max(c[2]), c[0].min(c[1]).min(c[2]));
    if mx > mn {
        c.map(|v| (v - mn) * s / (mx - mn))
    } else {
        [0.0; 3]
    }
}

/// `B(Cb, Cs)` on unpremultiplied, sRGB-encoded colours.
fn blend_encoded(mode: BlendMode, b: [f64; 3], s: [f64; 3]) -> [f64; 3] {
    match mode {
        BlendMode::Hue => set_lum(set_sat(s, sat(b)), lum(b)),
        BlendMode::Saturation => set_lum(set_sat(b, sat(s)), lum(b)),
        BlendMode::Color => set_lum(s, lum(b)),
        BlendMode::Luminosity => set_lum(b, lum(s)),
        _ => [0, 1, 2].map(|k| separable(mode, b[k], s[k])),
    }
}

/// Premultiplied sRGB-encoded colour channel `c` of alpha `a` (nondecreasing
/// in both: `srgb_encode` is concave with value 0 at 0).
fn encoded_premultiplied(c: f64, a: f64) -> f64 {
    if a <= 0.0 {
        0.0
    } else {
        srgb_encode((c / a).clamp(0.0, 1.0)) * a
    }
}

/// Linear premultiplied channel of encoded premultiplied `e` at alpha `a`
/// (nondecreasing in `e`, nonincreasing in `a`: `srgb_decode` is convex).
fn linear_premultiplied(e: f64, a: f64) -> f64 {
    if a <= 0.0 {
        0.0
    } else {
        srgb_decode((e / a).clamp(0.0, 1.0)) * a
    }
}

/// The source `s` blended onto the backdrop `b` (premultiplied, linear).
pub fn blend(mode: BlendMode, b: [f64; 4], s: [f64; 4]) -> [f64; 4] {
    let (ab, a_s) = (b[3], s[3]);
    if mode == BlendMode::PlusLighter {
        let a = (ab + a_s).min(1.0);
        let mut out = [0.0, 0.0, 0.0, a];
        for k in 0..3 {
            let e = encoded_premultiplied(b[k], ab) + encoded_premultiplied(s[k], a_s);
            out[k] = linear_premultiplied(e.min(a), a);
        }
        return out;
    }
    if mode == BlendMode::Normal || ab <= 0.0 || a_s <= 0.0 {
        return [0, 1, 2, 3].map(|k| s[k] + (1.0 - a_s) * b[k]);
    }
    let unpremultiply = |c: [f64; 4]| [0, 1, 2].map(|k| srgb_encode((c[k] / c[3]).min(1.0)));
    let mixed = blend_encoded(mode, unpremultiply(b), unpremultiply(s)).map(srgb_decode);
    let mut out = [0.0; 4];
    for k in 0..3 {
        out[k] = (1.0 - ab) * s[k] + (1.0 - a_s) * b[k] + a_s * ab * mixed[k].clamp(0.0, 1.0);
    }
    out[3] = a_s + ab * (1.0 - a_s);
    out
}

/// Per channel `[lo, hi]` of [`blend`] over every backdrop and source in
/// the ranges `b` and `s` (a bound; `[0, 1]` for the non-separable modes).
/// Every separable mode's function is monotone in each argument except
/// difference and exclusion, whose extremes over a box are at its corners
/// (and 0 for difference when the two ranges overlap); the weights around
/// it are products of non-negative ranges.
pub fn blend_range(mode: BlendMode, b: [[f64; 2]; 4], s: [[f64; 2]; 4]) -> [[f64; 2]; 4] {
    let unit = [0.0, 1.0];
    if mode == BlendMode::PlusLighter {
        let (ab, a_s) = (b[3], s[3]);
        let a = [(ab[0] + a_s[0]).min(1.0), (ab[1] + a_s[1]).min(1.0)];
        let mut out = [[0.0; 2]; 4];
        for k in 0..3 {
            let e = [
                encoded_premultiplied(b[k][0], ab[0]) + encoded_premultiplied(s[k][0], a_s[0]),
                encoded_premultiplied(b[k][1], ab[1]) + encoded_premultiplied(s[k][1], a_s[1]),
            ];
            // Smallest at the least sum and the most alpha; largest at the
            // greatest sum and the least alpha that can hold it (the result
            // never exceeds its alpha, nor the encoded sum).
            // (Where the clamp to alpha binds, the result is alpha itself.)
            let lo = linear_premultiplied(e[0].min(a[1]), a[1]).min(a[0]);
            let hi = if e[1] <= a[0] {
                linear_premultiplied(e[1], a[0])
            } else {
                e[1].min(a[1])
            };
            out[k] = [lo, hi];
        }
        out[3] = a;
        return out;
    }
    if matches!(
        mode,
        BlendMode::Hue | BlendMode::Saturation | BlendMode::Color | BlendMode::Luminosity
    ) {
        return [unit; 4];
    }
    let (ab, a_s) = (b[3], s[3]);
    // Unpremultiplied, encoded colour ranges.
    let colour = |c: [f64; 2], a: [f64; 2]| {
        if a[0] <= 0.0 {
            unit
        } else {
            [
                srgb_encode((c[0] / a[1]).min(1.0)),
                srgb_encode((c[1] / a[0]).min(1.0)),
            ]
        }
    };
    let mut out = [[0.0; 2]; 4];
    for k in 0..3 {
        let (cb, cs) = (colour(b[k], ab), colour(s[k], a_s));
        let corners = [
            separable(mode, cb[0], cs[0]),
            separable(mode, cb[0], cs[1]),
            separable(mode, cb[1], cs[0]),
            separable(mode, cb[1], cs[1]),
        ];
        let mut lo = corners.iter().copied().fold(f64::INFINITY, f64::min);
        let hi = corners.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        if mode == BlendMode::Difference && cb[0] <= cs[1] && cs[0] <= cb[1] {
            lo = 0.0;
        }
        let mixed = [
            srgb_decode(lo.clamp(0.0, 1.0)),
            srgb_decode(hi.clamp(0.0, 1.0)),
        ];
        out[k] = [
            (1.0 - ab[1]) * s[k][0] + (1.0 - a_s[1]) * b[k][0] + a_s[0] * ab[0] * mixed[0],
            (1.0 - ab[0]) * s[k][1] + (1.0 - a_s[0]) * b[k][1] + a_s[1] * ab[1] * mixed[1],
        ];
    }
    out[3] = [
        a_s[0] + ab[0] * (1.0 - a_s[0]),
        a_s[1] + ab[1] * (1.0 - a_s[1]),
    ];
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn opaque_multiply_and_screen_match_the_encoded_formulas() {
        let (b, s) = ([0.2, 0.5, 0.9, 1.0], [0.7, 0.1, 0.4, 1.0]);
        let m = blend(BlendMode::Multiply, b, s);
        let sc = blend(BlendMode::Screen, b, s);
        for k in 0..3 {
            let (eb, es) = (srgb_encode(b[k]), srgb_encode(s[k]));
            assert!((m[k] - srgb_decode(eb * es)).abs() < 1e-12);
            assert!((sc[k] - srgb_decode(eb + es - eb * es)).abs() < 1e-12);
        }
        assert_eq!(m[3], 1.0);
    }

    #[test]
    fn plus_lighter_adds_encoded_premultiplied_colours() {
        // Two half-covered greys: encoded 0.4·0.5 + 0.6·0.5 = 0.5 at alpha 1.
        let grey = |e: f64, a: f64| {
            let c = srgb_decode(e) * a;
            [c, c, c, a]
        };
        let sum = blend(BlendMode::PlusLighter, grey(0.4, 0.5), grey(0.6, 0.5));
        assert!((sum[3] - 1.0).abs() < 1e-15);
        assert!((srgb_encode(sum[0]) - 0.5).abs() < 1e-12, "{sum:?}");
        // Saturates at 1.
        let white = blend(BlendMode::PlusLighter, grey(0.9, 1.0), grey(0.9, 1.0));
        assert_eq!(white, [1.0; 4]);
    }

    #[test]
    fn transparent_layers_and_normal_reduce_to_over() {
        let b = [0.1, 0.2, 0.3, 0.5];
        let s = [0.2, 0.1, 0.0, 0.4];
        for mode in [BlendMode::Normal, BlendMode::Difference, BlendMode::Hue] {
            // Over a transparent backdrop every mode is the source.
            assert_eq!(blend(mode, [0.0; 4], s), s);
            // A transparent source leaves the backdrop.
            assert_eq!(blend(mode, b, [0.0; 4]), b);
        }
        let over = blend(BlendMode::Normal, b, s);
        for k in 0..4 {
            assert!((over[k] - (s[k] + 0.6 * b[k])).abs() < 1e-15);
        }
    }

    #[test]
    fn ranges_contain_every_blend_of_their_members() {
        let modes = [
            BlendMode::PlusLighter,
            BlendMode::Multiply,
            BlendMode::Screen,
            BlendMode::Overlay,
            BlendMode::Darken,
            BlendMode::Lighten,
            BlendMode::ColorDodge,
            BlendMode::ColorBurn,
            BlendMode::HardLight,
            BlendMode::SoftLight,
            BlendMode::Difference,
            BlendMode::Exclusion,
        ];
        // Backdrop and source ranges (premultiplied), sampled on a grid.
        let b = [[0.1, 0.3], [0.0, 0.5], [0.2, 0.25], [0.6, 0.9]];
        let s = [[0.05, 0.4], [0.3, 0.35], [0.0, 0.1], [0.4, 1.0]];
        let pick = |r: [[f64; 2]; 4], t: f64| {
            // Alpha first, colours at most alpha (premultiplied).
            let a = r[3][0] + t * (r[3][1] - r[3][0]);
            let mut c = [0.0, 0.0, 0.0, a];
            for k in 0..3 {
                c[k] = (r[k][0] + t * (r[k][1] - r[k][0])).min(a);
            }
            c
        };
        for mode in modes {
            let r = blend_range(mode, b, s);
            for i in 0..=8 {
                for j in 0..=8 {
                    let (bb, ss) = (pick(b, i as f64 / 8.0), pick(s, j as f64 / 8.0));
                    let c = blend(mode, bb, ss);
                    for k in 0..4 {
                        assert!(
                            r[k][0] - 1e-12 <= c[k] && c[k] <= r[k][1] + 1e-12,
                            "{mode:?} ch {k}: {} not in {:?}",
                            c[k],
                            r[k]
                        );
                    }
                }
            }
        }
    }

    #[test]
    fn non_separable_modes_keep_channels_in_range() {
        let colours = [
            [0.9, 0.1, 0.1],
            [0.1, 0.8, 0.3],
            [0.5, 0.5, 0.5],
            [0.0, 0.0, 1.0],
        ];
        for mode in [
            BlendMode::Hue,
            BlendMode::Saturation,
            BlendMode::Color,
            BlendMode::Luminosity,
        ] {
            for b in colours {
                for s in colours {
                    let c = blend_encoded(mode, b, s);
                    assert!(
                        c.iter().all(|v| (-1e-12..=1.0 + 1e-12).contains(v)),
                        "{mode:?} {c:?}"
                    );
                }
            }
        }
    }
}
