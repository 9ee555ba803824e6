//! Result rows and how they are written: one CSV line and one Markdown table row each, under a
//! header naming the date, machine and device.
use super::{machine, today, ORACLE_SAMPLE};
use anyhow::{Context, Result};
use std::fmt::Write as _;
use std::path::Path;

/// One measured configuration.
#[derive(Clone, Debug)]
pub struct Row {
    pub scene: String,
    pub triangles: usize,
    /// Image width and height of the ray batch.
    pub resolution: u32,
    pub ray_type: String,
    pub rays: usize,
    /// Traversal and options (`shortstack:3+packets`, `decomposed:16`, …).
    pub method: String,
    /// From GPU timestamps (None on the CPU or without timestamp queries).
    pub mrays_gpu: Option<f64>,
    /// From submit to completion (GPU) or the call's wall time (CPU).
    pub mrays_wall: f64,
    pub nodes: f64,
    pub leaves: f64,
    pub tris: f64,
    pub restarts: f64,
    /// Node visits relative to the full stack on the same rays, where measured.
    pub vs_stack: Option<f64>,
    pub oracle_mismatch: f64,
    pub reference_mismatch: f64,
    /// Decomposed pipeline: rays whose leaf list overflowed before the answer was settled.
    pub fallbacks: Option<usize>,
    pub notes: String,
}

impl Row {
    /// Mrays/s from GPU time where there is one, else from wall time.
    pub fn mrays(&self) -> f64 {
        self.mrays_gpu.unwrap_or(self.mrays_wall)
    }
}

/// `v` with `p` digits after the point (in exponent form with `exp`), `none` where it was not
/// measured (NaN: a peer's counts and oracle check).
fn num(v: f64, p: usize, exp: bool, none: &str) -> String {
    match (v.is_nan(), exp) {
        (true, _) => none.to_string(),
        (false, true) => format!("{v:.p$e}"),
        (false, false) => format!("{v:.p$}"),
    }
}

fn opt(v: Option<f64>, p: usize) -> String {
    v.map(|x| format!("{x:.p$}")).unwrap_or_default()
}

/// Writes `name.csv` (every row) and `name.md` (`title`, the header, `summary` Markdown, then
/// every row) into `dir`.
pub fn write_rows(dir: &Path, name: &str, title: &str, device: &str, summary: &str, rows: &[Row]) -> Result<()> {
    let date = today();
    let machine = machine();
    let mut csv = String::from(
        "date,machine,device,scene,triangles,resolution,ray_type,rays,method,mrays_s_gpu_timestamps,mrays_s_wall,nodes_per_ray,leaves_per_ray,tris_per_ray,restarts_per_ray,node_visits_vs_stack,oracle_mismatch_rate,reference_mismatch_rate,notes\n",
    );
    for r in rows {
        writeln!(
            csv,
            "{date},{},{},{},{},{},{},{},{},{},{:.3},{},{},{},{},{},{},{},{}",
            csv_cell(&machine),
            csv_cell(device),
            csv_cell(&r.scene),
            r.triangles,
            r.resolution,
            csv_cell(&r.ray_type),
            r.rays,
            csv_cell(&r.method),
            opt(r.mrays_gpu, 3),
            r.mrays_wall,
            num(r.nodes, 3, false, ""),
            num(r.leaves, 3, false, ""),
            num(r.tris, 3, false, ""),
            num(r.restarts, 4, false, ""),
            opt(r.vs_stack, 4),
            num(r.oracle_mismatch, 3, true, ""),
            num(r.reference_mismatch, 3, true, ""),
            csv_cell(&r.notes)
        )?;
    }
    let mut md = format!(
        "# {title}\n\nDate {date}; machine {machine}; device {device}.\n\n\
         Mrays/s: median of the timed repetitions after a warm-up, from GPU timestamps where the adapter has them, and wall time (submit to completion) always. \
         Counts per ray come from a separate native counting run (a packet's node visits count once for its rays: four for the kd-tree's, eight for the BVH's; rays that leave or skip the packet, one by one). \
         Oracle mismatch: fraction of {ORACLE_SAMPLE} sampled rays whose answer differs from the brute-force oracle; vs reference: fraction of all rays whose answer differs from the native full-stack traversal.\n\n\
         {summary}\n## All rows\n\n\
         | scene | tris | res | ray type | rays | method | Mrays/s (GPU time) | Mrays/s (wall) | nodes/ray | vs stack | leaves/ray | tris/ray | restarts/ray | oracle mismatch | vs reference | notes |\n\
         |---|---:|---:|---|---:|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---|\n"
    );
    for r in rows {
        writeln!(
            md,
            "| {} | {} | {}² | {} | {} | {} | {} | {:.1} | {} | {} | {} | {} | {} | {} | {} | {} |",
            r.scene,
            r.triangles,
            r.resolution,
            r.ray_type,
            r.rays,
            r.method,
            opt(r.mrays_gpu, 1),
            r.mrays_wall,
            num(r.nodes, 1, false, "–"),
            r.vs_stack.map(|v| format!("{:+.1} %", 100.0 * v)).unwrap_or_else(|| "–".into()),
            num(r.leaves, 2, false, "–"),
            num(r.tris, 2, false, "–"),
            num(r.restarts, 2, false, "–"),
            num(r.oracle_mismatch, 2, true, "–"),
            num(r.reference_mismatch, 2, true, "–"),
            r.notes
        )?;
    }
    save(dir, name, &csv, &md)
}

/// A CSV cell: quoted when it holds a comma or a quote (quotes inside become apostrophes).
fn csv_cell(c: &str) -> String {
    if c.contains(',') || c.contains('"') {
        format!("\"{}\"", c.replace('"', "'"))
    } else {
        c.to_string()
    }
}

/// Writes `dir/name.csv` and `dir/name.md`, creating `dir`.
fn save(dir: &Path, name: &str, csv: &str, md: &str) -> Result<()> {
    std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
    let base = dir.join(name);
    for (ext, text) in [("csv", csv), ("md", md)] {
        let path = base.with_extension(ext);
        kdray::files::write(&path, text)?;
    }
    Ok(())
}

/// A Markdown table from a header and rows of cells.
pub fn markdown(header: &[String], rows: &[Vec<String>]) -> String {
    let mut s = format!("| {} |\n|{}\n", header.join(" | "), "---|".repeat(header.len()));
    for r in rows {
        let _ = writeln!(s, "| {} |", r.join(" | "));
    }
    s
}

/// Writes `name.csv` and `name.md` from string cells (date, machine and device columns
/// added in front of the CSV), for suites whose rows are not timed ray batches; `summary`
/// (Markdown) goes before the table of all rows.
pub fn write_cells(dir: &Path, name: &str, title: &str, device: &str, summary: &str, header: &[String], rows: &[Vec<String>]) -> Result<()> {
    let date = today();
    let machine = machine();
    let mut csv = format!("date,machine,device,{}\n", header.iter().map(|h| csv_cell(h)).collect::<Vec<_>>().join(","));
    for r in rows {
        writeln!(csv, "{date},{},{},{}", csv_cell(&machine), csv_cell(device), r.iter().map(|c| csv_cell(c)).collect::<Vec<_>>().join(","))?;
    }
    let rows_heading = if summary.is_empty() { "" } else { "## All rows\n\n" };
    let md = format!("# {title}\n\nDate {date}; machine {machine}; device {device}.\n\n{summary}{rows_heading}{}", markdown(header, rows));
    save(dir, name, &csv, &md)
}
