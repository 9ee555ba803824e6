//! Rays traversed together through the compressed wide BVH, `W` per packet (Wald et al. 2001's
//! packets over Ylitie et al.'s nodes; Embree's packet kernels do the same over its own): each
//! node is fetched and decoded once per packet and each of its child boxes tested against every
//! lane at once, lanes held in `[f32; W]` arrays whose loops the compiler turns into vector
//! instructions (eight lanes, one AVX register, in the native runtime). Written once for every
//! width up to 32.
//!
//! The CPU's walk: a GPU already runs neighbouring rays in lockstep across threads, and this
//! walk's box test relies on correctly rounded division, which Vulkan does not promise (OpFDiv
//! may be 2.5 ulp off); the GPU kernel of `bvh+packets` traces its four rays one by one with the
//! single-ray walk. (Tried on lavapipe, the packet kernel also lost the answers of lanes after
//! the first: a compiler problem not tracked down.)
//!
//! A packet goes together unless its origins lie apart (rays from scattered points share few
//! nodes: measured on random rays in the bunny's box, packets lost 21 % to single rays) or a
//! valid ray has a direction component too small to invert (`traverse_packet` then returns
//! `false` before testing anything, and the caller traces the rays one by one). Lanes may point into different octants: each lane takes its own near and
//! far planes, and children are visited in the first valid lane's octant order (the single-ray
//! walk's order for it), roughly front to back for a coherent packet.
//!
//! Exactness: per lane, a child is culled only by `aabb::intersect_box`'s slab test of its
//! stored box (reconstructed exactly) against the lane's interval widened as the single-ray walk
//! widens it (`widened`) — the test the single-ray walk falls back to where its fast form's bound
//! does not hold. So no box holding a triangle whose computed hit could answer the lane's query
//! is culled, every such triangle is tested with the lane's own query, and as answers do not
//! depend on the order triangles are tested in (closest hit: the nearest, ties to the lower
//! index; any hit: whether one exists), each lane's answer is the single-ray walk's, bit for bit
//! (a leaf triangle is tested for all lanes at once by `triangle::intersect_triangle_lanes`,
//! the same operations as the one-ray test, and its hits offered to each lane's query).
//! A lane that an any-hit packet hands to the single-ray walk (`SOLO`) gets that walk's
//! answer over the node's subtree, with the same query.
//! Every loop is bounded by the node count (a packet enters each node at most once).
use super::{widened, Bvh, SlotBits, BVH_WIDTH, MAX_BVH_DEPTH, META_EMPTY};
use crate::aabb::inv_dir;
use crate::math::{gamma, max_num, min_num, LaneMask};
use crate::query::Query;
use crate::ray::Ray;
use crate::stats::Stats;
use crate::triangle::{intersect_triangle_lanes, ShearedLanes, ShearedRay, TriHit};
use core::mem::MaybeUninit;

/// Rays per work item of `bvh+packets`: the native runtime traces two items' rays as one packet
/// of eight where it can, the GPU each item's four one by one.
pub const BVH_PACKET: usize = 4;

/// Stack capacity: a node pushes at most `BVH_WIDTH` children, and the entries below a node
/// are its ancestors' siblings, so a tree of depth `MAX_BVH_DEPTH` never needs more.
const STACK: usize = BVH_WIDTH * MAX_BVH_DEPTH;

/// Far-plane widening of the slab test (`aabb::slab`'s).
const FAR: f32 = 1.0 + 2.0 * gamma(3);

/// Any-hit packets enter a node that at most this many of their lanes reach with those lanes
/// one by one (`traverse_from`: the single-ray walk through the node's subtree), as Embree's
/// hybrid traversal does: a packet's node test costs about what eight single-ray ones do,
/// whatever its lanes. Shadow rays toward points of area lights scatter (natively, 2 cores:
/// the conference room's 7–10 % faster); closest-hit packets, whose coherent lanes seldom part,
/// ran 3–6 % slower with it and do not switch (`docs/benchmarks/2026-12-06-cpu-packet-levers`).
pub const SOLO: u32 = 1;

/// Traverses `rays` together for `q` (lane l's query answers ray l) and returns `true`, or
/// returns `false` at once, having tested nothing, for a packet whose valid rays' origins lie
/// apart (more than a sixteenth of the scene's largest extent from the first's along an axis: scattered rays
/// gain nothing from going together and lose the packet's setup) or with a valid ray whose
/// direction has a component too small to invert: the caller then traverses the rays one by
/// one. Invalid rays (`Ray::is_valid`) are misses.
#[inline(always)]
pub fn traverse_packet<Q: Query, S: Stats, const W: usize>(bvh: &Bvh, rays: &[Ray; W], q: &mut [Q; W], stats: &mut S) -> bool {
    let mut sheared = ShearedLanes::<W>::default();
    let mut inv = [[0.0f32; W]; 3];
    let mut inv_dmax = [0.0f32; W];
    let mut t_min = [0.0f32; W];
    let mut active = 0u32;
    let mut together = true;
    // The first valid ray's octant (bit 2: x < 0, bit 1: y < 0, bit 0: z < 0): the child
    // order; 8 until a valid ray sets it.
    let mut octant = 8u32;
    // Lane masks are u32.
    const { assert!(W <= 32) };
    // Coherent enough to gain from going together: every valid ray's origin near the first
    // valid one's, within a sixteenth of the scene's largest extent along every axis (the
    // root's grid spans the scene: 255 steps per axis). Asked first, as it is cheap: a packet
    // of scattered rays is declined at once.
    if bvh.nodes.is_empty() {
        return true;
    }
    let st = bvh.nodes.get(0).steps();
    let near_origin = max_num(max_num(st[0], st[1]), st[2]) * (255.0 / 16.0);
    let mut first = W;
    let mut l = 0;
    while l < W {
        if rays[l].is_valid() {
            if first == W {
                first = l;
            }
            let mut a = 0;
            while a < 3 {
                together &= (rays[l].origin[a] - rays[first].origin[a]).abs() <= near_origin;
                a += 1;
            }
        }
        l += 1;
    }
    if !together {
        return false;
    }
    // No return inside the loops (as `traverse`): flags end them.
    let mut l = 0;
    while l < W {
        let ray = &rays[l];
        if let Some(r) = ShearedRay::new(ray) {
            let d = ray.dir;
            let id = inv_dir(d);
            together &= !(id[0].is_infinite() || id[1].is_infinite() || id[2].is_infinite());
            if octant == 8 {
                octant = ((id[0] < 0.0) as u32) << 2 | ((id[1] < 0.0) as u32) << 1 | (id[2] < 0.0) as u32;
            }
            // (`sheared.origin` holds the origins the box tests need.)
            sheared.set(l, &r);
            let mut a = 0;
            while a < 3 {
                inv[a][l] = id[a];
                a += 1;
            }
            inv_dmax[l] = 1.0 / max_num(max_num(d[0].abs(), d[1].abs()), d[2].abs());
            t_min[l] = ray.t_min;
            active |= 1 << l;
        }
        l += 1;
    }
    if !together {
        return false;
    }
    let n_nodes = bvh.nodes.len() as u32;
    let n_tris = bvh.tris.len() as u32;
    if active == 0 || n_nodes == 0 {
        return true;
    }
    let oct_inv = 7 - octant;
    // Pending nodes: index and the lanes whose intervals overlapped its box. Not initialised
    // (2 KiB a packet otherwise): entries below `sp` are written before read.
    let mut stack = [MaybeUninit::<[u32; 2]>::uninit(); STACK];
    let mut sp = 0usize;
    let mut entry = [0u32, active];
    // Every step enters at most one node, and a packet enters each node at most once.
    let max_steps = n_nodes.min(u32::MAX - 1) + 1;
    let mut steps = 0u32;
    while steps < max_steps {
        steps += 1;
        // The entry's lanes whose queries are still open.
        let mut mask = 0u32;
        let mut l = 0;
        while l < W {
            if entry[1] & (1 << l) != 0 && q[l].open() {
                mask |= 1 << l;
            }
            l += 1;
        }
        if entry[0] >= n_nodes {
            // A corrupt index (the host validates trees): the walk ends.
            mask = 0;
            steps = max_steps;
        }
        if Q::ANY_HIT && mask != 0 && mask.count_ones() <= SOLO {
            // Each lane walks the subtree alone with its own query (answers do not depend on
            // the order triangles are tested in).
            while mask != 0 {
                let l = mask.trailing_zeros() as usize;
                mask &= mask - 1;
                super::traverse_from(bvh, entry[0], &rays[l], &mut q[l], stats);
            }
        }
        if mask != 0 {
            // SAFETY: entry[0] < n_nodes, checked above.
            let node = unsafe { bvh.nodes.get_unchecked(entry[0] as usize) };
            stats.node();
            let mut t0 = [0.0f32; W];
            let mut t1 = [0.0f32; W];
            let mut l = 0;
            while l < W {
                let (a, b) = widened(t_min[l], q[l].bound(), &node, inv_dmax[l]);
                t0[l] = a;
                t1[l] = b;
                l += 1;
            }
            let bits = SlotBits::new(&node, oct_inv);
            let (lo, hi) = node.child_boxes();
            // Lanes per slot, in the octant's visiting order (j = slot ^ oct_inv; highest first).
            let mut lanes = [0u32; BVH_WIDTH];
            let mut j = 0u32;
            while j < BVH_WIDTH as u32 {
                let s = j ^ oct_inv;
                if node.meta(s) != META_EMPTY {
                    let si = s as usize;
                    let mut m = LaneMask::<W>::new();
                    let mut l = 0;
                    while l < W {
                        // Per axis the distances to both planes; the nearer is the near plane
                        // (each lane's own sign), the farther is widened as `aabb::slab`'s. No
                        // NaN: finite planes, origins and reciprocals; t0, t1 not NaN.
                        let o = &sheared.origin;
                        let (x0, x1) = ((lo[0][si] - o[0][l]) * inv[0][l], (hi[0][si] - o[0][l]) * inv[0][l]);
                        let (y0, y1) = ((lo[1][si] - o[1][l]) * inv[1][l], (hi[1][si] - o[1][l]) * inv[1][l]);
                        let (z0, z1) = ((lo[2][si] - o[2][l]) * inv[2][l], (hi[2][si] - o[2][l]) * inv[2][l]);
                        // (Widening the smallest far distance is widening each: rounding is
                        // monotonic.)
                        let near = max_num(max_num(min_num(x0, x1), min_num(y0, y1)), max_num(min_num(z0, z1), t0[l]));
                        let far = min_num(min_num(max_num(x0, x1), max_num(y0, y1)), max_num(z0, z1)) * FAR;
                        m.put(l, near <= min_num(far, t1[l]));
                        l += 1;
                    }
                    lanes[j as usize] = m.bits() & mask;
                }
                j += 1;
            }
            // Leaves first, each with its own lanes; then the child nodes, nearest on top.
            let imask = node.imask();
            let mut j = 0u32;
            while j < BVH_WIDTH as u32 {
                let s = j ^ oct_inv;
                let m = lanes[j as usize];
                if m != 0 && imask & (1 << s) == 0 {
                    stats.leaf();
                    let mut tris = bits.get(s);
                    while tris != 0 {
                        let k = node.tri_base() + tris.trailing_zeros();
                        tris &= tris - 1;
                        if k < n_tris {
                            // SAFETY: k < n_tris, checked above.
                            let tri = unsafe { bvh.tris.get_unchecked(k as usize) }.triangle();
                            // Every lane's test at once (`Query::test` split in two: the
                            // watertight test, then `accept` for the lanes that hit).
                            let mut bound = [0.0f32; W];
                            let mut open = 0u32;
                            let mut l = 0;
                            while l < W {
                                bound[l] = q[l].bound();
                                if m & (1 << l) != 0 && q[l].open() {
                                    open |= 1 << l;
                                    stats.tri();
                                }
                                l += 1;
                            }
                            let (mut t, mut b1, mut b2) = ([0.0f32; W], [0.0f32; W], [0.0f32; W]);
                            let mut hit = open & intersect_triangle_lanes(&sheared, tri.v0, tri.v1, tri.v2, &t_min, &bound, &mut t, &mut b1, &mut b2);
                            while hit != 0 {
                                let l = hit.trailing_zeros() as usize;
                                hit &= hit - 1;
                                q[l].accept(tri._pad, TriHit { t: t[l], b1: b1[l], b2: b2[l] });
                            }
                        } else {
                            // A corrupt index: the walk ends.
                            tris = 0;
                            steps = max_steps;
                        }
                    }
                }
                if m != 0 && imask & (1 << s) != 0 && sp < STACK {
                    let index = node.child_base() + (imask & ((1u32 << s) - 1)).count_ones();
                    stack[sp] = MaybeUninit::new([index, m]);
                    sp += 1;
                }
                j += 1;
            }
        }
        // Done when the stack is empty or every query has its answer (any hit found).
        let mut open = false;
        let mut l = 0;
        while l < W {
            open |= active & (1 << l) != 0 && q[l].open();
            l += 1;
        }
        if sp == 0 || !open {
            steps = max_steps;
        } else if steps < max_steps {
            sp -= 1;
            // SAFETY: entry sp < the pushes' count was written by the push that made it.
            entry = unsafe { stack[sp].assume_init() };
        }
    }
    true
}

/// `traverse_packet`, or where it declines the packet each ray alone (`bvh::traverse`): the
/// rays' answers either way (the native `bvh+packets` and its counting run).
#[inline(always)]
pub fn packet_or_single<Q: Query, S: Stats, const W: usize>(bvh: &Bvh, rays: &[Ray; W], q: &mut [Q; W], stats: &mut S) {
    if !traverse_packet(bvh, rays, q, stats) {
        let mut l = 0;
        while l < W {
            super::traverse(bvh, &rays[l], &mut q[l], stats);
            l += 1;
        }
    }
}
