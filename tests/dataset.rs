//! End-to-end tests of `odocal synth experiment` and `odocal dataset` (issue 4), without video.

mod common;

use std::path::Path;

use common::{fails, ok, p, rms, succeeded};
use odocal_dataset::{Dataset, OracleFile};

fn synth(dir: &Path, runs: usize, seed: u64, per: usize) {
    synth_with(dir, runs, seed, &["--runs-per-recording", &per.to_string()]);
}

/// `odocal dataset --manifest MANIFEST --out OUT` and `extra`, as arguments.
fn dataset_args<'a>(manifest: &'a Path, out: &'a Path, extra: &[&'a str]) -> Vec<&'a str> {
    let mut args = vec!["dataset", "--manifest", p(manifest), "--out", p(out)];
    args.extend_from_slice(extra);
    args
}

/// `odocal synth experiment` without video, with `extra` options.
fn synth_with(dir: &Path, runs: usize, seed: u64, extra: &[&str]) {
    let (runs, seed) = (runs.to_string(), seed.to_string());
    let mut args = vec![
        "synth",
        "experiment",
        "--out",
        p(dir),
        "--runs",
        &runs,
        "--seed",
        &seed,
        "--frames",
        "none",
    ];
    args.extend(extra);
    ok(&args);
}

fn build(dir: &Path) -> Dataset {
    let out = dir.join("dataset.json");
    ok(&dataset_args(
        &dir.join("manifest.json"),
        &out,
        &["--csv", p(&dir.join("dataset.csv"))],
    ));
    Dataset::read(&out).expect("dataset.json")
}

/// The acceptance experiment itself: 131 runs, seed 1, trajectories instead of video.
#[test]
fn default_experiment_meets_the_acceptance_bounds() {
    let dir = tempfile::tempdir().unwrap();
    synth(dir.path(), 131, 1, 1);
    let ds = build(dir.path());
    let oracle = OracleFile::read(&dir.path().join("truth/oracle.json")).unwrap();
    assert_eq!(ds.samples.len(), 131, "rejected: {:?}", ds.rejected);
    assert!(ds.rejected.is_empty());
    let mut target_err = Vec::new();
    let mut offset_err = Vec::new();
    let mut oracle_rel = Vec::new();
    for s in &ds.samples {
        let t = oracle.get(&s.run_id).expect("truth of run");
        target_err.push((s.target_m[0] - t.true_end_m[0]).hypot(s.target_m[1] - t.true_end_m[1]));
        offset_err.push(s.clock_offset_s - t.clock_offset_s);
        let e = oracle.end_m(s).unwrap();
        oracle_rel.push((e[0] - s.target_m[0]).hypot(e[1] - s.target_m[1]) / s.path_length_m);
    }
    let target_rms = rms(&target_err);
    assert!(target_rms <= 0.0025, "target RMS {target_rms} m");
    let off_rms = rms(&offset_err);
    let off_max = offset_err.iter().fold(0.0f64, |m, e| m.max(e.abs()));
    assert!(off_rms <= 0.005, "clock offset RMS error {off_rms} s");
    // Slow runs carry little timing information at 12 counts/rev and 200 ms rows.
    assert!(off_max <= 0.02, "largest clock offset error {off_max} s");
    let rel = ds.summary.raw_relative_error;
    assert!((0.08..=0.10).contains(&rel), "raw relative error {rel}");
    // The oracle (true effective geometry) is far better than raw odometry.
    let orc = oracle_rel.iter().sum::<f64>() / oracle_rel.len() as f64;
    assert!(orc < 0.6 * rel, "oracle {orc} vs raw {rel}");
    // Three speeds, path lengths about 1.5 m, 18 inputs each.
    for s in &ds.samples {
        assert_eq!(s.inputs.len(), 18);
        assert!((s.path_length_m - 1.48).abs() < 0.1, "{}", s.path_length_m);
        assert!([0.2, 0.5, 0.7].contains(&s.speed_mps));
    }
    let csv = std::fs::read_to_string(dir.path().join("dataset.csv")).unwrap();
    assert_eq!(csv.lines().count(), 132);
}

/// Several runs per recording (one log, one trajectory) are split by motion detection.
#[test]
fn long_recordings_are_split_into_runs() {
    let dir = tempfile::tempdir().unwrap();
    synth(dir.path(), 12, 5, 3);
    let ds = build(dir.path());
    let oracle = OracleFile::read(&dir.path().join("truth/oracle.json")).unwrap();
    assert_eq!(ds.summary.recordings, 4);
    assert_eq!(ds.samples.len(), 12, "rejected: {:?}", ds.rejected);
    assert_eq!(ds.samples[4].run_id, "rec002.2");
    let err: Vec<f64> = ds
        .samples
        .iter()
        .map(|s| {
            let t = oracle.get(&s.run_id).expect("truth of run");
            (s.target_m[0] - t.true_end_m[0]).hypot(s.target_m[1] - t.true_end_m[1])
        })
        .collect();
    assert!(rms(&err) <= 0.0025, "target RMS {}", rms(&err));
}

/// A recording of 6 runs (and one of 12): the robot is carried back between runs, which the
/// log cannot see, so its dead-reckoned path grows with every run (9 m for 6 runs of 1.5 m)
/// while the camera's stays at 1.5 m. That used to be refused as "a ratio of 0.172; is the
/// log paired with the right trajectory".
#[test]
fn recordings_of_many_runs_are_not_refused_as_mispaired() {
    for per in [6, 12] {
        let dir = tempfile::tempdir().unwrap();
        synth(dir.path(), per, 5, per);
        let ds = build(dir.path());
        assert_eq!(ds.summary.recordings, 1);
        assert_eq!(ds.samples.len(), per, "rejected: {:?}", ds.rejected);
    }
    // A --min-gap-s longer than the pauses joins the runs: rejected as missed frames (the
    // robot carried back out of view), which it names now.
    let dir = tempfile::tempdir().unwrap();
    synth(dir.path(), 3, 5, 3);
    let e = fails(&[
        "dataset",
        "--manifest",
        p(&dir.path().join("manifest.json")),
        "--out",
        p(&dir.path().join("ds.json")),
        "--min-gap-s",
        "8",
    ]);
    assert!(
        e.contains("--min-gap-s 8 joined 3 runs that pauses of 1 s or more keep apart"),
        "{e}"
    );
}

/// A robot's 16-bit encoder counters wrap (unsigned from 65 535 to 0, signed from 32 767 to
/// −32 768), or 8-bit ones every 256 ticks, within its logs: the dataset is the same as from the unwrapped logs, and says
/// where it unwrapped them. A count that flickers by a tick at rest (a wheel on a tick's
/// edge) before the first run made its log "start during the run's motion", and one a row
/// later moved t_b 0.4 s early (every input shifted): both are rest, and said.
#[test]
fn wrapped_encoder_counters_and_twitches_give_the_same_dataset() {
    let dir = tempfile::tempdir().unwrap();
    synth(dir.path(), 9, 5, 3);
    let plain = build(dir.path());
    assert!(plain.notes.is_empty(), "{:?}", plain.notes);
    let wrap = |name: &str, start: i64, signed: bool, bits: u32| {
        let turn = 1i64 << bits;
        let path = dir.path().join("runs").join(name);
        let text = std::fs::read_to_string(&path).unwrap();
        let mut out = String::new();
        for (i, line) in text.lines().enumerate() {
            if i == 0 {
                out.push_str(line);
            } else {
                let f: Vec<&str> = line.split(',').collect();
                let w = |v: &str| {
                    let c = (v.parse::<i64>().unwrap() + start).rem_euclid(turn);
                    if signed && c >= turn / 2 {
                        c - turn
                    } else {
                        c
                    }
                };
                out.push_str(&format!("{},{},{}", f[0], w(f[1]), w(f[2])));
            }
            out.push('\n');
        }
        std::fs::write(&path, out).unwrap();
    };
    wrap("rec001.odometry.csv", 65_400, false, 16);
    wrap("rec002.odometry.csv", 32_700, true, 16);
    // A small motor board's 8-bit counter, which wraps every few runs: its wraps were read as
    // counter resets and the log refused.
    wrap("rec003.odometry.csv", 0, false, 8);
    let unwrapped = build(dir.path());
    assert_eq!(unwrapped.samples, plain.samples);
    assert_eq!(unwrapped.notes.len(), 3, "{:?}", unwrapped.notes);
    for (n, (rec, bits)) in
        unwrapped
            .notes
            .iter()
            .zip([("rec001", "a 16"), ("rec002", "a 16"), ("rec003", "an 8")])
    {
        assert!(
            n.contains(&format!("{rec}.odometry.csv: encoder counts unwrapped: left_ticks wraps as {bits}-bit counter at line")),
            "{n}"
        );
    }
    // One tick more on the left wheel at rest, on the log's second row (line 3) or third.
    for line in [3, 4] {
        let path = dir.path().join("runs/rec002.odometry.csv");
        let text = std::fs::read_to_string(&path).unwrap();
        let mut lines: Vec<String> = text.lines().map(String::from).collect();
        let mut f: Vec<String> = lines[line - 1].split(',').map(String::from).collect();
        f[1] = (f[1].parse::<i64>().unwrap() + 1).to_string();
        lines[line - 1] = f.join(",");
        let flickered = lines.join("\n") + "\n";
        std::fs::write(&path, &flickered).unwrap();
        let ds = build(dir.path());
        assert_eq!(ds.samples, plain.samples, "a flicker on line {line}");
        assert!(
            ds.notes[1].contains(&format!(
                "encoder counts flickering by a tick at rest read as rest: line {line}"
            )),
            "{:?}",
            ds.notes
        );
        std::fs::write(&path, &text).unwrap();
    }
}

/// Adds `offset` to every count of the tick log at `path`, as a 64-bit counter that did not
/// start at 0 logs them.
fn offset_counts(path: &Path, offset: i128) {
    let text = std::fs::read_to_string(path).unwrap();
    let mut out = String::new();
    for (i, line) in text.lines().enumerate() {
        if i == 0 {
            out.push_str(line);
        } else {
            let f: Vec<&str> = line.split(',').collect();
            let c = |v: &str| v.parse::<i128>().unwrap() + offset;
            out.push_str(&format!("{},{},{}", f[0], c(f[1]), c(f[2])));
        }
        out.push('\n');
    }
    std::fs::write(path, out).unwrap();
}

/// A 64-bit counter's counts were read as doubles: near 10^16 two ticks apart (raw
/// odometry's error read as 31.04 % where it is 10.02 %, a right wheel fitted as 1.0042 where
/// it is 0.9762), near 2^62 1024 apart (every run "no motion"), and past 32 bits `correct`
/// refused the log as a glitch that `dataset` had taken.
#[test]
fn sixty_four_bit_encoder_counts_give_the_same_dataset_and_correction() {
    let dir = tempfile::tempdir().unwrap();
    synth(dir.path(), 6, 5, 1);
    let plain = build(dir.path());
    let model = dir.path().join("model.json");
    ok(&[
        "train",
        p(&dir.path().join("dataset.json")),
        "--out",
        p(&model),
        "--no-cv",
    ]);
    let log = dir.path().join("runs/run002.odometry.csv");
    let correct = || ok(&["correct", "--model", p(&model), p(&log)]);
    let corrected = correct();
    let text = std::fs::read_to_string(&log).unwrap();
    for offset in [5_000_000_000, 10_i128.pow(16) + 1, 1 << 62] {
        for rec in 1..=6 {
            offset_counts(
                &dir.path().join(format!("runs/run{rec:03}.odometry.csv")),
                offset,
            );
        }
        let wide = build(dir.path());
        assert_eq!(wide.samples, plain.samples, "counts from {offset}");
        assert!(wide.notes.is_empty(), "{:?}", wide.notes);
        assert_eq!(correct(), corrected, "counts from {offset}");
        for rec in 1..=6 {
            offset_counts(
                &dir.path().join(format!("runs/run{rec:03}.odometry.csv")),
                -offset,
            );
        }
    }
    assert_eq!(std::fs::read_to_string(&log).unwrap(), text);
}

/// A counter reset at rest between two runs costs no run; its note said "cut the log before
/// line 53, or record the run again; no run spans it", advice and its denial at once.
#[test]
fn a_counter_reset_between_runs_is_noted_as_harmless() {
    let dir = tempfile::tempdir().unwrap();
    synth(dir.path(), 6, 4, 3);
    let plain = build(dir.path());
    let path = dir.path().join("runs/rec001.odometry.csv");
    let text = std::fs::read_to_string(&path).unwrap();
    let rows: Vec<Vec<i64>> = text
        .lines()
        .skip(1)
        .map(|l| l.split(',').skip(1).map(|c| c.parse().unwrap()).collect())
        .collect();
    // The fourth row at rest after the first run's motion.
    let first_move = (1..rows.len()).find(|&i| rows[i] != rows[i - 1]).unwrap();
    let reset = (first_move..rows.len())
        .filter(|&i| rows[i] == rows[i - 1])
        .nth(3)
        .unwrap();
    let mut out = String::from(text.lines().next().unwrap());
    for (i, (line, r)) in text.lines().skip(1).zip(&rows).enumerate() {
        let t = line.split(',').next().unwrap();
        let base = if i >= reset {
            &rows[reset]
        } else {
            &vec![0, 0]
        };
        out.push_str(&format!("\n{t},{},{}", r[0] - base[0], r[1] - base[1]));
    }
    std::fs::write(&path, out + "\n").unwrap();
    let ds = build(dir.path());
    assert_eq!(ds.samples, plain.samples);
    let line = reset + 2;
    let [note] = &ds.notes[..] else {
        panic!("{:?}", ds.notes)
    };
    assert!(
        note.contains(&format!("line {line}: left_ticks drops from"))
            && note.contains(
                "the counter was reset (motor board restarted?); harmless: no run spans it"
            )
            && !note.contains("cut the log"),
        "{note}"
    );
}

/// A right encoder counting down on tours (`--layout windows`) made the odometry spin in
/// place: blamed on counts per period or a mispaired log ("a ratio of 9.895"), where
/// straight runs named the encoders' sense.
#[test]
fn an_encoder_counting_down_on_tours_is_named() {
    let dir = tempfile::tempdir().unwrap();
    let d = |s: &str| dir.path().join(s);
    ok(&[
        "synth",
        "experiment",
        "--paths",
        "tours",
        "--runs",
        "2",
        "--frames",
        "none",
        "--out",
        p(&d("tours")),
    ]);
    let windows = |out: &str| {
        dataset_args(&d("tours/manifest.json"), &d(out), &["--layout", "windows"])
            .into_iter()
            .map(String::from)
            .collect::<Vec<_>>()
    };
    let args = windows("w.json");
    ok(&args.iter().map(String::as_str).collect::<Vec<_>>());
    for rec in ["run001", "run002"] {
        offset_counts_by(&d(&format!("tours/runs/{rec}.odometry.csv")), &|_, r| -r);
    }
    let args = windows("n.json");
    let e = fails(&args.iter().map(String::as_str).collect::<Vec<_>>());
    assert!(
        e.contains("with one wheel's counts negated the odometry's path spans the camera's: is one encoder counting down as the robot drives forward?")
            && !e.contains("cumulative counts"),
        "{e}"
    );
}

/// Rewrites each count pair (left, right) of the tick log at `path` by `f`.
fn offset_counts_by(path: &Path, f: &dyn Fn(i128, i128) -> i128) {
    let text = std::fs::read_to_string(path).unwrap();
    let mut out = String::new();
    for (i, line) in text.lines().enumerate() {
        if i == 0 {
            out.push_str(line);
        } else {
            let c: Vec<&str> = line.split(',').collect();
            let (l, r) = (c[1].parse().unwrap(), c[2].parse().unwrap());
            out.push_str(&format!("{},{l},{}", c[0], f(l, r)));
        }
        out.push('\n');
    }
    std::fs::write(path, out).unwrap();
}

/// A robot file of another wheel base on tours: most windows were rejected as "the clock is
/// off here, or the log is not this run's", exit 0 with no summary; said, naming the file.
#[test]
fn most_windows_rejected_are_summed_up_naming_the_robot_file() {
    let dir = tempfile::tempdir().unwrap();
    let d = |s: &str| dir.path().join(s);
    ok(&[
        "synth",
        "experiment",
        "--paths",
        "tours",
        "--runs",
        "3",
        "--frames",
        "none",
        "--out",
        p(&d("tours")),
    ]);
    let robot = d("wide.json");
    std::fs::write(
        &robot,
        r#"{"format":"odocal.robot/1","wheel_diameter_m":0.043,"ticks_per_rev":12,"wheel_base_m":0.35,"period_s":0.2}"#,
    )
    .unwrap();
    let out = common::odocal(&dataset_args(
        &d("tours/manifest.json"),
        &d("w.json"),
        &["--layout", "windows", "--robot", p(&robot)],
    ));
    succeeded(&out);
    let err = String::from_utf8_lossy(&out.stderr);
    let ds = Dataset::read(&d("w.json")).unwrap();
    assert!(ds.rejected.len() > ds.samples.len(), "{err}");
    let warning = format!(
        "warning: {} of {} windows rejected (",
        ds.rejected.len(),
        ds.rejected.len() + ds.samples.len()
    );
    assert!(
        err.contains(&warning)
            && err.contains(&format!(
                "also what {} gives when its wheel_base_m or wheel_diameter_m is not the robot's",
                p(&robot)
            )),
        "{err}"
    );
}

#[test]
fn same_seed_same_bytes() {
    let a = tempfile::tempdir().unwrap();
    let b = tempfile::tempdir().unwrap();
    synth(a.path(), 3, 9, 1);
    synth(b.path(), 3, 9, 1);
    for f in [
        "runs/run002.odometry.csv",
        "runs/run002.trajectory.csv",
        "truth/oracle.json",
    ] {
        assert_eq!(
            std::fs::read(a.path().join(f)).unwrap(),
            std::fs::read(b.path().join(f)).unwrap(),
            "{f}"
        );
    }
}

#[test]
fn bad_input_gives_clear_errors_and_writes_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    synth(d, 2, 4, 1);
    let manifest = d.join("manifest.json");
    let out = d.join("ds.json");
    let run = |m: &Path| fails(&["dataset", "--manifest", p(m), "--out", p(&out)]);

    // Malformed odometry CSV: line and column.
    let log = d.join("runs/run001.odometry.csv");
    let good = std::fs::read_to_string(&log).unwrap();
    let mut lines: Vec<String> = good.lines().map(str::to_string).collect();
    lines[3] = "0.6,abc,4".into();
    std::fs::write(&log, lines.join("\n")).unwrap();
    let e = run(&manifest);
    assert!(
        e.contains("run001.odometry.csv:4:2: \"abc\" is not a number"),
        "{e}"
    );
    // Duplicated timestamp.
    let mut lines: Vec<String> = good.lines().map(str::to_string).collect();
    lines[3] = lines[2].clone();
    std::fs::write(&log, lines.join("\n")).unwrap();
    assert!(run(&manifest).contains(":4:1: duplicated timestamp"));
    // NaN.
    let mut lines: Vec<String> = good.lines().map(str::to_string).collect();
    lines[5] = "1,NaN,0".into();
    std::fs::write(&log, lines.join("\n")).unwrap();
    assert!(run(&manifest).contains(":6:2:"));
    std::fs::write(&log, &good).unwrap();

    // Ticks per period instead of cumulative counts in both logs: no run gives a sample,
    // and the error says how the logs may be read wrongly.
    let log2 = d.join("runs/run002.odometry.csv");
    let good2 = std::fs::read_to_string(&log2).unwrap();
    for (path, text) in [(&log, &good), (&log2, &good2)] {
        let mut prev = (0i64, 0i64);
        let per_period: Vec<String> = text
            .lines()
            .enumerate()
            .map(|(i, l)| {
                if i == 0 {
                    return l.to_string();
                }
                let f: Vec<&str> = l.split(',').collect();
                let (a, b) = (f[1].parse::<i64>().unwrap(), f[2].parse::<i64>().unwrap());
                let row = format!("{},{},{}", f[0], a - prev.0, b - prev.1);
                prev = (a, b);
                row
            })
            .collect();
        std::fs::write(path, per_period.join("\n")).unwrap();
    }
    let e = run(&manifest);
    assert!(
        e.contains("the odometry's 0.101 m") && e.contains("are the ticks cumulative counts"),
        "{e}"
    );
    std::fs::write(&log, &good).unwrap();
    std::fs::write(&log2, &good2).unwrap();
    // A log's times in milliseconds are its unit: the advice was to give the robot's own
    // file with --robot, which would not mend them.
    let ms: Vec<String> = good
        .lines()
        .enumerate()
        .map(|(i, l)| match l.split_once(',') {
            Some((t, rest)) if i > 0 => format!("{},{rest}", t.parse::<f64>().unwrap() * 1000.0),
            _ => l.to_string(),
        })
        .collect();
    std::fs::write(&log, ms.join("\n")).unwrap();
    let e = run(&manifest);
    assert!(
        e.contains("are the times in milliseconds?")
            && e.contains("write the log's times in seconds (divide them by 1000)")
            && !e.contains("--robot"),
        "{e}"
    );
    std::fs::write(&log, &good).unwrap();

    // A trajectory that cannot overlap its log.
    let traj = d.join("runs/run002.trajectory.csv");
    let full = std::fs::read_to_string(&traj).unwrap();
    let short: Vec<&str> = full.lines().take(20).collect();
    std::fs::write(&traj, short.join("\n")).unwrap();
    assert!(run(&manifest).contains("cannot overlap"));
    // A header and no rows read as "the trajectory covers 0.00 s; they cannot overlap".
    std::fs::write(&traj, full.lines().next().unwrap()).unwrap();
    let e = run(&manifest);
    assert!(
        e.contains("run \"run002\" (")
            && e.contains("run002.trajectory.csv): the trajectory has no rows (only its header)"),
        "{e}"
    );
    // The trajectory with `columns` rewritten by `f`, run through `dataset`.
    let rewritten = |columns: &[usize], f: &dyn Fn(f64) -> f64| -> String {
        let rows: Vec<String> = full
            .lines()
            .enumerate()
            .map(|(i, l)| {
                if i == 0 {
                    return l.to_string();
                }
                let mut c: Vec<String> = l.split(',').map(str::to_string).collect();
                for &k in columns {
                    c[k] = f(c[k].parse::<f64>().unwrap()).to_string();
                }
                c.join(",")
            })
            .collect();
        std::fs::write(&traj, rows.join("\n")).unwrap();
        run(&manifest)
    };
    // A trajectory in millimetres (motion capture often exports them): named as such.
    let e = rewritten(&[1, 2], &|v| v * 1000.0);
    assert!(
        e.contains("run \"run002\"") && e.contains("is the trajectory in millimetres?"),
        "{e}"
    );
    // A tag mounted turned 180° (or a motion-capture body facing backwards): every run used
    // to be accepted, with raw odometry "200 % off". A heading in degrees used to be blamed
    // on the pairing of the files. Both are named, and the trajectory file with them.
    let heading = |f: &dyn Fn(f64) -> f64| rewritten(&[3], f);
    let e = heading(&|t| t + std::f64::consts::PI);
    assert!(
        e.contains("run002.trajectory.csv)")
            && e.contains("the wheels drive the robot forwards (100 % of their travel) but the trajectory has it move backwards")
            && e.contains("is the tag (or laser scanner) mounted turned 180°"),
        "{e}"
    );
    let e = heading(&|t| t + std::f64::consts::FRAC_PI_2);
    assert!(
        e.contains("° off the direction the robot moves in")
            && e.contains("the robot moves at -90° to its heading"),
        "{e}"
    );
    let e = heading(&|t| t.to_degrees() + 360.0);
    assert!(e.contains("theta is in degrees"), "{e}");
    // Times in milliseconds used to read as "the trajectory never covers the log's motion
    // (too many missed frames?)".
    let e = rewritten(&[0], &|t| t * 1000.0);
    assert!(
        e.contains("run002.trajectory.csv)")
            && e.contains("the trajectory's rows are 33.3 apart")
            && e.contains("are its times in milliseconds?"),
        "{e}"
    );
    std::fs::write(&traj, &full).unwrap();

    // Missing file, video rows, wrong format.
    let text = std::fs::read_to_string(&manifest).unwrap();
    let m2 = d.join("m2.json");
    std::fs::write(&m2, text.replace("run002.trajectory.csv", "missing.csv")).unwrap();
    assert!(run(&m2).contains("missing.csv listed in the manifest does not exist"));
    // One recording listed twice (its copies would sit on both sides of every split).
    let m5 = d.join("m5.json");
    std::fs::write(
        &m5,
        text.replace("run002.odometry.csv", "run001.odometry.csv")
            .replace("run002.trajectory.csv", "run001.trajectory.csv"),
    )
    .unwrap();
    let e = run(&m5);
    assert!(
        e.contains("runs \"run001\" and \"run002\" list the same file runs/run001.odometry.csv (as their odometry log)"),
        "{e}"
    );
    // Another run's trajectory pasted in gave run002 run001's end point as its target, with
    // every run accepted.
    std::fs::write(
        &m5,
        text.replace("run002.trajectory.csv", "run001.trajectory.csv"),
    )
    .unwrap();
    let e = run(&m5);
    assert!(
        e.contains("runs \"run001\" and \"run002\" list the same file runs/run001.trajectory.csv (as their trajectory)"),
        "{e}"
    );
    // The same log copied under another name is the same recording.
    let runs = manifest.parent().unwrap().join("runs");
    std::fs::copy(
        runs.join("run001.odometry.csv"),
        runs.join("copy.odometry.csv"),
    )
    .unwrap();
    std::fs::write(
        &m5,
        text.replace("run002.odometry.csv", "copy.odometry.csv"),
    )
    .unwrap();
    let e = run(&m5);
    assert!(
        e.contains("runs \"run001\" and \"run002\" list files holding the same recording")
            && e.contains("copy.odometry.csv (odometry log)"),
        "{e}"
    );
    // Saved again with Windows line ends, it is still that recording.
    let log = std::fs::read_to_string(runs.join("run001.odometry.csv")).unwrap();
    std::fs::write(runs.join("copy.odometry.csv"), log.replace('\n', "\r\n")).unwrap();
    let e = run(&m5);
    assert!(
        e.contains("list files holding the same recording") && e.contains("copy.odometry.csv"),
        "{e}"
    );
    std::fs::remove_file(runs.join("copy.odometry.csv")).unwrap();
    let m3 = d.join("m3.csv");
    std::fs::write(
        &m3,
        "id,video,odometry\nv1,runs/run002.odometry.csv,runs/run001.odometry.csv\n",
    )
    .unwrap();
    let e = fails(&[
        "dataset",
        "--manifest",
        p(&m3),
        "--camera",
        p(&m3),
        "--out",
        p(&out),
    ]);
    assert!(e.contains("expected a camera.json"), "{e}");
    // A folder as --camera was "camera calibration … does not exist".
    let e = fails(&[
        "dataset",
        "--manifest",
        p(&m3),
        "--camera",
        p(d),
        "--out",
        p(&out),
    ]);
    assert!(
        e.contains(&format!(
            "camera calibration {} is a directory",
            d.display()
        )),
        "{e}"
    );
    // A frame folder as a run's video, as `odocal track` takes it, was refused as "a folder,
    // not a file". Without timestamps.csv the dataset cannot time its frames (it has no
    // --fps); with one, the row goes on to tracking (here stopped by the camera).
    let frames = d.join("frames");
    std::fs::create_dir_all(&frames).unwrap();
    std::fs::write(
        &m3,
        "id,video,odometry\nv1,frames,runs/run001.odometry.csv\n",
    )
    .unwrap();
    let camera_of = |c: &Path| {
        fails(&[
            "dataset",
            "--manifest",
            p(&m3),
            "--camera",
            p(c),
            "--out",
            p(&out),
        ])
    };
    let e = camera_of(&m3);
    assert!(
        e.contains("frames listed as its video has no timestamps.csv to time its frames: add one"),
        "{e}"
    );
    std::fs::write(frames.join("timestamps.csv"), "file,t\n").unwrap();
    let e = camera_of(&m3);
    assert!(e.contains("expected a camera.json"), "{e}");
    let m4 = d.join("m4.json");
    std::fs::write(&m4, r#"{"format":"odocal.dataset/1","runs":[]}"#).unwrap();
    assert!(run(&m4).contains("expected \"odocal.manifest/1\""));
    // A truth file that is not the experiment's oracle: refused before any work.
    let e = fails(&dataset_args(&manifest, &out, &["--truth", p(&manifest)]));
    assert!(e.contains("odocal.oracle/1"), "{e}");
    // Window options for a dataset of straight runs used to be ignored unsaid.
    let e = fails(&dataset_args(&manifest, &out, &["--window-s", "5"]));
    assert!(
        e.contains("--window-s is only used with --layout windows")
            && e.contains("add --layout windows, or leave it out"),
        "{e}"
    );
    assert!(!out.exists(), "nothing half-written");

    // And the intact experiment still builds; tag options given for a manifest without
    // videos are said to be unused rather than silently ignored.
    let res = common::odocal(&dataset_args(
        &manifest,
        &out,
        &["--tag-size", "0.12", "--rolling-shutter-s", "0.02"],
    ));
    common::succeeded(&res);
    let err = String::from_utf8_lossy(&res.stderr);
    assert!(
        err.contains("note: --tag-size 0.12, --rolling-shutter-s 0.02 not used"),
        "{err}"
    );
    assert_eq!(Dataset::read(&out).unwrap().samples.len(), 2);
    // A value that makes no sense is an error, unused or not, and no note comes before it.
    let res = common::odocal(&dataset_args(
        &manifest,
        &d.join("y.json"),
        &["--tag-yaw", "400"],
    ));
    assert_eq!(res.status.code(), Some(2));
    let err = String::from_utf8_lossy(&res.stderr);
    assert!(err.starts_with("odocal: error: --tag-yaw 400"), "{err}");
}

/// Wheels that turn the robot the other way from the camera: the log's left and right columns
/// swapped, or a trajectory in a mirrored floor frame. The speed (and so the alignment) is the
/// same either way, so every window of a tour used to be accepted, with raw odometry 63 % off
/// instead of 11 %. (Straight runs turn too little to tell: their few degrees of drift are the
/// odometry's own error.) Nothing is written over the dataset built before.
#[test]
fn wheels_that_turn_the_other_way_are_named() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    synth_with(d, 2, 3, &["--paths", "tours"]);
    let manifest = d.join("manifest.json");
    let out = d.join("ds.json");
    let args = [
        "dataset",
        "--manifest",
        p(&manifest),
        "--out",
        p(&out),
        "--layout",
        "windows",
    ];
    ok(&args);
    let built = std::fs::read(&out).unwrap();
    // Rewrites every row of a file but the header.
    let rewrite = |path: &Path, f: &dyn Fn(Vec<String>) -> Vec<String>| -> String {
        let text = std::fs::read_to_string(path).unwrap();
        let rows: Vec<String> = text
            .lines()
            .enumerate()
            .map(|(i, l)| {
                if i == 0 {
                    return l.to_string();
                }
                f(l.split(',').map(str::to_string).collect()).join(",")
            })
            .collect();
        std::fs::write(path, rows.join("\n")).unwrap();
        text
    };
    let log = d.join("runs/run001.odometry.csv");
    let good = rewrite(&log, &|c| vec![c[0].clone(), c[2].clone(), c[1].clone()]);
    let e = fails(&args);
    assert!(
        e.contains("the wheels turn the robot the other way from the trajectory")
            && e.contains("are the log's left and right columns swapped"),
        "{e}"
    );
    std::fs::write(&log, good).unwrap();
    let traj = d.join("runs/run001.trajectory.csv");
    let negate = |v: &str| (-v.parse::<f64>().unwrap()).to_string();
    rewrite(&traj, &|mut c| {
        c[2] = negate(&c[2]);
        c[3] = negate(&c[3]);
        c
    });
    let e = fails(&args);
    assert!(
        e.contains("run001.trajectory.csv") && e.contains("floor frame mirrored"),
        "{e}"
    );
    assert_eq!(std::fs::read(&out).unwrap(), built);
}

/// A robot file that is not the robot's: the alignment matches the speed profiles' shapes
/// whatever their scale, so a quadrature encoder's ×4 used to give a dataset with raw odometry
/// "74 %" off and every run accepted. The median ratio of the odometry's end points to the
/// camera's names it: 1.5 times or more is refused (with the likely mix-up), 20 % warned,
/// lengths in millimetres refused on reading.
/// Windows of tours turn: their odometry's end lies nearer or farther than the camera's by
/// the turns' heading error, not by the robot file. Compared end to end, three recordings of
/// one robot read 0.79 times the camera's and one was rejected as another robot's; the
/// windows that turned are no longer compared.
#[test]
fn windows_that_turn_are_not_taken_for_another_robot() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    synth_with(d, 3, 5, &["--paths", "tours", "--tour-legs", "2"]);
    let out = d.join("windows.json");
    let res = common::odocal(&dataset_args(
        &d.join("manifest.json"),
        &out,
        &["--layout", "windows"],
    ));
    let err = String::from_utf8_lossy(&res.stderr);
    assert!(res.status.success(), "{err}");
    assert!(
        !err.contains("times the camera's") && !err.contains("another robot"),
        "{err}"
    );
    let ds = Dataset::read(&out).expect("dataset.json");
    assert!(ds.rejected.is_empty(), "{:?}", ds.rejected);
}

#[test]
fn a_robot_file_of_another_robot_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    synth_with(d, 6, 2, &[]);
    let out = d.join("dataset.json");
    let robot = d.join("robot.json");
    let with = |diameter: f64, ticks: f64, base: f64| -> std::process::Output {
        std::fs::write(
            &robot,
            format!(
                r#"{{"format":"odocal.robot/1","wheel_diameter_m":{diameter},"ticks_per_rev":{ticks},"wheel_base_m":{base},"period_s":0.2}}"#
            ),
        )
        .unwrap();
        common::odocal(&dataset_args(
            &d.join("manifest.json"),
            &out,
            &["--robot", p(&robot)],
        ))
    };
    let refused = |o: std::process::Output, says: &str| {
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{err}");
        assert!(err.contains(says), "{says}: {err}");
        assert!(!out.exists(), "{says}: written anyway");
    };
    refused(
        with(0.043, 48.0, 0.1),
        "distances are 0.258 times the camera's (median over 6 samples) with this robot file; a factor of 4 is a quadrature encoder's",
    );
    refused(
        with(0.043, 48.0, 0.1),
        "ticks_per_rev = 48 the count of the log's ticks per wheel turn (12 would fit)?",
    );
    refused(
        with(0.0215, 12.0, 0.1),
        "a factor of 2 is a radius for a diameter or an encoder counting twice or half the edges (quadrature decoding x2, x4): is wheel_diameter_m = 0.0215 the wheels' diameter (0.043 would fit), and ticks_per_rev = 12 the count of the log's ticks per wheel turn (6 would fit)?",
    );
    // An encoder read on both edges: the same factor, the ticks named with the value.
    refused(
        with(0.043, 24.0, 0.1),
        "is wheel_diameter_m = 0.043 the wheels' diameter (0.086 would fit), and ticks_per_rev = 24 the count of the log's ticks per wheel turn (12 would fit)?",
    );
    refused(
        with(43.0, 12.0, 0.1),
        "wheel_diameter_m = 43 m is not a small wheeled robot's",
    );
    refused(
        with(0.043, 12.0, 100.0),
        "wheel_base_m = 100 m is not a small wheeled robot's",
    );
    // 30 % off is named but kept: an uncalibrated robot may be that far.
    let o = with(0.043 * 1.3, 12.0, 0.1);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    assert!(
        err.contains("warning:") && err.contains("distances are 1.3"),
        "{err}"
    );
    // The robot's own file says nothing.
    let o = with(0.043, 12.0, 0.1);
    assert!(o.status.success());
    assert!(!String::from_utf8_lossy(&o.stderr).contains("distances are"));
    std::fs::remove_file(&out).unwrap();
    // A parameter odocal does not read used to be passed over: a gear ratio its writer
    // expected applied. Notes are kept.
    let text = std::fs::read_to_string(&robot).unwrap();
    std::fs::write(
        &robot,
        text.replace("\"period_s\"", "\"gear_ratio\":30,\"period_s\""),
    )
    .unwrap();
    refused(
        common::odocal(&dataset_args(
            &d.join("manifest.json"),
            &out,
            &["--robot", p(&robot)],
        )),
        "\"gear_ratio\" is not a robot parameter odocal reads",
    );
    std::fs::write(
        &robot,
        text.replace("\"period_s\"", "\"name\":\"rover 2\",\"period_s\""),
    )
    .unwrap();
    succeeded(&common::odocal(&dataset_args(
        &d.join("manifest.json"),
        &out,
        &["--robot", p(&robot)],
    )));
    // So are manifest fields and columns it does not read.
    let manifest = std::fs::read_to_string(d.join("manifest.json")).unwrap();
    let m2 = d.join("m2.json");
    std::fs::write(
        &m2,
        manifest.replacen("\"id\"", "\"tag_offset\": \"0.05,0\", \"id\"", 1),
    )
    .unwrap();
    let e = fails(&dataset_args(&m2, &d.join("x.json"), &[]));
    assert!(e.contains("unknown field `tag_offset`"), "{e}");
    let m3 = d.join("m3.csv");
    std::fs::write(
        &m3,
        "id,odometry,trajectory,clock_offset_s\nr,a.csv,b.csv,0.1\n",
    )
    .unwrap();
    let e = fails(&dataset_args(&m3, &d.join("x.json"), &[]));
    assert!(
        e.contains("column \"clock_offset_s\" is not one odocal reads"),
        "{e}"
    );
    // A spreadsheet's semicolons read as one column named "id;odometry;…" to be removed.
    let m4 = d.join("m4.csv");
    std::fs::write(&m4, "id;odometry;trajectory\nr;a.csv;b.csv\n").unwrap();
    let e = fails(&dataset_args(&m4, &d.join("x.json"), &[]));
    assert!(
        e.contains(&format!("{}:1:1: the header \"id;odometry;trajectory\" is separated by semicolons, but odocal reads comma-separated CSV; separate the columns with commas", p(&m4))),
        "{e}"
    );
    // So do the logs and trajectories it lists.
    for kind in ["odometry", "trajectory"] {
        let file = d.join(format!("runs/run001.{kind}.csv"));
        let text = std::fs::read_to_string(&file).unwrap();
        std::fs::write(&file, text.replace(',', ";")).unwrap();
        let e = fails(&dataset_args(
            &d.join("manifest.json"),
            &d.join("x.json"),
            &[],
        ));
        assert!(
            e.contains("is separated by semicolons, but odocal reads comma-separated CSV")
                && e.contains(&format!("run001.{kind}.csv")),
            "{kind}: {e}"
        );
        std::fs::write(&file, text).unwrap();
    }
}

/// Notes for people are not fields odocal must use: "comment", "notes" and "description"
/// at the top of a JSON manifest, in its runs, and as CSV columns are read and ignored. A
/// byte order mark (Windows editors save one) used to read as "invalid JSON … line 1
/// column 1".
#[test]
fn manifests_take_notes_and_a_byte_order_mark() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    synth(d, 2, 4, 1);
    let plain = build(d);
    let manifest = d.join("manifest.json");
    let text = std::fs::read_to_string(&manifest).unwrap();
    let noted = text
        .replacen(
            "\"runs\"",
            "\"comment\": \"lab B, 3 May\", \"description\": {\"floor\": \"lino\"}, \"runs\"",
            1,
        )
        .replace(
            "\"id\"",
            "\"notes\": \"battery fresh\", \"comment\": \"\", \"id\"",
        );
    std::fs::write(&manifest, format!("\u{feff}{noted}")).unwrap();
    let noted_ds = build(d);
    assert_eq!(noted_ds.samples, plain.samples);
    // A field that is not a note is still refused.
    std::fs::write(
        &manifest,
        text.replacen("\"runs\"", "\"remark\": 1, \"runs\"", 1),
    )
    .unwrap();
    let e = fails(&dataset_args(&manifest, &d.join("x.json"), &[]));
    assert!(e.contains("unknown field `remark`"), "{e}");
    std::fs::write(&manifest, &text).unwrap();
    let csv = d.join("m.csv");
    std::fs::write(
        &csv,
        "id,trajectory,odometry,notes,description,comment\n\
         run001,runs/run001.trajectory.csv,runs/run001.odometry.csv,fresh battery,,x\n\
         run002,runs/run002.trajectory.csv,runs/run002.odometry.csv,,,\n",
    )
    .unwrap();
    let out = d.join("csv.json");
    ok(&dataset_args(&csv, &out, &[]));
    let from_csv = Dataset::read(&out).unwrap();
    assert_eq!(
        from_csv.samples.len(),
        2,
        "rejected: {:?}",
        from_csv.rejected
    );
}

/// Keeps the data rows of the trajectory at `path` whose 1-based index passes `keep` (and its header).
fn keep_data_rows(path: &Path, keep: &dyn Fn(usize) -> bool) {
    let text = std::fs::read_to_string(path).unwrap();
    let rows: Vec<&str> = text
        .lines()
        .enumerate()
        .filter(|&(i, _)| i == 0 || keep(i))
        .map(|(_, l)| l)
        .collect();
    std::fs::write(path, rows.join("\n") + "\n").unwrap();
}

/// The data row (1-based) of the trajectory at `path` where the robot moves fastest: well
/// inside a run.
fn fastest_row(path: &Path) -> usize {
    let text = std::fs::read_to_string(path).unwrap();
    let xy: Vec<(f64, f64)> = text
        .lines()
        .skip(1)
        .map(|l| {
            let f: Vec<f64> = l.split(',').map(|v| v.parse().unwrap()).collect();
            (f[1], f[2])
        })
        .collect();
    (1..xy.len() - 1)
        .max_by(|&a, &b| {
            let v = |i: usize| (xy[i + 1].0 - xy[i - 1].0).hypot(xy[i + 1].1 - xy[i - 1].1);
            v(a).total_cmp(&v(b))
        })
        .unwrap()
        + 1
}

/// The gap bridged between a trajectory's rows follows its rate: a 10 Hz laser trajectory
/// missing one scan mid-run (a 0.2 s gap) used to reject the run ("the camera's trajectory has
/// no rows for 0.20 s"); 10 missed frames of a 30 frames/s camera still reject it.
#[test]
fn the_bridged_trajectory_gap_follows_its_rate() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    // One run per recording: the fastest rows are then the run's, not a carry back.
    synth(d, 2, 3, 1);
    let traj = d.join("runs/run001.trajectory.csv");
    let full = std::fs::read_to_string(&traj).unwrap();
    // 10 Hz: every 3rd row, then one scan missed where the robot moves fastest.
    keep_data_rows(&traj, &|i| (i - 1) % 3 == 0);
    let mid = fastest_row(&traj);
    keep_data_rows(&traj, &|i| i != mid);
    let ds = build(d);
    assert_eq!(ds.samples.len(), 2, "rejected: {:?}", ds.rejected);
    // 30 frames/s with 10 frames missing mid-run.
    std::fs::write(&traj, &full).unwrap();
    let mid = fastest_row(&traj);
    keep_data_rows(&traj, &|i| !(mid - 5..mid + 5).contains(&i));
    let ds = build(d);
    assert_eq!((ds.samples.len(), ds.rejected.len()), (1, 1));
    assert!(
        ds.rejected[0]
            .reason
            .contains("the camera's trajectory has no rows for 0.37 s"),
        "{:?}",
        ds.rejected
    );
}

/// Outputs never replace what the manifest lists: a dataset written over a run's odometry log
/// or trajectory used to exit 0 with the log gone.
#[test]
fn outputs_never_replace_the_manifests_files() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    synth_with(d, 3, 2, &[]);
    let log = d.join("runs/run001.odometry.csv");
    let traj = d.join("runs/run002.trajectory.csv");
    let (log_before, traj_before) = (std::fs::read(&log).unwrap(), std::fs::read(&traj).unwrap());
    let manifest = d.join("manifest.json");
    let e = fails(&dataset_args(&manifest, &log, &[]));
    assert!(
        e.contains("run001.odometry.csv (listed in the manifest), which writing it would replace"),
        "{e}"
    );
    let e = fails(&dataset_args(
        &manifest,
        &d.join("o.json"),
        &["--csv", p(&traj)],
    ));
    assert!(e.contains("--csv"), "{e}");
    assert_eq!(std::fs::read(&log).unwrap(), log_before);
    assert_eq!(std::fs::read(&traj).unwrap(), traj_before);
    assert!(!d.join("o.json").exists());
}

/// Tours built as straight runs used to give "4 samples from 4 runs … mean path 17.401 m":
/// each run is now refused as not straight, naming --layout windows. A manifest speed in mm/s
/// used to be stored as given; it is refused against the camera's peak speed, and the right
/// label of a run too short to reach it is kept.
#[test]
fn runs_that_are_not_straight_runs_are_named() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    synth_with(d, 12, 1, &["--paths", "tours"]);
    let manifest = d.join("manifest.json");
    let out = d.join("dataset.json");
    // The second piece of run011 turns 174° in place, then drives 2.2 m: a turn in place adds
    // no path, so its end lay far enough from its start and it was taken as a straight run.
    let mut m: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&manifest).unwrap()).unwrap();
    m["runs"] = serde_json::json!([m["runs"][0].clone(), m["runs"][10].clone()]);
    std::fs::write(&manifest, m.to_string()).unwrap();
    let e = fails(&dataset_args(&manifest, &out, &[]));
    assert!(
        e.contains("run001: not a straight run: its path is")
            && e.contains("take --layout windows"),
        "{e}"
    );
    assert!(
        e.contains("run011.2: not a straight run: its heading turns 174° from its start (a straight run's stays within 45°)"),
        "{e}"
    );
    let straight = d.join("straight");
    synth_with(&straight, 3, 1, &[]);
    let manifest = straight.join("manifest.json");
    let mut m: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&manifest).unwrap()).unwrap();
    m["runs"][1]["speed_mps"] = serde_json::json!(500.0);
    // Another run's label: no unit is a factor of three or four off.
    let third = m["runs"][2]["speed_mps"].as_f64().unwrap();
    m["runs"][2]["speed_mps"] = serde_json::json!(if third > 0.4 { 0.2 } else { 0.7 });
    std::fs::write(&manifest, m.to_string()).unwrap();
    let o = common::odocal(&dataset_args(&manifest, &out, &[]));
    let said = String::from_utf8_lossy(&o.stdout);
    assert!(o.status.success());
    assert!(
        said.contains("rejected run002: the manifest's speed_mps 500 is")
            && said.contains("is it in mm/s? It must be"),
        "{said}"
    );
    assert!(
        said.contains("rejected run003: the manifest's speed_mps")
            && said.contains("is it another run's label (rows of the manifest mixed up)?"),
        "{said}"
    );
    // Two of three runs gone: said as a warning, not only listed.
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains("warning: 2 of 3 runs rejected (2 like run002: the manifest's speed_mps")
            && err.contains("the dataset holds a minority of the experiment"),
        "{err}"
    );
    // Runs of 0.4 m never reach 0.7 m/s at 1 m/s²: their right label was refused as mixed up
    // ("0.7 is 2.379 times the 0.294 m/s the camera saw the run average").
    let short = d.join("short");
    std::fs::create_dir_all(&short).unwrap();
    let config = short.join("r40.json");
    std::fs::write(
        &config,
        r#"{"format":"odocal.robotsim/1","protocol":{"run_distance_m":0.4}}"#,
    )
    .unwrap();
    synth_with(&short, 3, 1, &["--config", p(&config)]);
    let said = ok(&dataset_args(
        &short.join("manifest.json"),
        &short.join("dataset.json"),
        &[],
    ));
    assert!(said.contains("3 samples from 3 runs"), "{said}");
    // Recordings shorter than a window used to vanish from a windows dataset unsaid, and a
    // window longer than all of them read "all 0 rejected ()".
    let e = fails(&[
        "dataset",
        "--manifest",
        p(&manifest),
        "--layout",
        "windows",
        "--window-s",
        "1000",
        "--out",
        p(&out),
    ]);
    assert!(
        e.contains("all 3 rejected")
            && e.contains("fewer than one window of 5000 (--window-s 1000.0 s)"),
        "{e}"
    );
    // Windows a stride apart longer than every recording: the only window of each lies at
    // its start, where the robot stands still. It read "all 0 rejected ()".
    let e = fails(&[
        "dataset",
        "--manifest",
        p(&manifest),
        "--layout",
        "windows",
        "--window-s",
        "0.4",
        "--window-stride-s",
        "100",
        "--out",
        p(&out),
    ]);
    assert!(
        e.contains("every window lay where the robot stood still (windows of 0.4 s every 100.0 s)"),
        "{e}"
    );
}

/// Keeps the header and the rows of a CSV file whose first column `keep` accepts.
fn keep_rows(path: &Path, keep: &dyn Fn(f64) -> bool) {
    let text = std::fs::read_to_string(path).unwrap();
    let kept: Vec<&str> = text
        .lines()
        .enumerate()
        .filter(|(i, l)| *i == 0 || keep(l.split(',').next().unwrap().parse().unwrap()))
        .map(|(_, l)| l)
        .collect();
    std::fs::write(path, kept.join("\n") + "\n").unwrap();
}

/// Builds the dataset of the experiment in `dir`, expecting success; (dataset, stdout+stderr).
fn build_said(dir: &Path) -> (Dataset, String) {
    let out = dir.join("dataset.json");
    let o = common::odocal(&dataset_args(&dir.join("manifest.json"), &out, &[]));
    common::succeeded(&o);
    let said = format!(
        "{}{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    );
    (Dataset::read(&out).expect("dataset.json"), said)
}

/// The rejection of `run`, or a panic naming what was rejected.
fn rejection<'a>(ds: &'a Dataset, run: &str) -> &'a str {
    ds.rejected
        .iter()
        .find(|r| r.run_id == run)
        .map(|r| r.reason.as_str())
        .unwrap_or_else(|| panic!("{run} not rejected: {:?}", ds.rejected))
}

/// A camera that missed 2.5 s in the middle of one run used to stop the whole dataset ("the
/// trajectory never covers the log's motion"), after minutes of tracking with videos: that
/// run is rejected with where the camera lost it, the others kept.
#[test]
fn a_run_the_camera_partly_missed_is_rejected_alone() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    synth(d, 3, 1, 1);
    keep_rows(&d.join("runs/run001.trajectory.csv"), &|t| {
        !(3.5..=6.0).contains(&t)
    });
    let (ds, said) = build_said(d);
    assert_eq!(ds.samples.len(), 2, "{said}");
    let why = rejection(&ds, "run001");
    assert!(
        why.contains("the camera's trajectory has no rows for 2.5")
            && why.contains("(3.47-6.0")
            && why.contains("during this run (missed frames?"),
        "{why}"
    );
    assert!(
        said.contains("rejected run001: the camera's trajectory has no rows"),
        "{said}"
    );
}

/// Recordings of three runs whose camera stopped early or started late: the log's motion did
/// not fit inside the trajectory, so the whole dataset failed ("they cannot overlap"), or a
/// wrong clock offset rejected all three runs ("correlation -0.11"). The runs the camera saw
/// are kept, at the true clock offset; the others are rejected, saying where the trajectory
/// starts or ends.
#[test]
fn a_camera_that_started_late_or_stopped_early_keeps_the_runs_it_saw() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    synth(d, 9, 1, 3);
    let traj = d.join("runs/rec001.trajectory.csv");
    let full = std::fs::read_to_string(&traj).unwrap();
    let oracle = OracleFile::read(&d.join("truth/oracle.json")).unwrap();
    for (keep, missed, says) in [
        (
            &(|t: f64| t < 20.0) as &dyn Fn(f64) -> bool,
            "rec001.3",
            "the camera's trajectory ends at 19.43 s, before this run (the log puts this run at 22.5",
        ),
        (
            &|t: f64| t > 11.0,
            "rec001.1",
            "the camera's trajectory starts at 11.03 s, after this run (the log puts this run at 2.3",
        ),
        (
            &|t: f64| t > 4.0,
            "rec001.1",
            "the camera's trajectory starts at 4.03 s, during this run",
        ),
    ] {
        std::fs::write(&traj, &full).unwrap();
        keep_rows(&traj, keep);
        let (ds, said) = build_said(d);
        assert_eq!(ds.samples.len(), 8, "{missed}: {said}");
        let why = rejection(&ds, missed);
        assert!(why.contains(says), "{missed}: {why}");
        for s in &ds.samples {
            let truth = oracle.get(&s.run_id).unwrap().clock_offset_s;
            assert!(
                (s.clock_offset_s - truth).abs() < 0.02,
                "{}: offset {} against {truth}",
                s.run_id,
                s.clock_offset_s
            );
        }
    }
    // A camera that stopped after two whole runs of four: the log's motion, rests between
    // runs included, spans 35.6 s, and the camera's 19.4 s held 17.1 s of it at its offset,
    // under half, so no offset was found ("correlation 0.601") and all four were refused.
    let four = d.join("four");
    synth(&four, 4, 1, 4);
    keep_rows(&four.join("runs/rec001.trajectory.csv"), &|t| t < 20.0);
    let (ds, said) = build_said(&four);
    let four_oracle = OracleFile::read(&four.join("truth/oracle.json")).unwrap();
    assert_eq!(ds.samples.len(), 2, "{said}");
    for s in &ds.samples {
        let truth = four_oracle.get(&s.run_id).unwrap();
        let off_m =
            (s.target_m[0] - truth.true_end_m[0]).hypot(s.target_m[1] - truth.true_end_m[1]);
        assert!(off_m < 0.002, "{}: target {off_m} m off", s.run_id);
        assert!(
            (s.clock_offset_s - truth.clock_offset_s).abs() < 0.01,
            "{}",
            s.run_id
        );
    }
    for run in ["rec001.3", "rec001.4"] {
        let why = rejection(&ds, run);
        assert!(
            why.contains("the camera's trajectory ends at 19.43 s, before this run"),
            "{why}"
        );
    }
    // Less than half of the log's motion inside the trajectory is another recording's file.
    std::fs::write(&traj, &full).unwrap();
    keep_rows(&traj, &|t| t < 8.0);
    let e = fails(&dataset_args(
        &d.join("manifest.json"),
        &d.join("dataset.json"),
        &[],
    ));
    assert!(
        e.contains("rec001: the log moves for 23.00 s but the trajectory spans only 7.97 s")
            && e.contains("check that the manifest pairs"),
        "{e}"
    );
}

/// Runs alike in speed and rest: a camera that saw two of three fits the log at two clock
/// offsets, one run apart, and which runs it saw cannot be told. The recording's runs are
/// rejected saying so, not given a guessed offset.
#[test]
fn a_partly_seen_recording_of_runs_alike_is_not_guessed() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    synth(d, 3, 1, 1);
    let truth: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(d.join("truth/experiment.json")).unwrap())
            .unwrap();
    let mut config = truth["config"].clone();
    config["protocol"]["speeds_mps"] = serde_json::json!([0.5]);
    let config_path = d.join("alike.json");
    std::fs::write(&config_path, config.to_string()).unwrap();
    let alike = d.join("alike");
    synth_with(
        &alike,
        6,
        1,
        &["--runs-per-recording", "3", "--config", p(&config_path)],
    );
    keep_rows(&alike.join("runs/rec001.trajectory.csv"), &|t| t < 14.0);
    let (ds, _) = build_said(&alike);
    assert_eq!(ds.samples.len(), 3, "{:?}", ds.rejected);
    for run in ["rec001.1", "rec001.2", "rec001.3"] {
        let why = rejection(&ds, run);
        assert!(
            why.contains(
                "the camera saw only part of the log's motion, and it fits two clock offsets"
            ) && why.contains("which runs the camera saw cannot be told"),
            "{why}"
        );
    }
    // Two runs at 0.2 m/s, the camera stopped after the first or started before the second:
    // at its own offset it overlapped the log's motion (rests included) a hair under half,
    // so only the other run's offset was searched, and that run's log was paired with the
    // camera's run (offset -11.3 s against 0.98 s, target 69 mm off), exit 0.
    config["protocol"]["speeds_mps"] = serde_json::json!([0.2]);
    std::fs::write(&config_path, config.to_string()).unwrap();
    let two = d.join("two");
    synth_with(
        &two,
        2,
        1,
        &["--runs-per-recording", "2", "--config", p(&config_path)],
    );
    let traj = two.join("runs/rec001.trajectory.csv");
    let full = std::fs::read_to_string(&traj).unwrap();
    for (keep, seen) in [
        (
            &(|t: f64| t < 12.5) as &dyn Fn(f64) -> bool,
            "s the log's 1.4-10.5 s",
        ),
        (&|t: f64| t >= 12.5, "s the log's 12.7-21.6 s"),
    ] {
        std::fs::write(&traj, &full).unwrap();
        keep_rows(&traj, keep);
        let e = fails(&dataset_args(
            &two.join("manifest.json"),
            &two.join("dataset.json"),
            &[],
        ));
        assert!(
            e.contains("rec001.1: the camera saw only part of the log's motion, and it fits two clock offsets")
                && e.contains(seen)
                && e.contains("which runs the camera saw cannot be told"),
            "{e}"
        );
    }
}

/// The warning that most runs' logs never followed the camera used to count recordings as
/// runs ("6 of 3 runs rejected"); it gives the runs' totals.
#[test]
fn the_warning_on_logs_that_never_follow_counts_runs() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    synth(d, 9, 1, 3);
    // Two of the three logs played backwards: the same wheel travel, another speed profile.
    for rec in ["rec001", "rec002"] {
        let path = d.join(format!("runs/{rec}.odometry.csv"));
        let text = std::fs::read_to_string(&path).unwrap();
        let rows: Vec<Vec<i64>> = text
            .lines()
            .skip(1)
            .map(|l| l.split(',').skip(1).map(|v| v.parse().unwrap()).collect())
            .collect();
        let times: Vec<&str> = text
            .lines()
            .skip(1)
            .map(|l| l.split(',').next().unwrap())
            .collect();
        let mut out = String::from("t,left_ticks,right_ticks\n");
        let last = rows.len() - 1;
        for (i, t) in times.iter().enumerate() {
            let (l, r) = (
                rows[last][0] - rows[last - i][0],
                rows[last][1] - rows[last - i][1],
            );
            out.push_str(&format!("{t},{l},{r}\n"));
        }
        std::fs::write(&path, out).unwrap();
    }
    let (ds, said) = build_said(d);
    assert_eq!(ds.rejected.len(), 6, "{said}");
    assert!(
        said.contains("warning: 6 of 9 runs rejected; the log's speed never followed the camera's in 6 of the 9 runs: are the ticks cumulative counts"),
        "{said}"
    );
}

/// A log with rows lost: windows are cut by row count, so a 1.6 s step read as one 200 ms
/// step of 3.5 m/s, and the path model trained on it took 3.55 m/s for its largest wheel
/// speed (0.79 without), so `correct` accepted logs far too fast. The windows spanning the gap
/// are rejected naming its rows, as `correct` names them; a straight run spanning one too.
#[test]
fn windows_and_runs_spanning_a_gap_in_the_log_are_rejected_and_jitter_is_not() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    synth_with(d, 3, 1, &["--paths", "tours"]);
    let log = d.join("runs/run001.odometry.csv");
    let text = std::fs::read_to_string(&log).unwrap();
    let cut: Vec<&str> = text
        .lines()
        .enumerate()
        .filter(|(i, _)| !(99..106).contains(i))
        .map(|(_, l)| l)
        .collect();
    std::fs::write(&log, cut.join("\n") + "\n").unwrap();
    let out = d.join("windows.json");
    let said = ok(&[
        "dataset",
        "--manifest",
        p(&d.join("manifest.json")),
        "--layout",
        "windows",
        "--out",
        p(&out),
    ]);
    let ds = Dataset::read(&out).unwrap();
    let gap = "lines 99 and 100 are 1.600 s apart, but the robot logs every 0.200 s";
    let (gap_rows, _) = gap.split_once(", but").unwrap();
    let spanning: Vec<&str> = ds
        .rejected
        .iter()
        .filter(|r| r.reason.contains(gap))
        .map(|r| r.run_id.as_str())
        .collect();
    assert_eq!(spanning, ["run001.w0050", "run001.w0075"], "{said}");
    let fastest = ds
        .samples
        .iter()
        .flat_map(|s| s.inputs.iter())
        .fold(0.0f64, |m, d| m.max(d.abs()))
        / 0.2;
    assert!(fastest < 1.0, "a wheel at {fastest} m/s");
    let model = d.join("path-model.json");
    ok(&["train", p(&out), "--out", p(&model)]);
    let e = fails(&[
        "correct",
        "--model",
        p(&model),
        p(&log),
        "--out",
        p(&d.join("c.csv")),
    ]);
    assert!(e.contains(gap_rows), "{e}");

    let straight = d.join("straight");
    synth(&straight, 2, 1, 1);
    let log = straight.join("runs/run002.odometry.csv");
    let text = std::fs::read_to_string(&log).unwrap();
    let cut: Vec<&str> = text
        .lines()
        .enumerate()
        .filter(|(i, _)| !(19..24).contains(i))
        .map(|(_, l)| l)
        .collect();
    std::fs::write(&log, cut.join("\n") + "\n").unwrap();
    // The other run's log stamps a row 120 ms late and the next on time (a logger's jitter,
    // counts read as stamped): that run is kept.
    let log = straight.join("runs/run001.odometry.csv");
    let text = std::fs::read_to_string(&log).unwrap();
    let mut lines: Vec<String> = text.lines().map(String::from).collect();
    let (t, counts) = lines[15].split_once(',').unwrap();
    lines[15] = format!("{:.3},{counts}", t.parse::<f64>().unwrap() + 0.12);
    std::fs::write(&log, lines.join("\n") + "\n").unwrap();
    let (ds, _) = build_said(&straight);
    assert_eq!(ds.samples.len(), 1);
    assert_eq!(ds.samples[0].run_id, "run001");
    let why = rejection(&ds, "run002");
    assert!(
        why.contains(
            "the log's lines 19 and 20 are 1.200 s apart, but the robot logs every 0.200 s"
        ),
        "{why}"
    );
}

/// `--truth` of another experiment with the same run ids: every run has a truth, so the
/// comparison used to print "targets RMS 137 mm, clock offsets RMS 887 ms" as if it judged
/// the dataset. Far beyond the dataset's own error (0.34 mm, 4 ms here), it is named.
#[test]
fn the_truth_of_another_experiment_is_named() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let (e1, e2) = (d.join("e1"), d.join("e2"));
    synth_with(&e1, 12, 2, &[]);
    synth_with(&e2, 12, 3, &[]);
    let run = |truth: &Path| {
        let o = common::odocal(&dataset_args(
            &e1.join("manifest.json"),
            &d.join("ds.json"),
            &["--truth", p(truth)],
        ));
        succeeded(&o);
        String::from_utf8_lossy(&o.stderr).into_owned()
    };
    let err = run(&e2.join("truth/oracle.json"));
    assert!(
        err.contains("warning: the dataset is ")
            && err.contains("is that the truth of the experiment the dataset was built from?"),
        "{err}"
    );
    let err = run(&e1.join("truth/oracle.json"));
    assert!(!err.contains("warning"), "{err}");
}

/// The data rows (0-based) of the tick log at `path` where a wheel's count changes, grouped
/// into runs (apart by a second of rest or more).
fn moving_rows_by_run(path: &Path) -> Vec<Vec<usize>> {
    let text = std::fs::read_to_string(path).unwrap();
    let rows: Vec<Vec<f64>> = text
        .lines()
        .skip(1)
        .map(|l| l.split(',').map(|v| v.parse().unwrap()).collect())
        .collect();
    let mut runs: Vec<Vec<usize>> = Vec::new();
    for k in 1..rows.len() {
        if rows[k][1] == rows[k - 1][1] && rows[k][2] == rows[k - 1][2] {
            continue;
        }
        match runs.last_mut() {
            Some(run) if rows[k - 1][0] - rows[*run.last().unwrap()][0] < 1.0 => run.push(k),
            _ => runs.push(vec![k]),
        }
    }
    runs
}

/// Adds `by` ticks to the left count of the tick log at `path` on the data rows (0-based)
/// that `which` accepts.
fn add_left_ticks(path: &Path, which: &dyn Fn(usize) -> bool, by: f64) {
    add_to_column(path, 1, which, by);
}

/// Adds `by` to column `col` of the data rows (counted from 0) of the CSV at `path` that
/// `which` accepts.
fn add_to_column(path: &Path, col: usize, which: &dyn Fn(usize) -> bool, by: f64) {
    let text = std::fs::read_to_string(path).unwrap();
    let lines: Vec<String> = text
        .lines()
        .enumerate()
        .map(|(i, l)| {
            if i == 0 || !which(i - 1) {
                return l.to_string();
            }
            let mut f: Vec<String> = l.split(',').map(str::to_string).collect();
            f[col] = (f[col].parse::<f64>().unwrap() + by).to_string();
            f.join(",")
        })
        .collect();
    std::fs::write(path, lines.join("\n") + "\n").unwrap();
}

/// One log timed in Unix seconds among logs counting from their start: its runs' t_b and t_e,
/// inputs of the net, lay 1.7e9 s outside the others', and a model trained on them put the
/// linear baseline's error at 1e9 %, unsaid. Its recording is rejected, naming the clock.
#[test]
fn a_log_on_another_clock_is_rejected() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    synth_with(d, 6, 3, &[]);
    add_to_column(&d.join("runs/run002.odometry.csv"), 0, &|_| true, 1.7e9);
    let (ds, said) = build_said(d);
    assert_eq!(ds.samples.len(), 5, "{said}");
    assert!(
        rejection(&ds, "run002").contains(
            "its log's first run starts at 1700000001 s on the robot's clock, where the 6 logs' first runs start at"
        ) && rejection(&ds, "run002").contains("is this log timed on another clock (Unix time)?"),
        "{said}"
    );
    assert!(ds.samples.iter().all(|s| s.inputs[16] < 100.0));
}

/// Recordings of three runs, a counter glitch in the middle of each one's second run: in
/// rec001 the left counter jumps by 40000 and counts on from there, in rec002 one reading is
/// 40000 off and the next is back. Either rejected all three runs of its recording, although
/// the glitch touched one. The jump rejects its run alone, naming the rows; the garbled
/// reading, told for certain, is read between its neighbours and named; every other run gives
/// its sample as a clean log does, checked against the truth.
#[test]
fn a_counter_glitch_spoils_the_run_across_it_not_its_recording() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    synth(d, 6, 2, 3);
    let (log1, log2) = (
        d.join("runs/rec001.odometry.csv"),
        d.join("runs/rec002.odometry.csv"),
    );
    let runs1 = moving_rows_by_run(&log1);
    let runs2 = moving_rows_by_run(&log2);
    assert_eq!((runs1.len(), runs2.len()), (3, 3));
    let (jump, spike) = (runs1[1][runs1[1].len() / 2], runs2[1][runs2[1].len() / 2]);
    add_left_ticks(&log1, &|k| k >= jump, 40000.0);
    add_left_ticks(&log2, &|k| k == spike, 40000.0);
    let (ds, said) = build_said(d);
    // The file's lines: the header is line 1, data row k is line k + 2.
    let (jump_line, spike_line) = (jump + 2, spike + 2);
    let why = rejection(&ds, "rec001.2");
    assert!(
        why.contains(&format!(
            "rec001.odometry.csv: lines {} and {jump_line}: the left wheel goes from ",
            jump_line - 1
        )) && why.contains("the run's travel across it is unknown"),
        "{why}"
    );
    assert_eq!(ds.rejected.len(), 1, "{:?}", ds.rejected);
    assert!(
        said.contains(&format!(
            "rec002.odometry.csv: line {spike_line}: left_ticks reads "
        )) && said.contains("a garbled reading, read as"),
        "{said}"
    );
    let oracle = OracleFile::read(&d.join("truth/oracle.json")).unwrap();
    let ids: Vec<&str> = ds.samples.iter().map(|s| s.run_id.as_str()).collect();
    assert_eq!(
        ids,
        ["rec001.1", "rec001.3", "rec002.1", "rec002.2", "rec002.3"]
    );
    for s in &ds.samples {
        let t = oracle.get(&s.run_id).expect("truth of run");
        let target_m = (s.target_m[0] - t.true_end_m[0]).hypot(s.target_m[1] - t.true_end_m[1]);
        let offset_s = (s.clock_offset_s - t.clock_offset_s).abs();
        // The clean experiment's bounds (default_experiment_meets_the_acceptance_bounds).
        assert!(
            target_m <= 0.0025 && offset_s <= 0.02,
            "{}: target {target_m} m, clock offset {offset_s} s off the truth",
            s.run_id
        );
        assert!((s.path_length_m - 1.48).abs() < 0.1, "{}", s.path_length_m);
    }
    // The mended run's inputs are its clean log's: the garbled row read within a tick.
    let clean = tempfile::tempdir().unwrap();
    synth(clean.path(), 6, 2, 3);
    let clean = build(clean.path());
    let (a, b) = (
        ds.samples.iter().find(|s| s.run_id == "rec002.2").unwrap(),
        clean
            .samples
            .iter()
            .find(|s| s.run_id == "rec002.2")
            .unwrap(),
    );
    let one_tick_m = std::f64::consts::PI * 0.043 / 12.0;
    for (x, y) in a.inputs.iter().zip(&b.inputs) {
        assert!(
            (x - y).abs() <= one_tick_m,
            "{:?} vs {:?}",
            a.inputs,
            b.inputs
        );
    }
}

/// A log whose every fast step is impossible is no glitch but a unit: its recording is
/// rejected whole, naming it.
#[test]
fn a_log_in_another_unit_rejects_its_recording() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    synth_with(d, 6, 2, &[]);
    // A log of wheel speeds in mm/s: the speeds use no robot parameter, so their unit is
    // named, not ticks_per_rev and wheel_diameter_m.
    let log2 = d.join("runs/run002.odometry.csv");
    let text = std::fs::read_to_string(&log2).unwrap();
    let rows: Vec<Vec<f64>> = text
        .lines()
        .skip(1)
        .map(|l| l.split(',').map(|v| v.parse().unwrap()).collect())
        .collect();
    let metres_per_tick = std::f64::consts::PI * 0.043 / 12.0;
    let mut speeds = vec![
        "t,v_left,v_right".to_string(),
        format!("{},0,0", rows[0][0]),
    ];
    for w in rows.windows(2) {
        let dt = w[1][0] - w[0][0];
        let v = |c: usize| 1000.0 * (w[1][c] - w[0][c]) * metres_per_tick / dt;
        speeds.push(format!("{},{},{}", w[1][0], v(1), v(2)));
    }
    std::fs::write(&log2, speeds.join("\n") + "\n").unwrap();
    let out = ok(&dataset_args(
        &d.join("manifest.json"),
        &d.join("ds2.json"),
        &[],
    ));
    assert!(
        out.contains("5 samples from 6 runs")
            && out.contains("rejected run002: ")
            && out.contains("speeds not in m/s? mm/s read 1000 times too fast")
            && out.contains("more such steps, too many for glitches"),
        "{out}"
    );
}

/// Two rows' logs swapped in the manifest (run003's 0.7 m/s runs and run007's 0.2 m/s): each
/// was rejected on its own ("clock offset not found: speed-profile correlation 0.386") and
/// the dataset written without them, saying nothing of the other. The pair is named with its
/// lines, and nothing is written.
#[test]
fn logs_swapped_between_two_rows_are_named_as_a_pair() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    synth(d, 8, 4, 1);
    let m = odocal_dataset::Manifest::read(&d.join("manifest.json")).unwrap();
    let mut csv = String::from("id,trajectory,odometry,speed_mps\n");
    for r in &m.runs {
        let log = match r.id.as_str() {
            "run003" => "runs/run007.odometry.csv".to_string(),
            "run007" => "runs/run003.odometry.csv".to_string(),
            _ => r.odometry.clone(),
        };
        let traj = r.trajectory.as_deref().unwrap();
        let speed = r.speed_mps.map_or(String::new(), |v| v.to_string());
        csv.push_str(&format!("{},{traj},{log},{speed}\n", r.id));
    }
    let manifest = d.join("swapped.csv");
    std::fs::write(&manifest, csv).unwrap();
    let out = d.join("ds.json");
    let e = fails(&dataset_args(&manifest, &out, &[]));
    assert!(
        e.contains(&format!(
            "run003's log matches run007's trajectory and run007's log matches run003's: the two logs (or the two trajectories) are swapped in {} lines 4 and 8; swap them back",
            manifest.display()
        )),
        "{e}"
    );
    assert!(!out.exists(), "a dataset was written");
    // The rows of a JSON manifest are named by place and id.
    let json = std::fs::read_to_string(d.join("manifest.json"))
        .unwrap()
        .replace("runs/run003.odometry.csv", "SWAP")
        .replace("runs/run007.odometry.csv", "runs/run003.odometry.csv")
        .replace("SWAP", "runs/run007.odometry.csv");
    let manifest = d.join("swapped.json");
    std::fs::write(&manifest, json).unwrap();
    let e = fails(&dataset_args(&manifest, &out, &[]));
    assert!(
        e.contains("are swapped in ")
            && e.contains(" run 3 (\"run003\") and run 7 (\"run007\"); swap them back"),
        "{e}"
    );
    assert!(!out.exists(), "a dataset was written");
}

/// A logger that lost a row or two while the wheels turned: its cumulative counts keep the
/// travel, but the run was rejected ("rows 16 and 17 are 0.400 s apart … a dropped or extra
/// row?"), and `correct` refused the log. The lost rows are filled in between the counts
/// around them and said; the runs come out as from the whole logs.
#[test]
fn rows_lost_while_moving_are_filled_in_and_said() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    synth(d, 6, 4, 1);
    let (whole, _) = build_said(d);
    assert_eq!(whole.samples.len(), 6);
    // Takes `lost` rows out of a run's log where its wheels turn, and gives the log and the
    // file's lines on either side of the gap.
    let lose = |run: &str, lost: usize| {
        let log = d.join(format!("runs/{run}.odometry.csv"));
        let text = std::fs::read_to_string(&log).unwrap();
        let rows: Vec<&str> = text.lines().collect();
        let ticks = |i: usize| rows[i].split_once(',').unwrap().1;
        let first = (10..rows.len() - 4)
            .find(|&i| (i - 1..=i + lost).all(|j| ticks(j) != ticks(j + 1)))
            .expect("the wheels turn");
        let kept: Vec<&str> = rows
            .iter()
            .enumerate()
            .filter(|(i, _)| !(first..first + lost).contains(i))
            .map(|(_, l)| *l)
            .collect();
        std::fs::write(&log, kept.join("\n") + "\n").unwrap();
        (log, first, first + 1)
    };
    let whole_log = d.join("run002.whole.csv");
    std::fs::copy(d.join("runs/run002.odometry.csv"), &whole_log).unwrap();
    let (one, a, b) = lose("run002", 1);
    let (_, c, e) = lose("run003", 2);
    let (ds, said) = build_said(d);
    assert_eq!(ds.samples.len(), 6, "{said}");
    assert!(
        said.contains(&format!("run002.odometry.csv: 1 row the logger lost while the wheels turned (lines {a} and {b} are 0.400 s apart) filled in")),
        "{said}"
    );
    assert!(
        said.contains(&format!("run003.odometry.csv: 2 rows the logger lost while the wheels turned (lines {c} and {e} are 0.600 s apart)")),
        "{said}"
    );
    for (a, b) in whole.samples.iter().zip(&ds.samples) {
        assert_eq!(a.run_id, b.run_id);
        let inputs = a
            .inputs
            .iter()
            .zip(&b.inputs)
            .fold(0.0f64, |m, (x, y)| m.max((x - y).abs()));
        // The filled rows' counts are a tick or so off the lost ones: a tick of the
        // reference robot's encoder (12 a turn of a 43 mm wheel) is 11 mm of travel.
        assert!(inputs < 0.0113, "{}: inputs {inputs} off", a.run_id);
        let target = (a.target_m[0] - b.target_m[0]).hypot(a.target_m[1] - b.target_m[1]);
        assert!(target < 1e-4, "{}: target {target} m off", a.run_id);
    }
    // `correct` reads the log as the whole one: the corrected end moves by a tick's travel
    // at most.
    let model = d.join("model.json");
    ok(&["train", p(&d.join("dataset.json")), "--out", p(&model)]);
    let corrected = |log: &Path| {
        let o = common::odocal(&["correct", "--model", p(&model), p(log)]);
        succeeded(&o);
        let out = String::from_utf8_lossy(&o.stdout).into_owned();
        let end = out
            .split("corrected end: x ")
            .nth(1)
            .expect("corrected end");
        let (x, rest) = end.split_once(" m, y ").expect("x");
        let y = rest.split_once(" m").expect("y").0;
        let xy = [x.parse::<f64>().unwrap(), y.parse::<f64>().unwrap()];
        (xy, String::from_utf8_lossy(&o.stderr).into_owned())
    };
    let (from_whole, _) = corrected(&whole_log);
    let (filled, said) = corrected(&one);
    assert!(
        said.contains("1 row the logger lost while the wheels turned"),
        "{said}"
    );
    let moved = (from_whole[0] - filled[0]).hypot(from_whole[1] - filled[1]);
    assert!(moved < 0.0113, "corrected end moved {moved} m");
}

/// Straight runs in a mirrored floor frame (y and theta negated: a left-handed motion-capture
/// export, image coordinates): each run turns too little to judge alone, and 40 of 40 were
/// kept with targets 332 mm RMS from the truth. Over all runs the wheels' small turns
/// correlate at +0.44 with the camera's, mirrored at -0.44: refused, nothing written.
#[test]
fn straight_runs_in_a_mirrored_floor_frame_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    synth(d, 40, 1, 1);
    let (manifest, out) = (d.join("manifest.json"), d.join("ds.json"));
    let args = dataset_args(&manifest, &out, &[]);
    ok(&args);
    std::fs::remove_file(&out).unwrap();
    for i in 1..=40 {
        let path = d.join(format!("runs/run{i:03}.trajectory.csv"));
        let text = std::fs::read_to_string(&path).unwrap();
        let rows: Vec<String> = text
            .lines()
            .enumerate()
            .map(|(k, l)| {
                if k == 0 {
                    return l.to_string();
                }
                let mut c: Vec<String> = l.split(',').map(str::to_string).collect();
                for j in [2, 3] {
                    c[j] = (-c[j].parse::<f64>().unwrap()).to_string();
                }
                c.join(",")
            })
            .collect();
        std::fs::write(&path, rows.join("\n") + "\n").unwrap();
    }
    let e = fails(&args);
    assert!(
        e.contains("floor frame mirrored") && e.contains("correlate at -0.4"),
        "{e}"
    );
    assert!(!out.exists());
}

/// A window dataset's robot file is judged on the wheels' travel against the camera's, step
/// by step over whole recordings. Before, ticks_per_rev 24 for 12 rejected 176 of 178 windows
/// as off the clock and wrote 2 (exit 0), and 60 s windows with the right robot file were
/// refused on one window's end point, "1.835 times the camera's (0.0215 would fit)".
#[test]
fn a_window_dataset_names_a_robot_file_of_another_scale_and_no_other() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    synth_with(d, 4, 1, &["--paths", "tours"]);
    let (manifest, out, robot) = (d.join("manifest.json"), d.join("w.json"), d.join("r.json"));
    for (ticks, factor, fits) in [(24, 0.517, "(12 would fit)"), (48, 0.258, "(12 would fit)")] {
        std::fs::write(
            &robot,
            format!(r#"{{"format":"odocal.robot/1","wheel_diameter_m":0.043,"ticks_per_rev":{ticks},"wheel_base_m":0.1,"period_s":0.2}}"#),
        )
        .unwrap();
        let e = fails(&dataset_args(
            &manifest,
            &out,
            &["--layout", "windows", "--robot", p(&robot)],
        ));
        let at = e.find("the odometry's distances are ").expect(&e) + 29;
        let read: f64 = e[at..at + 5].parse().expect(&e);
        // The synthetic wheels are 3 % larger than nominal on average.
        assert!((read / factor - 1.0).abs() < 0.03, "{e}");
        assert!(e.contains(fits) && !e.contains("clock"), "{e}");
        assert!(!out.exists());
    }
    for window_s in ["60", "55", "10"] {
        ok(&dataset_args(
            &manifest,
            &out,
            &["--layout", "windows", "--window-s", window_s],
        ));
        let ds = Dataset::read(&out).expect("dataset.json");
        let t = ds.summary.travel_scale.expect("travel scale");
        assert!((t.ratio - 1.03).abs() < 0.03, "{t:?}");
        assert!(!ds.samples.is_empty() && ds.rejected.is_empty());
    }
}

/// A 50 ms logger: one tick of the 12-count encoders is a 0.22 m/s step of speed over one
/// period, so speeds are compared over 200 ms spans. Before, every slow run was refused
/// (speed profiles correlating at 0.59) and 32 of 178 tour windows beyond 0.08 m/s; now the
/// runs give what they give at 200 ms.
#[test]
fn a_50_ms_logger_keeps_every_run() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let (sim, robot) = (d.join("sim50.json"), d.join("robot50.json"));
    std::fs::write(
        &sim,
        r#"{"format":"odocal.robotsim/1","nominal":{"log_period_s":0.05}}"#,
    )
    .unwrap();
    std::fs::write(&robot, r#"{"format":"odocal.robot/1","wheel_diameter_m":0.043,"ticks_per_rev":12,"wheel_base_m":0.1,"period_s":0.05}"#).unwrap();
    let exp = d.join("exp");
    synth_with(&exp, 9, 1, &["--config", p(&sim)]);
    let out = d.join("ds.json");
    ok(&dataset_args(
        &exp.join("manifest.json"),
        &out,
        &["--robot", p(&robot)],
    ));
    let ds = Dataset::read(&out).expect("dataset.json");
    assert!(ds.rejected.is_empty(), "{:?}", ds.rejected);
    assert_eq!(ds.samples.len(), 9);
    assert!(
        ds.summary.max_alignment_residual_mps < 0.04,
        "{:?}",
        ds.summary
    );
    let oracle = OracleFile::read(&exp.join("truth/oracle.json")).unwrap();
    for s in &ds.samples {
        let truth = oracle.runs.iter().find(|r| r.run_id == s.run_id).unwrap();
        let e = (s.target_m[0] - truth.true_end_m[0]).hypot(s.target_m[1] - truth.true_end_m[1]);
        assert!(e < 0.002, "{}: target {e} m off", s.run_id);
    }
    // Tours' windows at 50 ms: none beyond the residual's limit, and no clock rate read into
    // a true clock (one recording of 12 was told 345 ppm slow).
    let tours = d.join("tours");
    synth_with(&tours, 4, 1, &["--paths", "tours", "--config", p(&sim)]);
    ok(&dataset_args(
        &tours.join("manifest.json"),
        &out,
        &["--robot", p(&robot), "--layout", "windows"],
    ));
    let ds = Dataset::read(&out).expect("dataset.json");
    assert!(ds.rejected.is_empty(), "{:?}", ds.rejected);
    assert!(ds.samples.len() > 40, "{} windows", ds.samples.len());
    assert!(ds.samples.iter().all(|s| s.clock_rate.is_none()));
    assert!(
        ds.summary.max_alignment_residual_mps < 0.05,
        "{:?}",
        ds.summary
    );
}

/// Every log a speed log in km/h: a speed log's distances use no robot parameter, so the
/// factor of 3.6 is named as km/h, where it was blamed on ticks_per_rev ("3.695 times … (48
/// would fit)"); in m/s the same logs pass.
#[test]
fn speed_logs_in_km_per_hour_are_named() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    synth_with(d, 4, 2, &[]);
    let metres_per_tick = std::f64::consts::PI * 0.043 / 12.0;
    let write_speeds = |unit: f64| {
        for i in 1..=4 {
            let path = d.join(format!("runs/run{i:03}.odometry.csv"));
            let text = std::fs::read_to_string(&path).unwrap();
            let rows: Vec<Vec<f64>> = text
                .lines()
                .skip(1)
                .map(|l| l.split(',').map(|v| v.parse().unwrap()).collect())
                .collect();
            let mut speeds = vec![
                "t,v_left,v_right".to_string(),
                format!("{},0,0", rows[0][0]),
            ];
            for w in rows.windows(2) {
                let dt = w[1][0] - w[0][0];
                let v = |c: usize| unit * (w[1][c] - w[0][c]) * metres_per_tick / dt;
                speeds.push(format!("{},{},{}", w[1][0], v(1), v(2)));
            }
            std::fs::write(
                d.join(format!("runs/run{i:03}.speeds.csv")),
                speeds.join("\n") + "\n",
            )
            .unwrap();
        }
        let m = std::fs::read_to_string(d.join("manifest.json")).unwrap();
        std::fs::write(
            d.join("speeds.json"),
            m.replace(".odometry.csv", ".speeds.csv"),
        )
        .unwrap();
    };
    let (manifest, out) = (d.join("speeds.json"), d.join("ds.json"));
    let args = dataset_args(&manifest, &out, &[]);
    write_speeds(3.6);
    let e = fails(&args);
    assert!(
        e.contains("times the camera's")
            && e.contains("a factor of 3.6 is km/h")
            && !e.contains("ticks_per_rev"),
        "{e}"
    );
    let at = e.find("distances are ").unwrap() + 14;
    let factor: f64 = e[at..at + 5].parse().expect(&e);
    // The synthetic wheels are about 3 % larger than nominal.
    assert!((factor / 3.6 - 1.0).abs() < 0.05, "{e}");
    assert!(!out.exists());
    write_speeds(1.0);
    ok(&args);
}

/// Rewrites every data row of the experiment's trajectory files in `dir` with `edit` (the
/// row's 0-based index and its fields t,x,y,theta,quality; an empty row drops it).
fn edit_trajectories(dir: &Path, edit: &dyn Fn(usize, &mut Vec<String>)) {
    for entry in std::fs::read_dir(dir.join("runs")).unwrap() {
        let path = entry.unwrap().path();
        if !p(&path).ends_with(".trajectory.csv") {
            continue;
        }
        let text = std::fs::read_to_string(&path).unwrap();
        let mut lines: Vec<String> = vec![text.lines().next().unwrap().to_string()];
        for (i, l) in text.lines().skip(1).enumerate() {
            let mut f: Vec<String> = l.split(',').map(str::to_string).collect();
            edit(i, &mut f);
            if !f.is_empty() {
                lines.push(f.join(","));
            }
        }
        std::fs::write(&path, lines.join("\n") + "\n").unwrap();
    }
}

/// The field `f[k]` as a number.
fn num(f: &[String], k: usize) -> f64 {
    f[k].parse().unwrap()
}

/// RMS distance of the dataset's targets from the truth's end points, millimetres.
fn target_rms_mm(dir: &Path, ds: &Dataset) -> f64 {
    let oracle = OracleFile::read(&dir.join("truth/oracle.json")).unwrap();
    let e = odocal_dataset::errors_against_truth(ds, &oracle, "oracle.json")
        .unwrap()
        .expect("samples");
    1e3 * e.target_rms_m
}

/// A motion-capture body whose x axis is 3° off the robot's front turned every straight-run
/// target by 3°: 77 mm RMS from the truth where the dataset's own error is 0.5 mm, with exit
/// 0 and nothing said, and --tag-yaw was "not used". The turn is measured over the
/// recordings and refused with the --tag-yaw that takes it off, which the dataset now takes.
#[test]
fn a_trajectory_heading_turned_from_the_drive_is_refused_and_tag_yaw_takes_it_off() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    synth(d, 20, 1, 1);
    edit_trajectories(d, &|_, f| {
        f[3] = (num(f, 3) + 3f64.to_radians()).to_string()
    });
    let (manifest, out) = (d.join("manifest.json"), d.join("ds.json"));
    let e = fails(&dataset_args(&manifest, &out, &[]));
    let at = e.find("heading is turned +").expect(&e) + 19;
    let deg: f64 = e[at..at + 3].parse().expect(&e);
    assert!((deg - 3.0).abs() <= 0.1, "{e}");
    assert!(e.contains("give --tag-yaw 3.0"), "{e}");
    assert!(!out.exists());
    let o = common::odocal(&dataset_args(&manifest, &out, &["--tag-yaw", "3"]));
    succeeded(&o);
    let said = String::from_utf8_lossy(&o.stderr);
    assert!(
        !said.contains("not used") && !said.contains("warning"),
        "{said}"
    );
    let ds = Dataset::read(&out).unwrap();
    assert_eq!(ds.samples.len(), 20);
    let rms_mm = target_rms_mm(d, &ds);
    assert!(rms_mm < 1.0, "targets {rms_mm:.2} mm RMS from the truth");
}

/// A motion-capture body 8 cm ahead of the axle and 2 cm to its left put straight-run targets
/// 15 mm RMS from the truth (0.5 mm without) and tour windows 128 mm, unsaid. Its distance
/// ahead is fitted from the turns and warned of with the --tag-offset that takes it off.
#[test]
fn a_trajectory_point_off_the_axle_is_named_and_tag_offset_takes_it_off() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    synth(d, 20, 1, 1);
    edit_trajectories(d, &|_, f| {
        let (s, c) = num(f, 3).sin_cos();
        f[1] = (num(f, 1) + 0.08 * c - 0.02 * s).to_string();
        f[2] = (num(f, 2) + 0.08 * s + 0.02 * c).to_string();
    });
    let (manifest, out) = (d.join("manifest.json"), d.join("ds.json"));
    let o = common::odocal(&dataset_args(&manifest, &out, &[]));
    succeeded(&o);
    let said = String::from_utf8_lossy(&o.stderr);
    let at = said.find("as a point ").expect(&said) + 11;
    let cm: f64 = said[at..at + 3].parse().expect(&said);
    assert!((cm - 8.0).abs() < 0.5, "{said}");
    assert!(said.contains("ahead of the wheel axle") && said.contains("give --tag-offset 0.0"));
    assert!(target_rms_mm(d, &Dataset::read(&out).unwrap()) > 10.0);
    let o = common::odocal(&dataset_args(
        &manifest,
        &out,
        &["--tag-offset", "0.08,0.02"],
    ));
    succeeded(&o);
    let said = String::from_utf8_lossy(&o.stderr);
    assert!(
        !said.contains("warning") && !said.contains("not used"),
        "{said}"
    );
    let rms_mm = target_rms_mm(d, &Dataset::read(&out).unwrap());
    assert!(rms_mm < 1.0, "targets {rms_mm:.2} mm RMS from the truth");
}

/// Frames of a trajectory file that are no pose of the robot: a wrong fit jumping 0.6 m and
/// 0.5 rad for one frame, a symmetric marker set's heading flipped by π for two frames, lost
/// frames written as (0, 0, 0). Before, the jumps spoiled the targets (tour windows 11.8 mm
/// RMS from the truth against 3.1) or read as a turned mount, the flips rejected nearly every
/// straight run as "not a straight run", and the zeros read as a mount turned 6°. They are
/// dropped as lost frames, counted by kind, and the targets are the clean experiment's.
#[test]
fn trajectory_frames_that_jump_flip_or_read_zero_are_dropped_and_said() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    type Edit = fn(usize, &mut Vec<String>);
    let edits: [(Edit, &str); 3] = [
        (
            |i, f| {
                if i % 90 == 10 {
                    f[1] = (num(f, 1) + 0.6).to_string();
                    f[3] = (num(f, 3) + 0.5).to_string();
                }
            },
            "that jumped up to 0.6",
        ),
        (
            |i, f| {
                if i % 90 == 45 || i % 90 == 46 {
                    f[3] = (num(f, 3) + std::f64::consts::PI).to_string();
                }
            },
            "whose heading flipped by 180° and back",
        ),
        (
            |i, f| {
                if (45..48).contains(&(i % 90)) {
                    for v in &mut f[1..4] {
                        *v = "0".into();
                    }
                }
            },
            "written as (0, 0, 0) away from where the robot was",
        ),
    ];
    for (edit, kind) in edits {
        let _ = std::fs::remove_dir_all(d);
        synth(d, 20, 1, 1);
        edit_trajectories(d, &edit);
        let (ds, said) = build_said(d);
        assert!(
            said.contains("frames dropped as lost") && said.contains(kind),
            "{said}"
        );
        assert_eq!(ds.samples.len(), 20, "{said}");
        let rms_mm = target_rms_mm(d, &ds);
        assert!(
            rms_mm < 1.0,
            "{kind}: targets {rms_mm:.2} mm RMS from the truth"
        );
    }
}

/// Trajectories in feet were blamed on the manifest's speed labels (straight runs) or the
/// robot file (tours), in inches on counts per period; millimetres and centimetres were
/// named. Feet and inches are named too, with the factor that mends them.
#[test]
fn trajectories_in_feet_or_inches_are_named() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    // A tour whose path in feet lies beyond what drift explains is named on the wheels'
    // travel against the camera's, after the windows are made, not blamed on the robot file.
    for (paths, runs) in [("straight", "20"), ("tours", "2"), ("tours", "1")] {
        for (k, unit) in [(3.28084, "in feet"), (39.37, "in inches")] {
            let _ = std::fs::remove_dir_all(d);
            ok(&[
                "synth",
                "experiment",
                "--out",
                p(d),
                "--runs",
                runs,
                "--frames",
                "none",
                "--paths",
                paths,
            ]);
            edit_trajectories(d, &|_, f| {
                for j in [1, 2] {
                    f[j] = (num(f, j) * k).to_string();
                }
            });
            let out = d.join("ds.json");
            let layout = if paths == "tours" { "windows" } else { "runs" };
            let e = fails(&dataset_args(
                &d.join("manifest.json"),
                &out,
                &["--layout", layout],
            ));
            assert!(
                e.contains(unit) && e.contains("it must be in metres"),
                "{e}"
            );
            if runs == "1" && k < 10.0 {
                assert!(
                    e.contains("0.314 times the camera's")
                        && e.contains("1/3.281 is a trajectory in feet")
                        && !e.contains("robot"),
                    "{e}"
                );
            }
            assert!(!out.exists());
        }
    }
}

/// A `t,x,y,theta` motion-capture export marks its lost frames with NaN (or nothing): such
/// files were refused "NaN is not a finite number", with no hint. Those rows are read as
/// lost frames, and said; the targets are the clean experiment's.
#[test]
fn nan_rows_of_a_trajectory_without_quality_are_lost_frames() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    synth(d, 20, 1, 1);
    edit_trajectories(d, &|i, f| {
        f.truncate(4);
        if i % 90 == 45 {
            f[1] = "NaN".into();
            f[2] = "NaN".into();
            f[3] = if i % 180 == 45 { "NaN" } else { "" }.into();
        }
    });
    for entry in std::fs::read_dir(d.join("runs")).unwrap() {
        let path = entry.unwrap().path();
        if p(&path).ends_with(".trajectory.csv") {
            let text = std::fs::read_to_string(&path).unwrap();
            let text = text.replacen("t,x,y,theta,quality", "t,x,y,theta", 1);
            std::fs::write(&path, text).unwrap();
        }
    }
    let (ds, said) = build_said(d);
    assert!(
        said.contains("rows have no pose (NaN or empty x, y and theta): read as lost frames"),
        "{said}"
    );
    assert_eq!(ds.samples.len(), 20, "{said}");
    let rms_mm = target_rms_mm(d, &ds);
    assert!(rms_mm < 1.0, "targets {rms_mm:.2} mm RMS from the truth");
}
