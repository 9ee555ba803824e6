//! The single-ray traversal family, one generic function: the stack kind (`NoStack`,
//! `ShortStack<N>`, `FullStack`) and `PUSHDOWN` select kd-restart, push-down, short-stack or the
//! classic full stack (see the module table in `kdtree`).
use super::stack::{Entry, ExitEntry, FullStack, NoStack, ShortStack, Stack as StackKind, StackEntry, NO_NODE};
use super::{exit_bound, near_end, plane_band, KdTree, MAX_DEPTH};
use crate::query::{AnyHit, Closest, Query, Visitor};
use crate::stats::Stats;
use crate::aabb::{intersect_box, inv_dir};
use crate::pod::Hit;
use crate::ray::Ray;
use crate::triangle::ShearedRay;
use crate::math::pick3;
use super::packet::PacketTraversal;

/// Walks the tree for `q`. `PUSHDOWN` selects Horn's push-down restart node.
///
/// A split plane whose ray parameter lies within rounding of an end of the current interval
/// (`plane_band`: a cell thinner along the ray than the rounding of t, or a ray starting on the
/// plane) is resolved by visiting both children. A stack that may drop entries cannot promise
/// that (a restart from the end of a leaf could pass over a cell that thin), so such a ray is
/// traversed again from the start with the full stack: every variant returns the oracle's
/// hits, whatever the cells' thickness and the ray's distance.
#[inline(always)]
pub fn traverse<Q: Visitor, E: StackEntry, K: StackKind<E>, S: Stats, const PUSHDOWN: bool>(
    tree: &KdTree,
    ray: &Ray,
    q: &mut Q,
    stack: &mut K,
    stats: &mut S,
) {
    if !walk::<_, _, _, _, PUSHDOWN>(tree, ray, q, stack, stats) && !K::KEEPS_ALL {
        stats.restart();
        walk::<_, Entry, _, _, false>(tree, ray, q, &mut FullStack::new(), stats);
    }
}

/// `traverse` with stack `stack`; returns `false` (the query left as it is, to be completed
/// by a full-stack walk) where a stack that drops entries meets a plane too near an end of the
/// interval to tell the order.
#[inline(always)]
fn walk<Q: Visitor, E: StackEntry, K: StackKind<E>, S: Stats, const PUSHDOWN: bool>(
    tree: &KdTree,
    ray: &Ray,
    q: &mut Q,
    stack: &mut K,
    stats: &mut S,
) -> bool {
    let r = match ShearedRay::new(ray) {
        Some(r) => r,
        None => return true,
    };
    let o = ray.origin;
    let inv = inv_dir(ray.dir);
    let (scene_t0, scene_t1) = match intersect_box(o, inv, &tree.bounds, ray.t_min, ray.t_max) {
        Some(i) => i,
        None => return true,
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
    // Where entries may be dropped: the node whose plane ends the interval at t1, and after a
    // restart the plane the ray restarts on (its t is t0 exactly: the ray goes beyond it).
    let mut exit = NO_NODE;
    let mut passed = NO_NODE;
    let mut pushdown = true;
    stack.clear();
    while steps < max_steps {
        steps += 1;
        if node_idx >= n_nodes {
            return true;
        }
        let node = tree.nodes.get(node_idx as usize);
        stats.node();
        if !node.is_leaf() {
            let k = node.axis();
            let p = node.split();
            let (ok, ik) = (pick3(o, k), pick3(inv, k));
            let below = node.first_child();
            let above = below + 1;
            if ik.is_infinite() {
                // Parallel to the plane: the side of the origin (on the plane: below, which
                // holds every triangle touching the plane too).
                node_idx = if ok <= p { below } else { above };
            } else {
                let ts = (p - ok) * ik;
                // The child the ray is in before the plane (a) and after it (b).
                let (a, b) = if ik > 0.0 { (below, above) } else { (above, below) };
                if !K::KEEPS_ALL {
                    // A plane too near an end of the interval to tell the order (but the one
                    // a restart starts on, which the ray is beyond: ts = t0 exactly there):
                    // the full stack's walk decides. Otherwise the exact decisions.
                    if node_idx != passed && (near_end(ts, t0) || near_end(ts, t1)) {
                        return false;
                    }
                    if ts >= t1 {
                        node_idx = a;
                    } else if ts <= t0 {
                        node_idx = b;
                    } else {
                        stack.push(E::new(b, ts, t1, exit));
                        exit = node_idx;
                        node_idx = a;
                        t1 = ts;
                        pushdown = false;
                    }
                } else if ts > t1 + plane_band(ts) {
                    node_idx = a;
                } else if ts < t0 - plane_band(ts) {
                    node_idx = b;
                } else {
                    // The plane crosses the interval, or lies too near an end of it to tell:
                    // both children, each with the interval clamped to the parent's.
                    let ts = ts.max(t0).min(t1);
                    stack.push(E::new(b, ts, t1, exit));
                    node_idx = a;
                    t1 = ts;
                    pushdown = false;
                }
            }
            if PUSHDOWN && pushdown {
                restart_node = node_idx;
            }
            continue;
        }
        stats.leaf();
        q.leaf(&prims, node.prim_offset(), node.prim_count(), &r, ray.t_min, t1, stats);
        if q.done(exit_bound(t1)) {
            return true;
        }
        match stack.pop() {
            Some(e) => {
                node_idx = e.node();
                t0 = e.t0();
                t1 = e.t1();
                exit = e.exit();
                passed = NO_NODE;
            }
            None => {
                if !stack.dropped() || t1 >= scene_t1 {
                    return true;
                }
                stats.restart();
                t0 = t1;
                t1 = scene_t1;
                passed = exit;
                exit = NO_NODE;
                node_idx = if PUSHDOWN { restart_node } else { 0 };
                pushdown = true;
                stack.clear();
            }
        }
    }
    true
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
        traverse::<_, Entry, _, _, false>(tree, ray, v, &mut FullStack::new(), stats)
    }
}
impl Traversal for Restart {
    #[inline(always)]
    fn run<V: Visitor, S: Stats>(tree: &KdTree, ray: &Ray, v: &mut V, stats: &mut S) {
        traverse::<_, ExitEntry, _, _, false>(tree, ray, v, &mut NoStack::new(), stats)
    }
}
impl Traversal for PushDown {
    #[inline(always)]
    fn run<V: Visitor, S: Stats>(tree: &KdTree, ray: &Ray, v: &mut V, stats: &mut S) {
        traverse::<_, ExitEntry, _, _, true>(tree, ray, v, &mut NoStack::new(), stats)
    }
}
impl<const N: usize> Traversal for Short<N> {
    #[inline(always)]
    fn run<V: Visitor, S: Stats>(tree: &KdTree, ray: &Ray, v: &mut V, stats: &mut S) {
        traverse::<_, ExitEntry, _, _, true>(tree, ray, v, &mut ShortStack::<ExitEntry, N>::new(), stats)
    }
}
