#![allow(dead_code)]
//! Helpers shared by the integration tests: the core suite's scene builders, and the binary.

#[path = "../../crates/peridyn-core/tests/suite/common.rs"]
mod core_common;
pub use core_common::*;

/// Runs the `peridyn` binary with `args`.
pub fn peridyn(args: &[&str]) -> std::process::Output {
    std::process::Command::new(env!("CARGO_BIN_EXE_peridyn"))
        .args(args)
        .output()
        .expect("run peridyn")
}

/// A path in this test process's own folder for one test module (`module` keeps the modules'
/// files apart: they share the process).
pub fn temp(module: &str, name: &str) -> std::path::PathBuf {
    let dir = std::env::temp_dir().join(format!("peridyn-{module}-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir.join(name)
}
