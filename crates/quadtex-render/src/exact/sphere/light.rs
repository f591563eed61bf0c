//! How far the light at a polygon's centroid is from the light's mean
//! over it, on a sphere under the box filter
//! ([`SphereView::midpoint_cosine_error`]): a bound of second order in
//! the polygon's size, where the spread of the cosine is of first order.
//!
//! With `c` the polygon's centroid (area), the mean of a smooth `f` over
//! the polygon `R` less `f(c)` is the mean of `f(s) − f(c) − ∇f(c)·(s −
//! c)` (the first moment about `c` vanishes), and each of those is at
//! most `½·(H_xx·dx² + 2·H_xy·|dx·dy| + H_yy·dy²)` with `H_ij` a bound on
//! `|∂²f/∂i∂j|` over `R` (convex, so the segment from `c` to `s` lies in
//! it). Averaged, with `I_xx`, `I_yy` the second moments about `c` and
//! `∫|dx·dy| ≤ √(I_xx·I_yy)`:
//! `|mean f − f(c)| ≤ ½·(H_xx·I_xx + 2·H_xy·√(I_xx·I_yy) + H_yy·I_yy)/A`.
//!
//! The cosine is `f = n·l`. With `d(s) = d0 + dx·x + dy·y` the camera's
//! ray, `m` the centre seen from the camera and `k = |m|² − r²`, the ray
//! meets the sphere's near side at `t = (a − √Q)/g` (`a = m·d`, `g = d·d`,
//! `Q = a² − k·g`), so `f = (t·(l·d) − l·m)/r = (u·w − l·m)/r` with
//! `u = a − √Q`, `w = (l·d)/g`, and
//! `∂²(u·w) = u_ij·w + u_i·w_j + u_j·w_i + u·w_ij`, each factor from `a`,
//! `l·d` (linear in `s`), `g` (convex), `Q` (concave) and their
//! derivatives, all bounded over `R` in interval arithmetic: linear ones
//! by the vertices, `g` and `Q` by the vertices on one side and the
//! tangent plane at `c` on the other. Where `Q` may reach 0 (the outline,
//! where `√Q` has no second derivative) there is no bound.

use quadtex_core::ConvexPolygon;

use crate::math::Vec3;

use super::SphereView;

/// A closed interval of reals.
#[derive(Debug, Clone, Copy)]
struct Interval {
    lo: f64,
    hi: f64,
}

impl Interval {
    fn point(v: f64) -> Interval {
        Interval { lo: v, hi: v }
    }

    fn over(values: impl Iterator<Item = f64>) -> Interval {
        values.fold(
            Interval {
                lo: f64::INFINITY,
                hi: f64::NEG_INFINITY,
            },
            |r, v| Interval {
                lo: r.lo.min(v),
                hi: r.hi.max(v),
            },
        )
    }

    fn add(self, o: Interval) -> Interval {
        Interval {
            lo: self.lo + o.lo,
            hi: self.hi + o.hi,
        }
    }

    fn sub(self, o: Interval) -> Interval {
        Interval {
            lo: self.lo - o.hi,
            hi: self.hi - o.lo,
        }
    }

    fn mul(self, o: Interval) -> Interval {
        let p = [
            self.lo * o.lo,
            self.lo * o.hi,
            self.hi * o.lo,
            self.hi * o.hi,
        ];
        Interval::over(p.into_iter())
    }

    fn scale(self, c: f64) -> Interval {
        self.mul(Interval::point(c))
    }

    /// `1/self`; `None` where `self` may hold 0.
    fn recip(self) -> Option<Interval> {
        (self.lo > 0.0 || self.hi < 0.0).then(|| Interval {
            lo: 1.0 / self.hi,
            hi: 1.0 / self.lo,
        })
    }

    fn magnitude(self) -> f64 {
        self.lo.abs().max(self.hi.abs())
    }
}

impl SphereView {
    /// A bound on `|mean of n·l over piece − n(c)·l|` (`c` the piece's
    /// centroid, `l` the unit direction to the light) for a convex piece
    /// inside the outline (module doc); `None` where the piece reaches
    /// the outline or a number is not finite.
    pub(super) fn midpoint_cosine_error(&self, piece: &ConvexPolygon, l: Vec3) -> Option<f64> {
        let v = piece.vertices();
        let area = piece.area();
        if v.len() < 3 || area.is_nan() || area <= 0.0 {
            return None;
        }
        let c = piece.centroid();
        // Second moments about the centroid.
        let (mut ixx, mut iyy) = (0.0, 0.0);
        for i in 0..v.len() {
            let (p, q) = (v[i], v[(i + 1) % v.len()]);
            let (px, py, qx, qy) = (p[0] - c[0], p[1] - c[1], q[0] - c[0], q[1] - c[1]);
            let cross = px * qy - qx * py;
            ixx += cross * (px * px + px * qx + qx * qx);
            iyy += cross * (py * py + py * qy + qy * qy);
        }
        let (ixx, iyy) = ((ixx / 12.0).abs(), (iyy / 12.0).abs());
        let [d0, dx, dy] = self.basis;
        let m = self.centre - self.camera;
        let axes = [dx, dy];
        let at = |s: [f64; 2]| d0 + dx * s[0] + dy * s[1];
        let linear = |f: &dyn Fn(Vec3) -> f64| Interval::over(v.iter().map(|&s| f(at(s))));
        let a = linear(&|d| m.dot(d));
        let b = linear(&|d| l.dot(d));
        let a_i = axes.map(|e| m.dot(e));
        let b_i = axes.map(|e| l.dot(e));
        let g_i = axes.map(|e| linear(&|d| 2.0 * d.dot(e)));
        let q_i: [Interval; 2] = std::array::from_fn(|i| {
            linear(&|d| 2.0 * m.dot(d) * a_i[i] - self.k * 2.0 * d.dot(axes[i]))
        });
        let g_ij = |i: usize, j: usize| 2.0 * axes[i].dot(axes[j]);
        let q_ij = |i: usize, j: usize| 2.0 * a_i[i] * a_i[j] - self.k * g_ij(i, j);
        // g (convex) and Q (concave): their tangent planes at the centroid
        // bound them on one side, the vertices on the other.
        let dc = at(c);
        let tangent = |value: f64, gradient: [f64; 2]| {
            Interval::over(
                v.iter()
                    .map(|s| value + gradient[0] * (s[0] - c[0]) + gradient[1] * (s[1] - c[1])),
            )
        };
        let g_at = |d: Vec3| d.dot(d);
        let q_at = |d: Vec3| m.dot(d) * m.dot(d) - self.k * d.dot(d);
        let g_vertices = Interval::over(v.iter().map(|&s| g_at(at(s))));
        let q_vertices = Interval::over(v.iter().map(|&s| q_at(at(s))));
        let g_grad = axes.map(|e| 2.0 * dc.dot(e));
        let q_grad = [0, 1].map(|i| 2.0 * m.dot(dc) * a_i[i] - self.k * g_grad[i]);
        let g = Interval {
            lo: tangent(g_at(dc), g_grad).lo,
            hi: g_vertices.hi,
        };
        let q = Interval {
            lo: q_vertices.lo,
            hi: tangent(q_at(dc), q_grad).hi,
        };
        if !(q.lo > 0.0 && g.lo > 0.0) {
            return None;
        }
        let root = Interval {
            lo: q.lo.sqrt(),
            hi: q.hi.sqrt(),
        };
        let inv_root = root.recip()?;
        let inv_g = g.recip()?;
        let inv_root3 = inv_root.mul(inv_root).mul(inv_root);
        let u = a.sub(root);
        let w = b.mul(inv_g);
        let s_i = q_i.map(|qi| qi.mul(inv_root).scale(0.5));
        let u_i: [Interval; 2] = std::array::from_fn(|i| Interval::point(a_i[i]).sub(s_i[i]));
        let w_i: [Interval; 2] = std::array::from_fn(|i| {
            Interval::point(b_i[i])
                .mul(inv_g)
                .sub(b.mul(g_i[i]).mul(inv_g).mul(inv_g))
        });
        let second = |i: usize, j: usize| {
            let qiqj = if i == j {
                let m = q_i[i].magnitude();
                let least = if q_i[i].lo <= 0.0 && q_i[i].hi >= 0.0 {
                    0.0
                } else {
                    q_i[i].lo.abs().min(q_i[i].hi.abs())
                };
                Interval {
                    lo: least * least,
                    hi: m * m,
                }
            } else {
                q_i[i].mul(q_i[j])
            };
            let s_ij = inv_root
                .scale(0.5 * q_ij(i, j))
                .sub(qiqj.mul(inv_root3).scale(0.25));
            let u_ij = Interval::point(0.0).sub(s_ij);
            let inv_g2 = inv_g.mul(inv_g);
            let w_ij = Interval::point(0.0)
                .sub((g_i[j].scale(b_i[i]).add(g_i[i].scale(b_i[j]))).mul(inv_g2))
                .sub(b.scale(g_ij(i, j)).mul(inv_g2))
                .add(b.mul(g_i[i]).mul(g_i[j]).mul(inv_g2).mul(inv_g).scale(2.0));
            u_ij.mul(w)
                .add(u_i[i].mul(w_i[j]))
                .add(u_i[j].mul(w_i[i]))
                .add(u.mul(w_ij))
                .magnitude()
                / self.radius
        };
        let (hxx, hxy, hyy) = (second(0, 0), second(0, 1), second(1, 1));
        let bound = 0.5 * (hxx * ixx + 2.0 * hxy * (ixx * iyy).sqrt() + hyy * iyy) / area;
        // Relative slack for the rounding of the sums above.
        let bound = bound * (1.0 + 1e-9) + 1e-15;
        bound.is_finite().then_some(bound)
    }
}
