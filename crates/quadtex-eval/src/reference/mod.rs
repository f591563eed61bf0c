//! The closed-form reference: the exact box-filtered image of an unlit
//! textured plane or quad with the sky behind it, independent of every
//! contender (it never calls the quadtex filter; it reads the tree's finest
//! cells only).
//!
//! # Method
//!
//! The texture→screen map of a planar surface is a homography `M`. When the
//! texture's `x` axis is parallel to the camera's right vector (or its `z`
//! axis is: the axes are then swapped), a texture row `z = const` has
//! constant depth and projects to a screen row, and along it screen `x` is
//! affine in texture `x`: `sx = a(y) + b(y)·X`, with `a`, `b` affine in `y`.
//! So over a band of cells `Z ∈ [j h, (j+1) h]` (constant colour per cell
//! along `X`) the box integral of the pixel `[px, px+1]` is
//! `∫ b(y)·(F_j(X_R(y)) − F_j(X_L(y))) dy` with `F_j` the cumulative
//! integral of the row: piecewise linear in `X`, and on each linear piece
//! `b·F_j(X(y))` is affine in `y`, so the midpoint rule is exact. Each
//! pixel edge `sx = e` is integrated once per row and shared by its two
//! pixels. For a quad, `F_j` is clamped to the quad's `X` range and the
//! bands to its `Z` range (the outline must be a texture-axis rectangle).
//!
//! **Far rows (plane).** Bands up to the horizon are infinitely many. The
//! row function is split as `F_j = μ_j X + P_j(X)`: `μ_j` (the row mean)
//! contributes `μ_j` times the band's screen height (`b·(X_R − X_L) = 1`),
//! summed exactly over enumerated bands; beyond a cut `y_J` the rest is
//! `μ̄·|y_J − y_h|` with error at most `B_μ·|y_J − y_h|` by Abel summation
//! (`B_μ` = twice the largest partial sum of `μ_j − μ̄`; 0 for a checker).
//! The periodic part `P_j` (|P| ≤ `P_max`) beyond the cut contributes at
//! most `P_max·∫|b| dy = P_max·|m00·n21|·(y_J − y_h)²/2` per pixel edge
//! (`b` is affine in `y` and vanishes at the horizon). The cut is placed so
//! each edge's bound is ≤ [`EDGE_BUDGET`] and the mean bound ≤
//! [`MEAN_BUDGET`].
//!
//! **Sky.** The part of the pixel the surface does not cover is
//! `pixel − (pixel ∩ outline)` (the outline: the plane's half-plane below
//! its horizon, or the quad's projected quadrilateral). The sky there is
//! `h + Δ·sqrt(max(L,0))·ν`, with `L = d_y` affine in screen coordinates
//! (`d` the unnormalised ray direction) and `ν = |d|^(-1/2)` smooth.
//! `∫ sqrt(L)` and `∫ sqrt(L)·x` over a convex polygon (clipped to `L ≥ 0`)
//! are computed by the divergence theorem edge by edge (exact, plus an
//! 8-point Gauss rule for one first-moment term), and `ν` is replaced by
//! its tangent plane at the centre of each of `n × n` sub-squares of the
//! pixel: with `‖∇²ν‖ ≤ k²/2` (`k` the image-plane size of a pixel at unit
//! distance) the error is at most `|Δ|·sqrt(L_max)·k²/4·∫|x − c|²`, with
//! `∫|x − c|² = 1/(6n⁴)` per sub-square, two polygons each: in all
//! `2|Δ|·sqrt(L_max)·k²/(24n²)` per pixel; `n` is chosen to make this
//! ≤ [`SKY_BUDGET`] (n = 1 at 960×540, 9 at 96×54). The
//! singular derivative of `sqrt` at `d_y = 0` (inside the quad scene's sky,
//! on the plane's horizon) is integrated exactly, not sampled.
//!
//! The per-pixel error bound (tail + sky + f32 output rounding) is returned
//! in [`ClosedForm::bounds`].

use std::sync::Mutex;
use std::sync::atomic::{AtomicUsize, Ordering};

use quadtex_core::{Rgba, WrapMode};
use quadtex_render::Scene;
use quadtex_render::Vec3;
use quadtex_render::{Geometry, Lighting, Sky, Surface};

/// Bound on the far-tail error of one pixel edge's periodic part (plane
/// scenes, horizon row only), per channel.
pub const EDGE_BUDGET: f64 = 3e-7;
/// Bound on the far-tail error of a row's mean part (0 for rows whose
/// means are all equal, such as a checker's).
pub const MEAN_BUDGET: f64 = 1e-7;
/// Bound on the sky quadrature error of one pixel.
pub const SKY_BUDGET: f64 = 1e-7;
/// More bands than this per pixel edge and row: the scene is refused.
const MAX_BANDS: f64 = 5e7;
/// Rounding allowance: f32 output (half an ulp at 1) plus f64 sums.
const ROUNDING: f64 = 6e-8 + 1e-9;

/// The closed-form image with its error bounds.
#[derive(Debug, Clone)]
pub struct ClosedForm {
    /// Row-major pixels, `None` where the method does not apply (never, for
    /// the scenes it accepts).
    pub pixels: Vec<Option<Rgba>>,
    /// Per pixel, a bound on `|computed − exact|` per channel.
    pub bounds: Vec<f64>,
}

impl ClosedForm {
    /// Fraction of pixels covered (`Some`).
    pub fn coverage(&self) -> f64 {
        coverage(&self.pixels)
    }
    /// The largest per-pixel error bound.
    pub fn max_bound(&self) -> f64 {
        self.bounds.iter().copied().fold(0.0, f64::max)
    }
}

/// Fraction of `pixels` that are `Some`.
pub fn coverage(pixels: &[Option<Rgba>]) -> f64 {
    if pixels.is_empty() {
        return 0.0;
    }
    pixels.iter().filter(|p| p.is_some()).count() as f64 / pixels.len() as f64
}

/// The closed-form box-filtered image of a scene made of one unlit,
/// textured surface (a **plane**, or a **quad** whose outline is a
/// rectangle in texture space) with repeat wrap on both axes, seen with a
/// texture axis parallel to the camera's right vector, in front of the
/// sky: every pixel is the exact integral over the pixel square of the
/// texture (where the surface is seen) and of the sky (elsewhere), within
/// the stated per-pixel bound (see the module docs; at most 1e-6).
/// Returns `None` for scenes of any other kind.
pub fn closed_form_plane(scene: &Scene, width: u32, height: u32) -> Option<Vec<Option<Rgba>>> {
    closed_form(scene, width, height).map(|c| c.pixels)
}

/// As [`closed_form_plane`], with per-pixel error bounds.
pub fn closed_form(scene: &Scene, width: u32, height: u32) -> Option<ClosedForm> {
    let setup = Setup::new(scene, width, height)?;
    let next = AtomicUsize::new(0);
    let rows: Mutex<Vec<(usize, Row)>> = Mutex::new(Vec::new());
    let threads = std::thread::available_parallelism()
        .map(|n| n.get())
        .unwrap_or(1)
        .min(height as usize);
    std::thread::scope(|s| {
        for _ in 0..threads {
            s.spawn(|| {
                loop {
                    let y = next.fetch_add(1, Ordering::Relaxed);
                    if y >= height as usize {
                        break;
                    }
                    let row = setup.row(y as u32);
                    if let Ok(mut r) = rows.lock() {
                        r.push((y, row));
                    }
                }
            });
        }
    });
    let mut rows = rows.into_inner().ok()?;
    rows.sort_by_key(|r| r.0);
    if rows.len() != height as usize {
        return None;
    }
    let mut pixels = Vec::with_capacity((width * height) as usize);
    let mut bounds = Vec::with_capacity((width * height) as usize);
    for (_, row) in rows {
        for (c, b) in row {
            pixels.push(Some(c));
            bounds.push(b);
        }
    }
    Some(ClosedForm { pixels, bounds })
}

type C4 = [f64; 4];
/// One row of pixels with their error bounds.
type Row = Vec<(Rgba, f64)>;

fn add(a: C4, b: C4, s: f64) -> C4 {
    [
        a[0] + s * b[0],
        a[1] + s * b[1],
        a[2] + s * b[2],
        a[3] + s * b[3],
    ]
}

/// Everything a row needs.
struct Setup {
    width: u32,
    /// Texture (X, Z, 1) → screen (sx·w, sy·w, w), w = depth.
    m: [[f64; 3]; 3],
    /// Its inverse: screen (sx, sy, 1) → (X, Z, 1)/w.
    n: [[f64; 3]; 3],
    /// Cells per tile side and cell size.
    cells: usize,
    h: f64,
    /// `colour[j][i]`: cell `i` along X of row `j` along Z (after any swap).
    colour: Vec<Vec<C4>>,
    /// Plane: row means, and the periodic part at each cell's left edge.
    mean: Vec<C4>,
    p_left: Vec<Vec<C4>>,
    /// Quad: cumulative integral of a row from X = 0 at each cell's left edge.
    cum: Vec<Vec<C4>>,
    /// Texture rectangle of a quad (`None`: plane).
    rect: Option<[f64; 4]>,
    /// Plane tail: cut distance from the horizon, the mean-part constants.
    p_max: f64,
    mean_bar: C4,
    mean_b: f64,
    /// Where the surface is seen, as half-planes `a·x + b·y + c ≥ 0`.
    outline: Vec<[f64; 3]>,
    sky: SkyModel,
    /// Sub-squares per pixel side for the sky, and the resulting bound.
    sky_subdivision: usize,
    sky_bound: f64,
}

/// The sky as `h + Δ·sqrt(max(L,0))·ν`.
struct SkyModel {
    horizon: C4,
    delta: C4,
    /// `L(x, y) = g[0] x + g[1] y + g[2]` (unnormalised ray direction's y).
    g: [f64; 3],
    /// `ν = |d|^(-1/2)` as a function of screen position.
    nu: Box<dyn Fn(f64, f64) -> f64 + Send + Sync>,
}

fn c4(c: Rgba) -> C4 {
    c.to_array().map(f64::from)
}

/// The camera as the reference uses it: eye, orthonormal basis, the
/// tangent of half the vertical field of view and the image size.
struct CameraFrame {
    eye: Vec3,
    fwd: Vec3,
    up: Vec3,
    right: Vec3,
    tan_half: f64,
    /// Pixels per unit of the image plane at depth 1.
    kf: f64,
    wf: f64,
    hf: f64,
}

impl CameraFrame {
    /// The camera basis, recovered from its rays.
    fn new(scene: &Scene, width: u32, height: u32) -> CameraFrame {
        let camera = scene.camera.with_size(width, height);
        let (wf, hf) = (f64::from(width), f64::from(height));
        let eye = camera.ray(0.0, 0.0).origin;
        let fwd = camera.forward();
        let basis = |px: f64, py: f64| {
            let d = camera.ray(px, py).direction;
            d * (1.0 / d.dot(fwd)) - fwd
        };
        let up_t = basis(wf / 2.0, 0.0);
        let tan_half = up_t.length();
        let up = up_t * (1.0 / tan_half);
        let right_t = basis(wf, hf / 2.0);
        let right = right_t * (1.0 / right_t.length());
        let kf = hf / (2.0 * tan_half);
        CameraFrame {
            eye,
            fwd,
            up,
            right,
            tan_half,
            kf,
            wf,
            hf,
        }
    }
}

/// The texture→screen homography of a surface and what shapes it.
struct Projection {
    /// Texture (X, Z, 1) → screen (sx·w, sy·w, w), w = depth.
    m: [[f64; 3]; 3],
    /// Its inverse.
    n: [[f64; 3]; 3],
    /// Whether the texture's axes were swapped to put X along the camera's
    /// right vector.
    swapped: bool,
    /// A quad (bounded) rather than a plane.
    is_quad: bool,
}

impl Setup {
    fn new(scene: &Scene, width: u32, height: u32) -> Option<Setup> {
        let [surface] = scene.surfaces.as_slice() else {
            return None;
        };
        let (Some(texture), Lighting::Unlit, (WrapMode::Repeat, WrapMode::Repeat)) = (
            &surface.texture,
            scene.lighting,
            (surface.wrap.x(), surface.wrap.z()),
        ) else {
            return None;
        };
        let tree = &texture.tree;
        // Cells at the depth must be uniform: leaves that keep a gradient
        // or contours are not.
        if tree.depth() > 12 || tree.gradient_leaves().is_some() || tree.contour_leaves().is_some()
        {
            return None;
        }
        let cells = 1usize << tree.depth();
        let h = 1.0 / cells as f64;
        let mut colour = cell_colours(tree, c4(surface.colour), cells, h)?;
        let frame = CameraFrame::new(scene, width, height);
        let Projection {
            m,
            n,
            swapped,
            is_quad,
        } = projection(surface, &frame)?;
        if swapped {
            colour = (0..cells)
                .map(|i| (0..cells).map(|j| colour[j][i]).collect())
                .collect();
        }
        let rect = if is_quad {
            Some(quad_rect(surface, &m, swapped)?)
        } else {
            None
        };
        let RowSums {
            mean,
            p_left,
            cum,
            p_max,
        } = row_sums(&colour, cells, h);
        let (mean_bar, mean_b) = mean_tail(&mean, cells);
        let outline = outline(rect, &m, &n);
        let (sky, sky_subdivision, sky_bound) = sky_model(scene, &frame);
        let setup = Setup {
            width,
            m,
            n,
            cells,
            h,
            colour,
            mean,
            p_left,
            cum,
            rect,
            p_max,
            mean_bar,
            mean_b,
            outline,
            sky_subdivision,
            sky_bound,
            sky,
        };
        Some(setup)
    }

    /// `1/w` at screen row `y` (positive where the surface is in front).
    fn inv_w(&self, y: f64) -> f64 {
        self.n[2][1] * y + self.n[2][2]
    }
    /// Texture Z at screen row `y`.
    fn z_at(&self, y: f64) -> f64 {
        (self.n[1][1] * y + self.n[1][2]) / self.inv_w(y)
    }
    /// Screen row of texture row `z`.
    fn y_of_z(&self, z: f64) -> f64 {
        (self.m[1][1] * z + self.m[1][2]) / (self.m[2][1] * z + self.m[2][2])
    }
    /// Texture X at screen point `(e, y)`.
    fn x_at(&self, e: f64, y: f64) -> f64 {
        (self.n[0][0] * e + self.n[0][1] * y + self.n[0][2]) / self.inv_w(y)
    }
    /// Screen row where the pixel edge `sx = e` meets texture column `x`.
    fn y_of_x(&self, e: f64, x: f64) -> f64 {
        // n00 e + n01 y + n02 = x (n21 y + n22)
        (x * self.n[2][2] - self.n[0][2] - self.n[0][0] * e) / (self.n[0][1] - x * self.n[2][1])
    }

    /// The visible interval of screen rows within `[y0, y1]`, and whether
    /// its end at index 0/1 is the horizon.
    fn visible(&self, y0: f64, y1: f64) -> Option<(f64, f64, [bool; 2])> {
        let (mut lo, mut hi, mut horizon) = (y0, y1, [false, false]);
        let (a, b) = (self.n[2][1], self.n[2][2]);
        if a == 0.0 {
            if b <= 0.0 {
                return None;
            }
        } else {
            let yh = -b / a;
            if a > 0.0 && yh >= lo {
                lo = yh;
                horizon[0] = true;
            } else if a < 0.0 && yh <= hi {
                hi = yh;
                horizon[1] = true;
            }
        }
        if let Some([_, z0, _, z1]) = self.rect {
            let (ya, yb) = (self.y_of_z(z0), self.y_of_z(z1));
            lo = lo.max(ya.min(yb));
            hi = hi.min(ya.max(yb));
            horizon = [false, false];
        }
        (hi > lo).then_some((lo, hi, horizon))
    }

    /// One row of pixels with their bounds.
    fn row(&self, py: u32) -> Row {
        let w = self.width as usize;
        let (y0, y1) = (f64::from(py), f64::from(py) + 1.0);
        let mut edges = vec![[0.0; 4]; w + 1];
        let mut mean_part = [0.0; 4];
        let mut tail_bound = 0.0;
        if let Some((lo, hi, horizon)) = self.visible(y0, y1) {
            let (mut lo, mut hi) = (lo, hi);
            // The far tail beside the horizon.
            let slope = (self.m[0][0] * self.n[2][1]).abs();
            if horizon[0] || horizon[1] {
                let yh = if horizon[0] { lo } else { hi };
                let mut delta = (2.0 * EDGE_BUDGET / (self.p_max * slope).max(1e-300)).sqrt();
                if self.mean_b > 0.0 {
                    delta = delta.min(MEAN_BUDGET / self.mean_b);
                }
                delta = delta.min(hi - lo);
                let cut = if horizon[0] { yh + delta } else { yh - delta };
                let tail = (cut - yh).abs();
                mean_part = add(mean_part, self.mean_bar, tail);
                tail_bound = 2.0 * self.p_max * slope * tail * tail / 2.0 + self.mean_b * tail;
                if horizon[0] {
                    lo = cut;
                } else {
                    hi = cut;
                }
            }
            let (za, zb) = (self.z_at(lo), self.z_at(hi));
            let (zmin, zmax) = (za.min(zb), za.max(zb));
            if (zmax - zmin) / self.h > MAX_BANDS {
                return vec![(Rgba::new(0.0, 0.0, 0.0, 0.0), f64::INFINITY); w];
            }
            let (j0, j1) = (
                (zmin / self.h).floor() as i64,
                (zmax / self.h).ceil() as i64,
            );
            for j in j0..j1 {
                let (ya, yb) = (
                    self.y_of_z(j as f64 * self.h),
                    self.y_of_z((j + 1) as f64 * self.h),
                );
                let (ba, bb) = (ya.min(yb).max(lo), ya.max(yb).min(hi));
                if bb <= ba {
                    continue;
                }
                let jr = j.rem_euclid(self.cells as i64) as usize;
                if self.rect.is_none() {
                    mean_part = add(mean_part, self.mean[jr], bb - ba);
                }
                for (e, acc) in edges.iter_mut().enumerate() {
                    *acc = add(*acc, self.band_edge(jr, e as f64, ba, bb), 1.0);
                }
            }
        }
        let sky_bound = self.sky_bound;
        (0..w)
            .map(|px| {
                let mut c = add(add(edges[px + 1], edges[px], -1.0), mean_part, 1.0);
                let (sky, has_sky) = self.sky_part(px as f64, f64::from(py));
                c = add(c, sky, 1.0);
                let bound = tail_bound + if has_sky { sky_bound } else { 0.0 } + ROUNDING;
                (
                    Rgba::new(c[0] as f32, c[1] as f32, c[2] as f32, c[3] as f32),
                    bound,
                )
            })
            .collect()
    }

    /// `∫ b(y)·F_j(X_e(y)) dy` over `[ya, yb]` inside band `j`.
    fn band_edge(&self, j: usize, e: f64, ya: f64, yb: f64) -> C4 {
        let (xa, xb) = (self.x_at(e, ya), self.x_at(e, yb));
        let mut acc = [0.0; 4];
        let (mut ys, mut xs) = (ya, xa);
        let up = xb >= xa;
        // Breakpoints strictly between xa and xb, in order.
        let next_break = |x: f64| -> f64 {
            let mut nb = if up {
                (x / self.h).floor() * self.h + self.h
            } else {
                (x / self.h).ceil() * self.h - self.h
            };
            if let Some([x0, _, x1, _]) = self.rect {
                for v in [x0, x1] {
                    if up && v > x && v < nb || !up && v < x && v > nb {
                        nb = v;
                    }
                }
            }
            nb
        };
        loop {
            let nb = next_break(xs);
            let done = if up { nb >= xb } else { nb <= xb };
            let (ye, xe) = if done {
                (yb, xb)
            } else {
                (self.y_of_x(e, nb).clamp(ys, yb), nb)
            };
            if ye > ys {
                let xm = (xs + xe) / 2.0;
                let (value, slope, xi) = self.piece(j, xm);
                let ym = (ys + ye) / 2.0;
                let b = self.m[0][0] * self.inv_w(ym);
                // e − a(y) − b(y)·X_i = b·(X_e(y) − X_i), affine in y.
                let rel = self.m[0][0]
                    * (self.n[0][0] * e + self.n[0][1] * ym + self.n[0][2] - self.inv_w(ym) * xi);
                for ch in 0..4 {
                    acc[ch] += (ye - ys) * (value[ch] * b + slope[ch] * rel);
                }
            }
            if done {
                break;
            }
            (ys, xs) = (ye, xe);
        }
        acc
    }

    /// The linear piece of `F_j` containing `x`: value at `x_i`, slope, `x_i`.
    fn piece(&self, j: usize, x: f64) -> (C4, C4, f64) {
        let i = (x / self.h).floor() as i64;
        let ir = i.rem_euclid(self.cells as i64) as usize;
        let xi = i as f64 * self.h;
        match self.rect {
            None => (
                self.p_left[j][ir],
                add(self.colour[j][ir], self.mean[j], -1.0),
                xi,
            ),
            Some([x0, _, x1, _]) => {
                let cum = |x: f64| {
                    let i = (x / self.h).floor() as i64;
                    let ir = i.rem_euclid(self.cells as i64) as usize;
                    let tiles = i.div_euclid(self.cells as i64) as f64;
                    let base = add(self.cum[j][ir], self.mean[j], tiles);
                    add(base, self.colour[j][ir], x - i as f64 * self.h)
                };
                let start = cum(x0);
                if x < x0 {
                    ([0.0; 4], [0.0; 4], x0)
                } else if x > x1 {
                    (add(cum(x1), start, -1.0), [0.0; 4], x1)
                } else {
                    let left = xi.max(x0);
                    (add(cum(left), start, -1.0), self.colour[j][ir], left)
                }
            }
        }
    }

    /// The sky over the part of pixel `(px, py)` the surface does not cover,
    /// and whether there is any.
    fn sky_part(&self, px: f64, py: f64) -> (C4, bool) {
        let pixel = [
            [px, py],
            [px + 1.0, py],
            [px + 1.0, py + 1.0],
            [px, py + 1.0],
        ];
        let inside = |p: &[f64; 2], hp: &[f64; 3]| hp[0] * p[0] + hp[1] * p[1] + hp[2] >= 0.0;
        if pixel
            .iter()
            .all(|p| self.outline.iter().all(|hp| inside(p, hp)))
        {
            return ([0.0; 4], false);
        }
        // n × n sub-squares, each with its own tangent plane of ν.
        let n = self.sky_subdivision;
        let step = 1.0 / n as f64;
        let mut out = [0.0; 4];
        for j in 0..n {
            for i in 0..n {
                let (x0, y0) = (px + i as f64 * step, py + j as f64 * step);
                let sub = vec![
                    [x0, y0],
                    [x0 + step, y0],
                    [x0 + step, y0 + step],
                    [x0, y0 + step],
                ];
                let mut seen = sub.clone();
                for hp in &self.outline {
                    seen = clip_halfplane(&seen, *hp);
                }
                let centre = [x0 + step / 2.0, y0 + step / 2.0];
                out = add(out, self.sky_integral(&sub, centre), 1.0);
                if seen.len() >= 3 {
                    out = add(out, self.sky_integral(&seen, centre), -1.0);
                }
            }
        }
        (out, true)
    }

    /// `∫_poly sky` with `ν` replaced by its tangent plane at `c`.
    fn sky_integral(&self, poly: &[[f64; 2]], c: [f64; 2]) -> C4 {
        let s = &self.sky;
        let area = signed_area(poly).abs();
        let mut out = s.horizon.map(|v| v * area);
        if s.delta.iter().all(|d| *d == 0.0) || poly.len() < 3 {
            return out;
        }
        let lpos = clip_halfplane(poly, s.g);
        if lpos.len() < 3 {
            return out;
        }
        let (m0, m1) = sqrt_moments(&lpos, s.g);
        let e = 1e-3;
        let nu0 = (s.nu)(c[0], c[1]);
        let gx = ((s.nu)(c[0] + e, c[1]) - (s.nu)(c[0] - e, c[1])) / (2.0 * e);
        let gy = ((s.nu)(c[0], c[1] + e) - (s.nu)(c[0], c[1] - e)) / (2.0 * e);
        let v = nu0 * m0 + gx * (m1[0] - c[0] * m0) + gy * (m1[1] - c[1] * m0);
        out = add(out, s.delta, v);
        out
    }
}

/// `colour[j][i]`: the mean colour of cell `i` along texture x, `j` along
/// texture z, times `tint`.
fn cell_colours(
    tree: &quadtex_core::QuadTree,
    tint: C4,
    cells: usize,
    h: f64,
) -> Option<Vec<Vec<C4>>> {
    let mut colour: Vec<Vec<C4>> = Vec::with_capacity(cells);
    for j in 0..cells {
        let mut row = Vec::with_capacity(cells);
        for i in 0..cells {
            let f = quadtex_core::Fragment::new(
                i as f64 * h,
                j as f64 * h,
                (i + 1) as f64 * h,
                (j + 1) as f64 * h,
            )
            .ok()?;
            let c = c4(tree.weighted_colour(&f, u8::MAX).mean_over(f.area()));
            row.push([
                c[0] * tint[0],
                c[1] * tint[1],
                c[2] * tint[2],
                c[3] * tint[3],
            ]);
        }
        colour.push(row);
    }
    Some(colour)
}

/// The surface's texture→screen homography; `None` unless it is a plane
/// or quad with a texture axis parallel to the camera's right vector.
fn projection(surface: &Surface, frame: &CameraFrame) -> Option<Projection> {
    let CameraFrame {
        eye,
        fwd,
        up,
        right,
        kf,
        wf,
        hf,
        ..
    } = *frame;
    // Texture → world, affine.
    let uv0 = surface.uv_transform.invert([0.0, 0.0]);
    let uvx = surface.uv_transform.invert([1.0, 0.0]);
    let uvz = surface.uv_transform.invert([0.0, 1.0]);
    let (base, ea, eb, is_quad) = match surface.geometry {
        Geometry::Plane {
            point,
            u_axis,
            v_axis,
            ..
        } => (point, u_axis, v_axis, false),
        Geometry::Quad {
            origin,
            edge_u,
            edge_v,
        } => (origin, edge_u, edge_v, true),
        _ => return None,
    };
    let lin = |uv: [f64; 2]| ea * uv[0] + eb * uv[1];
    let q0 = base + lin(uv0) - eye;
    let mut qx = lin([uvx[0] - uv0[0], uvx[1] - uv0[1]]);
    let mut qz = lin([uvz[0] - uv0[0], uvz[1] - uv0[1]]);
    let aligned = |q: Vec3| {
        let l = q.length();
        q.dot(fwd).abs() <= 1e-12 * l && q.dot(up).abs() <= 1e-12 * l
    };
    let swapped = if aligned(qx) {
        false
    } else if aligned(qz) {
        std::mem::swap(&mut qx, &mut qz);
        true
    } else {
        return None;
    };
    let row_of = |q: Vec3, zero_w: bool| -> [f64; 3] {
        let w = if zero_w { 0.0 } else { q.dot(fwd) };
        [
            wf / 2.0 * w + kf * q.dot(right),
            hf / 2.0 * w - kf * q.dot(up),
            w,
        ]
    };
    let (cx, cz, c0) = (row_of(qx, true), row_of(qz, false), row_of(q0, false));
    let mut m = [
        [cx[0], cz[0], c0[0]],
        [0.0, cz[1], c0[1]],
        [0.0, cz[2], c0[2]],
    ];
    let _ = cx;
    let n = invert3(&m)?;
    m[1][0] = 0.0;
    Some(Projection {
        m,
        n,
        swapped,
        is_quad,
    })
}

/// The texture rectangle `[x0, z0, x1, z1]` of a quad; `None` unless its
/// corners form a texture-axis rectangle all in front of the camera.
fn quad_rect(surface: &Surface, m: &[[f64; 3]; 3], swapped: bool) -> Option<[f64; 4]> {
    let swap2 = |t: [f64; 2]| if swapped { [t[1], t[0]] } else { t };
    let corners = [[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]]
        .map(|uv| swap2(surface.uv_transform.apply(uv)));
    let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
    for c in &corners {
        for a in 0..2 {
            lo[a] = lo[a].min(c[a]);
            hi[a] = hi[a].max(c[a]);
        }
    }
    let tol = 1e-9 * (1.0 + hi[0] - lo[0] + hi[1] - lo[1]);
    let on_box = |c: &[f64; 2]| {
        ((c[0] - lo[0]).abs() < tol || (c[0] - hi[0]).abs() < tol)
            && ((c[1] - lo[1]).abs() < tol || (c[1] - hi[1]).abs() < tol)
    };
    if !corners.iter().all(on_box) {
        return None;
    }
    for c in &corners {
        if m[2][0] * c[0] + m[2][1] * c[1] + m[2][2] <= 1e-9 {
            return None;
        }
    }
    Some([lo[0], lo[1], hi[0], hi[1]])
}

/// Per texture row: its mean, the periodic part at each cell's left edge,
/// the cumulative integral from X = 0, and the largest periodic part.
struct RowSums {
    mean: Vec<C4>,
    p_left: Vec<Vec<C4>>,
    cum: Vec<Vec<C4>>,
    p_max: f64,
}

/// Row means, periodic parts, cumulative sums of `colour`.
fn row_sums(colour: &[Vec<C4>], cells: usize, h: f64) -> RowSums {
    let mut mean = Vec::with_capacity(cells);
    let mut p_left = Vec::with_capacity(cells);
    let mut cum = Vec::with_capacity(cells);
    let mut p_max = 0f64;
    for row in colour {
        let mut c = vec![[0.0; 4]; cells + 1];
        for i in 0..cells {
            c[i + 1] = add(c[i], row[i], h);
        }
        let mu = c[cells];
        let raw: Vec<C4> = (0..=cells)
            .map(|i| add(c[i], mu, -(i as f64) * h))
            .collect();
        let mut kappa = [0.0; 4];
        for (ch, k) in kappa.iter_mut().enumerate() {
            let lo = raw.iter().map(|r| r[ch]).fold(f64::INFINITY, f64::min);
            let hi = raw.iter().map(|r| r[ch]).fold(f64::NEG_INFINITY, f64::max);
            *k = (lo + hi) / 2.0;
            p_max = p_max.max((hi - lo) / 2.0);
        }
        p_left.push(raw.iter().map(|r| add(*r, kappa, -1.0)).collect());
        mean.push(mu);
        cum.push(c);
    }
    RowSums {
        mean,
        p_left,
        cum,
        p_max,
    }
}

/// The plane tail's constants: the mean of the row means, and the bound
/// on partial sums of their deviations from it.
fn mean_tail(mean: &[C4], cells: usize) -> (C4, f64) {
    let mut mean_bar = [0.0; 4];
    for mu in mean {
        mean_bar = add(mean_bar, *mu, 1.0 / cells as f64);
    }
    // Abel summation: partial sums of μ_j − μ̄ over any run are at most
    // twice the largest prefix sum; the first (partial) band adds one term.
    let mut mean_b = 0f64;
    for ch in 0..4 {
        let (mut s, mut prefix, mut term) = (0f64, 0f64, 0f64);
        for mu in mean {
            s += mu[ch] - mean_bar[ch];
            prefix = prefix.max(s.abs());
            term = term.max((mu[ch] - mean_bar[ch]).abs());
        }
        mean_b = mean_b.max(2.0 * prefix + term);
    }
    (mean_bar, mean_b)
}

/// Where the surface is seen, as half-planes `a·x + b·y + c ≥ 0`: in
/// front of the horizon for a plane, inside the projected rectangle for a
/// quad.
fn outline(rect: Option<[f64; 4]>, m: &[[f64; 3]; 3], n: &[[f64; 3]; 3]) -> Vec<[f64; 3]> {
    match rect {
        None => vec![[0.0, n[2][1], n[2][2]]],
        Some([x0, z0, x1, z1]) => {
            let p = |x: f64, z: f64| {
                let w = m[2][0] * x + m[2][1] * z + m[2][2];
                [
                    (m[0][0] * x + m[0][1] * z + m[0][2]) / w,
                    (m[1][1] * z + m[1][2]) / w,
                ]
            };
            let poly = [p(x0, z0), p(x1, z0), p(x1, z1), p(x0, z1)];
            let s = signed_area(&poly).signum();
            (0..4)
                .map(|k| {
                    let (a, b) = (poly[k], poly[(k + 1) % 4]);
                    // s·cross(b − a, q − a) ≥ 0 inside.
                    [
                        -s * (b[1] - a[1]),
                        s * (b[0] - a[0]),
                        s * ((b[1] - a[1]) * a[0] - (b[0] - a[0]) * a[1]),
                    ]
                })
                .collect()
        }
    }
}

/// The sky seen through `frame`, with the sub-squares per pixel side its
/// integral needs to stay within [`SKY_BUDGET`] and the resulting bound.
fn sky_model(scene: &Scene, frame: &CameraFrame) -> (SkyModel, usize, f64) {
    let CameraFrame {
        fwd,
        up,
        right,
        tan_half,
        wf,
        hf,
        ..
    } = *frame;
    let (horizon, zenith) = match scene.sky {
        Sky::Solid(c) => (c4(c), c4(c)),
        Sky::Gradient { horizon, zenith } => (c4(horizon), c4(zenith)),
    };
    let delta = add(zenith, horizon, -1.0);
    let k = 2.0 * tan_half / hf;
    // d(x, y) = fwd + right·(x − W/2)·k + up·(H/2 − y)·k.
    let g = [
        right.y * k,
        -up.y * k,
        fwd.y - right.y * k * wf / 2.0 + up.y * k * hf / 2.0,
    ];
    let nu = move |x: f64, y: f64| {
        let (a, b) = ((x - wf / 2.0) * k, (hf / 2.0 - y) * k);
        (1.0 + a * a + b * b).powf(-0.25)
    };
    let corner_len = (1.0 + (wf / 2.0 * k).powi(2) + (hf / 2.0 * k).powi(2)).sqrt();
    // Per polygon ≤ |Δ|·sqrt(L_max)·(k²/2)/2·∫|x − c|², ∫|x − c|² = 1/(6n⁴)
    // per sub-square, n² sub-squares, two polygons each: 2|Δ|·sqrt(L_max)·k²/(24 n²).
    let dmax = delta.iter().fold(0f64, |m, d| m.max(d.abs()));
    let one = 2.0 * dmax * corner_len.sqrt() * k * k / 24.0;
    let sky_subdivision = ((one / SKY_BUDGET).sqrt().ceil() as usize).clamp(1, 64);
    let sky_bound = one / (sky_subdivision * sky_subdivision) as f64;
    let sky = SkyModel {
        horizon,
        delta,
        g,
        nu: Box::new(nu),
    };
    (sky, sky_subdivision, sky_bound)
}

/// `∫ sqrt(L)` and `∫ sqrt(L)·(x, y)` over a convex polygon where
/// `L = g0 x + g1 y + g2 ≥ 0`, by the divergence theorem: with `G = ∇L`,
/// `div(⅔ L^{3/2} G/|G|²) = sqrt(L)`, `div(⅖ L^{5/2} G/|G|²) = L^{3/2}`,
/// `div(⅔ L^{3/2} s G/|G|²) = sqrt(L)·s` for `s ⊥ G`.
fn sqrt_moments(poly: &[[f64; 2]], g: [f64; 3]) -> (f64, [f64; 2]) {
    let gg = g[0] * g[0] + g[1] * g[1];
    if gg < 1e-300 {
        // L constant over the screen.
        let area = signed_area(poly).abs();
        let r = g[2].max(0.0).sqrt() * area;
        let c = centroid(poly);
        return (r, [c[0] * r, c[1] * r]);
    }
    let l = |p: [f64; 2]| (g[0] * p[0] + g[1] * p[1] + g[2]).max(0.0);
    let orient = signed_area(poly).signum();
    let (mut m0, mut m32, mut ms) = (0.0, 0.0, 0.0);
    let perp = [-g[1] / gg.sqrt(), g[0] / gg.sqrt()];
    let p_ref = poly[0];
    let s_of = |p: [f64; 2]| perp[0] * (p[0] - p_ref[0]) + perp[1] * (p[1] - p_ref[1]);
    let n = poly.len();
    for k in 0..n {
        let (p, q) = (poly[k], poly[(k + 1) % n]);
        // Outward normal times length.
        let flux = orient * (g[0] * (q[1] - p[1]) - g[1] * (q[0] - p[0])) / gg;
        if flux == 0.0 {
            continue;
        }
        let (la, lb) = (l(p), l(q));
        let (y, x) = (la.sqrt(), lb.sqrt());
        let avg = |powers: i32, denom: f64| -> f64 {
            // (2/denom)·(x^(powers+1)... ): ∫₀¹ ℓ^((powers−1)/2)
            if x + y == 0.0 {
                return 0.0;
            }
            let mut sum = 0.0;
            for i in 0..=powers {
                sum += x.powi(powers - i) * y.powi(i);
            }
            2.0 / denom * sum / (x + y)
        };
        let a32 = avg(4, 5.0); // avg of L^{3/2}
        let a52 = avg(6, 7.0); // avg of L^{5/2}
        m0 += flux * 2.0 / 3.0 * a32;
        m32 += flux * 2.0 / 5.0 * a52;
        // avg of L^{3/2}·s, s linear along the edge: 8-point Gauss.
        let (sa, sb) = (s_of(p), s_of(q));
        let mut a = 0.0;
        for (t, wt) in GAUSS8 {
            let tau = 0.5 * (t + 1.0);
            let lt = la + (lb - la) * tau;
            a += 0.5 * wt * lt.max(0.0).powf(1.5) * (sa + (sb - sa) * tau);
        }
        ms += flux * 2.0 / 3.0 * a;
    }
    // x = p_ref + (L − L_ref)·G/|G|² + s·perp.
    let lref = g[0] * p_ref[0] + g[1] * p_ref[1] + g[2];
    let along = m32 - lref * m0;
    let m1 = [
        p_ref[0] * m0 + g[0] / gg * along + perp[0] * ms,
        p_ref[1] * m0 + g[1] / gg * along + perp[1] * ms,
    ];
    (m0, m1)
}

const GAUSS8: [(f64, f64); 8] = [
    (-0.960_289_856_497_536_3, 0.101_228_536_290_376_26),
    (-0.796_666_477_413_626_7, 0.222_381_034_453_374_47),
    (-0.525_532_409_916_329, 0.313_706_645_877_887_3),
    (-0.183_434_642_495_649_8, 0.362_683_783_378_362),
    (0.183_434_642_495_649_8, 0.362_683_783_378_362),
    (0.525_532_409_916_329, 0.313_706_645_877_887_3),
    (0.796_666_477_413_626_7, 0.222_381_034_453_374_47),
    (0.960_289_856_497_536_3, 0.101_228_536_290_376_26),
];

fn centroid(p: &[[f64; 2]]) -> [f64; 2] {
    let n = p.len();
    let (mut cx, mut cy, mut a) = (0.0, 0.0, 0.0);
    for i in 0..n {
        let (u, v) = (p[i], p[(i + 1) % n]);
        let cross = u[0] * v[1] - v[0] * u[1];
        a += cross;
        cx += (u[0] + v[0]) * cross;
        cy += (u[1] + v[1]) * cross;
    }
    if a == 0.0 {
        return p.first().copied().unwrap_or([0.0, 0.0]);
    }
    [cx / (3.0 * a), cy / (3.0 * a)]
}

fn signed_area(p: &[[f64; 2]]) -> f64 {
    let n = p.len();
    (0..n)
        .map(|i| p[i][0] * p[(i + 1) % n][1] - p[(i + 1) % n][0] * p[i][1])
        .sum::<f64>()
        * 0.5
}

/// The part of convex `poly` where `hp[0]·x + hp[1]·y + hp[2] ≥ 0`.
fn clip_halfplane(poly: &[[f64; 2]], hp: [f64; 3]) -> Vec<[f64; 2]> {
    let side = |p: [f64; 2]| hp[0] * p[0] + hp[1] * p[1] + hp[2];
    let mut out = Vec::with_capacity(poly.len() + 1);
    for i in 0..poly.len() {
        let (p, q) = (poly[i], poly[(i + 1) % poly.len()]);
        let (sp, sq) = (side(p), side(q));
        if sp >= 0.0 {
            out.push(p);
        }
        if (sp >= 0.0) != (sq >= 0.0) {
            let t = sp / (sp - sq);
            out.push([p[0] + t * (q[0] - p[0]), p[1] + t * (q[1] - p[1])]);
        }
    }
    out
}

fn invert3(m: &[[f64; 3]; 3]) -> Option<[[f64; 3]; 3]> {
    let c = |r: usize, k: usize| {
        let (r1, r2) = ((r + 1) % 3, (r + 2) % 3);
        let (k1, k2) = ((k + 1) % 3, (k + 2) % 3);
        m[r1][k1] * m[r2][k2] - m[r1][k2] * m[r2][k1]
    };
    let det = m[0][0] * c(0, 0) + m[0][1] * c(0, 1) + m[0][2] * c(0, 2);
    if det.abs() < 1e-300 || !det.is_finite() {
        return None;
    }
    let mut inv = [[0.0; 3]; 3];
    for (r, row) in inv.iter_mut().enumerate() {
        for (k, v) in row.iter_mut().enumerate() {
            *v = c(k, r) / det;
        }
    }
    Some(inv)
}

#[cfg(test)]
mod tests;
