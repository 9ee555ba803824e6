//! Scalar helpers that lower to the same operation on CPU (LLVM intrinsics) and GPU
//! (GLSL.std.450 through rust-gpu). Fused multiply-add is used explicitly wherever the
//! result must not depend on whether a compiler contracts `a * b + c`.

/// Fused multiply-add `a * b + c`: `mul_add` in the shader build; natively the FMA instruction,
/// inline, where the build targets it (x86-64 with `target-feature=+fma`, as this repository's
/// `.cargo/config.toml` sets), else `libm::fmaf` (correctly rounded too, but a call through a
/// pointer chosen at run time: it took 28 % of a native trace's time).
#[inline(always)]
pub fn fma(a: f32, b: f32, c: f32) -> f32 {
    #[cfg(target_arch = "spirv")]
    return core::f32::math::mul_add(a, b, c);
    #[cfg(all(target_arch = "x86_64", target_feature = "fma"))]
    // SAFETY: the build targets FMA (the cfg), so the instruction exists.
    #[allow(unused_unsafe)]
    return unsafe {
        use core::arch::x86_64::{_mm_cvtss_f32, _mm_fmadd_ss, _mm_set_ss};
        _mm_cvtss_f32(_mm_fmadd_ss(_mm_set_ss(a), _mm_set_ss(b), _mm_set_ss(c)))
    };
    #[cfg(not(any(target_arch = "spirv", all(target_arch = "x86_64", target_feature = "fma"))))]
    return libm::fmaf(a, b, c);
}

/// A mask of lanes (bit l for lane l < `W` ≤ 32) set one lane at a time in a loop over the
/// lanes, each lane once. Natively with AVX each lane's flag is kept as a whole word of its
/// sign, and with eight lanes the mask is taken at once (`vmovmskps`; other widths shift the
/// signs in): a compiler turns `m |= flag << l` over eight vectorised lanes into an and and an
/// or-reduction of the eight bits, 14 % of a BVH packet's walk. Elsewhere (the GPU among them)
/// the bits themselves.
#[derive(Copy, Clone)]
pub struct LaneMask<const W: usize> {
    #[cfg(all(target_arch = "x86_64", target_feature = "avx"))]
    words: [u32; W],
    #[cfg(not(all(target_arch = "x86_64", target_feature = "avx")))]
    bits: u32,
}

impl<const W: usize> LaneMask<W> {
    /// No lane set.
    #[inline(always)]
    pub fn new() -> Self {
        #[cfg(all(target_arch = "x86_64", target_feature = "avx"))]
        return LaneMask { words: [0; W] };
        #[cfg(not(all(target_arch = "x86_64", target_feature = "avx")))]
        return LaneMask { bits: 0 };
    }
    /// Lane `l` set where `on` (each lane is given once).
    #[inline(always)]
    pub fn put(&mut self, l: usize, on: bool) {
        #[cfg(all(target_arch = "x86_64", target_feature = "avx"))]
        {
            self.words[l] = (on as u32).wrapping_neg();
        }
        #[cfg(not(all(target_arch = "x86_64", target_feature = "avx")))]
        {
            self.bits |= (on as u32) << l;
        }
    }
    /// The mask.
    #[inline(always)]
    pub fn bits(&self) -> u32 {
        #[cfg(all(target_arch = "x86_64", target_feature = "avx"))]
        {
            if W == 8 {
                use core::arch::x86_64::{_mm256_castsi256_ps, _mm256_loadu_si256, _mm256_movemask_ps};
                // SAFETY: the cfg guarantees AVX; the words are eight u32 (W == 8).
                return unsafe { _mm256_movemask_ps(_mm256_castsi256_ps(_mm256_loadu_si256(self.words.as_ptr().cast()))) as u32 };
            }
            let mut m = 0u32;
            let mut l = 0;
            while l < W {
                m |= (self.words[l] >> 31) << l;
                l += 1;
            }
            m
        }
        #[cfg(not(all(target_arch = "x86_64", target_feature = "avx")))]
        return self.bits;
    }
}

impl<const W: usize> Default for LaneMask<W> {
    fn default() -> Self {
        Self::new()
    }
}

/// The larger of `a` and `b`, for operands known not to be NaN (with a NaN the result is
/// either operand). `f32::max` natively: its NaN rule costs a compare and a blend beside the
/// `maxss` on x86 (a fifth of a BVH walk's time); here the comparison is the instruction's
/// own. On the GPU the GLSL FMax both compile to.
#[inline(always)]
pub fn max_num(a: f32, b: f32) -> f32 {
    #[cfg(target_arch = "spirv")]
    return a.max(b);
    #[cfg(not(target_arch = "spirv"))]
    return if a > b { a } else { b };
}

/// The smaller of `a` and `b`, for operands known not to be NaN (`max_num`'s twin).
#[inline(always)]
pub fn min_num(a: f32, b: f32) -> f32 {
    #[cfg(target_arch = "spirv")]
    return a.min(b);
    #[cfg(not(target_arch = "spirv"))]
    return if a < b { a } else { b };
}

/// `v[k]` (k in 0..3, else `v[2]`) by comparisons and selects instead of an index computed at
/// run time: a GPU compiler may place an array indexed dynamically in local memory.
#[inline(always)]
pub fn pick3(v: [f32; 3], k: usize) -> f32 {
    let a = if k == 0 { v[0] } else { v[1] };
    if k >= 2 { v[2] } else { a }
}

/// Square root (`core::f32::math::sqrt` in the shader build, `libm::sqrtf` natively).
#[inline(always)]
pub fn sqrt(x: f32) -> f32 {
    #[cfg(target_arch = "spirv")]
    return core::f32::math::sqrt(x);
    #[cfg(not(target_arch = "spirv"))]
    return libm::sqrtf(x);
}

/// `a * b - c * d` with the sign of the exact result (Kahan's algorithm: error ≤ 1.5 ulp, and
/// exactly 0 only when the exact value is 0). Used for the triangle edge functions, so that the
/// two triangles sharing an edge see exactly opposite signs whatever the driver contracts.
#[inline(always)]
pub fn diff_of_products(a: f32, b: f32, c: f32, d: f32) -> f32 {
    let w = c * d;
    let e = fma(-c, d, w);
    let f = fma(a, b, -w);
    f + e
}

/// The power of two `s` with `|x| * s` in [1, 2), for normal finite non-zero `x` whose exponent
/// leaves room (|x| in [2^-125, 2^126)); `None` otherwise. Scaling by it is exact.
#[inline(always)]
pub fn pow2_normaliser(x: f32) -> Option<f32> {
    let e = (x.to_bits() >> 23) & 0xff;
    if e < 2 || e > 252 {
        return None;
    }
    Some(f32::from_bits((254 - e) << 23))
}

/// γ(n) = nε/(1 − nε) of Higham / pbrt, ε = 2^-24: bounds the relative rounding error of n
/// floating-point operations.
pub const fn gamma(n: u32) -> f32 {
    let e = n as f32 * (f32::EPSILON * 0.5);
    e / (1.0 - e)
}

/// `a` if `c`, else `b`.
#[inline(always)]
pub fn select(c: bool, a: f32, b: f32) -> f32 {
    if c {
        a
    } else {
        b
    }
}

/// Dot product.
#[inline(always)]
pub fn dot3(a: [f32; 3], b: [f32; 3]) -> f32 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// Component-wise difference `a - b`.
#[inline(always)]
pub fn sub3(a: [f32; 3], b: [f32; 3]) -> [f32; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

/// Component-wise sum `a + b`.
#[inline(always)]
pub fn add3(a: [f32; 3], b: [f32; 3]) -> [f32; 3] {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}

/// `a` times the scalar `s`.
#[inline(always)]
pub fn scale3(a: [f32; 3], s: f32) -> [f32; 3] {
    [a[0] * s, a[1] * s, a[2] * s]
}

/// Component-wise product.
#[inline(always)]
pub fn mul3(a: [f32; 3], b: [f32; 3]) -> [f32; 3] {
    [a[0] * b[0], a[1] * b[1], a[2] * b[2]]
}

/// Cross product `a × b`.
#[inline(always)]
pub fn cross3(a: [f32; 3], b: [f32; 3]) -> [f32; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

/// Euclidean length.
#[inline(always)]
pub fn length3(a: [f32; 3]) -> f32 {
    sqrt(dot3(a, a))
}

/// `a` scaled to unit length (NaN for the zero vector).
#[inline(always)]
pub fn normalize3(a: [f32; 3]) -> [f32; 3] {
    scale3(a, 1.0 / length3(a))
}

/// `x` of a non-negative finite value rounded down to an integer, as `u32` (saturating).
#[inline(always)]
pub fn floor_u32(x: f32) -> u32 {
    if x >= 4_294_967_040.0 {
        u32::MAX
    } else if x > 0.0 {
        x as u32
    } else {
        0
    }
}

/// The fractional part of a non-negative `x` below 2^24.
#[inline(always)]
pub fn fract_pos(x: f32) -> f32 {
    x - (floor_u32(x) as f32)
}

/// (sin 2πu, cos 2πu) for u in [0, 1], from additions and multiplications only, so every
/// device computes the same values (to rounding): the quadrant from 4u, then Taylor polynomials
/// on [−π/4, π/4] (truncation below 3·10⁻⁸).
#[inline(always)]
pub fn sin_cos_turn(u: f32) -> (f32, f32) {
    let x = u * 4.0;
    let q = floor_u32(x + 0.5);
    let g = (x - q as f32) * core::f32::consts::FRAC_PI_2;
    let g2 = g * g;
    let s = g * (1.0 + g2 * (-1.0 / 6.0 + g2 * (1.0 / 120.0 + g2 * (-1.0 / 5040.0 + g2 * (1.0 / 362_880.0)))));
    let c = 1.0 + g2 * (-0.5 + g2 * (1.0 / 24.0 + g2 * (-1.0 / 720.0 + g2 * (1.0 / 40_320.0))));
    match q & 3 {
        0 => (s, c),
        1 => (c, -s),
        2 => (-s, -c),
        _ => (-c, s),
    }
}

/// Two unit vectors completing unit `n` to an orthonormal basis (Duff et al. 2017).
#[inline(always)]
pub fn basis(n: [f32; 3]) -> ([f32; 3], [f32; 3]) {
    let sign = select(n[2] >= 0.0, 1.0, -1.0);
    let a = -1.0 / (sign + n[2]);
    let b = n[0] * n[1] * a;
    ([1.0 + sign * n[0] * n[0] * a, sign * b, -sign * n[0]], [b, sign + n[1] * n[1] * a, -n[1]])
}

/// The direction `n`-hemisphere direction of cosine-weighted sample (u1, u2) (pdf cos θ / π).
#[inline(always)]
pub fn cosine_direction(n: [f32; 3], u1: f32, u2: f32) -> [f32; 3] {
    let r = sqrt(u1);
    let (s, c) = sin_cos_turn(u2);
    let z = sqrt((1.0 - u1).max(0.0));
    let (t, b) = basis(n);
    add3(add3(scale3(t, r * c), scale3(b, r * s)), scale3(n, z))
}

/// A direction with `cos θ` to `axis` and azimuth 2πu (for uniform sphere and cone samples).
#[inline(always)]
pub fn direction_around(axis: [f32; 3], cos_theta: f32, u: f32) -> [f32; 3] {
    let sin_theta = sqrt((1.0 - cos_theta * cos_theta).max(0.0));
    let (s, c) = sin_cos_turn(u);
    let (t, b) = basis(axis);
    add3(add3(scale3(t, sin_theta * c), scale3(b, sin_theta * s)), scale3(axis, cos_theta))
}

/// ⌊√n⌋, bit by bit: integers only, so every runtime gives the same root (a GPU's float square
/// root need not be correctly rounded). Fifteen steps at most.
#[inline(always)]
pub fn isqrt(n: u32) -> u32 {
    let (mut n, mut root, mut bit) = (n, 0u32, 1u32 << 30);
    while bit > n {
        bit >>= 2;
    }
    while bit != 0 {
        if n >= root + bit {
            n -= root + bit;
            root = (root >> 1) + bit;
        } else {
            root >>= 1;
        }
        bit >>= 2;
    }
    root
}

/// 2^k as f32 for k in [−126, 127].
#[inline(always)]
pub fn exp2i(k: i32) -> f32 {
    f32::from_bits(((k + 127) as u32) << 23)
}

/// Squared distance from `p` to the segment `a`–`b` (a degenerate segment: to `a`).
#[inline(always)]
pub fn dist2_point_segment(p: [f32; 3], a: [f32; 3], b: [f32; 3]) -> f32 {
    let ab = sub3(b, a);
    let l2 = dot3(ab, ab);
    let t = if l2 > 0.0 { (dot3(sub3(p, a), ab) / l2).max(0.0).min(1.0) } else { 0.0 };
    let d = sub3(p, add3(a, scale3(ab, t)));
    dot3(d, d)
}

/// Squared distance from `p` to the triangle `a`, `b`, `c` (its closest point): the region of
/// the triangle's plane `p` projects into — a vertex's, an edge's or the face's — from the
/// signs of the projections on the edges (barycentric Voronoi regions).
#[inline(always)]
pub fn dist2_point_triangle(p: [f32; 3], a: [f32; 3], b: [f32; 3], c: [f32; 3]) -> f32 {
    let (ab, ac, ap) = (sub3(b, a), sub3(c, a), sub3(p, a));
    let (d1, d2) = (dot3(ab, ap), dot3(ac, ap));
    let bp = sub3(p, b);
    let (d3, d4) = (dot3(ab, bp), dot3(ac, bp));
    let cp = sub3(p, c);
    let (d5, d6) = (dot3(ab, cp), dot3(ac, cp));
    // Twice the signed areas of the sub-triangles opposite c, b, a.
    let (vc, vb, va) = (d1 * d4 - d3 * d2, d5 * d2 - d1 * d6, d3 * d6 - d5 * d4);
    // A degenerate triangle (zero area in f32; the scene loader drops exact ones) takes a
    // vertex: no division by zero, and no early return (the NVIDIA driver 580's compiler
    // crashed on one in this function).
    let s = va + vb + vc;
    let inv = if s > 0.0 { 1.0 / s } else { 0.0 };
    let q = if d1 <= 0.0 && d2 <= 0.0 {
        a
    } else if d3 >= 0.0 && d4 <= d3 {
        b
    } else if d6 >= 0.0 && d5 <= d6 {
        c
    } else if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        add3(a, scale3(ab, d1 / (d1 - d3)))
    } else if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        add3(a, scale3(ac, d2 / (d2 - d6)))
    } else if va <= 0.0 && d4 - d3 >= 0.0 && d5 - d6 >= 0.0 {
        add3(b, scale3(sub3(c, b), (d4 - d3) / ((d4 - d3) + (d5 - d6))))
    } else {
        add3(a, add3(scale3(ab, vb * inv), scale3(ac, vc * inv)))
    };
    let d = sub3(p, q);
    dot3(d, d)
}
