// Scratch: where Tracer::update's time goes (natively), chairs:1024.
use std::time::Instant;
fn main() {
    let s = kdray::scene::load(&std::env::args().nth(1).unwrap_or("chairs:1024".into())).unwrap();
    let rt: &dyn kdray::Runtime = &kdray::runtime::cpu::NATIVE;
    let mut t = kdray::Tracer::new(rt, &s, None).unwrap();
    for _ in 0..3 {
        let t0 = Instant::now(); s.validate().unwrap(); let a = t0.elapsed().as_secs_f64() * 1e3;
        let t0 = Instant::now(); let l = s.lights(); let b = t0.elapsed().as_secs_f64() * 1e3;
        let t0 = Instant::now(); let _ = t.holds(&s); let c = t0.elapsed().as_secs_f64() * 1e3;
        let t0 = Instant::now(); let _ = s.bounds(); let d = t0.elapsed().as_secs_f64() * 1e3;
        let t0 = Instant::now(); t.update(&s).unwrap(); let e = t0.elapsed().as_secs_f64() * 1e3;
        println!("validate {a:.1} lights {b:.1} ({}) fingerprint {c:.1} bounds {d:.1} update {e:.1} ms", l.len());
    }
}
