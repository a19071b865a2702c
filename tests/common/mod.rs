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

/// `odocal synth arena` of a small arena into `out`: 480x320 cameras, each calibrated from
/// 6 views, with the `extra` options.
pub fn synth_small_arena(out: &std::path::Path, seed: u64, extra: &[&str]) {
    let seed = seed.to_string();
    let mut args = vec![
        "synth",
        "arena",
        "--out",
        p(out),
        "--seed",
        &seed,
        "--width",
        "480",
        "--height",
        "320",
        "--calib-views",
        "6",
    ];
    args.extend_from_slice(extra);
    ok(&args);
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

/// Asserts that a run of odocal succeeded, showing its output if not.
pub fn succeeded(out: &Output) {
    assert!(
        out.status.success(),
        "odocal failed: {}\n{}",
        String::from_utf8_lossy(&out.stderr),
        String::from_utf8_lossy(&out.stdout)
    );
}

/// Asserts exit code 2 and exactly one `odocal: error:` line containing `needle`; returns
/// standard error.
pub fn fails_with(out: &Output, needle: &str) -> String {
    let err = String::from_utf8_lossy(&out.stderr).to_string();
    assert_eq!(out.status.code(), Some(2), "expected exit 2, stderr: {err}");
    let lines: Vec<&str> = err.lines().filter(|l| !l.trim().is_empty()).collect();
    assert_eq!(lines.len(), 1, "expected one error line, got: {err}");
    assert!(lines[0].starts_with("odocal: error: "), "{err}");
    assert!(lines[0].contains(needle), "expected {needle:?} in: {err}");
    err
}

/// Simulates `runs` runs (`--frames none`) into the folder `exp` and builds `dataset` from
/// them, as `odocal synth experiment` and `odocal dataset` do.
pub fn experiment_dataset(exp: &Path, dataset: &Path, runs: usize, seed: u64) {
    ok(&[
        "synth",
        "experiment",
        "--out",
        p(exp),
        "--runs",
        &runs.to_string(),
        "--seed",
        &seed.to_string(),
        "--frames",
        "none",
    ]);
    ok(&[
        "dataset",
        "--manifest",
        p(&exp.join("manifest.json")),
        "--out",
        p(dataset),
    ]);
}

/// A path as a command-line argument.
pub fn p(path: &Path) -> &str {
    path.to_str().expect("utf-8 path")
}

/// Root mean square.
pub fn rms(v: &[f64]) -> f64 {
    (v.iter().map(|x| x * x).sum::<f64>() / v.len().max(1) as f64).sqrt()
}

/// `jpeg` with an EXIF segment whose only entry is the display orientation `orientation`
/// (1–8; 3 asks for a turn of 180°), as a camera held turned writes.
pub fn with_exif_orientation(jpeg: &[u8], orientation: u16) -> Vec<u8> {
    assert!(jpeg.starts_with(&[0xFF, 0xD8]), "not a JPEG");
    let mut exif = b"Exif\0\0MM\0\x2a\0\0\0\x08\0\x01\x01\x12\0\x03\0\0\0\x01".to_vec();
    exif.extend_from_slice(&orientation.to_be_bytes());
    exif.extend_from_slice(&[0; 6]); // the value's padding, then no next directory
    let mut out = vec![0xFF, 0xD8, 0xFF, 0xE1];
    out.extend_from_slice(&(exif.len() as u16 + 2).to_be_bytes());
    out.extend_from_slice(&exif);
    out.extend_from_slice(&jpeg[2..]);
    out
}

/// FFmpeg, quiet, overwriting its output: for making test videos (see [`ran`]).
pub fn ffmpeg() -> std::process::Command {
    let mut c = std::process::Command::new("ffmpeg");
    c.args(["-hide_banner", "-y"]);
    c
}

/// Runs `cmd` to success, with its error output in the failure.
pub fn ran(cmd: &mut std::process::Command) {
    let out = cmd
        .output()
        .unwrap_or_else(|e| panic!("{cmd:?} could not run ({e}): `make deps` installs FFmpeg"));
    assert!(
        out.status.success(),
        "{cmd:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
}
