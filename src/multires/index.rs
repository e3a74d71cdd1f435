//! The index types a polygon cache and the packed records hold: `u16` and `u32`.

/// An index type a [`PolygonCache`](super::PolygonCache) can hold: `u32` (any mesh), or
/// `u16` (meshes of at most 65,535 vertices: index `0xFFFF` is left unused, since Metal and
/// WebGL read it as a primitive restart even in triangle lists).
pub trait CacheIndex:
    Copy + Eq + Into<u32> + Send + Sync + std::fmt::Debug + sealed::Sealed + 'static
{
    /// The most vertices it can address.
    const MAX_VERTICES: u64;

    /// `v` narrowed to `Self`; callers check that it fits.
    #[doc(hidden)]
    fn from_u32(v: u32) -> Self;
}

mod sealed {
    pub trait Sealed {}
    impl Sealed for u16 {}
    impl Sealed for u32 {}
}

impl CacheIndex for u16 {
    const MAX_VERTICES: u64 = u16::MAX as u64;

    #[inline]
    fn from_u32(v: u32) -> Self {
        debug_assert!(
            v < u32::from(u16::MAX),
            "index {v} does not fit a 16-bit cache"
        );
        v as u16
    }
}

impl CacheIndex for u32 {
    const MAX_VERTICES: u64 = 1 << 32;

    #[inline]
    fn from_u32(v: u32) -> Self {
        v
    }
}
