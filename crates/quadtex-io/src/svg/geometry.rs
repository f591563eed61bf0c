//! Affine transforms and 2-D vector arithmetic in `f64`.

/// A transform as `[sx, ky, kx, sy, tx, ty]` in `f64`:
/// `x' = sx·x + kx·y + tx`, `y' = ky·x + sy·y + ty`.
pub(super) fn affine(t: usvg::Transform) -> [f64; 6] {
    [t.sx, t.ky, t.kx, t.sy, t.tx, t.ty].map(f64::from)
}

/// `m` applied to point `p`.
pub(super) fn apply(m: [f64; 6], p: [f64; 2]) -> [f64; 2] {
    [
        m[0] * p[0] + m[2] * p[1] + m[4],
        m[1] * p[0] + m[3] * p[1] + m[5],
    ]
}

/// `a ∘ b` (apply `b` first).
pub(super) fn concat(a: [f64; 6], b: [f64; 6]) -> [f64; 6] {
    let [a0, a1, a2, a3, a4, a5] = a;
    let [b0, b1, b2, b3, b4, b5] = b;
    [
        a0 * b0 + a2 * b1,
        a1 * b0 + a3 * b1,
        a0 * b2 + a2 * b3,
        a1 * b2 + a3 * b3,
        a0 * b4 + a2 * b5 + a4,
        a1 * b4 + a3 * b5 + a5,
    ]
}

pub(super) fn invert(m: [f64; 6]) -> Option<[f64; 6]> {
    let [a, b, c, d, e, f] = m;
    let det = a * d - b * c;
    if !(det.is_finite() && det.abs() > f64::MIN_POSITIVE) {
        return None;
    }
    let inv = [d / det, -b / det, -c / det, a / det];
    let r = [
        inv[0],
        inv[1],
        inv[2],
        inv[3],
        -(inv[0] * e + inv[2] * f),
        -(inv[1] * e + inv[3] * f),
    ];
    r.iter().all(|v| v.is_finite()).then_some(r)
}

/// Chords needed for a curve whose error bound with one chord is `ratio`
/// tolerances (the error falls as `1/n²`); at most 65536.
pub(super) fn segments_for(ratio: f64) -> usize {
    if ratio.is_finite() {
        ratio.sqrt().ceil().clamp(1.0, 65536.0) as usize
    } else {
        1
    }
}

pub(super) fn add(a: [f64; 2], b: [f64; 2]) -> [f64; 2] {
    [a[0] + b[0], a[1] + b[1]]
}
pub(super) fn sub(a: [f64; 2], b: [f64; 2]) -> [f64; 2] {
    [a[0] - b[0], a[1] - b[1]]
}
pub(super) fn scale(a: [f64; 2], k: f64) -> [f64; 2] {
    [a[0] * k, a[1] * k]
}
pub(super) fn norm(a: [f64; 2]) -> f64 {
    a[0].hypot(a[1])
}
