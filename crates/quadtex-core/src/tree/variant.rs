//! The six relative positions ("variants") of a fragment's extent `[A, B)` and
//! a square's extent `[lo, hi)` on one axis, and their transitions from a
//! square to its two halves (ALGORITHM.md, paper's eq. 1–8, with the erratum
//! in `F_init` fixed).
//!
//! | V | relation |
//! |---|---|
//! | 0 | fragment entirely below: `B ≤ lo` |
//! | 1 | fragment overlaps the low end only: `A < lo < B < hi` |
//! | 2 | fragment inside the square: `lo ≤ A`, `B < hi` |
//! | 3 | square inside the fragment: `A ≤ lo`, `hi ≤ B` |
//! | 4 | fragment overlaps the high end only: `lo ≤ A < hi ≤ B` |
//! | 5 | fragment entirely above: `A ≥ hi` |

/// A variant number `0..=5` (see the module documentation).
pub type Variant = u8;

/// Fragment entirely below the square.
pub const BELOW: Variant = 0;
/// Fragment overlaps the low end of the square only.
pub const LOW_END: Variant = 1;
/// Fragment lies inside the square.
pub const FRAGMENT_INSIDE: Variant = 2;
/// Square lies inside the fragment.
pub const SQUARE_INSIDE: Variant = 3;
/// Fragment overlaps the high end of the square only.
pub const HIGH_END: Variant = 4;
/// Fragment entirely above the square.
pub const ABOVE: Variant = 5;

/// Initial variant of `[a, b)` against the unit interval `[0, 1)` (eq. 1–2, corrected).
#[inline]
pub fn f_init(a: f64, b: f64) -> Variant {
    if b < 0.0 {
        BELOW
    } else if a < 0.0 {
        if b < 1.0 { LOW_END } else { SQUARE_INSIDE }
    } else if a >= 1.0 {
        ABOVE
    } else if b < 1.0 {
        FRAGMENT_INSIDE
    } else {
        HIGH_END
    }
}

/// Variant of `[a, b)` against the lower half `[lo, m)` of a square whose
/// variant is `v` (eq. 7).
#[inline]
pub fn f_low(a: f64, b: f64, m: f64, v: Variant) -> Variant {
    match v {
        LOW_END => {
            if m >= b {
                LOW_END
            } else {
                SQUARE_INSIDE
            }
        }
        FRAGMENT_INSIDE => {
            if m >= b {
                FRAGMENT_INSIDE
            } else if a <= m {
                HIGH_END
            } else {
                ABOVE
            }
        }
        HIGH_END => {
            if m >= a {
                HIGH_END
            } else {
                ABOVE
            }
        }
        other => other,
    }
}

/// Variant of `[a, b)` against the upper half `[m, hi)` of a square whose
/// variant is `v` (eq. 8).
#[inline]
pub fn f_high(a: f64, b: f64, m: f64, v: Variant) -> Variant {
    match v {
        LOW_END => {
            if m >= b {
                BELOW
            } else {
                LOW_END
            }
        }
        FRAGMENT_INSIDE => {
            if m < a {
                FRAGMENT_INSIDE
            } else if m >= b {
                BELOW
            } else {
                LOW_END
            }
        }
        HIGH_END => {
            if m < a {
                HIGH_END
            } else {
                SQUARE_INSIDE
            }
        }
        other => other,
    }
}

/// Variant of `[a, b)` against an arbitrary interval `[lo, hi)` by direct
/// comparison; used to start a traversal below the root. Where several
/// variants describe the same overlap (zero-width cases) it returns one that
/// yields the same integral.
#[inline]
pub fn classify(a: f64, b: f64, lo: f64, hi: f64) -> Variant {
    if b <= lo {
        BELOW
    } else if a >= hi {
        ABOVE
    } else if a <= lo {
        if b >= hi { SQUARE_INSIDE } else { LOW_END }
    } else if b >= hi {
        HIGH_END
    } else {
        FRAGMENT_INSIDE
    }
}

/// True when the variant means "no overlap".
#[inline]
pub fn is_disjoint(v: Variant) -> bool {
    v == BELOW || v == ABOVE
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// `F_init` exactly as printed in the paper's eq. (2): variants 2 and 3 swapped.
    pub(crate) fn f_init_as_printed(a: f64, b: f64) -> Variant {
        match f_init(a, b) {
            SQUARE_INSIDE => FRAGMENT_INSIDE,
            FRAGMENT_INSIDE => SQUARE_INSIDE,
            v => v,
        }
    }

    /// Length of the overlap implied by a variant, from its definition.
    fn overlap_from_variant(v: Variant, a: f64, b: f64, lo: f64, hi: f64) -> f64 {
        match v {
            BELOW | ABOVE => 0.0,
            LOW_END => b - lo,
            FRAGMENT_INSIDE => b - a,
            SQUARE_INSIDE => hi - lo,
            _ => hi - a,
        }
    }

    fn true_overlap(a: f64, b: f64, lo: f64, hi: f64) -> f64 {
        (b.min(hi) - a.max(lo)).max(0.0)
    }

    #[test]
    fn transitions_agree_with_direct_classification_on_a_grid() {
        // Every pair of endpoints on a grid of eighths around a square [0.25, 0.75).
        let pts: Vec<f64> = (-2..=10).map(|i| f64::from(i) / 8.0).collect();
        let (lo, hi) = (0.25, 0.75);
        let m = 0.5;
        for &a in &pts {
            for &b in pts.iter().filter(|&&b| b >= a) {
                let v = classify(a, b, lo, hi);
                let low = f_low(a, b, m, v);
                let high = f_high(a, b, m, v);
                assert_eq!(
                    overlap_from_variant(low, a, b, lo, m),
                    true_overlap(a, b, lo, m),
                    "low half, a={a} b={b} v={v} -> {low}"
                );
                assert_eq!(
                    overlap_from_variant(high, a, b, m, hi),
                    true_overlap(a, b, m, hi),
                    "high half, a={a} b={b} v={v} -> {high}"
                );
            }
        }
    }

    #[test]
    fn init_matches_classification_against_unit_interval() {
        let pts: Vec<f64> = (-4..=12).map(|i| f64::from(i) / 8.0).collect();
        for &a in &pts {
            for &b in pts.iter().filter(|&&b| b >= a) {
                let v = f_init(a, b);
                assert_eq!(
                    overlap_from_variant(v, a, b, 0.0, 1.0),
                    true_overlap(a, b, 0.0, 1.0),
                    "a={a} b={b} v={v}"
                );
            }
        }
    }

    #[test]
    fn printed_init_differs_exactly_on_variants_two_and_three() {
        assert_eq!(f_init(0.25, 0.5), FRAGMENT_INSIDE);
        assert_eq!(f_init_as_printed(0.25, 0.5), SQUARE_INSIDE);
        assert_eq!(f_init(-1.0, 2.0), SQUARE_INSIDE);
        assert_eq!(f_init_as_printed(-1.0, 2.0), FRAGMENT_INSIDE);
    }
}
