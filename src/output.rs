//! Shared helpers of the binary: progress bars, and outputs that appear together or not at
//! all.
//!
//! Every file a command writes goes through [`write_atomic`], which writes a temporary file
//! beside the target and only records it; `main` renames them all into place when the command
//! succeeds ([`commit`]) and deletes them when it fails ([`discard`]). So a command that fails
//! half-way, at any step, leaves every earlier output as it was. Directory outputs (rendered
//! videos) are built in a temporary directory beside the target ([`staged_dir`]) and moved in
//! the same way.

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Mutex;

use anyhow::{bail, Context};
use indicatif::{ProgressBar, ProgressStyle};

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

/// A temporary file or directory and the path it becomes on [`commit`].
struct Staged {
    tmp: PathBuf,
    target: PathBuf,
    is_dir: bool,
}

static STAGED: Mutex<Vec<Staged>> = Mutex::new(Vec::new());
static COUNTER: AtomicUsize = AtomicUsize::new(0);

fn staged() -> std::sync::MutexGuard<'static, Vec<Staged>> {
    // A panic while holding the lock cannot leave the list inconsistent (pushes only).
    STAGED.lock().unwrap_or_else(|e| e.into_inner())
}

/// The directory `path` goes in ("." for a bare file name).
fn parent_of(path: &Path) -> &Path {
    match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    }
}

/// A short temporary name in `dir` (short, so that a target name near the file system's
/// 255-byte limit still works).
fn temp_in(dir: &Path) -> PathBuf {
    let n = COUNTER.fetch_add(1, Ordering::Relaxed);
    dir.join(format!(".odocal-{}-{n}.tmp", std::process::id()))
}

/// Refuses an output path that is not a plain file to be replaced: an existing directory,
/// device or FIFO, or a name the file system cannot hold. Commands call it on every output
/// path before doing any work, so a wrong path fails at once.
pub fn check_output_file(path: &Path, option: &str) -> anyhow::Result<()> {
    if path.as_os_str().is_empty() {
        bail!("{option}: the output path is empty; give a file name");
    }
    if let Ok(meta) = std::fs::metadata(path) {
        if meta.is_dir() {
            bail!(
                "{option} {}: is a directory; give a file path",
                path.display()
            );
        }
        if !meta.is_file() {
            bail!(
                "{option} {}: is not a regular file (a device, FIFO or socket); give a file path",
                path.display()
            );
        }
    }
    if let Some(name) = path.file_name() {
        if name.len() > 255 {
            bail!(
                "{option} {}: the file name is {} bytes long, more than the 255 a file system allows",
                path.display(),
                name.len()
            );
        }
    }
    let dir = parent_of(path);
    if let Ok(meta) = std::fs::metadata(dir) {
        if !meta.is_dir() {
            bail!(
                "{option} {}: {} is not a directory",
                path.display(),
                dir.display()
            );
        }
    }
    Ok(())
}

/// Refuses an output directory path that exists as something other than a directory.
pub fn check_output_dir(path: &Path, option: &str) -> anyhow::Result<()> {
    if path.as_os_str().is_empty() {
        bail!("{option}: the output directory is empty; give a directory name");
    }
    if let Ok(meta) = std::fs::metadata(path) {
        if !meta.is_dir() {
            bail!(
                "{option} {}: exists and is not a directory; give a directory path",
                path.display()
            );
        }
    }
    Ok(())
}

/// Writes `bytes` for `path`: into a temporary file beside it, moved into place by [`commit`]
/// when the command succeeds. A path inside a [`staged_dir`] is written directly (the whole
/// directory moves on commit).
pub fn write_atomic(path: &Path, bytes: &[u8]) -> anyhow::Result<()> {
    check_output_file(path, "output")?;
    let dir = parent_of(path);
    std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
    let inside_staged_dir = staged()
        .iter()
        .any(|s| s.is_dir && path.starts_with(&s.tmp));
    if inside_staged_dir {
        return std::fs::write(path, bytes)
            .with_context(|| format!("cannot write {}", path.display()));
    }
    let tmp = temp_in(dir);
    if let Err(e) = std::fs::write(&tmp, bytes) {
        let _ = std::fs::remove_file(&tmp);
        return Err(e).with_context(|| format!("cannot write {}", path.display()));
    }
    staged().push(Staged {
        tmp,
        target: path.to_path_buf(),
        is_dir: false,
    });
    Ok(())
}

/// Serialises `value` as pretty JSON and writes it with [`write_atomic`].
pub fn write_json<T: serde::Serialize>(path: &Path, value: &T) -> anyhow::Result<()> {
    let mut s = serde_json::to_string_pretty(value)?;
    s.push('\n');
    write_atomic(path, s.as_bytes())
}

/// A temporary directory whose entries move into `target` on [`commit`] (replacing entries
/// of the same name in an existing `target`); write the command's directory output into the
/// returned path.
pub fn staged_dir(target: &Path, option: &str) -> anyhow::Result<PathBuf> {
    check_output_dir(target, option)?;
    // Inside a directory that is staged already, the outer one moves it into place.
    let inside_staged_dir = staged()
        .iter()
        .any(|s| s.is_dir && target.starts_with(&s.tmp));
    if inside_staged_dir {
        std::fs::create_dir_all(target)
            .with_context(|| format!("cannot create {}", target.display()))?;
        return Ok(target.to_path_buf());
    }
    let parent = parent_of(target);
    std::fs::create_dir_all(parent)
        .with_context(|| format!("cannot create {}", parent.display()))?;
    let tmp = temp_in(parent);
    std::fs::create_dir_all(&tmp).with_context(|| format!("cannot create {}", tmp.display()))?;
    staged().push(Staged {
        tmp: tmp.clone(),
        target: target.to_path_buf(),
        is_dir: true,
    });
    Ok(tmp)
}

/// Moves every staged output into place (files first, in the order written, then
/// directories). Called once, when the command has succeeded.
pub fn commit() -> anyhow::Result<()> {
    let mut list = std::mem::take(&mut *staged());
    // Files staged inside a staged directory move with it.
    list.sort_by_key(|s| s.is_dir);
    for s in &list {
        if s.is_dir {
            if s.target.is_dir() {
                merge_dir(&s.tmp, &s.target)?;
            } else {
                std::fs::rename(&s.tmp, &s.target)
                    .with_context(|| format!("cannot write {}", s.target.display()))?;
            }
        } else {
            std::fs::rename(&s.tmp, &s.target)
                .with_context(|| format!("cannot write {}", s.target.display()))?;
        }
    }
    Ok(())
}

/// Moves every entry of the staged directory `tmp` into the existing directory `target`,
/// replacing entries of the same name (other entries of `target` stay); files last, so an
/// index such as manifest.json appears after what it lists.
fn merge_dir(tmp: &Path, target: &Path) -> anyhow::Result<()> {
    let mut entries: Vec<(bool, PathBuf)> = std::fs::read_dir(tmp)
        .with_context(|| format!("cannot read {}", tmp.display()))?
        .filter_map(|e| e.ok())
        .map(|e| (e.path().is_file(), e.path()))
        .collect();
    entries.sort();
    for (_, from) in entries {
        let Some(name) = from.file_name() else {
            continue;
        };
        let to = target.join(name);
        let old = if to.exists() {
            let old = temp_in(target);
            std::fs::rename(&to, &old)
                .with_context(|| format!("cannot replace {}", to.display()))?;
            Some(old)
        } else {
            None
        };
        std::fs::rename(&from, &to).with_context(|| format!("cannot write {}", to.display()))?;
        if let Some(old) = old {
            let removed = if old.is_dir() {
                std::fs::remove_dir_all(&old)
            } else {
                std::fs::remove_file(&old)
            };
            removed.with_context(|| format!("cannot remove the old {}", to.display()))?;
        }
    }
    std::fs::remove_dir(tmp).with_context(|| format!("cannot remove {}", tmp.display()))
}

/// Deletes every staged output: the command failed, so nothing it wrote appears.
pub fn discard() {
    for s in std::mem::take(&mut *staged()) {
        if s.is_dir {
            let _ = std::fs::remove_dir_all(&s.tmp);
        } else {
            let _ = std::fs::remove_file(&s.tmp);
        }
    }
}

/// "1 run", "3 runs": a count with its noun in the right number.
pub fn count(n: usize, noun: &str) -> String {
    if n == 1 {
        format!("1 {noun}")
    } else {
        format!("{n} {noun}s")
    }
}
