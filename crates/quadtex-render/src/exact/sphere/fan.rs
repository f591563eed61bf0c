//! Polar fans ([`PolarFans`]): a sphere's texture squares that touch a
//! pole, seen in the coordinates of the pole's tangent plane, where they
//! are wedges with straight sides through the pole.
//!
//! **Pole coordinates.** For the sphere's outward unit normal `n` (its UV is
//! `u = (atan2(n.z, n.x) + π)/2π`, `v = 1 − acos(n.y)/π`), a fan reads the
//! point at `(x, z) = (½ + n.x/2R, ½ + n.z/2R)`: the normal's orthographic
//! image on the pole's tangent plane, scaled so that the fan, the
//! latitudes within `reach` of the pole (colatitude `π·reach`, radius
//! `R = sin(π·reach)`), is the disc of radius ½ about `(½, ½)`. The map
//! from the screen to these coordinates is smooth at the pole (the UV
//! map's longitude turns around the pole's image, and no straight-edged
//! piece fits it; algorithm.md §8), and a texture square `[u0, u1] × [v, 1]`
//! touching the (north) pole is there the wedge between the rays at angles
//! `2πu0 − π` and `2πu1 − π`, out to its other latitude.
//!
//! **The fan.** The squares touching the pole (terminal nodes and texels,
//! their exact means, through the surface's UV transform and wrap), out to
//! the nearest latitude where one ends (`reach`): a piece whose image lies
//! within it is integrated exactly as the wedges' flat colours over the
//! piece clipped to each wedge's two sides (straight lines on the screen
//! too, under the piece's projective map).
//!
//! **Bands.** Beyond the fan, out to a colatitude of 45°, the squares
//! between consecutive latitudes where squares end are annular sectors
//! whose sides are the same lines through the pole: a piece the sphere's
//! UV cannot fit there (its outline near the pole) but the pole's
//! coordinates can, whose image lies within one band, is integrated on
//! that band's wedges the same way. Fans are drawn where that is
//! exact and small: no rotation in the UV transform, no gradient or
//! contour leaves in the texture, at most [`MAX_FAN_WEDGES`] wedges, of a
//! texture of at most [`MAX_TEXTURE_CELLS`] cells.

use std::sync::Arc;

use quadtex_core::{QuadTree, Rgba, Wrap, WrapMode};

use crate::math::Vec3;
use crate::scene::UvTransform;

/// The widest reach of a fan (of `v`'s unit range, from the pole).
const WIDEST_REACH: f64 = 1.0 / 8.0;

/// How far from a pole (in `v`) its coordinates serve beyond the fan:
/// pieces there whose image lies within one band of texture squares are
/// integrated on that band's wedges (a colatitude of 45°).
const CHART_REACH: f64 = 0.25;

/// Texture squares within [`CHART_REACH`] of a pole, at most, for its
/// bands beyond the fan to be drawn.
const MAX_BAND_SQUARES: usize = 8192;

/// Wedges a fan holds at most.
const MAX_FAN_WEDGES: usize = 4096;

/// Cells of the texture's finest grid at most for its fans to be drawn:
/// every square of the texture is looked at once, about 10 ms for 1024²
/// (a 4096² photograph's 16 M took 0.2 s of its sphere's first frame and
/// changed no pixel of it).
const MAX_TEXTURE_CELLS: u64 = 1 << 20;

/// Tiles of the texture the widest reach may cross along each axis.
const MAX_TILES: i64 = 64;

/// One pole's fan (module doc).
#[derive(Debug)]
pub(crate) struct PolarFan {
    /// `v` at the pole: 1 (north, `+y`) or 0 (south).
    pole_v: f64,
    /// How far from the pole (in `v`) every wedge reaches.
    reach: f64,
    /// `R = sin(π·reach)`: pole coordinates are `½ + (n.x, n.z)/2R`.
    extent: f64,
    /// The wedges `(from, to, colour)`, angles about `(½, ½)` in pole
    /// coordinates, `from < to ≤ from + π/2`, in order, covering `[−π, π]`.
    wedges: Vec<Wedge>,
    /// Beyond the fan, out to [`CHART_REACH`]: bands `[near, far)` of
    /// distance from the pole (in `v`) within which every longitude has
    /// one texture square, with their wedges as the fan's (annular sectors
    /// there, whose sides are the same straight lines through the pole).
    bands: Vec<Band>,
}

/// A wedge `(from, to, colour)`: angles about `(½, ½)` in pole coordinates.
pub(crate) type Wedge = (f64, f64, Rgba);

/// A band of texture squares around a pole beyond its fan.
#[derive(Debug)]
struct Band {
    near: f64,
    far: f64,
    wedges: Vec<Wedge>,
}

impl PolarFan {
    /// Whether UV point `uv` lies within the fan's reach.
    pub(crate) fn holds(&self, uv: [f64; 2]) -> bool {
        (uv[1] - self.pole_v).abs() < self.reach
    }

    /// The point in pole coordinates of the sphere's outward unit normal `n`.
    pub(crate) fn point(&self, n: Vec3) -> [f64; 2] {
        let scale = 0.5 / self.extent;
        [0.5 + n.x * scale, 0.5 + n.z * scale]
    }

    /// Whether the fan holds every point of the box `(lo, hi)` of pole
    /// coordinates (the disc of radius ½ about `(½, ½)`).
    pub(crate) fn holds_box(&self, (lo, hi): ([f64; 2], [f64; 2])) -> bool {
        let far = |a: f64, b: f64| (a - 0.5).abs().max((b - 0.5).abs());
        let (dx, dz) = (far(lo[0], hi[0]), far(lo[1], hi[1]));
        dx * dx + dz * dz < 0.25
    }

    /// The fan's wedges.
    pub(crate) fn wedges(&self) -> &[Wedge] {
        &self.wedges
    }

    /// The wedges that may meet a polygon of pole coordinates with
    /// `vertices` (all of them when it holds the pole).
    #[cfg(test)]
    pub(crate) fn wedges_meeting(&self, vertices: &[[f64; 2]]) -> &[Wedge] {
        meeting(&self.wedges, vertices)
    }

    /// Whether UV point `uv` lies within [`CHART_REACH`] of the pole.
    pub(crate) fn near(&self, uv: [f64; 2]) -> bool {
        (uv[1] - self.pole_v).abs() < CHART_REACH
    }

    /// The wedges of the band beyond the fan that holds every point of
    /// the box `(lo, hi)` of pole coordinates, if one does: the box's
    /// radii (its nearest point to the pole and its farthest corner) read
    /// as distances from the pole in `v`. `None` also where the box holds
    /// the pole or reaches past a colatitude of about 64° (`r = 0.9`,
    /// where `sin` nears its turn).
    pub(crate) fn band_holding(&self, (lo, hi): ([f64; 2], [f64; 2])) -> Option<&[Wedge]> {
        let normal = |c: f64| (c - 0.5) * 2.0 * self.extent;
        let (x, z) = (
            [normal(lo[0]), normal(hi[0])],
            [normal(lo[1]), normal(hi[1])],
        );
        let nearest = |a: [f64; 2]| {
            if a[0] <= 0.0 && 0.0 <= a[1] {
                0.0
            } else {
                a[0].abs().min(a[1].abs())
            }
        };
        let farthest = |a: [f64; 2]| a[0].abs().max(a[1].abs());
        let (r_min, r_max) = (nearest(x).hypot(nearest(z)), farthest(x).hypot(farthest(z)));
        if r_min == 0.0 || r_max.is_nan() || r_max >= 0.9 {
            return None;
        }
        let pi = std::f64::consts::PI;
        let (near, far) = (r_min.asin() / pi, r_max.asin() / pi);
        let band = self.bands.iter().find(|b| b.near <= near && far <= b.far)?;
        Some(&band.wedges)
    }
}

/// The wedges of `wedges` (in order, covering the turn) that may meet a
/// polygon of pole coordinates with `vertices` (all of them when it holds
/// the pole).
pub(crate) fn meeting<'w>(wedges: &'w [Wedge], vertices: &[[f64; 2]]) -> &'w [Wedge] {
    use std::f64::consts::PI;
    let n = vertices.len();
    if n < 3 {
        return &[];
    }
    let cross = |i: usize| {
        let (a, b) = (vertices[i], vertices[(i + 1) % n]);
        (b[0] - a[0]) * (0.5 - a[1]) - (b[1] - a[1]) * (0.5 - a[0])
    };
    let first = cross(0);
    let holds_pole = (0..n).all(|i| cross(i) * first >= 0.0 && cross(i) != 0.0);
    if holds_pole || vertices.iter().any(|p| p[0] == 0.5 && p[1] == 0.5) {
        return wedges;
    }
    let angles: Vec<[f64; 2]> = vertices.iter().map(|p| [p[0] - 0.5, p[1] - 0.5]).collect();
    let (from, span) = super::angles_seen(&angles);
    if span.is_nan() || span >= PI {
        return wedges;
    }
    // The wedges over [from, from + span], which may wrap past π.
    let (lo, hi) = (from, from + span);
    let (lo, hi) = if lo < -PI {
        (lo + 2.0 * PI, hi + 2.0 * PI)
    } else {
        (lo, hi)
    };
    if hi > PI {
        return wedges;
    }
    let start = wedges.partition_point(|w| w.1 <= lo);
    let end = wedges.partition_point(|w| w.0 < hi);
    &wedges[start..end.max(start)]
}

/// A sphere's fans, for one texture under one UV transform and wrap
/// ([`crate::scene::SceneTexture`] keeps them); `None` where a fan is not
/// drawn (module doc).
#[derive(Debug, Default)]
pub(crate) struct PolarFans {
    pub(crate) north: Option<PolarFan>,
    pub(crate) south: Option<PolarFan>,
}

impl PolarFans {
    /// The fans of `tree` on a sphere whose UV goes to texture space by
    /// `uv` and reads it under `wrap`.
    pub(crate) fn new(tree: &Arc<QuadTree>, uv: &UvTransform, wrap: Wrap) -> PolarFans {
        let drawable = uv.rotation_degrees == 0.0
            && uv.scale.iter().chain(&uv.offset).all(|v| v.is_finite())
            && uv.scale.iter().all(|&s| s != 0.0)
            && tree.contour_leaves().is_none()
            && tree.gradient_leaves().is_none();
        let [columns, rows] = tree.finest_grid();
        if !drawable || columns.saturating_mul(rows) > MAX_TEXTURE_CELLS {
            return PolarFans::default();
        }
        // Only the squares within the charts' reach of a pole are kept:
        // the rows of the unit texture each pole's strip `v ∈ [0, ¼]` or
        // `[¾, 1]` falls on when tiles repeat (all rows otherwise, or when
        // the strip spans a whole tile).
        let mut pole_rows: Vec<[f64; 2]> = Vec::new();
        for (a, b) in [(0.0, CHART_REACH), (1.0 - CHART_REACH, 1.0)] {
            let (za, zb) = (
                uv.scale[1] * a + uv.offset[1],
                uv.scale[1] * b + uv.offset[1],
            );
            let (lo, hi) = (za.min(zb), za.max(zb));
            if wrap.z() != WrapMode::Repeat || hi - lo >= 1.0 {
                pole_rows.push([0.0, 1.0]);
                continue;
            }
            let (flo, fhi) = (lo - lo.floor(), hi - lo.floor());
            if fhi <= 1.0 {
                pole_rows.push([flo, fhi]);
            } else {
                pole_rows.extend([[flo, 1.0], [0.0, fhi - 1.0]]);
            }
        }
        let scale = tree.aspect().scale();
        let mut squares = Vec::new();
        tree.for_each_leaf(tree.depth(), |level, ix, iz, colour| {
            let side = (-f64::from(level)).exp2();
            let x = [ix, ix + 1].map(|i| (f64::from(i) * side / scale[0]).min(1.0));
            let z = [iz, iz + 1].map(|i| (f64::from(i) * side / scale[1]).min(1.0));
            let on_a_pole_row = pole_rows.iter().any(|r| z[0] <= r[1] && r[0] <= z[1]);
            if x[0] < x[1] && z[0] < z[1] && on_a_pole_row {
                squares.push(([x[0], x[1], z[0], z[1]], colour));
            }
        });
        PolarFans {
            north: fan(&squares, uv, wrap, 1.0),
            south: fan(&squares, uv, wrap, 0.0),
        }
    }
}

/// Where tile `tile` along an axis under `mode` puts `[a, b)` of the unit
/// texture; `None` where the axis has no such tile (clamp and border
/// beyond the unit square, where a fan is not drawn).
fn in_tile(mode: WrapMode, tile: i64, [a, b]: [f64; 2]) -> Option<[f64; 2]> {
    let t = tile as f64;
    match mode {
        WrapMode::Repeat => Some([t + a, t + b]),
        WrapMode::Mirror if tile.rem_euclid(2) == 1 => Some([t + 1.0 - b, t + 1.0 - a]),
        WrapMode::Mirror => Some([t + a, t + b]),
        WrapMode::Clamp | WrapMode::Border => (tile == 0).then_some([a, b]),
    }
}

/// The fan of the pole at `pole_v` from the texture's `squares`
/// (`[x0, x1, z0, z1]` in texture space, exact mean colour).
fn fan(
    squares: &[([f64; 4], [f64; 4])],
    uv: &UvTransform,
    wrap: Wrap,
    pole_v: f64,
) -> Option<PolarFan> {
    use std::f64::consts::PI;
    // The widest reach's texture box, and the tiles it crosses.
    let to_texture = |u: f64, v: f64| {
        [
            uv.scale[0] * u + uv.offset[0],
            uv.scale[1] * v + uv.offset[1],
        ]
    };
    let far_v = if pole_v == 1.0 {
        1.0 - CHART_REACH
    } else {
        CHART_REACH
    };
    let (p, q) = (to_texture(0.0, pole_v), to_texture(1.0, far_v));
    let tiles = |a: f64, b: f64| {
        let lo = a.min(b).floor() as i64;
        let hi = (a.max(b).ceil() as i64 - 1).max(lo);
        (hi - lo < MAX_TILES).then_some(lo..=hi)
    };
    let (columns, rows) = (tiles(p[0], q[0])?, tiles(p[1], q[1])?);
    // The squares touching the pole: their longitudes and how far from
    // the pole they reach.
    let mut touching = Vec::new();
    let mut beyond = Vec::new();
    let mut reach = WIDEST_REACH;
    for i in columns {
        for j in rows.clone() {
            for &([x0, x1, z0, z1], colour) in squares {
                let (Some(x), Some(z)) = (
                    in_tile(wrap.x(), i, [x0, x1]),
                    in_tile(wrap.z(), j, [z0, z1]),
                ) else {
                    // The reach crosses a clamped or bordered edge.
                    return None;
                };
                let us = x.map(|x| (x - uv.offset[0]) / uv.scale[0]);
                let vs = z.map(|z| (z - uv.offset[1]) / uv.scale[1]);
                let (u0, u1) = (us[0].min(us[1]).max(0.0), us[0].max(us[1]).min(1.0));
                let (v0, v1) = (vs[0].min(vs[1]), vs[0].max(vs[1]));
                let (from, to) = if pole_v == 1.0 {
                    (1.0 - v1, 1.0 - v0)
                } else {
                    (v0, v1)
                };
                if u0 < u1 && from <= 0.0 && to > 0.0 {
                    reach = reach.min(to);
                    touching.push((u0, u1, colour));
                } else if u0 < u1 && from > 0.0 && from < CHART_REACH {
                    beyond.push((from, to, [u0, u1], colour));
                }
            }
        }
    }
    touching.sort_by(|a, b| a.0.total_cmp(&b.0));
    // They must cover every longitude once.
    let mut at = 0.0;
    for &(u0, u1, _) in &touching {
        if u0 != at {
            return None;
        }
        at = u1;
    }
    if at != 1.0 || touching.len() > MAX_FAN_WEDGES {
        return None;
    }
    let wedges = as_wedges(&touching);
    let bands = if beyond.len() <= MAX_BAND_SQUARES {
        bands_beyond(&beyond, reach)
    } else {
        Vec::new()
    };
    Some(PolarFan {
        pole_v,
        reach,
        extent: (PI * reach).sin(),
        wedges,
        bands,
    })
}

/// Wedges of at most a quarter turn (each then the meet of two
/// half-planes) from squares `(u0, u1, colour)` in order of `u0`.
fn as_wedges(squares: &[(f64, f64, [f64; 4])]) -> Vec<Wedge> {
    use std::f64::consts::{FRAC_PI_2, PI, TAU};
    let mut wedges = Vec::with_capacity(squares.len());
    for &(u0, u1, colour) in squares {
        let c = colour.map(|v| v as f32);
        let colour = Rgba::new(c[0], c[1], c[2], c[3]);
        let (a0, a1) = (TAU * u0 - PI, TAU * u1 - PI);
        let parts = ((a1 - a0) / FRAC_PI_2).ceil().max(1.0);
        for k in 0..parts as usize {
            let from = a0 + (a1 - a0) * k as f64 / parts;
            let to = if k + 1 == parts as usize {
                a1
            } else {
                a0 + (a1 - a0) * (k + 1) as f64 / parts
            };
            wedges.push((from, to, colour));
        }
    }
    wedges
}

/// The bands beyond the fan (which ends at `reach`) out to
/// [`CHART_REACH`], from the squares `(from, to, [u0, u1], colour)` there
/// (distances from the pole in `v`): between consecutive ends of squares,
/// each longitude's square, as long as they cover the turn once (the
/// bands stop at the first that does not).
fn bands_beyond(squares: &[(f64, f64, [f64; 2], [f64; 4])], reach: f64) -> Vec<Band> {
    let mut ends: Vec<f64> = squares
        .iter()
        .flat_map(|s| [s.0, s.1])
        .chain([reach])
        .filter(|&d| d >= reach && d <= CHART_REACH)
        .collect();
    ends.sort_by(f64::total_cmp);
    ends.dedup();
    let mut bands = Vec::new();
    for pair in ends.windows(2) {
        let (near, far) = (pair[0], pair[1]);
        let mut row: Vec<(f64, f64, [f64; 4])> = squares
            .iter()
            .filter(|s| s.0 <= near && s.1 >= far)
            .map(|s| (s.2[0], s.2[1], s.3))
            .collect();
        row.sort_by(|a, b| a.0.total_cmp(&b.0));
        let mut at = 0.0;
        let covered = row.iter().all(|&(u0, u1, _)| {
            let next = u0 == at;
            at = u1;
            next
        }) && at == 1.0;
        if !covered || row.len() > MAX_FAN_WEDGES {
            break;
        }
        bands.push(Band {
            near,
            far,
            wedges: as_wedges(&row),
        });
    }
    bands
}

#[cfg(test)]
mod tests {
    use super::*;
    use quadtex_core::{BuildOptions, ConvexPolygon, synth};

    /// The built-in 2 × 2 checker's tree.
    fn checker() -> Arc<QuadTree> {
        let grid = synth::checkerboard(2, 2).unwrap();
        Arc::new(
            QuadTree::from_texels(&grid, &BuildOptions::default())
                .unwrap()
                .0,
        )
    }

    fn scaled(u: f64, v: f64) -> UvTransform {
        UvTransform {
            scale: [u, v],
            ..UvTransform::default()
        }
    }

    /// The checker 8 × 8 around and along: each pole touches 16 cells,
    /// alternating, out to a sixteenth of the latitudes; the wedges tile
    /// the turn in order.
    #[test]
    fn the_checkered_ball_has_a_fan_of_sixteen_wedges_at_each_pole() {
        let fans = PolarFans::new(&checker(), &scaled(8.0, 8.0), Wrap::REPEAT);
        for fan in [fans.north.unwrap(), fans.south.unwrap()] {
            assert_eq!(fan.wedges.len(), 16);
            assert_eq!(fan.reach, 1.0 / 16.0);
            let mut at = -std::f64::consts::PI;
            for (i, &(from, to, c)) in fan.wedges.iter().enumerate() {
                assert!((from - at).abs() < 1e-12 && to > from, "{i}: {from} {to}");
                at = to;
                let next = fan.wedges[(i + 1) % 16].2;
                assert_ne!(c, next, "neighbours alternate");
            }
            assert!((at - std::f64::consts::PI).abs() < 1e-12);
        }
        // Halves at the pole (u scale 1): each wedge at most a quarter turn.
        let fans = PolarFans::new(&checker(), &scaled(1.0, 8.0), Wrap::REPEAT);
        let north = fans.north.unwrap();
        assert_eq!(north.wedges.len(), 4);
        assert!(
            north
                .wedges
                .iter()
                .all(|w| w.1 - w.0 <= std::f64::consts::FRAC_PI_2 + 1e-12)
        );
    }

    /// Beyond the fan, bands: the checker 8 × 4 has its fan out to an
    /// eighth of the latitudes and one band from there to a quarter, its
    /// 16 wedges alternating and each the colour of the fan's wedge
    /// across the band's boundary's opposite (the checker flips there);
    /// a box of pole coordinates within the band finds it, one reaching
    /// into the fan or over the pole does not.
    #[test]
    fn bands_beyond_the_fan_hold_the_next_squares() {
        let fans = PolarFans::new(&checker(), &scaled(8.0, 4.0), Wrap::REPEAT);
        let north = fans.north.unwrap();
        assert_eq!(north.reach, 1.0 / 8.0);
        assert_eq!(north.bands.len(), 1);
        let band = &north.bands[0];
        assert_eq!((band.near, band.far), (1.0 / 8.0, 1.0 / 4.0));
        assert_eq!(band.wedges.len(), 16);
        for (fan_wedge, band_wedge) in north.wedges.iter().zip(&band.wedges) {
            assert_eq!((fan_wedge.0, fan_wedge.1), (band_wedge.0, band_wedge.1));
            assert_ne!(
                fan_wedge.2, band_wedge.2,
                "the checker flips across the band's edge"
            );
        }
        // Pole coordinates of the point at colatitude `c` (in v) and angle 0.3.
        let at = |c: f64| {
            let r = (std::f64::consts::PI * c).sin();
            north.point(Vec3::new(r * 0.3f64.cos(), 0.0, r * 0.3f64.sin()))
        };
        let boxed = |a: [f64; 2], b: [f64; 2]| {
            (
                [a[0].min(b[0]), a[1].min(b[1])],
                [a[0].max(b[0]), a[1].max(b[1])],
            )
        };
        assert!(north.band_holding(boxed(at(0.15), at(0.2))).is_some());
        assert!(north.band_holding(boxed(at(0.1), at(0.2))).is_none());
        assert!(north.band_holding(([0.4, 0.4], [0.6, 0.6])).is_none());
    }

    /// Where a fan would not be exact, there is none: a rotated UV, a
    /// reach beyond a clamped edge. Within the unit square clamp is fine,
    /// and mirrored tiles are fans too.
    #[test]
    fn fans_are_drawn_only_where_exact() {
        let tree = checker();
        let rotated = UvTransform {
            rotation_degrees: 30.0,
            ..scaled(8.0, 8.0)
        };
        assert!(
            PolarFans::new(&tree, &rotated, Wrap::REPEAT)
                .north
                .is_none()
        );
        assert!(
            PolarFans::new(&tree, &scaled(8.0, 8.0), Wrap::CLAMP)
                .north
                .is_none()
        );
        assert!(
            PolarFans::new(&tree, &scaled(1.0, 1.0), Wrap::CLAMP)
                .north
                .is_some()
        );
        let mirrored = PolarFans::new(&tree, &scaled(3.0, 8.0), Wrap::MIRROR);
        assert_eq!(mirrored.south.unwrap().wedges.len(), 6);
    }

    /// The wedges a polygon may meet hold every wedge it does meet: for
    /// random polygons near and around the pole, the wedges left out clip
    /// it to nothing.
    #[test]
    fn wedges_meeting_a_polygon_leave_none_out() {
        let fans = PolarFans::new(&checker(), &scaled(8.0, 8.0), Wrap::REPEAT);
        let fan = fans.north.unwrap();
        let mut seed = 0x2545_f491_4f6c_dd1d_u64;
        let mut next = || {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            (seed >> 11) as f64 / (1u64 << 53) as f64
        };
        let left_of = |angle: f64| {
            let (sn, cs) = f64::sin_cos(angle);
            [-sn, cs, 0.5 * (sn - cs)]
        };
        let mut held = 0;
        for _ in 0..2000 {
            let (cx, cz, r) = (
                0.5 + 0.4 * (next() - 0.5),
                0.5 + 0.4 * (next() - 0.5),
                0.2 * next(),
            );
            let turn = next() * std::f64::consts::TAU;
            let corners: Vec<[f64; 2]> = (0..5)
                .map(|k| {
                    let a = turn + std::f64::consts::TAU * f64::from(k) / 5.0;
                    [cx + r * a.cos(), cz + r * a.sin()]
                })
                .collect();
            let Ok(polygon) = ConvexPolygon::new(&corners) else {
                continue;
            };
            let meeting = fan.wedges_meeting(polygon.vertices());
            if meeting.len() == fan.wedges.len() {
                held += 1;
            }
            for w in &fan.wedges {
                if meeting.iter().any(|m| m.0 == w.0) {
                    continue;
                }
                let part = polygon.clip_lines([left_of(w.0), left_of(w.1).map(|v| -v)]);
                assert!(
                    part.area().abs() < 1e-15,
                    "{corners:?}: wedge {w:?} left out"
                );
            }
        }
        assert!(held > 0 && held < 2000, "{held}");
    }
}
