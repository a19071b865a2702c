//! Building dataset.json from a run manifest: every row's odometry log paired with its camera
//! trajectory (read from a file, or made from the row's video by the caller's tracker),
//! processed in parallel, and the dataset's errors against a synthetic experiment's truth.

use std::path::Path;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::Mutex;

use odocal_core::Trajectory;

use crate::build::{
    assemble, coarse_of, process_recording_at, BuildOptions, Recording, RunOutcome,
};
use crate::glitch::{mend_glitches, LogGlitches, LostStep};
use crate::manifest::{Manifest, ManifestRow};
use crate::odometry::OdometryLog;
use crate::oracle::OracleFile;
use crate::sample::Dataset;
use crate::turn_sides::TurnEvidence;
use crate::windows::{window_samples_at, Layout, WINDOW_RULE};
use crate::DatasetError;

/// Makes the camera trajectory of a row that has a video (the tracker, in the binary): the
/// row and the video's resolved path in, the trajectory or a message out.
pub type VideoTracker<'a> = dyn Fn(&ManifestRow, &Path) -> Result<Trajectory, String> + Sync + 'a;

/// A row's runs, the notes on what reading its log took out of it, and its turns against its
/// camera's (pooled over the manifest: see [`TurnEvidence`]).
type RowOutcome = (Vec<RunOutcome>, Vec<String>, RowEvidence);

/// What a row says about the whole manifest, pooled over its rows.
#[derive(Default)]
struct RowEvidence {
    /// Its log's small turns against its camera's.
    turns: TurnEvidence,
    /// Its wheel travel against the camera's ([`crate::units::travel_against_camera`]).
    travel: Option<[f64; 2]>,
}

/// A row's log (glitches mended) and camera trajectory, once both are read: what the search
/// for swapped pairs compares.
type RowPair = Option<(OdometryLog, Trajectory)>;

/// Processes one row; `pair` receives its log and trajectory once both are read.
fn one_row(
    m: &Manifest,
    row: &ManifestRow,
    track: Option<&VideoTracker>,
    opts: &BuildOptions,
    pair: &mut RowPair,
) -> Result<RowOutcome, DatasetError> {
    let log_path = m.resolve(&row.odometry);
    let log = OdometryLog::read_csv(&log_path)?;
    let mut notes: Vec<String> = log
        .count_note()
        .map(|n| format!("{}: {n}", log_path.display()))
        .into_iter()
        .collect();
    if let Some(why) = log.period_mismatch(opts.robot.period_s) {
        // Times in milliseconds are the log's unit: another robot file would not mend them.
        let advice = match log.time_unit(opts.robot.period_s) {
            Some((_, k)) => format!("; write the log's times in seconds (divide them by {k:.0})"),
            None => " (period_s); give the robot's own file with --robot, or a log of this robot"
                .to_string(),
        };
        return Err(DatasetError::Mismatch(format!(
            "{}: {why}{advice}",
            log_path.display()
        )));
    }
    // Glitches are found before any tracking. A few spoil the runs or windows across them
    // alone; impossible steps everywhere are the log's unit or the robot file, and spoil the
    // whole recording.
    let runs_of = |log: &OdometryLog| match opts.layout {
        Layout::StraightRuns => crate::segment::split_runs(log, opts.min_gap_s),
        Layout::Windows(_) => Vec::new(),
    };
    let mended = match mend_glitches(&log, &opts.robot) {
        LogGlitches::Mended(m) => m,
        LogGlitches::Everywhere(why) => {
            // Counted as the runs it holds, as the runs of a recording are counted otherwise.
            let runs = match opts.layout {
                Layout::StraightRuns => runs_of(&log).len(),
                Layout::Windows(_) => 1,
            };
            let rejected = (0..runs.max(1))
                .map(|j| {
                    RunOutcome::Rejected(crate::sample::RejectedRun {
                        run_id: if runs > 1 {
                            format!("{}.{}", row.id, j + 1)
                        } else {
                            row.id.clone()
                        },
                        reason: format!("{}: {why}", log_path.display()),
                    })
                })
                .collect();
            return Ok((rejected, notes, RowEvidence::default()));
        }
    };
    let at_log = |what: &str| format!("{}: {what}", log_path.display());
    notes.extend(mended.mended.iter().map(|m| at_log(m)));
    let segments = runs_of(&mended.log);
    for step in &mended.lost {
        if matches!(opts.layout, Layout::StraightRuns)
            && !segments
                .iter()
                .any(|s| step.touches(s.start_row, s.end_row))
        {
            // The reason's advice to cut the log or record again is for a run across the
            // step; between runs the step costs nothing, and said so.
            let what = step
                .reason
                .split(crate::odometry::RESET_ADVICE)
                .next()
                .unwrap_or(&step.reason);
            notes.push(at_log(&format!(
                "{what}; harmless: no run spans it, and the counts after it are read on from the rows before it"
            )));
        }
    }
    let lost: Vec<LostStep> = mended
        .lost
        .iter()
        .map(|s| LostStep {
            row: s.row,
            reason: at_log(&s.reason),
        })
        .collect();
    let log = mended.log;
    let traj = match (&row.trajectory, &row.video, track) {
        (Some(t), _, _) => {
            let path = m.resolve(t);
            let (read, lost_note) = crate::frame_glitch::read_trajectory(&path)?;
            notes.extend(lost_note.map(|n| format!("{}: {n}", path.display())));
            let (kept, dropped) = crate::frame_glitch::drop_glitch_frames(&read);
            notes.extend(
                dropped
                    .note(read.rows.len())
                    .map(|n| format!("{}: {n}", path.display())),
            );
            opts.trajectory_mount.robot_trajectory(&kept)
        }
        (None, Some(v), Some(track)) => {
            track(row, &m.resolve(v)).map_err(DatasetError::Mismatch)?
        }
        (None, Some(_), None) => {
            return Err(DatasetError::Mismatch(format!(
                "run \"{}\" has a video: give the calibration with --camera camera.json",
                row.id
            )))
        }
        (None, None, _) => {
            return Err(DatasetError::Mismatch(format!(
                "run \"{}\": no video and no trajectory",
                row.id
            )))
        }
    };
    // A header alone (an export of no fixes) would otherwise read as a trajectory of 0 s that
    // cannot overlap the log, blaming the manifest's pairing.
    if traj.rows.len() < 2 {
        let camera = row.trajectory.as_ref().or(row.video.as_ref());
        return Err(DatasetError::Mismatch(format!(
            "run \"{}\" ({}): the trajectory has {}; give this run's camera trajectory, or leave the run out of the manifest",
            row.id,
            camera.map_or(log_path.clone(), |c| m.resolve(c)).display(),
            if traj.rows.is_empty() {
                "no rows (only its header)".to_string()
            } else {
                format!("one row only, at {:.2} s", traj.start_s())
            }
        )));
    }
    *pair = Some((log.clone(), traj.clone()));
    if let Some(why) = crate::units::unit_mismatch(&log, &traj, &opts.robot) {
        return Err(DatasetError::Mismatch(format!(
            "run \"{}\" ({}): {why}",
            row.id,
            log_path.display()
        )));
    }
    let mismatch = |why: String| {
        let camera = row.trajectory.as_ref().or(row.video.as_ref());
        Err(DatasetError::Mismatch(format!(
            "run \"{}\" ({}): {why}",
            row.id,
            camera.map_or(log_path.clone(), |c| m.resolve(c)).display()
        )))
    };
    if let Some(why) = mismatch_before_alignment(&log, &traj, &opts.robot) {
        return mismatch(why);
    }
    let rec = Recording {
        id: &row.id,
        speed_mps: row.speed_mps,
        log: &log,
        camera: &traj,
    };
    let coarse = coarse_of(&rec, opts);
    if let Some(why) = coarse.as_ref().ok().and_then(|c| c.implausible_rate()) {
        return Err(DatasetError::Mismatch(format!(
            "run \"{}\" ({}): {why}",
            row.id,
            log_path.display()
        )));
    }
    if let Some(why) = coarse
        .as_ref()
        .ok()
        .and_then(|c| crate::turn_sides::turn_mismatch(&log, &traj, &opts.robot, &opts.align, c))
    {
        return mismatch(why);
    }
    let evidence = coarse
        .as_ref()
        .map_or(RowEvidence::default(), |c| RowEvidence {
            turns: TurnEvidence::of(&log, &traj, &opts.robot, &opts.align, c),
            travel: crate::units::travel_against_camera(&log, &traj, &opts.robot, &opts.align, c),
        });
    let runs = match opts.layout {
        Layout::StraightRuns => process_recording_at(&rec, opts, coarse, &lost),
        Layout::Windows(w) => window_samples_at(&rec, opts, &w, coarse, &lost),
    }?;
    Ok((runs, notes, evidence))
}

/// Why `camera` cannot be the trajectory of the robot that wrote `log`, judged on the
/// trajectory alone or against the log: times that are not seconds, a heading that does not
/// point where the robot drives, turns the other way from the wheels' (`None` when it can be).
pub fn trajectory_mismatch(
    log: &OdometryLog,
    camera: &Trajectory,
    robot: &crate::RobotParams,
    align: &crate::align::AlignOptions,
) -> Option<String> {
    mismatch_before_alignment(log, camera, robot).or_else(|| {
        let revs = log.wheel_revs(robot);
        let geom = crate::kinematics::WheelGeometry::nominal(robot);
        let coarse = crate::align::coarse_offset(log, &revs, &geom, camera, align, "").ok()?;
        crate::turn_sides::turn_mismatch(log, camera, robot, align, &coarse)
    })
}

/// Whether `camera` may be the trajectory of the robot that wrote `log`: no unit mismatch, no
/// [`trajectory_mismatch`], and a clock offset at which their speed profiles correlate as
/// `align` asks.
pub fn log_fits_camera(
    log: &OdometryLog,
    camera: &Trajectory,
    robot: &crate::RobotParams,
    align: &crate::align::AlignOptions,
) -> bool {
    if crate::units::unit_mismatch(log, camera, robot).is_some()
        || mismatch_before_alignment(log, camera, robot).is_some()
    {
        return false;
    }
    let revs = log.wheel_revs(robot);
    let geom = crate::kinematics::WheelGeometry::nominal(robot);
    crate::align::coarse_offset(log, &revs, &geom, camera, align, "").is_ok_and(|c| {
        c.correlation >= align.min_correlation
            && crate::turn_sides::turn_mismatch(log, camera, robot, align, &c).is_none()
    })
}

/// The other of `n` recordings that recording `i` is swapped with: `i`'s log does not fit its
/// own camera, nor the other's log its own, while each fits the other's camera (`fits(a, b)`:
/// recording `a`'s log fits recording `b`'s camera, as [`log_fits_camera`] judges). Two logs,
/// or two trajectories or videos, given to each other's rows: each pair on its own reads as a
/// log of another robot or a camera that lost its clock, until the pairs are tried.
pub fn swapped_with(n: usize, i: usize, fits: impl Fn(usize, usize) -> bool) -> Option<usize> {
    if fits(i, i) {
        return None;
    }
    (0..n).find(|&j| j != i && fits(i, j) && fits(j, i) && !fits(j, j))
}

/// The checks of [`trajectory_mismatch`] that need no clock offset: times that are not
/// seconds, a heading that does not point where the robot drives. They come first, since
/// the offset's search spans the trajectory's times, which may be milliseconds.
fn mismatch_before_alignment(
    log: &OdometryLog,
    camera: &Trajectory,
    robot: &crate::RobotParams,
) -> Option<String> {
    crate::units::time_unit_mismatch(log, camera)
        .or_else(|| crate::heading::heading_mismatch(log, camera, robot))
}

/// Builds the dataset of every row of `m`. Rows with a video are tracked by `track` on
/// `threads` plain threads, one video per thread at a time (each tracker runs a decoder
/// thread of its own, so tracking never waits on a busy rayon pool); rows with trajectories
/// only are processed on the rayon pool. `on_row` is called after each row.
///
/// A video that cannot be tracked (a wrong tag id or family, say, which every video of the
/// manifest shares) stops the threads from taking further rows: the error is the first such
/// row's in manifest order, whichever thread met it first, and comes after the rows before
/// it rather than after the whole manifest.
pub fn build_from_manifest(
    m: &Manifest,
    opts: &BuildOptions,
    track: Option<&VideoTracker>,
    threads: usize,
    on_row: &(dyn Fn() + Sync),
) -> Result<Dataset, DatasetError> {
    use rayon::prelude::*;
    type Done = (Result<RowOutcome, DatasetError>, RowPair);
    let untrackable = &AtomicBool::new(false);
    let watched = track.map(|track| {
        move |row: &ManifestRow, video: &Path| {
            let r = track(row, video);
            if r.is_err() {
                untrackable.store(true, Ordering::SeqCst);
            }
            r
        }
    });
    let watched = watched.as_ref().map(|w| w as &VideoTracker);
    let work = |row: &ManifestRow| {
        let mut pair = None;
        let r = one_row(m, row, watched, opts, &mut pair);
        on_row();
        (r, pair)
    };
    let results: Vec<Done> = if watched.is_some() {
        let next = AtomicUsize::new(0);
        let mut slots: Vec<Option<Done>> = (0..m.runs.len()).map(|_| None).collect();
        let done = Mutex::new(&mut slots);
        std::thread::scope(|scope| {
            for _ in 0..threads.clamp(1, m.runs.len().max(1)) {
                scope.spawn(|| loop {
                    if untrackable.load(Ordering::SeqCst) {
                        break;
                    }
                    let i = next.fetch_add(1, Ordering::SeqCst);
                    let Some(row) = m.runs.get(i) else {
                        break;
                    };
                    let r = work(row);
                    done.lock().unwrap_or_else(|e| e.into_inner())[i] = Some(r);
                });
            }
        });
        // Every row before the first one left untaken was taken before it, and finished: the
        // first error among them is the first of the whole manifest's untrackable rows.
        if slots.iter().any(Option::is_none) {
            let first = slots.into_iter().flatten().find_map(|(r, _)| r.err());
            return Err(first.unwrap_or_else(|| {
                DatasetError::Mismatch("a video could not be tracked".to_string())
            }));
        }
        slots.into_iter().flatten().collect()
    } else {
        m.runs.par_iter().map(work).collect()
    };
    if let Some(why) = swapped_pair(m, &results, opts) {
        return Err(DatasetError::Mismatch(why));
    }
    // Tracked videos are checked for their mount by the tracker; trajectory files are not.
    let files: Vec<&Trajectory> = m
        .runs
        .iter()
        .zip(&results)
        .filter(|(row, _)| row.trajectory.is_some())
        .filter_map(|(_, (_, pair))| pair.as_ref().map(|(_, t)| t))
        .collect();
    let mount = crate::mount::check_mount(&files, &opts.trajectory_mount);
    let mut outcomes = Vec::with_capacity(results.len());
    let mut notes = Vec::new();
    let mut turns = TurnEvidence::default();
    let mut travel = Vec::new();
    for (r, _) in results {
        let (runs, note, evidence) = r?;
        outcomes.push(runs);
        notes.extend(note);
        turns.add(&evidence.turns);
        travel.extend(evidence.travel);
    }
    // After each row's own refusals, which name its file: a trajectory turned 180° or in
    // degrees is one row's fault, not the mount of all of them.
    if let Some(why) = mount.refusal {
        return Err(DatasetError::Mismatch(format!(
            "{}: {why}",
            m.source_name()
        )));
    }
    // Each straight run turns too little to judge on its own; all of them together show a
    // mirrored floor frame, which left the alignment untouched and every run accepted with
    // its target on the wrong side (332 mm RMS from the truth over 40 runs).
    if let Some(why) = turns.mirrored(outcomes.len()) {
        return Err(DatasetError::Mismatch(format!(
            "{}: {why}",
            m.source_name()
        )));
    }
    crate::units::reject_scale_outliers(&mut outcomes, matches!(opts.layout, Layout::Windows(_)));
    // A window's inputs hold no times.
    if !matches!(opts.layout, Layout::Windows(_)) {
        crate::units::reject_clock_outliers(&mut outcomes);
    }
    let mut ds = assemble(opts.robot, outcomes);
    ds.notes = notes;
    ds.warnings.extend(mount.warning);
    if let Layout::Windows(_) = opts.layout {
        ds.feature_rule = WINDOW_RULE.to_string();
        ds.summary.travel_scale = crate::units::travel_scale(&travel);
    }
    Ok(ds)
}

/// The message on the first two rows of `m` whose logs (or cameras) are each other's
/// ([`swapped_with`]), among the rows that gave no sample: their own pairings refused or every
/// run rejected, each on its own for a reason that does not name the other.
fn swapped_pair(
    m: &Manifest,
    results: &[(Result<RowOutcome, DatasetError>, RowPair)],
    opts: &BuildOptions,
) -> Option<String> {
    let suspects: Vec<(usize, &OdometryLog, &Trajectory)> = results
        .iter()
        .enumerate()
        .filter_map(|(i, (r, pair))| {
            let (log, camera) = pair.as_ref()?;
            let sampled = r
                .as_ref()
                .is_ok_and(|(runs, _, _)| runs.iter().any(|o| matches!(o, RunOutcome::Sample(_))));
            (!sampled).then_some((i, log, camera))
        })
        .collect();
    let fits = |a: usize, b: usize| {
        log_fits_camera(suspects[a].1, suspects[b].2, &opts.robot, &opts.align)
    };
    let (a, b) =
        (0..suspects.len()).find_map(|a| swapped_with(suspects.len(), a, fits).map(|b| (a, b)))?;
    let (i, j) = (suspects[a].0, suspects[b].0);
    let (x, y) = (&m.runs[i], &m.runs[j]);
    let camera = |r: &ManifestRow| {
        if r.video.is_some() {
            "video"
        } else {
            "trajectory"
        }
    };
    let cameras = if x.video.is_some() && y.video.is_some() {
        "videos"
    } else {
        "trajectories"
    };
    let (pi, pj) = (m.place_of(i), m.place_of(j));
    let places = match (pi.strip_prefix("line "), pj.strip_prefix("line ")) {
        (Some(li), Some(lj)) => format!("lines {li} and {lj}"),
        _ => format!("{pi} and {pj}"),
    };
    Some(format!(
        "{}'s log matches {}'s {} and {}'s log matches {}'s: the two logs (or the two {cameras}) are swapped in {} {places}; swap them back",
        x.id,
        y.id,
        camera(y),
        y.id,
        x.id,
        m.source_name(),
    ))
}

/// The dataset's errors against a synthetic experiment's truth.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TruthErrors {
    /// RMS distance of the targets from the true end points, metres (NaN for windows).
    pub target_rms_m: f64,
    /// Largest such distance, metres.
    pub target_max_m: f64,
    /// RMS error of the estimated clock offsets, seconds.
    pub offset_rms_s: f64,
    /// Largest clock-offset error, seconds.
    pub offset_max_s: f64,
    /// Largest departure of a recording's clock rate from the truth's (a synthetic
    /// experiment's clocks tick together), parts per million.
    pub rate_max_ppm: f64,
    /// Samples compared.
    pub n: usize,
}

/// End points (metres) and clock offsets (seconds) this far from a synthetic experiment's
/// truth (RMS) are judged against another experiment's truth: a dataset's own errors are a
/// millimetre and a few milliseconds.
pub const TRUTH_MISMATCH_M: f64 = 0.05;
/// See [`TRUTH_MISMATCH_M`].
pub const TRUTH_MISMATCH_S: f64 = 0.05;

impl TruthErrors {
    /// The warning for a truth (`name`) far from the dataset it is compared with: another
    /// experiment's truth with the same run ids. None when it fits.
    pub fn mismatch_warning(&self, name: &str) -> Option<String> {
        let far_target = self.target_rms_m > TRUTH_MISMATCH_M;
        (far_target || self.offset_rms_s > TRUTH_MISMATCH_S).then(|| {
            let what = if self.target_rms_m.is_nan() {
                format!("{:.0} ms RMS", 1e3 * self.offset_rms_s)
            } else {
                format!(
                    "{:.0} mm and {:.0} ms RMS",
                    1e3 * self.target_rms_m,
                    1e3 * self.offset_rms_s
                )
            };
            // Clock offsets within a few milliseconds of the truth's are this experiment's
            // clocks: then the targets themselves are off (a mirrored or turned frame), and
            // the dataset is no training set whatever the truth file.
            let own_clocks = far_target && self.offset_rms_s <= TRUTH_MISMATCH_S;
            let targets = if own_clocks {
                format!(
                    " Its clock offsets are within {:.0} ms of the truth's, so it likely is, and the targets are {:.0} mm RMS off where a dataset's own are about 2 mm: do not train on it before finding why (a trajectory frame mirrored, turned or scaled?)",
                    1e3 * self.offset_rms_s,
                    1e3 * self.target_rms_m
                )
            } else {
                String::new()
            };
            format!(
                "the dataset is {what} from {name}: is that the truth of the experiment the dataset was built from?{targets}"
            )
        })
    }
}

/// Compares every sample's target and clock offset with the truth (`name` is the truth
/// file, for the message when a run is missing). None when the dataset has no samples.
pub fn errors_against_truth(
    ds: &Dataset,
    oracle: &OracleFile,
    name: &str,
) -> Result<Option<TruthErrors>, DatasetError> {
    let (mut target, mut offset, mut rate_max_ppm) = (Vec::new(), Vec::new(), 0.0);
    // Windows have no truth of their own in the oracle file: only their recording's clock
    // offset is compared (the targets' errors are NaN).
    let windows = ds.is_windows();
    for sample in &ds.samples {
        let key = if windows {
            &sample.recording_id
        } else {
            &sample.run_id
        };
        let t = oracle.get(key).ok_or_else(|| {
            DatasetError::Mismatch(format!(
                "{name}: no truth for run \"{}\"; is this the experiment's truth/oracle.json?",
                sample.run_id
            ))
        })?;
        target.push(if windows {
            f64::NAN
        } else {
            (sample.target_m[0] - t.true_end_m[0]).hypot(sample.target_m[1] - t.true_end_m[1])
        });
        offset.push((sample.clock_offset_s - t.clock_offset_s).abs());
        rate_max_ppm = f64::max(
            rate_max_ppm,
            1e6 * (sample.clock_rate.unwrap_or(1.0) - 1.0).abs(),
        );
    }
    if target.is_empty() {
        return Ok(None);
    }
    let rms = |v: &[f64]| (v.iter().map(|e| e * e).sum::<f64>() / v.len() as f64).sqrt();
    let max = |v: &[f64]| v.iter().fold(0.0f64, |m, e| m.max(*e));
    Ok(Some(TruthErrors {
        target_rms_m: rms(&target),
        target_max_m: max(&target),
        offset_rms_s: rms(&offset),
        offset_max_s: max(&offset),
        rate_max_ppm,
        n: target.len(),
    }))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Targets 332 mm from the truth at its own clock offsets (a mirrored frame) were warned
    /// of only as another experiment's truth; they are said to be the dataset's own error.
    #[test]
    fn targets_far_from_the_truth_at_its_own_clocks_are_the_datasets_error() {
        let e = |target_rms_m: f64, offset_rms_s: f64| TruthErrors {
            target_rms_m,
            target_max_m: target_rms_m,
            offset_rms_s,
            offset_max_s: offset_rms_s,
            rate_max_ppm: 0.0,
            n: 40,
        };
        assert_eq!(e(0.0012, 0.003).mismatch_warning("o.json"), None);
        let own = e(0.332, 0.006).mismatch_warning("o.json").expect("warned");
        assert!(
            own.contains("within 6 ms of the truth's")
                && own.contains("the targets are 332 mm RMS off")
                && own.contains("do not train on it"),
            "{own}"
        );
        let other = e(0.332, 2.5).mismatch_warning("o.json").expect("warned");
        assert!(
            other.ends_with("is that the truth of the experiment the dataset was built from?"),
            "{other}"
        );
    }

    /// A manifest of `n` rows with a video each (never opened: the tracker below is a stand-in)
    /// and a log of the robot standing still, in a folder of its own.
    fn manifest_of_videos(n: usize, name: &str) -> Manifest {
        let dir = std::env::temp_dir().join(format!("odocal-{name}-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let mut log = String::from("t,left_ticks,right_ticks\n");
        for k in 0..30 {
            log.push_str(&format!("{:.1},0,0\n", k as f64 * 0.2));
        }
        let runs = (0..n)
            .map(|i| {
                let odometry = format!("run{i}.csv");
                std::fs::write(dir.join(&odometry), &log).unwrap();
                ManifestRow {
                    id: format!("run{i}"),
                    video: Some(format!("run{i}.avi")),
                    trajectory: None,
                    odometry,
                    speed_mps: None,
                    comment: crate::manifest::Note,
                    notes: crate::manifest::Note,
                    description: crate::manifest::Note,
                }
            })
            .collect();
        Manifest::new(runs, &dir)
    }

    /// A video that cannot be tracked stops the manifest there, on any number of threads:
    /// with a wrong tag id every video fails alike, and tracking them all only to report the
    /// first took minutes.
    #[test]
    fn an_untrackable_video_stops_the_manifest() {
        let m = manifest_of_videos(12, "untrackable");
        for (bad_from, threads) in [(0, 1), (0, 2), (0, 3), (5, 2), (11, 2)] {
            let tried = AtomicUsize::new(0);
            let track = |row: &ManifestRow, _: &Path| -> Result<Trajectory, String> {
                tried.fetch_add(1, Ordering::SeqCst);
                let i: usize = row.id.trim_start_matches("run").parse().unwrap();
                if i >= bad_from {
                    return Err(format!("tag 5 was never seen in {}", row.id));
                }
                // The robot standing still where its log says it stands.
                let rows = (0..180)
                    .map(|k| odocal_core::TrajectoryRow {
                        t_s: k as f64 / 30.0,
                        pose: odocal_core::Pose2::new(1.0, 1.0, 0.0),
                        quality: 1.0,
                        sigma: None,
                    })
                    .collect();
                Trajectory::new(rows).map_err(|e| e.to_string())
            };
            let err =
                build_from_manifest(&m, &BuildOptions::default(), Some(&track), threads, &|| {})
                    .unwrap_err()
                    .to_string();
            assert!(
                err.contains(&format!("tag 5 was never seen in run{bad_from}")),
                "{err}"
            );
            // Every row before the first untrackable one is tracked; after it, at most one
            // more per other thread (rows already taken when it failed).
            let tried = tried.load(Ordering::SeqCst);
            assert!(
                (bad_from + 1..=bad_from + threads).contains(&tried),
                "{tried} videos tracked on {threads} thread(s); the first untrackable is run{bad_from}"
            );
        }
        let _ = std::fs::remove_dir_all(&m.base_dir);
    }
}
