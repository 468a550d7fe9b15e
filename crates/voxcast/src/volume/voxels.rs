//! The storage behind [`VoxelData`](super::VoxelData): voxels the volume
//! owns (a `Vec`, what every reader makes) or voxels it shares with another
//! owner (a NumPy array from the Python module, a memory map), read in place
//! without a copy.

use std::any::Any;
use std::fmt;
use std::ops::Deref;
use std::sync::Arc;

/// Read-only voxel values of type `T`, owned or shared; dereferences to
/// `[T]`. Cloning a shared one shares the same memory.
pub struct Voxels<T> {
    repr: Repr<T>,
}

enum Repr<T> {
    Owned(Vec<T>),
    Shared {
        ptr: *const T,
        len: usize,
        /// Keeps the memory alive; dropped with the last clone.
        _owner: Arc<dyn Any + Send + Sync>,
    },
}

// SAFETY: an owned `Voxels` is a `Vec`. A shared one only ever reads
// through `ptr`, whose memory `_owner` (itself `Send + Sync`) keeps alive;
// `Voxels::shared`'s caller promises the memory is not written meanwhile.
unsafe impl<T: Send + Sync> Send for Voxels<T> {}
unsafe impl<T: Send + Sync> Sync for Voxels<T> {}

impl<T> Voxels<T> {
    /// Voxels read in place from memory another object owns.
    ///
    /// # Safety
    /// `ptr` must point to `len` initialised, properly aligned values of `T`
    /// that stay valid, and are not written, for as long as `owner` lives.
    pub unsafe fn shared(ptr: *const T, len: usize, owner: Arc<dyn Any + Send + Sync>) -> Self {
        // A zero-length slice still needs a non-null, aligned pointer.
        let ptr = if len == 0 {
            std::ptr::NonNull::dangling().as_ptr()
        } else {
            ptr
        };
        Voxels {
            repr: Repr::Shared {
                ptr,
                len,
                _owner: owner,
            },
        }
    }

    /// True when the values live in memory another object owns.
    pub fn is_shared(&self) -> bool {
        matches!(self.repr, Repr::Shared { .. })
    }

    /// The values to change in place: the `Vec` when owned; a shared one
    /// is first copied into a `Vec` of its own (the owner's memory is never
    /// written).
    pub fn make_mut(&mut self) -> &mut Vec<T>
    where
        T: Clone,
    {
        if let Repr::Shared { .. } = self.repr {
            self.repr = Repr::Owned(self.to_vec());
        }
        match &mut self.repr {
            Repr::Owned(v) => v,
            Repr::Shared { .. } => unreachable!("made owned above"),
        }
    }

    /// The same values, shared: an owned `Vec` moves behind an `Arc`, so
    /// clones of the volume no longer copy it.
    pub fn into_shared(self) -> Self
    where
        T: Send + Sync + 'static,
    {
        match self.repr {
            Repr::Owned(v) => {
                let v = Arc::new(v);
                let (ptr, len) = (v.as_ptr(), v.len());
                // SAFETY: the Arc'd Vec is never written and lives as long as
                // its last clone.
                unsafe { Voxels::shared(ptr, len, v) }
            }
            shared => Voxels { repr: shared },
        }
    }

    /// The values as a `Vec` (a copy when shared).
    pub fn into_vec(self) -> Vec<T>
    where
        T: Clone,
    {
        match self.repr {
            Repr::Owned(v) => v,
            Repr::Shared { .. } => self.to_vec(),
        }
    }
}

impl<T> Deref for Voxels<T> {
    type Target = [T];
    fn deref(&self) -> &[T] {
        match &self.repr {
            Repr::Owned(v) => v,
            // SAFETY: `Voxels::shared`'s contract.
            Repr::Shared { ptr, len, .. } => unsafe { std::slice::from_raw_parts(*ptr, *len) },
        }
    }
}

impl<T> From<Vec<T>> for Voxels<T> {
    fn from(v: Vec<T>) -> Self {
        Voxels {
            repr: Repr::Owned(v),
        }
    }
}

impl<'a, T> IntoIterator for &'a Voxels<T> {
    type Item = &'a T;
    type IntoIter = std::slice::Iter<'a, T>;
    fn into_iter(self) -> Self::IntoIter {
        self.iter()
    }
}

impl<T> FromIterator<T> for Voxels<T> {
    fn from_iter<I: IntoIterator<Item = T>>(iter: I) -> Self {
        Vec::from_iter(iter).into()
    }
}

impl<T: Clone> Clone for Voxels<T> {
    fn clone(&self) -> Self {
        match &self.repr {
            Repr::Owned(v) => v.clone().into(),
            Repr::Shared { ptr, len, _owner } => Voxels {
                repr: Repr::Shared {
                    ptr: *ptr,
                    len: *len,
                    _owner: _owner.clone(),
                },
            },
        }
    }
}

impl<T: PartialEq> PartialEq for Voxels<T> {
    fn eq(&self, other: &Self) -> bool {
        **self == **other
    }
}

impl<T: fmt::Debug> fmt::Debug for Voxels<T> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if self.len() <= 16 {
            f.debug_list().entries(self.iter()).finish()
        } else {
            write!(
                f,
                "[{} voxels{}]",
                self.len(),
                if self.is_shared() { ", shared" } else { "" }
            )
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shared_voxels_read_the_owner_memory_and_keep_it_alive() {
        let owner = Arc::new(vec![1.0f32, 2.0, 3.0]);
        let ptr = owner.as_ptr();
        let v = unsafe { Voxels::shared(ptr, 3, owner.clone()) };
        let w = v.clone();
        drop(owner);
        drop(v);
        assert!(w.is_shared());
        assert_eq!(&*w, &[1.0, 2.0, 3.0]);
        assert_eq!(w.as_ptr(), ptr, "a clone shares, it does not copy");
        assert_eq!(w.into_vec(), vec![1.0, 2.0, 3.0]);
        let empty: Voxels<u16> = unsafe { Voxels::shared(std::ptr::null(), 0, Arc::new(())) };
        assert!(empty.is_empty());
    }
}
