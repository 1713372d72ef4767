//! The fuzz corpus replayed under `cargo test`: every file in
//! `fuzz/seeds/<target>/` (valid and near-valid inputs the fuzzer starts
//! from) and `fuzz/regressions/<target>/` (inputs that once made a target
//! panic, abort, hang or allocate without bound) goes through the same
//! harness function as the fuzzer (`fuzz/harness.rs`). A panic fails the
//! test, naming the file. `scripts/fuzz.sh` runs the fuzzers themselves.

use std::path::{Path, PathBuf};

#[path = "../fuzz/harness.rs"]
mod harness;

fn fuzz_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("fuzz")
}

/// The files of `fuzz/<kind>/<target>/`, sorted (none when the folder is absent).
fn inputs(kind: &str, target: &str) -> Vec<PathBuf> {
    let dir = fuzz_dir().join(kind).join(target);
    let mut files: Vec<PathBuf> = std::fs::read_dir(&dir)
        .map(|rd| {
            rd.filter_map(|e| e.ok().map(|e| e.path()))
                .filter(|p| p.is_file())
                .collect()
        })
        .unwrap_or_default();
    files.sort();
    files
}

fn replay(kind: &str) -> usize {
    let mut count = 0;
    let mut failures = Vec::new();
    for &(target, run) in harness::TARGETS {
        for path in inputs(kind, target) {
            let data = std::fs::read(&path).expect("corpus file");
            count += 1;
            if let Err(e) = std::panic::catch_unwind(|| run(&data)) {
                let msg = e
                    .downcast_ref::<String>()
                    .cloned()
                    .or_else(|| e.downcast_ref::<&str>().map(|s| (*s).to_string()))
                    .unwrap_or_default();
                failures.push(format!("{target}: {}: {msg}", path.display()));
            }
        }
    }
    assert!(
        failures.is_empty(),
        "{} corpus inputs panic:\n{}",
        failures.len(),
        failures.join("\n")
    );
    count
}

#[test]
fn seed_corpus_replays_without_panics() {
    let n = replay("seeds");
    eprintln!("replayed {n} seed inputs");
    // Every target has seeds: a folder renamed or emptied would otherwise
    // make this test pass on nothing.
    for &(target, _) in harness::TARGETS {
        assert!(
            !inputs("seeds", target).is_empty(),
            "fuzz/seeds/{target}/ has no inputs"
        );
    }
}

#[test]
fn regression_corpus_replays_without_panics() {
    let n = replay("regressions");
    eprintln!("replayed {n} regression inputs");
}
