//! A render (or a batch of rays: `closest_hits_on`) shared out over several runtimes
//! (several GPUs, or GPUs and the native runtime), and over the ranks of an MPI job
//! (`Part`): the render is cut into units — a photon render's chunks of passes, a
//! path-traced render's groups of samples — each a function of its index and the render's
//! options only. Every device takes the next unit when it is free (a faster device takes
//! more), renders it into a film of its own from zero and hands the film over. The films are
//! summed exactly (`FilmSum`: fixed point, so the sum is the same in any order), so the image
//! is the same, bit for bit, on one device or on several of the same kind, in one process or
//! in many (devices of different kinds differ in the last bits of their arithmetic, not in
//! the work they do).
//!
//! A device that fails (lost, out of memory, a killed process behind a runtime) gives its
//! unfinished units back, and the others render them; the render says which device failed and
//! why. Only when no device is left does it end with fewer units than asked — the image of
//! the units finished, `interrupted` saying why.
use crate::accel::Accel;
use crate::error::{bail, err, Error, Result};
use crate::tracer::Tracer;
use kdray_shared::{Hit, Ray};
use std::sync::mpsc::{channel, Sender};
use std::sync::{Condvar, Mutex};

/// The units of a render this process renders: unit `rank`, then every `ranks`-th (the
/// ranks of an MPI job divide the units so; `Part::WHOLE` is every unit).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Part {
    /// This process's rank, below `ranks`.
    pub rank: u32,
    /// The processes sharing the render.
    pub ranks: u32,
}

impl Part {
    /// Every unit: one process.
    pub const WHOLE: Part = Part { rank: 0, ranks: 1 };

    /// How many of `total` units are this part's.
    pub fn count(self, total: u32) -> u32 {
        total.saturating_sub(self.rank).div_ceil(self.ranks.max(1))
    }

    /// Whether unit `u` is this part's.
    pub fn holds(self, u: u32) -> bool {
        u % self.ranks.max(1) == self.rank
    }
}

/// The units of a render and who holds them: handed out lowest first, given-back ones before
/// new ones.
pub struct Units {
    state: Mutex<UnitState>,
    changed: Condvar,
}

struct UnitState {
    total: u32,
    /// This process's units: `part.rank`, then every `part.ranks`-th.
    part: Part,
    /// The next unit never handed out.
    next: u32,
    /// Units given back by a device that failed.
    again: Vec<u32>,
    /// Units delivered.
    finished: u32,
    /// No new units: the render stops (time limit, cancelled).
    stop: bool,
}

impl Units {
    fn new(total: u32, part: Part) -> Self {
        let next = part.rank.min(total);
        Units { state: Mutex::new(UnitState { total, part, next, again: Vec::new(), finished: 0, stop: false }), changed: Condvar::new() }
    }

    fn lock(&self) -> std::sync::MutexGuard<'_, UnitState> {
        // A worker that panicked holding the lock left consistent counts (each change is one
        // statement): go on with them.
        self.state.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// The next unit to render, or `None` once every unit is finished or the render stops.
    /// While the rest are all in other devices' hands it waits (one of them may fail and give
    /// its units back) — unless the caller holds units itself (`holding`): it is then told
    /// `None` at once, and asks again once it has delivered them.
    fn take(&self, holding: bool) -> Option<u32> {
        let mut s = self.lock();
        loop {
            if s.stop {
                return None;
            }
            if let Some(k) = (0..s.again.len()).min_by_key(|&k| s.again[k]) {
                return Some(s.again.swap_remove(k));
            }
            if s.next < s.total {
                let u = s.next;
                s.next = u.saturating_add(s.part.ranks).min(s.total);
                return Some(u);
            }
            if s.finished >= s.part.count(s.total) || holding {
                return None;
            }
            s = self.changed.wait(s).unwrap_or_else(|e| e.into_inner());
        }
    }

    fn finish(&self) {
        self.lock().finished += 1;
        self.changed.notify_all();
    }

    fn give_back(&self, units: &[u32]) {
        self.lock().again.extend_from_slice(units);
        self.changed.notify_all();
    }

    fn stop(&self) {
        self.lock().stop = true;
        self.changed.notify_all();
    }

    /// Whether the render stops: a device ends the unit it is on early (after the work in
    /// flight), delivering what it did.
    pub fn stopping(&self) -> bool {
        self.lock().stop
    }
}

/// A finished unit (or one ended early by a stop): its film, per pixel in ray order (the
/// sum of its samples' radiance, their number in the fourth component), the primary hits
/// (unit 0 only: the image's hits are the same whoever renders), and what the integrator
/// counts.
pub struct Unit<S> {
    /// The unit's index.
    pub index: u32,
    /// Per pixel, in ray order.
    pub film: Vec<[f32; 4]>,
    /// Unit 0's primary hits, per pixel in ray order.
    pub hits: Option<Vec<Hit>>,
    /// The integrator's counts of the unit.
    pub stats: S,
}

enum Report<S> {
    Advance(u64),
    Done(usize, Unit<S>),
    Failed(usize, Error),
}

/// One device's hold on the units: what it takes, reports and delivers. Units it holds when
/// it goes (an error, a panic) are given back to the others.
pub struct Hand<'a, S> {
    units: &'a Units,
    held: Vec<u32>,
    tx: Sender<Report<S>>,
    device: usize,
}

impl<S> Hand<'_, S> {
    /// The next unit for this device (`Units::take`; `None` at once while it holds units and
    /// all the others are handed out).
    pub fn take(&mut self) -> Option<u32> {
        let u = self.units.take(!self.held.is_empty())?;
        self.held.push(u);
        Some(u)
    }

    /// `n` more units of progress (passes, samples per pixel) done.
    pub fn advance(&self, n: u64) {
        let _ = self.tx.send(Report::Advance(n));
    }

    /// Whether the render stops (`Units::stopping`).
    pub fn stopping(&self) -> bool {
        self.units.stopping()
    }

    /// Hands a unit's film over.
    pub fn deliver(&mut self, unit: Unit<S>) {
        self.held.retain(|&u| u != unit.index);
        let _ = self.tx.send(Report::Done(self.device, unit));
        self.units.finish();
    }
}

impl<S> Drop for Hand<'_, S> {
    fn drop(&mut self) {
        self.units.give_back(&self.held);
    }
}

/// What a shared render came to.
pub struct Shared<S> {
    /// Per pixel in ray order: the films of the units delivered, summed exactly.
    pub sum: FilmSum,
    /// Unit 0's primary hits, if it was delivered.
    pub hits: Option<Vec<Hit>>,
    /// Each delivered unit's counts, in unit order.
    pub stats: Vec<(u32, S)>,
    /// Units not delivered because no device was left to render them (not those the render
    /// stopped before).
    pub missing: Vec<u32>,
    /// Each device that failed: its index and why. Its units went to the others.
    pub failed: Vec<(usize, Error)>,
    /// Units each device delivered.
    pub per_device: Vec<u32>,
}

impl<S> Shared<S> {
    /// What failed, for a render's stats: each failed device as `name: error` (`names` in
    /// the devices' order), and, when units were left with no device to render them, why the
    /// render stopped early (`held` says what the image holds). With no unit delivered and a
    /// device failed, the first failure is the render's error (named when there were several
    /// devices).
    pub fn failures(&mut self, names: &[String], held: impl FnOnce() -> String) -> Result<(Vec<String>, Option<String>)> {
        if self.stats.is_empty() && !self.failed.is_empty() {
            let (i, e) = self.failed.remove(0);
            return Err(if names.len() > 1 { e.context(&names[i]) } else { e });
        }
        let failed: Vec<String> = self.failed.iter().map(|(i, e)| format!("{}: {e}", names[*i])).collect();
        let interrupted = (!self.missing.is_empty() && !failed.is_empty()).then(|| format!("{} (no device left: {})", failed.join("; "), held()));
        Ok((failed, interrupted))
    }
}

/// The sum of films, per pixel and component, exactly: each value as a fixed-point number
/// of 2^-64 in an `i128`, so that the sum is the same in any order — of units, devices or
/// ranks (`add_sums` merges two). A value of magnitude at most 2^40 is represented to 2^-65
/// (exactly where it is at least 2^-41); larger ones, and values that are not finite (NaN
/// is taken as 0), are clamped to ±2^40 and counted in `clamped`. With at most `MAX_UNITS`
/// units no sum overflows.
#[derive(Clone, Debug, PartialEq)]
pub struct FilmSum {
    /// Per pixel: the four components' sums, in units of 2^-64.
    pub sum: Vec<[i128; 4]>,
    /// Values clamped (out of range or not finite).
    pub clamped: u64,
}

/// The most units a render may have (`FilmSum`'s sums stay below 2^126).
pub const MAX_UNITS: u32 = 1 << 22;

const FIXED_ONE: f64 = 18_446_744_073_709_551_616.0; // 2^64
const FIXED_MAX: f32 = 1_099_511_627_776.0; // 2^40

/// `v` (at most 2^40 in magnitude) in units of 2^-64, rounded to nearest (ties away from
/// zero): its 24-bit significand shifted, in integer arithmetic.
#[inline(always)]
fn fixed(v: f32) -> i128 {
    let b = v.to_bits();
    let e = ((b >> 23) & 0xff) as i32;
    if e == 0 {
        // Zero or subnormal: below 2^-126, far below 2^-64.
        return 0;
    }
    // v = m · 2^(e − 150), so v · 2^64 = m · 2^(e − 86).
    let m = ((b & 0x7f_ffff) | 0x80_0000) as i128;
    let shift = e - 86;
    let magnitude = if shift >= 0 {
        m << shift
    } else if shift >= -24 {
        (m + (1 << (-shift - 1))) >> -shift
    } else {
        0
    };
    if b >> 31 == 1 { -magnitude } else { magnitude }
}

impl FilmSum {
    /// A zero sum of `pixels` pixels.
    pub fn new(pixels: usize) -> Self {
        FilmSum { sum: vec![[0; 4]; pixels], clamped: 0 }
    }

    /// Adds a film (per pixel, four components).
    pub fn add(&mut self, film: &[[f32; 4]]) {
        use rayon::prelude::*;
        // Over all cores: a film arrives per unit from every device, and one thread would
        // bound how many devices the host keeps up with (512²: 4 ms a film on one core).
        let clamped: u64 = self
            .sum
            .par_chunks_mut(1 << 14)
            .zip(film.par_chunks(1 << 14))
            .map(|(sums, films)| {
                let mut clamped = 0;
                for (s, f) in sums.iter_mut().zip(films) {
                    for c in 0..4 {
                        let v = f[c];
                        let v = if v.is_nan() { 0.0 } else { v.clamp(-FIXED_MAX, FIXED_MAX) };
                        if v != f[c] {
                            clamped += 1;
                        }
                        s[c] += fixed(v);
                    }
                }
                clamped
            })
            .sum();
        self.clamped += clamped;
    }

    /// Adds another sum (of the same pixels).
    pub fn add_sums(&mut self, other: &FilmSum) {
        for (s, o) in self.sum.iter_mut().zip(&other.sum) {
            for c in 0..4 {
                s[c] += o[c];
            }
        }
        self.clamped += other.clamped;
    }

    /// The sums as `f32` (rounded to nearest via `f64`).
    pub fn film(&self) -> Vec<[f32; 4]> {
        let f = |v: i128| ((v as f64) / FIXED_ONE) as f32;
        self.sum.iter().map(|s| [f(s[0]), f(s[1]), f(s[2]), f(s[3])]).collect()
    }
}

/// Renders `part`'s share of `units` units on the `workers` (one per device, each on a thread
/// of its own): `work` takes units through its `Hand` until there are none, rendering each
/// into a film of `pixels` pixels. `advance` is called on the caller's thread for every bit of progress
/// reported; when it returns true the render stops (each device delivers the unit it is on as
/// far as it got). A worker that returns an error gives its units back to the others.
pub fn share<W: Send, S: Send>(
    workers: &mut [W],
    units: u32,
    part: Part,
    pixels: usize,
    work: impl Fn(&mut W, &mut Hand<'_, S>) -> Result<()> + Sync,
    mut advance: impl FnMut(u64) -> bool,
) -> Result<Shared<S>> {
    if units > MAX_UNITS || part.ranks == 0 || part.rank >= part.ranks {
        bail!(InvalidInput: "a render of {units} units (at most {MAX_UNITS}) as part {} of {}", part.rank, part.ranks);
    }
    let pool = Units::new(units, part);
    let (tx, rx) = channel();
    let mut out = Shared { sum: FilmSum::new(pixels), hits: None, stats: Vec::new(), missing: Vec::new(), failed: Vec::new(), per_device: vec![0; workers.len()] };
    let mut delivered = vec![false; units as usize];
    std::thread::scope(|scope| {
        for (i, w) in workers.iter_mut().enumerate() {
            let (work, pool, tx) = (&work, &pool, tx.clone());
            scope.spawn(move || {
                let failed = tx.clone();
                let mut hand = Hand { units: pool, held: Vec::new(), tx, device: i };
                if let Err(e) = work(w, &mut hand) {
                    let _ = failed.send(Report::Failed(i, e));
                }
            });
        }
        drop(tx);
        for r in rx {
            match r {
                Report::Advance(n) => {
                    if advance(n) {
                        pool.stop();
                    }
                }
                Report::Done(device, u) => {
                    delivered[u.index as usize] = true;
                    out.per_device[device] += 1;
                    if u.hits.is_some() {
                        out.hits = u.hits;
                    }
                    out.sum.add(&u.film);
                    out.stats.push((u.index, u.stats));
                }
                Report::Failed(i, e) => out.failed.push((i, e)),
            }
        }
    });
    out.stats.sort_by_key(|s| s.0);
    // Units never handed out because the render stopped are not missing.
    let s = pool.lock();
    let end = if s.stop { s.next } else { units };
    drop(s);
    out.missing = (0..end).filter(|&u| part.holds(u) && !delivered[u as usize]).collect();
    Ok(out)
}

/// Each ray's closest hit in its interval (`Tracer::closest_hits`), the rays shared out over
/// the tracers' devices (one tracer per device, all over the same scene) in units of `unit`
/// rays: the same answers as on one device of the kind (a hit depends on its ray alone). A
/// device that fails hands its units to the others; with none left it is an error. Also
/// returns the units each device traced and the devices that failed, with why.
pub fn closest_hits_on(ts: &[&Tracer], accel: Accel, rays: &[Ray], unit: usize) -> Result<(Vec<Hit>, Vec<u32>, Vec<String>)> {
    if ts.is_empty() || unit == 0 {
        bail!(InvalidInput: "tracing on several devices needs at least one device and one ray a unit");
    }
    if ts.iter().any(|t| !t.holds_same(ts[0])) {
        bail!(InvalidInput: "the devices of a query need tracers over the same scene");
    }
    let units = u32::try_from(rays.len().div_ceil(unit)).map_err(|_| err!(TooLarge: "{} rays in units of {unit} are too many units", rays.len()))?;
    let mut devices: Vec<&Tracer> = ts.to_vec();
    let shared = share(
        &mut devices,
        units,
        Part::WHOLE,
        0,
        |t, hand| {
            while let Some(u) = hand.take() {
                let first = u as usize * unit;
                let hits = t.closest_hits(accel, &rays[first..(first + unit).min(rays.len())]).map_err(|e| e.context(format!("rays {first}.. failed")))?;
                hand.deliver(Unit { index: u, film: Vec::new(), hits: None, stats: hits });
            }
            Ok(())
        },
        |_| false,
    )?;
    let failed: Vec<String> = shared.failed.iter().map(|(i, e)| format!("{}: {e}", ts[*i].rt.name())).collect();
    if shared.stats.len() != units as usize {
        return Err(match shared.failed.into_iter().next() {
            Some((i, e)) => e.context(format!("no device left ({})", ts[i].rt.name())),
            None => err!(InvalidInput: "the query stopped early"),
        });
    }
    Ok((shared.stats.into_iter().flat_map(|s| s.1).collect(), shared.per_device, failed))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Units 0 and 1 cancel; in floating point the others' small values would be lost when
    /// added to either first (so a sum in another order would differ): summed exactly, any
    /// order gives 38 · 2^-30.
    fn film(u: u32) -> Vec<[f32; 4]> {
        let big = 1_099_511_627_776.0; // 2^40
        vec![[[big, -big][..].get(u as usize).copied().unwrap_or(2f32.powi(-30)), u as f32, 1.0, 1.0]; 5]
    }

    fn run(workers: &mut [u32], part: Part) -> Shared<u32> {
        // Every worker holds a unit before any goes on, so worker 1 surely fails holding one.
        let all_hold = std::sync::Barrier::new(workers.len());
        share(
            workers,
            40,
            part,
            5,
            |w: &mut u32, hand: &mut Hand<'_, u32>| {
                let mut done = 0;
                while let Some(u) = hand.take() {
                    if done == 0 {
                        all_hold.wait();
                    }
                    if *w == 1 {
                        return Err(Error::DeviceLost(format!("injected in unit {u}")));
                    }
                    // Each unit takes a while (the third worker's longer).
                    std::thread::sleep(std::time::Duration::from_millis(if *w == 2 { 3 } else { 1 }));
                    hand.advance(1);
                    hand.deliver(Unit { index: u, film: film(u), hits: (u == 0).then(|| vec![Hit::NONE; 5]), stats: *w });
                    done += 1;
                }
                Ok(())
            },
            |_| false,
        )
        .unwrap()
    }

    /// Three workers, one failing holding its first unit and one slow: every unit is delivered
    /// once, the failed worker's unit by another, and the sum is exact, the same as one
    /// worker's; two parts (ranks) of the units, summed, give it too.
    #[test]
    fn units_of_a_failed_worker_go_to_the_others_and_the_sum_is_exact_in_any_order() {
        let one = run(&mut [0], Part::WHOLE);
        let three = run(&mut [0, 1, 2], Part::WHOLE);
        assert_eq!(three.failed.len(), 1);
        assert!(three.missing.is_empty());
        assert_eq!(three.stats.iter().map(|s| s.0).collect::<Vec<_>>(), (0..40).collect::<Vec<_>>());
        assert!(three.stats.iter().all(|s| s.1 != 1) && three.per_device[1] == 0, "the failing worker delivered nothing: its unit went to another");
        assert!(one.sum == three.sum && three.hits.is_some());
        assert_eq!(one.sum.film()[0][0], 38.0 * 2f32.powi(-30));
        let (mut a, b) = (run(&mut [0, 2], Part { rank: 0, ranks: 2 }), run(&mut [0], Part { rank: 1, ranks: 2 }));
        assert!(a.stats.iter().all(|s| s.0 % 2 == 0) && b.stats.iter().all(|s| s.0 % 2 == 1) && a.stats.len() == 20 && b.stats.len() == 20);
        assert!(a.hits.is_some() && b.hits.is_none(), "unit 0 is rank 0's");
        a.sum.add_sums(&b.sum);
        assert!(a.sum == one.sum, "two ranks' sums");
        // In floating point, in reverse order, the small values are lost.
        let mut f = 0.0f64;
        for u in (0..40).rev() {
            f += film(u)[0][0] as f64;
        }
        assert_ne!(f as f32, one.sum.film()[0][0], "the films chosen do not tell an exact sum from a floating-point one");
    }

    /// The integer conversion is the exact one (v · 2^64 in f64, rounded half away from zero)
    /// for values of every exponent, ties included.
    #[test]
    fn fixed_point_conversion_is_exact() {
        let mut rng = kdray_shared::rng::Rng::new(5, 0);
        let mut values: Vec<f32> = vec![0.0, -0.0, 1.0, -1.0, 2f32.powi(-64), 2f32.powi(-65), 3.0 * 2f32.powi(-66), -3.0 * 2f32.powi(-66), 2f32.powi(40), -(2f32.powi(40)), f32::MIN_POSITIVE, 2f32.powi(-88)];
        for _ in 0..200_000 {
            let bits = rng.next_u32();
            let v = f32::from_bits(bits);
            if v.is_finite() && v.abs() <= FIXED_MAX {
                values.push(v);
            }
        }
        for v in values {
            assert_eq!(fixed(v), ((v as f64) * FIXED_ONE).round() as i128, "{v:e}");
        }
    }

    /// Values beyond ±2^40 and NaN are clamped and counted; a value below 2^-64 is lost.
    #[test]
    fn film_sums_clamp_what_they_cannot_hold() {
        let mut s = FilmSum::new(1);
        s.add(&[[f32::INFINITY, f32::NAN, -1e13, 1e-25]]);
        assert_eq!(s.clamped, 3);
        assert_eq!(s.film()[0], [2f32.powi(40), 0.0, -(2f32.powi(40)), 0.0]);
    }

    /// With every worker failing, the units not delivered are missing, and a stop ends the
    /// hand-out without missing units.
    #[test]
    fn units_no_worker_is_left_for_are_missing_and_a_stop_hands_out_no_more() {
        let r = share(
            &mut [0u32, 1],
            10,
            Part::WHOLE,
            1,
            |w: &mut u32, hand: &mut Hand<'_, ()>| {
                let u = hand.take().unwrap();
                if *w == 0 {
                    hand.deliver(Unit { index: u, film: vec![[1.0; 4]], hits: None, stats: () });
                    hand.take();
                }
                Err(Error::DeviceLost("injected".into()))
            },
            |_| false,
        )
        .unwrap();
        assert_eq!((r.failed.len(), r.stats.len()), (2, 1));
        assert_eq!(r.missing.len(), 9, "{:?}", r.missing);
        assert!(!r.missing.contains(&r.stats[0].0));
        assert_eq!(r.sum.film(), vec![[1.0; 4]]);
        let r = share(
            &mut [0u32],
            1000,
            Part::WHOLE,
            1,
            |_: &mut u32, hand: &mut Hand<'_, ()>| {
                while let Some(u) = hand.take() {
                    hand.advance(1);
                    std::thread::sleep(std::time::Duration::from_millis(1));
                    hand.deliver(Unit { index: u, film: vec![[1.0; 4]], hits: None, stats: () });
                }
                Ok(())
            },
            |_| true,
        )
        .unwrap();
        assert!(r.stats.len() < 1000 && r.missing.is_empty() && r.failed.is_empty());
    }
}
