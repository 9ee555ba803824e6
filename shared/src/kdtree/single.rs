//! The single-ray traversal family, one generic function: the stack kind (`NoStack`,
//! `ShortStack<N>`, `FullStack`) and `PUSHDOWN` select kd-restart, push-down, short-stack or the
//! classic full stack (see the module table in `kdtree`).
use super::stack::{Entry, FullStack, NoStack, ShortStack, Stack as StackKind};
use super::{KdTree, MAX_DEPTH};
use crate::query::{AnyHit, Closest, Query, Visitor};
use crate::stats::Stats;
use crate::aabb::{intersect_box, inv_dir};
use crate::pod::Hit;
use crate::ray::Ray;
use crate::triangle::ShearedRay;
use crate::math::pick3;
use super::packet::PacketTraversal;

/// Walks the tree for `q`. `PUSHDOWN` selects Horn's push-down restart node.
#[inline(always)]
pub fn traverse<Q: Visitor, K: StackKind<Entry>, S: Stats, const PUSHDOWN: bool>(
    tree: &KdTree,
    ray: &Ray,
    q: &mut Q,
    stack: &mut K,
    stats: &mut S,
) {
    let r = match ShearedRay::new(ray) {
        Some(r) => r,
        None => return,
    };
    let o = ray.origin;
    let inv = inv_dir(ray.dir);
    let (scene_t0, scene_t1) = match intersect_box(o, inv, &tree.bounds, ray.t_min, ray.t_max) {
        Some(i) => i,
        None => return,
    };
    let prims = tree.prims();
    let n_nodes = tree.nodes.len() as u32;
    // Hang guard: a valid ray visits far fewer nodes than this.
    let max_steps = n_nodes.min(1 << 24) * MAX_DEPTH as u32 + 64;
    let mut steps = 0u32;

    let mut restart_node = 0u32;
    let mut node_idx = 0u32;
    let mut t0 = scene_t0;
    let mut t1 = scene_t1;
    let mut pushdown = true;
    stack.clear();
    while steps < max_steps {
        steps += 1;
        if node_idx >= n_nodes {
            return;
        }
        let node = tree.nodes[node_idx as usize];
        stats.node();
        if !node.is_leaf() {
            let k = node.axis();
            let p = node.split();
            let (ok, ik) = (pick3(o, k), pick3(inv, k));
            let below = node.first_child();
            let above = below + 1;
            // The child the ray is in before the plane (A) and after it (B).
            let (a, b, t_split) = if ik.is_infinite() {
                // Parallel to the plane: the side of the origin (on the plane: below, which
                // holds every triangle touching the plane too).
                let c = if ok <= p { below } else { above };
                (c, c, f32::INFINITY)
            } else {
                let ts = (p - ok) * ik;
                if ik > 0.0 {
                    (below, above, ts)
                } else {
                    (above, below, ts)
                }
            };
            if t_split >= t1 {
                node_idx = a;
            } else if t_split <= t0 {
                node_idx = b;
            } else {
                stack.push(Entry { node: b, t0: t_split, t1 });
                node_idx = a;
                t1 = t_split;
                pushdown = false;
            }
            if PUSHDOWN && pushdown {
                restart_node = node_idx;
            }
            continue;
        }
        stats.leaf();
        q.leaf(&prims, node.prim_offset(), node.prim_count(), &r, ray.t_min, t1, stats);
        if q.done(t1) {
            return;
        }
        match stack.pop() {
            Some(e) => {
                node_idx = e.node;
                t0 = e.t0;
                t1 = e.t1;
            }
            None => {
                if !stack.dropped() || t1 >= scene_t1 {
                    return;
                }
                stats.restart();
                t0 = t1;
                t1 = scene_t1;
                node_idx = if PUSHDOWN { restart_node } else { 0 };
                pushdown = true;
                stack.clear();
            }
        }
    }
}

/// The algorithms by name. Short stacks of 1 to `MAX_SHORT_STACK` entries are instantiated.
#[derive(Copy, Clone, Debug, PartialEq, Eq, Hash)]
pub enum Algorithm {
    /// The classic full stack (`Full`).
    Stack,
    /// kd-restart, no stack (`Restart`).
    Restart,
    /// kd-restart with push-down (`PushDown`).
    PushDown,
    /// Push-down with a short stack of this many entries (`Short`).
    ShortStack(u32),
}

/// Largest short stack instantiated; larger sizes fall back to it.
pub const MAX_SHORT_STACK: u32 = 8;

/// Runs `alg` for query `q` (short-stack sizes outside 1..=8 fall back to 8).
#[inline(always)]
pub fn run<Q: Visitor, S: Stats>(alg: Algorithm, tree: &KdTree, ray: &Ray, q: &mut Q, stats: &mut S) {
    struct Run<'a, 'b, Q, S>(&'a KdTree<'b>, &'a Ray, &'a mut Q, &'a mut S);
    impl<Q: Visitor, S: Stats> WithTraversal for Run<'_, '_, Q, S> {
        type Out = ();
        #[inline(always)]
        fn call<T: Traversal + PacketTraversal>(self) {
            T::run(self.0, self.1, self.2, self.3)
        }
    }
    with_traversal(alg, Run(tree, ray, q, stats))
}

/// Something to do with the traversal type that `alg` names: the one place where an
/// `Algorithm` value becomes a type (the runtimes pick their kernels through it).
pub trait WithTraversal {
    /// What `call` returns.
    type Out;
    /// Does the work with traversal type `T`.
    fn call<T: Traversal + PacketTraversal>(self) -> Self::Out;
}

/// Calls `w` with the traversal type of `alg` (short stacks of 1..=8 entries; larger sizes
/// fall back to 8).
#[inline(always)]
pub fn with_traversal<W: WithTraversal>(alg: Algorithm, w: W) -> W::Out {
    match alg {
        Algorithm::Stack => w.call::<Full>(),
        Algorithm::Restart => w.call::<Restart>(),
        Algorithm::PushDown => w.call::<PushDown>(),
        Algorithm::ShortStack(1) => w.call::<Short<1>>(),
        Algorithm::ShortStack(2) => w.call::<Short<2>>(),
        Algorithm::ShortStack(3) => w.call::<Short<3>>(),
        Algorithm::ShortStack(4) => w.call::<Short<4>>(),
        Algorithm::ShortStack(5) => w.call::<Short<5>>(),
        Algorithm::ShortStack(6) => w.call::<Short<6>>(),
        Algorithm::ShortStack(7) => w.call::<Short<7>>(),
        Algorithm::ShortStack(_) => w.call::<Short<8>>(),
    }
}

/// The closest hit of `ray` found by traversal `alg`.
#[inline(always)]
pub fn closest_hit<S: Stats>(alg: Algorithm, tree: &KdTree, ray: &Ray, stats: &mut S) -> Hit {
    let mut q = Closest::new(ray);
    run(alg, tree, ray, &mut q, stats);
    q.hit
}

/// Whether traversal `alg` finds any hit of `ray` in its interval.
#[inline(always)]
pub fn any_hit<S: Stats>(alg: Algorithm, tree: &KdTree, ray: &Ray, stats: &mut S) -> bool {
    let mut q = AnyHit::new(ray);
    run(alg, tree, ray, &mut q, stats);
    q.found
}

/// A single-ray traversal as a type, so that kernels are generic over it (one kernel per
/// traversal without a copy of the kernel).
pub trait Traversal {
    /// Walks `tree` along `ray`, calling `v` at each leaf it visits.
    fn run<V: Visitor, S: Stats>(tree: &KdTree, ray: &Ray, v: &mut V, stats: &mut S);
}
/// The classic full stack.
pub struct Full;
/// kd-restart (Foley & Sugerman 2005).
pub struct Restart;
/// kd-restart + push-down (Horn et al. 2007).
pub struct PushDown;
/// Push-down + a short stack of `N` entries (Horn et al. 2007).
pub struct Short<const N: usize>;

impl Traversal for Full {
    #[inline(always)]
    fn run<V: Visitor, S: Stats>(tree: &KdTree, ray: &Ray, v: &mut V, stats: &mut S) {
        traverse::<_, _, _, false>(tree, ray, v, &mut FullStack::new(), stats)
    }
}
impl Traversal for Restart {
    #[inline(always)]
    fn run<V: Visitor, S: Stats>(tree: &KdTree, ray: &Ray, v: &mut V, stats: &mut S) {
        traverse::<_, _, _, false>(tree, ray, v, &mut NoStack::new(), stats)
    }
}
impl Traversal for PushDown {
    #[inline(always)]
    fn run<V: Visitor, S: Stats>(tree: &KdTree, ray: &Ray, v: &mut V, stats: &mut S) {
        traverse::<_, _, _, true>(tree, ray, v, &mut NoStack::new(), stats)
    }
}
impl<const N: usize> Traversal for Short<N> {
    #[inline(always)]
    fn run<V: Visitor, S: Stats>(tree: &KdTree, ray: &Ray, v: &mut V, stats: &mut S) {
        traverse::<_, _, _, true>(tree, ray, v, &mut ShortStack::<Entry, N>::new(), stats)
    }
}
