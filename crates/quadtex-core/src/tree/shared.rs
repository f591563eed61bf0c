//! Immutable bytes a tree reads its colours and texels from, owned or
//! borrowed from a source that outlives no one (a memory-mapped file).

use std::ops::{Deref, Range};

/// Immutable, cheaply cloned bytes: a `Vec<u8>` the tree owns, or a range
/// of something larger kept alive by reference counting (for example a
/// memory-mapped `.qtx` file, whose node colours a tree then reads in
/// place: only the pages a query touches are ever loaded).
///
/// Dereferences to `&[u8]` without a call through the owner, so the
/// traversals pay nothing for the sharing.
#[derive(Clone, Default, PartialEq, Eq)]
pub struct SharedBytes(bytes::Bytes);

impl SharedBytes {
    /// All of `owner`'s bytes, kept alive as long as any slice of them.
    pub fn from_owner<T: AsRef<[u8]> + Send + 'static>(owner: T) -> SharedBytes {
        SharedBytes(bytes::Bytes::from_owner(owner))
    }

    /// The bytes in `range`, sharing the owner; `None` if `range` is not
    /// within `0..len`.
    pub fn slice(&self, range: Range<usize>) -> Option<SharedBytes> {
        (range.start <= range.end && range.end <= self.0.len())
            .then(|| SharedBytes(self.0.slice(range)))
    }
}

impl From<Vec<u8>> for SharedBytes {
    fn from(bytes: Vec<u8>) -> SharedBytes {
        SharedBytes(bytes::Bytes::from(bytes))
    }
}

impl Deref for SharedBytes {
    type Target = [u8];

    #[inline]
    fn deref(&self) -> &[u8] {
        &self.0
    }
}

impl std::fmt::Debug for SharedBytes {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "SharedBytes({} bytes)", self.0.len())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn slices_share_the_owner_and_refuse_out_of_range() {
        let all = SharedBytes::from_owner(vec![1u8, 2, 3, 4, 5]);
        let mid = all.slice(1..4).expect("in range");
        assert_eq!(&*mid, &[2, 3, 4]);
        assert_eq!(mid.slice(1..3).as_deref(), Some(&[3u8, 4][..]));
        assert!(all.slice(2..6).is_none());
        #[allow(clippy::reversed_empty_ranges)]
        let backwards = all.slice(3..2);
        assert!(backwards.is_none());
        assert_eq!(SharedBytes::from(vec![7u8]).len(), 1);
    }
}
