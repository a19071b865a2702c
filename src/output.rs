//! Shared helpers of the binary: progress bars, counts, and the outputs of a command, which
//! appear together when it succeeds and not at all when it fails
//! (`odocal_core::staging`).

use std::path::Path;

use indicatif::{ProgressBar, ProgressStyle};
pub use odocal_core::staging::{
    check_output_dir, check_output_file, commit, discard, staged_dir, write_atomic,
};

/// A progress bar for `len` items of work, hidden when stderr is not a terminal.
pub fn progress(len: u64, what: &str) -> ProgressBar {
    let bar = ProgressBar::new(len);
    bar.set_style(
        ProgressStyle::with_template("{msg:>12} [{bar:30}] {pos}/{len} {per_sec} eta {eta}")
            .unwrap_or_else(|_| ProgressStyle::default_bar())
            .progress_chars("=> "),
    );
    bar.set_message(what.to_string());
    bar
}

/// Serialises `value` as pretty JSON and writes it with [`write_atomic`].
pub fn write_json<T: serde::Serialize>(path: &Path, value: &T) -> anyhow::Result<()> {
    let mut s = serde_json::to_string_pretty(value)?;
    s.push('\n');
    Ok(write_atomic(path, s.as_bytes())?)
}

/// "1 run", "3 runs": a count with its noun in the right number.
pub fn count(n: usize, noun: &str) -> String {
    if n == 1 {
        format!("1 {noun}")
    } else {
        format!("{n} {noun}s")
    }
}
