//! The eye paths' numbers (`kdray_shared::sampler`): each pixel's scrambled Sobol points are
//! nets over the samples of any pass split, every number is uniform and the dimensions and
//! pixels independent, they integrate an edge and a soft shadow with less error than
//! independent numbers, and a render with them converges to the same image with less error.
mod common;

use kdray::accel::Accel;
use kdray::integrator::path::{self, PathOptions};
use kdray::integrator::photon::{self as pm, PhotonMap, PhotonOptions};
use kdray::integrator::{RenderOutput, SamplerKind};
use kdray::kdtree::{self, BuildOptions};
use kdray::runtime::cpu::NATIVE;
use kdray::{scene, Tracer};
use kdray_shared::kdtree::Algorithm;
use kdray_shared::sampler::{owen, sobol_1, Sampler};
use kdray_shared::{Camera, RenderParams, RENDER_SOBOL};

/// Render parameters of an image of `pixels` pixels whose dispatch starts at sample `base`.
fn params(pixels: u32, base: u32, sobol: bool, seed: u32) -> RenderParams {
    RenderParams {
        camera: Camera { width: pixels, height: 1, ..Default::default() },
        flags: if sobol { RENDER_SOBOL } else { 0 },
        sample_base: base,
        sequence: seed,
        seed,
        ..Default::default()
    }
}

/// The top `bits` bits of a number in [0, 1).
fn top(u: f32, bits: u32) -> u32 {
    ((u as f64) * (1u64 << bits) as f64) as u32
}

/// Samples `first..first + 2^k` of a pixel are a (0, k, 2)-net in every dimension pair: one
/// point in each elementary box of 2^-k, of every shape — for the first block and later ones,
/// whether the samples come one per dispatch (passes) or several per dispatch (eye samples of a
/// pass: the pixel's stream is pixel + sample × pixels).
#[test]
fn each_block_of_a_pixels_samples_is_a_net() {
    let pixels = 7;
    for (pixel, dim) in [(0u32, 0u32), (3, 1), (6, 0x1234)] {
        for k in 1..=10u32 {
            let n = 1u32 << k;
            for block in [0, 1, 5] {
                // Per pass of 4 samples: dispatch d holds samples 4d..4d + 4.
                let per = 4.min(n);
                let pts: Vec<[f32; 2]> = (0..n)
                    .map(|i| {
                        let s = block * n + i;
                        let p = params(pixels, s / per * per, true, 42);
                        Sampler::new(&p, pixel + (s % per) * pixels).get2(dim)
                    })
                    .collect();
                for split in 0..=k {
                    let mut seen = vec![false; n as usize];
                    for u in &pts {
                        let cell = (top(u[0], split) << (k - split)) | top(u[1], k - split);
                        assert!(!seen[cell as usize], "pixel {pixel} dim {dim} k {k} block {block} split {split}: two points in one box");
                        seen[cell as usize] = true;
                    }
                }
            }
        }
    }
}

/// The plain sequence is Sobol's: van der Corput and the Pascal matrix (first points known),
/// and Owen scrambling keeps leading bits together (numbers agreeing in their top j bits
/// still agree after it) and is a bijection.
#[test]
fn sobol_points_and_owen_scrambling() {
    let first: Vec<(u32, u32)> = (0..8u32).map(|n| (n.reverse_bits() >> 29, sobol_1(n) >> 29)).collect();
    assert_eq!(first, vec![(0, 0), (4, 4), (2, 6), (6, 2), (1, 5), (5, 1), (3, 3), (7, 7)]);
    for seed in [1u32, 0x9E37_79B9, 12345] {
        for a in (0..100_000u32).map(|i| i.wrapping_mul(0x9E37_79B9)) {
            assert_eq!(owen(a, seed) >> 1, owen(a ^ 1, seed) >> 1);
            assert_eq!(owen(a, seed) >> 21, owen(a ^ (1 << 20), seed) >> 21);
        }
        let mut seen = std::collections::HashSet::new();
        for a in 0..1u32 << 16 {
            assert!(seen.insert(owen(a << 16, seed) >> 16), "not a bijection");
        }
    }
}

/// Pearson's statistic of `counts` against equal probabilities.
fn chi2_uniform(counts: &[u64]) -> f64 {
    let n: u64 = counts.iter().sum();
    let e = n as f64 / counts.len() as f64;
    counts.iter().map(|&c| (c as f64 - e).powi(2) / e).sum()
}

/// Across pixels each number is uniform (chi-square over 16 × 16 boxes, for a sample deep in
/// the sequence and for both modes), and two dimensions of one sample, or one dimension of two
/// neighbouring pixels, are uncorrelated.
#[test]
fn numbers_are_uniform_and_independent() {
    let pixels = 1 << 16;
    for sobol in [true, false] {
        for (base, dim) in [(0u32, 0u32), (37, 5), (1 << 20, 0x1003)] {
            let p = params(pixels, base, sobol, 9);
            let mut counts = vec![0u64; 256];
            let (mut sxy, mut sx, mut sy, mut sxx) = (0.0f64, 0.0, 0.0, 0.0);
            let mut prev = 0.0f64;
            let mut s_adj = 0.0f64;
            for px in 0..pixels {
                let smp = Sampler::new(&p, px);
                let u = smp.get2(dim);
                counts[(top(u[0], 4) * 16 + top(u[1], 4)) as usize] += 1;
                let v = smp.get1(dim + 1) as f64;
                let x = u[0] as f64;
                sxy += x * v;
                sx += x;
                sy += v;
                sxx += x * x;
                s_adj += x * prev;
                prev = x;
            }
            let n = pixels as f64;
            // 255 degrees of freedom: mean 255, sd 22.6.
            let c = chi2_uniform(&counts);
            assert!(c < 255.0 + 6.0 * 22.6, "sobol {sobol} base {base} dim {dim}: chi-square {c}");
            let var = sxx / n - (sx / n).powi(2);
            let cov = sxy / n - sx / n * sy / n;
            let cov_adj = s_adj / n - (sx / n).powi(2);
            // Correlation of independent uniforms: sd 1/sqrt(n) = 0.004.
            assert!((cov / var).abs() < 0.02, "dimensions correlated: {}", cov / var);
            assert!((cov_adj / var).abs() < 0.02, "neighbouring pixels correlated: {}", cov_adj / var);
        }
    }
}

/// RMSE over many pixels of the estimate of ∫ f over the unit square with `n` samples each.
fn integration_error(f: &dyn Fn([f32; 2]) -> f64, exact: f64, n: u32, sobol: bool) -> f64 {
    let pixels = 2000;
    let mut se = 0.0;
    for px in 0..pixels {
        let mut sum = 0.0;
        for s in 0..n {
            sum += f(Sampler::new(&params(pixels, s, sobol, 3), px).get2(16));
        }
        se += (sum / n as f64 - exact).powi(2);
    }
    (se / pixels as f64).sqrt()
}

/// Where stratification pays: an edge through a pixel (a silhouette) and a smooth integrand
/// (a soft shadow's ramp). Independent numbers' error falls as n^-1/2; the sequence's, at 256
/// samples, is several times lower (an edge: about n^-3/4).
#[test]
fn stratified_numbers_integrate_an_edge_and_a_ramp_with_less_error() {
    let edge = |u: [f32; 2]| if (u[0] as f64) + 0.37 * (u[1] as f64) < 0.61 { 1.0 } else { 0.0 };
    // Area below the line x = 0.61 − 0.37 y, 0 <= y <= 1: 0.61 − 0.37/2.
    let edge_area = 0.61 - 0.185;
    let ramp = |u: [f32; 2]| (u[0] as f64) * (u[1] as f64).sqrt();
    let ramp_exact = 0.5 * 2.0 / 3.0;
    for (name, f, exact, gain) in [("edge", &edge as &dyn Fn([f32; 2]) -> f64, edge_area, 4.0), ("ramp", &ramp, ramp_exact, 10.0)] {
        let mc = integration_error(f, exact, 256, false);
        let qmc = integration_error(f, exact, 256, true);
        // Independent: sd of the integrand / 16.
        assert!(mc > 0.005, "{name}: independent error {mc} implausibly low");
        assert!(qmc * gain < mc, "{name}: Sobol error {qmc} not {gain}x below independent {mc}");
    }
}

/// The relative RMSE of `img` against `reference` over all pixels and channels.
fn rel_rmse(img: &RenderOutput, reference: &RenderOutput) -> f64 {
    let (mut se, mut sum) = (0.0, 0.0);
    for (a, b) in img.radiance.iter().zip(&reference.radiance) {
        for c in 0..3 {
            se += (a[c] as f64 - b[c] as f64).powi(2);
            sum += b[c] as f64;
        }
    }
    let n = img.radiance.len() as f64 * 3.0;
    (se / n).sqrt() / (sum / n)
}

/// The Cornell box by direct lighting with jittered camera rays (edges, the light's soft
/// shadows): at 64 samples per pixel the Sobol render is closer to a 4096-sample reference
/// than the independent one (both unbiased: the same image in the limit), natively and on the
/// GPU (the same numbers: the images agree to rounding).
#[test]
fn a_sobol_render_has_less_error_at_equal_samples() {
    let scene = scene::load("cornell").unwrap();
    let tree = kdtree::try_build(&scene.triangles, &BuildOptions::default()).unwrap();
    let cam = scene.camera.to_pod(32, 32);
    let t = Tracer::new(&NATIVE, &scene, Some(&tree)).unwrap();
    let accel = Accel::kd(Algorithm::ShortStack(3));
    let opts = |spp, sampler, seed| PathOptions { jitter: true, spp, sampler, ..PathOptions::direct(seed, 4) };
    let reference = path::render(&t, accel, &cam, &opts(4096, SamplerKind::Independent, 77), &()).unwrap();
    let mut errs = [0.0f64; 2];
    for (k, sampler) in [SamplerKind::Sobol, SamplerKind::Independent].into_iter().enumerate() {
        for seed in 1..=3 {
            errs[k] += rel_rmse(&path::render(&t, accel, &cam, &opts(64, sampler, seed), &()).unwrap(), &reference) / 3.0;
        }
    }
    eprintln!("direct lighting, 64 spp: Sobol {:.3} %, independent {:.3} %", errs[0] * 100.0, errs[1] * 100.0);
    assert!(errs[0] * 1.5 < errs[1], "Sobol {} not clearly below independent {}", errs[0], errs[1]);
    if let Some(g) = common::gpu() {
        let tg = Tracer::new(g, &scene, Some(&tree)).unwrap();
        let a = path::render(&tg, accel, &cam, &opts(16, SamplerKind::Sobol, 5), &()).unwrap();
        let b = path::render(&t, accel, &cam, &opts(16, SamplerKind::Sobol, 5), &()).unwrap();
        let e = rel_rmse(&a, &b);
        assert!(e < 1e-4, "GPU and native Sobol renders differ by {e}");
    }
}

/// Photon mapping's eye samples continue one sequence per pixel over the passes: the render
/// of 8 passes with the Sobol sampler is closer to the reference than with independent
/// numbers, the photons being the same.
#[test]
fn photon_passes_continue_each_pixels_sequence() {
    let scene = scene::load("cornell").unwrap();
    let tree = kdtree::try_build(&scene.triangles, &BuildOptions::default()).unwrap();
    let cam = scene.camera.to_pod(24, 24);
    let t = Tracer::new(&NATIVE, &scene, Some(&tree)).unwrap();
    let accel = Accel::kd(Algorithm::ShortStack(3));
    let reference = path::render(&t, accel, &cam, &PathOptions::path(0x5EED, 16, 4096), &()).unwrap();
    let mut errs = [0.0f64; 2];
    for (k, sampler) in [SamplerKind::Sobol, SamplerKind::Independent].into_iter().enumerate() {
        let o = PhotonOptions { photons: 1 << 15, passes: 16, eye_samples: 4, sampler, ..Default::default() };
        let mut map = PhotonMap::new(&t, accel, Some(&tree), &scene, o).unwrap();
        errs[k] = rel_rmse(&pm::render(&mut map, &cam, &()).unwrap().0, &reference);
    }
    eprintln!("photon mapping, 16 passes × 4: Sobol {:.3} %, independent {:.3} %", errs[0] * 100.0, errs[1] * 100.0);
    assert!(errs[0] < errs[1], "Sobol {} not below independent {}", errs[0], errs[1]);
}
