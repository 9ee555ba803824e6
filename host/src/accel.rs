//! How hits are found, as four independent choices: the structure searched (brute force, the
//! kd-tree or the compressed wide BVH), the traversal of that structure, the grouping of rays (one per thread, or
//! packets) and the pipeline (one kernel per query, or the decomposed traverse → leaf
//! list → intersect → fallback). `Accel` names one combination; `Accel::parse` reads the CLI's
//! names and rejects combinations that do not exist.
use crate::kernels::TraceMethod;
use crate::error::{bail, Result};
use kdray_shared::kdtree::{Algorithm, MAX_SHORT_STACK};

/// What is searched.
#[derive(Copy, Clone, Debug, PartialEq, Eq, Hash)]
pub enum Structure {
    /// Every triangle (the oracle).
    Brute,
    /// The SAH kd-tree (it must have been built).
    KdTree,
    /// The compressed 8-wide BVH (it must have been built: `Tracer::with_bvh`).
    Bvh,
}

/// How many rays one thread traces together.
#[derive(Copy, Clone, Debug, PartialEq, Eq, Hash)]
pub enum Grouping {
    /// One ray per thread.
    Single,
    /// Four rays per thread with lane masks: the kd-tree's Horn et al. packets (Wald's, four
    /// lanes on both sides), or the BVH's packets (natively eight lanes: two threads' rays
    /// together; on the GPU a thread's four rays one by one).
    Packet4,
}

/// How a query is split into kernels.
#[derive(Copy, Clone, Debug, PartialEq, Eq, Hash)]
pub enum Pipeline {
    /// One kernel per query: traversal and intersection together.
    Monolithic,
    /// Frolov & Ignatenko: leaf lists of `capacity` entries per ray (full-stack traversal),
    /// intersection over them, a full-stack fallback for rays whose list overflowed.
    Decomposed {
        /// Leaf-list entries per ray.
        capacity: u32,
    },
}

/// One way of finding hits: structure × traversal × grouping × pipeline.
#[derive(Copy, Clone, Debug, PartialEq, Eq, Hash)]
pub struct Accel {
    /// What is searched.
    pub structure: Structure,
    /// The kd traversal (ignored by brute force; the decomposed pipeline uses the full stack).
    pub traversal: Algorithm,
    /// How many rays one thread traces together.
    pub grouping: Grouping,
    /// How a query is split into kernels.
    pub pipeline: Pipeline,
}

/// Default leaf-list capacity of the decomposed pipeline.
pub const DEFAULT_LEAF_CAPACITY: u32 = 16;
/// Largest leaf-list capacity accepted.
pub const MAX_LEAF_CAPACITY: u32 = kdray_shared::kdtree::MAX_LEAF_LIST as u32;

impl Accel {
    /// The brute-force oracle.
    pub const BRUTE: Accel = Accel { structure: Structure::Brute, traversal: Algorithm::Stack, grouping: Grouping::Single, pipeline: Pipeline::Monolithic };

    /// The compressed 8-wide BVH, one ray per thread (its traversal is its own: `traversal`
    /// is not used).
    pub const BVH: Accel = Accel { structure: Structure::Bvh, traversal: Algorithm::Stack, grouping: Grouping::Single, pipeline: Pipeline::Monolithic };

    /// A kd traversal, one ray per thread.
    pub const fn kd(traversal: Algorithm) -> Accel {
        Accel { structure: Structure::KdTree, traversal, grouping: Grouping::Single, pipeline: Pipeline::Monolithic }
    }

    /// A kd traversal in packets of four rays.
    pub const fn packet(traversal: Algorithm) -> Accel {
        Accel { structure: Structure::KdTree, traversal, grouping: Grouping::Packet4, pipeline: Pipeline::Monolithic }
    }

    /// The compressed 8-wide BVH in packets: natively `bvh::traverse_packet` over eight rays
    /// (one AVX register per value); on the GPU four rays per thread, each traced alone (the
    /// packet walk is the CPU's: see `kdray_shared::bvh::packet`).
    pub const BVH_PACKETS: Accel = Accel { structure: Structure::Bvh, traversal: Algorithm::Stack, grouping: Grouping::Packet4, pipeline: Pipeline::Monolithic };

    /// The decomposed pipeline with leaf lists of `capacity` entries.
    pub const fn decomposed(capacity: u32) -> Accel {
        Accel { structure: Structure::KdTree, traversal: Algorithm::Stack, grouping: Grouping::Single, pipeline: Pipeline::Decomposed { capacity } }
    }

    /// `brute`, `bvh`, `stack`, `restart`, `pushdown`, `shortstack` (= `shortstack:3`),
    /// `shortstack:N`, `bvh` or any kd traversal followed by `+packets`, or
    /// `decomposed[:CAPACITY]`.
    pub fn parse(s: &str) -> Result<Accel> {
        if let Some(alg) = s.strip_suffix("+packets") {
            let a = Accel::parse(alg)?;
            return match a.with_packets() {
                Some(p) => Ok(p),
                None => bail!(InvalidInput: "'+packets' applies to bvh and the kd traversals (stack, restart, pushdown, shortstack[:N]), not '{alg}'"),
            };
        }
        if let Some(rest) = s.strip_prefix("decomposed") {
            let capacity = match rest.strip_prefix(':').map(str::parse::<u32>) {
                None if rest.is_empty() => DEFAULT_LEAF_CAPACITY,
                Some(Ok(c)) if (1..=MAX_LEAF_CAPACITY).contains(&c) => c,
                _ => bail!(InvalidInput: "unknown pipeline '{s}': use decomposed or decomposed:CAPACITY (1..={MAX_LEAF_CAPACITY} leaves per ray)"),
            };
            return Ok(Accel::decomposed(capacity));
        }
        Ok(match s {
            "brute" => Accel::BRUTE,
            "bvh" => Accel::BVH,
            "stack" => Accel::kd(Algorithm::Stack),
            "restart" => Accel::kd(Algorithm::Restart),
            "pushdown" => Accel::kd(Algorithm::PushDown),
            "shortstack" => Accel::kd(Algorithm::ShortStack(3)),
            s => match s.strip_prefix("shortstack:").map(str::parse::<u32>) {
                Some(Ok(n)) if (1..=MAX_SHORT_STACK).contains(&n) => Accel::kd(Algorithm::ShortStack(n)),
                _ => bail!(InvalidInput:
                    "unknown traversal '{s}': use brute, bvh, stack, restart, pushdown, shortstack or shortstack:N (N = 1..={MAX_SHORT_STACK}), optionally +packets, or decomposed[:CAPACITY]"
                ),
            },
        })
    }

    /// The name `parse` reads back: `brute`, a traversal (`shortstack:N`, never bare
    /// `shortstack`), with `+packets` for packets, or `decomposed:CAPACITY`.
    pub fn name(&self) -> String {
        match (self.structure, self.grouping, self.pipeline) {
            (Structure::Brute, _, _) => "brute".into(),
            (Structure::Bvh, Grouping::Single, _) => "bvh".into(),
            (Structure::Bvh, Grouping::Packet4, _) => "bvh+packets".into(),
            (_, _, Pipeline::Decomposed { capacity }) => format!("decomposed:{capacity}"),
            (_, Grouping::Single, _) => alg_name(self.traversal),
            (_, Grouping::Packet4, _) => format!("{}+packets", alg_name(self.traversal)),
        }
    }

    /// The same traversal in packets (`None` for brute force and the decomposed pipeline).
    pub fn with_packets(self) -> Option<Accel> {
        match (self.structure, self.pipeline) {
            (Structure::KdTree, Pipeline::Monolithic) => Some(Accel::packet(self.traversal)),
            (Structure::Bvh, Pipeline::Monolithic) => Some(Accel::BVH_PACKETS),
            _ => None,
        }
    }

    /// Whether rays are traced in packets.
    pub fn is_packet(self) -> bool {
        self.grouping == Grouping::Packet4
    }

    /// The query kernels' method where rays go one per thread and one kernel per query (brute
    /// force, a single-ray kd traversal or the BVH; `None` for packets and the decomposed
    /// pipeline).
    pub fn one_ray_method(self) -> Option<TraceMethod> {
        if self.pipeline != Pipeline::Monolithic || self.grouping != Grouping::Single {
            return None;
        }
        Some(match self.structure {
            Structure::Brute => TraceMethod::Brute,
            Structure::KdTree => TraceMethod::Single(self.traversal),
            Structure::Bvh => TraceMethod::Bvh,
        })
    }

    /// The method of a whole-path kernel family (entry points `<prefix>_<method>`: photon or
    /// eye paths) for this way of finding hits, if the module has that entry point (brute
    /// force, full stack, short stack of 3, the BVH).
    pub fn whole_path_method(self, prefix: &str) -> Option<TraceMethod> {
        let m = self.one_ray_method()?;
        let info = crate::runtime::module::module_info().ok()?;
        crate::runtime::module::find_entry(info, &format!("{prefix}_{}", m.suffix())).map(|_| m)
    }

    /// Whether a kd-tree is needed.
    pub fn needs_tree(self) -> bool {
        self.structure == Structure::KdTree
    }

    /// Whether the wide BVH is needed.
    pub fn needs_bvh(self) -> bool {
        self.structure == Structure::Bvh
    }

    /// The brute-force oracle and every single-ray kd traversal the GPU module has a kernel
    /// for (read from the module: short stacks of the sizes it was built with).
    pub fn all() -> Vec<Accel> {
        let mut v = vec![Accel::BRUTE, Accel::kd(Algorithm::Stack), Accel::kd(Algorithm::Restart), Accel::kd(Algorithm::PushDown)];
        v.extend(gpu_short_stacks().into_iter().map(|n| Accel::kd(Algorithm::ShortStack(n))));
        v
    }

    /// The kd-tree's packet traversals the GPU module has kernels for (the BVH's is
    /// `Accel::BVH_PACKETS`).
    pub fn gpu_packets() -> Vec<Accel> {
        let names = gpu_entry_points();
        [Algorithm::Stack, Algorithm::Restart, Algorithm::PushDown]
            .into_iter()
            .chain((1..=MAX_SHORT_STACK).map(Algorithm::ShortStack))
            .filter(|a| names.iter().any(|n| *n == format!("closest_packet_{}", crate::kernels::kernel_suffix(*a))))
            .map(Accel::packet)
            .collect()
    }
}

fn gpu_entry_points() -> Vec<String> {
    crate::runtime::module::module_info().map(|m| m.entry_points.iter().map(|e| crate::runtime::module::short_name(&e.name).to_string()).collect()).unwrap_or_default()
}

/// Short-stack sizes with a single-ray GPU kernel.
pub fn gpu_short_stacks() -> Vec<u32> {
    let names = gpu_entry_points();
    (1..=MAX_SHORT_STACK).filter(|n| names.iter().any(|e| *e == format!("closest_shortstack{n}"))).collect()
}

fn alg_name(a: Algorithm) -> String {
    match a {
        Algorithm::Stack => "stack".into(),
        Algorithm::Restart => "restart".into(),
        Algorithm::PushDown => "pushdown".into(),
        Algorithm::ShortStack(n) => format!("shortstack:{n}"),
    }
}
