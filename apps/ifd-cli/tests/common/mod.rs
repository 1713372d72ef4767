//! Helpers shared by the `ifd` binary's integration tests (each test file
//! uses some of them).
#![allow(dead_code, reason = "each test binary uses a subset")]

use std::path::Path;
use std::process::Command;

/// Runs `cmd` and returns its exit code (-1 when killed), stdout and stderr.
pub fn run(cmd: &mut Command) -> (i32, String, String) {
    let out = cmd.output().expect("run ifd");
    (
        out.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

/// The `ifd` binary under test.
pub fn ifd_command() -> Command {
    Command::new(env!("CARGO_BIN_EXE_ifd"))
}

/// Runs `ifd ARGS...`.
pub fn ifd(args: &[&str]) -> (i32, String, String) {
    run(ifd_command().args(args))
}

/// The path of a bundled test file.
pub fn testdata(name: &str) -> String {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../testdata")
        .join(name)
        .to_string_lossy()
        .into_owned()
}
