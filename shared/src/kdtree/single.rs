//! The single-ray traversal family, one generic function: the stack kind (`NoStack`,
//! `ShortStack<N>`, `FullStack`) and `PUSHDOWN` select kd-restart, push-down, short-stack or the
//! classic full stack (see the module table in `kdtree`).
use super::query::{AnyHit, Closest, Query, Visitor};
use super::stack::{Entry, FullStack, NoStack, ShortStack, Stack};
use super::{KdTree, Stats, MAX_DEPTH};
use crate::aabb::{intersect_box, inv_dir};
use crate::pod::Hit;
use crate::ray::Ray;
use crate::triangle::ShearedRay;

/// Walks the tree for `q`. `PUSHDOWN` selects Horn's push-down restart node.
#[inline(always)]
pub fn traverse<Q: Visitor, K: Stack<Entry>, S: Stats, const PUSHDOWN: bool>(
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
            let below = node.first_child();
            let above = below + 1;
            // The child the ray is in before the plane (A) and after it (B).
            let (a, b, t_split) = if inv[k].is_infinite() {
                // Parallel to the plane: the side of the origin (on the plane: below, which
                // holds every triangle touching the plane too).
                let c = if o[k] <= p { below } else { above };
                (c, c, f32::INFINITY)
            } else {
                let ts = (p - o[k]) * inv[k];
                if inv[k] > 0.0 {
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
        q.leaf(tree, node, &r, ray.t_min, t1, stats);
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
    Stack,
    Restart,
    PushDown,
    ShortStack(u32),
}

pub const MAX_SHORT_STACK: u32 = 8;

/// Runs `alg` for query `q` (short-stack sizes outside 1..=8 fall back to 8).
#[inline(always)]
pub fn run<Q: Visitor, S: Stats>(alg: Algorithm, tree: &KdTree, ray: &Ray, q: &mut Q, stats: &mut S) {
    match alg {
        Algorithm::Stack => traverse::<_, _, _, false>(tree, ray, q, &mut FullStack::new(), stats),
        Algorithm::Restart => traverse::<_, _, _, false>(tree, ray, q, &mut NoStack::new(), stats),
        Algorithm::PushDown => traverse::<_, _, _, true>(tree, ray, q, &mut NoStack::new(), stats),
        Algorithm::ShortStack(1) => traverse::<_, _, _, true>(tree, ray, q, &mut ShortStack::<Entry, 1>::new(), stats),
        Algorithm::ShortStack(2) => traverse::<_, _, _, true>(tree, ray, q, &mut ShortStack::<Entry, 2>::new(), stats),
        Algorithm::ShortStack(3) => traverse::<_, _, _, true>(tree, ray, q, &mut ShortStack::<Entry, 3>::new(), stats),
        Algorithm::ShortStack(4) => traverse::<_, _, _, true>(tree, ray, q, &mut ShortStack::<Entry, 4>::new(), stats),
        Algorithm::ShortStack(5) => traverse::<_, _, _, true>(tree, ray, q, &mut ShortStack::<Entry, 5>::new(), stats),
        Algorithm::ShortStack(6) => traverse::<_, _, _, true>(tree, ray, q, &mut ShortStack::<Entry, 6>::new(), stats),
        Algorithm::ShortStack(7) => traverse::<_, _, _, true>(tree, ray, q, &mut ShortStack::<Entry, 7>::new(), stats),
        Algorithm::ShortStack(_) => traverse::<_, _, _, true>(tree, ray, q, &mut ShortStack::<Entry, 8>::new(), stats),
    }
}

#[inline(always)]
pub fn closest_hit<S: Stats>(alg: Algorithm, tree: &KdTree, ray: &Ray, stats: &mut S) -> Hit {
    let mut q = Closest::new(ray);
    run(alg, tree, ray, &mut q, stats);
    q.hit
}

#[inline(always)]
pub fn any_hit<S: Stats>(alg: Algorithm, tree: &KdTree, ray: &Ray, stats: &mut S) -> bool {
    let mut q = AnyHit::new(ray);
    run(alg, tree, ray, &mut q, stats);
    q.found
}
