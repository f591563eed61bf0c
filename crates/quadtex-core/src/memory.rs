//! Memory budgets: the builders' estimates and fallible allocation.
//!
//! This crate does no I/O, so it never looks at the machine: a caller passes
//! a budget in bytes (`max_bytes` in [`crate::BuildOptions`] and
//! [`crate::VectorOptions`]; `quadtex-io` derives one from the cgroup, the
//! address-space limit and physical memory). Each builder estimates its peak
//! before it allocates and refuses with [`Error::MemoryBudget`] when the
//! estimate is above the budget; every allocation whose size comes from the
//! input is fallible and turns a refusal by the allocator into
//! [`Error::AllocationFailed`], never an abort.

use crate::Error;

/// Peak bytes a builder holds per tree node: the per-level node lists
/// (10 bytes a node, up to twice that while a list grows) plus the final
/// tree's arrays (8.25 bytes a node) built from them.
pub const BUILD_BYTES_PER_NODE: u64 = 30;

/// Peak bytes the packer holds per point of a contour leaf: the point
/// while the leaf is built (16 bytes), again in the finished leaves, and
/// the slack of the lists that grow to hold them. Measured with a counting
/// allocator on the Ghostscript tiger at edge budgets 16 to 256 and levels
/// 12 to 20 (see `docs/limits.md`).
pub const CONTOUR_BYTES_PER_POINT: u64 = 40;

/// Peak bytes the packer holds per contour leaf beyond its points: the
/// leaf's lists of pieces and contours while it is built, and their
/// headers in the finished leaves; measured as [`CONTOUR_BYTES_PER_POINT`].
pub const CONTOUR_BYTES_PER_LEAF: u64 = 200;

/// Bytes per node of a finished tree (colour plus inner bit and rank
/// counters; the top table adds at most 1/16 of the colour bytes).
pub const TREE_BYTES_PER_NODE: u64 = 9;

/// `bytes` for people: `9.3 GiB`, `512.0 MiB`, `12.0 KiB`, `100 B`.
pub fn format_bytes(bytes: u64) -> String {
    const UNITS: [(&str, u64); 4] = [
        ("TiB", 1 << 40),
        ("GiB", 1 << 30),
        ("MiB", 1 << 20),
        ("KiB", 1 << 10),
    ];
    for (unit, size) in UNITS {
        if bytes >= size {
            return format!("{:.1} {unit}", bytes as f64 / size as f64);
        }
    }
    format!("{bytes} B")
}

/// Refuses `estimate` above `budget` (when there is one).
pub fn check_budget(
    what: impl FnOnce() -> String,
    estimate: u64,
    budget: Option<u64>,
    knobs: &'static str,
) -> Result<(), Error> {
    match budget {
        Some(budget) if estimate > budget => Err(Error::MemoryBudget {
            what: what(),
            estimate,
            budget,
            knobs,
        }),
        _ => Ok(()),
    }
}

/// The error for an allocation of `count` values of `T` the allocator refused.
pub(crate) fn refused<T>(what: &str, count: usize) -> Error {
    Error::AllocationFailed {
        what: what.to_string(),
        bytes: (count as u64).saturating_mul(std::mem::size_of::<T>() as u64),
    }
}

/// `vec![value; len]`, but an allocation failure is an error.
pub(crate) fn try_vec<T: Clone>(len: usize, value: T, what: &str) -> Result<Vec<T>, Error> {
    let mut v = Vec::new();
    v.try_reserve_exact(len)
        .map_err(|_| refused::<T>(what, len))?;
    v.resize(len, value);
    Ok(v)
}

/// `Vec::with_capacity(len)`, but an allocation failure is an error.
pub(crate) fn try_with_capacity<T>(len: usize, what: &str) -> Result<Vec<T>, Error> {
    let mut v = Vec::new();
    v.try_reserve_exact(len)
        .map_err(|_| refused::<T>(what, len))?;
    Ok(v)
}

/// Pushes `value`, growing `v` fallibly.
pub(crate) fn try_push<T>(v: &mut Vec<T>, value: T, what: &str) -> Result<(), Error> {
    if v.len() == v.capacity() {
        v.try_reserve(1)
            .map_err(|_| refused::<T>(what, v.len().saturating_mul(2)))?;
    }
    v.push(value);
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bytes_are_formatted_with_binary_units() {
        assert_eq!(format_bytes(100), "100 B");
        assert_eq!(format_bytes(1536), "1.5 KiB");
        assert_eq!(format_bytes(4 << 30), "4.0 GiB");
        assert_eq!(format_bytes(9_985_798_963), "9.3 GiB");
    }

    #[test]
    fn budget_is_checked_only_when_set() {
        assert!(check_budget(|| "x".into(), 10, None, "k").is_ok());
        assert!(check_budget(|| "x".into(), 10, Some(10), "k").is_ok());
        let e = check_budget(
            || "packing at level 20".into(),
            11 << 30,
            Some(4 << 30),
            "lower --max-level",
        )
        .unwrap_err();
        assert_eq!(
            e.to_string(),
            "packing at level 20 needs an estimated 11.0 GiB, above the memory budget of 4.0 GiB (lower --max-level)"
        );
    }

    #[test]
    fn refused_allocations_are_errors() {
        let e = try_vec(usize::MAX / 2, 0u64, "a grid").unwrap_err();
        assert!(matches!(e, Error::AllocationFailed { .. }), "{e}");
        let e = try_with_capacity::<u64>(usize::MAX / 2, "a list").unwrap_err();
        assert!(e.to_string().contains("a list"), "{e}");
    }
}
