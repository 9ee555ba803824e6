//! Native measurements of the traversals (not passes: they inspect what a traversal does):
//! node / leaf / triangle counts per ray, how many packets are coherent, how many rays the
//! decomposed pipeline must finish with its fallback. Used by the benchmarks and tests.
use crate::accel::{Accel, Grouping, Pipeline, Structure};
use crate::kdtree::KdTreeData;
use crate::error::Result;
use kdray_shared::brute::BruteForce;
use kdray_shared::kdtree::{self, KdTree, PACKET};
use kdray_shared::query::{AnyHit, Closest, Query};
use kdray_shared::stats::{Counters, NoStats, Stats};
use kdray_shared::parts::Parts;
use kdray_shared::{Ray, Triangle};
use rayon::prelude::*;

/// Up to `PACKET` rays padded with invalid ones.
fn group(rays: &[Ray]) -> [Ray; PACKET] {
    let mut g = [Ray::default(); PACKET];
    g[..rays.len()].copy_from_slice(rays);
    g
}

/// Answers `Q` for four rays with `accel`, counting into `stats`.
fn trace4<Q: Query + BruteForce, S: Stats>(tree: &KdTree, accel: Accel, rays: &[Ray; PACKET], stats: &mut S) -> [Q; PACKET] {
    let mut q = rays.each_ref().map(Q::new);
    match (accel.structure, accel.grouping, accel.pipeline) {
        (Structure::Brute, _, _) => q.iter_mut().zip(rays).for_each(|(q, r)| q.brute(r, &tree.tris)),
        (Structure::Bvh, _, _) => unreachable!("`counts` refuses the BVH"),
        (_, _, Pipeline::Decomposed { capacity }) => {
            for (q, r) in q.iter_mut().zip(rays) {
                let l = kdtree::record_leaves(tree, r, capacity, stats);
                if !kdtree::intersect_leaves(&tree.prims(), r, &l.entries, 0, l.status(), q, stats) {
                    *q = Q::new(r);
                    kdtree::run(kdtree::Algorithm::Stack, tree, r, q, stats);
                }
            }
        }
        (_, Grouping::Single, _) => q.iter_mut().zip(rays).for_each(|(q, r)| kdtree::run(accel.traversal, tree, r, q, stats)),
        (_, Grouping::Packet4, _) => {
            kdtree::run_packet(accel.traversal, tree, rays, &mut q, stats);
        }
    }
    q
}

/// Traversal counters of `accel` (closest hit if `closest`, else any hit), one per group of
/// four rays in order: a packet's node and leaf visits are counted once for its four rays.
pub fn counts(tris: &[Triangle], tree: &KdTreeData, accel: Accel, rays: &[Ray], closest: bool) -> Result<Vec<Counters>> {
    if accel.needs_bvh() {
        crate::error::bail!(InvalidInput: "the BVH's counts come from `bvh_counts`");
    }
    let t = tree.view(tris);
    Ok(rays
        .par_chunks(PACKET)
        .map(|c| {
            let mut s = Counters::default();
            let g = group(c);
            if closest {
                trace4::<Closest, _>(&t, accel, &g, &mut s);
            } else {
                trace4::<AnyHit, _>(&t, accel, &g, &mut s);
            }
            s
        })
        .collect())
}

/// Traversal counters of the wide BVH (closest hit if `closest`, else any hit), one per group
/// of four rays in order (summed over the four), like `counts`. With `packets`, as the native
/// runtime runs `bvh+packets`: eight rays per packet, whose node and leaf visits count once for
/// the eight (in the first of its two groups; the second gets zeros). Rays that go alone (a
/// declined packet's, an any-hit lane's `bvh::packet::SOLO` walk) count per ray, and the
/// single-ray walk counts one leaf visit per node whose leaf slots it enters (the packet walk:
/// one per slot), so triangles per ray compare across the two, leaves less so.
pub fn bvh_counts(bvh: &crate::bvh::BvhData, rays: &[Ray], closest: bool, packets: bool) -> Vec<Counters> {
    let b = kdray_shared::bvh::Bvh { nodes: Parts::one(&bvh.nodes), tris: Parts::one(kdray_shared::bvh::TriWords::cast(&bvh.tris)) };
    fn packet<Q: Query>(b: &kdray_shared::bvh::Bvh, c: &[Ray], s: &mut Counters) {
        let mut r = [Ray::default(); 2 * PACKET];
        r[..c.len()].copy_from_slice(c);
        kdray_shared::bvh::packet_or_single(b, &r, &mut r.map(|r| Q::new(&r)), s);
    }
    if packets {
        return rays
            .par_chunks(2 * PACKET)
            .flat_map_iter(|c| {
                let mut s = Counters::default();
                if closest {
                    packet::<Closest>(&b, c, &mut s);
                } else {
                    packet::<AnyHit>(&b, c, &mut s);
                }
                [s, Counters::default()].into_iter().take(c.len().div_ceil(PACKET))
            })
            .collect();
    }
    rays.par_chunks(PACKET)
        .map(|c| {
            let mut s = Counters::default();
            for r in c {
                if closest {
                    kdray_shared::bvh::traverse(&b, r, &mut Closest::new(r), &mut s);
                } else {
                    kdray_shared::bvh::traverse(&b, r, &mut AnyHit::new(r), &mut s);
                }
            }
            s
        })
        .collect()
}

/// How many rays the decomposed pipeline with `capacity` leaves per list must finish with
/// the fallback traversal (their list overflowed before the query was settled).
pub fn decomposed_fallbacks(tris: &[Triangle], tree: &KdTreeData, rays: &[Ray], capacity: u32, closest: bool) -> usize {
    let tree = tree.view(tris);
    rays.par_iter()
        .filter(|r| {
            let l = kdtree::record_leaves(&tree, r, capacity, &mut NoStats);
            if closest {
                !kdtree::intersect_leaves(&tree.prims(), r, &l.entries, 0, l.status(), &mut Closest::new(r), &mut NoStats)
            } else {
                !kdtree::intersect_leaves(&tree.prims(), r, &l.entries, 0, l.status(), &mut AnyHit::new(r), &mut NoStats)
            }
        })
        .count()
}

/// How many of the groups of four rays the packet traversal takes together (the others go
/// ray by ray because their direction signs differ).
pub fn coherent_packets(rays: &[Ray]) -> usize {
    rays.par_chunks(PACKET).filter(|c| kdtree::direction_signs(&group(c)).is_some()).count()
}
