//! Compile-time layout checks of every buffer type the host and the kernels share: its size
//! in bytes and its alignment (4: `f32`/`u32` fields and arrays only, so std430 and
//! `#[repr(C)]` agree). A change that moves a byte fails to compile, natively and for SPIR-V.

/// `layout!(Type => size, …)`: asserts `size_of::<Type>() == size` and `align_of::<Type>() == 4`.
macro_rules! layout {
    ($($t:ty => $size:expr),* $(,)?) => {
        $(
            const _: () = assert!(
                core::mem::size_of::<$t>() == $size,
                concat!("size_of::<", stringify!($t), ">() is not ", stringify!($size))
            );
            const _: () = assert!(
                core::mem::align_of::<$t>() == 4,
                concat!("align_of::<", stringify!($t), ">() is not 4")
            );
        )*
    };
}

layout! {
    crate::pod::Triangle => 48,
    crate::pod::Hit => 16,
    crate::pod::Material => 32,
    crate::pod::Light => 64,
    crate::pod::Camera => 64,
    crate::pod::TraceParams => 48,
    crate::pod::RasterParams => 128,
    crate::pod::RenderParams => 112,
    crate::pod::PhotonParams => 80,
    crate::pod::PhotonPath => 16,
    crate::pod::Photon => 20,
    crate::pod::IndexParams => 80,
    crate::pod::LeafCells => 32,
    crate::pod::ItemParams => 16,
    crate::pod::SortParams => 16,
    crate::pod::ShadeTerms => 32,
    crate::pod::PathState => 32,
    crate::kdtree::KdNode => 8,
    crate::kdtree::LeafRef => 12,
    crate::stats::Counters => 16,
    crate::ray::Ray => 32,
}

// The BVH node: five 16-byte vectors (`UVec4`: 16-byte aligned in SPIR-V, 4 natively; its
// offsets are multiples of 16 either way).
const _: () = assert!(core::mem::size_of::<crate::bvh::BvhNode>() == 80, "size_of::<BvhNode>() is not 80");
// A photon's gather word: one 16-byte vector.
const _: () = assert!(core::mem::size_of::<crate::photon::PhotonWord>() == 16, "size_of::<PhotonWord>() is not 16");
