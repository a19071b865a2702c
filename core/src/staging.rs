//! Outputs that appear together or not at all. Every file a command writes goes through
//! [`write_atomic`], which writes a temporary file beside the target and only records it;
//! [`commit`] renames them all into place when the command has succeeded, and [`discard`]
//! deletes them when it failed. So a command that fails half-way, at any step, leaves every
//! earlier output as it was. Directory outputs (rendered videos) are built in a temporary
//! directory beside the target ([`staged_dir`]) and moved in the same way. The staged list
//! belongs to the process: one command, one set of outputs. Temporary names are
//! `.odocal-<pid>-<n>.tmp` ([`temp_owner`]), so that a later run can tell the leftovers of a
//! process that was killed from those of one still running.

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{Mutex, MutexGuard};

use crate::file_error::FileError;

/// A temporary file or directory and the path it becomes on [`commit`].
struct Staged {
    tmp: PathBuf,
    target: PathBuf,
    is_dir: bool,
}

static STAGED: Mutex<Vec<Staged>> = Mutex::new(Vec::new());
/// Directories the command created to hold its outputs, outermost first: removed again by
/// [`discard`] when they are still empty, so a failed command leaves no empty folder behind.
static CREATED: Mutex<Vec<PathBuf>> = Mutex::new(Vec::new());
static COUNTER: AtomicUsize = AtomicUsize::new(0);

fn staged() -> MutexGuard<'static, Vec<Staged>> {
    // A panic while holding the lock cannot leave the list inconsistent (pushes only).
    STAGED.lock().unwrap_or_else(|e| e.into_inner())
}

fn created() -> MutexGuard<'static, Vec<PathBuf>> {
    CREATED.lock().unwrap_or_else(|e| e.into_inner())
}

/// `create_dir_all`, remembering which of the directories did not exist before.
fn make_dirs(dir: &Path) -> Result<(), FileError> {
    let missing: Vec<PathBuf> = dir
        .ancestors()
        .take_while(|d| !d.as_os_str().is_empty() && !d.exists())
        .map(Path::to_path_buf)
        .collect();
    std::fs::create_dir_all(dir).map_err(|e| io(dir, e))?;
    created().extend(missing.into_iter().rev());
    Ok(())
}

fn io(path: &Path, source: std::io::Error) -> FileError {
    FileError::Write {
        path: path.display().to_string(),
        source,
    }
}

fn refuse(option: &str, path: &Path, why: &str) -> FileError {
    FileError::Content {
        path: format!("{option} {}", path.display()),
        message: why.to_string(),
    }
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

/// The process id in a temporary name of [`temp_in`] (`.odocal-<pid>-<n>.tmp`), `None` for
/// any other name.
pub fn temp_owner(name: &str) -> Option<u32> {
    let (pid, n) = name
        .strip_prefix(".odocal-")?
        .strip_suffix(".tmp")?
        .split_once('-')?;
    n.parse::<usize>().ok()?;
    pid.parse().ok()
}

fn inside_staged_dir(path: &Path) -> bool {
    staged()
        .iter()
        .any(|s| s.is_dir && path.starts_with(&s.tmp))
}

/// Refuses an output path that is not a plain file to be replaced: an existing directory,
/// device or FIFO, a path ending in a slash (which names a folder), a name the file system
/// cannot hold, or a place the command cannot create files in. Commands call it on every
/// output path (`option` names it) before doing any work, so a wrong path fails at once.
pub fn check_output_file(path: &Path, option: &str) -> Result<(), FileError> {
    let file = through_links(path, option)?;
    check_file_shape(&file, option)?;
    check_can_create(parent_of(&file), path, option)
}

/// The file an output path names once its symbolic links are followed (a link is written
/// through, never replaced by a file of its own). Refused when it leads into /dev or /proc:
/// `--out /dev/stdout` under `> out.txt` resolves to a regular file, and the rename into
/// place would have replaced the system's link with one.
fn through_links(path: &Path, option: &str) -> Result<PathBuf, FileError> {
    let mut file = path.to_path_buf();
    // Linux's own limit on links followed in one path.
    for _ in 0..40 {
        if file.starts_with("/dev") || file.starts_with("/proc") {
            return Err(refuse(
                option,
                path,
                &format!(
                    "{} in {}, where devices and processes' files are (standard output?): odocal writes its outputs to ordinary files only; give a file path elsewhere",
                    match file == path {
                        true => "is".to_string(),
                        false => format!("leads to {},", file.display()),
                    },
                    if file.starts_with("/dev") { "/dev" } else { "/proc" }
                ),
            ));
        }
        match std::fs::symlink_metadata(&file) {
            Ok(m) if m.file_type().is_symlink() => {
                let to = std::fs::read_link(&file).map_err(|e| io(&file, e))?;
                file = parent_of(&file).join(to);
            }
            _ => return Ok(file),
        }
    }
    Err(refuse(
        option,
        path,
        "is a chain of more than 40 symbolic links (a loop?); give a file path",
    ))
}

fn check_file_shape(path: &Path, option: &str) -> Result<(), FileError> {
    if path.as_os_str().is_empty() {
        return Err(refuse(
            option,
            path,
            "the output path is empty; give a file name",
        ));
    }
    if let Ok(meta) = std::fs::metadata(path) {
        if meta.is_dir() {
            return Err(refuse(option, path, "is a directory; give a file path"));
        }
        if !meta.is_file() {
            return Err(refuse(
                option,
                path,
                "is not a regular file (a device, FIFO or socket); give a file path",
            ));
        }
    }
    // `Path` drops a trailing slash, and the rename into place would fail after all the work.
    if path
        .to_string_lossy()
        .ends_with(['/', std::path::MAIN_SEPARATOR])
    {
        return Err(refuse(
            option,
            path,
            "ends in a slash, which names a folder; give a file path (the folder followed by a file name)",
        ));
    }
    if path.file_name().is_some_and(|n| n.len() > 255) {
        return Err(refuse(
            option,
            path,
            "the file name is longer than the 255 bytes a file system allows",
        ));
    }
    if std::fs::metadata(parent_of(path)).is_ok_and(|m| !m.is_dir()) {
        return Err(refuse(option, path, "its parent is not a directory"));
    }
    Ok(())
}

/// Refuses an output whose folder `dir` (made if missing) cannot take a new file: tried by
/// creating one in the nearest folder that exists, since permissions, ACLs, a read-only
/// mount or root's exemption from them are only known to the file system.
fn check_can_create(dir: &Path, path: &Path, option: &str) -> Result<(), FileError> {
    let Some(existing) = dir
        .ancestors()
        .find(|d| d.as_os_str().is_empty() || d.exists())
    else {
        return Ok(());
    };
    let existing = if existing.as_os_str().is_empty() {
        Path::new(".")
    } else {
        existing
    };
    if !existing.is_dir() {
        return Err(refuse(
            option,
            path,
            &format!("{} is not a directory", existing.display()),
        ));
    }
    let probe = temp_in(existing);
    match std::fs::OpenOptions::new()
        .write(true)
        .create_new(true)
        .open(&probe)
    {
        Ok(_) => {
            let _ = std::fs::remove_file(&probe);
            Ok(())
        }
        Err(e) => Err(refuse(
            option,
            path,
            &format!(
                "cannot create a file in {} ({e}); give a folder you can write to",
                existing.display()
            ),
        )),
    }
}

/// Refuses an output directory path that exists as something other than a directory, or
/// where the command cannot create files.
pub fn check_output_dir(path: &Path, option: &str) -> Result<(), FileError> {
    if path.as_os_str().is_empty() {
        return Err(refuse(
            option,
            path,
            "the output directory is empty; give a name",
        ));
    }
    if std::fs::metadata(path).is_ok_and(|m| !m.is_dir()) {
        return Err(refuse(
            option,
            path,
            "exists and is not a directory; give a directory path",
        ));
    }
    check_can_create(path, path, option)
}

/// Writes `bytes` for `path`: into a temporary file beside it, moved into place by [`commit`].
/// A path inside a [`staged_dir`] is written directly (the whole directory moves on commit).
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<(), FileError> {
    let path = &through_links(path, "output")?;
    check_file_shape(path, "output")?;
    let dir = parent_of(path);
    if inside_staged_dir(path) {
        std::fs::create_dir_all(dir).map_err(|e| io(dir, e))?;
        return std::fs::write(path, bytes).map_err(|e| io(path, e));
    }
    make_dirs(dir)?;
    let tmp = temp_in(dir);
    if let Err(e) = std::fs::write(&tmp, bytes) {
        let _ = std::fs::remove_file(&tmp);
        return Err(io(path, e));
    }
    staged().push(Staged {
        tmp,
        target: path.to_path_buf(),
        is_dir: false,
    });
    Ok(())
}

/// A temporary directory whose entries move into `target` on [`commit`] (replacing entries
/// of the same name in an existing `target`); write the directory output into the returned
/// path. Inside a directory that is staged already, `target` itself is returned.
pub fn staged_dir(target: &Path, option: &str) -> Result<PathBuf, FileError> {
    check_output_dir(target, option)?;
    if inside_staged_dir(target) {
        std::fs::create_dir_all(target).map_err(|e| io(target, e))?;
        return Ok(target.to_path_buf());
    }
    let parent = parent_of(target);
    make_dirs(parent)?;
    let tmp = temp_in(parent);
    std::fs::create_dir_all(&tmp).map_err(|e| io(&tmp, e))?;
    staged().push(Staged {
        tmp: tmp.clone(),
        target: target.to_path_buf(),
        is_dir: true,
    });
    Ok(tmp)
}

/// Moves every staged output into place (files first, in the order written, then
/// directories): all of them or, when one cannot be moved, none (those already moved are put
/// back and every temporary is deleted). Called once, when the command has succeeded, and
/// before it says what it wrote.
///
/// The list stays locked throughout, so an interrupt's [`discard`] waits for the moves to end
/// instead of deleting temporaries half-way through them. A directory merged into an existing
/// one comes last and is not undone if it fails part-way.
pub fn commit() -> Result<(), FileError> {
    let mut list = staged();
    list.sort_by_key(|s| s.is_dir && s.target.is_dir());
    let mut placed: Vec<Placed> = Vec::new();
    let mut result = Ok(());
    for s in list.iter() {
        let step = if s.is_dir && s.target.is_dir() {
            merge_dir(&s.tmp, &s.target).map(|()| None)
        } else {
            place(s).map(Some)
        };
        match step {
            Ok(p) => placed.extend(p),
            Err(e) => {
                result = Err(e);
                break;
            }
        }
    }
    if result.is_err() {
        for p in placed.iter().rev() {
            p.undo();
        }
        remove_temporaries(&mut list);
        return result;
    }
    list.clear();
    for p in placed {
        if let Some(b) = p.backup {
            let _ = std::fs::remove_file(b);
        }
    }
    created().clear();
    Ok(())
}

/// An output moved into place, with what it replaced.
struct Placed {
    target: PathBuf,
    /// The file the target was before (a second name for it), or `None` when it is new.
    backup: Option<PathBuf>,
    is_dir: bool,
}

impl Placed {
    fn undo(&self) {
        match &self.backup {
            Some(b) => {
                let _ = std::fs::rename(b, &self.target);
            }
            None if self.is_dir => {
                let _ = std::fs::remove_dir_all(&self.target);
            }
            None => {
                let _ = std::fs::remove_file(&self.target);
            }
        }
    }
}

/// Renames a staged file or new directory to its target, keeping a second name for the file
/// it replaces so that [`commit`] can put it back. The target is never absent meanwhile (a
/// hard link, or a copy where the file system has none), so a process killed here loses
/// nothing: the backup is only a leftover temporary.
fn place(s: &Staged) -> Result<Placed, FileError> {
    let backup = if !s.is_dir && s.target.is_file() {
        let b = temp_in(parent_of(&s.target));
        if std::fs::hard_link(&s.target, &b).is_err() {
            std::fs::copy(&s.target, &b).map_err(|e| io(&s.target, e))?;
        }
        Some(b)
    } else {
        None
    };
    if let Err(e) = std::fs::rename(&s.tmp, &s.target) {
        if let Some(b) = backup {
            let _ = std::fs::remove_file(b);
        }
        return Err(io(&s.target, e));
    }
    Ok(Placed {
        target: s.target.clone(),
        backup,
        is_dir: s.is_dir,
    })
}

/// Deletes the temporaries of `list` that are still there, and empties it.
fn remove_temporaries(list: &mut Vec<Staged>) {
    for s in list.drain(..) {
        if s.is_dir {
            let _ = std::fs::remove_dir_all(&s.tmp);
        } else {
            let _ = std::fs::remove_file(&s.tmp);
        }
    }
}

/// Moves every entry of the staged directory `tmp` into the existing directory `target`,
/// replacing entries of the same name (other entries of `target` stay); files last, so an
/// index such as manifest.json appears after what it lists.
///
/// A numbered series the new output writes (`view_00.png` … `view_02.png`) replaces the
/// target's whole series of that name: a `view_07.png` left from an earlier, larger set would
/// otherwise be picked up by `view_*.png` beside views of another camera.
/// The entries of `target` that merging the staged folder `tmp` into it replaces (an entry of
/// the same name, file or folder) or deletes (a file numbered in a series `tmp` writes, which
/// a shorter run of it would leave stale: `view_07.png` beside a new `view_00`…`view_02`).
pub fn replaced_by_merge(tmp: &Path, target: &Path) -> Result<Vec<PathBuf>, FileError> {
    let (names, stale) = merge_plan(tmp, target)?;
    let mut out: Vec<PathBuf> = names
        .iter()
        .map(|n| target.join(n))
        .filter(|p| p.exists())
        .chain(stale)
        .collect();
    out.sort();
    Ok(out)
}

/// The names of `tmp`'s entries, and the files of `target` a merge deletes as stale
/// ([`replaced_by_merge`]).
fn merge_plan(tmp: &Path, target: &Path) -> Result<(Vec<String>, Vec<PathBuf>), FileError> {
    let entries: Vec<(bool, String)> = std::fs::read_dir(tmp)
        .map_err(|e| io(tmp, e))?
        .filter_map(|e| e.ok())
        .map(|e| {
            (
                e.path().is_file(),
                e.file_name().to_string_lossy().into_owned(),
            )
        })
        .collect();
    let series: Vec<String> = entries
        .iter()
        .filter(|(is_file, _)| *is_file)
        .filter_map(|(_, n)| series_of(n))
        .collect();
    let names: Vec<String> = entries.into_iter().map(|(_, n)| n).collect();
    let stale: Vec<PathBuf> = std::fs::read_dir(target)
        .map_err(|e| io(target, e))?
        .filter_map(|e| e.ok())
        .filter(|e| e.path().is_file())
        .filter(|e| {
            let name = e.file_name().to_string_lossy().into_owned();
            !names.contains(&name) && series_of(&name).is_some_and(|k| series.contains(&k))
        })
        .map(|e| e.path())
        .collect();
    Ok((names, stale))
}

fn merge_dir(tmp: &Path, target: &Path) -> Result<(), FileError> {
    let mut entries: Vec<(bool, PathBuf)> = std::fs::read_dir(tmp)
        .map_err(|e| io(tmp, e))?
        .filter_map(|e| e.ok())
        .map(|e| (e.path().is_file(), e.path()))
        .collect();
    entries.sort();
    let (_, stale) = merge_plan(tmp, target)?;
    for old in stale {
        std::fs::remove_file(&old).map_err(|e| io(&old, e))?;
    }
    for (_, from) in entries {
        let Some(name) = from.file_name() else {
            continue;
        };
        let to = target.join(name);
        let old = if to.exists() {
            let old = temp_in(target);
            std::fs::rename(&to, &old).map_err(|e| io(&to, e))?;
            Some(old)
        } else {
            None
        };
        std::fs::rename(&from, &to).map_err(|e| io(&to, e))?;
        if let Some(old) = old {
            let removed = if old.is_dir() {
                std::fs::remove_dir_all(&old)
            } else {
                std::fs::remove_file(&old)
            };
            removed.map_err(|e| io(&old, e))?;
        }
    }
    std::fs::remove_dir(tmp).map_err(|e| io(tmp, e))
}

/// The series a numbered file name belongs to: the name with each run of digits as `#`
/// (`view_07.png` → `view_#.png`); `None` for a name without digits.
fn series_of(name: &str) -> Option<String> {
    let mut key = String::with_capacity(name.len());
    let (mut numbered, mut in_digits) = (false, false);
    for c in name.chars() {
        let digit = c.is_ascii_digit();
        if !digit {
            key.push(c);
        } else if !in_digits {
            key.push('#');
        }
        numbered |= digit;
        in_digits = digit;
    }
    numbered.then_some(key)
}

/// Deletes every staged output: the command failed or was interrupted, so nothing it wrote
/// appears. Safe to call from any thread; it waits for a [`commit`] under way.
pub fn discard() {
    remove_temporaries(&mut staged());
    // Innermost first; `remove_dir` leaves a directory someone else has filled meanwhile.
    for dir in std::mem::take(&mut *created()).iter().rev() {
        let _ = std::fs::remove_dir(dir);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn outputs_appear_on_commit_and_never_on_discard() {
        let dir = std::env::temp_dir().join(format!("odocal-staging-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        let a = dir.join("a.txt");
        write_atomic(&a, b"one").unwrap();
        assert!(!a.exists());
        discard();
        assert!(!a.exists());
        assert_eq!(
            std::fs::read_dir(&dir).unwrap().count(),
            0,
            "no temporary left"
        );
        // Folders made for an output that never appears are removed again; a folder the
        // user had already is kept.
        write_atomic(&dir.join("new/deeper/b.txt"), b"one").unwrap();
        assert!(dir.join("new/deeper").is_dir());
        discard();
        assert!(!dir.join("new").exists(), "no empty folder left");
        assert!(dir.is_dir());
        write_atomic(&a, b"two").unwrap();
        let sub = staged_dir(&dir.join("sub"), "--out").unwrap();
        std::fs::write(sub.join("f"), b"x").unwrap();
        commit().unwrap();
        assert_eq!(std::fs::read(&a).unwrap(), b"two");
        assert!(dir.join("sub/f").exists());
        assert!(check_output_file(&dir, "--out").is_err());
        assert!(check_output_file(Path::new("/dev/null"), "--out").is_err());
        // A link is written through, never replaced by a file of its own; one into /dev or
        // /proc (`--out /dev/stdout` under `> out.txt`) is refused.
        let (real, link) = (dir.join("real.txt"), dir.join("link.txt"));
        std::fs::write(&real, b"keep").unwrap();
        std::os::unix::fs::symlink("real.txt", &link).unwrap();
        check_output_file(&link, "--out").unwrap();
        write_atomic(&link, b"through").unwrap();
        commit().unwrap();
        assert!(std::fs::symlink_metadata(&link)
            .unwrap()
            .file_type()
            .is_symlink());
        assert_eq!(std::fs::read(&real).unwrap(), b"through");
        let stdout = dir.join("stdout");
        std::os::unix::fs::symlink("/proc/self/fd/1", &stdout).unwrap();
        for out in [stdout.as_path(), Path::new("/dev/stdout")] {
            let e = check_output_file(out, "--out").unwrap_err().to_string();
            assert!(
                e.contains("writes its outputs to ordinary files only"),
                "{e}"
            );
            assert!(write_atomic(out, b"x").is_err());
        }
        let looped = dir.join("loop");
        std::os::unix::fs::symlink("loop", &looped).unwrap();
        let e = check_output_file(&looped, "--out").unwrap_err().to_string();
        assert!(e.contains("a loop?"), "{e}");
        // A folder that cannot be made is a write that failed, not a read.
        let e = write_atomic(&a.join("under/a/file.txt"), b"x").unwrap_err();
        assert!(e.to_string().starts_with("cannot write "), "{e}");
        // A smaller set over a larger one: the new series replaces the old one whole, and
        // files of no series written now stay.
        let set = dir.join("set");
        std::fs::create_dir_all(&set).unwrap();
        for k in 0..5 {
            std::fs::write(set.join(format!("view_{k:02}.png")), b"old").unwrap();
        }
        std::fs::write(set.join("notes.txt"), b"mine").unwrap();
        std::fs::write(set.join("scan_1.csv"), b"mine").unwrap();
        let staged = staged_dir(&set, "--out").unwrap();
        for k in 0..2 {
            std::fs::write(staged.join(format!("view_{k:02}.png")), b"new").unwrap();
        }
        commit().unwrap();
        let mut left: Vec<String> = std::fs::read_dir(&set)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        left.sort();
        assert_eq!(
            left,
            ["notes.txt", "scan_1.csv", "view_00.png", "view_01.png"]
        );
        assert_eq!(std::fs::read(set.join("view_01.png")).unwrap(), b"new");
        // One output that cannot be moved into place: none is, the files replaced before it
        // are back, and no temporary is left.
        std::fs::write(&a, b"old").unwrap();
        write_atomic(&a, b"new").unwrap();
        write_atomic(&dir.join("fresh.txt"), b"new").unwrap();
        write_atomic(&dir.join("lost.txt"), b"new").unwrap();
        let lost = super::staged().last().map(|s| s.tmp.clone()).unwrap();
        std::fs::remove_file(lost).unwrap();
        assert!(commit().unwrap_err().to_string().contains("lost.txt"));
        assert_eq!(std::fs::read(&a).unwrap(), b"old");
        assert!(!dir.join("fresh.txt").exists());
        let left: Vec<String> = std::fs::read_dir(&dir)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .filter(|n| n.starts_with(".odocal-"))
            .collect();
        assert!(left.is_empty(), "{left:?}");
        assert_eq!(temp_owner(".odocal-12-3.tmp"), Some(12));
        assert_eq!(temp_owner(".odocal-12.tmp"), None);
        // A path ending in a slash names a folder, whose rename would fail after the work.
        assert!(check_output_file(Path::new("somedir/"), "--out")
            .unwrap_err()
            .to_string()
            .contains("ends in a slash"));
        assert_eq!(
            series_of("run012.odometry.csv").as_deref(),
            Some("run#.odometry.csv")
        );
        assert_eq!(series_of("truth.json"), None);
        let _ = std::fs::remove_dir_all(&dir);
    }
}
