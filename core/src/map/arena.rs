//! A fixed-capacity arena with generation-checked handles: the storage behind the map's keyframes
//! and landmarks.
//!
//! Slots are reused after removal; each slot carries a generation counter that a removal bumps,
//! so a handle to a removed object never reaches the object that later takes its slot
//! ([`Arena::get`] returns `None` for it). Insertion takes the most recently freed slot, else the
//! lowest never-used one: the same sequence of calls always gives the same handles.

/// A handle into an [`Arena`]: slot index and the slot's generation when the object was inserted.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Handle {
    index: u16,
    generation: u16,
}

impl Handle {
    /// The slot index (below the arena's capacity).
    pub const fn index(self) -> usize {
        self.index as usize
    }

    /// The slot's generation at insertion.
    pub const fn generation(self) -> u16 {
        self.generation
    }
}

/// `N` slots of `T` (`N` at most 65,536), no heap.
#[derive(Debug, Clone)]
pub struct Arena<T, const N: usize> {
    slots: [Option<T>; N],
    generations: [u16; N],
    /// Freed slot indices, most recent last.
    free: heapless::Vec<u16, N>,
    /// Slots `next_unused..N` have never held an object.
    next_unused: usize,
    len: usize,
}

impl<T, const N: usize> Default for Arena<T, N> {
    fn default() -> Self {
        Self::new()
    }
}

impl<T, const N: usize> Arena<T, N> {
    /// An empty arena (`const`: it can initialize a `static`).
    pub const fn new() -> Self {
        Self {
            slots: [const { None }; N],
            generations: [0; N],
            free: heapless::Vec::new(),
            next_unused: 0,
            len: 0,
        }
    }

    /// Objects held.
    pub const fn len(&self) -> usize {
        self.len
    }

    /// Whether no object is held.
    pub const fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// Whether every slot is taken.
    pub const fn is_full(&self) -> bool {
        self.len >= N
    }

    /// Stores `value` and returns its handle, or gives `value` back when the arena is full.
    ///
    /// # Errors
    /// `Err(value)` when all `N` slots are taken (or `N` exceeds the handle's 16-bit index).
    pub fn insert(&mut self, value: T) -> Result<Handle, T> {
        let index = match self.free.pop() {
            Some(i) => usize::from(i),
            None if self.next_unused < N && self.next_unused <= usize::from(u16::MAX) => {
                self.next_unused += 1;
                self.next_unused - 1
            }
            None => return Err(value),
        };
        let (Some(slot), Some(&generation)) =
            (self.slots.get_mut(index), self.generations.get(index))
        else {
            return Err(value);
        };
        *slot = Some(value);
        self.len += 1;
        // `index < N <= 65,536`: the cast is exact.
        Ok(Handle { index: index as u16, generation })
    }

    /// The object behind `handle`, unless it was removed.
    pub fn get(&self, handle: Handle) -> Option<&T> {
        let i = handle.index();
        match self.generations.get(i) {
            Some(&g) if g == handle.generation => self.slots.get(i)?.as_ref(),
            _ => None,
        }
    }

    /// The object behind `handle`, mutably, unless it was removed.
    pub fn get_mut(&mut self, handle: Handle) -> Option<&mut T> {
        let i = handle.index();
        match self.generations.get(i) {
            Some(&g) if g == handle.generation => self.slots.get_mut(i)?.as_mut(),
            _ => None,
        }
    }

    /// Removes and returns the object behind `handle`; `None` if it was already removed.
    pub fn remove(&mut self, handle: Handle) -> Option<T> {
        let i = handle.index();
        if self.generations.get(i) != Some(&handle.generation) {
            return None;
        }
        let value = self.slots.get_mut(i)?.take()?;
        if let Some(g) = self.generations.get_mut(i) {
            *g = g.wrapping_add(1);
        }
        // Cannot fail: at most N slots are ever freed at once. `i < N <= 65,536`.
        let _ = self.free.push(i as u16);
        self.len -= 1;
        Some(value)
    }

    /// Every object with its handle, in slot order.
    pub fn iter(&self) -> impl Iterator<Item = (Handle, &T)> + '_ {
        self.slots.iter().zip(self.generations.iter()).enumerate().filter_map(|(i, (s, &g))| {
            // `i < N <= 65,536`: the cast is exact.
            s.as_ref().map(|v| (Handle { index: i as u16, generation: g }, v))
        })
    }

    /// Every object mutably with its handle, in slot order.
    pub fn iter_mut(&mut self) -> impl Iterator<Item = (Handle, &mut T)> + '_ {
        self.slots.iter_mut().zip(self.generations.iter()).enumerate().filter_map(|(i, (s, &g))| {
            s.as_mut().map(|v| (Handle { index: i as u16, generation: g }, v))
        })
    }

    /// The handle of the object in slot `index`, if the slot is taken.
    pub fn handle_at(&self, index: usize) -> Option<Handle> {
        let g = *self.generations.get(index)?;
        self.slots.get(index)?.as_ref().map(|_| Handle { index: index as u16, generation: g })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn handles_of_removed_objects_never_reach_new_ones() {
        let mut a: Arena<u32, 3> = Arena::new();
        let h0 = a.insert(10).unwrap();
        let h1 = a.insert(11).unwrap();
        let h2 = a.insert(12).unwrap();
        assert_eq!(a.insert(13), Err(13), "full arena gives the value back");
        assert_eq!(a.remove(h1), Some(11));
        assert_eq!(a.remove(h1), None);
        let h3 = a.insert(14).unwrap();
        assert_eq!(h3.index(), h1.index(), "the freed slot is reused");
        assert_eq!(a.get(h1), None, "stale handle");
        assert_eq!(a.get(h3), Some(&14));
        assert_eq!(a.len(), 3);
        let seen: heapless::Vec<u32, 3> = a.iter().map(|(_, v)| *v).collect();
        assert_eq!(seen, [10, 14, 12]);
        *a.get_mut(h0).unwrap() += 1;
        assert_eq!(a.get(h0), Some(&11));
        assert_eq!(a.handle_at(2), Some(h2));
        assert_eq!(a.handle_at(7), None);
    }
}
