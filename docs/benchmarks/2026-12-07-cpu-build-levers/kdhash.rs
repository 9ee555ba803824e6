//! Scratch: build kd-trees of scenes, print time, nodes, SAH and a hash of the tree.
use kdray::kdtree::{self, BuildOptions};
use std::hash::{Hash, Hasher};

fn cpu_s() -> f64 {
    let mut ns = 0u64;
    for e in std::fs::read_dir("/proc/self/task").unwrap() {
        let p = e.unwrap().path().join("schedstat");
        if let Ok(t) = std::fs::read_to_string(p) {
            ns += t.split_whitespace().next().unwrap().parse::<u64>().unwrap();
        }
    }
    ns as f64 * 1e-9
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let reps: usize = std::env::var("REPS").ok().and_then(|s| s.parse().ok()).unwrap_or(3);
    let exact = std::env::var("EXACT").is_ok();
    for spec in &args {
        let s = kdray::scene::load(spec).unwrap();
        let n = s.triangles.len();
        let opt = if exact { BuildOptions { binned_above: None, ..Default::default() } } else { BuildOptions::default() };
        let mut times = Vec::new();
        let mut last = None;
        let mut cpus = Vec::new();
        for _ in 0..reps {
            let c0 = cpu_s();
            let t = kdtree::try_build(&s.triangles, &opt).unwrap();
            cpus.push(((cpu_s() - c0) / (n as f64 / 1e6) * 1000.0).round() / 1000.0);
            times.push(t.stats.build_seconds / (n as f64 / 1e6));
            last = Some(t);
        }
        let t = last.unwrap();
        let mut h = std::collections::hash_map::DefaultHasher::new();
        for nd in &t.nodes { nd.a.hash(&mut h); nd.b.hash(&mut h); }
        t.prims.hash(&mut h);
        let mut ts = times.clone();
        ts.sort_by(|a, b| a.partial_cmp(b).unwrap());
        println!("{:<14} n={:<8} s/M min {:.3} all {:?} cpu-s/M {:?} nodes {} refs {} sah {:.3} hash {:016x}", s.name, n, ts[0],
            times.iter().map(|x| (x * 1000.0).round() / 1000.0).collect::<Vec<_>>(), cpus, t.stats.nodes, t.stats.references, t.stats.sah_cost, h.finish());
    }
}
