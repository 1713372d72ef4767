//! The brush app's strokes files, fuzzed apart from `harness.rs` because
//! they need the app's crate (eframe, wgpu). Included by
//! `fuzz/fuzz_targets/strokes.rs` and by the app's `tests/replay.rs`, which
//! replays `fuzz/regressions/strokes/` under `cargo test`.

/// `ifd-brush --replay FILE` and the app's history: the strokes JSON.
pub fn strokes(data: &[u8]) {
    let dir = std::env::temp_dir().join(format!("ifd-fuzz-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("scratch folder");
    let path = dir.join("strokes.json");
    std::fs::write(&path, data).expect("scratch write");
    if let Ok(f) = ifd_brush::strokes::StrokesFile::load(&path) {
        let back = dir.join("strokes-again.json");
        f.save(&back)
            .expect("a strokes file that loaded can be saved");
        let again = ifd_brush::strokes::StrokesFile::load(&back).expect("and loaded again");
        assert_eq!(again, f);
    }
}
