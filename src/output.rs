//! Shared helpers of the binary: progress bars, counts, and the outputs of a command, which
//! appear together when it succeeds and not at all when it fails
//! (`odocal_core::staging`).

use std::ffi::OsStr;
use std::path::{Path, PathBuf};

use indicatif::{ProgressBar, ProgressStyle};
pub use odocal_core::staging::{check_output_dir, commit, discard, staged_dir, write_atomic};
use odocal_core::FileError;

/// What a failed write to standard output means: a closed pipe (`| head -1`) is a reader
/// who has seen enough, and the command goes on to commit its files; any other failure (a
/// full disk under `> out.csv`) loses what was printed, which for `correct` or `lrf
/// check-map` is the result, so the command fails and commits nothing.
pub fn stdout_failed(e: std::io::Error) {
    if e.kind() == std::io::ErrorKind::BrokenPipe {
        return;
    }
    discard();
    let _ = std::io::Write::write_all(
        &mut std::io::stderr(),
        format!("odocal: error: cannot write to standard output: {e}\n").as_bytes(),
    );
    std::process::exit(2);
}

/// Refuses an output path that is not a plain file to be replaced
/// ([`odocal_core::staging::check_output_file`]), or that names the same file as another
/// argument of the command: an input the output would destroy (`track a.avi --out a.avi`),
/// or a second output that would overwrite the first (`--out x.csv --tum x.csv`). The value
/// given to `option` itself is not counted.
pub fn check_output_file(path: &Path, option: &str) -> Result<(), FileError> {
    odocal_core::staging::check_output_file(path, option)?;
    let Some(target) = file_identity(path) else {
        return Ok(());
    };
    let args: Vec<_> = std::env::args_os().skip(1).collect();
    let own = format!("{option}=");
    let mut i = 0;
    while i < args.len() {
        let a = &args[i];
        i += 1;
        let text = a.to_string_lossy();
        if text == option {
            i += 1; // the option's own value
            continue;
        }
        if text.starts_with(&own) {
            continue;
        }
        // `--opt=value`: the value is the path.
        let value = match text.split_once('=') {
            Some((opt, v)) if opt.starts_with("--") => OsStr::new(v).to_os_string(),
            _ => a.clone(),
        };
        if file_identity(Path::new(&value)).as_ref() == Some(&target) {
            return Err(FileError::content(
                &format!("{option} {}", path.display()),
                format!(
                    "is the same file as the argument {}, which writing it would replace; give {option} another path",
                    text
                ),
            ));
        }
    }
    Ok(())
}

/// Refuses an output path that would replace a file the command reads without it being an
/// argument (a manifest's logs and trajectories, a frame folder's images), or land inside an
/// input folder (whose every file is read as a frame). `inputs` are those files and folders;
/// `whose` says where they come from ("listed in the manifest").
pub fn check_output_not_input(
    path: &Path,
    option: &str,
    inputs: &[PathBuf],
    whose: &str,
) -> Result<(), FileError> {
    let Some(target) = file_identity(path) else {
        return Ok(());
    };
    for input in inputs {
        let Some(id) = file_identity(input) else {
            continue;
        };
        let inside = input.is_dir() && target.starts_with(&id);
        if inside || target == id {
            return Err(FileError::content(
                &format!("{option} {}", path.display()),
                if inside {
                    format!(
                        "lies inside {} ({whose}), whose files are all read as input; give {option} a path outside it",
                        input.display()
                    )
                } else {
                    format!(
                        "is {} ({whose}), which writing it would replace; give {option} another path",
                        input.display()
                    )
                },
            ));
        }
    }
    Ok(())
}

/// The file a path names, whether or not it exists yet: the canonical path, or the
/// canonical parent joined with the name. `None` when even the parent does not exist.
fn file_identity(path: &Path) -> Option<PathBuf> {
    if let Ok(c) = std::fs::canonicalize(path) {
        return Some(c);
    }
    let name = path.file_name()?;
    let parent = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    std::fs::canonicalize(parent).ok().map(|d| d.join(name))
}

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
