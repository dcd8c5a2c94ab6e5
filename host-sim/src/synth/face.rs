//! Which face of which object a ray hit: the key that the ray caster (`scene`) and the posters
//! pasted on faces (`poster`) share, so neither needs the other's module for it.

use super::noise::hash2;

/// Which face of which object a ray hit. Face index `k`: axis `k / 2` (x, y, z), the minimum side
/// for even `k`, the maximum for odd `k` (box-local axes for boxes).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum FaceId {
    /// A face of the room: 0 west, 1 east, 2 south, 3 north wall, 4 floor, 5 ceiling.
    Room(u8),
    /// Face `face` of box `index`.
    Box { index: u8, face: u8 },
    /// Sphere `index`.
    Sphere(u8),
}

impl FaceId {
    /// A per-face salt for the texture hashes.
    pub(super) fn salt(self) -> u32 {
        match self {
            Self::Room(f) => hash2(0, i32::from(f), 0xA11),
            Self::Box { index, face } => hash2(i32::from(index) + 1, i32::from(face), 0xB0C),
            Self::Sphere(i) => hash2(i32::from(i), -7, 0x5F),
        }
    }
}
