//! Four rays traversed together (Wald's SIMD packets; Horn et al. 2007, Algorithm 5, with
//! push-down and a short stack kept per packet). Per-lane values live in `Vec4` (SSE on the CPU,
//! a vec4 register on the GPU) and lane masks in `BVec4A`; each node and each triangle is
//! fetched once per packet.
//!
//! A packet is traversed together only when all its valid rays have non-zero direction
//! components of the same sign on every axis: then every ray meets the two children of a node
//! in the same order. Otherwise (`traverse_packet` returns `false`) the rays go one by one
//! through the single-ray traversal.
//!
//! At an interior node each active lane decides exactly as the single-ray traversal does (near
//! only if `t_split >= t1`, far only if `t_split <= t0`, else both, with the same intervals):
//! the packet goes near if no lane needs the far child, far if no lane needs the near one,
//! otherwise it pushes the far child with the lanes that need it and their intervals and goes
//! near with the others. A lane is finished when its query is satisfied before the end of the
//! leaf it just visited; popped entries keep only unfinished lanes. When the stack runs dry
//! after dropping entries, every unfinished lane restarts from the end of the last leaf *it*
//! visited (push-down: from the deepest node entered since the last restart with no split).
//! Each lane therefore visits the same leaves in the same order as it would alone and its
//! result is identical to the single-ray result. A lane meeting an ambiguous plane
//! (`kdtree::near_end`) where the stack may drop entries ends the packet: the rays are
//! traversed alone, which resolves it; the full-stack packet visits both children instead
//! (`kdtree::plane_band`).
use super::single::{traverse, with_traversal, Algorithm, Full, PushDown, Restart, Short, Traversal, WithTraversal};
use super::stack::{Entry, ExitEntry, NoStack, ShortStack, Stack, StackEntry, NO_NODE};
use super::{exit_bound, near_end, plane_band, KdTree, MAX_DEPTH};
use crate::query::Query;
use crate::stats::Stats;
use crate::aabb::{intersect_box, inv_dir};
use crate::ray::Ray;
use crate::triangle::ShearedRay;
use glam::{BVec4A, Vec4};

/// Rays per packet.
pub const PACKET: usize = 4;

/// A far child, the lanes that still need it (bit l = lane l) and their intervals inside it.
/// Stored as plain arrays (4-byte aligned): an `Option` of 16-byte-aligned vectors is a value
/// rust-gpu cannot express.
#[derive(Copy, Clone, Default)]
pub struct PacketEntry {
    /// Index of the far child.
    pub node: u32,
    /// Lanes that still need it (bit l = lane l).
    pub mask: u32,
    /// Start of each lane's interval inside the child.
    pub t0: [f32; PACKET],
    /// End of each lane's interval inside the child.
    pub t1: [f32; PACKET],
    /// Per lane, the node whose plane ends its interval (`NO_NODE`: the scene box).
    pub exit: [u32; PACKET],
}

#[inline(always)]
fn lanes(bits: u32) -> BVec4A {
    BVec4A::new(bits & 1 != 0, bits & 2 != 0, bits & 4 != 0, bits & 8 != 0)
}

#[inline(always)]
fn pick(v: [Vec4; 3], k: usize) -> Vec4 {
    if k == 0 {
        v[0]
    } else if k == 1 {
        v[1]
    } else {
        v[2]
    }
}

/// Whether a packet is coherent: its valid rays have non-zero direction components of one sign
/// on every axis. Returns the signs as bits (bit a set: positive along axis a), or `None` if
/// it is not (a packet without valid rays is coherent).
#[inline(always)]
pub fn direction_signs(rays: &[Ray; PACKET]) -> Option<u32> {
    let mut sign = [0i32; 3];
    let mut l = 0;
    while l < PACKET {
        if rays[l].is_valid() {
            let id = inv_dir(rays[l].dir);
            let mut a = 0;
            while a < 3 {
                let s = if id[a].is_infinite() {
                    0
                } else if id[a] > 0.0 {
                    1
                } else {
                    -1
                };
                if s == 0 || (sign[a] != 0 && sign[a] != s) {
                    return None;
                }
                sign[a] = s;
                a += 1;
            }
        }
        l += 1;
    }
    Some((sign[0] >= 0) as u32 | ((sign[1] >= 0) as u32) << 1 | ((sign[2] >= 0) as u32) << 2)
}

/// Traverses the four rays together if they are coherent (see the module notes) and returns
/// `true`; returns `false` otherwise — at once for an incoherent packet, or where a lane meets a
/// split plane within rounding of an end of its interval (`kdtree::near_end`), which the
/// single-ray traversal resolves: the caller then traverses each ray alone (queries keep what
/// they found).
#[inline(always)]
pub fn traverse_packet<Q: Query, K: Stack<PacketEntry>, S: Stats, const PUSHDOWN: bool>(
    tree: &KdTree,
    rays: &[Ray; PACKET],
    q: &mut [Q; PACKET],
    stack: &mut K,
    stats: &mut S,
) -> bool {
    // Per-lane constants; invalid rays and rays missing the scene box start inactive. Built in
    // arrays (vector lanes are never written one by one: on the GPU that needs pointers to
    // lanes).
    let mut sheared = [ShearedRay::default(); PACKET];
    let mut o = [[0.0f32; PACKET]; 3];
    let mut inv = [[0.0f32; PACKET]; 3];
    let mut t_min = [0.0f32; PACKET];
    let mut t0a = [0.0f32; PACKET];
    let mut t1a = [0.0f32; PACKET];
    let positive = match direction_signs(rays) {
        Some(p) => p,
        None => return false,
    };
    let mut valid = 0u32;
    let mut l = 0;
    while l < PACKET {
        let ray = &rays[l];
        if let Some(r) = ShearedRay::new(ray) {
            sheared[l] = r;
            let id = inv_dir(ray.dir);
            let mut a = 0;
            while a < 3 {
                o[a][l] = ray.origin[a];
                inv[a][l] = id[a];
                a += 1;
            }
            t_min[l] = ray.t_min;
            if let Some((a, b)) = intersect_box(ray.origin, id, &tree.bounds, ray.t_min, ray.t_max) {
                t0a[l] = a;
                t1a[l] = b;
                valid |= 1 << l;
            }
        }
        l += 1;
    }
    let o = [Vec4::from_array(o[0]), Vec4::from_array(o[1]), Vec4::from_array(o[2])];
    let inv = [Vec4::from_array(inv[0]), Vec4::from_array(inv[1]), Vec4::from_array(inv[2])];
    let mut t0 = Vec4::from_array(t0a);
    let mut t1 = Vec4::from_array(t1a);
    let valid = lanes(valid);
    let scene_t1 = t1;
    // End of the last leaf each lane visited: where it restarts.
    let mut t_last = t0;
    // Per lane: the node whose plane ends its interval, the one ending its last leaf's, and
    // after a restart the plane it has just passed (see `single::traverse`).
    let mut exit = [NO_NODE; PACKET];
    let mut exit_last = [NO_NODE; PACKET];
    let mut passed = [NO_NODE; PACKET];
    let mut alive = valid;
    let mut mask = valid;
    if !mask.any() {
        return true;
    }

    let n_nodes = tree.nodes.len() as u32;
    let max_steps = PACKET as u32 * (n_nodes.min(1 << 24) * MAX_DEPTH as u32 + 64);
    let mut steps = 0u32;
    let mut restart_node = 0u32;
    let mut node_idx = 0u32;
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
            let below = node.first_child();
            let (near, far) = if positive & (1 << k) != 0 { (below, below + 1) } else { (below + 1, below) };
            let ts = (Vec4::splat(node.split()) - pick(o, k)) * pick(inv, k);
            let (need_far, need_near);
            if !K::KEEPS_ALL {
                // As `single::traverse` where entries may be dropped: a lane meeting a plane
                // too near an end of its interval (but the one it restarts on) sends the rays
                // alone; otherwise the exact decisions, per lane.
                let close = near_end(ts, t0) | near_end(ts, t1);
                let passing = BVec4A::new(passed[0] == node_idx, passed[1] == node_idx, passed[2] == node_idx, passed[3] == node_idx);
                if (mask & close & !passing).any() {
                    return false;
                }
                need_far = mask & ts.cmplt(t1);
                need_near = mask & !(ts.cmplt(t1) & ts.cmple(t0));
            } else {
                // A full stack: the plane beyond the interval (near only), before it (far
                // only), or crossing it or too near an end to tell (both).
                let band = plane_band(ts);
                need_far = mask & !ts.cmpgt(t1 + band);
                need_near = mask & !ts.cmplt(t0 - band);
            }
            if !need_far.any() {
                node_idx = near;
            } else if !need_near.any() {
                node_idx = far;
            } else {
                let cut = ts.max(t0).min(t1);
                stack.push(PacketEntry { node: far, mask: need_far.bitmask(), t0: cut.to_array(), t1: t1.to_array(), exit });
                if !K::KEEPS_ALL {
                    // Lanes whose interval now ends at this plane.
                    let ends = need_near & need_far;
                    let mut l = 0;
                    while l < PACKET {
                        if ends.test(l) {
                            exit[l] = node_idx;
                        }
                        l += 1;
                    }
                }
                node_idx = near;
                mask = need_near;
                t1 = Vec4::select(need_far, cut, t1);
                pushdown = false;
            }
            if PUSHDOWN && pushdown {
                restart_node = node_idx;
            }
            continue;
        }
        stats.leaf();
        let off = node.prim_offset() as usize;
        let n = node.prim_count() as usize;
        let mut j = 0;
        while j < n {
            let p = tree.prims.get(off + j);
            let tri = &tree.tris.get(p as usize);
            let mut open = false;
            let mut l = 0;
            while l < PACKET {
                if mask.test(l) && q[l].open() {
                    q[l].test(p, tri, &sheared[l], t_min[l], stats);
                    open = true;
                }
                l += 1;
            }
            if !open {
                break;
            }
            j += 1;
        }
        t_last = Vec4::select(mask, t1, t_last);
        let t_end = t1.to_array();
        let mut l = 0;
        while l < PACKET {
            if mask.test(l) {
                exit_last[l] = exit[l];
                if q[l].finished(exit_bound(t_end[l])) {
                    alive &= !lanes(1 << l);
                }
            }
            l += 1;
        }
        // Next: the newest stacked entry with an unfinished lane, else a restart.
        loop {
            match stack.pop() {
                Some(e) => {
                    mask = lanes(e.mask) & alive;
                    if mask.any() {
                        node_idx = e.node;
                        t0 = Vec4::from_array(e.t0);
                        t1 = Vec4::from_array(e.t1);
                        exit = e.exit;
                        passed = [NO_NODE; PACKET];
                        break;
                    }
                }
                None => {
                    mask = alive & t_last.cmplt(scene_t1);
                    if !stack.dropped() || !mask.any() {
                        return true;
                    }
                    stats.restart();
                    t0 = t_last;
                    t1 = scene_t1;
                    passed = exit_last;
                    exit = [NO_NODE; PACKET];
                    node_idx = if PUSHDOWN { restart_node } else { 0 };
                    pushdown = true;
                    stack.clear();
                    break;
                }
            }
        }
    }
    true
}

/// Traverses the packet together if it is coherent, else ray by ray with the single-ray
/// traversal of the same kind (`K`, push-down as given). Returns whether it went together.
#[inline(always)]
pub fn packet_or_single<Q, KP, E, K, S, const PUSHDOWN: bool>(tree: &KdTree, rays: &[Ray; PACKET], q: &mut [Q; PACKET], stats: &mut S) -> bool
where
    Q: Query,
    KP: Stack<PacketEntry> + Default,
    E: StackEntry,
    K: Stack<E> + Default,
    S: Stats,
{
    if traverse_packet::<_, _, _, PUSHDOWN>(tree, rays, q, &mut KP::default(), stats) {
        return true;
    }
    let mut l = 0;
    while l < PACKET {
        traverse::<_, E, _, _, PUSHDOWN>(tree, &rays[l], &mut q[l], &mut K::default(), stats);
        l += 1;
    }
    false
}

/// Runs `alg` on a packet (`packet_or_single`). Short-stack sizes other than 1..=8 fall back to
/// 8 as in `single::run`.
#[inline(always)]
pub fn run_packet<Q: Query, S: Stats>(alg: Algorithm, tree: &KdTree, rays: &[Ray; PACKET], q: &mut [Q; PACKET], stats: &mut S) -> bool {
    struct Run<'a, 'b, Q, S>(&'a KdTree<'b>, &'a [Ray; PACKET], &'a mut [Q; PACKET], &'a mut S);
    impl<Q: Query, S: Stats> WithTraversal for Run<'_, '_, Q, S> {
        type Out = bool;
        #[inline(always)]
        fn call<T: Traversal + PacketTraversal>(self) -> bool {
            T::run_packet(self.0, self.1, self.2, self.3)
        }
    }
    with_traversal(alg, Run(tree, rays, q, stats))
}

/// The packet form of a traversal type (`single::Traversal`): Horn et al.'s packet variant
/// with the same stack kind and push-down rule, falling back to single rays for incoherent
/// packets.
pub trait PacketTraversal {
    /// Traverses `rays` for `q` with this traversal's packet form; returns whether the rays went
    /// together (`false`: one by one).
    fn run_packet<Q: Query, S: Stats>(tree: &KdTree, rays: &[Ray; PACKET], q: &mut [Q; PACKET], stats: &mut S) -> bool;
}
impl PacketTraversal for Full {
    #[inline(always)]
    fn run_packet<Q: Query, S: Stats>(tree: &KdTree, rays: &[Ray; PACKET], q: &mut [Q; PACKET], stats: &mut S) -> bool {
        packet_or_single::<_, ShortStack<PacketEntry, MAX_DEPTH>, Entry, ShortStack<Entry, MAX_DEPTH>, _, false>(tree, rays, q, stats)
    }
}
impl PacketTraversal for Restart {
    #[inline(always)]
    fn run_packet<Q: Query, S: Stats>(tree: &KdTree, rays: &[Ray; PACKET], q: &mut [Q; PACKET], stats: &mut S) -> bool {
        packet_or_single::<_, NoStack, ExitEntry, NoStack, _, false>(tree, rays, q, stats)
    }
}
impl PacketTraversal for PushDown {
    #[inline(always)]
    fn run_packet<Q: Query, S: Stats>(tree: &KdTree, rays: &[Ray; PACKET], q: &mut [Q; PACKET], stats: &mut S) -> bool {
        packet_or_single::<_, NoStack, ExitEntry, NoStack, _, true>(tree, rays, q, stats)
    }
}
impl<const N: usize> PacketTraversal for Short<N> {
    #[inline(always)]
    fn run_packet<Q: Query, S: Stats>(tree: &KdTree, rays: &[Ray; PACKET], q: &mut [Q; PACKET], stats: &mut S) -> bool {
        packet_or_single::<_, ShortStack<PacketEntry, N>, ExitEntry, ShortStack<ExitEntry, N>, _, true>(tree, rays, q, stats)
    }
}
