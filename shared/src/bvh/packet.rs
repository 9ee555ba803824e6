//! Rays traversed together through the compressed wide BVH, `W` per packet (Wald et al. 2001's
//! packets over Ylitie et al.'s nodes; Embree's packet kernels do the same over its own): each
//! node is fetched and decoded once per packet and each of its child boxes tested against every
//! lane at once, lanes held in `[f32; W]` arrays whose loops the compiler turns into vector
//! instructions (eight lanes, one AVX register, in the native runtime). Written once for every
//! width up to 32.
//!
//! The CPU's walk: a GPU already runs neighbouring rays in lockstep across threads; the GPU
//! kernel of `bvh+packets` traces its four rays one by one with the single-ray walk. (Tried on
//! lavapipe, an earlier packet kernel lost the answers of lanes after the first: a compiler
//! problem not tracked down.)
//!
//! A packet goes together unless its origins lie apart (rays from scattered points share few
//! nodes: measured on random rays in the bunny's box, packets lost 21 % to single rays) or a
//! valid ray is not `BoxRay::tame` (a direction parallel or nearly parallel to an axis):
//! `traverse_packet` then returns `false` before walking, and the caller traces the rays one by
//! one. Lanes may point into different octants: each lane takes its own near and far planes,
//! and children are visited in the first valid lane's octant order (the single-ray walk's order
//! for it), roughly front to back for a coherent packet.
//!
//! Exactness: per lane, a child is culled only by the single-ray walk's fast test
//! (`fast_children`: the lane's `Grid`, the same multiply-adds, minima, maxima and comparison,
//! `fast_lanes`) against the lane's interval widened as the single-ray walk widens it
//! (`widened`): the lane's bits are that walk's for its ray. So no box holding a triangle whose
//! computed hit could answer the lane's query is culled (the parent module's rules), every such
//! triangle is tested with the lane's own query, and as answers do not
//! depend on the order triangles are tested in (closest hit: the nearest, ties to the lower
//! index; any hit: whether one exists), each lane's answer is the single-ray walk's, bit for bit
//! (a leaf triangle is tested for all lanes at once by `triangle::intersect_triangle_lanes`,
//! the same operations as the one-ray test, and its hits offered to each lane's query).
//! A lane that an any-hit packet hands to the single-ray walk (`SOLO`) gets that walk's
//! answer over the node's subtree, with the same query.
//! Every loop is bounded by the node count (a packet enters each node at most once).
use super::{grid_axis, widened, Bvh, BvhNode, SlotBits, BVH_WIDTH, MAX_BVH_DEPTH, META_EMPTY};
use crate::math::{fma, max_num, min_num, LaneMask};
use crate::query::Query;
use crate::ray::Ray;
use crate::stats::Stats;
use crate::triangle::{intersect_triangle_lanes, ShearedLanes, TriHit};
use core::mem::MaybeUninit;

/// Rays per work item of `bvh+packets`: the native runtime traces two items' rays as one packet
/// of eight where it can, the GPU each item's four one by one.
pub const BVH_PACKET: usize = 4;

/// Stack capacity: a node pushes at most `BVH_WIDTH` children, and the entries below a node
/// are its ancestors' siblings, so a tree of depth `MAX_BVH_DEPTH` never needs more.
const STACK: usize = BVH_WIDTH * MAX_BVH_DEPTH;

/// Any-hit packets enter a node that at most this many of their lanes reach with those lanes
/// one by one (`traverse_from`: the single-ray walk through the node's subtree), as Embree's
/// hybrid traversal does: a packet's node test costs about what eight single-ray ones do,
/// whatever its lanes. Shadow rays toward points of area lights scatter (natively, 2 cores:
/// the conference room's 7–10 % faster); closest-hit packets, whose coherent lanes seldom part,
/// ran 3–6 % slower with it and do not switch (`docs/benchmarks/2026-12-06-cpu-packet-levers`).
pub const SOLO: u32 = 1;

/// Traverses `rays` together for `q` (lane l's query answers ray l) and returns `true`, or
/// returns `false`, having tested nothing, for a packet whose valid rays' origins lie apart
/// (more than a sixteenth of the scene's largest extent from the first's along an axis:
/// scattered rays gain nothing from going together) or with a valid ray that is not
/// `BoxRay::tame`: the caller then traverses the rays one by one. Invalid rays
/// (`Ray::is_valid`) are misses.
#[inline(always)]
pub fn traverse_packet<Q: Query, S: Stats, const W: usize>(bvh: &Bvh, rays: &[Ray; W], q: &mut [Q; W], stats: &mut S) -> bool {
    // Lane masks are u32.
    const { assert!(W <= 32) };
    if bvh.nodes.is_empty() {
        return true;
    }
    // Each valid lane's sheared ray (`sheared.origin` holds the origins), direction and t_min,
    // side by side (invalid lanes: direction 1, origin 0, so the loops below compute nothing
    // infinite for them).
    let (sheared, active) = ShearedLanes::of(rays);
    let mut dir = [[1.0f32; W]; 3];
    let mut t_min = [0.0f32; W];
    let mut l = 0;
    while l < W {
        let valid = active & (1 << l) != 0;
        let mut a = 0;
        while a < 3 {
            dir[a][l] = if valid { rays[l].dir[a] } else { 1.0 };
            a += 1;
        }
        t_min[l] = if valid { rays[l].t_min } else { 0.0 };
        l += 1;
    }
    if active == 0 {
        return true;
    }
    let org = &sheared.origin;
    let first = active.trailing_zeros() as usize;
    // Per lane (vector instructions natively, as every loop over the lanes): the reciprocals,
    // then whether the lane goes with the first valid one: its origin near the first's, within
    // a sixteenth of the scene's largest extent along every axis (the root's grid spans the
    // scene: 255 steps per axis), and the lane `BoxRay::tame` (its sum as there; the fast
    // child test needs it).
    let root = bvh.nodes.get(0);
    let (ro, st) = (root.origin(), root.steps());
    let near_origin = max_num(max_num(st[0], st[1]), st[2]) * (255.0 / 16.0);
    let mut inv = [[0.0f32; W]; 3];
    let mut inv_dmax = [0.0f32; W];
    let mut l = 0;
    while l < W {
        let mut a = 0;
        while a < 3 {
            inv[a][l] = 1.0 / dir[a][l];
            a += 1;
        }
        inv_dmax[l] = 1.0 / max_num(max_num(dir[0][l].abs(), dir[1][l].abs()), dir[2][l].abs());
        l += 1;
    }
    let neg = [(inv[0][first] < 0.0) as u32, (inv[1][first] < 0.0) as u32, (inv[2][first] < 0.0) as u32];
    let mut goes = LaneMask::<W>::new();
    let mut l = 0;
    while l < W {
        let mut near = true;
        let mut a = 0;
        while a < 3 {
            near &= (org[a][l] - org[a][first]).abs() <= near_origin;
            a += 1;
        }
        // `BoxRay::tame`'s sum, in its order, written out over the lanes' arrays (a shared
        // function called with each lane's values gathered ran the bunny's primary rays at
        // 21.8–21.9 Mrays/s against 22.4–22.5, one thread). An infinite reciprocal makes it
        // infinite, never NaN: the first factor is positive.
        let mut reach = 0.0f32;
        let mut a = 0;
        while a < 3 {
            reach += fma(1024.0, st[a], (ro[a] - org[a][l]).abs()) * inv[a][l].abs();
            a += 1;
        }
        goes.put(l, near && reach < f32::MAX / 8.0);
        l += 1;
    }
    if goes.bits() & active != active {
        return false;
    }
    // Per axis, the lanes whose direction is negative (all bits set) and the others (none).
    let mut neg_lanes = [[0u32; W]; 3];
    let mut l = 0;
    while l < W {
        let mut a = 0;
        while a < 3 {
            neg_lanes[a][l] = ((inv[a][l] < 0.0) as u32).wrapping_neg();
            a += 1;
        }
        l += 1;
    }
    let octant = neg[0] << 2 | neg[1] << 1 | neg[2];
    let n_nodes = bvh.nodes.len() as u32;
    let n_tris = bvh.tris.len() as u32;
    let oct_inv = 7 - octant;
    // Pending nodes: index and the lanes whose intervals overlapped its box. Not initialised
    // (2 KiB a packet otherwise): entries below `sp` are written before read.
    let mut stack = [MaybeUninit::<[u32; 2]>::uninit(); STACK];
    let mut sp = 0usize;
    let mut entry = [0u32, active];
    // Each lane's query bound and whether it is still open, as the queries say: read once here
    // and again only after a lane's query changed (an accepted hit, a subtree walked alone).
    let mut bound = [0.0f32; W];
    let mut open = 0u32;
    let mut l = 0;
    while l < W {
        bound[l] = q[l].bound();
        if active & (1 << l) != 0 && q[l].open() {
            open |= 1 << l;
        }
        l += 1;
    }
    // Every step enters at most one node, and a packet enters each node at most once.
    let max_steps = n_nodes.min(u32::MAX - 1) + 1;
    let mut steps = 0u32;
    while steps < max_steps {
        steps += 1;
        // The entry's lanes whose queries are still open.
        let mut mask = entry[1] & open;
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
                bound[l] = q[l].bound();
                if !q[l].open() {
                    open &= !(1 << l);
                }
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
                let (a, b) = widened(t_min[l], bound[l], &node, inv_dmax[l]);
                t0[l] = a;
                t1[l] = b;
                l += 1;
            }
            let bits = SlotBits::new(&node, oct_inv);
            // Lanes per slot, in the octant's visiting order (j = slot ^ oct_inv; highest first).
            let lanes = fast_lanes(&node, &sheared.origin, &inv, &neg_lanes, &t0, &t1, oct_inv, mask);
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
                            let lanes = m & open;
                            let mut c = lanes;
                            while c != 0 {
                                c &= c - 1;
                                stats.tri();
                            }
                            let (mut t, mut b1, mut b2) = ([0.0f32; W], [0.0f32; W], [0.0f32; W]);
                            let mut hit = lanes & intersect_triangle_lanes(&sheared, tri.v0, tri.v1, tri.v2, &t_min, &bound, &mut t, &mut b1, &mut b2);
                            while hit != 0 {
                                let l = hit.trailing_zeros() as usize;
                                hit &= hit - 1;
                                q[l].accept(tri._pad, TriHit { t: t[l], b1: b1[l], b2: b2[l] });
                                bound[l] = q[l].bound();
                                if !q[l].open() {
                                    open &= !(1 << l);
                                }
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
        if sp == 0 || open == 0 {
            steps = max_steps;
        } else if steps < max_steps {
            sp -= 1;
            // SAFETY: entry sp < the pushes' count was written by the push that made it.
            entry = unsafe { stack[sp].assume_init() };
        }
    }
    true
}

/// The lanes of `mask` whose intervals [`t0`, `t1`] may meet each child box of `node`, per slot
/// in the visiting order (entry j: slot `j ^ oct_inv`; 0 for an empty slot), by the single-ray
/// walk's fast test: each lane's `Grid` (`grid_axis`), then per slot `fast_children`'s
/// multiply-adds, minima, maxima and comparison in its order, each lane's near and far planes
/// picked by its own signs (`neg`, per axis: all bits set where the direction is negative). For
/// lanes that are `BoxRay::tame` each lane's bits are `fast_children`'s for its ray, so no box
/// its exact interval meets is culled (the parent module's rules; a test checks the two agree).
/// Against the exact slab test this walk used before: six multiply-adds and six bit selects per
/// slot and lane instead of six subtractions, six products, six minima and maxima and the far
/// plane's widening (natively, 2 cores, with the changes made beside it:
/// `docs/benchmarks/2026-12-06-cpu-packet-grid/`).
#[inline(always)]
fn fast_lanes<const W: usize>(node: &BvhNode, o: &[[f32; W]; 3], inv: &[[f32; W]; 3], neg: &[[u32; W]; 3], t0: &[f32; W], t1: &[f32; W], oct_inv: u32, mask: u32) -> [u32; BVH_WIDTH] {
    let go = node.origin();
    let st = node.steps();
    let mut scale = [[0.0f32; W]; 3];
    let mut gn = [[0.0f32; W]; 3];
    let mut gf = [[0.0f32; W]; 3];
    let mut a = 0;
    while a < 3 {
        let mut l = 0;
        while l < W {
            (scale[a][l], gn[a][l], gf[a][l]) = grid_axis(go[a], st[a], o[a][l], inv[a][l]);
            l += 1;
        }
        a += 1;
    }
    let q = node.quantised_boxes();
    let (lx, ly, lz, hx, hy, hz) = (&q[0], &q[1], &q[2], &q[3], &q[4], &q[5]);
    let mut lanes = [0u32; BVH_WIDTH];
    let mut j = 0u32;
    while j < BVH_WIDTH as u32 {
        let s = (j ^ oct_inv) as usize;
        {
            let mut m = LaneMask::<W>::new();
            let mut l = 0;
            while l < W {
                // Per axis the near and far planes' bytes: the upper ones where the lane's
                // direction is negative (a select of bits, which vectorises).
                let pick = |m: u32, a: f32, b: f32| f32::from_bits((b.to_bits() & m) | (a.to_bits() & !m));
                let (nx, fx) = (pick(neg[0][l], lx[s], hx[s]), pick(neg[0][l], hx[s], lx[s]));
                let (ny, fy) = (pick(neg[1][l], ly[s], hy[s]), pick(neg[1][l], hy[s], ly[s]));
                let (nz, fz) = (pick(neg[2][l], lz[s], hz[s]), pick(neg[2][l], hz[s], lz[s]));
                // `fast_children`'s operations, in its order. No NaN: every distance finite
                // (`BoxRay::tame`), t0 and t1 not NaN.
                let near = max_num(max_num(fma(nx, scale[0][l], gn[0][l]), fma(ny, scale[1][l], gn[1][l])), max_num(fma(nz, scale[2][l], gn[2][l]), t0[l]));
                let far = min_num(min_num(fma(fx, scale[0][l], gf[0][l]), fma(fy, scale[1][l], gf[1][l])), min_num(fma(fz, scale[2][l], gf[2][l]), t1[l]));
                m.put(l, near <= far);
                l += 1;
            }
            // An empty slot's bytes mean nothing: no lanes.
            lanes[j as usize] = if node.meta(s as u32) != META_EMPTY { m.bits() & mask } else { 0 };
        }
        j += 1;
    }
    lanes
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

#[cfg(test)]
mod tests {
    use super::super::{fast_children, BoxRay};
    use super::*;
    use crate::rng::Rng;
    use glam::UVec4;

    /// `fast_lanes` gives every lane `fast_children`'s bits for its own ray, bit for bit: random
    /// grids and boxes (any bytes, empty slots among them), eight rays a packet in any mix of
    /// octants (each lane's own planes), intervals per lane that end inside the boxes, at
    /// infinity, or equal the planes' distances.
    #[test]
    fn lanes_take_the_single_ray_fast_test() {
        let mut rng = Rng::new(5, 0);
        let f = |rng: &mut Rng, s: f32| (rng.next_f32() * 2.0 - 1.0) * s;
        let (mut met, mut tested) = (0u32, 0u32);
        for i in 0..20_000u32 {
            let exps = (118 + rng.next_u32() % 6) | (118 + rng.next_u32() % 6) << 8 | (118 + rng.next_u32() % 6) << 16;
            // Slot s: a leaf of one triangle at offset s (its own hit bit), or empty.
            let mut meta = [0u32; 2];
            for s in 0..8 {
                if rng.next_u32() % 5 != 0 {
                    meta[s / 4] |= (0x20 | s as u32) << (8 * (s % 4));
                }
            }
            // Upper bytes at or above the lower ones, but in every fourth node any bytes (inverted
            // boxes among them).
            let lo: [u32; 6] = core::array::from_fn(|_| rng.next_u32() & 0x7f7f_7f7f);
            let hi: [u32; 6] = core::array::from_fn(|k| if i % 4 == 0 { rng.next_u32() } else { lo[k] + (rng.next_u32() & 0x7f7f_7f7f) });
            let node = BvhNode {
                origin_exp: UVec4::new(f(&mut rng, 8.0).to_bits(), f(&mut rng, 8.0).to_bits(), f(&mut rng, 8.0).to_bits(), exps),
                bases_meta: UVec4::new(0, 0, meta[0], meta[1]),
                lo_x_y: UVec4::new(lo[0], lo[1], lo[2], lo[3]),
                lo_z_hi_x: UVec4::new(lo[4], lo[5], hi[0], hi[1]),
                hi_y_z: UVec4::new(hi[2], hi[3], hi[4], hi[5]),
            };
            let mut org = [[0.0f32; 8]; 3];
            let mut inv = [[0.0f32; 8]; 3];
            let mut neg = [[0u32; 8]; 3];
            let (mut t0, mut t1) = ([0.0f32; 8], [0.0f32; 8]);
            let mut rays = [BoxRay::new(&Ray::default()); 8];
            let mut tame = true;
            for l in 0..8 {
                let origin = [f(&mut rng, 16.0), f(&mut rng, 16.0), f(&mut rng, 16.0)];
                // Towards a random point of slot l's box (as stored, whether empty or not).
                let (bl, bh) = node.child_box(l as u32);
                let d: [f32; 3] = core::array::from_fn(|a| bl[a] + (bh[a] - bl[a]) * rng.next_f32() - origin[a]);
                let r = BoxRay::new(&Ray::new(origin, d, 0.0, f32::INFINITY));
                tame &= r.tame(&node);
                for a in 0..3 {
                    org[a][l] = origin[a];
                    inv[a][l] = r.inv[a];
                    neg[a][l] = r.neg[a].wrapping_neg();
                }
                t0[l] = if (i + l as u32) % 7 == 0 { 0.0 } else { f(&mut rng, 1.0) };
                t1[l] = if (i + l as u32) % 4 == 0 { f32::INFINITY } else { t0[l] + rng.next_f32() * 2.0 };
                rays[l] = r;
            }
            if !tame {
                continue;
            }
            // Visited in the first lane's order, whatever the others' octants.
            let oct_inv = rays[0].oct_inv;
            let lanes = fast_lanes(&node, &org, &inv, &neg, &t0, &t1, oct_inv, 0xff);
            for l in 0..8 {
                let one = fast_children(&node, &rays[l], t0[l], t1[l]);
                for s in 0..8u32 {
                    let bit = lanes[(s ^ oct_inv) as usize] >> l & 1;
                    assert_eq!(bit, one >> s & 1, "case {i}, lane {l}, slot {s}");
                    tested += 1;
                    met += bit;
                }
            }
        }
        // Both outcomes, many times.
        assert!(met > tested / 10 && met < tested * 9 / 10, "{met} of {tested}");
    }
}
