//! A fixed-size bitset of per-correspondence flags.

use super::MAX_CORRESPONDENCES;

const WORDS: usize = MAX_CORRESPONDENCES.div_ceil(32);

/// One flag per correspondence index `0..MAX_CORRESPONDENCES` (64 bytes), e.g. "is an inlier".
///
/// Indices at or beyond [`MAX_CORRESPONDENCES`] are never set: [`Self::insert`] ignores them and
/// [`Self::contains`] reports false.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct InlierMask {
    words: [u32; WORDS],
}

impl InlierMask {
    /// The empty mask.
    pub const fn new() -> Self {
        Self { words: [0; WORDS] }
    }

    /// The mask holding indices `0..len` (clamped to [`MAX_CORRESPONDENCES`]).
    pub fn first(len: usize) -> Self {
        let mut mask = Self::new();
        for i in 0..len.min(MAX_CORRESPONDENCES) {
            mask.insert(i);
        }
        mask
    }

    /// Whether index `i` is set.
    pub fn contains(&self, i: usize) -> bool {
        self.words.get(i / 32).is_some_and(|w| w & (1 << (i % 32)) != 0)
    }

    /// Sets index `i`; returns false (and does nothing) if `i >= MAX_CORRESPONDENCES`.
    pub fn insert(&mut self, i: usize) -> bool {
        match self.words.get_mut(i / 32) {
            Some(w) => {
                *w |= 1 << (i % 32);
                true
            }
            None => false,
        }
    }

    /// Clears index `i` (no-op when out of range).
    pub fn remove(&mut self, i: usize) {
        if let Some(w) = self.words.get_mut(i / 32) {
            *w &= !(1 << (i % 32));
        }
    }

    /// Number of set indices.
    pub fn count(&self) -> usize {
        self.words.iter().map(|w| w.count_ones() as usize).sum()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn mask_sets_clears_and_counts() {
        let mut m = InlierMask::new();
        assert!(m.insert(0) && m.insert(31) && m.insert(32) && m.insert(511));
        assert!(!m.insert(512));
        assert!(m.contains(31) && m.contains(511) && !m.contains(1) && !m.contains(9999));
        assert_eq!(m.count(), 4);
        m.remove(31);
        m.remove(100_000);
        assert_eq!(m.count(), 3);
        assert_eq!(InlierMask::first(40).count(), 40);
        assert_eq!(InlierMask::first(10_000).count(), MAX_CORRESPONDENCES);
    }
}
