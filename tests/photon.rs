//! Photon mapping against what it must reproduce: the lights' emission distribution
//! (chi-square), the index against brute force, irradiance under a point light, a furnace,
//! convergence to the path-traced reference, and the same photons and images on the native
//! runtime and the GPU (lavapipe in CI).
mod common;

use glam::Vec3;
use kdray::accel::Accel;
use kdray::integrator::path::{self, PathOptions};
use kdray::integrator::photon::{self as pm, FinalGather, IndexKind, PhotonMap, PhotonOptions};
use kdray::integrator::RenderOutput;
use kdray::kdtree::{self, BuildOptions, KdTreeData};
use kdray::runtime::cpu::NATIVE;
use kdray::scene::{self, CameraSpec, PointLight, Scene, Spot};
use kdray::{Runtime, Tracer};
use kdray_shared::kdtree::Algorithm;
use kdray_shared::photon::{cell_range, emission_numbers, emit_photon, irradiance, HashGrid, KdCells, PhotonIndex, PhotonWord, SortedPhotons, WordFrame};
use kdray_shared::{Material, Photon, PhotonParams, INDEX_KD, PHOTON_SOBOL};

fn runtimes() -> Vec<&'static dyn Runtime> {
    let mut v: Vec<&'static dyn Runtime> = vec![&NATIVE];
    if let Some(g) = common::gpu() {
        v.push(g);
    }
    v
}

fn tree(s: &Scene) -> KdTreeData {
    kdtree::try_build(&s.triangles, &BuildOptions::default()).unwrap()
}

/// Pearson's statistic of `counts` against expected probabilities `p` (summing to 1).
fn chi2(counts: &[u64], p: &[f64]) -> f64 {
    let n: u64 = counts.iter().sum();
    counts.iter().zip(p).map(|(&c, &q)| (c as f64 - n as f64 * q).powi(2) / (n as f64 * q)).sum()
}

/// Far beyond chance for `dof` degrees of freedom (about 6 standard deviations).
fn chi2_bound(dof: usize) -> f64 {
    dof as f64 + 6.0 * (2.0 * dof as f64).sqrt()
}

fn uniform(k: usize) -> Vec<f64> {
    vec![1.0 / k as f64; k]
}

fn bin(x: f64, lo: f64, hi: f64, k: usize) -> usize {
    (((x - lo) / (hi - lo) * k as f64) as usize).min(k - 1)
}

#[test]
fn emitted_photons_follow_the_lights_emission() {
    // A right-triangle light in the plane y = 1 facing +y, a point light and a spot light.
    let mut s = Scene::new("lights", CameraSpec::framing(Vec3::ZERO, Vec3::ONE));
    let m = s.add_material("emitter", Material { diffuse: [0.5; 3], emission: [2.0, 1.0, 0.5], ..Default::default() });
    s.add_triangle([Vec3::new(0.0, 1.0, 0.0), Vec3::new(0.0, 1.0, 1.0), Vec3::new(1.0, 1.0, 0.0)], m, &|| "light".into()).unwrap();
    s.point_lights.push(PointLight { position: Vec3::new(5.0, 5.0, 5.0), intensity: Vec3::new(0.3, 0.2, 0.1), spot: None });
    let axis = Vec3::new(0.0, -1.0, 0.0);
    s.point_lights.push(PointLight {
        position: Vec3::new(-5.0, 5.0, 5.0),
        intensity: Vec3::new(1.0, 1.0, 1.0),
        spot: Some(Spot { direction: axis, cone_deg: 30.0, falloff_start_deg: 30.0 }),
    });
    let lights = s.lights();
    assert_eq!(lights.len(), 3);
    let total: f64 = lights.iter().map(scene::power).sum();
    let expected: Vec<f64> = lights.iter().map(|l| scene::power(l) / total).collect();
    // Photons of one lane across groups are independent (or, from the Sobol sequence,
    // stratified: a chi-square far below its expectation), each with the lights' distribution
    // (the toroidal shift); photons of one group are not independent of each other, so
    // grouped emission is tested lane by lane.
    let n = 200_000u32;
    let cases = [(0.0f32, None), (1.0, Some(0)), (1.0, Some(13)), (0.25, Some(31)), (0.25, Some(5)), (0.1, Some(7))];
    for (flags, (spread, lane)) in [0, PHOTON_SOBOL].into_iter().flat_map(|f| cases.into_iter().map(move |c| (f, c))) {
        let params = PhotonParams { seed: 77, sequence: 78, pass: 3, emitted: n * 32, spread, flags, ..Default::default() };
        let (mut which, mut x_bins, mut cos2, mut phi) = ([0u64; 3], [0u64; 10], [0u64; 10], [0u64; 8]);
        let (mut sphere_z, mut cone_z) = ([0u64; 10], [0u64; 10]);
        let mut power = [0.0f64; 3];
        for k in 0..n {
            let i = match lane {
                None => k,
                Some(l) => k * 32 + l,
            };
            let (ray, p) = emit_photon(&lights, 3, n, emission_numbers(&params, i));
            for c in 0..3 {
                power[c] += p[c] as f64;
            }
            let (o, d) = (Vec3::from(ray.origin), Vec3::from(ray.dir).normalize());
            if o.distance(Vec3::new(5.0, 5.0, 5.0)) < 1e-6 {
                which[1] += 1;
                sphere_z[bin(d.z as f64, -1.0, 1.0, 10)] += 1;
            } else if o.distance(Vec3::new(-5.0, 5.0, 5.0)) < 1e-6 {
                which[2] += 1;
                let c = d.dot(axis) as f64;
                let cmax = 30f64.to_radians().cos();
                assert!(c >= cmax - 1e-6, "spot photon outside its cone: cos {c}");
                cone_z[bin(c, cmax, 1.0, 10)] += 1;
            } else {
                which[0] += 1;
                assert!((o.y - 1.0).abs() < 1e-4 && o.x >= -1e-6 && o.z >= -1e-6 && o.x + o.z <= 1.0 + 1e-5, "{o}");
                x_bins[bin(o.x as f64, 0.0, 1.0, 10)] += 1;
                assert!(d.y > 0.0, "an area light photon leaves from its back side: {d}");
                let c = d.y as f64;
                cos2[bin(c * c, 0.0, 1.0, 10)] += 1;
                phi[bin((d.z as f64).atan2(d.x as f64), -std::f64::consts::PI, std::f64::consts::PI, 8)] += 1;
            }
        }
        // The x marginal of a uniform point on the triangle: density 2(1 − x).
        let px: Vec<f64> = (0..10).map(|k| (1.0 - k as f64 / 10.0).powi(2) - (1.0 - (k + 1) as f64 / 10.0).powi(2)).collect();
        for (name, counts, p) in [
            ("light choice ∝ power", &which[..], expected.clone()),
            ("position on the triangle", &x_bins[..], px),
            ("cos² θ (cosine-weighted)", &cos2[..], uniform(10)),
            ("azimuth", &phi[..], uniform(8)),
            ("point light z (uniform sphere)", &sphere_z[..], uniform(10)),
            ("spot light cos θ (uniform cone)", &cone_z[..], uniform(10)),
        ] {
            let x = chi2(counts, &p);
            assert!(x < chi2_bound(p.len() - 1), "flags {flags}, spread {spread}, lane {lane:?}: {name}: chi-square {x:.1} over {} bins ({counts:?})", p.len());
        }
        // Energy: the photons carry the lights' power (luminance-weighted selection, RGB power).
        let want: [f64; 3] = [0, 1, 2].map(|c| {
            lights
                .iter()
                .map(|l| scene::power(l) * l.emission[c] as f64 / (0.2126 * l.emission[0] as f64 + 0.7152 * l.emission[1] as f64 + 0.0722 * l.emission[2] as f64))
                .sum()
        });
        for c in 0..3 {
            assert!((power[c] / want[c] - 1.0).abs() < 0.01, "flags {flags}, spread {spread}, lane {lane:?}: channel {c}: photons carry {} W, lights emit {} W", power[c], want[c]);
        }
    }
}

fn small_options(index: IndexKind, photons: u32) -> PhotonOptions {
    PhotonOptions { photons, passes: 1, index, final_gather: FinalGather::Off, ..Default::default() }
}

/// Checks an index built on `rt` against the records: a permutation of their words, every
/// photon in its own cell, and gathers equal to brute force over the words.
fn check_index(map: &PhotonMap, tree: &KdTreeData, records: &[Photon], what: &str, pass: u32) {
    let (sorted, offsets) = map.read_index().unwrap();
    let view = SortedPhotons { words: &sorted, offsets: &offsets };
    let p = map.index_params(pass, 0);
    let frame = WordFrame::new(&p);
    // The words of the records; a word's maps (several records may share a word).
    let mut of_word: std::collections::HashMap<PhotonWord, Vec<u32>> = Default::default();
    for r in records {
        let w = PhotonWord::of(r, &frame);
        let q = frame.position(w.word);
        let field = frame.encode(r.position);
        for a in 0..3 {
            // Within half a step of where the photon landed (a step at the box's far end, where
            // the coordinate is clamped), plus the rounding of the frame's origin, of the
            // encoding's subtraction of the box's corner and of the decoding.
            let step = frame.step[a] as f64;
            let origin_error = (frame.origin[a] as f64 - (p.bounds_min[a] as f64 - 8_388_608.0 * step)).abs();
            let half_steps = if field[a] == (1 << kdray_shared::photon::WORD_BITS) - 1 { 1.0 } else { 0.5 };
            let encode_error = ((r.position[a] - p.bounds_min[a]).abs() as f64) * f32::EPSILON as f64;
            let tolerance = half_steps * step + origin_error + encode_error + (q[a].abs() as f64) * f32::EPSILON as f64;
            assert!(((q[a] - r.position[a]) as f64).abs() <= tolerance, "{what}: word at {q:?} for a photon at {:?}", r.position);
        }
        // The word's power: its photon's, rounded to a mantissa of 6 bits (red, green) or 5
        // (blue) up or down (`word_power`: every power lies within its range here).
        let (wp, rp) = (w.power(&frame), r.power());
        for c in 0..3 {
            let ulp = if c == 2 { 1.0 / 32.0 } else { 1.0 / 64.0 };
            assert!((wp[c] - rp[c]).abs() <= rp[c] * ulp, "{what}: a word's power {wp:?} is not its photon's {rp:?}");
        }
        // The word's normal: its photon's octahedral normal in whole numbers (`normal_bytes`:
        // at most 0.4° off).
        let dot = Vec3::from(w.normal()).dot(Vec3::from(r.normal()));
        assert!(dot >= 0.9999, "{what}: a word's normal is not its photon's ({:?} vs {:?})", w.normal(), r.normal());
        of_word.entry(w).or_default().push(if p.maps > 1 && r.is_caustic() { 1 } else { 0 });
    }
    let mut a: Vec<_> = records.iter().map(|r| PhotonWord::of(r, &frame).word.to_array()).collect();
    let mut b: Vec<_> = sorted.iter().map(|w| w.word.to_array()).collect();
    a.sort();
    b.sort();
    assert!(a == b, "{what}: the sorted photons are not the stored ones ({} vs {})", a.len(), b.len());
    let table = map.leaf_table(pass);
    let kd;
    let grid = HashGrid::new(&p);
    let index: &dyn Fn([f32; 3], u32) -> u32 = if p.kind == INDEX_KD {
        kd = KdCells::new(&p, &tree.nodes, table.as_deref().unwrap());
        &|x, m| kd.cell(x, m)
    } else {
        &|x, m| grid.cell(x, m)
    };
    // Each placed word with its map (the caustic map's cells follow the global map's).
    let mut placed: Vec<(PhotonWord, u32)> = Vec::new();
    for c in 0..p.cells * p.maps {
        let (a, b) = cell_range(&p, &offsets, c);
        let m = c / p.cells;
        for w in &sorted[a as usize..b as usize] {
            assert!(of_word[w].contains(&m), "{what}: a photon in the wrong map");
            assert_eq!(index(w.position(&frame), m), c, "{what}: a photon in the wrong cell");
            placed.push((*w, m));
        }
    }
    assert_eq!(placed.len(), sorted.len(), "{what}: the cells do not hold every placed photon once");
    // Gathers at photon positions (offset) against brute force.
    let gather = |x: [f32; 3], n: [f32; 3], m: u32| -> kdray_shared::photon::Estimate {
        if p.kind == INDEX_KD {
            let kd = KdCells::new(&p, &tree.nodes, table.as_deref().unwrap());
            irradiance(&kd, &p, &view, x, n, m)
        } else {
            irradiance(&grid, &p, &view, x, n, m)
        }
    };
    let mut nonempty = 0;
    // Points near photons, some of them on the grid's cell boundaries (where a gather that
    // trims its cells to the sphere must not lose a photon to rounding) or a radius away from
    // a photon along an axis.
    let cell_size = |m: u32, axis: usize| p.radius[m as usize] * 2.0 / (kdray_shared::photon::grid_windows(p.grid)[axis.min(1)] - 1) as f32;
    let snap = |x: f32, o: f32, c: f32| o + ((x - o) / c).round() * c;
    for (k, (ph, m)) in placed.iter().step_by((placed.len() / 1200).max(1)).enumerate() {
        let m = *m;
        let r = p.radius[m as usize];
        let q = ph.position(&frame);
        let (c, o) = ([cell_size(m, 0), cell_size(m, 1), cell_size(m, 2)], p.bounds_min);
        // The last two: the photon just within the radius along x, or along a diagonal (at the
        // end of the chord a row of the grid is clipped to, in a row away from x's).
        let x = match k % 5 {
            0 => [q[0] + 0.3 * r * ((k % 3) as f32 - 1.0), q[1], q[2] + 0.2 * r],
            1 => [snap(q[0], o[0], c[0]), snap(q[1], o[1], c[1]), snap(q[2], o[2], c[2])],
            2 => [snap(q[0], o[0], c[0]), q[1], q[2]],
            3 => [q[0] + r * [1.0, -1.0, 0.999_999][k % 3], q[1], q[2]],
            _ => {
                let s = [0.6, -0.6][k % 2] * 0.999_999 * r;
                [q[0] + s, q[1] + [0.48, -0.48][k / 5 % 2] * 0.999_999 * r, q[2] + [0.64, -0.64][k / 10 % 2] * 0.999_999 * r]
            }
        };
        let n = ph.normal();
        let est = gather(x, n, m);
        let (e, found) = (est.irradiance, est.found);
        let (mut want, mut count) = ([0.0f64; 3], 0);
        for (q, _) in placed.iter().filter(|(_, qm)| *qm == m) {
            // A word's offset from x as a gather decodes it (`WordFrame::offset`).
            let d = Vec3::from(frame.offset(q.word, frame.base(x)));
            if d.length_squared() > r * r {
                continue;
            }
            if kdray_shared::photon::facing(q.word, kdray_shared::photon::normal_units(n)) {
                count += 1;
                for c in 0..3 {
                    want[c] += q.power(&frame)[c] as f64;
                }
            }
        }
        assert_eq!(found, count, "{what}: gather at {x:?} found {found} photons, brute force {count}");
        let scale = 1.0 / (std::f64::consts::PI * (r as f64).powi(2));
        for c in 0..3 {
            let w = want[c] * scale;
            assert!((e[c] as f64 - w).abs() <= 1e-4 * w + 1e-30, "{what}: irradiance {} vs brute force {w}", e[c]);
        }
        nonempty += (count > 0) as usize;
    }
    assert!(nonempty > 300, "{what}: only {nonempty} gathers found photons");
}

/// Photon words sorted by cell as the index's sort leaves them (`cell_range` reads them back).
fn hand_index<I: PhotonIndex>(p: &kdray_shared::IndexParams, index: &I, words: &[PhotonWord]) -> (Vec<PhotonWord>, Vec<u32>) {
    let frame = WordFrame::new(p);
    let mut placed: Vec<(u32, PhotonWord)> = words.iter().map(|w| (index.cell(frame.position(w.word), 0), *w)).collect();
    placed.sort_by_key(|c| c.0);
    let slot = |c: u32| kdray_shared::photon::offset_slot(p, c) as usize;
    let mut offsets = vec![0u32; slot(p.cells - 1) + 2];
    let mut j = 0;
    for c in 0..p.cells {
        offsets[slot(c)] = j as u32;
        while j < placed.len() && placed[j].0 == c {
            j += 1;
        }
        offsets[slot(c) + 1] = j as u32;
    }
    assert_eq!(j, placed.len(), "a photon outside every cell");
    (placed.into_iter().map(|c| c.1).collect(), offsets)
}

/// The smallest `f32` in (a, b] for which `f` holds, where `f(a)` does not and `f(b)` does
/// (a < b; bisection over the floats in order).
fn first_where(a: f32, b: f32, f: impl Fn(f32) -> bool) -> f32 {
    // The floats' order as unsigned integers, and back.
    let key = |x: f32| if x.to_bits() >> 31 == 1 { !x.to_bits() } else { x.to_bits() | 1 << 31 };
    let from = |k: u32| f32::from_bits(if k >> 31 == 1 { k & !(1 << 31) } else { !k });
    let (mut lo, mut hi) = (key(a), key(b));
    assert!(lo < hi && !f(a) && f(b), "first_where({a}, {b}): {} {} {}", lo < hi, f(a), f(b));
    while hi - lo > 1 {
        let mid = lo + (hi - lo) / 2;
        if f(from(mid)) {
            hi = mid;
        } else {
            lo = mid;
        }
    }
    from(hi)
}

/// Gathers at radii of a few photon-word steps (10^-7 to 10^-5 of the scene box), where the
/// distance test's own rounding (its offsets are decoded against origin − x, rounded to about a
/// step) is as large as the radius: every index finds exactly the photons brute force counts
/// (`Disc::test` on every word), never one twice, at points a radius past a cell boundary with
/// photons just behind it (along an axis) and with photons all around at the radius; and a
/// gather at a point at infinity or NaN finds none (no panic, no endless loop).
#[test]
fn gathers_find_what_brute_force_counts_at_radii_of_a_few_word_steps() {
    let mut seed = 0x9e37_79b9_7f4a_7c15u64;
    let mut rand = move || {
        seed ^= seed << 13;
        seed ^= seed >> 7;
        seed ^= seed << 17;
        (seed >> 40) as f32 / (1u64 << 24) as f32
    };
    let n = [0.0, 0.0, 1.0];
    let mut accepted_behind = 0;
    for (min, max) in [([0.0f32; 3], [1000.0f32; 3]), ([1.5e5, 1e3, -2.2e5], [1.5e5 + 20.0, 1e3 + 20.0, -2.2e5 + 20.0]), ([-3.0, -1.0, -2.0], [4.0, 2.5, 1.0])] {
        for grid in [0, 2, 3, 5, 7, 9] {
            let base = kdray_shared::IndexParams { maps: 1, filter: kdray_shared::FILTER_CONSTANT, bounds_min: min, bounds_max: max, power_top: 2, ..Default::default() };
            let frame = WordFrame::new(&base);
            let step = frame.step[0].max(frame.step[1]).max(frame.step[2]);
            for r in [1.5 * step, 4.0 * step, 40.0 * step] {
                let p = if grid == 0 {
                    let d = 37u32;
                    kdray_shared::IndexParams { kind: INDEX_KD, cells: d * d * d, radius: [r, r], ..base }
                } else {
                    let [wx, w] = kdray_shared::photon::grid_windows(grid);
                    kdray_shared::IndexParams { kind: kdray_shared::INDEX_GRID, grid, cells: 64 * wx * w * w, radius: [r, r], ..base }
                };
                let nodes = [kdray_shared::kdtree::KdNode::leaf(0, 0)];
                let leaves = [kdray_shared::LeafCells { lo: min, base: 0, hi: max, dims: 37 | 37 << 10 | 37 << 20 }];
                let (kd, hash) = (KdCells::new(&p, &nodes, &leaves), HashGrid::new(&p));
                let cell = |x: [f32; 3]| if grid == 0 { kd.cell(x, 0) } else { hash.cell(x, 0) };
                let word = |x: [f32; 3]| PhotonWord::of(&Photon::new(x, [1.0; 3], [0.0, 0.0, 1.0], [0.0, 0.0, -1.0], false, false, 0.5), &frame);
                for trial in 0..60 {
                    let a = trial % 3;
                    let c: [f32; 3] = std::array::from_fn(|k| min[k] + (0.2 + 0.6 * rand()) * (max[k] - min[k]));
                    // Points a radius (and up to three steps) past a cell boundary b along axis
                    // a, photons on the words' steps just behind it. b: the first change of cell
                    // along a, found by stepping a quarter of a cell (so into the next cell),
                    // then bisecting. `at(t)`: c with its coordinate along a at t.
                    let size = if grid == 0 { (max[a] - min[a]) / 37.0 } else { hash.cell_size[0][a.min(1)] };
                    let at = |t: f32| {
                        let mut y = c;
                        y[a] = t;
                        y
                    };
                    let (mut near, mut far) = (c[a], c);
                    while cell(far) == cell(c) {
                        near = far[a];
                        // (At least a float further: a cell may be a few ulps wide.)
                        far[a] = (far[a] + 0.25 * size).max(far[a].next_up());
                        assert!(far[a] - c[a] < 2.0 * size, "grid {grid} axis {a} r {r}: no cell boundary within {size} of {c:?} ({:?})", hash.cell_size);
                    }
                    let b = first_where(near, far[a], |t| cell(at(t)) != cell(c));
                    let mut words = Vec::new();
                    for k in 1..=6 {
                        words.push(word(at(b - k as f32 * frame.step[a])));
                    }
                    // And photons all around a point, from 2 steps within the radius to 2 beyond.
                    for _ in 0..40 {
                        let d = Vec3::new(rand() - 0.5, rand() - 0.5, rand() - 0.5).normalize_or(Vec3::X);
                        let off = (r + (rand() - 0.5) * 4.0 * step) * d;
                        words.push(word([c[0] + off.x, c[1] + off.y, c[2] + off.z]));
                    }
                    let (sorted, offsets) = if grid == 0 { hand_index(&p, &kd, &words) } else { hand_index(&p, &hash, &words) };
                    let view = SortedPhotons { words: &sorted, offsets: &offsets };
                    let found_at = |x: [f32; 3]| if grid == 0 { irradiance(&kd, &p, &view, x, n, 0).found } else { irradiance(&hash, &p, &view, x, n, 0).found };
                    let mut points = vec![c];
                    for d in [0.0, 0.25, 0.5, 1.0, 2.0, 3.0] {
                        points.push(at(b + r + d * frame.step[a]));
                    }
                    for x in points {
                        let disc = kdray_shared::photon::Disc::new(&p, x, n, r);
                        let brute = sorted.iter().filter(|w| disc.test(w.word).0).count() as u32;
                        let found = found_at(x);
                        assert_eq!(found, brute, "grid {grid}, box {min:?}..{max:?}, r {r}: a gather at {x:?} found {found}, brute force {brute}");
                        // Photons behind the boundary that count from a point whose radius
                        // ends before it: the cases this test is for.
                        if x[a] - r >= b {
                            accepted_behind += words[..6].iter().filter(|w| disc.test(w.word).0).count();
                        }
                    }
                    // A point at infinity, or NaN: nothing found, no panic, no endless loop.
                    if trial == 0 {
                        for x in [[f32::INFINITY; 3], [f32::NEG_INFINITY, c[1], c[2]], [f32::NAN; 3], [1e38, -1e38, 1e38], [c[0], f32::INFINITY, c[2]]] {
                            let found = found_at(x);
                            assert_eq!(found, 0, "grid {grid}: a gather at {x:?} found {found}");
                        }
                    }
                }
            }
        }
    }
    assert!(accepted_behind > 0, "no photon behind a boundary counted: the cases miss what they test");
}

/// A photon word's power (`word_power`), from its record's RGB9E5: within its range each
/// channel rounded to 6 (red, green) or 5 (blue) bits of mantissa, up or down, and exactly
/// right on average over the dither (all 8^3 patterns of the bits it reads) up to the largest
/// value (above it, rounding up is clamped); below the range
/// dithered to 0 or the smallest value, right on average within the sampling error; above it
/// the largest; zero stays zero. Its floats (`power_floats`) are normal (GPUs may flush
/// subnormals) and times `power_scale` give the decoded power exactly, for every `power_top`.
#[test]
fn photon_word_powers_are_unbiased_over_their_dither() {
    use kdray_shared::photon::{power_floats, power_scale, word_power, POWER_TOP};
    let decode = |v: u32, top: i32| -> [f64; 3] {
        let f = power_floats(v);
        let s = power_scale(top);
        for x in f {
            assert!(x == 0.0 || x.is_normal(), "{v:#x}: a subnormal channel {x}");
        }
        let p = [f[0] * s, f[1] * s, f[2] * s];
        for c in 0..3 {
            assert_eq!(p[c] as f64, f[c] as f64 * s as f64, "{v:#x}: the scale's product is not exact");
        }
        p.map(|x| x as f64)
    };
    // RGB9E5 of three channels' mantissas and a shared exponent.
    let rgb9e5 = |m: [u32; 3], e: u32| m[0] | m[1] << 9 | m[2] << 18 | e << 27;
    let value = |m: u32, e: u32| m as f64 * 2f64.powi(e as i32 - 24);
    let patterns: Vec<u32> = (0..512u32).map(|k| (k & 7) | ((k >> 3) & 7) << 8 | (k >> 6) << 16).collect();
    let mut seed = 0x2545_f491_4f6c_dd1du64;
    let mut rand = move || {
        seed ^= seed << 13;
        seed ^= seed >> 7;
        seed ^= seed << 17;
        (seed >> 32) as u32
    };
    let mut below = 0;
    for top in [POWER_TOP[0], -20, 0, 3, 10, POWER_TOP[1]] {
        for trial in 0..400 {
            let m = [rand() % 512, rand() % 512, if trial % 7 == 0 { 0 } else { rand() % 512 }];
            let e = rand() % 32;
            let v = rgb9e5(m, e);
            let want = [value(m[0], e), value(m[1], e), value(m[2], e)];
            let (lo, hi) = (2f64.powi(top - 31), 2f64.powi(top));
            let mut mean = [0.0f64; 3];
            for &h in &patterns {
                let got = decode(word_power(v, top, h), top);
                for c in 0..3 {
                    let ulp = if c == 2 { 1.0 / 32.0 } else { 1.0 / 64.0 };
                    if want[c] == 0.0 {
                        assert_eq!(got[c], 0.0, "top {top}: zero became {}", got[c]);
                    } else if want[c] >= hi {
                        assert_eq!(got[c], hi * (1.0 - ulp / 2.0), "top {top}: {} not clamped to the largest", want[c]);
                    } else if want[c] >= lo {
                        assert!((got[c] - want[c]).abs() < want[c] * ulp, "top {top}: {} rounded to {}", want[c], got[c]);
                    } else {
                        assert!(got[c] == 0.0 || got[c] == lo, "top {top}: {} below the range became {}", want[c], got[c]);
                    }
                    mean[c] += got[c] / patterns.len() as f64;
                }
            }
            for c in 0..3 {
                let ulp = if c == 2 { 1.0 / 32.0 } else { 1.0 / 64.0 };
                if want[c] >= lo && want[c] <= hi * (1.0 - ulp / 2.0) {
                    assert!((mean[c] - want[c]).abs() <= want[c] * 1e-12, "top {top}: {} averages {} over the dither", want[c], mean[c]);
                } else if want[c] > 0.0 && want[c] < lo && want[c] > lo / 8.0 {
                    // Below the range: the smallest value with probability want / lo, over
                    // random hashes (the dither's second draw).
                    below += 1;
                    let n = 20_000;
                    let hits = (0..n).filter(|_| decode(word_power(v, top, rand()), top)[c] > 0.0).count() as f64;
                    let q = want[c] / lo;
                    let sigma = (q * (1.0 - q) / n as f64).sqrt();
                    assert!((hits / n as f64 - q).abs() <= 5.0 * sigma + 1e-9, "top {top}: {} below the range kept {} of the time, not {q}", want[c], hits / n as f64);
                }
            }
        }
    }
    assert!(below > 20, "only {below} channels below a range: the cases miss what they test");
}

/// The photon words' frame (`WordFrame`): steps of a power of two, fewer than 2^23 of them
/// across the box and at most twice the fewest, exact reciprocals, whatever the extent — a
/// power of two (where a division would round to either side), tiny, huge, or none.
#[test]
fn photon_word_frames_are_powers_of_two_within_a_factor_two() {
    for extent in [1.0f32, 2.0, 1024.0, 0.75, 3.0, 550.0, 1e-3, 1e-30, 3e30, 0.999_999_94, 0.0] {
        for min in [0.0f32, -1.0, 1.5e5] {
            let p = kdray_shared::IndexParams { bounds_min: [min; 3], bounds_max: [min + extent; 3], ..Default::default() };
            let f = WordFrame::new(&p);
            let (step, e) = (f.step[0] as f64, (p.bounds_max[0] - p.bounds_min[0]) as f64);
            if e == 0.0 {
                assert_eq!((f.step[0], f.inv[0]), (0.0, 0.0));
                continue;
            }
            assert_eq!(f.step[0].to_bits() & 0x7f_ffff, 0, "extent {e}: step {step} is not a power of two");
            assert_eq!(f.step[0] * f.inv[0], 1.0, "extent {e}: step {step}, inverse {}", f.inv[0]);
            assert!(e / step < 8_388_608.0 && e / step >= 4_194_304.0, "extent {e}: {} steps", e / step);
            // Both ends of the box decode to within a step and the origin's rounding.
            for x in [p.bounds_min[0], p.bounds_max[0]] {
                let q = f.encode([x; 3]);
                let w = glam::UVec4::new(q[0], q[1], q[2], 0);
                let err = (f.position(w)[0] as f64 - x as f64).abs();
                assert!(err <= step + (f.origin[0] as f64).abs() * 1.2e-7, "extent {e}, min {min}: {x} decodes {err} away");
            }
        }
    }
}

/// Every octahedral normal (all 2^16 codes) as a word's three bytes (`normal_bytes`): within
/// 0.4° of the code's direction and of length 127 within 0.9 (the gather's fixed bound,
/// `photon::facing`, rests on it), the bytes in range and never all zero,
/// and the word's normal (`PhotonWord::normal`) that direction; `facing` (integers) true for
/// directions within 59° of the code's, false beyond 61°. And the integer square root the
/// bytes are scaled by, against `f64`.
#[test]
fn photon_word_normals_are_the_octahedral_normals_within_a_degree() {
    let frame = WordFrame::new(&kdray_shared::IndexParams { bounds_max: [1.0; 3], ..Default::default() });
    let mut worst = 1.0f32;
    let mut rng = kdray_shared::rng::Rng::new(9, 2);
    let mut near = [0usize; 2];
    for oct in 0..1u32 << 16 {
        let n = kdray_shared::photon::decode_oct(oct, 8);
        let b = kdray_shared::photon::normal_bytes(oct);
        assert!(b.iter().all(|&v| v < 256), "code {oct:#x}: bytes {b:?}");
        let ph = Photon { position: [0.5; 3], packed: oct, ..Default::default() };
        let w = PhotonWord::of(&ph, &frame);
        assert!(b != [0; 3], "code {oct:#x}: a zero normal");
        let dot = Vec3::from(w.normal()).dot(Vec3::from(n));
        worst = worst.min(dot);
        assert!(dot >= (0.4f32).to_radians().cos() - 1e-6, "code {oct:#x}: {:?} against {n:?}", w.normal());
        let len = b.iter().map(|&v| (v as u8 as i8 as f64).powi(2)).sum::<f64>().sqrt();
        // Directions at angles from the code's near 60° (a random axis of rotation).
        for _ in 0..4 {
            let angle = (55.0 + 10.0 * rng.next_f32()).to_radians();
            let a = Vec3::from(n).any_orthonormal_vector();
            let b2 = Vec3::from(n).cross(a);
            let phi = 6.283_185_3 * rng.next_f32();
            let d = Vec3::from(n) * angle.cos() + (a * phi.cos() + b2 * phi.sin()) * angle.sin();
            let f = kdray_shared::photon::facing(w.word, kdray_shared::photon::normal_units(d.normalize().to_array()));
            let deg = angle.to_degrees();
            if deg < 59.0 {
                assert!(f, "code {oct:#x}: a direction {deg}° away does not face it");
                near[0] += (deg > 58.0) as usize;
            } else if deg > 61.0 {
                assert!(!f, "code {oct:#x}: a direction {deg}° away faces it");
                near[1] += (deg < 62.0) as usize;
            }
        }
        assert!((len - kdray_shared::photon::NORMAL_LENGTH as f64).abs() <= 0.9, "code {oct:#x}: bytes {b:?} of length {len}");
    }
    assert!(worst < 0.99999, "no code was rounded at all ({worst}): the test would not see a wrong rounding");
    assert!(near[0] > 1000 && near[1] > 1000, "too few directions near the bound: {near:?}");
    let mut rng = kdray_shared::rng::Rng::new(5, 1);
    for k in (0..1u32 << 20).chain((0..100_000).map(|_| rng.next_u32())).chain([u32::MAX, u32::MAX - 1, 1 << 30, (1 << 30) - 1, 65535 * 65535, 65536 * 65535]) {
        let want = (k as f64).sqrt().floor() as u32;
        assert_eq!(kdray_shared::math::isqrt(k), want, "isqrt({k})");
    }
}

#[test]
fn photon_indices_hold_every_photon_in_its_cell_and_gather_like_brute_force() {
    for spec in ["cornell", "cornell-glass"] {
        let s = scene::load(spec).unwrap();
        let tr = tree(&s);
        for rt in runtimes() {
            let t = Tracer::new(rt, &s, Some(&tr)).unwrap();
            for (kind, grid_window) in [(IndexKind::Grid, 3), (IndexKind::Grid, 2), (IndexKind::Grid, 5), (IndexKind::Grid, 7), (IndexKind::Grid, 9), (IndexKind::Kd, 3)] {
                let what = format!("{spec} on {}, {kind:?} index, window {grid_window}", rt.name());
                let o = PhotonOptions { grid_window, ..small_options(kind, 20_000) };
                let mut map = PhotonMap::new(&t, Accel::kd(Algorithm::ShortStack(3)), Some(&tr), &s, o).unwrap();
                let stored = map.trace_and_index(0).unwrap();
                let records = map.read_records().unwrap();
                assert_eq!(records.len(), stored as usize, "{what}");
                assert!(stored > 20_000, "{what}: only {stored} photons stored");
                if spec == "cornell-glass" {
                    assert!(records.iter().any(|p| p.is_caustic()), "{what}: no caustic photon");
                }
                check_index(&map, &tr, &records, &what, 0);
                // The next pass's index with the same buffers (other photons, a smaller
                // radius: other cells, some emptied): the sort left them ready for it.
                map.trace_and_index(1).unwrap();
                check_index(&map, &tr, &map.read_records().unwrap(), &format!("{what}, pass 1"), 1);
            }
        }
    }
}

/// The kd index gives every leaf of the tree at least one cell, so a tree with more leaves
/// than twice the photons (the index's budget before) needs more cells: the conference room
/// with 2 000 photons a pass. Before, the leaves' cells ran past the offsets (natively a panic
/// out of bounds in the gather; on a GPU reads past the buffer).
#[test]
fn the_kd_photon_index_has_a_cell_for_every_leaf() {
    let s = scene::load("conference").unwrap();
    let tr = tree(&s);
    let leaves = tr.nodes.iter().filter(|n| n.is_leaf()).count();
    for rt in runtimes() {
        let t = Tracer::new(rt, &s, Some(&tr)).unwrap();
        let what = format!("conference on {}, kd index, 2 000 photons", rt.name());
        let mut map = PhotonMap::new(&t, Accel::kd(Algorithm::ShortStack(3)), Some(&tr), &s, small_options(IndexKind::Kd, 2_000)).unwrap();
        let stored = map.trace_and_index(0).unwrap();
        assert!(leaves as u64 > 2 * map.capacity() as u64, "{what}: {leaves} leaves, {} photons' room: the test needs more leaves", map.capacity());
        let records = map.read_records().unwrap();
        assert_eq!(records.len(), stored as usize, "{what}");
        check_index(&map, &tr, &records, &what, 0);
    }
}

/// The kd index needs the kd-tree on the device: a tracer made without it is one clear error,
/// not a grid index under the kd index's parameters.
#[test]
fn the_kd_photon_index_without_the_tree_on_the_device_is_an_error() {
    let s = scene::load("cornell").unwrap();
    let tr = tree(&s);
    let t = Tracer::new(&NATIVE, &s, None).unwrap();
    let e = PhotonMap::new(&t, Accel::BRUTE, Some(&tr), &s, small_options(IndexKind::Kd, 1000)).err().expect("an error").to_string();
    assert!(e.contains("kd photon index needs the kd-tree on the device"), "{e}");
    let e = PhotonMap::new(&t, Accel::BRUTE, None, &s, small_options(IndexKind::Kd, 1000)).err().expect("an error").to_string();
    assert!(e.contains("kd photon index needs the scene's kd-tree"), "{e}");
    assert!(PhotonMap::new(&t, Accel::BRUTE, None, &s, small_options(IndexKind::Grid, 1000)).is_ok());
}

/// A 40 × 40 plane (albedo 0.5) at z = 0 under a point light of intensity 1 at height 1, seen
/// from above.
fn plane_scene() -> Scene {
    let mut s = Scene::new(
        "plane",
        CameraSpec { eye: Vec3::new(0.0, 0.0, 3.0), look_at: Vec3::ZERO, up: Vec3::Y, fov_y_deg: 40.0 },
    );
    let m = s.add_material("grey", Material { diffuse: [0.5; 3], ..Default::default() });
    s.add_quad([Vec3::new(-20.0, -20.0, 0.0), Vec3::new(20.0, -20.0, 0.0), Vec3::new(20.0, 20.0, 0.0), Vec3::new(-20.0, 20.0, 0.0)], m).unwrap();
    s.point_lights.push(PointLight { position: Vec3::new(0.0, 0.0, 1.0), intensity: Vec3::ONE, spot: None });
    s
}

/// Where the ray through pixel `i`'s centre meets the plane z = 0.
fn plane_point(cam: &kdray_shared::Camera, i: u32) -> Vec3 {
    let r = kdray_shared::camera::primary_ray(cam, i);
    let (o, d) = (Vec3::from(r.origin), Vec3::from(r.dir));
    o + d * (-o.z / d.z)
}

#[test]
fn photon_map_irradiance_under_a_point_light_is_i_cos_over_d_squared() {
    let s = plane_scene();
    let size = 32;
    let cam = s.camera.to_pod(size, size);
    for rt in runtimes() {
        let t = Tracer::new(rt, &s, None).unwrap();
        let (photons, passes) = if rt.is_native() { (1 << 20, 8) } else { (1 << 19, 4) };
        let o = PhotonOptions { photons, passes, radius: Some(0.05), photon_direct: true, final_gather: FinalGather::Off, ..Default::default() };
        let mut map = PhotonMap::new(&t, Accel::BRUTE, None, &s, o).unwrap();
        let (img, _) = pm::render(&mut map, &cam, &()).unwrap();
        let (mut sum, mut sq, mut n) = (0.0f64, 0.0f64, 0);
        for i in 0..size * size {
            let x = plane_point(&cam, i);
            let rho = (x.x * x.x + x.y * x.y).sqrt();
            if rho > 1.0 {
                continue;
            }
            let d2 = (x.x * x.x + x.y * x.y + 1.0) as f64;
            let e = 1.0 / d2 * (1.0 / d2.sqrt());
            let want = 0.5 / std::f64::consts::PI * e;
            let ratio = img.radiance[i as usize][0] as f64 / want;
            sum += ratio;
            sq += (ratio - 1.0).powi(2);
            n += 1;
        }
        let (mean, rms) = (sum / n as f64, (sq / n as f64).sqrt());
        eprintln!("{}: {n} pixels, irradiance / (I cos θ / d²) = {mean:.4} on average, {rms:.4} rms error", rt.name());
        assert!(n > 200);
        assert!((mean - 1.0).abs() < 0.01, "{}: mean ratio {mean}", rt.name());
        assert!(rms < 0.05, "{}: rms error {rms}", rt.name());
    }
}

/// A closed cube (side 2, centred at the origin) whose every face emits radiance 1 and reflects
/// with albedo 0.5: the radiance everywhere inside is 1 / (1 − 0.5) = 2.
fn furnace() -> Scene {
    let mut s = Scene::new(
        "furnace",
        CameraSpec { eye: Vec3::new(0.0, 0.0, 0.9), look_at: Vec3::new(0.0, 0.0, -1.0), up: Vec3::Y, fov_y_deg: 60.0 },
    );
    let m = s.add_material("wall", Material { diffuse: [0.5; 3], emission: [1.0; 3], ..Default::default() });
    let c = |x: f32, y: f32, z: f32| Vec3::new(x, y, z);
    for q in [
        [c(-1., -1., -1.), c(1., -1., -1.), c(1., 1., -1.), c(-1., 1., -1.)],
        [c(-1., -1., 1.), c(-1., 1., 1.), c(1., 1., 1.), c(1., -1., 1.)],
        [c(-1., -1., -1.), c(-1., 1., -1.), c(-1., 1., 1.), c(-1., -1., 1.)],
        [c(1., -1., -1.), c(1., -1., 1.), c(1., 1., 1.), c(1., 1., -1.)],
        [c(-1., -1., -1.), c(-1., -1., 1.), c(1., -1., 1.), c(1., -1., -1.)],
        [c(-1., 1., -1.), c(1., 1., -1.), c(1., 1., 1.), c(-1., 1., 1.)],
    ] {
        s.add_quad(q, m).unwrap();
    }
    s
}

/// The mean and rms deviation from 2 of the pixels whose centre ray meets the back wall away
/// from its edges.
fn furnace_error(img: &RenderOutput, cam: &kdray_shared::Camera) -> (f64, f64, usize) {
    let (mut sum, mut sq, mut n) = (0.0, 0.0, 0);
    for i in 0..cam.width * cam.height {
        let r = kdray_shared::camera::primary_ray(cam, i);
        let (o, d) = (Vec3::from(r.origin), Vec3::from(r.dir));
        let x = o + d * ((-1.0 - o.z) / d.z);
        if x.x.abs() > 0.8 || x.y.abs() > 0.8 {
            continue;
        }
        let v = img.radiance[i as usize][1] as f64;
        sum += v;
        sq += (v - 2.0).powi(2);
        n += 1;
    }
    (sum / n as f64, (sq / n as f64).sqrt(), n)
}

#[test]
fn furnace_radiance_is_emission_over_one_minus_albedo() {
    let s = furnace();
    let size = 24;
    let cam = s.camera.to_pod(size, size);
    for rt in runtimes() {
        let t = Tracer::new(rt, &s, None).unwrap();
        let (photons, passes) = if rt.is_native() { (1 << 19, 8) } else { (1 << 18, 4) };
        let o = PhotonOptions { photons, passes, radius: Some(0.05), final_gather: FinalGather::Off, ..Default::default() };
        let mut map = PhotonMap::new(&t, Accel::BRUTE, None, &s, o).unwrap();
        let (img, _) = pm::render(&mut map, &cam, &()).unwrap();
        let (mean, rms, n) = furnace_error(&img, &cam);
        eprintln!("{}: photon mapping, {n} pixels: mean {mean:.4} (want 2), rms deviation {rms:.4}", rt.name());
        assert!((mean / 2.0 - 1.0).abs() < 0.01, "{}: photon-mapped furnace mean {mean}", rt.name());
        // Final gathering: direct light by shadow rays, one bounce (near edges: up to two), at
        // the second point direct light by its shadow ray and the rest from the photons.
        for fg in [FinalGather::All, FinalGather::Edges] {
            let o = PhotonOptions { photons, passes, radius: Some(0.05), final_gather: fg, ..Default::default() };
            let mut map = PhotonMap::new(&t, Accel::BRUTE, None, &s, o).unwrap();
            let (img, _) = pm::render(&mut map, &cam, &()).unwrap();
            let (mean, rms, n) = furnace_error(&img, &cam);
            eprintln!("{}: final gathering {fg:?}, {n} pixels: mean {mean:.4} (want 2), rms deviation {rms:.4}", rt.name());
            assert!((mean / 2.0 - 1.0).abs() < 0.01, "{}: final-gathered ({fg:?}) furnace mean {mean}", rt.name());
        }
        let img = path::render(&t, Accel::BRUTE, &cam, &PathOptions::path(3, 64, if rt.is_native() { 512 } else { 256 }), &()).unwrap();
        let (mean, rms, n) = furnace_error(&img, &cam);
        eprintln!("{}: path tracing, {n} pixels: mean {mean:.4} (want 2), rms deviation {rms:.4}", rt.name());
        assert!((mean / 2.0 - 1.0).abs() < 0.01, "{}: path-traced furnace mean {mean}", rt.name());
    }
}

fn error(a: &RenderOutput, b: &RenderOutput) -> f64 {
    let f = |o: &RenderOutput| o.radiance.iter().map(|c| [c[0], c[1], c[2]]).collect::<Vec<_>>();
    kdray::image_out::image_error(&f(a), &f(b)).rel_rmse
}

#[test]
fn progressive_photon_mapping_converges_to_the_path_traced_reference() {
    let s = scene::load("cornell").unwrap();
    let tr = tree(&s);
    let size = 32;
    let cam = s.camera.to_pod(size, size);
    let t = Tracer::new(&NATIVE, &s, Some(&tr)).unwrap();
    let accel = Accel::kd(Algorithm::ShortStack(3));
    let reference = path::render(&t, accel, &cam, &PathOptions::path(11, 32, 4096), &()).unwrap();
    let mut errors = Vec::new();
    for passes in [1, 4, 16] {
        let o = PhotonOptions { photons: 1 << 16, passes, ..Default::default() };
        let mut map = PhotonMap::new(&t, accel, Some(&tr), &s, o).unwrap();
        let (img, _) = pm::render(&mut map, &cam, &()).unwrap();
        errors.push(error(&img, &reference));
    }
    eprintln!("relative RMSE against the path-traced reference after 1, 4, 16 passes: {errors:?}");
    // Early passes are dominated by the eye samples at the light's edges (one per pass).
    assert!(errors[1] < errors[0] && errors[2] < 0.8 * errors[1] && errors[2] < 0.6 * errors[0], "{errors:?}");
}

#[test]
fn native_and_gpu_trace_the_same_photons_and_render_the_same_image() {
    let Some(g) = common::gpu() else { return };
    for spec in ["cornell", "cornell-glass"] {
        let s = scene::load(spec).unwrap();
        let tr = tree(&s);
        let accel = Accel::kd(Algorithm::ShortStack(3));
        let records = |rt: &dyn Runtime| {
            let t = Tracer::new(rt, &s, Some(&tr)).unwrap();
            let mut map = PhotonMap::new(&t, accel, Some(&tr), &s, small_options(IndexKind::Grid, 50_000)).unwrap();
            map.trace_and_index(0).unwrap();
            map.read_records().unwrap()
        };
        let (a, b) = (records(&NATIVE), records(g));
        // Match by position: a grid of cells of 1e-3 of the scene size around each native photon.
        let scale = 560.0f32;
        let cell = |p: [f32; 3]| p.map(|x| (x / (scale * 1e-3)).floor() as i64);
        let mut grid: std::collections::HashMap<[i64; 3], Vec<[f32; 3]>> = Default::default();
        for p in &a {
            grid.entry(cell(p.position)).or_default().push(p.position);
        }
        let mut same = 0;
        for p in &b {
            let c = cell(p.position);
            let mut found = false;
            for dx in -1..=1 {
                for dy in -1..=1 {
                    for dz in -1..=1 {
                        if let Some(v) = grid.get(&[c[0] + dx, c[1] + dy, c[2] + dz]) {
                            found |= v.iter().any(|q| (Vec3::from(*q) - Vec3::from(p.position)).abs().max_element() <= 1e-4 * scale);
                        }
                    }
                }
            }
            same += found as usize;
        }
        let share = same as f64 / a.len().max(b.len()) as f64;
        eprintln!("{spec}: {} native and {} GPU photons, {:.4} % at the same position", a.len(), b.len(), share * 100.0);
        assert!(share >= 0.999, "{spec}: only {:.3} % of the photons agree", share * 100.0);
        // Images: the same photons and eye paths; sums may differ in order only.
        let size = 48;
        let cam = s.camera.to_pod(size, size);
        for final_gather in [FinalGather::Off, FinalGather::Edges, FinalGather::All] {
            let render = |rt: &dyn Runtime| {
                let t = Tracer::new(rt, &s, Some(&tr)).unwrap();
                let o = PhotonOptions { photons: 1 << 16, passes: 2, final_gather, ..Default::default() };
                let mut map = PhotonMap::new(&t, accel, Some(&tr), &s, o).unwrap();
                pm::render(&mut map, &cam, &()).unwrap().0
            };
            let e = error(&render(g), &render(&NATIVE));
            eprintln!("{spec}, final gather {final_gather:?}: GPU vs native image: relative RMSE {:.5} %", e * 100.0);
            assert!(e < 0.002, "{spec}, final gather {final_gather:?}: GPU and native images differ by {:.3} %", e * 100.0);
        }
    }
}

#[test]
fn whole_path_photon_kernel_traces_the_photons_of_the_pass_per_bounce_schedule() {
    let s = scene::load("cornell-glass").unwrap();
    let tr = tree(&s);
    // Brute force too: on lavapipe its whole-path items (every triangle at every bounce)
    // outran the driver's loop limit and lost a fifth of the photons, silently.
    // (runtime, traversal, photons, fewest stored photons)
    let bvh = kdray::bvh::build(&s.triangles);
    let cases = |rt| [(rt, Accel::kd(Algorithm::ShortStack(3)), 20_000, 20_000), (rt, Accel::BVH, 20_000, 20_000), (rt, Accel::BRUTE, 2_000, 1_800)];
    for (rt, accel, photons, least) in runtimes().into_iter().flat_map(cases) {
        let t = Tracer::new(rt, &s, Some(&tr)).unwrap().with_bvh(&bvh).unwrap();
        let mut sets = Vec::new();
        // Whole paths one photon per thread, the per-bounce passes, and whole paths by 999
        // threads each starting its next photon as soon as one is absorbed
        // (`photon::trace_photons`).
        for (fused, photon_threads) in [(true, 0), (false, 0), (true, 999)] {
            let o = PhotonOptions { fused, photon_threads, ..small_options(IndexKind::Grid, photons) };
            let mut map = PhotonMap::new(&t, accel, Some(&tr), &s, o).unwrap();
            map.trace_and_index(0).unwrap();
            let mut v: Vec<_> = map.read_records().unwrap().iter().map(|p| (p.position.map(f32::to_bits), p.power, p.packed)).collect();
            v.sort();
            sets.push(v);
        }
        assert!(sets[0].len() > least, "{} {}: {} photons stored", rt.name(), accel.name(), sets[0].len());
        // The same kernel, the photons shared out otherwise: the same photons, bit for bit.
        eprintln!("{} {}: {} / {} / {} photons", rt.name(), accel.name(), sets[0].len(), sets[1].len(), sets[2].len());
        if sets[0] != sets[2] {
            let common = sets[0].iter().filter(|p| sets[2].binary_search(p).is_ok()).count();
            panic!("{} {}: 999 threads store other photons than one per photon ({} and {}, {common} in common)", rt.name(), accel.name(), sets[0].len(), sets[2].len());
        }
        if rt.is_native() {
            assert!(sets[0] == sets[1], "{}: the whole-path kernel and the per-bounce passes store different photons", rt.name());
        } else {
            // Two SPIR-V kernels may round differently (contracted multiply-adds): the same
            // number of photons, the same total position to 1e-5.
            let (a, b) = (&sets[0], &sets[1]);
            assert!((a.len() as f64 - b.len() as f64).abs() <= 1e-3 * a.len() as f64, "{}: {} vs {} photons", rt.name(), a.len(), b.len());
            let sum = |v: &[([u32; 3], u32, u32)]| v.iter().map(|p| p.0.iter().map(|b| f32::from_bits(*b) as f64).sum::<f64>()).sum::<f64>();
            let (sa, sb) = (sum(a), sum(b));
            assert!((sa - sb).abs() <= 1e-5 * sa.abs(), "{}: {sa} vs {sb}", rt.name());
        }
    }
}

/// The final gather resumes eye paths from their gather points: in the whole-path kernel
/// (`render::trace_path` with `RENDER_CONTINUE`) and in the per-bounce schedule
/// (`continue_paths`, then a pass per bounce) alike — the same image, natively bit for bit.
/// The glass sphere has a caustic map (gathered at the first point) and specular bounces on
/// the way to the second.
#[test]
fn final_gather_renders_the_same_with_whole_paths_and_per_bounce_passes() {
    let s = scene::load("cornell-glass").unwrap();
    let tr = tree(&s);
    let cam = s.camera.to_pod(24, 24);
    for rt in runtimes() {
        let t = Tracer::new(rt, &s, Some(&tr)).unwrap();
        let render_with = |fused: bool, final_gather: FinalGather, list_points: bool, edge_levels: u32| {
            let o = PhotonOptions { photons: 1 << 14, passes: 2, fused, final_gather, list_points, edge_levels, ..Default::default() };
            let mut map = PhotonMap::new(&t, Accel::kd(Algorithm::ShortStack(3)), Some(&tr), &s, o).unwrap();
            pm::render(&mut map, &cam, &()).unwrap().0
        };
        let render = |fused: bool, final_gather: FinalGather| render_with(fused, final_gather, true, 2);
        let direct = render(true, FinalGather::Off);
        // Near edges, each level's gather over the list of the points the level before kept
        // (an indirect dispatch) or over every path: the same gathers, the same image bit for
        // bit; and a second level changes the image (its points near edges bounce again).
        for fused in [true, false] {
            let mut images = Vec::new();
            for levels in [1, 2, 3] {
                let (listed, every) = (render_with(fused, FinalGather::Edges, true, levels), render_with(fused, FinalGather::Edges, false, levels));
                assert!(listed.radiance == every.radiance, "{}: the listed points' gathers render another image (fused {fused}, {levels} levels)", rt.name());
                images.push(listed);
            }
            let (d12, d23) = (error(&images[0], &images[1]), error(&images[1], &images[2]));
            eprintln!("{}: final gather near edges, 1 vs 2 levels {:.4} %, 2 vs 3 {:.4} %", rt.name(), d12 * 100.0, d23 * 100.0);
            assert!(d12 > 1e-5 && d23 > 1e-6, "{}: more levels left the image as it was ({d12}, {d23})", rt.name());
        }
        for fg in [FinalGather::All, FinalGather::Edges] {
            let (whole, split) = (render(true, fg), render(false, fg));
            let e = error(&whole, &split);
            eprintln!("{}: final gather {fg:?}, whole paths vs per-bounce passes: relative RMSE {:.6} %", rt.name(), e * 100.0);
            if rt.is_native() {
                assert!(whole.radiance == split.radiance, "{}: the two schedules render different images ({fg:?})", rt.name());
            } else {
                assert!(e < 0.002, "{}: the two schedules differ by {:.3} % ({fg:?})", rt.name(), e * 100.0);
            }
            // And it is a different estimate of the same image: not the direct visualisation.
            let d = error(&whole, &direct);
            assert!(d > 1e-4 && d < 0.5, "{}: final gather {fg:?} vs direct visualisation {d}", rt.name());
            assert!(whole.hits == direct.hits, "{}: the final gather changed the primary hits", rt.name());
        }
    }
}

/// The wide BVH finds the kd-tree's hits, so it traces the same photons and eye paths: natively
/// bit for bit, on the GPU up to rounding (whole-path kernels on both).
#[test]
fn bvh_traces_the_photons_and_paths_of_the_kd_tree() {
    let s = scene::load("cornell-glass").unwrap();
    let tr = tree(&s);
    let bvh = kdray::bvh::build(&s.triangles);
    let cam = s.camera.to_pod(32, 32);
    for rt in runtimes() {
        let t = Tracer::new(rt, &s, Some(&tr)).unwrap().with_bvh(&bvh).unwrap();
        let photons = |accel: Accel| {
            let mut map = PhotonMap::new(&t, accel, Some(&tr), &s, small_options(IndexKind::Grid, 20_000)).unwrap();
            map.trace_and_index(0).unwrap();
            let mut v: Vec<_> = map.read_records().unwrap().iter().map(|p| (p.position.map(f32::to_bits), p.power, p.packed)).collect();
            v.sort();
            v
        };
        let (a, b) = (photons(Accel::kd(Algorithm::ShortStack(3))), photons(Accel::BVH));
        let image = |accel: Accel| path::render(&t, accel, &cam, &PathOptions::path(4, 8, 4), &()).unwrap();
        let e = error(&image(Accel::BVH), &image(Accel::kd(Algorithm::ShortStack(3))));
        eprintln!("{}: {} / {} photons (kd / BVH), path-traced images differ by {:.6} %", rt.name(), a.len(), b.len(), e * 100.0);
        if rt.is_native() {
            assert!(a == b, "native: the BVH and the kd-tree store different photons");
            assert_eq!(e, 0.0, "native: the BVH and the kd-tree render different images");
        } else {
            assert!((a.len() as f64 - b.len() as f64).abs() <= 1e-3 * a.len() as f64, "{}: {} vs {} photons", rt.name(), a.len(), b.len());
            assert!(e < 0.002, "{}: the BVH's and the kd-tree's images differ by {:.3} %", rt.name(), e * 100.0);
        }
    }
}

/// A runtime that works like the native one until its `fail_at`-th submission, then fails
/// every call, as a lost device would (#11 item 4: a failure mid-render keeps what is done).
struct LostAfter {
    fail_at: u32,
    submits: std::sync::atomic::AtomicU32,
}

impl LostAfter {
    fn lost(&self) -> kdray::Result<()> {
        if self.submits.load(std::sync::atomic::Ordering::SeqCst) >= self.fail_at {
            return Err(kdray::Error::DeviceLost("injected by the test".into()));
        }
        Ok(())
    }
}

impl Runtime for LostAfter {
    fn name(&self) -> String {
        NATIVE.name()
    }
    fn is_native(&self) -> bool {
        true
    }
    fn is_software(&self) -> bool {
        false
    }
    fn max_binding(&self) -> u64 {
        NATIVE.max_binding()
    }
    fn alloc_raw(&self, label: &str, bytes: u64) -> kdray::Result<kdray::runtime::RawBuffer> {
        self.lost()?;
        NATIVE.alloc_raw(label, bytes)
    }
    fn write_raw(&self, buf: &kdray::runtime::RawBuffer, data: &[u8]) -> kdray::Result<()> {
        self.lost()?;
        NATIVE.write_raw(buf, data)
    }
    fn begin(&self) -> kdray::runtime::Commands {
        NATIVE.begin()
    }
    fn clear(&self, c: &mut kdray::runtime::Commands, buf: &kdray::runtime::RawBuffer) -> kdray::Result<()> {
        self.lost()?;
        NATIVE.clear(c, buf)
    }
    fn dispatch(&self, c: &mut kdray::runtime::Commands, k: &dyn kdray::runtime::Kernel) -> kdray::Result<()> {
        self.lost()?;
        NATIVE.dispatch(c, k)
    }
    fn dispatch_indirect(&self, c: &mut kdray::runtime::Commands, k: &dyn kdray::runtime::Kernel, args: &kdray::runtime::Buffer<[u32; 3]>, index: usize) -> kdray::Result<()> {
        self.lost()?;
        NATIVE.dispatch_indirect(c, k, args, index)
    }
    fn read_back(&self, c: &mut kdray::runtime::Commands, buf: &kdray::runtime::RawBuffer, bytes: u64) -> kdray::Result<kdray::runtime::Pending> {
        self.lost()?;
        NATIVE.read_back(c, buf, bytes)
    }
    fn submit(&self, c: kdray::runtime::Commands) -> kdray::Result<()> {
        self.lost()?;
        self.submits.fetch_add(1, std::sync::atomic::Ordering::SeqCst);
        NATIVE.submit(c)
    }
    fn wait(&self, p: kdray::runtime::Pending) -> kdray::Result<Vec<u32>> {
        self.lost()?;
        NATIVE.wait(p)
    }
    fn finish(&self) -> kdray::Result<()> {
        self.lost()?;
        NATIVE.finish()
    }
}

/// A device lost in the middle of a render: the units of passes it delivered come back as the
/// image (the same image as a render of that many passes), with the error beside it; lost in
/// its first unit, the render is an error. Beside a second device, the lost one's units go to
/// that one and the image is the whole render's, bit for bit, the loss reported.
#[test]
fn a_render_whose_device_is_lost_returns_the_passes_before_it() {
    let (s, tr, cam, accel) = small_cornell();
    let options = |passes| PhotonOptions { photons: 1 << 12, passes, unit_passes: 2, ..Default::default() };
    let render = |rts: &[&dyn Runtime], passes| {
        let ts: Vec<Tracer> = rts.iter().map(|&rt| Tracer::new(rt, &s, Some(&tr)).unwrap()).collect();
        let mut maps: Vec<PhotonMap> = ts.iter().map(|t| PhotonMap::new(t, accel, Some(&tr), &s, options(passes)).unwrap()).collect();
        pm::render_on(&mut maps, &cam, &())
    };
    // Submissions of the set-up and of each pass, counted on a runtime that never fails.
    let count = |passes| {
        let rt = LostAfter { fail_at: u32::MAX, submits: 0.into() };
        render(&[&rt], passes).unwrap();
        rt.submits.into_inner()
    };
    // Lost after the seventh pass's submission (the fourth unit): passes are checked, and
    // films read, behind the submissions, so the loss is found at an earlier pass; the units
    // delivered before it are kept.
    let fail_at = count(6) + 1;
    let rt = LostAfter { fail_at, submits: 0.into() };
    let (img, stats) = render(&[&rt], 8).expect("the passes before the loss come back");
    let why = stats.interrupted.expect("the render says it was interrupted");
    assert!(why.contains("failed") && why.contains("GPU device lost: injected"), "{why}");
    assert!(stats.passes > 0 && stats.passes < 8 && stats.passes % 2 == 0, "{} passes: whole units", stats.passes);
    let (want, w) = render(&[&NATIVE], stats.passes).unwrap();
    assert!(img.radiance == want.radiance && img.hits == want.hits, "the image is that of the {} passes done", stats.passes);
    assert_eq!((stats.emitted, stats.stored), (w.emitted, w.stored));
    // Lost in the first unit: nothing to return.
    let rt = LostAfter { fail_at: count(1), submits: 0.into() };
    let e = render(&[&rt], 8).err().expect("an error");
    assert!(matches!(e.kind(), kdray::Error::DeviceLost(_)), "{e}");
    // Beside a device that does not fail: the whole render, as on that device alone. (Lost at
    // its second pass's submission: it shares the work, so it submits fewer passes.)
    let rt = LostAfter { fail_at: count(1) + 1, submits: 0.into() };
    // (Whether it gets a unit before the other has rendered them all depends on the threads'
    // timing; that a lost device's units go to the others, whatever the timing: the unit tests
    // of `integrator::share`.)
    let (img, stats) = render(&[&rt, &NATIVE], 8).unwrap();
    let (want, w) = render(&[&NATIVE], 8).unwrap();
    assert!(stats.interrupted.is_none() && stats.failed.len() <= 1 && stats.failed.iter().all(|f| f.contains("injected")), "{:?}", stats.failed);
    assert_eq!(stats.per_device.iter().sum::<u32>(), 4);
    assert!(img.radiance == want.radiance && img.hits == want.hits, "the lost device's units were rendered by the other");
    assert_eq!((stats.passes, stats.emitted, stats.stored), (8, w.emitted, w.stored));
}

/// A render shared out over several devices is the render on one, bit for bit (units summed in
/// unit order whoever renders them): photon mapping and path tracing on two and three native
/// runtimes, and on the GPU twice (two devices on one adapter; lavapipe in CI). The GPU beside
/// the native runtime differs from either alone only in the last bits of the arithmetic.
#[test]
fn a_render_on_several_devices_is_the_render_on_one() {
    let (s, tr, cam, accel) = small_cornell();
    let photons = |rts: &[&dyn Runtime]| {
        let ts: Vec<Tracer> = rts.iter().map(|&rt| Tracer::new(rt, &s, Some(&tr)).unwrap()).collect();
        let o = PhotonOptions { photons: 1 << 12, passes: 7, unit_passes: 2, ..Default::default() };
        let mut maps: Vec<PhotonMap> = ts.iter().map(|t| PhotonMap::new(t, accel, Some(&tr), &s, o.clone()).unwrap()).collect();
        let (img, stats) = pm::render_on(&mut maps, &cam, &()).unwrap();
        assert!(stats.failed.is_empty() && stats.passes == 7);
        assert_eq!(stats.last_radius, pm::pass_radius(maps[0].initial_radius(), o.alpha, 6), "the last pass's radius");
        img
    };
    let paths = |rts: &[&dyn Runtime]| {
        let ts: Vec<Tracer> = rts.iter().map(|&rt| Tracer::new(rt, &s, Some(&tr)).unwrap()).collect();
        let refs: Vec<&Tracer> = ts.iter().collect();
        let o = PathOptions { unit_samples: 3, ..PathOptions::path(5, 8, 20) };
        let (img, stats) = path::render_on(&refs, accel, &cam, &o, &()).unwrap();
        assert!(stats.failed.is_empty() && stats.samples == 20);
        img
    };
    let (two, three) = (kdray::runtime::Cpu::new(), kdray::runtime::Cpu::new());
    let one = (photons(&[&NATIVE]), paths(&[&NATIVE]));
    for rts in [&[&NATIVE as &dyn Runtime, &two][..], &[&NATIVE, &two, &three]] {
        assert!(photons(rts).radiance == one.0.radiance, "photons on {} native devices", rts.len());
        assert!(paths(rts).radiance == one.1.radiance, "paths on {} native devices", rts.len());
    }
    // The images are not trivially equal: another unit size sums in another order.
    let ts = Tracer::new(&NATIVE, &s, Some(&tr)).unwrap();
    let o = PathOptions { unit_samples: 4, ..PathOptions::path(5, 8, 20) };
    assert!(path::render_on(&[&ts], accel, &cam, &o, &()).unwrap().0.radiance != one.1.radiance, "units of 3 and 4 samples give the same bits");
    // A batch of rays in units of 100: the same hits on three devices, one lost at its first
    // unit (if it gets one before the others have traced them all), as on one; lost alone, an
    // error. (That a lost device's units go to the others, whatever the timing: the unit tests
    // of `integrator::share`.)
    let rays: Vec<kdray::Ray> = common::random_dirs(1000, 7).into_iter().map(|d| kdray::Ray::new([0.5, 0.5, 0.5], d, 0.0, f32::INFINITY)).collect();
    let t1 = Tracer::new(&NATIVE, &s, Some(&tr)).unwrap();
    let want = t1.closest_hits(accel, &rays).unwrap();
    let lost = LostAfter { fail_at: 1, submits: 0.into() };
    let ts: Vec<Tracer> = [&lost as &dyn Runtime, &two, &three].iter().map(|&rt| Tracer::new(rt, &s, Some(&tr)).unwrap()).collect();
    let refs: Vec<&Tracer> = ts.iter().collect();
    let e = kdray::integrator::share::closest_hits_on(&refs[..1], accel, &rays, 100).err().expect("no device left");
    assert!(e.to_string().contains("injected"), "{e}");
    let (hits, per, failed) = kdray::integrator::share::closest_hits_on(&refs, accel, &rays, 100).unwrap();
    assert!(hits == want, "the hits of rays shared out over devices");
    assert!(per[0] == 0 && per.iter().sum::<u32>() == 10 && failed.iter().all(|f| f.contains("injected")), "{failed:?} {per:?}");
    let Some(g) = common::gpu() else { return };
    let twin = kdray::Gpu::open(g.index).unwrap();
    let gpu = (photons(&[g]), paths(&[g]));
    assert!(photons(&[g, &twin]).radiance == gpu.0.radiance, "photons on the GPU twice");
    assert!(paths(&[g, &twin]).radiance == gpu.1.radiance, "paths on the GPU twice");
    let mixed = (photons(&[g, &NATIVE]), paths(&[g, &NATIVE]));
    for (what, m, a, b) in [("photons", &mixed.0, &gpu.0, &one.0), ("paths", &mixed.1, &gpu.1, &one.1)] {
        let (ea, eb) = (error(m, a), error(m, b));
        eprintln!("{what}: the GPU and the native runtime together against the GPU alone {:.4} %, against the native runtime alone {:.4} %", ea * 100.0, eb * 100.0);
        assert!(ea < 0.002 && eb < 0.002, "{what}: {ea} {eb}");
    }
}

/// The Cornell box, its kd-tree, a 24² camera and the short stack: the fault and cancellation
/// tests' set-up.
fn small_cornell() -> (Scene, KdTreeData, kdray_shared::Camera, Accel) {
    let s = scene::load("cornell").unwrap();
    let tr = tree(&s);
    let cam = s.camera.to_pod(24, 24);
    (s, tr, cam, Accel::kd(Algorithm::ShortStack(3)))
}

/// A caller stops a render through `Progress::cancelled` (asked after each photon pass and
/// path sample group): the render returns, without an error, the image of the work done —
/// exactly a render asked for that much — on both runtimes (path tracing natively).
#[test]
fn a_cancelled_render_returns_the_work_done() {
    struct StopAfter {
        after: u64,
        done: std::cell::Cell<u64>,
        asked: std::cell::Cell<u32>,
    }
    impl kdray::integrator::Progress for StopAfter {
        fn advance(&self, n: u64) {
            self.done.set(self.done.get() + n);
        }
        fn cancelled(&self) -> bool {
            self.asked.set(self.asked.get() + 1);
            self.done.get() >= self.after
        }
    }
    let (s, tr, cam, accel) = small_cornell();
    for rt in runtimes() {
        let t = Tracer::new(rt, &s, Some(&tr)).unwrap();
        let options = |passes| PhotonOptions { photons: 1 << 12, passes, ..Default::default() };
        let stop = StopAfter { after: 2, done: 0.into(), asked: 0.into() };
        let mut map = PhotonMap::new(&t, accel, Some(&tr), &s, options(64)).unwrap();
        let (img, stats) = pm::render(&mut map, &cam, &stop).unwrap();
        assert!(stop.asked.get() >= 2 && stats.interrupted.is_none(), "{}", rt.name());
        // The passes already in flight when it was asked finish too.
        assert!((2..64).contains(&stats.passes), "{}: {} passes", rt.name(), stats.passes);
        let mut map = PhotonMap::new(&t, accel, Some(&tr), &s, options(stats.passes)).unwrap();
        let (want, _) = pm::render(&mut map, &cam, &()).unwrap();
        assert!(img.radiance == want.radiance, "{}: the image of the {} passes done", rt.name(), stats.passes);
        // Path tracing: natively, 2 000 samples per pixel come in several sample groups (a GPU
        // takes them in one; the loop is the same).
        if !rt.is_native() {
            continue;
        }
        let stop = StopAfter { after: 1, done: 0.into(), asked: 0.into() };
        let (img, stats) = path::render_checkpointed(&t, accel, &cam, &PathOptions::path(3, 8, 2000), &stop).unwrap();
        assert!(stats.samples > 0 && stats.samples < 2000 && stats.interrupted.is_none(), "{}: {} samples", rt.name(), stats.samples);
        let want = path::render(&t, accel, &cam, &PathOptions::path(3, 8, stats.samples), &()).unwrap();
        assert!(img.radiance == want.radiance, "{}: the image of the {} samples done", rt.name(), stats.samples);
    }
}

/// A pass whose photons do not fit the records (their capacity set to the first pass's count,
/// so that later passes that store more overflow) is found one pass late and redone from the
/// last checkpoint (every pass) or from the start (no checkpoint): the image and statistics are
/// those of a render whose records were large enough, bit for bit, on both runtimes.
#[test]
fn passes_whose_photons_overflow_the_records_are_redone() {
    let (s, tr, cam, accel) = small_cornell();
    for rt in runtimes() {
        let t = Tracer::new(rt, &s, Some(&tr)).unwrap();
        for unit_passes in [1, 4] {
            let o = PhotonOptions { photons: 1 << 12, passes: 6, unit_passes, ..Default::default() };
            let mut fits = PhotonMap::new(&t, accel, Some(&tr), &s, o.clone()).unwrap();
            let (want, want_stats) = pm::render(&mut fits, &cam, &()).unwrap();
            let mut tight = PhotonMap::new(&t, accel, Some(&tr), &s, o).unwrap();
            let first = tight.trace_and_index(0).unwrap();
            // Smaller than the buffers: safe, every kernel bounds its stores by it.
            tight.capacity = first;
            let (img, stats) = pm::render(&mut tight, &cam, &()).unwrap();
            assert!(tight.capacity > first, "{}: no pass overflowed {first} slots, the test tests nothing", rt.name());
            assert!(img.radiance == want.radiance, "{}, units of {unit_passes} passes: the redone render differs", rt.name());
            assert_eq!((stats.passes, stats.emitted, stats.stored), (want_stats.passes, want_stats.emitted, want_stats.stored));
        }
    }
}

/// The path tracer keeps what is done too: lost after a few sample groups (checkpoints after
/// every one), it returns the image of the groups before — exactly a render of that many
/// samples per pixel — and says why; lost in the first, it is an error.
#[test]
fn a_path_traced_render_whose_device_is_lost_returns_the_samples_before_it() {
    let (s, tr, cam, accel) = small_cornell();
    // 2 000 samples per pixel of 576 pixels: several sample groups of a native batch.
    let o = |spp| PathOptions::path(3, 8, spp);
    let render = |rt: &dyn Runtime, spp| {
        let t = Tracer::new(rt, &s, Some(&tr)).unwrap();
        path::render_checkpointed(&t, accel, &cam, &o(spp), &())
    };
    let rt = LostAfter { fail_at: 5, submits: 0.into() };
    let (img, stats) = render(&rt, 2000).expect("the samples before the loss come back");
    let why = stats.interrupted.expect("the render says it was interrupted");
    assert!(why.contains("injected"), "{why}");
    assert!(stats.samples > 0 && stats.samples < 2000, "{} samples", stats.samples);
    let (want, full) = render(&NATIVE, stats.samples).unwrap();
    assert!(full.interrupted.is_none());
    assert!(img.radiance == want.radiance, "the image is that of the {} samples done", stats.samples);
    // Lost at the first checkpoint: nothing saved yet.
    let rt = LostAfter { fail_at: 1, submits: 0.into() };
    assert!(matches!(render(&rt, 2000).err().expect("an error").kind(), kdray::Error::DeviceLost(_)));
}

/// A real device lost mid-render (destroyed from the progress callback after the fifth pass,
/// units of one pass, so some are delivered whatever the passes in flight): the render
/// returns the image of the units delivered before, says why, and never panics or waits out a
/// timeout.
#[test]
fn a_destroyed_device_mid_render_returns_the_passes_before_it() {
    let Some(g) = common::gpu() else { return };
    // A device of its own: destroying it must not break the other tests' GPU.
    let gpu = kdray::Gpu::open(g.index).unwrap();
    let (s, tr, cam, accel) = small_cornell();
    struct DestroyAfter<'a>(&'a kdray::Gpu, std::cell::Cell<u64>);
    impl kdray::integrator::Progress for DestroyAfter<'_> {
        fn advance(&self, n: u64) {
            self.1.set(self.1.get() + n);
            if self.1.get() == 5 {
                self.0.device.destroy();
            }
        }
    }
    let t = Tracer::new(&gpu, &s, Some(&tr)).unwrap();
    let o = PhotonOptions { photons: 1 << 12, passes: 64, unit_passes: 1, ..Default::default() };
    let mut map = PhotonMap::new(&t, accel, Some(&tr), &s, o).unwrap();
    let start = std::time::Instant::now();
    let (img, stats) = pm::render(&mut map, &cam, &DestroyAfter(&gpu, 0.into())).expect("the passes before the loss come back");
    assert!(start.elapsed().as_secs() < 60, "waited {:?} for a lost device", start.elapsed());
    let why = stats.interrupted.expect("the render says it was interrupted");
    assert!(why.contains("failed") && (why.contains("lost") || why.contains("destroyed") || why.contains("cannot read")), "{why}");
    assert!(stats.passes >= 2 && stats.passes < 64, "{} passes", stats.passes);
    assert!(img.radiance.iter().any(|p| p[0] > 0.0));
}

/// The indirect dispatch over a list (`kernel::dispatch_args`) covers every item with at most
/// 65 535 workgroups along x and no row of workgroups to spare, past one row too.
#[test]
fn dispatch_args_cover_every_listed_item() {
    use kdray_shared::kernel::{dispatch_args, MAX_GROUPS, WORKGROUP};
    for items in [0u32, 1, 63, 64, 65, 1 << 20, MAX_GROUPS * WORKGROUP, MAX_GROUPS * WORKGROUP + 1, 1024 * 1024 * 4, u32::MAX / 2] {
        let [x, y, z] = dispatch_args(items);
        assert_eq!(z, 1);
        assert!(x <= MAX_GROUPS && y <= MAX_GROUPS, "{items}: {x} × {y}");
        let threads = x as u64 * y as u64 * WORKGROUP as u64;
        assert!(threads >= items as u64, "{items}: {x} × {y} workgroups leave items out");
        assert!(items == 0 || (x as u64 * (y as u64 - 1) * WORKGROUP as u64) < items as u64, "{items}: a spare row ({x} × {y})");
        assert!(items > 0 || x == 0, "no items, no workgroups");
    }
}

/// The final gather's levels are checked where they apply: 0 or more than 8 near edges is an
/// error, and any value passes when the final gather is off.
#[test]
fn final_gather_levels_are_checked_near_edges_only() {
    let s = scene::load("cornell").unwrap();
    let t = Tracer::new(&NATIVE, &s, None).unwrap();
    for (final_gather, edge_levels, ok) in [(FinalGather::Edges, 0, false), (FinalGather::Edges, 9, false), (FinalGather::Edges, 3, true), (FinalGather::Off, 0, true)] {
        let o = PhotonOptions { photons: 1024, passes: 1, final_gather, edge_levels, ..Default::default() };
        let r = PhotonMap::new(&t, Accel::BRUTE, None, &s, o);
        assert_eq!(r.is_ok(), ok, "{final_gather:?} with {edge_levels} levels");
    }
}

/// Open edges are the edges no other triangle shares, whatever their direction: a quad has
/// four (its diagonal is shared), a closed tetrahedron none, and −0 is 0.
#[test]
fn open_edges_are_where_surfaces_end() {
    use kdray_shared::Triangle;
    let tri = |a: [f32; 3], b: [f32; 3], c: [f32; 3]| Triangle { v0: a, v1: b, v2: c, ..Default::default() };
    let quad = [tri([0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 1.0, 0.0]), tri([-0.0, 0.0, 0.0], [1.0, 1.0, 0.0], [0.0, 1.0, 0.0])];
    // Edges 0 and 1 of the first (v0-v1, v1-v2), 1 and 2 of the second; the diagonal is shared.
    assert_eq!(scene::open_edges(&quad), vec![0b011, 0b110]);
    let p = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
    let tet = [tri(p[0], p[2], p[1]), tri(p[0], p[1], p[3]), tri(p[1], p[2], p[3]), tri(p[0], p[3], p[2])];
    assert_eq!(scene::open_edges(&tet), vec![0; 4]);
    assert_eq!(scene::open_edges(&tet[..3]), vec![0b001, 0b100, 0b010], "the missing face's edges are open");
}

/// Squared distance from `x` to triangle `t` in f64, computed otherwise than the kernels do:
/// the plane's foot if it lies inside, else the nearest edge.
fn dist2_f64(x: glam::DVec3, t: &kdray_shared::Triangle) -> f64 {
    let v = [Vec3::from(t.v0).as_dvec3(), Vec3::from(t.v1).as_dvec3(), Vec3::from(t.v2).as_dvec3()];
    let seg = |a: glam::DVec3, b: glam::DVec3| {
        let ab = b - a;
        let s = ((x - a).dot(ab) / ab.length_squared()).clamp(0.0, 1.0);
        (x - (a + ab * s)).length_squared()
    };
    let n = (v[1] - v[0]).cross(v[2] - v[0]);
    let foot = x - n * ((x - v[0]).dot(n) / n.length_squared());
    let inside = (0..3).all(|k| (v[(k + 1) % 3] - v[k]).cross(foot - v[k]).dot(n) >= 0.0);
    if inside {
        (x - foot).length_squared()
    } else {
        (0..3).map(|k| seg(v[k], v[(k + 1) % 3])).fold(f64::INFINITY, f64::min)
    }
}

/// Whether the disc at `x` (normal `n`, radius `r`) reaches past its surface, from every
/// triangle in f64 (`photon::EdgeProbe`'s rule).
fn near_edge_f64(tris: &[kdray_shared::Triangle], open: &[u32], x: glam::DVec3, n: glam::DVec3, r: f64) -> bool {
    tris.iter().zip(open).any(|(t, &o)| {
        if dist2_f64(x, t) > r * r {
            return false;
        }
        let v = [Vec3::from(t.v0).as_dvec3(), Vec3::from(t.v1).as_dvec3(), Vec3::from(t.v2).as_dvec3()];
        let nt = (v[1] - v[0]).cross(v[2] - v[0]).normalize();
        nt.dot(n).abs() <= 0.5
            || (0..3).any(|k| {
                let (a, b) = (v[k], v[(k + 1) % 3]);
                let ab = b - a;
                let s = ((x - a).dot(ab) / ab.length_squared()).clamp(0.0, 1.0);
                o & (1 << k) != 0 && (x - (a + ab * s)).length_squared() <= r * r
            })
    })
}

/// The edge marks (`photon::mark_edges`) by brute force, the kd-tree and the BVH, natively and
/// on the GPU, against the rule evaluated in f64 over every triangle, at points on the Cornell
/// box with a glass sphere (creases, corners, the room's open front, the sphere's fine
/// triangles): the same verdicts except within 10⁻⁴ of the radius; paths that are not gather
/// points are left alone and stale marks cleared.
#[test]
fn edge_marks_follow_the_geometry_with_every_structure_and_runtime() {
    use kdray::kernels::MarkEdges;
    use kdray_shared::{IndexParams, PathState, Ray, PATH_GATHER, PATH_NEAR_EDGE};
    let s = scene::load("cornell-glass").unwrap();
    let tr = tree(&s);
    let bvh = kdray::bvh::try_build(&s.triangles).unwrap();
    let open = scene::open_edges(&s.triangles);
    assert!(open.iter().any(|&o| o != 0), "the room's front is open");
    // Points on triangles chosen by area, a third of them within 1 % of an edge of their
    // triangle.
    let area = |t: &kdray_shared::Triangle| (Vec3::from(t.v1) - Vec3::from(t.v0)).cross(Vec3::from(t.v2) - Vec3::from(t.v0)).length() as f64;
    let cdf: Vec<f64> = s.triangles.iter().scan(0.0, |a, t| {
        *a += area(t);
        Some(*a)
    }).collect();
    let mut rng = kdray_shared::rng::Rng::new(7, 0);
    let (mut rays, mut paths, mut points) = (vec![], vec![], vec![]);
    for i in 0..3000u32 {
        let pick = rng.next_f32() as f64 * cdf[cdf.len() - 1];
        let t = &s.triangles[cdf.partition_point(|&a| a < pick).min(cdf.len() - 1)];
        let (mut u, mut v) = (rng.next_f32(), rng.next_f32());
        if u + v > 1.0 {
            (u, v) = (1.0 - u, 1.0 - v);
        }
        if i % 3 == 0 {
            v *= 0.01;
        }
        let (a, b, c) = (Vec3::from(t.v0), Vec3::from(t.v1), Vec3::from(t.v2));
        let x = a + (b - a) * u + (c - a) * v;
        let n = (b - a).cross(c - a).normalize() * if i % 2 == 0 { 1.0 } else { -1.0 };
        rays.push(kdray_shared::shade::gather_point(x.to_array(), n.to_array()));
        // Every tenth path is not a gather point (a stale mark must stay); every fourth gather
        // point starts with a stale mark (which must go where it is not near an edge).
        let flags = if i % 10 == 9 { PATH_NEAR_EDGE } else if i % 4 == 0 { PATH_GATHER | PATH_NEAR_EDGE } else { PATH_GATHER };
        paths.push(PathState { flags, ..Default::default() });
        points.push((x.as_dvec3(), n.as_dvec3()));
    }
    let (lo, hi) = s.bounds();
    // The f64 verdicts, once for every structure and runtime: (within r(1 - 1e-4), within
    // r(1 + 1e-4)) per radius and point.
    const RADII: [f32; 3] = [1.5, 6.0, 25.0];
    let verdicts: Vec<Vec<(bool, bool)>> = RADII
        .iter()
        .map(|&r| {
            let r = r as f64;
            points.iter().map(|&(x, n)| (near_edge_f64(&s.triangles, &open, x, n, r * (1.0 - 1e-4)), near_edge_f64(&s.triangles, &open, x, n, r * (1.0 + 1e-4)))).collect()
        })
        .collect();
    for rt in runtimes() {
        let t = Tracer::new(rt, &s, Some(&tr)).unwrap().with_bvh(&bvh).unwrap();
        let (open_buf, ray_buf) = (rt.upload("open edges", &open).unwrap(), rt.upload::<Ray>("gather points", &rays).unwrap());
        use kdray::kernels::TraceMethod;
        for (accel, method) in [(Accel::BRUTE, TraceMethod::Brute), (Accel::kd(Algorithm::ShortStack(3)), TraceMethod::Single(Algorithm::ShortStack(3))), (Accel::BVH, TraceMethod::Bvh)] {
            let (mut near, mut far, mut wrong) = (0, 0, vec![]);
            for (&r, verdicts) in RADII.iter().zip(&verdicts) {
                let path_buf = rt.upload("paths", &paths).unwrap();
                let params = IndexParams { count: paths.len() as u32, radius: [r, r], bounds_min: lo.to_array(), bounds_max: hi.to_array(), ..Default::default() };
                let k = MarkEdges::new(method, params, t.scene_binds(accel), &open_buf, &ray_buf, &path_buf);
                rt.run(&[&k]).unwrap();
                let out = rt.read(&path_buf, paths.len()).unwrap();
                for (i, ((before, after), (&(x, n), &(inner, outer)))) in paths.iter().zip(&out).zip(points.iter().zip(verdicts)).enumerate() {
                    if before.flags & PATH_GATHER == 0 {
                        assert_eq!(after.flags, before.flags, "{} {}: path {i} is no gather point and was changed", rt.name(), accel.name());
                        continue;
                    }
                    if inner != outer {
                        continue;
                    }
                    let marked = after.flags & PATH_NEAR_EDGE != 0;
                    if marked != inner {
                        wrong.push(format!("radius {r} at {x} (normal {n}): marked {marked}"));
                    }
                    assert_eq!(after.flags & !PATH_NEAR_EDGE, before.flags & !PATH_NEAR_EDGE);
                    if inner { near += 1 } else { far += 1 }
                }
            }
            assert!(wrong.is_empty(), "{} {}: {} of {} discs marked against the geometry, e.g. {:?}", rt.name(), accel.name(), wrong.len(), near + far, &wrong[..wrong.len().min(4)]);
            assert!(near > 1000 && far > 1000, "{} {}: {near} points near edges, {far} not: the test decides too little", rt.name(), accel.name());
        }
    }
}

/// The default unit of work: at least four passes, at most 16 units a render; a unit given is
/// kept.
#[test]
fn the_default_unit_cuts_a_render_into_at_most_sixteen_units() {
    let unit = |passes, unit_passes| PhotonOptions { passes, unit_passes, ..Default::default() }.unit();
    assert_eq!((unit(1, 0), unit(16, 0), unit(64, 0), unit(65, 0), unit(256, 0), unit(1000, 0)), (4, 4, 4, 5, 16, 63));
    assert_eq!(unit(256, 3), 3);
    for passes in 1u32..2000 {
        assert!(passes.div_ceil(unit(passes, 0)) <= 16);
    }
}
