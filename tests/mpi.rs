//! `kdray render --mpi` under `mpirun` (feature `mpi`; Open MPI from scripts/setup.sh --mpi):
//! one photon render over 2 and 3 ranks — one of them with no unit of passes — writes the same
//! image, bit for bit, as one process rendering every unit; and a rank that cannot open its
//! device takes part with its error, rank 0 writing the image of the others' units and
//! exiting non-zero.
use std::path::{Path, PathBuf};
use std::process::Command;

fn kdray() -> Command {
    Command::new(env!("CARGO_BIN_EXE_kdray"))
}

/// `mpirun -n N` (as root too: CI runs so) of the kdray binary.
fn mpirun(n: u32) -> Command {
    let mut c = Command::new("mpirun");
    c.env("OMPI_ALLOW_RUN_AS_ROOT", "1").env("OMPI_ALLOW_RUN_AS_ROOT_CONFIRM", "1");
    c.args(["--oversubscribe", "-n", &n.to_string(), env!("CARGO_BIN_EXE_kdray")]);
    c
}

const RENDER: &[&str] = &["render", "--device", "cpu", "--scene", "cornell", "--size", "48", "--passes", "10", "--photons", "4096"];

fn dir() -> PathBuf {
    let d = Path::new(env!("CARGO_TARGET_TMPDIR")).join("mpi");
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn run(mut c: Command, out: &Path, extra: &[&str]) -> (bool, String) {
    let o = c.args(RENDER).args(extra).arg("--out").arg(out).output().expect("mpirun runs (Open MPI: scripts/setup.sh --mpi)");
    (o.status.success(), format!("{}{}", String::from_utf8_lossy(&o.stdout), String::from_utf8_lossy(&o.stderr)))
}

#[test]
fn an_mpi_render_is_the_one_process_render() {
    let d = dir();
    let (ok, log) = run(kdray(), &d.join("one.png"), &[]);
    assert!(ok, "{log}");
    let one = std::fs::read(d.join("one.pfm")).unwrap();
    // 10 passes are three units of four: with 3 ranks each renders one, with 2 rank 0 two.
    for n in [2, 3] {
        let out = d.join(format!("ranks{n}.png"));
        let (ok, log) = run(mpirun(n), &out, &["--mpi"]);
        assert!(ok, "{n} ranks: {log}");
        assert_eq!(log.matches("photon mapping:").count(), 1, "rank 0 alone reports: {log}");
        // Every unit once: ranks that each rendered every unit would give the same radiance
        // (sums and sample counts doubled alike), not the same count.
        assert!(log.contains("photon mapping: 10 passes"), "{n} ranks: {log}");
        assert!(std::fs::read(out.with_extension("pfm")).unwrap() == one, "{n} ranks: the image differs from one process's");
    }
}

/// Rank 1 cannot open its device (adapter 99 of a machine that has fewer): it says so and
/// takes part with nothing; rank 0 writes the image of its own units, says which rank failed
/// and exits non-zero.
#[test]
fn a_rank_that_fails_leaves_the_other_ranks_units() {
    let d = dir();
    let out = d.join("failed-rank.png");
    // A wrapper gives rank 1 a device that does not exist (Open MPI names each process's rank
    // in OMPI_COMM_WORLD_RANK).
    let script = d.join("rank.sh");
    std::fs::write(&script, format!("#!/bin/sh\nif [ \"$OMPI_COMM_WORLD_RANK\" = 1 ]; then exec {} \"$@\" --devices 99; else exec {} \"$@\" --devices cpu; fi\n", env!("CARGO_BIN_EXE_kdray"), env!("CARGO_BIN_EXE_kdray"))).unwrap();
    let mut c = Command::new("mpirun");
    c.env("OMPI_ALLOW_RUN_AS_ROOT", "1").env("OMPI_ALLOW_RUN_AS_ROOT_CONFIRM", "1");
    c.args(["--oversubscribe", "-n", "2", "sh"]).arg(&script);
    let args: Vec<&str> = RENDER.iter().copied().filter(|a| *a != "--device" && *a != "cpu").collect();
    let o = c.args(&args).arg("--mpi").arg("--out").arg(&out).output().unwrap();
    let log = format!("{}{}", String::from_utf8_lossy(&o.stdout), String::from_utf8_lossy(&o.stderr));
    assert!(!o.status.success(), "{log}");
    assert!(log.contains("rank 1") && log.contains("adapter 99"), "{log}");
    // Rank 0 rendered units 0 and 2 (passes 0–3 and 8–9): 6 of the 10.
    assert!(log.contains("photon mapping: 6 passes"), "{log}");
    assert!(out.with_extension("pfm").exists(), "rank 0 wrote the image of its units: {log}");
}
