use crate::Error;

/// An axis-aligned, half-open rectangle `[x0, x1) × [z0, z1)` in texture space.
///
/// Invariants (checked by [`Fragment::new`]): every coordinate is finite,
/// `x0 <= x1` and `z0 <= z1`. A fragment may reach outside the unit square
/// (only its overlap with `[0,1)²` carries texture) and may have zero area.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Fragment {
    x0: f64,
    z0: f64,
    x1: f64,
    z1: f64,
}

impl Fragment {
    /// A fragment from its lower-left `(x0, z0)` and upper-right `(x1, z1)` corners.
    pub fn new(x0: f64, z0: f64, x1: f64, z1: f64) -> Result<Fragment, Error> {
        for (field, value) in [("x0", x0), ("z0", z0), ("x1", x1), ("z1", z1)] {
            if !value.is_finite() {
                return Err(Error::NonFiniteCoordinate { field, value });
            }
        }
        if x1 < x0 {
            return Err(Error::ReversedBounds {
                axis: "x",
                lo: x0,
                hi: x1,
            });
        }
        if z1 < z0 {
            return Err(Error::ReversedBounds {
                axis: "z",
                lo: z0,
                hi: z1,
            });
        }
        Ok(Fragment { x0, z0, x1, z1 })
    }

    /// Left edge (included).
    pub fn x0(&self) -> f64 {
        self.x0
    }
    /// Bottom edge (included).
    pub fn z0(&self) -> f64 {
        self.z0
    }
    /// Right edge (excluded).
    pub fn x1(&self) -> f64 {
        self.x1
    }
    /// Top edge (excluded).
    pub fn z1(&self) -> f64 {
        self.z1
    }
    /// Width `x1 - x0`.
    pub fn width(&self) -> f64 {
        self.x1 - self.x0
    }
    /// Height `z1 - z0`.
    pub fn height(&self) -> f64 {
        self.z1 - self.z0
    }
    /// Area of the whole fragment, inside the unit square or not.
    pub fn area(&self) -> f64 {
        self.width() * self.height()
    }

    /// The part of the fragment inside the unit square, or `None` when that
    /// part has zero area.
    pub fn clip_to_unit(&self) -> Option<Fragment> {
        let x0 = self.x0.max(0.0);
        let z0 = self.z0.max(0.0);
        let x1 = self.x1.min(1.0);
        let z1 = self.z1.min(1.0);
        (x0 < x1 && z0 < z1).then_some(Fragment { x0, z0, x1, z1 })
    }

    /// Area of the overlap with the axis-aligned square `[lo_x, lo_x+side) × [lo_z, lo_z+side)`.
    pub fn overlap_area(&self, lo_x: f64, lo_z: f64, side: f64) -> f64 {
        overlap_1d(self.x0, self.x1, lo_x, lo_x + side)
            * overlap_1d(self.z0, self.z1, lo_z, lo_z + side)
    }
}

/// Length of `[a,b) ∩ [lo,hi)`, zero when they do not meet.
#[inline]
pub(crate) fn overlap_1d(a: f64, b: f64, lo: f64, hi: f64) -> f64 {
    (b.min(hi) - a.max(lo)).max(0.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rejects_nan_infinite_and_reversed() {
        assert!(matches!(
            Fragment::new(f64::NAN, 0.0, 1.0, 1.0),
            Err(Error::NonFiniteCoordinate { field: "x0", .. })
        ));
        assert!(matches!(
            Fragment::new(0.0, 0.0, 1.0, f64::INFINITY),
            Err(Error::NonFiniteCoordinate { field: "z1", .. })
        ));
        assert!(matches!(
            Fragment::new(0.5, 0.0, 0.25, 1.0),
            Err(Error::ReversedBounds { axis: "x", .. })
        ));
        assert!(matches!(
            Fragment::new(0.0, 0.5, 1.0, 0.25),
            Err(Error::ReversedBounds { axis: "z", .. })
        ));
        assert!(
            Fragment::new(0.3, 0.3, 0.3, 0.3).is_ok(),
            "zero area is allowed"
        );
    }

    #[test]
    fn clip_and_overlap() {
        let f = Fragment::new(-0.5, 0.25, 0.5, 2.0).unwrap();
        let c = f.clip_to_unit().unwrap();
        assert_eq!((c.x0(), c.z0(), c.x1(), c.z1()), (0.0, 0.25, 0.5, 1.0));
        assert_eq!(f.overlap_area(0.0, 0.0, 1.0), 0.5 * 0.75);
        assert!(
            Fragment::new(1.0, 0.0, 2.0, 1.0)
                .unwrap()
                .clip_to_unit()
                .is_none()
        );
    }
}
