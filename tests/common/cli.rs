//! Running the `lapidary` binary from integration tests.

use std::path::PathBuf;
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
/// different files and of one file apart; the process id keeps runs apart).
pub fn scratch(suite: &str, name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("lapidary-{suite}-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// The process's standard error as text.
pub fn stderr(out: &Output) -> String {
    String::from_utf8_lossy(&out.stderr).into_owned()
}
