//! Running the `lapidary` binary from integration tests.

use std::ops::Deref;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// Runs `lapidary ARGS…` and waits for it.
pub fn lapidary(args: &[&str]) -> Output {
    lapidary_with_env(args, &[])
}

/// Runs `lapidary ARGS…` with the environment variables `env` set.
pub fn lapidary_with_env(args: &[&str], env: &[(&str, &str)]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_lapidary"))
        .args(args)
        .envs(env.iter().copied())
        .output()
        .expect("binary runs")
}

/// A fresh, empty directory for one test (`suite` and `name` keep tests of
/// different files and of one file apart; the process id keeps runs apart),
/// removed when the test passes and kept for a look when it fails.
pub fn scratch(suite: &str, name: &str) -> Scratch {
    let dir = std::env::temp_dir().join(format!("lapidary-{suite}-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    Scratch(dir)
}

/// A test's scratch directory (see [`scratch`]): its path, removed with
/// everything in it when dropped, unless the thread is panicking (a failed
/// assertion), so that a failing test's files stay behind.
pub struct Scratch(PathBuf);

impl Deref for Scratch {
    type Target = PathBuf;

    fn deref(&self) -> &PathBuf {
        &self.0
    }
}

impl AsRef<Path> for Scratch {
    fn as_ref(&self) -> &Path {
        &self.0
    }
}

impl Drop for Scratch {
    fn drop(&mut self) {
        if !std::thread::panicking() {
            let _ = std::fs::remove_dir_all(&self.0);
        }
    }
}

/// The process's standard error as text.
pub fn stderr(out: &Output) -> String {
    String::from_utf8_lossy(&out.stderr).into_owned()
}
