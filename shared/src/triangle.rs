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
use crate::math::{diff_of_products, fma, LaneMask};
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
        let (valid, r) = Self::of(ray);
        if valid {
            Some(r)
        } else {
            None
        }
    }

    /// Whether `new` gives `Some`, and its value then (else the values of
    /// `ShearedLanes::default`'s lanes), computed without branches, so that a loop of it over
    /// the lanes of a packet vectorises (`ShearedLanes::of`).
    #[inline(always)]
    pub fn of(ray: &Ray) -> (bool, Self) {
        let (o, d) = (ray.origin, ray.dir);
        let finite = o[0].is_finite() & o[1].is_finite() & o[2].is_finite() & d[0].is_finite() & d[1].is_finite() & d[2].is_finite();
        let (ax, ay, az) = (d[0].abs(), d[1].abs(), d[2].abs());
        let kz = if ax >= ay && ax >= az { 0u32 } else if ay >= az { 1 } else { 2 };
        let p = permute(d, kz);
        // `pow2_normaliser(p[2])` written out. For finite directions |p[2]| is the largest
        // component, so its exponent's range is also `Ray::is_valid`'s condition on the
        // direction; the rest of that: finite, and the interval ordered.
        let ez = (p[2].to_bits() >> 23) & 0xff;
        let valid = finite & (ez >= 2) & (ez <= 252) & (ray.t_min >= 0.0) & (ray.t_min <= ray.t_max);
        let scale = f32::from_bits(254u32.wrapping_sub(ez) << 23);
        let pick = |v: f32| if valid { v } else { 0.0 };
        let r = Self { origin: [pick(o[0]), pick(o[1]), pick(o[2])], kz: if valid { kz } else { 2 }, dx: pick(p[0] * scale), dy: pick(p[1] * scale), dz: pick(p[2] * scale), scale: pick(scale) };
        (valid, r)
    }

    /// Vertex relative to the origin, sheared (and multiplied by dz): (x, y, z-unsheared).
    #[inline(always)]
    fn transform(&self, v: [f32; 3]) -> [f32; 3] {
        sheared_vertex(self.origin, self.kz, self.dx, self.dy, self.dz, v)
    }
}

/// `ShearedRay::transform` of `v` for the ray with these constants.
#[inline(always)]
fn sheared_vertex(origin: [f32; 3], kz: u32, dx: f32, dy: f32, dz: f32, v: [f32; 3]) -> [f32; 3] {
    let a = [v[0] - origin[0], v[1] - origin[1], v[2] - origin[2]];
    let p = permute(a, kz);
    [fma(p[0], dz, -(dx * p[2])), fma(p[1], dz, -(dy * p[2])), p[2]]
}

/// The edge functions of the sheared vertices `a`, `b`, `c` (the barycentric numerators of v0,
/// v1, v2), each with the sign of its exact value.
#[inline(always)]
fn edges(a: [f32; 3], b: [f32; 3], c: [f32; 3]) -> [f32; 3] {
    [diff_of_products(c[0], b[1], c[1], b[0]), diff_of_products(a[0], c[1], a[1], c[0]), diff_of_products(b[0], a[1], b[1], a[0])]
}

/// Whether the edge functions have mixed signs (the ray passes beside the triangle).
#[inline(always)]
fn beside(e: [f32; 3]) -> bool {
    (e[0] < 0.0 || e[1] < 0.0 || e[2] < 0.0) && (e[0] > 0.0 || e[1] > 0.0 || e[2] > 0.0)
}

/// The hit's ray parameter from the edge functions `e` (summing to `det`) and the sheared
/// vertices' unsheared z.
#[inline(always)]
fn hit_t(e: [f32; 3], det: f32, az: f32, bz: f32, cz: f32, dz: f32, scale: f32) -> f32 {
    let tt = fma(e[0], az, fma(e[1], bz, e[2] * cz));
    tt / (det * dz) * scale
}

/// `ShearedRay`s of `W` rays, a field per array (lanes side by side, as vector registers hold
/// them): the input of `intersect_triangle_lanes`.
#[derive(Copy, Clone)]
pub struct ShearedLanes<const W: usize> {
    /// Origins, per axis.
    pub origin: [[f32; W]; 3],
    /// `ShearedRay::kz` per lane.
    pub kz: [u32; W],
    /// `ShearedRay::dx` per lane.
    pub dx: [f32; W],
    /// `ShearedRay::dy` per lane.
    pub dy: [f32; W],
    /// `ShearedRay::dz` per lane.
    pub dz: [f32; W],
    /// `ShearedRay::scale` per lane.
    pub scale: [f32; W],
}

impl<const W: usize> Default for ShearedLanes<W> {
    fn default() -> Self {
        // Lanes never set answer nonsense: callers mask them out.
        ShearedLanes { origin: [[0.0; W]; 3], kz: [2; W], dx: [0.0; W], dy: [0.0; W], dz: [0.0; W], scale: [0.0; W] }
    }
}

impl<const W: usize> ShearedLanes<W> {
    /// `ShearedRay::new` of every ray (`ShearedRay::of`, in a loop over the lanes that
    /// vectorises natively): lane l holds ray l's constants and bit l of the mask returned is set
    /// where it is `Some`; other lanes hold `default`'s values.
    #[inline(always)]
    pub fn of(rays: &[Ray; W]) -> (Self, u32) {
        let mut lanes = Self::default();
        let mut valid = LaneMask::<W>::new();
        let mut l = 0;
        while l < W {
            let (ok, r) = ShearedRay::of(&rays[l]);
            lanes.set(l, &r);
            valid.put(l, ok);
            l += 1;
        }
        (lanes, valid.bits())
    }

    /// Lane `l` becomes `r`.
    #[inline(always)]
    pub fn set(&mut self, l: usize, r: &ShearedRay) {
        let mut a = 0;
        while a < 3 {
            self.origin[a][l] = r.origin[a];
            a += 1;
        }
        self.kz[l] = r.kz;
        self.dx[l] = r.dx;
        self.dy[l] = r.dy;
        self.dz[l] = r.dz;
        self.scale[l] = r.scale;
    }
}

/// `intersect_triangle` for every lane at once, without branches (a compiler turns the lane
/// loop into vector instructions): the same operations on the same values, so for each lane
/// the same hit or miss and the same `t`, `b1`, `b2` bit for bit. Returns the lanes that hit
/// (bit l) and writes their hits into `t`, `b1`, `b2` (other lanes' entries are meaningless).
#[inline(always)]
#[allow(clippy::too_many_arguments)]
pub fn intersect_triangle_lanes<const W: usize>(
    r: &ShearedLanes<W>,
    v0: [f32; 3],
    v1: [f32; 3],
    v2: [f32; 3],
    t_min: &[f32; W],
    t_max: &[f32; W],
    t: &mut [f32; W],
    b1: &mut [f32; W],
    b2: &mut [f32; W],
) -> u32 {
    let mut hits = LaneMask::<W>::new();
    let mut l = 0;
    while l < W {
        let o = [r.origin[0][l], r.origin[1][l], r.origin[2][l]];
        let a = sheared_vertex(o, r.kz[l], r.dx[l], r.dy[l], r.dz[l], v0);
        let b = sheared_vertex(o, r.kz[l], r.dx[l], r.dy[l], r.dz[l], v1);
        let c = sheared_vertex(o, r.kz[l], r.dx[l], r.dy[l], r.dz[l], v2);
        let e = edges(a, b, c);
        let det = e[0] + e[1] + e[2];
        let tl = hit_t(e, det, a[2], b[2], c[2], r.dz[l], r.scale[l]);
        let inv_det = 1.0 / det;
        t[l] = tl;
        b1[l] = e[1] * inv_det;
        b2[l] = e[2] * inv_det;
        // NaN fails both comparisons: a miss, as in `intersect_triangle`.
        let hit = !beside(e) & (det != 0.0) & (tl >= t_min[l]) & (tl <= t_max[l]);
        hits.put(l, hit);
        l += 1;
    }
    hits.bits()
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
    let e = edges(a, b, c);
    if beside(e) {
        return None;
    }
    let det = e[0] + e[1] + e[2];
    if det == 0.0 {
        return None;
    }
    let t = hit_t(e, det, a[2], b[2], c[2], r.dz, r.scale);
    // NaN fails both comparisons: a miss.
    if !(t >= t_min && t <= t_max) {
        return None;
    }
    let inv_det = 1.0 / det;
    Some(TriHit { t, b1: e[1] * inv_det, b2: e[2] * inv_det })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::Rng;

    /// `ShearedRay::new` (now branch-free, `ShearedRay::of`) is the straightforward one: `None`
    /// exactly for the rays `Ray::is_valid` rejects, else the largest component's axis and its
    /// power-of-two normaliser; and `ShearedLanes::of` holds every lane's value (invalid lanes:
    /// the default's). Rays with zeros of both signs, subnormal, tiny, huge, infinite and NaN
    /// components and intervals in every order.
    #[test]
    fn lanes_are_set_up_as_one_ray_each() {
        const W: usize = 8;
        let mut rng = Rng::new(9, 2);
        // Among them the edges of the normalisable range: biased exponents 0, 1, 2 and 252, 253,
        // 254.
        let special = [0.0, -0.0, 1e-40, -1e-39, 1.5e-38, -2e-38, 3e-38, 1.0, -3.5, 5e37, -1e38, 1.2e38, -2e38, 3.3e38, f32::INFINITY, f32::NEG_INFINITY, f32::NAN];
        let (mut valid_rays, mut rays_seen) = (0, 0);
        for i in 0..20_000u32 {
            let c = |rng: &mut Rng, p: u32| if rng.next_u32() % p == 0 { special[(rng.next_u32() % special.len() as u32) as usize] } else { (rng.next_f32() * 2.0 - 1.0) * 8.0 };
            let rays: [Ray; W] = core::array::from_fn(|_| {
                let p = if i % 2 == 0 { 4 } else { 40 };
                let o = [c(&mut rng, p), c(&mut rng, p), c(&mut rng, p)];
                let mut d = [c(&mut rng, p), c(&mut rng, p), c(&mut rng, p)];
                if i % 3 == 0 {
                    // A special largest component, the others below it.
                    let m = special[(rng.next_u32() % special.len() as u32) as usize];
                    let k = (rng.next_u32() % 3) as usize;
                    d = [m * rng.next_f32(), m * rng.next_f32(), m * rng.next_f32()];
                    d[k] = m;
                }
                let t = [0.0, -0.0, -1.0, 0.5, 2.0, f32::INFINITY, f32::NAN];
                let t_min = if rng.next_u32() % 3 == 0 { t[(rng.next_u32() % 7) as usize] } else { 0.0 };
                let t_max = if rng.next_u32() % 3 == 0 { t[(rng.next_u32() % 7) as usize] } else { f32::INFINITY };
                Ray::new(o, d, t_min, t_max)
            });
            let (lanes, valid) = ShearedLanes::of(&rays);
            for (l, ray) in rays.iter().enumerate() {
                // The straightforward constants.
                let reference = ray.is_valid().then(|| {
                    let a = ray.dir.map(f32::abs);
                    let kz = if a[0] >= a[1] && a[0] >= a[2] { 0 } else if a[1] >= a[2] { 1 } else { 2 };
                    let p = permute(ray.dir, kz);
                    let scale = crate::math::pow2_normaliser(p[2]).unwrap();
                    (ray.origin, kz, p[0] * scale, p[1] * scale, p[2] * scale, scale)
                });
                let bits = |r: &ShearedRay| (r.origin.map(f32::to_bits), r.kz, r.dx.to_bits(), r.dy.to_bits(), r.dz.to_bits(), r.scale.to_bits());
                let one = ShearedRay::new(ray);
                assert_eq!(one.as_ref().map(bits), reference.map(|(o, kz, dx, dy, dz, s)| (o.map(f32::to_bits), kz, dx.to_bits(), dy.to_bits(), dz.to_bits(), s.to_bits())), "{ray:?}");
                assert_eq!(valid >> l & 1 == 1, one.is_some(), "{ray:?}");
                let lane = ShearedRay { origin: [lanes.origin[0][l], lanes.origin[1][l], lanes.origin[2][l]], kz: lanes.kz[l], dx: lanes.dx[l], dy: lanes.dy[l], dz: lanes.dz[l], scale: lanes.scale[l] };
                let default = ShearedLanes::<1>::default();
                let none = ShearedRay { origin: [0.0; 3], kz: default.kz[0], dx: default.dx[0], dy: default.dy[0], dz: default.dz[0], scale: default.scale[0] };
                assert_eq!(bits(&lane), bits(one.as_ref().unwrap_or(&none)), "{ray:?}");
                valid_rays += one.is_some() as u32;
                rays_seen += 1;
            }
        }
        // Both kinds, many times.
        assert!(valid_rays > rays_seen / 5 && valid_rays < rays_seen * 4 / 5, "{valid_rays} of {rays_seen}");
    }

    /// All lanes at once give each lane's one-ray answer bit for bit: random triangles (large,
    /// thin, degenerate, on a grid so rays pass through shared edges and vertices) and rays in
    /// every direction, with intervals that cut hits off at either end.
    #[test]
    fn lanes_give_the_one_ray_test_bit_for_bit() {
        const W: usize = 8;
        let mut rng = Rng::new(3, 1);
        let (mut hits, mut cases) = (0, 0);
        for i in 0..40_000u32 {
            let f = |rng: &mut Rng, s: f32| (rng.next_f32() * 2.0 - 1.0) * s;
            // On a coarse grid every few cases: shared coordinates, exact zeros.
            let grid = i % 4 == 0;
            let q = |x: f32| if grid { (x * 2.0).round() * 0.5 } else { x };
            let mut v = [[0.0f32; 3]; 3];
            for vert in v.iter_mut() {
                *vert = [q(f(&mut rng, 2.0)), q(f(&mut rng, 2.0)), q(f(&mut rng, 2.0))];
            }
            if i % 9 == 0 {
                v[2] = v[1]; // degenerate
            }
            let mut rays = [Ray::default(); W];
            let mut lanes = ShearedLanes::<W>::default();
            let (mut t_min, mut t_max) = ([0.0f32; W], [0.0f32; W]);
            let mut valid = 0u32;
            for l in 0..W {
                let o = [q(f(&mut rng, 4.0)), q(f(&mut rng, 4.0)), q(f(&mut rng, 4.0))];
                // Mostly towards the triangle (a vertex, an edge's midpoint or inside).
                let k = rng.next_u32() % 4;
                let target = match k {
                    0 => v[0],
                    1 => [(v[0][0] + v[1][0]) * 0.5, (v[0][1] + v[1][1]) * 0.5, (v[0][2] + v[1][2]) * 0.5],
                    2 => [(v[0][0] + v[1][0] + v[2][0]) / 3.0, (v[0][1] + v[1][1] + v[2][1]) / 3.0, (v[0][2] + v[1][2] + v[2][2]) / 3.0],
                    _ => [f(&mut rng, 2.0), f(&mut rng, 2.0), f(&mut rng, 2.0)],
                };
                let d = [target[0] - o[0], target[1] - o[1], target[2] - o[2]];
                let mut tmin = if l % 3 == 0 { rng.next_f32() } else { 0.0 };
                let mut tmax = if l % 2 == 0 { f32::INFINITY } else { tmin + rng.next_f32() * 1.5 };
                // Some intervals end, or start, exactly at the hit.
                if let Some(h) = ShearedRay::new(&Ray::new(o, d, 0.0, f32::INFINITY)).and_then(|r| intersect_triangle(&r, v[0], v[1], v[2], 0.0, f32::INFINITY)) {
                    match l % 4 {
                        1 => (tmin, tmax) = (0.0, h.t),
                        3 => (tmin, tmax) = (h.t, f32::INFINITY),
                        _ => {}
                    }
                }
                rays[l] = Ray::new(o, d, tmin, tmax);
                if let Some(r) = ShearedRay::new(&rays[l]) {
                    lanes.set(l, &r);
                    valid |= 1 << l;
                }
                t_min[l] = tmin;
                t_max[l] = tmax;
            }
            let (mut t, mut b1, mut b2) = ([0.0f32; W], [0.0f32; W], [0.0f32; W]);
            let got = valid & intersect_triangle_lanes(&lanes, v[0], v[1], v[2], &t_min, &t_max, &mut t, &mut b1, &mut b2);
            for l in 0..W {
                if valid & (1 << l) == 0 {
                    continue;
                }
                cases += 1;
                let one = intersect_triangle(&ShearedRay::new(&rays[l]).unwrap(), v[0], v[1], v[2], t_min[l], t_max[l]);
                let lane = (got & (1 << l) != 0).then(|| TriHit { t: t[l], b1: b1[l], b2: b2[l] });
                assert_eq!(lane.map(|h| (h.t.to_bits(), h.b1.to_bits(), h.b2.to_bits())), one.map(|h| (h.t.to_bits(), h.b1.to_bits(), h.b2.to_bits())), "case {i}, lane {l}: {:?}", rays[l]);
                hits += one.is_some() as u32;
            }
        }
        assert!(hits > cases / 10 && hits < cases * 9 / 10, "{hits} hits of {cases}");
    }
}
