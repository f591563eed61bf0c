use std::iter::Sum;
use std::ops::{Add, AddAssign, Mul, Sub};

/// A colour in linear light with premultiplied alpha, channels nominally in `[0,1]`.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Rgba {
    /// Red, premultiplied by alpha.
    pub r: f32,
    /// Green, premultiplied by alpha.
    pub g: f32,
    /// Blue, premultiplied by alpha.
    pub b: f32,
    /// Coverage / opacity.
    pub a: f32,
}

impl Rgba {
    /// Opaque black with zero alpha: the colour of "nothing".
    pub const TRANSPARENT: Rgba = Rgba {
        r: 0.0,
        g: 0.0,
        b: 0.0,
        a: 0.0,
    };

    /// A colour from premultiplied linear channels.
    pub const fn new(r: f32, g: f32, b: f32, a: f32) -> Rgba {
        Rgba { r, g, b, a }
    }
    /// An opaque colour from linear channels.
    pub const fn opaque(r: f32, g: f32, b: f32) -> Rgba {
        Rgba { r, g, b, a: 1.0 }
    }
    /// The channels as an array `[r, g, b, a]`.
    pub fn to_array(self) -> [f32; 4] {
        [self.r, self.g, self.b, self.a]
    }
    /// Quantise to the tree's storage format (clamped to `[0,1]`, then rounded).
    pub fn to_unorm16(self) -> Unorm16Rgba {
        let q = |v: f32| (v.clamp(0.0, 1.0) * 65535.0 + 0.5) as u16;
        let a = q(self.a);
        // Premultiplied colour never exceeds alpha; keep that true after rounding.
        Unorm16Rgba([q(self.r).min(a), q(self.g).min(a), q(self.b).min(a), a])
    }
}

/// Channel-wise sum: accumulating premultiplied colours (a weighted mean is
/// `Σ wᵢ·cᵢ · (1/Σ wᵢ)`).
impl Add for Rgba {
    type Output = Rgba;
    fn add(self, o: Rgba) -> Rgba {
        Rgba::new(self.r + o.r, self.g + o.g, self.b + o.b, self.a + o.a)
    }
}

impl AddAssign for Rgba {
    fn add_assign(&mut self, o: Rgba) {
        *self = *self + o;
    }
}

/// Channel-wise difference.
impl Sub for Rgba {
    type Output = Rgba;
    fn sub(self, o: Rgba) -> Rgba {
        Rgba::new(self.r - o.r, self.g - o.g, self.b - o.b, self.a - o.a)
    }
}

/// Every channel scaled by `s` (a premultiplied colour scales with its alpha).
impl Mul<f32> for Rgba {
    type Output = Rgba;
    fn mul(self, s: f32) -> Rgba {
        Rgba::new(self.r * s, self.g * s, self.b * s, self.a * s)
    }
}

/// Channel-wise product: a texture colour modulated by a surface colour or
/// a light.
impl Mul for Rgba {
    type Output = Rgba;
    fn mul(self, o: Rgba) -> Rgba {
        Rgba::new(self.r * o.r, self.g * o.g, self.b * o.b, self.a * o.a)
    }
}

impl Sum for Rgba {
    fn sum<I: Iterator<Item = Rgba>>(iter: I) -> Rgba {
        iter.fold(Rgba::TRANSPARENT, Add::add)
    }
}

impl Rgba {
    /// `self + t·(other − self)`, channel by channel.
    pub fn lerp(self, other: Rgba, t: f32) -> Rgba {
        Rgba::new(
            self.r + t * (other.r - self.r),
            self.g + t * (other.g - self.g),
            self.b + t * (other.b - self.b),
            self.a + t * (other.a - self.a),
        )
    }
}

/// A colour as stored in a tree node: linear, premultiplied, each channel an
/// integer `v` standing for `v / 65535`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Hash)]
pub struct Unorm16Rgba(pub [u16; 4]);

impl Unorm16Rgba {
    /// The colour as floats.
    pub fn to_rgba(self) -> Rgba {
        let f = |v: u16| f32::from(v) / 65535.0;
        Rgba::new(f(self.0[0]), f(self.0[1]), f(self.0[2]), f(self.0[3]))
    }
}

/// How a tree's nodes store colour: each channel is one `u16`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
#[non_exhaustive]
pub enum ColourEncoding {
    /// `v / 65535`: linear, premultiplied, in `[0, 1]` (LDR textures).
    #[default]
    Unorm16,
    /// IEEE 754 binary16 ("half"): linear, premultiplied, unclamped colour
    /// (HDR textures: values above 1 and below 0), alpha in `[0, 1]`;
    /// 11 significant bits, about 3 decimal digits, up to 65504.
    Half,
}

impl ColourEncoding {
    /// The channel `v` as a float.
    #[inline]
    pub fn decode(self, v: u16) -> f64 {
        match self {
            ColourEncoding::Unorm16 => f64::from(v) * (1.0 / 65535.0),
            ColourEncoding::Half => f64::from(half::f16::from_bits(v).to_f32()),
        }
    }

    /// A stored colour as floats.
    #[inline]
    pub fn decode_colour(self, c: Unorm16Rgba) -> [f64; 4] {
        c.0.map(|v| self.decode(v))
    }

    /// A channel value rounded to the nearest stored one (unorm16 clamps to
    /// `[0, 1]`; half rounds to nearest even and saturates to ±65504).
    #[inline]
    pub fn encode(self, v: f64) -> u16 {
        match self {
            ColourEncoding::Unorm16 => (v.clamp(0.0, 1.0) * 65535.0 + 0.5) as u16,
            ColourEncoding::Half => {
                let h = half::f16::from_f64(v.clamp(-65504.0, 65504.0));
                h.to_bits()
            }
        }
    }

    /// The code the `.qtx` header stores (`colour_format`).
    pub fn code(self) -> u8 {
        match self {
            ColourEncoding::Unorm16 => 1,
            ColourEncoding::Half => 2,
        }
    }

    /// The encoding of a header code.
    pub fn from_code(code: u8) -> Option<ColourEncoding> {
        match code {
            1 => Some(ColourEncoding::Unorm16),
            2 => Some(ColourEncoding::Half),
            _ => None,
        }
    }

    /// A short name for reports.
    pub fn name(self) -> &'static str {
        match self {
            ColourEncoding::Unorm16 => "unorm16 RGBA (linear, premultiplied, [0,1])",
            ColourEncoding::Half => "half-float RGBA (linear, premultiplied, HDR)",
        }
    }
}

/// Colour × area: the integral of the texture's colour over a region.
///
/// Channels are linear, premultiplied, in units of (colour × texture-space
/// area); dividing by the region's area gives its mean colour.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct WeightedColour(pub [f64; 4]);

impl WeightedColour {
    /// Zero.
    pub const ZERO: WeightedColour = WeightedColour([0.0; 4]);

    /// The mean colour over a region of area `area`; transparent for zero area.
    pub fn mean_over(self, area: f64) -> Rgba {
        if area > 0.0 {
            let s = 1.0 / area;
            Rgba::new(
                (self.0[0] * s) as f32,
                (self.0[1] * s) as f32,
                (self.0[2] * s) as f32,
                (self.0[3] * s) as f32,
            )
        } else {
            Rgba::TRANSPARENT
        }
    }

    /// `colour × area`, exactly in `f64` from the stored integers.
    pub fn from_unorm16(colour: Unorm16Rgba, area: f64) -> WeightedColour {
        WeightedColour(colour.0.map(|c| f64::from(c) * area * (1.0 / 65535.0)))
    }

    /// `colour × area`.
    pub fn from_colour(colour: Rgba, area: f64) -> WeightedColour {
        WeightedColour(colour.to_array().map(|c| f64::from(c) * area))
    }
}

impl Add for WeightedColour {
    type Output = WeightedColour;
    fn add(self, o: WeightedColour) -> WeightedColour {
        WeightedColour([
            self.0[0] + o.0[0],
            self.0[1] + o.0[1],
            self.0[2] + o.0[2],
            self.0[3] + o.0[3],
        ])
    }
}

impl AddAssign for WeightedColour {
    fn add_assign(&mut self, o: WeightedColour) {
        *self = *self + o;
    }
}

impl Mul<f64> for WeightedColour {
    type Output = WeightedColour;
    fn mul(self, s: f64) -> WeightedColour {
        WeightedColour(self.0.map(|c| c * s))
    }
}

/// The sRGB transfer function (IEC 61966-2-1), written once for both float
/// widths: each width keeps its own literals and arithmetic, so `f32`
/// callers get exactly what `f32` arithmetic gives (the texel tables and
/// PNG output depend on it) and `f64` callers what `f64` gives.
macro_rules! srgb_transfer {
    ($float:ty, $decode:ident, $encode:ident) => {
        /// sRGB decoding: encoded `[0,1]` → linear light.
        pub fn $decode(v: $float) -> $float {
            if v <= 0.04045 {
                v / 12.92
            } else {
                ((v + 0.055) / 1.055).powf(2.4)
            }
        }

        /// sRGB encoding: linear light → encoded, clamped to `[0,1]`.
        pub fn $encode(v: $float) -> $float {
            let v = v.clamp(0.0, 1.0);
            if v <= 0.003_130_8 {
                v * 12.92
            } else {
                1.055 * v.powf(1.0 / 2.4) - 0.055
            }
        }
    };
}

srgb_transfer!(f64, srgb_decode, srgb_encode);
srgb_transfer!(f32, srgb_decode_f32, srgb_encode_f32);
