//! Shared helpers of the binary: progress bars, counts, and the outputs of a command, which
//! appear together when it succeeds and not at all when it fails or is interrupted
//! (`odocal_core::staging`). A command writes all its outputs, then calls [`commit`], and
//! only then says what it wrote: a file it names is a file that is there.

use std::collections::HashSet;
use std::ffi::OsStr;
use std::path::{Path, PathBuf};
use std::sync::Mutex;

use indicatif::{ProgressBar, ProgressStyle};
pub use odocal_core::staging::discard;
use odocal_core::staging::{self, temp_owner};
use odocal_core::FileError;

/// What a failed write to standard output means: a closed pipe (`| head -1`) is a reader
/// who has seen enough, and the command goes on to commit its files; any other failure (a
/// full disk under `> out.csv`) loses what was printed, which for `correct` or `lrf
/// check-map` is the result, so the command fails and commits nothing (files it committed
/// before saying it wrote them stay: they hold the result).
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

/// Refuses an output path that is not a plain file to be replaced, or in a folder the command
/// cannot write ([`odocal_core::staging::check_output_file`]), or that names the same file
/// as another argument of the command: an input the output would destroy (`track a.avi --out
/// a.avi`, `train sw/report.json --report sw`), or a second output that would overwrite the
/// first (`--out x.csv --tum x.csv`). The value given to `option` itself is not counted.
pub fn check_output_file(path: &Path, option: &str) -> Result<(), FileError> {
    remove_stale_temporaries(path);
    staging::check_output_file(path, option)?;
    let Some(target) = file_identity(path) else {
        return Ok(());
    };
    let args: Vec<_> = std::env::args_os().skip(1).collect();
    let own = format!("{option}=");
    let mut i = 0;
    while i < args.len() {
        let a = &args[i];
        let before = i.checked_sub(1).map(|b| args[b].to_string_lossy());
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
            // The value of an option is named with its option (`--tum x.csv`).
            let named = match before {
                Some(opt) if takes_value(&opt) => format!("{opt} {text}"),
                _ => text.into_owned(),
            };
            return Err(FileError::content(
                &format!("{option} {}", path.display()),
                format!(
                    "is the same file as the argument {named}, which writing it would replace; give {option} another path"
                ),
            ));
        }
    }
    Ok(())
}

/// The long options of every command that take a value (`--out`, not `--pnp-check`), set
/// once from the command line's definition.
static VALUE_OPTIONS: std::sync::OnceLock<HashSet<String>> = std::sync::OnceLock::new();

/// Records which of `cmd`'s options (and its subcommands') take a value.
pub fn learn_value_options(cmd: &clap::Command) {
    fn walk(cmd: &clap::Command, set: &mut HashSet<String>) {
        for a in cmd.get_arguments() {
            if let (Some(long), true) = (a.get_long(), a.get_action().takes_values()) {
                set.insert(format!("--{long}"));
            }
        }
        for sub in cmd.get_subcommands() {
            walk(sub, set);
        }
    }
    let mut set = HashSet::new();
    walk(cmd, &mut set);
    let _ = VALUE_OPTIONS.set(set);
}

fn takes_value(arg: &str) -> bool {
    VALUE_OPTIONS.get().is_some_and(|s| s.contains(arg))
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

/// Refuses an output path that is an existing file inside one of `folders`, input folders the
/// command reads files from (`report --experiment exp --out exp/truth/run001.true.csv`): it
/// may be one of the files read. A new file there is no input, and is let through.
pub fn check_output_not_in_folder(
    path: &Path,
    option: &str,
    folders: &[PathBuf],
    whose: &str,
) -> Result<(), FileError> {
    let Some(target) = file_identity(path).filter(|t| t.is_file()) else {
        return Ok(());
    };
    for folder in folders {
        if file_identity(folder).is_some_and(|d| target.starts_with(d)) {
            return Err(FileError::content(
                &format!("{option} {}", path.display()),
                format!(
                    "is a file inside {} ({whose}), an input folder the command reads files from, which writing it could replace; give {option} a path outside it",
                    folder.display(),
                ),
            ));
        }
    }
    Ok(())
}

/// [`odocal_core::staging::check_output_dir`], after removing the leftovers of killed runs.
pub fn check_output_dir(path: &Path, option: &str) -> Result<(), FileError> {
    remove_stale_temporaries(path);
    staging::check_output_dir(path, option)
}

/// [`odocal_core::staging::write_atomic`], after removing the leftovers of killed runs.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<(), FileError> {
    remove_stale_temporaries(path);
    staging::write_atomic(path, bytes)
}

/// [`odocal_core::staging::staged_dir`], after removing the leftovers of killed runs.
pub fn staged_dir(target: &Path, option: &str) -> Result<PathBuf, FileError> {
    remove_stale_temporaries(target);
    staging::staged_dir(target, option)
}

/// The file `odocal synth` leaves in every folder it writes: a folder holding it is one synth
/// wrote, whose files a new synth run may replace.
pub const SYNTH_MARK: &str = ".synth-by-odocal";

/// What [`SYNTH_MARK`] says to whoever opens it.
pub const SYNTH_MARK_TEXT: &[u8] =
    b"written by odocal synth: its files may be replaced by the next run\n";

/// The synth output folders staged by [`synth_out_dir`]: (staged folder, `--out`, option).
static SYNTH_DIRS: Mutex<Vec<(PathBuf, PathBuf, String)>> = Mutex::new(Vec::new());

/// The refusal of a synth `--out` that holds `files` it would replace or delete, of a folder
/// synth did not write: a user's `view_07.png` beside the `view_00`…`02` rendered was
/// deleted, and `view_00.png` overwritten, exit 0.
fn refuse_replacing(out: &Path, option: &str, files: &[PathBuf]) -> FileError {
    let names: Vec<String> = files
        .iter()
        .filter_map(|f| f.file_name().map(|n| n.to_string_lossy().into_owned()))
        .collect();
    let more = if names.len() > 3 { ", …" } else { "" };
    FileError::content(
        &format!("{option} {}", out.display()),
        format!(
            "the folder holds {} file(s) synth would replace or delete ({}{more}) and was not written by synth: give a new folder, or one holding none of its outputs",
            names.len(),
            names.iter().take(3).cloned().collect::<Vec<_>>().join(", ")
        ),
    )
}

/// Refuses the synth outputs `names` in the folder `out` when one of them is there already
/// and synth did not write the folder (see [`refuse_replacing`]).
pub fn check_synth_files(out: &Path, names: &[&str], option: &str) -> Result<(), FileError> {
    if out.join(SYNTH_MARK).exists() {
        return Ok(());
    }
    let there: Vec<PathBuf> = names
        .iter()
        .map(|n| out.join(n))
        .filter(|p| p.exists())
        .collect();
    if there.is_empty() {
        Ok(())
    } else {
        Err(refuse_replacing(out, option, &there))
    }
}

/// [`staged_dir`] for an `odocal synth` output folder, marked as synth's; [`commit`] refuses
/// it when it would replace or delete files of a folder synth did not write.
pub fn synth_out_dir(out: &Path, option: &str) -> Result<PathBuf, FileError> {
    let dir = staged_dir(out, option)?;
    let mark = dir.join(SYNTH_MARK);
    std::fs::write(&mark, SYNTH_MARK_TEXT).map_err(|e| {
        FileError::content(&mark.display().to_string(), format!("cannot write: {e}"))
    })?;
    SYNTH_DIRS.lock().unwrap_or_else(|e| e.into_inner()).push((
        dir.clone(),
        out.to_path_buf(),
        option.to_string(),
    ));
    Ok(dir)
}

/// [`odocal_core::staging::commit`], after checking that no synth output replaces or deletes
/// a file of a folder synth did not write (the outputs are then discarded, nothing moved).
pub fn commit() -> Result<(), FileError> {
    let dirs = std::mem::take(&mut *SYNTH_DIRS.lock().unwrap_or_else(|e| e.into_inner()));
    for (tmp, out, option) in dirs.iter().cloned() {
        if !out.is_dir() || out.join(SYNTH_MARK).exists() || tmp == out {
            continue;
        }
        let replaced = staging::replaced_by_merge(&tmp, &out)?;
        if !replaced.is_empty() {
            discard();
            return Err(refuse_replacing(&out, &option, &replaced));
        }
    }
    for (tmp, out, _) in &dirs {
        if out.is_dir() && tmp != out {
            if let Err(e) = keep_others_in_subfolders(tmp, out) {
                discard();
                return Err(e);
            }
        }
    }
    staging::commit()
}

/// Carries into the staged synth folder `tmp` the files of `out`'s subfolders that the new
/// output neither replaces nor deletes as a stale part of its numbered series: a subfolder is
/// moved in whole, and `synth arena` used to delete the `cam1/camera.json` its own `next:`
/// hint had `calibrate` write there, and a user's `shared/NOTES.txt`, exit 0. Hard links where
/// the file system has them, copies elsewhere.
fn keep_others_in_subfolders(tmp: &Path, out: &Path) -> Result<(), FileError> {
    let io = |p: &Path, e: std::io::Error| {
        FileError::content(&p.display().to_string(), format!("cannot keep: {e}"))
    };
    let entries = std::fs::read_dir(tmp).map_err(|e| io(tmp, e))?;
    for entry in entries.filter_map(|e| e.ok()) {
        let (new, old) = (entry.path(), out.join(entry.file_name()));
        if new.is_dir() && old.is_dir() {
            keep_others(&new, &old)?;
        }
    }
    Ok(())
}

/// [`keep_others_in_subfolders`] for one subfolder `new` replacing `old`, and its own
/// subfolders in turn.
fn keep_others(new: &Path, old: &Path) -> Result<(), FileError> {
    let io = |p: &Path, e: std::io::Error| {
        FileError::content(&p.display().to_string(), format!("cannot keep: {e}"))
    };
    let replaced = staging::replaced_by_merge(new, old)?;
    let entries = std::fs::read_dir(old).map_err(|e| io(old, e))?;
    for entry in entries.filter_map(|e| e.ok()) {
        let (from, to) = (entry.path(), new.join(entry.file_name()));
        if from.is_dir() {
            std::fs::create_dir_all(&to).map_err(|e| io(&to, e))?;
            keep_others(&to, &from)?;
        } else if from.is_file()
            && !to.exists()
            && !replaced.contains(&from)
            && std::fs::hard_link(&from, &to).is_err()
        {
            std::fs::copy(&from, &to).map_err(|e| io(&from, e))?;
        }
    }
    Ok(())
}

/// Deletes the temporaries (`.odocal-<pid>-<n>.tmp`) beside `output` whose process no longer
/// exists: a run killed with SIGKILL, or before its interrupt handler could act, leaves its
/// unfinished outputs, and the next run writing to the same folder removes them. Each folder
/// is looked at once per run.
fn remove_stale_temporaries(output: &Path) {
    static SEEN: Mutex<Option<HashSet<PathBuf>>> = Mutex::new(None);
    let dir = match output.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    let mut seen = SEEN.lock().unwrap_or_else(|e| e.into_inner());
    if !seen
        .get_or_insert_with(HashSet::new)
        .insert(dir.to_path_buf())
    {
        return;
    }
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    for entry in entries.filter_map(|e| e.ok()) {
        let name = entry.file_name();
        let Some(pid) = name.to_str().and_then(temp_owner) else {
            continue;
        };
        if pid == std::process::id() || process_exists(pid) {
            continue;
        }
        let path = entry.path();
        let _ = if path.is_dir() {
            std::fs::remove_dir_all(&path)
        } else {
            std::fs::remove_file(&path)
        };
    }
}

/// Whether a process `pid` exists (signal 0 checks without sending; EPERM is another user's
/// live process). Where that cannot be asked, every process counts as alive.
fn process_exists(pid: u32) -> bool {
    #[cfg(unix)]
    {
        let Ok(pid) = libc::pid_t::try_from(pid) else {
            return true;
        };
        // SAFETY: kill with signal 0 only checks that the process exists.
        let r = unsafe { libc::kill(pid, 0) };
        r == 0 || std::io::Error::last_os_error().raw_os_error() != Some(libc::ESRCH)
    }
    #[cfg(not(unix))]
    {
        let _ = pid;
        true
    }
}

/// Deletes the command's temporary outputs when it is ended by SIGINT (Ctrl-C), SIGTERM or
/// SIGHUP, then ends it by that signal as before. The signals are blocked in every thread
/// (call this first in `main`, before any thread starts) and taken by one thread of its own,
/// where deleting files is safe, unlike in a signal handler. A signal that was ignored when
/// odocal started (`nohup`) stays ignored. Child processes start with the signals unblocked
/// (the standard library resets the mask).
#[cfg(unix)]
pub fn discard_on_interrupt() {
    const SIGNALS: [libc::c_int; 3] = [libc::SIGINT, libc::SIGTERM, libc::SIGHUP];
    // SAFETY: plain calls on a local, initialised signal set.
    let set = unsafe {
        let mut set: libc::sigset_t = std::mem::zeroed();
        libc::sigemptyset(&mut set);
        for sig in SIGNALS {
            libc::sigaddset(&mut set, sig);
        }
        if libc::pthread_sigmask(libc::SIG_BLOCK, &set, std::ptr::null_mut()) != 0 {
            return;
        }
        set
    };
    let waiter = std::thread::Builder::new()
        .name("odocal-interrupt".into())
        .spawn(move || loop {
            let mut sig: libc::c_int = 0;
            // SAFETY: `set` is initialised and `sig` is a valid place for the result.
            if unsafe { libc::sigwait(&set, &mut sig) } != 0 {
                continue;
            }
            discard();
            // SAFETY: restore the default action and deliver the signal to this thread,
            // unblocked here: the process ends as the signal asked, with its usual status.
            unsafe {
                libc::signal(sig, libc::SIG_DFL);
                let mut one: libc::sigset_t = std::mem::zeroed();
                libc::sigemptyset(&mut one);
                libc::sigaddset(&mut one, sig);
                libc::pthread_sigmask(libc::SIG_UNBLOCK, &one, std::ptr::null_mut());
                libc::raise(sig);
            }
            std::process::exit(128 + sig);
        });
    if waiter.is_err() {
        // No thread to take them: the signals end odocal as before.
        // SAFETY: unblocks the set blocked above.
        unsafe { libc::pthread_sigmask(libc::SIG_UNBLOCK, &set, std::ptr::null_mut()) };
    }
}

#[cfg(not(unix))]
pub fn discard_on_interrupt() {}

/// The file a path names, whether or not it exists yet: the canonical path, or the
/// canonical parent joined with the name. `None` when even the parent does not exist.
fn file_identity(path: &Path) -> Option<PathBuf> {
    if let Ok(c) = std::fs::canonicalize(path) {
        return Some(c);
    }
    // The deepest folder of the path that exists, resolved; the rest (folders the command
    // will create, and the file) applied to it as written, `..` included: `new/../x.csv` is
    // `x.csv` once `new` is made.
    for ancestor in path.ancestors().skip(1) {
        let existing = if ancestor.as_os_str().is_empty() {
            Path::new(".")
        } else {
            ancestor
        };
        let Ok(mut id) = std::fs::canonicalize(existing) else {
            continue;
        };
        for part in path.strip_prefix(ancestor).ok()?.components() {
            match part {
                std::path::Component::ParentDir => {
                    id.pop();
                }
                std::path::Component::CurDir => {}
                other => id.push(other),
            }
        }
        return Some(id);
    }
    None
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
