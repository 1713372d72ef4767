//! Tests that return early because an optional part of the machine is
//! missing (a Vulkan adapter, an X server) record themselves here, so that
//! they are counted as skipped, never as passed.
//!
//! libtest has no way to mark a test ignored at run time, and a test that
//! returns early reports `ok`. So each early return calls [`skip`], which
//! prints the reason and, when `IFD_SKIP_LOG` names a file (as
//! `scripts/test-all.sh` does), appends one line `test name<TAB>reason` to
//! it; the script moves those tests from the passed count to the skipped
//! count and lists them. A GPU or window test may only skip under the opt-in
//! variables `IFD_GPU_TESTS=skip` / `IFD_WINDOW_TESTS=skip`: without them it
//! fails instead. A unit test of a CPU or kernel feature (AVX-512, huge
//! pages on request) skips where the machine lacks it.
//!
//! Included by the GPU and window tests, and by unit tests in `ifd-planar`
//! and the `ifd` binary that need a CPU or kernel feature, with
//! `#[path = "../../../tests/support/skip.rs"] mod skip;`.

#![allow(dead_code, reason = "each test file uses what it needs")]

use std::io::Write;

/// Whether the opt-in variable `var` (`IFD_GPU_TESTS` or `IFD_WINDOW_TESTS`)
/// is `skip`.
pub fn allowed(var: &str) -> bool {
    std::env::var(var).is_ok_and(|v| v == "skip")
}

/// Records the current test as skipped for `reason`. The test name is the
/// thread's (libtest runs every test on a thread named after it).
pub fn skip(reason: &str) {
    let thread = std::thread::current();
    let name = thread.name().unwrap_or("unnamed test");
    let reason = reason.replace(['\n', '\t'], " ");
    eprintln!("SKIPPED {name}: {reason}");
    if let Some(path) = std::env::var_os("IFD_SKIP_LOG") {
        let line = format!("{name}\t{reason}\n");
        let written = std::fs::OpenOptions::new()
            .create(true)
            .append(true)
            .open(&path)
            .and_then(|mut f| f.write_all(line.as_bytes()));
        if let Err(e) = written {
            panic!("cannot record the skipped test in {}: {e}", path.display());
        }
    }
}
