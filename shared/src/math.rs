//! Scalar helpers that lower to the same operation on CPU (LLVM intrinsics) and GPU
//! (GLSL.std.450 through rust-gpu). Fused multiply-add is used explicitly wherever the
//! result must not depend on whether a compiler contracts `a * b + c`.

#[inline(always)]
pub fn fma(a: f32, b: f32, c: f32) -> f32 {
    core::f32::math::mul_add(a, b, c)
}

#[inline(always)]
pub fn sqrt(x: f32) -> f32 {
    core::f32::math::sqrt(x)
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

#[inline(always)]
pub fn select(c: bool, a: f32, b: f32) -> f32 {
    if c {
        a
    } else {
        b
    }
}

#[inline(always)]
pub fn dot3(a: [f32; 3], b: [f32; 3]) -> f32 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

#[inline(always)]
pub fn sub3(a: [f32; 3], b: [f32; 3]) -> [f32; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

#[inline(always)]
pub fn add3(a: [f32; 3], b: [f32; 3]) -> [f32; 3] {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}

#[inline(always)]
pub fn scale3(a: [f32; 3], s: f32) -> [f32; 3] {
    [a[0] * s, a[1] * s, a[2] * s]
}

#[inline(always)]
pub fn mul3(a: [f32; 3], b: [f32; 3]) -> [f32; 3] {
    [a[0] * b[0], a[1] * b[1], a[2] * b[2]]
}

#[inline(always)]
pub fn cross3(a: [f32; 3], b: [f32; 3]) -> [f32; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

#[inline(always)]
pub fn length3(a: [f32; 3]) -> f32 {
    sqrt(dot3(a, a))
}

#[inline(always)]
pub fn normalize3(a: [f32; 3]) -> [f32; 3] {
    scale3(a, 1.0 / length3(a))
}
