//! The pieces a sphere's region is integrated over ([`SphereView::shade`]):
//! squares over most of the disc ([`Square`]), rings of trapezoids along
//! the outline ([`Ring`]), each on a projective map fitted to the sphere's
//! UV and checked against it (the method: [`super`]'s doc).

use quadtex_core::{ConvexPolygon, Projection};

use crate::frame::lambert;
use crate::scene::Lighting;
use crate::stats::PixelStats;

use super::super::lighting::{Shading, apply_light};
use super::fan::{PolarFan, Wedge, meeting};

use super::arcs::UvBox;
use super::edges::BoxTexture;
use super::{Chords, SphereView};

/// The rings along the outline are spaced for a quarter of the default
/// error bound (pixels), the model's error being an estimate: with another
/// bound the rings are the same and the pieces are checked against it
/// (none of the checkered ball's failed at 1/512).
const RING_TOLERANCE: f64 = 1.0 / 512.0 / 4.0;

/// Deepest split of a sphere's region below its bounding square.
pub(super) const MAX_SPLITS: u32 = 10;

/// One row of [`HALF_PIXEL_UV`]: its tag `(view stamp, 2y)` and the UV
/// by column `2x`, where computed.
type GridRow = ((u64, u32), Vec<Option<[f64; 2]>>);

thread_local! {
    /// The sphere's UV at half-pixel grid points a thread computed lately:
    /// four rows of the grid (row `2y` in slot `2y mod 4`), each tagged with
    /// the view's stamp and its row, by column `2x`.
    static HALF_PIXEL_UV: std::cell::RefCell<[GridRow; 4]> = std::cell::RefCell::default();
}

/// Pieces a sphere's pixel may look at per square of the filter options'
/// budget (the renderer's 64: 1024 pieces). The checkered ball needs at
/// most that many at every pixel, and so does the runway's beacon, whose
/// pole is in view, since the poles have fans and bands
/// ([`super::fan`]).
const PIECES_PER_SQUARE: u64 = 16;

/// What a sphere's pixel may still spend ([`SphereView::shade`]): weight
/// that pieces still off the map's tolerance may take whole into the
/// bound (each at most an eighth of what is left), and pieces to look at
/// ([`PIECES_PER_SQUARE`] times the filter options' square budget per
/// pixel of the support; none without one): once they are spent, each piece left is integrated on its
/// fit as it stands, its weight in the bound where the fit is off (the
/// pixel then counts as above the target, as where squares run out).
struct Budget {
    weight: f64,
    pieces: u64,
    /// Whether a piece one texture edge crosses may be split along the
    /// edge's image ([`SphereView::two_colours`]) instead of cut further
    /// (not in the squares the tests check that against).
    edges_parted: bool,
}

/// A box `(lo, hi)` of the coordinates a fit maps to
/// ([`SphereView::image_box`]).
type ImageBox = ([f64; 2], [f64; 2]);

/// The sphere's UV at the midpoint of ray `e` between rings `a` and `b`,
/// by `(a, b, e)` ([`Ring::trapezoid_error`]).
type RayMiddle = ((usize, usize, usize), [f64; 2]);

/// One chord's sector of the rings along the outline
/// ([`SphereView::shade_ring`]).
struct Ring<'a> {
    chords: &'a Chords,
    radii: &'a [f64],
    chord: usize,
    /// The screen point and the sphere's UV at ring `k`'s chord end `e`,
    /// at `k·(chords + 1) + e`, where computed.
    corners: &'a mut Vec<Option<([f64; 2], [f64; 2])>>,
    /// The sphere's UV at the midpoint of ring `k`'s chord `j`, at
    /// `k·chords + j`, where computed.
    chord_middles: &'a mut Vec<Option<[f64; 2]>>,
    /// The sphere's UV at the midpoint of ray `e` between rings `a` and
    /// `b`, by `(a, b, e)`, where computed (shared by the sectors on
    /// either side).
    ray_middles: &'a mut Vec<RayMiddle>,
    /// Whether the region lies within the chords the sectors span (the
    /// support the region was cut from, the pixel's or a quarter of it,
    /// was clipped by them): then the first ring's pieces lie within their
    /// trapezoids, not between a chord and the outline.
    within_chords: bool,
}

impl Ring<'_> {
    /// The screen point and UV at ring `k` on the chords' end `e`.
    fn corner(&mut self, view: &SphereView, k: usize, e: usize) -> ([f64; 2], [f64; 2]) {
        let index = k * (self.chords.count + 1) + e;
        if let Some(found) = self.corners[index] {
            return found;
        }
        let theta = self.chords.from + self.chords.delta * e as f64;
        let (sn, cs) = theta.sin_cos();
        let r = self.radii[k];
        let s = [
            view.outline.e0[0] + r * (view.outline.ea[0] * cs + view.outline.eb[0] * sn),
            view.outline.e0[1] + r * (view.outline.ea[1] * cs + view.outline.eb[1] * sn),
        ];
        let found = (s, view.sphere_uv(s));
        self.corners[index] = Some(found);
        found
    }

    /// The largest error of `fit` (through the four corners of the
    /// trapezoid between rings `a` and `b` of this sector) at the
    /// trapezoid's check points, as [`SphereView::map_error`] measures it:
    /// its centre (the corners' mean) and its sides' midpoints, those on
    /// the rays and chords shared with the neighbouring trapezoids.
    fn trapezoid_error(
        &mut self,
        view: &SphereView,
        fit: &[[f64; 3]; 3],
        (a, b): (usize, usize),
    ) -> (f64, f64) {
        let j = self.chord;
        let [p, q, r, t] =
            [(a, j), (a, j + 1), (b, j + 1), (b, j)].map(|(k, e)| self.corner(view, k, e).0);
        let middle = |x: [f64; 2], y: [f64; 2]| [0.5 * (x[0] + y[0]), 0.5 * (x[1] + y[1])];
        let mut worst = (0f64, 0f64);
        let mut check = |s: [f64; 2], uv: [f64; 2]| {
            let (d, e) = view.fit_error_at(fit, s, uv, true);
            worst = (worst.0.max(d), worst.1.max(e));
        };
        let centre = middle(middle(p, r), middle(q, t));
        check(centre, view.sphere_uv(centre));
        let chords = self.chords.count;
        for (k, x, y) in [(a, p, q), (b, t, r)] {
            let s = middle(x, y);
            let uv = *self.chord_middles[k * chords + j].get_or_insert_with(|| view.sphere_uv(s));
            check(s, uv);
        }
        // Sectors run in order, each visiting a trapezoid once: its right
        // ray's midpoint is new (kept for the next sector, whose left ray
        // it is), its left ray's the previous sector's right one, if that
        // sector went down to the same rings (the latest kept, searched
        // from the end).
        for (e, x, y) in [(j, p, t), (j + 1, q, r)] {
            let s = middle(x, y);
            let key = (a, b, e);
            let kept = (e == j)
                .then(|| self.ray_middles.iter().rev().find(|(k, _)| *k == key))
                .flatten();
            let uv = match kept {
                Some(&(_, uv)) => uv,
                None => {
                    let uv = view.sphere_uv(s);
                    if e == j + 1 {
                        self.ray_middles.push((key, uv));
                    }
                    uv
                }
            };
            check(s, uv);
        }
        worst
    }
}

/// A square of a region's split, `[x0, x0 + h]²`, with the sphere's UV
/// at the points of its 3 × 3 grid (corners, edges' midpoints, centre)
/// as far as they have been computed: a whole square's checks are its
/// children's corners, and its corners its parent's grid points.
#[derive(Clone, Copy)]
pub(super) struct Square {
    x0: f64,
    y0: f64,
    h: f64,
    depth: u32,
    /// `uv[j][i]` at [`Square::point`]`(i, j)`.
    uv: [[Option<[f64; 2]>; 3]; 3],
}

impl Square {
    pub(super) fn new(lo: [f64; 2], h: f64) -> Square {
        Square {
            x0: lo[0],
            y0: lo[1],
            h,
            depth: 0,
            uv: [[None; 3]; 3],
        }
    }

    /// Grid point `(i, j)`, `i, j ∈ 0..3` (the midpoints by the same
    /// expression as an edge's midpoint).
    fn point(&self, i: usize, j: usize) -> [f64; 2] {
        let at = |lo: f64, k: usize| match k {
            0 => lo,
            1 => 0.5 * (lo + (lo + self.h)),
            _ => lo + self.h,
        };
        [at(self.x0, i), at(self.y0, j)]
    }

    /// The square's corners, counter-clockwise from `(x0, y0)`.
    fn corners(&self) -> [[f64; 2]; 4] {
        let (x0, y0, h) = (self.x0, self.y0, self.h);
        [[x0, y0], [x0 + h, y0], [x0 + h, y0 + h], [x0, y0 + h]]
    }

    /// The sphere's UV at grid point `(i, j)`.
    fn uv(&mut self, view: &SphereView, i: usize, j: usize) -> [f64; 2] {
        if let Some(uv) = self.uv[j][i] {
            return uv;
        }
        let uv = view.uv_at_grid_point(self.point(i, j));
        self.uv[j][i] = Some(uv);
        uv
    }

    /// The sphere's UV at `s`, kept when `s` is a grid point.
    fn uv_at(&mut self, view: &SphereView, s: [f64; 2]) -> [f64; 2] {
        let (xs, ys) = (
            [0, 1, 2].map(|k| self.point(k, k)[0]),
            [0, 1, 2].map(|k| self.point(k, k)[1]),
        );
        match (
            xs.iter().position(|&x| x == s[0]),
            ys.iter().position(|&y| y == s[1]),
        ) {
            (Some(i), Some(j)) => self.uv(view, i, j),
            _ => view.sphere_uv(s),
        }
    }

    /// The four quarters, their corners' UV taken from this grid.
    fn children(&mut self, view: &SphereView) -> [Square; 4] {
        for j in 0..3 {
            for i in 0..3 {
                self.uv(view, i, j);
            }
        }
        let g = 0.5 * self.h;
        [(0, 0), (1, 0), (0, 1), (1, 1)].map(|(a, b)| {
            let lo = self.point(a, b);
            let mut uv = [[None; 3]; 3];
            for (cj, pj) in [(0, b), (2, b + 1)] {
                for (ci, pi) in [(0, a), (2, a + 1)] {
                    uv[cj][ci] = self.uv[pj][pi];
                }
            }
            Square {
                x0: lo[0],
                y0: lo[1],
                h: g,
                depth: self.depth + 1,
                uv,
            }
        })
    }
}

/// Adds a piece's `(Σ colour·k, Σ k, bound)` to `sums`.
fn add(sums: &mut ([f64; 4], f64, f64), c: [f64; 4], w: f64, b: f64) {
    for (a, v) in sums.0.iter_mut().zip(c) {
        *a += v;
    }
    sums.1 += w;
    sums.2 += b;
}

/// The projective map sending screen quadrilateral `from` to UV
/// quadrilateral `to` corner by corner, as rows acting on `(x, y, 1)` with
/// `w > 0` inside `from` ([`Projection::matrix_between_quads`]); `None` when
/// either is folded or degenerate.
fn quad_to_quad(from: [[f64; 2]; 4], to: [[f64; 2]; 4]) -> Option<[[f64; 3]; 3]> {
    Projection::matrix_between_quads(&from, &to)
}

impl SphereView {
    /// `(Σ colour·k, Σ k, bound)` of the sphere over screen `region` (a
    /// part of its [`SphereView::region_into`]), split into pieces each
    /// integrated on a projective map within the error bound of the
    /// sphere's (module doc).
    pub(crate) fn shade(
        &self,
        shading: &Shading<'_>,
        region: &ConvexPolygon,
        stats: &mut PixelStats,
    ) -> ([f64; 4], f64, f64) {
        let mut sums = ([0.0; 4], 0.0, 0.0);
        if region.is_empty() {
            return sums;
        }
        let tolerance = shading.options.target_bound().unwrap_or(1.0 / 512.0);
        // The support the region was cut from (the pixel's, or a quarter
        // of it): its chords are the ones that clipped the region.
        let (lo, hi) = shading.support;
        let support = ConvexPolygon::rect(lo[0], lo[1], hi[0], hi[1]);
        let mut spare = Budget {
            weight: 0.5 * tolerance * shading.share,
            pieces: (shading.options.budget()).map_or(u64::MAX, |b| {
                // Per pixel of the support: a tent's is 4, a Mitchell's 16.
                let pixels = support.area().round().max(1.0) as u64;
                b.saturating_mul(PIECES_PER_SQUARE).saturating_mul(pixels)
            }),
            edges_parted: true,
        };
        let mut chords = Chords::default();
        let crossing = self.chords(&support, &mut chords).is_some() && chords.count > 0;
        if !crossing && !self.sectors_near_outline(&support, &mut chords) {
            if let Some((texture, run)) = self.run_texture(shading)
                && let Some(closed) =
                    self.shade_in_box(shading, region, &run, texture, spare.weight, stats)
            {
                return closed;
            }
            if let Some(closed) = self.in_closed_form(shading, region, &spare, stats) {
                return closed;
            }
            self.shade_squares(shading, region, &mut spare, &mut sums, stats);
            return sums;
        }
        // Along the outline: rings of trapezoids between the chords'
        // polygon and ones like it further in, each thin where the map's
        // square root bends most; inside them, squares.
        let radii = self.ring_radii(&chords);
        if radii.len() < 2 {
            self.shade_squares(shading, region, &mut spare, &mut sums, stats);
            return sums;
        }
        // One texture square may hold all of it: shown in closed form,
        // or through a fit across it.
        if let Some(closed) = self.in_closed_form(shading, region, &spare, stats) {
            return closed;
        }
        let (lo, hi) = region.bounds();
        let mut whole = Square::new(lo, (hi[0] - lo[0]).max(hi[1] - lo[1]));
        if let Some(fit) = self.fit(&mut whole)
            && let uv_error = self.map_error(&fit, region, &mut whole, &[], None).1
            && let Some(colour) = self.uniform(shading, &fit, region, uv_error)
        {
            self.add_uniform(shading, region, (colour, 0.0), &mut sums, stats);
            return sums;
        }
        let mut corners = vec![None; radii.len() * (chords.count + 1)];
        let mut chord_middles = vec![None; radii.len() * chords.count];
        let mut ray_middles = Vec::new();
        for j in 0..chords.count {
            let mut ring = Ring {
                chords: &chords,
                radii: &radii,
                chord: j,
                corners: &mut corners,
                chord_middles: &mut chord_middles,
                ray_middles: &mut ray_middles,
                within_chords: crossing,
            };
            self.shade_ring(
                shading,
                region,
                &mut ring,
                (0, radii.len() - 1),
                &mut spare,
                &mut sums,
                stats,
            );
        }
        let inner = radii[radii.len() - 1];
        let lines: Vec<[f64; 3]> = (0..chords.count)
            .map(|j| self.chord_line(chords.angle(j), chords.angle(j + 1), inner))
            .collect();
        let inside = region.clip_lines(lines);
        if !inside.is_empty() {
            self.shade_squares(shading, &inside, &mut spare, &mut sums, stats);
        }
        sums
    }

    /// `region` by squares alone ([`SphereView::shade_squares`]), with the
    /// budget [`SphereView::shade`] gives a call: the slow path that the
    /// closed forms are checked against.
    #[cfg(test)]
    pub(super) fn shade_by_squares(
        &self,
        shading: &Shading<'_>,
        region: &ConvexPolygon,
        stats: &mut PixelStats,
    ) -> ([f64; 4], f64, f64) {
        let tolerance = shading.options.target_bound().unwrap_or(1.0 / 512.0);
        let mut spare = Budget {
            weight: 0.5 * tolerance * shading.share,
            pieces: u64::MAX,
            edges_parted: false,
        };
        let mut sums = ([0.0; 4], 0.0, 0.0);
        self.shade_squares(shading, region, &mut spare, &mut sums, stats);
        sums
    }

    /// The q-radii of the rings along the outline, from 1 inward: the
    /// `k`-th `4·RING_TOLERANCE·k²` pixels in (along the middle of the
    /// chords' span), to a pixel: so that a fit across each, off by about
    /// `w²/(8·δ)` for width `w` at `δ` from the outline (the first by about
    /// `w/5`), stays within the default bound.
    fn ring_radii(&self, chords: &Chords) -> Vec<f64> {
        let theta = chords.from + 0.5 * chords.delta * chords.count as f64;
        let (sn, cs) = theta.sin_cos();
        let scale = (self.outline.ea[0] * cs + self.outline.eb[0] * sn)
            .hypot(self.outline.ea[1] * cs + self.outline.eb[1] * sn);
        let tolerance = RING_TOLERANCE;
        let mut radii = vec![1.0];
        for k in 1.. {
            let depth = 4.0 * tolerance * f64::from(k) * f64::from(k);
            let r = 1.0 - depth / scale;
            if r.is_nan() || r <= 0.5 || depth > 1.0 {
                break;
            }
            radii.push(r);
        }
        radii
    }

    /// The colour of the texture over all of `piece` when one texture
    /// square holds every image it may have under `fit` or, off by at most
    /// twice `uv_error` (the fit's at the check points), under the
    /// sphere's map;
    /// `Some(None)` when the surface has no texture.
    fn uniform(
        &self,
        shading: &Shading<'_>,
        fit: &[[f64; 3]; 3],
        piece: &ConvexPolygon,
        uv_error: f64,
    ) -> Option<Option<quadtex_core::Rgba>> {
        let Some(texture) = shading.frame.texture(self.surface) else {
            return Some(None);
        };
        let (lo, hi) = self.texture_box(fit, piece, uv_error)?;
        texture.uniform_colour_in_box(lo, hi).map(Some)
    }

    /// Adds `piece` in one colour (`None`: the surface's own) to `sums`,
    /// lit at its centroid, with `light_bound` (a bound on how far the
    /// light elsewhere in the piece takes its colour from the centroid's,
    /// per unit weight) times its weight in the bound.
    fn add_uniform(
        &self,
        shading: &Shading<'_>,
        piece: &ConvexPolygon,
        (colour, light_bound): (Option<quadtex_core::Rgba>, f64),
        sums: &mut ([f64; 4], f64, f64),
        stats: &mut PixelStats,
    ) {
        let w = shading.filter.integral(piece, shading.centre);
        let c = colour.map_or([w; 4], |c| c.to_array().map(|v| f64::from(v) * w));
        if colour.is_some() {
            stats.textured = 1;
            stats.filter.footprints += 1;
            stats.filter.fragments += 1;
        }
        add(
            sums,
            self.finish(shading, piece, c),
            w,
            light_bound * self.absolute_weight(shading, piece, w),
        );
    }

    /// [`SphereView::shade`] of `region`'s part between rings `a` and `b`
    /// of one chord's sector: one colour where one texture square holds
    /// it; else, across several rings, each half in turn; across one, on
    /// the projective map through the sphere's UV at its corners where
    /// that is within the tolerance, else by squares.
    #[allow(clippy::too_many_arguments)]
    fn shade_ring(
        &self,
        shading: &Shading<'_>,
        region: &ConvexPolygon,
        ring: &mut Ring<'_>,
        (a, b): (usize, usize),
        spare: &mut Budget,
        sums: &mut ([f64; 4], f64, f64),
        stats: &mut PixelStats,
    ) {
        let j = ring.chord;
        let ends = [(a, j), (a, j + 1), (b, j + 1), (b, j)].map(|(k, e)| ring.corner(self, k, e));
        let corners = ends.map(|(s, _)| s);
        // The sector's wedge, beyond ring b's chord and (past the first
        // ring) within ring a's; the first ring reaches the outline, so
        // that a support inside it but beyond its chord loses nothing.
        let (t0, t1) = (ring.chords.angle(j), ring.chords.angle(j + 1));
        let beyond = self.chord_line(t0, t1, ring.radii[b]).map(|v| -v);
        let within = (a > 0).then(|| self.chord_line(t0, t1, ring.radii[a]));
        let piece = region.clip_lines(
            [
                self.left_of_ray(t0),
                self.left_of_ray(t1).map(|v| -v),
                beyond,
            ]
            .into_iter()
            .chain(within),
        );
        if piece.is_empty() {
            return;
        }
        let tolerance = shading.options.target_bound().unwrap_or(1.0 / 512.0);
        // Around a pole: the fan, where its coordinates' fit holds.
        let mut nowhere = Square::new([f64::NAN, f64::NAN], f64::NAN);
        if let Some(fan) = self.pole_fan(|f| ends.iter().all(|e| f.holds(e.1)))
            && let Some((fit, image)) =
                self.pole_fit(fan, corners, &piece, &mut nowhere, &corners, tolerance)
            && fan.holds_box(image)
        {
            let (c, w, b) = self.shade_fan(shading, &piece, &fit, fan.wedges(), stats);
            add(sums, self.finish(shading, &piece, c), w, b);
            return;
        }
        let first = ends[0].1;
        let uv = ends.map(|(_, [u, v])| [u + (first[0] - u).round(), v]);
        let fit = quad_to_quad(corners, uv);
        let (error, uv_error) = match &fit {
            None => (f64::INFINITY, f64::INFINITY),
            // The piece lies within the trapezoid: its checks hold for it,
            // and neighbouring trapezoids share them.
            Some(f) if a > 0 || ring.within_chords => ring.trapezoid_error(self, f, (a, b)),
            Some(f) => {
                let mut nowhere = Square::new([f64::NAN, f64::NAN], f64::NAN);
                self.map_error(f, &piece, &mut nowhere, &corners, None)
            }
        };
        if let Some(fit) = &fit
            && let Some(colour) = self.uniform(shading, fit, &piece, uv_error)
        {
            self.add_uniform(shading, &piece, (colour, 0.0), sums, stats);
            return;
        }
        if b - a > 1 && self.part_by_edge(shading, &piece, spare, sums, stats) {
            return;
        }
        // Near a pole, where the UV's fit is off: a band of texture squares
        // beyond the fan may hold it, as the pole's coordinates see it
        // (tried on single rings: across several, the fit is off anyway).
        if error > tolerance
            && b - a == 1
            && let Some(fan) = self.pole_fan(|f| ends.iter().all(|e| f.near(e.1)))
            && let Some((pole_fit, image)) =
                self.pole_fit(fan, corners, &piece, &mut nowhere, &corners, tolerance)
            && let Some(wedges) = fan.band_holding(image)
        {
            let (c, w, b) = self.shade_fan(shading, &piece, &pole_fit, wedges, stats);
            add(sums, self.finish(shading, &piece, c), w, b);
            return;
        }
        spare.pieces = spare.pieces.saturating_sub(1);
        if spare.pieces == 0
            && let Some(fit) = fit
        {
            // The budget is spent: this piece on its fit, its weight in
            // the bound unless the fit is within the tolerance.
            let (c, w, b) = self.shade_piece(shading, &piece, &fit, stats);
            let off = if error > tolerance { w.abs() } else { 0.0 };
            add(sums, self.finish(shading, &piece, c), w, b + off);
            return;
        }
        if b - a > 1 {
            let middle = (a + b) / 2;
            for half in [(a, middle), (middle, b)] {
                self.shade_ring(shading, region, ring, half, spare, sums, stats);
            }
            return;
        }
        match fit {
            Some(fit) if error <= tolerance => {
                let (c, w, b) = self.shade_piece(shading, &piece, &fit, stats);
                add(sums, self.finish(shading, &piece, c), w, b);
            }
            _ => self.shade_squares(shading, &piece, spare, sums, stats),
        }
    }

    /// `(Σ colour·k, Σ k, bound)` of a call's whole `region` from its
    /// closed-form UV box ([`SphereView::shade_in_box`], within the call's
    /// allowance); `None` when that does not show it.
    fn in_closed_form(
        &self,
        shading: &Shading<'_>,
        region: &ConvexPolygon,
        spare: &Budget,
        stats: &mut PixelStats,
    ) -> Option<([f64; 4], f64, f64)> {
        let uv = self.region_uv_box(shading, region)?;
        let texture = self.box_texture(shading, &uv);
        self.shade_in_box(shading, region, &uv, texture, spare.weight, stats)
    }

    /// `(Σ colour·k, Σ k, bound)` of `region`, whose sphere UV lies in the
    /// box `uv` over which the texture is `texture`: in one colour, where
    /// the light moves it by little ([`SphereView::light_bound`]), or split
    /// along the one texture edge's image ([`SphereView::split_along`],
    /// its bound within `allowance`); `None` otherwise.
    fn shade_in_box(
        &self,
        shading: &Shading<'_>,
        region: &ConvexPolygon,
        uv: &UvBox,
        texture: BoxTexture,
        allowance: f64,
        stats: &mut PixelStats,
    ) -> Option<([f64; 4], f64, f64)> {
        match texture {
            BoxTexture::One(colour) => {
                let light = self.light_bound(shading, region, uv, &[colour])?;
                let mut sums = ([0.0; 4], 0.0, 0.0);
                self.add_uniform(shading, region, (colour, light), &mut sums, stats);
                Some(sums)
            }
            BoxTexture::Two(image) => {
                self.split_along(shading, region, uv, &image, allowance, stats)
            }
            BoxTexture::Other => None,
        }
    }

    /// Adds `piece` to `sums` split along the image of the one texture edge
    /// across it ([`SphereView::two_colours`]), where there is one and its
    /// bound is within an eighth of what is left of the call's allowance
    /// (as a piece off its fit may spend), and spends the bound; false
    /// (nothing added) otherwise.
    fn part_by_edge(
        &self,
        shading: &Shading<'_>,
        piece: &ConvexPolygon,
        spare: &mut Budget,
        sums: &mut ([f64; 4], f64, f64),
        stats: &mut PixelStats,
    ) -> bool {
        if !spare.edges_parted {
            return false;
        }
        let Some(uv) = self.region_uv_box(shading, piece) else {
            return false;
        };
        let Some((c, w, bound)) =
            self.two_colours(shading, piece, &uv, 0.125 * spare.weight, stats)
        else {
            return false;
        };
        spare.weight -= bound;
        add(sums, c, w, bound);
        true
    }

    /// [`SphereView::shade`] of `region` by squares, from its bounding
    /// square down, into `sums`.
    fn shade_squares(
        &self,
        shading: &Shading<'_>,
        region: &ConvexPolygon,
        spare: &mut Budget,
        sums: &mut ([f64; 4], f64, f64),
        stats: &mut PixelStats,
    ) {
        let (lo, hi) = region.bounds();
        let side = (hi[0] - lo[0]).max(hi[1] - lo[1]);
        if region.is_empty() || !(side > 0.0 && side.is_finite()) {
            return;
        }
        let tolerance = shading.options.target_bound().unwrap_or(1.0 / 512.0);
        let texture = shading.frame.texture(self.surface);
        let mut squares = vec![Square::new(lo, side)];
        while let Some(mut square) = squares.pop() {
            let Square { x0, y0, h, .. } = square;
            let piece = region.clip_rect(x0, y0, x0 + h, y0 + h);
            if piece.is_empty() {
                continue;
            }
            // Around a pole, its coordinates, where the map is smooth.
            let fan = self.fan_holding(&mut square);
            let fit = match fan {
                Some(fan) => self.fan_fit(fan, &square),
                None => self.fit(&mut square),
            };
            let (error, uv_error) = fit.map_or((f64::INFINITY, f64::INFINITY), |f| {
                self.map_error(&f, &piece, &mut square, &[], fan)
            });
            // Exact whatever the map's error: one texture square holds
            // every image the piece may have (or there is no texture).
            let uniform = match (texture, &fit, fan) {
                (None, _, _) => Some(None),
                (Some(texture), Some(f), None) => self
                    .texture_box(f, &piece, uv_error)
                    .and_then(|(lo, hi)| texture.uniform_colour_in_box(lo, hi))
                    .map(Some),
                _ => None,
            };
            // Near a pole, where the UV's fit is off: a band of texture
            // squares beyond the fan may hold it, as the pole sees it.
            if fan.is_none()
                && error > tolerance
                && texture.is_some()
                && let Some((pole_fit, wedges)) = self.band_holding(&mut square, &piece, tolerance)
            {
                let (c, w, b) = self.shade_fan(shading, &piece, &pole_fit, wedges, stats);
                add(sums, self.finish(shading, &piece, c), w, b);
                continue;
            }
            let w = shading.filter.integral(&piece, shading.centre);
            if let Some(colour) = uniform {
                let c = colour.map_or([w; 4], |c| c.to_array().map(|v| f64::from(v) * w));
                if texture.is_some() {
                    stats.textured = 1;
                    stats.filter.footprints += 1;
                    stats.filter.fragments += 1;
                }
                add(sums, self.finish(shading, &piece, c), w, 0.0);
                continue;
            }
            // The fan's wedges hold every image the piece may have.
            let on_fan = match (&fit, fan) {
                (Some(f), Some(fan)) => (self.image_box(f, &piece, uv_error))
                    .is_some_and(|b| fan.holds_box(b))
                    .then_some((f, fan)),
                _ => None,
            };
            let off = error > tolerance || (fan.is_some() && on_fan.is_none());
            if off && fan.is_none() && self.part_by_edge(shading, &piece, spare, sums, stats) {
                continue;
            }
            let spent = off && w.abs() <= 0.125 * spare.weight;
            spare.pieces = spare.pieces.saturating_sub(1);
            if off && !spent && square.depth < MAX_SPLITS && spare.pieces > 0 {
                for child in square.children(self) {
                    squares.push(child);
                }
                continue;
            }
            if spent {
                spare.weight -= w.abs();
            }
            let fit = match (on_fan, fan) {
                (Some(_), _) => fit,
                // Beyond the fan: the sphere's UV after all.
                (None, Some(_)) => self.fit(&mut square),
                (None, None) => fit,
            };
            let (c, w, b) = match (on_fan, fit) {
                (Some((f, fan)), _) => self.shade_fan(shading, &piece, f, fan.wedges(), stats),
                (None, Some(fit)) => self.shade_piece(shading, &piece, &fit, stats),
                (None, None) => match self.tangent_fit(piece.centroid(), h) {
                    Some(fit) => self.shade_piece(shading, &piece, &fit, stats),
                    None => continue,
                },
            };
            let off = if off { w.abs() } else { 0.0 };
            add(sums, self.finish(shading, &piece, c), w, b + off);
        }
    }

    /// The pole whose fan `accepts` (north first).
    fn pole_fan(&self, accepts: impl Fn(&PolarFan) -> bool) -> Option<&PolarFan> {
        [self.fans.north.as_ref(), self.fans.south.as_ref()]
            .into_iter()
            .flatten()
            .find(|f| accepts(f))
    }

    /// The pole fan whose reach holds the square's 3 × 3 grid points
    /// ([`PolarFan::holds`]), if any.
    fn fan_holding(&self, square: &mut Square) -> Option<&PolarFan> {
        let first = square.uv(self, 0, 0);
        let fan = self.pole_fan(|f| f.holds(first))?;
        for j in 0..3 {
            for i in 0..3 {
                if !fan.holds(square.uv(self, i, j)) {
                    return None;
                }
            }
        }
        Some(fan)
    }

    /// The projective map from screen quadrilateral `corners` to `fan`'s
    /// coordinates through the sphere's points there, and the box holding
    /// every image `piece` may have ([`SphereView::image_box`]), when the
    /// map is within `tolerance` at the piece's check points
    /// ([`SphereView::map_error`], with `square` and `exact` as it takes
    /// them).
    fn pole_fit(
        &self,
        fan: &PolarFan,
        corners: [[f64; 2]; 4],
        piece: &ConvexPolygon,
        square: &mut Square,
        exact: &[[f64; 2]],
        tolerance: f64,
    ) -> Option<([[f64; 3]; 3], ImageBox)> {
        let fit = quad_to_quad(corners, corners.map(|s| fan.point(self.normal(s))))?;
        let (error, image_error) = self.map_error(&fit, piece, square, exact, Some(fan));
        if error > tolerance {
            return None;
        }
        Some((fit, self.image_box(&fit, piece, image_error)?))
    }

    /// The fit of `square` in a pole's coordinates, within `tolerance`,
    /// and the wedges of the band beyond the pole's fan that holds every
    /// image `piece` may have, if a pole is near and one does.
    fn band_holding(
        &self,
        square: &mut Square,
        piece: &ConvexPolygon,
        tolerance: f64,
    ) -> Option<([[f64; 3]; 3], &[Wedge])> {
        let first = square.uv(self, 0, 0);
        let fan = self.pole_fan(|f| f.near(first))?;
        for (i, j) in [(2, 0), (2, 2), (0, 2)] {
            if !fan.near(square.uv(self, i, j)) {
                return None;
            }
        }
        let (fit, image) = self.pole_fit(fan, square.corners(), piece, square, &[], tolerance)?;
        Some((fit, fan.band_holding(image)?))
    }

    /// The projective map from the screen to the fan's coordinates through
    /// the sphere's points there at the square's corners.
    fn fan_fit(&self, fan: &PolarFan, square: &Square) -> Option<[[f64; 3]; 3]> {
        let corners = square.corners();
        quad_to_quad(corners, corners.map(|s| fan.point(self.normal(s))))
    }

    /// A box holding the image of `piece` under the fitted map `fit` and,
    /// by its error at the check points (`error`, doubled for margin),
    /// under the sphere's own: in the sphere's UV or the fan's
    /// coordinates, as `fit` maps to. `None` where the fit folds over the
    /// piece or the box is not finite.
    fn image_box(
        &self,
        fit: &[[f64; 3]; 3],
        piece: &ConvexPolygon,
        error: f64,
    ) -> Option<([f64; 2], [f64; 2])> {
        let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
        for &s in piece.vertices() {
            let w = fit[2][0] * s[0] + fit[2][1] * s[1] + fit[2][2];
            if w.is_nan() || w <= 0.0 {
                return None;
            }
            for a in 0..2 {
                let t = (fit[a][0] * s[0] + fit[a][1] * s[1] + fit[a][2]) / w;
                lo[a] = lo[a].min(t);
                hi[a] = hi[a].max(t);
            }
        }
        let margin = 2.0 * error + 1e-12;
        let (lo, hi) = (lo.map(|v| v - margin), hi.map(|v| v + margin));
        lo.iter()
            .chain(&hi)
            .all(|v| v.is_finite())
            .then_some((lo, hi))
    }

    /// `(Σ colour·k, Σ k, bound)` of one piece on map `fit` to the fan's
    /// coordinates, its image within the fan: each wedge's colour over
    /// the piece clipped to the wedge's sides (lines through the pole on
    /// the screen too), exactly.
    fn shade_fan(
        &self,
        shading: &Shading<'_>,
        piece: &ConvexPolygon,
        fit: &[[f64; 3]; 3],
        wedges: &[Wedge],
        stats: &mut PixelStats,
    ) -> ([f64; 4], f64, f64) {
        let Shading { filter, centre, .. } = *shading;
        stats.textured = 1;
        stats.filter.footprints += 1;
        let image: Vec<[f64; 2]> = (piece.vertices().iter())
            .map(|s| {
                let w = fit[2][0] * s[0] + fit[2][1] * s[1] + fit[2][2];
                [0, 1].map(|a| (fit[a][0] * s[0] + fit[a][1] * s[1] + fit[a][2]) / w)
            })
            .collect();
        // The half-plane left of the ray from the pole at `angle`, in pole
        // coordinates, pulled back to the screen through `fit` (w > 0 over
        // the piece).
        let left_of = |angle: f64| {
            let (sn, cs) = angle.sin_cos();
            let l = [-sn, cs, 0.5 * (sn - cs)];
            [0, 1, 2].map(|c| l[0] * fit[0][c] + l[1] * fit[1][c] + l[2] * fit[2][c])
        };
        let (mut colour, mut weight) = ([0.0; 4], 0.0);
        for &(from, to, c) in meeting(wedges, &image) {
            let part = piece.clip_lines([left_of(from), left_of(to).map(|v| -v)]);
            if part.is_empty() {
                continue;
            }
            let w = filter.integral(&part, centre);
            for (a, v) in colour.iter_mut().zip(c.to_array()) {
                *a += f64::from(v) * w;
            }
            weight += w;
            stats.filter.fragments += 1;
        }
        (colour, weight, 0.0)
    }

    /// The projective map from the screen to the sphere's `(u, v)` through
    /// its UV at the corners of the square `[x0, x0 + h]²` (longitude
    /// unwrapped around the first corner's), rows acting on
    /// `(px, py, 1)` with `w > 0` over the square; `None` when the corners'
    /// quadrilateral has no such map (it folds).
    pub(super) fn fit(&self, square: &mut Square) -> Option<[[f64; 3]; 3]> {
        let corners = square.corners();
        let first = square.uv(self, 0, 0);
        let mut corner = |i: usize, j: usize| {
            let [u, v] = square.uv(self, i, j);
            [u + (first[0] - u).round(), v]
        };
        let uv = [first, corner(2, 0), corner(2, 2), corner(0, 2)];
        quad_to_quad(corners, uv)
    }

    /// The affine map through the sphere's UV at `c` with its derivatives
    /// there (central differences over `h / 64`): the fallback where the
    /// corners' map folds.
    fn tangent_fit(&self, c: [f64; 2], h: f64) -> Option<[[f64; 3]; 3]> {
        let e = (h / 64.0).max(1e-9);
        let at = self.sphere_uv(c);
        let near = |s: [f64; 2]| {
            let [u, v] = self.sphere_uv(s);
            [u + (at[0] - u).round(), v]
        };
        let (xp, xm) = (near([c[0] + e, c[1]]), near([c[0] - e, c[1]]));
        let (yp, ym) = (near([c[0], c[1] + e]), near([c[0], c[1] - e]));
        let du = [(xp[0] - xm[0]) / (2.0 * e), (yp[0] - ym[0]) / (2.0 * e)];
        let dv = [(xp[1] - xm[1]) / (2.0 * e), (yp[1] - ym[1]) / (2.0 * e)];
        let m = [
            [du[0], du[1], at[0] - du[0] * c[0] - du[1] * c[1]],
            [dv[0], dv[1], at[1] - dv[0] * c[0] - dv[1] * c[1]],
            [0.0, 0.0, 1.0],
        ];
        let det = du[0] * dv[1] - du[1] * dv[0];
        (det.is_finite() && det.abs() > 1e-300).then_some(m)
    }

    /// The largest screen distance, at `piece`'s check points, between a
    /// point and the one the sphere's map sends where `fit` sends it
    /// (first order: `|J⁻¹·(H(s) − uv(s))|`, `J` the fit's Jacobian), and
    /// the largest UV difference there. The check points: the centre and
    /// edges' midpoints of `square` when the piece is all of it, or when
    /// the square lies inside the outline (its fit's error bounds the
    /// part's); else the piece's centroid, edges' midpoints and vertices
    /// but the square's corners and `exact` (where the fit passes through
    /// the sphere's UV).
    pub(super) fn map_error(
        &self,
        fit: &[[f64; 3]; 3],
        piece: &ConvexPolygon,
        square: &mut Square,
        exact: &[[f64; 2]],
        fan: Option<&PolarFan>,
    ) -> (f64, f64) {
        let Square { x0, y0, h, .. } = *square;
        let v = piece.vertices();
        let c = piece.centroid();
        let n = v.len();
        let mut worst = 0f64;
        let mut worst_uv = 0f64;
        let mut check = |s: [f64; 2], square: &mut Square| {
            let (d, e) = match fan {
                Some(fan) => self.fit_error_at(fit, s, fan.point(self.normal(s)), false),
                None => self.fit_error_at(fit, s, square.uv_at(self, s), true),
            };
            worst = worst.max(d);
            worst_uv = worst_uv.max(e);
        };
        // The fit is exact at the square's corners.
        let corner = |p: [f64; 2]| (p[0] == x0 || p[0] == x0 + h) && (p[1] == y0 || p[1] == y0 + h);
        let whole = n == 4 && v.iter().all(|&p| corner(p));
        // A part of a square lying inside the outline is checked as the
        // whole square (the fit's error over the square bounds it over
        // the part as well as the part's own points do), at points its
        // neighbours and children share; beyond the outline the sphere's
        // map is the limb's, not the square's.
        if whole
            || (h.is_finite()
                && [0, 1, 2].iter().all(|&j| {
                    [0, 1, 2]
                        .iter()
                        .all(|&i| self.inside_outline(square.point(i, j)))
                }))
        {
            // The square's centre and edges' midpoints, which are its
            // children's corners.
            for (i, j) in [(1, 1), (1, 0), (2, 1), (1, 2), (0, 1)] {
                let s = square.point(i, j);
                check(s, square);
            }
        } else {
            check(c, square);
            for i in 0..n {
                let (a, b) = (v[i], v[(i + 1) % n]);
                if !corner(a) && !exact.contains(&a) {
                    check(a, square);
                }
                check([0.5 * (a[0] + b[0]), 0.5 * (a[1] + b[1])], square);
            }
        }
        if worst_uv.is_nan() {
            worst_uv = f64::INFINITY;
        }
        (worst, worst_uv)
    }

    /// Whether screen point `s` lies strictly inside the outline.
    fn inside_outline(&self, s: [f64; 2]) -> bool {
        let q = self.circle(s);
        q[0] * q[0] + q[1] * q[1] < 1.0
    }

    /// The error of `fit` at screen point `s`, where the sphere's UV is
    /// `uv`: the screen distance from `s` to the point the sphere's map
    /// sends where `fit` sends `s` (first order: `|J⁻¹·(H(s) − uv)|`, `J`
    /// the fit's Jacobian; infinite where the fit folds or NaN), and the
    /// larger of the UV differences.
    fn fit_error_at(
        &self,
        fit: &[[f64; 3]; 3],
        s: [f64; 2],
        uv: [f64; 2],
        longitude: bool,
    ) -> (f64, f64) {
        let w = fit[2][0] * s[0] + fit[2][1] * s[1] + fit[2][2];
        let hu = (fit[0][0] * s[0] + fit[0][1] * s[1] + fit[0][2]) / w;
        let hv = (fit[1][0] * s[0] + fit[1][1] * s[1] + fit[1][2]) / w;
        let turns = if longitude { (hu - uv[0]).round() } else { 0.0 };
        let e = [uv[0] + turns - hu, uv[1] - hv];
        let uv_error = e[0].abs().max(e[1].abs());
        // Jacobian of (a·s̃ / w·s̃): (a_xy − value·w_xy) / w.
        let j = [
            [
                (fit[0][0] - hu * fit[2][0]) / w,
                (fit[0][1] - hu * fit[2][1]) / w,
            ],
            [
                (fit[1][0] - hv * fit[2][0]) / w,
                (fit[1][1] - hv * fit[2][1]) / w,
            ],
        ];
        let det = j[0][0] * j[1][1] - j[0][1] * j[1][0];
        let d = if w > 0.0 && det.abs() > 1e-300 {
            let dx = (j[1][1] * e[0] - j[0][1] * e[1]) / det;
            let dy = (-j[1][0] * e[0] + j[0][0] * e[1]) / det;
            (dx * dx + dy * dy).sqrt()
        } else {
            f64::INFINITY
        };
        (
            if d.is_nan() { f64::INFINITY } else { d },
            if uv_error.is_nan() {
                f64::INFINITY
            } else {
                uv_error
            },
        )
    }

    /// A texture-space box holding the image of `piece` under the fitted
    /// map `fit` and, by its error at the check points (`uv_error`, doubled
    /// for margin), under the sphere's own; `None` where the piece reaches
    /// across the longitude seam or the box is not finite.
    fn texture_box(
        &self,
        fit: &[[f64; 3]; 3],
        piece: &ConvexPolygon,
        uv_error: f64,
    ) -> Option<([f64; 2], [f64; 2])> {
        let (lo, hi) = self.image_box(fit, piece, uv_error)?;
        self.texture_box_of_uv(lo, hi)
    }

    /// The texture-space box of the UV box `(lo, hi)`, when it lies
    /// between two seams (`u` in one turn); read in `[0, 1)`.
    pub(super) fn texture_box_of_uv(
        &self,
        lo: [f64; 2],
        hi: [f64; 2],
    ) -> Option<([f64; 2], [f64; 2])> {
        let turn = lo[0].floor();
        if !(turn.is_finite() && hi[0].floor() == turn) {
            return None;
        }
        let t = &self.texture_from_uv;
        let (mut tlo, mut thi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
        for (u, v) in [
            (lo[0], lo[1]),
            (hi[0], lo[1]),
            (hi[0], hi[1]),
            (lo[0], hi[1]),
        ] {
            let u = u - turn;
            for a in 0..2 {
                let x = t[a][0] * u + t[a][1] * v + t[a][2];
                tlo[a] = tlo[a].min(x);
                thi[a] = thi[a].max(x);
            }
        }
        Some((tlo, thi))
    }

    /// `(Σ colour·k, Σ k, bound)` of one piece on map `fit` (to the
    /// sphere's UV), cut at the seams `u ∈ ℤ` and each side read in
    /// `[0, 1)`; tinted and lit at the piece's centroid.
    fn shade_piece(
        &self,
        shading: &Shading<'_>,
        piece: &ConvexPolygon,
        fit: &[[f64; 3]; 3],
        stats: &mut PixelStats,
    ) -> ([f64; 4], f64, f64) {
        let Shading {
            frame,
            filter,
            centre,
            options,
            ..
        } = *shading;
        let value = |row: &[f64; 3], s: [f64; 2]| row[0] * s[0] + row[1] * s[1] + row[2];
        let u_at = |s: [f64; 2]| value(&fit[0], s) / value(&fit[2], s);
        let (mut u_lo, mut u_hi) = (f64::INFINITY, f64::NEG_INFINITY);
        for &s in piece.vertices() {
            let u = u_at(s);
            u_lo = u_lo.min(u);
            u_hi = u_hi.max(u);
        }
        let mut colour = [0.0; 4];
        let (mut weight, mut bound) = (0.0, 0.0);
        let texture = frame.texture(self.surface);
        if !(u_lo.is_finite() && u_hi.is_finite()) {
            return (colour, 0.0, 0.0);
        }
        let first = u_lo.floor() as i64;
        let last = (u_hi.floor() as i64).max(first);
        for turn in first..=last {
            let k = turn as f64;
            // The piece's part with u in [k, k + 1), its u moved by −k.
            let shifted = [
                [
                    fit[0][0] - k * fit[2][0],
                    fit[0][1] - k * fit[2][1],
                    fit[0][2] - k * fit[2][2],
                ],
                fit[1],
                fit[2],
            ];
            let part = if first == last {
                piece.clone()
            } else {
                let upper = [
                    fit[2][0] - shifted[0][0],
                    fit[2][1] - shifted[0][1],
                    fit[2][2] - shifted[0][2],
                ];
                let mut lines = Vec::with_capacity(2);
                if turn > first {
                    lines.push(shifted[0]);
                }
                if turn < last {
                    lines.push(upper);
                }
                piece.clip_lines(lines)
            };
            if part.is_empty() {
                continue;
            }
            let (c, w, b) = match texture {
                Some(texture) => {
                    stats.textured = 1;
                    let t = &self.texture_from_uv;
                    let rows = [0, 1].map(|r| {
                        [0, 1, 2].map(|col| {
                            t[r][0] * shifted[0][col]
                                + t[r][1] * shifted[1][col]
                                + t[r][2] * shifted[2][col]
                        })
                    });
                    let Ok(projection) = Projection::new([rows[0], rows[1], shifted[2]]) else {
                        let w = filter.integral(&part, centre);
                        weight += w;
                        bound += w.abs();
                        continue;
                    };
                    let r = texture.integrate_region(
                        &projection,
                        &part,
                        filter,
                        centre,
                        options,
                        &mut stats.filter,
                    );
                    (r.colour.0, r.weight, r.error_bound)
                }
                None => {
                    let w = filter.integral(&part, centre);
                    ([w; 4], w, 0.0)
                }
            };
            for (a, v) in colour.iter_mut().zip(c) {
                *a += v;
            }
            weight += w;
            bound += b;
        }
        (colour, weight, bound)
    }

    /// A piece's texture integral `c` tinted by the surface's colour and
    /// lit at the piece's centroid (its normal and shadow ray there).
    pub(super) fn finish(
        &self,
        shading: &Shading<'_>,
        piece: &ConvexPolygon,
        mut c: [f64; 4],
    ) -> [f64; 4] {
        let scene = shading.frame.scene;
        let tint = scene.surfaces[self.surface]
            .colour
            .to_array()
            .map(f64::from);
        for (v, t) in c.iter_mut().zip(tint) {
            *v *= t;
        }
        if let Lighting::Lambert { .. } = scene.lighting {
            let s = piece.centroid();
            // The normal and point only: the UV's atan2 and acos are not
            // needed for the light.
            let normal = self.normal(s);
            let point = self.centre + normal * self.radius;
            let ray = scene.camera.ray(s[0], s[1]);
            let k = lambert(&shading.frame.rays, (self.surface, 0), normal, point, &ray);
            apply_light(&mut c, k);
        }
        c
    }

    /// The sphere's UV at `s` ([`SphereView::sphere_uv`]), kept in the
    /// thread's [`HALF_PIXEL_UV`] when `s` lies on the half-pixel grid
    /// (a pixel's corners, edges' midpoints and centre, shared with the
    /// pixels beside, above and below it): the same bits either way.
    fn uv_at_grid_point(&self, s: [f64; 2]) -> [f64; 2] {
        let (x2, y2) = (2.0 * s[0], 2.0 * s[1]);
        let on_grid = x2 == x2.floor() && y2 == y2.floor() && x2 >= 0.0 && y2 >= 0.0;
        if !(on_grid && x2 < 65536.0 && y2 < 65536.0) {
            return self.sphere_uv(s);
        }
        let (column, row) = (x2 as usize, y2 as u32);
        let tag = (self.stamp, row);
        HALF_PIXEL_UV
            .try_with(|rows| {
                let mut rows = rows.borrow_mut();
                let slot = &mut rows[(row % 4) as usize];
                if slot.0 != tag {
                    slot.0 = tag;
                    slot.1.clear();
                }
                if slot.1.len() <= column {
                    slot.1.resize(column + 1, None);
                }
                *slot.1[column].get_or_insert_with(|| self.sphere_uv(s))
            })
            .unwrap_or_else(|_| self.sphere_uv(s))
    }
}
