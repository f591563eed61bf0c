//! Gradient paints for [`VectorArt`](crate::VectorArt): linear and radial
//! (two-point conical) gradients with stops, a spread method, and colour
//! interpolated the way SVG specifies.
//!
//! ## Conventions
//!
//! * A gradient is a function `t(p)` of the texture-space point `p` (the
//!   *gradient parameter*) and a colour function of `t`.
//!   [`Gradient::linear`] and [`Gradient::radial`] take their geometry in a
//!   *gradient space* and the affine map `gradient_from_texture`
//!   `[a, b, c, d, e, f]`: `g = (a·x + c·z + e, b·x + d·z + f)`.
//! * **Spread** folds `t` into `[0,1]`: pad clamps, repeat takes the
//!   fractional part, reflect mirrors every other period.
//! * **Stops** carry *unpremultiplied* colours in the interpolation space and
//!   an opacity. Between two stops every channel and the opacity are
//!   interpolated linearly; the result is then decoded to linear light (for
//!   [`Interpolation::Srgb`], SVG's default `color-interpolation`) and
//!   premultiplied. Before the first stop the first colour holds, after the
//!   last the last; at two stops with the same offset the later one holds
//!   from that offset on.
//!
//! ## Means over polygons
//!
//! The mean colour of a linear gradient over a convex polygon is an integral
//! along `t` of the colour times the polygon's cross-section, which is
//! linear in `t` between the `t` of two vertices. The integral is cut at the
//! vertices, the stops, the period boundaries and the points where a
//! channel's sRGB decoding changes branch; on each piece the integrand is a
//! smooth function of one variable (a power 2.4 of a linear function times a
//! quadratic) and 8-point Gauss–Legendre quadrature, on sub-pieces over
//! which the power's base grows at most 1.5-fold, integrates it to within
//! rounding (tested against composite Simpson with 2^16 intervals a piece
//! and compensated sums: below 1e-13). Over more than [`MAX_PERIODS`]
//! periods the mean is the period mean, off by at most the colour range
//! times `2/periods`.
//!
//! A radial gradient's parameter is not linear in `p`: its mean over a
//! polygon is a 4×4-point Gauss rule on each triangle of a fan, and the
//! error bound is the colour range over the polygon, which the packer
//! reports ([`crate::VectorReport`]). Ranges use a Lipschitz bound of `t`:
//! `|∇t| = 1/|Δr + û·Δc|` for the two circles' centre offset `Δc` and
//! radius difference `Δr` (`û` a unit vector), at most `1/(Δr − |Δc|)` when
//! the focal circle lies inside the end circle, which is therefore required.

use crate::Error;
use crate::colour::srgb_decode;

type Point = [f64; 2];

/// Most periods of a repeated or reflected gradient a mean integrates piece
/// by piece; beyond, it uses the mean over one period.
pub const MAX_PERIODS: f64 = 256.0;

/// Most stops a gradient may have.
pub const MAX_STOPS: usize = 1024;

/// How `t` continues beyond `[0,1]`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Spread {
    /// The end colours extend.
    Pad,
    /// Every period mirrors the one before.
    Reflect,
    /// Every period repeats `[0,1]`.
    Repeat,
}

/// The space stop colours are interpolated in.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Interpolation {
    /// sRGB-encoded channels (SVG's default); decoded after interpolation.
    Srgb,
    /// Linear-light channels.
    Linear,
}

/// A circle in gradient space, one end of a radial gradient
/// ([`Gradient::radial`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Circle {
    /// The centre.
    pub centre: [f64; 2],
    /// The radius (`>= 0`).
    pub radius: f64,
}

/// One gradient stop.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Stop {
    /// Position in `[0,1]`, non-decreasing along the list.
    pub offset: f64,
    /// Unpremultiplied red, green, blue in the interpolation space, `[0,1]`.
    pub colour: [f64; 3],
    /// Opacity in `[0,1]`.
    pub opacity: f64,
}

#[derive(Debug, Clone, PartialEq)]
enum Kind {
    /// `t = g[0]·x + g[1]·z + g[2]`.
    Linear { g: [f64; 3] },
    /// Two-point conical, in gradient space.
    Radial {
        map: [f64; 6],
        focal: Point,
        focal_radius: f64,
        centre: Point,
        radius: f64,
        /// Bound of `|∇t|` in texture space.
        lipschitz: f64,
    },
}

/// A gradient paint (see the [module documentation](self)).
#[derive(Debug, Clone, PartialEq)]
pub struct Gradient {
    kind: Kind,
    stops: Vec<Stop>,
    spread: Spread,
    interpolation: Interpolation,
    /// Where the colour function of `u ∈ [0,1]` is not smooth: 0, 1, the
    /// stops, and where an interpolated channel crosses sRGB's branch point
    /// (sorted; from the stops, so equal stops give equal breaks).
    breaks: Vec<f64>,
}

fn bad(why: String) -> Error {
    Error::BadVector(why)
}

fn check_map(map: &[f64; 6]) -> Result<(), Error> {
    if map.iter().any(|v| !v.is_finite()) {
        return Err(bad(format!("gradient transform {map:?} is not finite")));
    }
    Ok(())
}

fn check_stops(stops: &[Stop]) -> Result<(), Error> {
    if stops.is_empty() || stops.len() > MAX_STOPS {
        return Err(bad(format!(
            "a gradient needs 1 to {MAX_STOPS} stops, not {}",
            stops.len()
        )));
    }
    let mut last = 0.0;
    for (i, s) in stops.iter().enumerate() {
        let unit = |v: f64| (0.0..=1.0).contains(&v);
        if !unit(s.offset) || s.offset < last {
            return Err(bad(format!(
                "stop {i}: offset {} is outside [0,1] or below the previous stop's",
                s.offset
            )));
        }
        if !s.colour.iter().all(|&c| unit(c)) || !unit(s.opacity) {
            return Err(bad(format!(
                "stop {i}: colour {:?} or opacity {} is outside [0,1]",
                s.colour, s.opacity
            )));
        }
        last = s.offset;
    }
    Ok(())
}

impl Gradient {
    /// A linear gradient from `start` (t = 0) to `end` (t = 1), both in
    /// gradient space; `t` is constant along lines perpendicular to
    /// `end − start` there.
    pub fn linear(
        gradient_from_texture: [f64; 6],
        start: Point,
        end: Point,
        stops: Vec<Stop>,
        spread: Spread,
        interpolation: Interpolation,
    ) -> Result<Gradient, Error> {
        check_map(&gradient_from_texture)?;
        check_stops(&stops)?;
        let d = [end[0] - start[0], end[1] - start[1]];
        let len2 = d[0] * d[0] + d[1] * d[1];
        if !(len2.is_finite() && len2 > 0.0) || start.iter().any(|v| !v.is_finite()) {
            return Err(bad(format!(
                "linear gradient from {start:?} to {end:?} has no direction"
            )));
        }
        let [a, b, c, dd, e, f] = gradient_from_texture;
        // t(g) = (g − start)·d / |d|², g = M p.
        let (u, v) = (d[0] / len2, d[1] / len2);
        let g = [
            a * u + b * v,
            c * u + dd * v,
            (e - start[0]) * u + (f - start[1]) * v,
        ];
        if g.iter().any(|v| !v.is_finite()) {
            return Err(bad("linear gradient is degenerate".into()));
        }
        Gradient::linear_from_parameter(g, stops, spread, interpolation)
    }

    /// A radial (two-point conical) gradient in gradient space: `t = 0` on
    /// the focal circle, `t = 1` on the end circle, and in between the
    /// circles interpolated in centre and radius; a point takes the largest
    /// `t` whose circle passes through it. The focal circle must lie inside
    /// the end circle (SVG 1.1's focal point inside the circle is a focal
    /// circle of radius 0).
    pub fn radial(
        gradient_from_texture: [f64; 6],
        focal: Circle,
        end: Circle,
        stops: Vec<Stop>,
        spread: Spread,
        interpolation: Interpolation,
    ) -> Result<Gradient, Error> {
        let Circle {
            centre: focal,
            radius: focal_radius,
        } = focal;
        let Circle { centre, radius } = end;
        check_map(&gradient_from_texture)?;
        check_stops(&stops)?;
        let dc = (centre[0] - focal[0]).hypot(centre[1] - focal[1]);
        let dr = radius - focal_radius;
        let finite = focal.iter().chain(&centre).all(|v| v.is_finite());
        if !(finite && focal_radius >= 0.0 && dr.is_finite()) || dr - dc <= 1e-9 * radius.abs() {
            return Err(bad(format!(
                "radial gradient: the focal circle ({focal:?}, r {focal_radius}) is not inside the end circle ({centre:?}, r {radius})"
            )));
        }
        let [a, b, c, d, _, _] = gradient_from_texture;
        // The operator norm of the linear part bounds how fast g moves with p.
        let (s, t) = (a * a + b * b + c * c + d * d, (a * d - b * c).powi(2));
        let norm = (0.5 * (s + (s * s - 4.0 * t).max(0.0).sqrt())).sqrt();
        let lipschitz = norm / (dr - dc);
        if !lipschitz.is_finite() {
            return Err(bad("radial gradient is degenerate".into()));
        }
        let kind = Kind::Radial {
            map: gradient_from_texture,
            focal,
            focal_radius,
            centre,
            radius,
            lipschitz,
        };
        Ok(Gradient::assemble(kind, stops, spread, interpolation))
    }

    /// A linear gradient given by its parameter directly:
    /// `t = g[0]·x + g[1]·z + g[2]` in texture space (what
    /// [`Gradient::linear_parameter`] returns, for storage).
    pub fn linear_from_parameter(
        g: [f64; 3],
        stops: Vec<Stop>,
        spread: Spread,
        interpolation: Interpolation,
    ) -> Result<Gradient, Error> {
        check_stops(&stops)?;
        if g.iter().any(|v| !v.is_finite()) {
            return Err(bad(format!(
                "linear gradient parameter {g:?} is not finite"
            )));
        }
        Ok(Gradient::assemble(
            Kind::Linear { g },
            stops,
            spread,
            interpolation,
        ))
    }

    /// For a linear gradient, `g` with `t = g[0]·x + g[1]·z + g[2]`.
    pub fn linear_parameter(&self) -> Option<[f64; 3]> {
        match self.kind {
            Kind::Linear { g } => Some(g),
            Kind::Radial { .. } => None,
        }
    }

    /// The stops, in order.
    pub fn stops(&self) -> &[Stop] {
        &self.stops
    }

    /// How `t` continues beyond `[0,1]`.
    pub fn spread(&self) -> Spread {
        self.spread
    }

    /// The space stop colours are interpolated in.
    pub fn interpolation(&self) -> Interpolation {
        self.interpolation
    }

    /// The gradient of checked parts, its breaks computed from its stops.
    fn assemble(
        kind: Kind,
        stops: Vec<Stop>,
        spread: Spread,
        interpolation: Interpolation,
    ) -> Gradient {
        let mut breaks = vec![0.0, 1.0];
        for (i, s) in stops.iter().enumerate() {
            breaks.push(s.offset);
            if let (Some(next), Interpolation::Srgb) = (stops.get(i + 1), interpolation) {
                for k in 0..3 {
                    let (a, b) = (s.colour[k], next.colour[k]);
                    let w = (0.04045 - a) / (b - a);
                    if w > 0.0 && w < 1.0 {
                        breaks.push(s.offset + w * (next.offset - s.offset));
                    }
                }
            }
        }
        breaks.sort_by(f64::total_cmp);
        breaks.dedup();
        Gradient {
            kind,
            stops,
            spread,
            interpolation,
            breaks,
        }
    }

    /// True when every stop is opaque.
    pub fn is_opaque(&self) -> bool {
        self.stops.iter().all(|s| s.opacity >= 1.0)
    }

    /// True for a linear gradient (whose means are exact).
    pub fn is_linear(&self) -> bool {
        matches!(self.kind, Kind::Linear { .. })
    }

    /// The gradient parameter at texture point `p`.
    pub fn parameter(&self, p: Point) -> f64 {
        match &self.kind {
            Kind::Linear { g } => g[0] * p[0] + g[1] * p[1] + g[2],
            Kind::Radial {
                map,
                focal,
                focal_radius,
                centre,
                radius,
                ..
            } => {
                let q = [
                    map[0] * p[0] + map[2] * p[1] + map[4] - focal[0],
                    map[1] * p[0] + map[3] * p[1] + map[5] - focal[1],
                ];
                let cd = [centre[0] - focal[0], centre[1] - focal[1]];
                let dr = radius - focal_radius;
                // |q − t·cd| = fr + t·dr  ⇔  a t² − 2 b t + c = 0.
                let a = cd[0] * cd[0] + cd[1] * cd[1] - dr * dr;
                let b = q[0] * cd[0] + q[1] * cd[1] + focal_radius * dr;
                let c = q[0] * q[0] + q[1] * q[1] - focal_radius * focal_radius;
                // a < 0 (focal circle inside): one root with fr + t·dr ≥ 0, the larger.
                let disc = (b * b - a * c).max(0.0);
                (b - disc.sqrt()) / a
            }
        }
    }

    /// `t` folded into `[0,1]` by the spread method.
    fn fold(&self, t: f64) -> f64 {
        match self.spread {
            Spread::Pad => t.clamp(0.0, 1.0),
            Spread::Repeat => t - t.floor(),
            Spread::Reflect => {
                let m = t.rem_euclid(2.0);
                if m > 1.0 { 2.0 - m } else { m }
            }
        }
    }

    /// Unpremultiplied colour and opacity at folded `u ∈ [0,1]`, in the
    /// interpolation space.
    fn interpolated(&self, u: f64) -> [f64; 4] {
        let stops = &self.stops;
        let at = |s: &Stop| [s.colour[0], s.colour[1], s.colour[2], s.opacity];
        // The first stop whose offset exceeds u (the later of equal stops holds).
        let i = stops.partition_point(|s| s.offset <= u);
        if i == 0 {
            return at(&stops[0]);
        }
        if i == stops.len() {
            return at(&stops[i - 1]);
        }
        let (s0, s1) = (&stops[i - 1], &stops[i]);
        let w = (u - s0.offset) / (s1.offset - s0.offset);
        let (a, b) = (at(s0), at(s1));
        [0, 1, 2, 3].map(|c| a[c] + (b[c] - a[c]) * w)
    }

    fn to_linear(&self, v: f64) -> f64 {
        match self.interpolation {
            Interpolation::Srgb => srgb_decode(v),
            Interpolation::Linear => v,
        }
    }

    /// Linear premultiplied colour at parameter `t`.
    pub fn colour_at_parameter(&self, t: f64) -> [f64; 4] {
        let c = self.interpolated(self.fold(t));
        let a = c[3];
        [
            self.to_linear(c[0]) * a,
            self.to_linear(c[1]) * a,
            self.to_linear(c[2]) * a,
            a,
        ]
    }

    /// Linear premultiplied colour at texture point `p`.
    pub fn colour_at(&self, p: Point) -> [f64; 4] {
        self.colour_at_parameter(self.parameter(p))
    }

    /// Per channel `[lo, hi]` of the colour over the convex polygon `poly`
    /// (a bound: exact ends for linear gradients, Lipschitz-widened for
    /// radial ones).
    pub fn range_over(&self, poly: &[Point]) -> [[f64; 2]; 4] {
        let (t0, t1) = self.parameter_range(poly);
        self.colour_range(t0, t1)
    }

    fn parameter_range(&self, poly: &[Point]) -> (f64, f64) {
        match &self.kind {
            Kind::Linear { .. } => poly
                .iter()
                .fold((f64::INFINITY, f64::NEG_INFINITY), |r, &p| {
                    let t = self.parameter(p);
                    (r.0.min(t), r.1.max(t))
                }),
            Kind::Radial { lipschitz, .. } => {
                let n = poly.len() as f64;
                let c = poly
                    .iter()
                    .fold([0.0, 0.0], |a, p| [a[0] + p[0] / n, a[1] + p[1] / n]);
                let reach = poly
                    .iter()
                    .map(|p| (p[0] - c[0]).hypot(p[1] - c[1]))
                    .fold(0.0, f64::max);
                let t = self.parameter(c);
                (t - lipschitz * reach, t + lipschitz * reach)
            }
        }
    }

    /// Channel ranges over parameters `[t0, t1]`.
    fn colour_range(&self, t0: f64, t1: f64) -> [[f64; 2]; 4] {
        // Unpremultiplied extremes: each channel is linear between stops, so
        // its extremes over a folded interval are at the ends and the stops.
        let mut lo = [f64::INFINITY; 4];
        let mut hi = [f64::NEG_INFINITY; 4];
        let mut take = |c: [f64; 4]| {
            for k in 0..4 {
                lo[k] = lo[k].min(c[k]);
                hi[k] = hi[k].max(c[k]);
            }
        };
        let mut folded = |a: f64, b: f64| {
            // [a, b] ⊆ [0, 1]
            take(self.interpolated(a));
            take(self.interpolated(b));
            for (i, s) in self.stops.iter().enumerate() {
                if s.offset >= a && s.offset <= b {
                    take(self.interpolated(s.offset));
                    let c = [s.colour[0], s.colour[1], s.colour[2], s.opacity];
                    take(c);
                    // A hard stop: the colour before it holds up to it.
                    if let Some(prev) = i
                        .checked_sub(1)
                        .map(|j| &self.stops[j])
                        .filter(|p| p.offset == s.offset)
                    {
                        take([prev.colour[0], prev.colour[1], prev.colour[2], prev.opacity]);
                    }
                }
            }
        };
        match self.spread {
            Spread::Pad => folded(t0.clamp(0.0, 1.0), t1.clamp(0.0, 1.0)),
            Spread::Repeat | Spread::Reflect if t1 - t0 >= 2.0 || !(t1 - t0).is_finite() => {
                folded(0.0, 1.0)
            }
            _ => {
                // Less than two periods: fold each period's piece.
                let mut k = t0.floor();
                while k <= t1 {
                    let (a, b) = (t0.max(k) - k, t1.min(k + 1.0) - k);
                    if self.spread == Spread::Reflect && k.rem_euclid(2.0) == 1.0 {
                        folded(1.0 - b, 1.0 - a);
                    } else {
                        folded(a, b);
                    }
                    k += 1.0;
                }
            }
        }
        let mut out = [[0.0; 2]; 4];
        for k in 0..3 {
            out[k] = [self.to_linear(lo[k]) * lo[3], self.to_linear(hi[k]) * hi[3]];
        }
        out[3] = [lo[3], hi[3]];
        out
    }

    /// The mean colour over the convex polygon `poly` (counter-clockwise or
    /// clockwise), and a bound on its error (0 for a linear gradient over
    /// at most [`MAX_PERIODS`] periods).
    pub fn mean_over(&self, poly: &[Point]) -> ([f64; 4], f64) {
        let area = polygon_area(poly).abs();
        if poly.len() < 3 || area <= 0.0 {
            let c = poly.first().copied().unwrap_or([0.0, 0.0]);
            return (self.colour_at(c), 0.0);
        }
        match &self.kind {
            Kind::Linear { g } => self.linear_mean(poly, *g, area),
            Kind::Radial { .. } => {
                let mut sum = [0.0; 4];
                for i in 1..poly.len() - 1 {
                    triangle_quadrature(poly[0], poly[i], poly[i + 1], |p, w| {
                        let c = self.colour_at(p);
                        for k in 0..4 {
                            sum[k] += w * c[k];
                        }
                    });
                }
                let range = self.range_over(poly);
                let bound = range.iter().map(|r| r[1] - r[0]).fold(0.0, f64::max);
                (sum.map(|s| s / area), bound)
            }
        }
    }

    fn linear_mean(&self, poly: &[Point], g: [f64; 3], area: f64) -> ([f64; 4], f64) {
        let grad = g[0].hypot(g[1]);
        let (t0, t1) = self.parameter_range(poly);
        if grad == 0.0 || t1 - t0 <= 0.0 {
            return (self.colour_at_parameter(0.5 * (t0 + t1)), 0.0);
        }
        if matches!(self.spread, Spread::Repeat | Spread::Reflect) && t1 - t0 > MAX_PERIODS {
            // Many periods: the period mean, off by at most the range · 2/periods.
            let period = if self.spread == Spread::Repeat {
                1.0
            } else {
                2.0
            };
            let mut sum = [0.0; 4];
            let mut cuts = Vec::new();
            self.cuts(0.0, period, &mut cuts);
            for w in cuts.windows(2) {
                gauss(w[0], w[1], |t, weight| {
                    let c = self.colour_at_parameter(t);
                    for k in 0..4 {
                        sum[k] += weight * c[k];
                    }
                });
            }
            let range = self.colour_range(0.0, period);
            let spread = range.iter().map(|r| r[1] - r[0]).fold(0.0, f64::max);
            return (sum.map(|s| s / period), spread * 2.0 * period / (t1 - t0));
        }
        // Cross-section length along the level line t = u.
        let dir = [-g[1] / grad, g[0] / grad];
        let section = |u: f64| {
            let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
            let n = poly.len();
            for i in 0..n {
                let (a, b) = (poly[i], poly[(i + 1) % n]);
                let (ta, tb) = (self.parameter(a), self.parameter(b));
                if (ta - u) * (tb - u) > 0.0 || ta == tb {
                    continue;
                }
                let w = ((u - ta) / (tb - ta)).clamp(0.0, 1.0);
                let p = [a[0] + w * (b[0] - a[0]), a[1] + w * (b[1] - a[1])];
                let s = (p[0] - poly[0][0]) * dir[0] + (p[1] - poly[0][1]) * dir[1];
                lo = lo.min(s);
                hi = hi.max(s);
            }
            if hi > lo { hi - lo } else { 0.0 }
        };
        let mut cuts: Vec<f64> = poly.iter().map(|&p| self.parameter(p)).collect();
        self.cuts(t0, t1, &mut cuts);
        let (mut sum, mut weight) = ([0.0; 4], 0.0);
        // Every vertex's `t` is a cut, so the cross-section is linear
        // between two cuts: evaluated at their two ends only.
        let mut below = cuts.first().map_or(0.0, |&t| section(t));
        for w in cuts.windows(2) {
            let (a, b) = (w[0], w[1]);
            let above = section(b);
            if b > a {
                let s = (above - below) / (b - a);
                self.integrate_piece(a, b, &|t: f64| below + s * (t - a), &mut sum);
                weight += 0.5 * (below + above) * (b - a);
            }
            below = above;
        }
        // dA = section · dt / |∇t|, so the weight's integral is area·|∇t|;
        // dividing by the same quadrature of it keeps a small polygon's
        // mean exact where rounding of its `t` would not.
        let total = if weight > 0.0 { weight } else { grad * area };
        (sum.map(|s| s / total), 0.0)
    }

    /// Adds `∫ colour(t)·weight(t) dt` over `[a, b]` to `sum`, where
    /// `[a, b]` lies between two cuts (so every interpolated channel is
    /// linear in `t` there) and `weight` is linear. The alpha channel and
    /// linear-light channels are polynomials, integrated exactly by the
    /// Gauss rule; an sRGB channel `((v + 0.055)/1.055)^2.4` is integrated
    /// on sub-pieces over which its base grows at most 1.5-fold, so the
    /// rule's error, governed by the distance to the power's branch point
    /// at base 0, stays near rounding.
    fn integrate_piece(&self, a: f64, b: f64, weight: &impl Fn(f64) -> f64, sum: &mut [f64; 4]) {
        if b <= a {
            return;
        }
        let at = |t: f64| self.interpolated(self.fold(t));
        // Interior samples: at a hard stop the piece's ends belong to other colours.
        let (q1, q3) = (at(a + 0.25 * (b - a)), at(a + 0.75 * (b - a)));
        let ends = |k: usize| {
            let e = (1.5 * q1[k] - 0.5 * q3[k], 1.5 * q3[k] - 0.5 * q1[k]);
            (e.0.clamp(0.0, 1.0), e.1.clamp(0.0, 1.0))
        };
        let lerp = |(va, vb): (f64, f64), t: f64| va + (vb - va) * (t - a) / (b - a);
        let alpha = ends(3);
        // Alpha, and linear-light channels, are cubics in `t` (colour,
        // alpha and weight each linear): two nodes integrate them exactly.
        gauss_2(a, b, |t, w| sum[3] += w * lerp(alpha, t) * weight(t));
        // At most 2 ends and log_1.5(1.055/0.055) < 8 interior splits.
        let mut splits = [0.0; 12];
        for (k, total) in sum.iter_mut().enumerate().take(3) {
            let v = ends(k);
            let mut count = 2;
            splits[..2].copy_from_slice(&[a, b]);
            if self.interpolation == Interpolation::Srgb && v.0.max(v.1) > 0.04045 {
                let (ua, ub) = ((v.0 + 0.055) / 1.055, (v.1 + 0.055) / 1.055);
                // The base is at least 0.055/1.055 (channels are in [0,1]).
                let (lo, hi) = (ua.min(ub).max(0.052), ua.max(ub));
                let mut u = lo * 1.5;
                while u < hi && count < splits.len() {
                    splits[count] = a + (b - a) * (u - ua) / (ub - ua);
                    count += 1;
                    u *= 1.5;
                }
                splits[..count].sort_by(f64::total_cmp);
            }
            let splits = &splits[..count];
            let srgb = self.interpolation == Interpolation::Srgb && v.0.max(v.1) > 0.04045;
            for w in splits.windows(2) {
                let mut add = |t: f64, weight_t: f64| {
                    let c = self.to_linear(lerp(v, t).max(0.0)) * lerp(alpha, t);
                    *total += weight_t * c * weight(t);
                };
                if !srgb {
                    gauss_2(w[0], w[1], add);
                    continue;
                }
                // The power's base over this sub-piece: within 2 %, four
                // nodes leave an error of order 0.01^8 of the integral.
                let base = |t: f64| (lerp(v, t).max(0.0) + 0.055) / 1.055;
                let (b0, b1) = (base(w[0]), base(w[1]));
                if b0.max(b1) <= 1.02 * b0.min(b1) {
                    gauss_4(w[0], w[1], &mut add);
                } else {
                    gauss(w[0], w[1], add);
                }
            }
        }
    }

    /// Appends to `cuts` every parameter in `[t0, t1]` where the colour
    /// function is not smooth (period ends, stops, sRGB branch changes),
    /// plus the ends; sorts and dedups.
    fn cuts(&self, t0: f64, t1: f64, cuts: &mut Vec<f64>) {
        cuts.push(t0);
        cuts.push(t1);
        let breaks = &self.breaks;
        let (first, last) = (t0.floor() as i64, t1.floor() as i64);
        for k in first..=last {
            let base = k as f64;
            for &b in breaks {
                let t = match self.spread {
                    Spread::Pad => {
                        if k != 0 {
                            continue;
                        }
                        b
                    }
                    Spread::Repeat => base + b,
                    Spread::Reflect => {
                        if k.rem_euclid(2) == 0 {
                            base + b
                        } else {
                            base + 1.0 - b
                        }
                    }
                };
                if t > t0 && t < t1 {
                    cuts.push(t);
                }
            }
        }
        cuts.sort_by(f64::total_cmp);
        cuts.retain(|t| *t >= t0 && *t <= t1);
        cuts.dedup();
    }
}

/// Signed (shoelace) area.
fn polygon_area(poly: &[Point]) -> f64 {
    let n = poly.len();
    let Some(&o) = poly.first() else {
        return 0.0;
    };
    // Relative to a vertex: a small polygon far from the origin keeps its
    // digits (absolute products of ~1 would cancel to rounding noise).
    (0..n)
        .map(|i| {
            let (p, q) = (poly[i], poly[(i + 1) % n]);
            (p[0] - o[0]) * (q[1] - o[1]) - (q[0] - o[0]) * (p[1] - o[1])
        })
        .sum::<f64>()
        * 0.5
}

/// 8-point Gauss–Legendre nodes and weights on `[-1, 1]`.
#[allow(clippy::excessive_precision)]
const GAUSS_8: [(f64, f64); 8] = [
    (-0.960_289_856_497_536_3, 0.101_228_536_290_376_26),
    (-0.796_666_477_413_626_7, 0.222_381_034_453_374_47),
    (-0.525_532_409_916_329_0, 0.313_706_645_877_887_3),
    (-0.183_434_642_495_649_8, 0.362_683_783_378_362_0),
    (0.183_434_642_495_649_8, 0.362_683_783_378_362_0),
    (0.525_532_409_916_329_0, 0.313_706_645_877_887_3),
    (0.796_666_477_413_626_7, 0.222_381_034_453_374_47),
    (0.960_289_856_497_536_3, 0.101_228_536_290_376_26),
];

/// Calls `f(t, weight)` at the 8 Gauss–Legendre nodes of `[a, b]`.
fn gauss(a: f64, b: f64, mut f: impl FnMut(f64, f64)) {
    let (m, h) = (0.5 * (a + b), 0.5 * (b - a));
    for (x, w) in GAUSS_8 {
        f(m + h * x, w * h);
    }
}

/// Calls `f(t, weight)` at the 2 Gauss–Legendre nodes of `[a, b]`: exact
/// for cubics.
fn gauss_2(a: f64, b: f64, mut f: impl FnMut(f64, f64)) {
    let (m, h) = (0.5 * (a + b), 0.5 * (b - a));
    let x = h / 3f64.sqrt();
    f(m - x, h);
    f(m + x, h);
}

/// Calls `f(t, weight)` at the 4 Gauss–Legendre nodes of `[a, b]`.
fn gauss_4(a: f64, b: f64, mut f: impl FnMut(f64, f64)) {
    for (x, w) in GAUSS_4 {
        f(a + (b - a) * x, w * (b - a));
    }
}

/// 4-point Gauss–Legendre on `[0, 1]`.
#[allow(clippy::excessive_precision)]
const GAUSS_4: [(f64, f64); 4] = [
    (0.069_431_844_202_973_71, 0.173_927_422_568_726_93),
    (0.330_009_478_207_571_87, 0.326_072_577_431_273_07),
    (0.669_990_521_792_428_1, 0.326_072_577_431_273_07),
    (0.930_568_155_797_026_3, 0.173_927_422_568_726_93),
];

/// Calls `f(p, weight)` at the nodes of a 4×4 Gauss rule on triangle
/// `abc` (the square collapsed onto the triangle; weights sum to its area).
fn triangle_quadrature(a: Point, b: Point, c: Point, mut f: impl FnMut(Point, f64)) {
    let area2 = ((b[0] - a[0]) * (c[1] - a[1]) - (c[0] - a[0]) * (b[1] - a[1])).abs();
    for (u, wu) in GAUSS_4 {
        for (v, wv) in GAUSS_4 {
            // p = a + u·(b − a) + u·v·(c − b); Jacobian area2 · u.
            let p = [
                a[0] + u * (b[0] - a[0]) + u * v * (c[0] - b[0]),
                a[1] + u * (b[1] - a[1]) + u * v * (c[1] - b[1]),
            ];
            f(p, wu * wv * area2 * u);
        }
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    const IDENTITY: [f64; 6] = [1.0, 0.0, 0.0, 1.0, 0.0, 0.0];

    fn stops() -> Vec<Stop> {
        vec![
            Stop {
                offset: 0.0,
                colour: [0.0, 0.2, 1.0],
                opacity: 1.0,
            },
            Stop {
                offset: 0.3,
                colour: [1.0, 0.02, 0.5],
                opacity: 0.6,
            },
            Stop {
                offset: 0.3,
                colour: [0.1, 0.9, 0.0],
                opacity: 0.9,
            },
            Stop {
                offset: 0.8,
                colour: [0.7, 0.7, 0.03],
                opacity: 0.2,
            },
        ]
    }

    /// Composite Simpson over the polygon's bounding box, point in polygon:
    /// the slow obvious mean (for convex polygons, on an `n × n` grid of
    /// cells, each split by sampling `s × s` points).
    fn brute_mean(g: &Gradient, poly: &[Point], n: usize) -> [f64; 4] {
        let (mut x0, mut x1, mut z0, mut z1) = (f64::MAX, f64::MIN, f64::MAX, f64::MIN);
        for p in poly {
            x0 = x0.min(p[0]);
            x1 = x1.max(p[0]);
            z0 = z0.min(p[1]);
            z1 = z1.max(p[1]);
        }
        let inside = |p: Point| {
            let m = poly.len();
            let s = polygon_area(poly).signum();
            (0..m).all(|i| {
                let (a, b) = (poly[i], poly[(i + 1) % m]);
                s * ((b[0] - a[0]) * (p[1] - a[1]) - (b[1] - a[1]) * (p[0] - a[0])) >= 0.0
            })
        };
        let (mut sum, mut count) = ([0.0; 4], 0.0);
        for i in 0..n {
            for j in 0..n {
                let p = [
                    x0 + (x1 - x0) * (i as f64 + 0.5) / n as f64,
                    z0 + (z1 - z0) * (j as f64 + 0.5) / n as f64,
                ];
                if inside(p) {
                    let c = g.colour_at(p);
                    for k in 0..4 {
                        sum[k] += c[k];
                    }
                    count += 1.0;
                }
            }
        }
        sum.map(|s| s / count)
    }

    #[test]
    fn linear_mean_over_a_band_is_the_one_dimensional_integral() {
        // Over the unit square with t = x, the mean is ∫₀¹ colour(t) dt:
        // against composite Simpson with 2^16 intervals per smooth piece.
        for spread in [Spread::Pad, Spread::Repeat, Spread::Reflect] {
            for interpolation in [Interpolation::Srgb, Interpolation::Linear] {
                // t from −0.7 to 2.3 across the square.
                let g = Gradient::linear(
                    [3.0, 0.0, 0.0, 3.0, -0.7, 0.0],
                    [0.0, 0.0],
                    [1.0, 0.0],
                    stops(),
                    spread,
                    interpolation,
                )
                .unwrap();
                let square = [[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]];
                let (mean, bound) = g.mean_over(&square);
                assert_eq!(bound, 0.0);
                let mut cuts = Vec::new();
                g.cuts(-0.7, 2.3, &mut cuts);
                // Compensated (Kahan) sums: 2^16 terms would otherwise lose ~1e-13.
                let (mut want, mut carry) = ([0.0f64; 4], [0.0f64; 4]);
                for w in cuts.windows(2) {
                    let n = 1 << 16;
                    let h = (w[1] - w[0]) / n as f64;
                    for i in 0..=n {
                        let k = if i == 0 || i == n {
                            1.0
                        } else if i % 2 == 1 {
                            4.0
                        } else {
                            2.0
                        };
                        // Just inside the piece: at a hard stop the ends belong to different colours.
                        let t = (w[0] + h * i as f64).clamp(w[0] + 1e-12, w[1] - 1e-12);
                        let c = g.colour_at_parameter(t);
                        for ch in 0..4 {
                            let y = k * h / 3.0 * c[ch] / 3.0 - carry[ch];
                            let t = want[ch] + y;
                            carry[ch] = (t - want[ch]) - y;
                            want[ch] = t;
                        }
                    }
                }
                for ch in 0..4 {
                    assert!(
                        (mean[ch] - want[ch]).abs() < 1e-13,
                        "{spread:?} {interpolation:?} ch {ch}: {} vs {}",
                        mean[ch],
                        want[ch]
                    );
                }
            }
        }
    }

    #[test]
    fn linear_mean_over_polygons_matches_dense_sampling() {
        // A skewed, rotated gradient over a triangle and a quadrilateral.
        let g = Gradient::linear(
            [2.0, 0.7, -0.4, 1.5, 0.1, -0.2],
            [0.1, 0.2],
            [0.9, 1.1],
            stops(),
            Spread::Reflect,
            Interpolation::Srgb,
        )
        .unwrap();
        for poly in [
            vec![[0.1, 0.1], [0.9, 0.3], [0.4, 0.8]],
            vec![[0.2, 0.1], [0.8, 0.2], [0.9, 0.7], [0.3, 0.9]],
        ] {
            let (mean, _) = g.mean_over(&poly);
            let want = brute_mean(&g, &poly, 1500);
            for ch in 0..4 {
                assert!(
                    (mean[ch] - want[ch]).abs() < 1e-4,
                    "ch {ch}: {} vs {}",
                    mean[ch],
                    want[ch]
                );
            }
        }
    }

    #[test]
    fn radial_mean_is_within_its_bound_and_close_to_sampling() {
        let g = Gradient::radial(
            [1.0, 0.0, 0.0, 1.0, 0.0, 0.0],
            Circle {
                centre: [0.45, 0.5],
                radius: 0.05,
            },
            Circle {
                centre: [0.5, 0.5],
                radius: 0.4,
            },
            stops(),
            Spread::Repeat,
            Interpolation::Srgb,
        )
        .unwrap();
        // A small square: the mean is within the stated bound of every
        // sample, and close to the dense mean.
        let sq = [[0.6, 0.6], [0.62, 0.6], [0.62, 0.62], [0.6, 0.62]];
        let (mean, bound) = g.mean_over(&sq);
        let want = brute_mean(&g, &sq, 200);
        let range = g.range_over(&sq);
        for ch in 0..4 {
            assert!((mean[ch] - want[ch]).abs() <= bound + 1e-12);
            assert!((mean[ch] - want[ch]).abs() < 1e-5, "ch {ch}");
            assert!(range[ch][0] <= want[ch] + 1e-12 && want[ch] <= range[ch][1] + 1e-12);
        }
        // The simple radial gradient: t is the distance from the centre / r.
        let simple = Gradient::radial(
            IDENTITY,
            Circle {
                centre: [0.5, 0.5],
                radius: 0.0,
            },
            Circle {
                centre: [0.5, 0.5],
                radius: 0.25,
            },
            stops(),
            Spread::Pad,
            Interpolation::Linear,
        )
        .unwrap();
        assert!((simple.parameter([0.5, 0.75]) - 1.0).abs() < 1e-12);
        assert!((simple.parameter([0.6, 0.5]) - 0.4).abs() < 1e-12);
    }

    #[test]
    fn ranges_contain_every_sampled_colour() {
        for spread in [Spread::Pad, Spread::Repeat, Spread::Reflect] {
            let lin = Gradient::linear(
                [1.0, 0.3, 0.2, 1.0, 0.0, 0.0],
                [0.2, 0.1],
                [0.6, 0.5],
                stops(),
                spread,
                Interpolation::Srgb,
            )
            .unwrap();
            let rad = Gradient::radial(
                [2.0, 0.0, 0.5, 1.0, -0.5, 0.0],
                Circle {
                    centre: [0.4, 0.5],
                    radius: 0.0,
                },
                Circle {
                    centre: [0.5, 0.5],
                    radius: 0.3,
                },
                stops(),
                spread,
                Interpolation::Srgb,
            )
            .unwrap();
            for g in [&lin, &rad] {
                for (x0, z0, side) in [(0.1, 0.2, 0.3), (0.5, 0.5, 0.05), (0.0, 0.0, 1.0)] {
                    let sq = [
                        [x0, z0],
                        [x0 + side, z0],
                        [x0 + side, z0 + side],
                        [x0, z0 + side],
                    ];
                    let r = g.range_over(&sq);
                    for i in 0..=40 {
                        for j in 0..=40 {
                            let p = [x0 + side * i as f64 / 40.0, z0 + side * j as f64 / 40.0];
                            let c = g.colour_at(p);
                            for ch in 0..4 {
                                assert!(
                                    r[ch][0] - 1e-12 <= c[ch] && c[ch] <= r[ch][1] + 1e-12,
                                    "{spread:?} {p:?} ch {ch}: {} not in {:?}",
                                    c[ch],
                                    r[ch]
                                );
                            }
                        }
                    }
                }
            }
        }
    }

    #[test]
    fn bad_gradients_are_refused() {
        let ok = stops();
        assert!(
            Gradient::linear(
                IDENTITY,
                [0.0, 0.0],
                [0.0, 0.0],
                ok.clone(),
                Spread::Pad,
                Interpolation::Srgb
            )
            .is_err()
        );
        assert!(
            Gradient::linear(
                IDENTITY,
                [0.0, 0.0],
                [1.0, 0.0],
                vec![],
                Spread::Pad,
                Interpolation::Srgb
            )
            .is_err()
        );
        let mut backwards = ok.clone();
        backwards.swap(0, 3);
        assert!(
            Gradient::linear(
                IDENTITY,
                [0.0, 0.0],
                [1.0, 0.0],
                backwards,
                Spread::Pad,
                Interpolation::Srgb
            )
            .is_err()
        );
        let nan = [f64::NAN, 0.0, 0.0, 1.0, 0.0, 0.0];
        assert!(
            Gradient::linear(
                nan,
                [0.0, 0.0],
                [1.0, 0.0],
                ok.clone(),
                Spread::Pad,
                Interpolation::Srgb
            )
            .is_err()
        );
        // Focal circle outside the end circle.
        assert!(
            Gradient::radial(
                IDENTITY,
                Circle {
                    centre: [0.9, 0.5],
                    radius: 0.0
                },
                Circle {
                    centre: [0.5, 0.5],
                    radius: 0.3
                },
                ok,
                Spread::Pad,
                Interpolation::Srgb
            )
            .is_err()
        );
    }
}
