//! What the end-to-end tests share: running the built `odocal` binary and small statistics.
#![allow(dead_code)] // each test binary uses its own part

use std::path::Path;
use std::process::{Command, Output};

/// Runs the built binary with `args`.
pub fn odocal(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_odocal"))
        .args(args)
        .output()
        .expect("run odocal")
}

/// Runs odocal expecting success; returns its standard output.
pub fn ok(args: &[&str]) -> String {
    let o = odocal(args);
    assert!(
        o.status.success(),
        "odocal {args:?} failed: {}",
        String::from_utf8_lossy(&o.stderr)
    );
    String::from_utf8_lossy(&o.stdout).into_owned()
}

/// Runs odocal expecting exit code 2 and a one-line error; returns the message.
pub fn fails(args: &[&str]) -> String {
    let o = odocal(args);
    let err = String::from_utf8_lossy(&o.stderr).into_owned();
    assert_eq!(
        o.status.code(),
        Some(2),
        "odocal {args:?} should fail: {err}"
    );
    assert!(err.starts_with("odocal: error: "), "{err}");
    assert_eq!(err.trim_end().lines().count(), 1, "{err}");
    err
}

/// A path as a command-line argument.
pub fn p(path: &Path) -> &str {
    path.to_str().expect("utf-8 path")
}

/// Root mean square.
pub fn rms(v: &[f64]) -> f64 {
    (v.iter().map(|x| x * x).sum::<f64>() / v.len().max(1) as f64).sqrt()
}
