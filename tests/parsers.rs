//! Every parser of a file a user passes to odocal, fed arbitrary bytes and mutated valid
//! files: it returns a value or an error, never panics, and never takes more than a second.
//! The valid files under tests/data/parsers are real outputs of `make demo`, trimmed.

use std::path::Path;
use std::time::{Duration, Instant};

use proptest::prelude::*;

/// What a parser under test does with one input: Ok or Err, as long as it returns.
type Parser = fn(&str, &Path) -> bool;

fn sample(name: &str) -> String {
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data/parsers")
        .join(name);
    std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

/// Writes `text` to `dir/name` and runs `parse` on it, checking the time taken.
fn run(parse: Parser, text: &str, dir: &Path, name: &str) -> bool {
    let path = dir.join(name);
    std::fs::write(&path, text).expect("temporary directory is writable");
    let start = Instant::now();
    let ok = parse(text, &path);
    let took = start.elapsed();
    assert!(
        took < Duration::from_secs(1),
        "{name}: parsing took {took:?} on {} bytes",
        text.len()
    );
    ok
}

fn odometry(text: &str, _: &Path) -> bool {
    odocal_dataset::OdometryLog::parse_csv(text, "log.csv").is_ok()
}
fn trajectory(text: &str, _: &Path) -> bool {
    odocal_core::Trajectory::parse_csv(text, "traj.csv").is_ok()
}
fn manifest(_: &str, path: &Path) -> bool {
    odocal_dataset::Manifest::read(path).is_ok()
}
fn camera(_: &str, path: &Path) -> bool {
    odocal_calib::CameraFile::load(path).is_ok()
}
fn model(text: &str, _: &Path) -> bool {
    odocal_trainer::ModelFile::parse(text, "model.json").is_ok()
}
fn dataset(_: &str, path: &Path) -> bool {
    odocal_dataset::Dataset::read(path).is_ok()
}
fn map(text: &str, _: &Path) -> bool {
    odocal_lrf::Map::parse(text, "map.json").is_ok()
}
fn scans(text: &str, _: &Path) -> bool {
    odocal_lrf::parse_scans_csv(text, "scans.csv").is_ok()
}

/// Each parser with the name of its valid sample.
const PARSERS: [(Parser, &str); 10] = [
    (odometry, "odometry.csv"),
    (trajectory, "trajectory.csv"),
    (manifest, "manifest.json"),
    (manifest, "manifest.csv"),
    (camera, "camera.json"),
    (model, "model.json"),
    (dataset, "dataset.json"),
    (map, "map.json"),
    (scans, "scans.csv"),
    (odometry, "trajectory.csv"),
];

#[test]
fn valid_samples_parse() {
    let dir = tempfile::tempdir().expect("temporary directory");
    for (parse, name) in PARSERS.iter().take(9) {
        assert!(
            run(*parse, &sample(name), dir.path(), name),
            "{name} should parse"
        );
    }
}

/// Values a hand-edited or corrupted file tends to hold where a number belongs.
const ODD_VALUES: [&str; 16] = [
    "",
    "-",
    "NaN",
    "inf",
    "-inf",
    "1e308",
    "-1e308",
    "1e-320",
    "0",
    "-0",
    "1e300",
    "-1",
    "18446744073709551616",
    "9999999999999",
    "\"x\"",
    "null",
];

/// A mutation of a valid file: what it does, applied to the text.
#[derive(Debug, Clone)]
enum Mutation {
    /// Replaces the `k`-th number in the text by an odd value.
    Number(usize, usize),
    /// Deletes `len` bytes at fraction `at` of the text.
    Delete(f64, usize),
    /// Inserts a string at fraction `at`.
    Insert(f64, String),
    /// Repeats or drops a line.
    RepeatLine(usize),
    DropLine(usize),
    /// Swaps two lines.
    SwapLines(usize, usize),
    /// Cuts the file at fraction `at`.
    Truncate(f64),
}

fn mutation() -> impl Strategy<Value = Mutation> {
    prop_oneof![
        (0usize..400, 0..ODD_VALUES.len()).prop_map(|(k, v)| Mutation::Number(k, v)),
        (0.0..1.0f64, 1usize..40).prop_map(|(a, n)| Mutation::Delete(a, n)),
        (0.0..1.0f64, "[-,.0-9eE\\[\\]{}\":a-z\n ]{0,12}")
            .prop_map(|(a, s)| Mutation::Insert(a, s)),
        (0usize..200).prop_map(Mutation::RepeatLine),
        (0usize..200).prop_map(Mutation::DropLine),
        (0usize..200, 0usize..200).prop_map(|(a, b)| Mutation::SwapLines(a, b)),
        (0.0..1.0f64).prop_map(Mutation::Truncate),
    ]
}

/// Byte index at fraction `at` of `s`, moved back to a character boundary.
fn at(s: &str, f: f64) -> usize {
    let mut i = ((s.len() as f64) * f) as usize;
    while i > 0 && !s.is_char_boundary(i) {
        i -= 1;
    }
    i.min(s.len())
}

fn apply(text: &str, m: &Mutation) -> String {
    let mut lines: Vec<&str> = text.split('\n').collect();
    let n = lines.len().max(1);
    match m {
        Mutation::Number(k, v) => {
            let bytes = text.as_bytes();
            let mut starts = Vec::new();
            let mut i = 0;
            while i < bytes.len() {
                if bytes[i].is_ascii_digit() || bytes[i] == b'-' {
                    let s = i;
                    while i < bytes.len()
                        && (bytes[i].is_ascii_digit() || b"-+.eE".contains(&bytes[i]))
                    {
                        i += 1;
                    }
                    starts.push((s, i));
                } else {
                    i += 1;
                }
            }
            match starts.get(k % starts.len().max(1)) {
                Some(&(s, e)) => format!("{}{}{}", &text[..s], ODD_VALUES[*v], &text[e..]),
                None => text.to_string(),
            }
        }
        Mutation::Delete(f, len) => {
            let a = at(text, *f);
            let b = at(text, ((a + len) as f64 / text.len().max(1) as f64).min(1.0)).max(a);
            format!("{}{}", &text[..a], &text[b..])
        }
        Mutation::Insert(f, s) => {
            let a = at(text, *f);
            format!("{}{}{}", &text[..a], s, &text[a..])
        }
        Mutation::RepeatLine(k) => {
            let l = lines[k % n];
            lines.insert(k % n, l);
            lines.join("\n")
        }
        Mutation::DropLine(k) => {
            lines.remove(k % n);
            lines.join("\n")
        }
        Mutation::SwapLines(a, b) => {
            lines.swap(a % n, b % n);
            lines.join("\n")
        }
        Mutation::Truncate(f) => text[..at(text, *f)].to_string(),
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 256, failure_persistence: None, ..ProptestConfig::default() })]

    #[test]
    fn arbitrary_bytes_never_panic(bytes in proptest::collection::vec(any::<u8>(), 0..600), which in 0..PARSERS.len()) {
        let dir = tempfile::tempdir().expect("temporary directory");
        let text = String::from_utf8_lossy(&bytes);
        let (parse, name) = PARSERS[which];
        run(parse, &text, dir.path(), name);
    }

    #[test]
    fn mutated_valid_files_never_panic(ms in proptest::collection::vec(mutation(), 1..4), which in 0..PARSERS.len()) {
        let dir = tempfile::tempdir().expect("temporary directory");
        let (parse, name) = PARSERS[which];
        let mut text = sample(name);
        for m in &ms {
            text = apply(&text, m);
        }
        run(parse, &text, dir.path(), name);
    }
}
