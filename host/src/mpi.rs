//! One photon render over the ranks of an MPI job (feature `mpi`; Open MPI or any MPI the
//! `mpi` crate builds against): rank r renders unit r of the render's units of passes, then
//! every `size`-th (`share::Part`), on its own devices (shared among them as on one machine),
//! and the ranks' exact film sums are added up a binary tree to rank 0 (log₂ size steps of
//! point-to-point messages), which writes the image. The sums are exact (`share::FilmSum`),
//! so the image is the same, bit for bit, as one process's render of every unit on devices of
//! the kind — whatever the number of ranks.
//!
//! A rank whose devices all fail (or that cannot open one) still takes part, with nothing
//! rendered and its error; rank 0's image then lacks that rank's units and says so
//! (`PhotonStats::interrupted`). A rank that dies (killed, crashed) ends the job: plain MPI
//! has no way for the others to go on (that needs ULFM's fault-tolerant communicators).
use crate::error::{bail, err, Result};
use crate::integrator::photon::{ray_camera, PhotonOptions, PhotonPart, PhotonStats};
use crate::integrator::share::{FilmSum, Part};
use kdray_shared::{Camera, Hit};
use mpi::traits::*;

/// The MPI environment of this process (initialised once; finalised when dropped).
pub struct Job {
    universe: mpi::environment::Universe,
}

impl Job {
    /// Initialises MPI (only the calling thread makes MPI calls). Outside `mpirun` the process
    /// is a job of one rank.
    pub fn init() -> Result<Job> {
        let (universe, _) = mpi::initialize_with_threading(mpi::Threading::Funneled).ok_or_else(|| err!(InvalidInput: "MPI was already initialised in this process"))?;
        Ok(Job { universe })
    }

    /// This process's rank.
    pub fn rank(&self) -> u32 {
        self.universe.world().rank() as u32
    }

    /// The ranks of the job.
    pub fn size(&self) -> u32 {
        self.universe.world().size() as u32
    }

    /// This rank's units of a render (`share::Part`).
    pub fn part(&self) -> Part {
        Part { rank: self.rank(), ranks: self.size() }
    }

    /// Adds every rank's part of a photon render up to rank 0: `Some(whole render)` there,
    /// `None` on the others. Every rank must call it once, with its part or the error that
    /// kept it from rendering (the render's options and camera say what an empty part is).
    pub fn reduce_photons(&self, part: Result<PhotonPart>, o: &PhotonOptions, camera: &Camera) -> Result<Option<PhotonPart>> {
        let world = self.universe.world();
        let (rank, size) = (self.rank(), self.size());
        let mut part = part.unwrap_or_else(|e| {
            let n = (camera.width * camera.height) as usize;
            let stats = PhotonStats { interrupted: Some(format!("rank {rank}: {e} (its passes are not in the image)")), ..Default::default() };
            PhotonPart { sum: FilmSum::new(n), hits: None, stats, camera: ray_camera(o, camera), passes: o.passes }
        });
        let mut step = 1u32;
        while step < size {
            if rank % (2 * step) == step {
                world.process_at_rank((rank - step) as i32).send(&encode(&part)[..]);
                return Ok(None);
            }
            if rank + step < size {
                let (bytes, _) = world.process_at_rank((rank + step) as i32).receive_vec::<u8>();
                part.add(&decode(&bytes, &part)?);
            }
            step *= 2;
        }
        Ok(Some(part))
    }
}

/// A part as bytes: the sums, the counts, the hits if any, then the failures' text.
fn encode(p: &PhotonPart) -> Vec<u8> {
    let s = &p.stats;
    let mut out = Vec::new();
    let words: [u64; 9] = [
        p.sum.sum.len() as u64,
        p.sum.clamped,
        s.passes as u64,
        s.emitted,
        s.stored,
        s.last_radius.to_bits() as u64,
        s.seconds.to_bits(),
        p.hits.as_ref().map_or(u64::MAX, |h| h.len() as u64),
        s.per_device.len() as u64,
    ];
    for w in words {
        out.extend_from_slice(&w.to_le_bytes());
    }
    out.extend_from_slice(bytemuck::cast_slice(&p.sum.sum));
    if let Some(h) = &p.hits {
        out.extend_from_slice(bytemuck::cast_slice(h));
    }
    out.extend_from_slice(bytemuck::cast_slice(&s.per_device));
    let text = format!("{}\u{0}{}", s.interrupted.clone().unwrap_or_default(), s.failed.join("\u{0}"));
    out.extend_from_slice(text.as_bytes());
    out
}

/// The part `encode` wrote (of the same render as `like`).
fn decode(b: &[u8], like: &PhotonPart) -> Result<PhotonPart> {
    let word = |k: usize| -> Result<u64> { Ok(u64::from_le_bytes(b.get(8 * k..8 * k + 8).ok_or_else(|| err!(InvalidInput: "MPI: a truncated part"))?.try_into().expect("8 bytes"))) };
    let (n, clamped, passes, emitted, stored, radius, seconds, hits, devices) = (word(0)?, word(1)?, word(2)?, word(3)?, word(4)?, word(5)?, word(6)?, word(7)?, word(8)?);
    if n as usize != like.sum.sum.len() {
        bail!(InvalidInput: "MPI: a part of {n} pixels where this render has {}", like.sum.sum.len());
    }
    let mut at = 72;
    let mut take = |bytes: usize| -> Result<&[u8]> {
        let s = b.get(at..at + bytes).ok_or_else(|| err!(InvalidInput: "MPI: a truncated part"))?;
        at += bytes;
        Ok(s)
    };
    let sum: Vec<[i128; 4]> = bytemuck::pod_collect_to_vec(take(n as usize * 64)?);
    let hits = if hits == u64::MAX { None } else { Some(bytemuck::pod_collect_to_vec::<u8, Hit>(take(hits as usize * std::mem::size_of::<Hit>())?)) };
    let per_device: Vec<u32> = bytemuck::pod_collect_to_vec(take(devices as usize * 4)?);
    let text = String::from_utf8_lossy(&b[at..]).into_owned();
    let mut fields = text.split('\u{0}');
    let interrupted = fields.next().filter(|s| !s.is_empty()).map(str::to_string);
    let failed = fields.filter(|s| !s.is_empty()).map(str::to_string).collect();
    let stats = PhotonStats { passes: passes as u32, emitted, stored, last_radius: f32::from_bits(radius as u32), seconds: f64::from_bits(seconds), interrupted, failed, per_device };
    Ok(PhotonPart { sum: FilmSum { sum, clamped }, hits, stats, camera: like.camera, passes: like.passes })
}
