//! The set-up every window test shares (both apps' `tests/window.rs`):
//! Xvfb (or a skip that says why, when `IFD_WINDOW_TESTS=skip` allows it),
//! a temporary folder with the app's state folder and a private
//! `XDG_RUNTIME_DIR`, and the command that starts an app in a virtual
//! 1280x800 screen.
//!
//! Included with `#[path = "../../../tests/support/xvfb.rs"] mod xvfb;`
//! beside `skip.rs` (as `mod skip`, which this file uses).

#![allow(dead_code, reason = "each test file uses what it needs")]

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};

use crate::skip;

/// Whether `cmd` is on `PATH`.
pub fn have(cmd: &str) -> bool {
    Command::new("sh")
        .args(["-c", &format!("command -v {cmd}")])
        .stdout(Stdio::null())
        .status()
        .is_ok_and(|s| s.success())
}

/// A window test's folder and the app's state and runtime folders in it.
pub struct WindowTest {
    dir: tempfile::TempDir,
    /// The app's state folder (its settings file, `app.ron`).
    pub state: PathBuf,
    runtime: PathBuf,
}

impl WindowTest {
    /// `None` when Xvfb is missing and the test may be skipped (it fails
    /// otherwise).
    pub fn new() -> Option<Self> {
        if !have("xvfb-run") || !have("Xvfb") {
            assert!(
                skip::allowed("IFD_WINDOW_TESTS"),
                "Xvfb/xvfb-run not installed for the window test (apt-get install xvfb xauth; \
                 scripts/test-all.sh does) or set IFD_WINDOW_TESTS=skip"
            );
            skip::skip("Xvfb/xvfb-run not installed (IFD_WINDOW_TESTS=skip)");
            return None;
        }
        let dir = tempfile::tempdir().expect("tempdir");
        let state = dir.path().join("state");
        std::fs::create_dir(&state).expect("state dir");
        let runtime = dir.path().join("xdg");
        std::fs::create_dir(&runtime).expect("xdg dir");
        #[cfg(unix)]
        {
            use std::os::unix::fs::PermissionsExt;
            std::fs::set_permissions(&runtime, std::fs::Permissions::from_mode(0o700))
                .expect("chmod");
        }
        Some(Self {
            dir,
            state,
            runtime,
        })
    }

    /// The test's temporary folder.
    pub fn path(&self) -> &Path {
        self.dir.path()
    }

    /// `xvfb-run ... exe` in a 1280x800 screen, run by `wrapper` (e.g.
    /// `["timeout", "300"]`, or none), with the state folder in the
    /// variable `state_var` and the private runtime folder; the caller adds
    /// the app's arguments.
    pub fn command(&self, wrapper: &[&str], exe: &str, state_var: &str) -> Command {
        let mut c = match wrapper.split_first() {
            Some((program, args)) => {
                let mut c = Command::new(program);
                c.args(args).arg("xvfb-run");
                c
            }
            None => Command::new("xvfb-run"),
        };
        c.args(["-a", "-s", "-screen 0 1280x800x24"])
            .arg(exe)
            .env(state_var, &self.state)
            .env("XDG_RUNTIME_DIR", &self.runtime);
        c
    }
}
