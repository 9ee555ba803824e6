//! Watertight ray/triangle intersection (Woop, Benthin, Wald 2013, JCGT 2(1)), two-sided.
//!
//! The ray is permuted so that its largest direction component is z and sheared so that it
//! points along +z; each vertex is transformed independently of the triangle it belongs to and
//! the three 2D edge functions are evaluated with the exact sign (`diff_of_products`). Two
//! triangles sharing an edge therefore always see exactly opposite edge-function signs, so a ray
//! through an edge or a vertex of a closed mesh hits at least one of the triangles around it.
//! Differences from the paper, all on purpose:
//! * The shear is written without division (each sheared coordinate is multiplied by d_z, which
//!   keeps every edge-function sign) and the direction is first scaled by the exact power of two
//!   that brings |d_z| into [1, 2). Every operation up to the final division is a correctly
//!   rounded `*`, `+` or explicit `fma`, so CPU and GPU compute bit-identical edge functions.
//! * Instead of recomputing in `f64` when an edge function is exactly 0, all three are always
//!   evaluated with the exact sign in `f32` (Kahan's difference of products): that is the
//!   "higher-precision fallback", made unconditional because GPU drivers may contract
//!   `a*b - c*d` into an FMA and break the antisymmetry the proof relies on.
//! * A degenerate (zero-area) triangle gives `det == 0` and never hits; the scene loader also
//!   drops triangles whose area is exactly 0.
use crate::math::{diff_of_products, fma, pow2_normaliser};
use crate::ray::Ray;

/// Per-ray constants of the test, computed once per ray.
#[derive(Copy, Clone, Debug, Default)]
pub struct ShearedRay {
    /// The ray's origin.
    pub origin: [f32; 3],
    /// Axis of the direction's largest component in magnitude, which becomes z (the axis after
    /// it becomes x, the next y: `permute`).
    pub kz: u32,
    /// Direction component along the axis that becomes x, scaled by `scale` (an exact power of
    /// two).
    pub dx: f32,
    /// Direction component along the axis that becomes y, scaled by `scale`.
    pub dy: f32,
    /// Direction component along `kz`, scaled by `scale`: |dz| in [1, 2).
    pub dz: f32,
    /// The exact power of two that brings the direction's `kz` component into [1, 2) in magnitude.
    pub scale: f32,
}

impl ShearedRay {
    /// `None` for a ray that `Ray::is_valid` rejects.
    #[inline(always)]
    pub fn new(ray: &Ray) -> Option<Self> {
        if !ray.is_valid() {
            return None;
        }
        let d = ray.dir;
        let ax = d[0].abs();
        let ay = d[1].abs();
        let az = d[2].abs();
        let kz = if ax >= ay && ax >= az {
            0u32
        } else if ay >= az {
            1
        } else {
            2
        };
        let p = permute(d, kz);
        let scale = match pow2_normaliser(p[2]) {
            Some(s) => s,
            None => return None,
        };
        Some(Self { origin: ray.origin, kz, dx: p[0] * scale, dy: p[1] * scale, dz: p[2] * scale, scale })
    }

    /// Vertex relative to the origin, sheared (and multiplied by dz): (x, y, z-unsheared).
    #[inline(always)]
    fn transform(&self, v: [f32; 3]) -> [f32; 3] {
        let a = [v[0] - self.origin[0], v[1] - self.origin[1], v[2] - self.origin[2]];
        let p = permute(a, self.kz);
        [fma(p[0], self.dz, -(self.dx * p[2])), fma(p[1], self.dz, -(self.dy * p[2])), p[2]]
    }
}

/// `v`'s coordinates along the axes after `kz`, after that, and `kz` (the rotation that makes
/// `kz` the last axis), by comparisons and selects rather than indices computed at run time: a
/// GPU compiler may place an array indexed dynamically in local memory, and two comparisons of
/// one value hold fewer registers than three indices.
#[inline(always)]
fn permute(v: [f32; 3], kz: u32) -> [f32; 3] {
    let (z0, z1) = (kz == 0, kz == 1);
    let pick = |a: f32, b: f32, c: f32| if z0 { a } else if z1 { b } else { c };
    [pick(v[1], v[2], v[0]), pick(v[2], v[0], v[1]), pick(v[0], v[1], v[2])]
}

/// Distance along the original ray direction and barycentric weights of v1 and v2.
#[derive(Copy, Clone, Debug, PartialEq)]
pub struct TriHit {
    /// Ray parameter of the hit, in units of the original direction.
    pub t: f32,
    /// Barycentric weight of v1.
    pub b1: f32,
    /// Barycentric weight of v2.
    pub b2: f32,
}

/// Hit with `t_min <= t <= t_max`, or `None`.
#[inline(always)]
pub fn intersect_triangle(
    r: &ShearedRay,
    v0: [f32; 3],
    v1: [f32; 3],
    v2: [f32; 3],
    t_min: f32,
    t_max: f32,
) -> Option<TriHit> {
    let a = r.transform(v0);
    let b = r.transform(v1);
    let c = r.transform(v2);
    let u = diff_of_products(c[0], b[1], c[1], b[0]);
    let v = diff_of_products(a[0], c[1], a[1], c[0]);
    let w = diff_of_products(b[0], a[1], b[1], a[0]);
    if (u < 0.0 || v < 0.0 || w < 0.0) && (u > 0.0 || v > 0.0 || w > 0.0) {
        return None;
    }
    let det = u + v + w;
    if det == 0.0 {
        return None;
    }
    let tt = fma(u, a[2], fma(v, b[2], w * c[2]));
    let t = tt / (det * r.dz) * r.scale;
    // NaN fails both comparisons: a miss.
    if !(t >= t_min && t <= t_max) {
        return None;
    }
    let inv_det = 1.0 / det;
    Some(TriHit { t, b1: v * inv_det, b2: w * inv_det })
}
