//! Run manifests (the format README.md documents): one row per recording with its id, a video or a
//! trajectory, an odometry log and the commanded speed. JSON (`"format": "odocal.manifest/1"`,
//! `runs: [...]`) or CSV (`id,video,trajectory,odometry,speed_mps`, empty cells allowed).
//! Relative paths are relative to the manifest's directory.

use std::collections::HashSet;
use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use crate::error::{parse_json_with_format, read_text, DatasetError};
use odocal_core::csv_table;

/// The `format` tag of manifest JSON files.
pub const MANIFEST_FORMAT: &str = "odocal.manifest/1";

/// Free text left for people in a manifest ("comment", "notes" or "description"): read as
/// anything and dropped. Other unknown fields are still refused; these ask for nothing.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Note;

impl<'de> Deserialize<'de> for Note {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        serde::de::IgnoredAny::deserialize(d).map(|_| Note)
    }
}

/// The fields and CSV columns of notes, ignored.
const NOTE_FIELDS: [&str; 3] = ["comment", "notes", "description"];

/// One recording: a camera source and the robot's odometry log. Fields odocal does not read
/// (a row's own tag offset or clock offset, say) are refused rather than passed over, since
/// whoever wrote them expects them used; notes ([`Note`]) are the exception.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ManifestRow {
    /// Recording identifier; runs split from it are named `<id>.<k>` (k from 1).
    pub id: String,
    /// Ceiling video (to be tracked), if any.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub video: Option<String>,
    /// Camera trajectory CSV (already tracked, or synthetic), if any.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub trajectory: Option<String>,
    /// Odometry log CSV.
    pub odometry: String,
    /// Commanded speed, m/s (optional: the odometry's cruise speed is used when absent).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub speed_mps: Option<f64>,
    /// Notes for people, ignored.
    #[serde(default, skip_serializing)]
    pub comment: Note,
    /// Notes for people, ignored.
    #[serde(default, skip_serializing)]
    pub notes: Note,
    /// Notes for people, ignored.
    #[serde(default, skip_serializing)]
    pub description: Note,
}

/// A run manifest.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Manifest {
    /// Always [`MANIFEST_FORMAT`].
    pub format: String,
    /// The recordings.
    pub runs: Vec<ManifestRow>,
    /// Directory relative paths are resolved against (not serialised).
    #[serde(skip)]
    pub base_dir: PathBuf,
    /// Notes for people, ignored.
    #[serde(default, skip_serializing)]
    pub comment: Note,
    /// Notes for people, ignored.
    #[serde(default, skip_serializing)]
    pub notes: Note,
    /// Notes for people, ignored.
    #[serde(default, skip_serializing)]
    pub description: Note,
    /// The file it was read from (empty when made in memory), for messages.
    #[serde(skip)]
    source: PathBuf,
    /// Each row's line in a CSV file (none for JSON), for messages.
    #[serde(skip)]
    lines: Vec<u64>,
}

impl Manifest {
    /// A manifest of `runs` with paths relative to `base_dir`.
    pub fn new(runs: Vec<ManifestRow>, base_dir: &Path) -> Self {
        Self {
            format: MANIFEST_FORMAT.to_string(),
            runs,
            base_dir: base_dir.to_path_buf(),
            comment: Note,
            notes: Note,
            description: Note,
            source: PathBuf::new(),
            lines: Vec::new(),
        }
    }

    /// Where row `i` is written, for a message: its line of a CSV manifest, or its place
    /// and id in a JSON one.
    pub fn place_of(&self, i: usize) -> String {
        match self.lines.get(i) {
            Some(&l) if l > 0 => format!("line {l}"),
            _ => format!(
                "run {} (\"{}\")",
                i + 1,
                self.runs.get(i).map_or("", |r| r.id.as_str())
            ),
        }
    }

    /// The file the manifest was read from, as given (\"the manifest\" when made in memory).
    pub fn source_name(&self) -> String {
        if self.source.as_os_str().is_empty() {
            "the manifest".into()
        } else {
            self.source.display().to_string()
        }
    }

    /// Reads a manifest (`.csv` by extension, JSON otherwise) and checks its rows.
    pub fn read(path: &Path) -> Result<Self, DatasetError> {
        let text = read_text(path)?;
        let name = path.display().to_string();
        let base = path.parent().map(Path::to_path_buf).unwrap_or_default();
        let is_csv = path
            .extension()
            .is_some_and(|e| e.eq_ignore_ascii_case("csv"));
        let (mut m, lines) = if is_csv {
            parse_csv(&text, &name)?
        } else {
            let m: Manifest = parse_json_with_format(&text, &name, MANIFEST_FORMAT)?;
            let n = m.runs.len();
            (m, (0..n).map(|_| 0).collect())
        };
        m.base_dir = base;
        m.source = path.to_path_buf();
        m.lines = lines;
        m.check(&name)?;
        Ok(m)
    }

    fn check(&self, name: &str) -> Result<(), DatasetError> {
        if self.runs.is_empty() {
            return Err(DatasetError::content(name, "the manifest lists no runs"));
        }
        let mut seen = HashSet::new();
        for (i, r) in self.runs.iter().enumerate() {
            let at = self.place_of(i);
            let bad = |msg: String| DatasetError::content(name, format!("{at}: {msg}"));
            if r.id.trim().is_empty() {
                return Err(bad("empty run id".into()));
            }
            if !seen.insert(r.id.clone()) {
                return Err(bad(format!(
                    "run id \"{}\" appears twice; ids must be unique",
                    r.id
                )));
            }
            match (&r.video, &r.trajectory) {
                (Some(_), Some(_)) => {
                    return Err(bad("give a video or a trajectory, not both".into()))
                }
                (None, None) => return Err(bad("no video and no trajectory".into())),
                _ => {}
            }
            if r.odometry.trim().is_empty() {
                return Err(bad("no odometry log".into()));
            }
            if let Some(v) = r.speed_mps {
                if !(v.is_finite() && v > 0.0) {
                    return Err(bad(format!("speed {v} m/s is not a positive number")));
                }
            }
        }
        Ok(())
    }

    /// Resolves a path of the manifest against its directory.
    pub fn resolve(&self, p: &str) -> PathBuf {
        let q = Path::new(p);
        if q.is_absolute() {
            q.to_path_buf()
        } else {
            self.base_dir.join(q)
        }
    }

    /// Checks that every referenced file exists; the error names the run and the file.
    pub fn check_files(&self) -> Result<(), DatasetError> {
        // A file listed twice is one recording counted twice: its copies would sit on both
        // sides of every cross-validation split, and a trajectory or video paired with two
        // logs gives one of them another run's end point as its target.
        let mut seen: Vec<(PathBuf, &str, &str)> = Vec::with_capacity(3 * self.runs.len());
        for r in &self.runs {
            for (p, role) in [
                (Some(&r.odometry), "odometry log"),
                (r.video.as_ref(), "video"),
                (r.trajectory.as_ref(), "trajectory"),
            ] {
                let Some(p) = p else { continue };
                let full = self.resolve(p);
                // A video may be a folder of frames, as `odocal track` reads it; the dataset
                // has no --fps to time them by, so the folder must carry its timestamps.
                if role == "video" && full.is_dir() && !full.join(FOLDER_TIMESTAMPS).is_file() {
                    return Err(DatasetError::Mismatch(format!(
                        "run \"{}\": the frame folder {} listed as its video has no {FOLDER_TIMESTAMPS} to time its frames: add one (columns file,t: each frame's file and its time in seconds), or track the folder with `odocal track --fps` and list the result as the run's trajectory",
                        r.id,
                        full.display()
                    )));
                }
                let frame_folder = role == "video" && full.is_dir();
                if !(full.is_file() || frame_folder) {
                    let what = if full.is_dir() {
                        "is a folder, not a file"
                    } else {
                        "does not exist"
                    };
                    return Err(DatasetError::Mismatch(format!(
                        "run \"{}\": {role} {} listed in the manifest {what}",
                        r.id,
                        full.display()
                    )));
                }
                let file = std::fs::canonicalize(&full).unwrap_or(full);
                if let Some((_, first, first_role)) = seen.iter().find(|(f, _, _)| *f == file) {
                    if *first == r.id {
                        return Err(DatasetError::Mismatch(format!(
                            "run \"{first}\" lists {p} as both its {first_role} and its {role}: give each its own file"
                        )));
                    }
                    let same_role = *first_role == role;
                    return Err(DatasetError::Mismatch(format!(
                        "runs \"{first}\" and \"{}\" list the same file {} (as {}): one recording counted twice or another run's file pasted in; give each run its own {role}",
                        r.id,
                        p,
                        if same_role {
                            format!("their {role}")
                        } else {
                            format!("{first_role} and {role}")
                        }
                    )));
                }
                seen.push((file, &r.id, role));
            }
        }
        // A copy under another name is the same recording too (a video exported twice, a
        // log saved again, with Windows line ends or not).
        let sized: Vec<_> = seen
            .iter()
            .filter(|(f, _, _)| f.is_file())
            .filter_map(|(f, id, role)| Some((std::fs::metadata(f).ok()?.len(), f, *id, *role)))
            .collect();
        for (i, (size, a, first, first_role)) in sized.iter().enumerate() {
            for (size_b, b, id, role) in &sized[i + 1..] {
                if same_recording(a, *size, b, *size_b) {
                    return Err(DatasetError::Mismatch(format!(
                        "runs \"{first}\" and \"{id}\" list files holding the same recording, {} ({first_role}) and {} ({role}): one recording copied under two names is counted twice; give each run its own recording",
                        a.display(),
                        b.display()
                    )));
                }
            }
        }
        Ok(())
    }

    /// Every file the manifest lists (logs, videos, trajectories), resolved.
    pub fn files(&self) -> Vec<PathBuf> {
        self.runs
            .iter()
            .flat_map(|r| [Some(&r.odometry), r.video.as_ref(), r.trajectory.as_ref()])
            .flatten()
            .map(|p| self.resolve(p))
            .collect()
    }

    /// The manifest as pretty JSON.
    pub fn to_json(&self) -> String {
        serde_json::to_string_pretty(self).unwrap_or_default()
    }
}

/// The file that times the frames of a folder listed as a video (the tracker's own name for
/// it, `odocal_tracker`'s `FOLDER_TIMESTAMPS`).
const FOLDER_TIMESTAMPS: &str = "timestamps.csv";

/// The columns of a CSV manifest.
const MANIFEST_COLUMNS: [&str; 5] = ["id", "video", "trajectory", "odometry", "speed_mps"];

fn parse_csv(text: &str, name: &str) -> Result<(Manifest, Vec<u64>), DatasetError> {
    let Some(table) = csv_table(text, name)? else {
        return Ok((Manifest::new(Vec::new(), Path::new("")), Vec::new()));
    };
    let (line, header) = &table.header;
    let h: Vec<String> = header.iter().map(str::to_string).collect();
    if let Some((i, c)) = h.iter().enumerate().find(|(_, c)| {
        !MANIFEST_COLUMNS.contains(&c.as_str()) && !NOTE_FIELDS.contains(&c.as_str())
    }) {
        return Err(DatasetError::parse(
            name,
            *line,
            i as u64 + 1,
            format!(
                "column \"{c}\" is not one odocal reads (it reads {}, and ignores notes in {}); remove it, or give what it says through the options or files that carry it",
                MANIFEST_COLUMNS.join(","),
                NOTE_FIELDS.join(",")
            ),
        ));
    }
    for need in ["id", "odometry"] {
        if !h.iter().any(|c| c == need) {
            return Err(DatasetError::parse(
                name,
                *line,
                1,
                format!("header lacks column \"{need}\" (expected id,video,trajectory,odometry,speed_mps)"),
            ));
        }
    }
    let mut runs = Vec::new();
    let mut lines = Vec::new();
    for &(line, ref rec) in &table.rows {
        if rec.len() != h.len() {
            // A spreadsheet set to a decimal comma writes 0.2 as "0,2": two fields of digits
            // side by side, one column too many.
            let fields: Vec<&str> = rec.iter().collect();
            let digits = |f: &str| !f.is_empty() && f.chars().all(|c| c.is_ascii_digit());
            let hint = if rec.len() > h.len() {
                fields
                    .windows(2)
                    .find(|w| digits(w[0]) && digits(w[1]))
                    .map(|w| {
                        format!(
                            ": \"{0},{1}\" looks like the number {0}.{1} written with a decimal comma; write decimals with a point ({0}.{1}), as odocal reads comma-separated CSV",
                            w[0], w[1]
                        )
                    })
                    .unwrap_or_default()
            } else {
                String::new()
            };
            return Err(DatasetError::parse(
                name,
                line,
                rec.len().min(h.len()) as u64 + 1,
                format!("expected {} fields, found {}{hint}", h.len(), rec.len()),
            ));
        }
        let get = |col: &str| -> Option<String> {
            h.iter()
                .position(|c| c == col)
                .and_then(|i| rec.get(i))
                .filter(|v| !v.is_empty())
                .map(str::to_string)
        };
        let speed = match h.iter().position(|c| c == "speed_mps") {
            Some(i) => match rec.get(i).filter(|v| !v.is_empty()) {
                Some(v) => Some(v.parse::<f64>().map_err(|_| {
                    DatasetError::parse(
                        name,
                        line,
                        i as u64 + 1,
                        format!("\"{v}\" is not a number"),
                    )
                })?),
                None => None,
            },
            None => None,
        };
        runs.push(ManifestRow {
            id: get("id").unwrap_or_default(),
            video: get("video"),
            trajectory: get("trajectory"),
            odometry: get("odometry").unwrap_or_default(),
            speed_mps: speed,
            comment: Note,
            notes: Note,
            description: Note,
        });
        lines.push(line);
    }
    Ok((Manifest::new(runs, Path::new("")), lines))
}

impl Manifest {
    /// The files this manifest lists that `other` lists too: the same file by any path, or
    /// a copy (the same bytes, or the same CSV text with other line ends): a calibration set
    /// that holds the very recordings it is judged on.
    pub fn shared_files(&self, other: &Manifest) -> Vec<PathBuf> {
        let theirs = other.files();
        let size = |p: &Path| std::fs::metadata(p).map(|m| m.len()).ok();
        self.files()
            .into_iter()
            .filter(|mine| {
                let canon = std::fs::canonicalize(mine).ok();
                theirs.iter().any(|t| {
                    (canon.is_some() && std::fs::canonicalize(t).ok() == canon)
                        || match (size(mine), size(t)) {
                            (Some(a), Some(b)) => same_recording(mine, a, t, b),
                            _ => false,
                        }
                })
            })
            .collect()
    }
}

/// Whether two files of `size_a` and `size_b` bytes hold one recording: the same bytes, or
/// CSV text that differs only in its line ends (a log saved again on Windows). Only CSVs of
/// at most [`MAX_TEXT_COMPARED`] bytes are read as text.
fn same_recording(a: &Path, size_a: u64, b: &Path, size_b: u64) -> bool {
    if size_a == 0 || size_b == 0 {
        return false;
    }
    if size_a == size_b {
        return same_bytes(a, b);
    }
    let csv = |p: &Path| p.extension().is_some_and(|e| e.eq_ignore_ascii_case("csv"));
    if !(csv(a) && csv(b)) || size_a.max(size_b) > MAX_TEXT_COMPARED {
        return false;
    }
    let text = |p: &Path| {
        std::fs::read_to_string(p)
            .ok()
            .map(|t| t.replace("\r\n", "\n").trim_end().to_string())
    };
    matches!((text(a), text(b)), (Some(x), Some(y)) if x == y)
}

/// The largest CSV compared as text, bytes (a 200 ms log of a day is about 2 MB).
const MAX_TEXT_COMPARED: u64 = 64 << 20;

/// Whether two files hold the same bytes (false when either cannot be read).
fn same_bytes(a: &Path, b: &Path) -> bool {
    use std::io::Read;
    let (Ok(fa), Ok(fb)) = (std::fs::File::open(a), std::fs::File::open(b)) else {
        return false;
    };
    let (mut ra, mut rb) = (std::io::BufReader::new(fa), std::io::BufReader::new(fb));
    let (mut ba, mut bb) = (vec![0u8; 1 << 16], vec![0u8; 1 << 16]);
    loop {
        let (Ok(na), Ok(nb)) = (read_full(&mut ra, &mut ba), read_full(&mut rb, &mut bb)) else {
            return false;
        };
        if na != nb || ba[..na] != bb[..nb] {
            return false;
        }
        if na == 0 {
            return true;
        }
    }
    fn read_full(r: &mut impl Read, buf: &mut [u8]) -> std::io::Result<usize> {
        let mut n = 0;
        while n < buf.len() {
            match r.read(&mut buf[n..])? {
                0 => break,
                k => n += k,
            }
        }
        Ok(n)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn csv_manifest_and_errors() {
        let (m, _) = parse_csv(
            "id,trajectory,odometry,speed_mps\nr1,a.csv,b.csv,0.5\nr2,c.csv,d.csv,\n",
            "m.csv",
        )
        .unwrap();
        assert_eq!(m.runs.len(), 2);
        assert_eq!(m.runs[0].speed_mps, Some(0.5));
        assert_eq!(m.runs[1].speed_mps, None);
        let e = parse_csv(
            "id,trajectory,odometry,speed_mps\nr1,a.csv,b.csv,fast\n",
            "m.csv",
        )
        .unwrap_err();
        assert_eq!(e.to_string(), "m.csv:2:4: \"fast\" is not a number");
        // A decimal comma: "expected 4 fields, found 5", with no hint, before.
        let e = parse_csv(
            "id,trajectory,odometry,speed_mps\nr1,a.csv,b.csv,0,2\n",
            "m.csv",
        )
        .unwrap_err()
        .to_string();
        assert!(
            e.starts_with("m.csv:2:5: expected 4 fields, found 5: \"0,2\" looks like the number 0.2 written with a decimal comma"),
            "{e}"
        );
        let (mut m, l) = parse_csv("id,trajectory,odometry\nr1,a,b\nr1,c,d\n", "m.csv").unwrap();
        m.lines = l;
        let e = m.check("m.csv").unwrap_err();
        assert!(e
            .to_string()
            .contains("line 3: run id \"r1\" appears twice"));
    }
}
