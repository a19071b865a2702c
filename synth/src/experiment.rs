//! The whole odometry experiment with known truth, as `odocal synth experiment` writes it:
//! a run manifest, per recording a 200 ms tick log and a ceiling video (or the camera
//! trajectory taken from the truth), and the truth itself (truth/oracle.json,
//! truth/simulator.json, truth/experiment.json, `truth/<id>.true.csv`, and with videos the
//! camera's truth per frame, `truth/<id>.frames.csv`). The videos can be taken by a realistic
//! camera ([`ExperimentSettings::effects`]).

use std::path::{Path, PathBuf};

use odocal_core::Pose2;
use odocal_dataset::manifest::{Manifest, ManifestRow};
use odocal_dataset::odometry::MAX_WHEEL_SPEED_MPS;
use odocal_dataset::oracle::{OracleFile, OracleRun, TrueKinematics};
use odocal_dataset::{DatasetError, WheelGeometry};
use rayon::prelude::*;
use serde::Serialize;
use thiserror::Error;

use crate::robot::{
    simulate_plan, simulate_recording, CameraTiming, PathKind, Plan, RobotSimConfig, RobotSimError,
    RunTruth, SimulatedRecording, TruthTrack,
};
use crate::scene::{
    frames_csv, render_video as render_scene_video, CameraEffects, FrameTruth, SceneConfig,
    SceneError, VideoFormat, ROW_TIME_CONVENTION,
};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

/// The `format` tag of truth/experiment.json.
pub const EXPERIMENT_TRUTH_FORMAT: &str = "odocal.experiment-truth/1";

/// Longest side of a square or tour area the simulator drives, metres: a lab's floor (UMBMark
/// drives 4 m squares).
pub const MAX_PATH_SIDE_M: f64 = 20.0;

/// What goes wrong while simulating an experiment.
#[derive(Debug, Error)]
pub enum ExperimentError {
    /// A setting without sense (names the option).
    #[error("{0}")]
    Settings(String),
    /// The robot simulator refused its configuration.
    #[error(transparent)]
    Sim(#[from] RobotSimError),
    /// Rendering a video failed.
    #[error(transparent)]
    Scene(#[from] SceneError),
    /// A simulated log or trajectory is not valid (a simulator defect).
    #[error(transparent)]
    Dataset(#[from] DatasetError),
    /// A simulated trajectory is not valid (a simulator defect).
    #[error(transparent)]
    File(#[from] odocal_core::FileError),
    /// A file could not be written.
    #[error("cannot write {path}")]
    Io {
        /// The file.
        path: String,
        /// The operating system's reason.
        #[source]
        source: std::io::Error,
    },
}

/// What stands for the camera.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Frames {
    /// Render ceiling videos (tracked later by `odocal dataset`).
    Video,
    /// No video: the true trajectory at the camera's frame times (with its clock offset and
    /// the configured mm-level noise) is written as the camera trajectory.
    None,
}

/// The experiment to simulate.
#[derive(Debug, Clone)]
pub struct ExperimentSettings {
    /// Number of runs.
    pub runs: usize,
    /// Random seed (same seed, same bytes).
    pub seed: u64,
    /// Camera source.
    pub frames: Frames,
    /// Runs per recording (several runs, separated by stops and carrying, in one log).
    pub runs_per_recording: usize,
    /// The robot simulator's configuration.
    pub config: RobotSimConfig,
    /// The paths driven: the straight runs of the reference experiment, or one plan per
    /// recording (tours, UMBMark squares).
    pub paths: PathKind,
    /// Side of the UMBMark square, metres.
    pub square_side_m: f64,
    /// Speed on the square's sides, m/s.
    pub square_speed_mps: f64,
    /// Legs of a random tour.
    pub tour_legs: usize,
    /// Side of the square the tour's waypoints lie in, metres.
    pub tour_area_m: f64,
    /// Container of the videos: MJPG AVI or H.264 MP4.
    pub video: VideoFormat,
    /// Exposure time of the videos, seconds.
    pub exposure_s: f64,
    /// What a real camera adds to the videos (all off by default).
    pub effects: CameraEffects,
}

impl ExperimentSettings {
    /// The reference experiment: straight runs, with the path options at their defaults.
    pub fn straight(
        runs: usize,
        seed: u64,
        frames: Frames,
        runs_per_recording: usize,
        config: RobotSimConfig,
    ) -> Self {
        Self {
            runs,
            seed,
            frames,
            runs_per_recording,
            config,
            paths: PathKind::Straight,
            square_side_m: 4.0,
            square_speed_mps: 0.5,
            tour_legs: 10,
            tour_area_m: 3.0,
            video: VideoFormat::Avi,
            exposure_s: SceneConfig::default().exposure_s,
            effects: CameraEffects::default(),
        }
    }

    /// The scene the videos are rendered in: the default camera and robot with this
    /// experiment's exposure and camera effects.
    pub fn scene(&self) -> SceneConfig {
        SceneConfig {
            exposure_s: self.exposure_s,
            effects: self.effects,
            ..SceneConfig::default()
        }
    }

    /// The plan of recording `r` (None for straight runs): squares alternate clockwise and
    /// counter-clockwise; tours are drawn from their own seeded stream.
    pub fn plan(&self, r: usize) -> Option<Plan> {
        match self.paths {
            PathKind::Straight => None,
            PathKind::Umbmark => Some(Plan::umbmark(
                self.square_side_m,
                r.is_multiple_of(2),
                self.square_speed_mps,
                0.2,
            )),
            PathKind::Tours => {
                let mut rng = ChaCha8Rng::seed_from_u64(self.seed);
                rng.set_stream((2u64 << 32) + r as u64);
                Some(Plan::tour(
                    self.tour_legs,
                    self.tour_area_m,
                    &self.config.protocol.speeds_mps,
                    &mut rng,
                ))
            }
        }
    }
}

/// Truth of one recording, as written to truth/experiment.json.
#[derive(Serialize)]
struct RecordingTruth {
    id: String,
    #[serde(skip_serializing_if = "Option::is_none")]
    plan: Option<Plan>,
    clock_offset_s: f64,
    camera_end_s: f64,
    runs: Vec<NamedRun>,
}

#[derive(Serialize)]
struct NamedRun {
    run_id: String,
    #[serde(flatten)]
    truth: RunTruth,
}

#[derive(Serialize)]
struct ExperimentTruth<'a> {
    format: &'static str,
    seed: u64,
    paths: PathKind,
    frames: Frames,
    runs: usize,
    runs_per_recording: usize,
    config: &'a RobotSimConfig,
    recordings: Vec<RecordingTruth>,
    #[serde(skip_serializing_if = "Option::is_none")]
    camera: Option<CameraTruth>,
}

/// The realistic camera of the videos, as truth/experiment.json states it.
#[derive(Serialize)]
struct CameraTruth {
    row_time: &'static str,
    exposure_s: f64,
    height_px: u32,
    effects: CameraEffects,
}

/// What [`simulate_experiment`] wrote.
pub struct ExperimentSummary {
    /// Recordings simulated.
    pub recordings: usize,
    /// The manifest, relative to the output directory.
    pub manifest: PathBuf,
}

fn write(path: &Path, bytes: &[u8]) -> Result<(), ExperimentError> {
    if let Some(dir) = path.parent() {
        std::fs::create_dir_all(dir).map_err(|source| ExperimentError::Io {
            path: dir.display().to_string(),
            source,
        })?;
    }
    std::fs::write(path, bytes).map_err(|source| ExperimentError::Io {
        path: path.display().to_string(),
        source,
    })
}

fn write_json<T: Serialize>(path: &Path, value: &T) -> Result<(), ExperimentError> {
    let mut s = serde_json::to_string_pretty(value).map_err(|e| {
        ExperimentError::Settings(format!("cannot serialise {}: {e}", path.display()))
    })?;
    s.push('\n');
    write(path, s.as_bytes())
}

/// Renders the ceiling video of one recording to `path` (`format`: MJPG AVI or H.264 MP4) in
/// `scene`: frame k at camera time k / fps, the robot at its true floor pose, seen by the same
/// camera as `synth calib` renders. Returns the truth of every frame.
pub fn render_recording_video(
    rec: &SimulatedRecording,
    camera: &CameraTiming,
    scene: &SceneConfig,
    format: VideoFormat,
    path: &Path,
    seed: u64,
) -> Result<Vec<FrameTruth>, ExperimentError> {
    let times = rec.frame_times(camera.fps);
    let trajectory: Vec<(f64, Pose2)> = times
        .iter()
        .filter_map(|&t| rec.pose_at_camera_time(t).map(|p| (t, p)))
        .collect();
    if trajectory.len() != times.len() {
        return Err(ExperimentError::Settings(
            "--frames video renders one run per recording (the robot is carried between runs); \
             use --runs-per-recording 1 or --frames none"
                .into(),
        ));
    }
    Ok(render_scene_video(
        path,
        format,
        scene,
        &trajectory,
        camera.fps,
        seed,
    )?)
}

/// Simulates the experiment into the directory `out` (which the caller makes all-or-nothing);
/// `on_recording` is called after each recording (for a progress bar).
pub fn simulate_experiment(
    out: &Path,
    s: &ExperimentSettings,
    on_recording: &(dyn Fn() + Sync),
) -> Result<ExperimentSummary, ExperimentError> {
    if s.runs == 0 {
        return Err(ExperimentError::Settings(
            "--runs must be at least 1".into(),
        ));
    }
    let per = s.runs_per_recording;
    if per == 0 {
        return Err(ExperimentError::Settings(
            "--runs-per-recording must be at least 1".into(),
        ));
    }
    if s.paths != PathKind::Straight && (per > 1 || s.frames == Frames::Video) {
        return Err(ExperimentError::Settings("--paths tours|umbmark drive one plan per recording and leave the camera's 3 x 1.7 m view: use --runs-per-recording 1 and --frames none".into()));
    }
    if !((0.0..=MAX_PATH_SIDE_M).contains(&s.square_side_m)
        && s.square_side_m > 0.0
        && s.square_speed_mps > 0.0
        && s.square_speed_mps <= MAX_WHEEL_SPEED_MPS
        && (1.0..=MAX_PATH_SIDE_M).contains(&s.tour_area_m)
        && s.tour_legs > 0)
    {
        return Err(ExperimentError::Settings(format!(
            "--square-m {:?} m, --square-speed {:?} m/s, --tour-area-m {:?} m, --tour-legs {}: the square's side must be above 0 and the tour's area at least 1 m, both at most {MAX_PATH_SIDE_M} m (a lab's floor), the speed above 0 and at most {MAX_WHEEL_SPEED_MPS} m/s (a small robot's), and a tour at least 1 leg",
            s.square_side_m, s.square_speed_mps, s.tour_area_m, s.tour_legs
        )));
    }
    if s.video == VideoFormat::Png {
        return Err(ExperimentError::Settings(
            "--video png: an experiment's videos are avi (MJPG) or mp4 (H.264)".into(),
        ));
    }
    if s.effects.h264_bitrate_kbps.is_some() && s.video != VideoFormat::Mp4 {
        return Err(ExperimentError::Settings(
            "--bitrate-kbps sets the H.264 bitrate: use it with --video mp4".into(),
        ));
    }
    if !(s.exposure_s >= 0.0 && s.exposure_s < 1.0 / s.config.camera.fps) {
        return Err(ExperimentError::Settings(format!(
            "--exposure-ms {}: must be between 0 and the frame period",
            s.exposure_s * 1e3
        )));
    }
    s.effects.check(s.config.camera.fps)?;
    if s.frames == Frames::None && s.effects != CameraEffects::default() {
        return Err(ExperimentError::Settings(
            "the camera options (--exposure-ms, --rolling-shutter-ms, --realistic, ...) shape rendered videos: use them with --frames video".into(),
        ));
    }
    if s.frames == Frames::Video && per > 1 {
        return Err(ExperimentError::Settings("--frames video renders one run per recording: use --runs-per-recording 1 or --frames none".into()));
    }
    let n_rec = s.runs.div_ceil(per);
    type Outcome = Result<(ManifestRow, RecordingTruth, Vec<OracleRun>), ExperimentError>;
    let results: Vec<Outcome> = (0..n_rec)
        .into_par_iter()
        .map(|r| {
            let res = one_recording(out, s, r);
            on_recording();
            res
        })
        .collect();
    let mut rows = Vec::with_capacity(n_rec);
    let mut truths = Vec::with_capacity(n_rec);
    let mut oracle = Vec::with_capacity(s.runs);
    for res in results {
        let (row, truth, orc) = res?;
        rows.push(row);
        truths.push(truth);
        oracle.extend(orc);
    }
    let manifest = Manifest::new(rows, out);
    write(
        &out.join("manifest.json"),
        format!("{}\n", manifest.to_json()).as_bytes(),
    )?;
    let mut oracle = OracleFile::new(oracle);
    if s.paths != PathKind::Straight {
        let sys = &s.config.systematic;
        oracle.kinematics = Some(TrueKinematics {
            left_wheel_diameter_m: sys.left_wheel_diameter_m,
            right_wheel_diameter_m: sys.right_wheel_diameter_m,
            wheel_base_m: sys.wheel_base_m,
            left_slip_per_mps: sys.left_slip_per_mps,
            right_slip_per_mps: sys.right_slip_per_mps,
        });
    }
    write_json(&out.join("truth/oracle.json"), &oracle)?;
    write_json(&out.join("truth/simulator.json"), &s.config)?;
    write_json(
        &out.join("truth/experiment.json"),
        &ExperimentTruth {
            format: EXPERIMENT_TRUTH_FORMAT,
            seed: s.seed,
            paths: s.paths,
            frames: s.frames,
            runs: s.runs,
            runs_per_recording: per,
            config: &s.config,
            recordings: truths,
            camera: (s.frames == Frames::Video && s.effects != CameraEffects::default()).then(
                || CameraTruth {
                    row_time: ROW_TIME_CONVENTION,
                    exposure_s: s.exposure_s,
                    height_px: s.scene().camera.height,
                    effects: s.effects,
                },
            ),
        },
    )?;
    Ok(ExperimentSummary {
        recordings: n_rec,
        manifest: PathBuf::from("manifest.json"),
    })
}

fn one_recording(
    out: &Path,
    s: &ExperimentSettings,
    r: usize,
) -> Result<(ManifestRow, RecordingTruth, Vec<OracleRun>), ExperimentError> {
    let per = s.runs_per_recording;
    let cfg = &s.config;
    let first = r * per;
    let last = (first + per).min(s.runs);
    let speeds: Vec<f64> = (first..last).map(|i| cfg.speed_of_run(i)).collect();
    let id = if per == 1 {
        format!("run{:03}", r + 1)
    } else {
        format!("rec{:03}", r + 1)
    };
    let plan = s.plan(r);
    let rec = match &plan {
        Some(p) => simulate_plan(cfg, p, s.seed, r as u64)?,
        None => simulate_recording(cfg, &speeds, s.seed, r as u64)?,
    };
    let speeds = match &plan {
        Some(_) => vec![rec.runs.first().map_or(0.0, |t| t.speed_mps)],
        None => speeds,
    };
    if rec.runs.len() != speeds.len() {
        return Err(ExperimentError::Settings(format!(
            "recording {id}: simulated {} of {} runs",
            rec.runs.len(),
            speeds.len()
        )));
    }
    let log = rec.odometry_log()?;
    let odo_rel = format!("runs/{id}.odometry.csv");
    write(&out.join(&odo_rel), log.to_csv().as_bytes())?;
    let (video, trajectory) = match s.frames {
        Frames::None => {
            let traj = rec.camera_track(&cfg.camera, s.seed, (1u64 << 32) + r as u64)?;
            let rel = format!("runs/{id}.trajectory.csv");
            write(&out.join(&rel), traj.to_csv().as_bytes())?;
            (None, Some(rel))
        }
        Frames::Video => {
            let ext = if s.video == VideoFormat::Mp4 {
                "mp4"
            } else {
                "avi"
            };
            let rel = format!("runs/{id}.{ext}");
            let seed = s.seed.wrapping_mul(1_000_003).wrapping_add(r as u64);
            let frames = render_recording_video(
                &rec,
                &cfg.camera,
                &s.scene(),
                s.video,
                &out.join(&rel),
                seed,
            )?;
            // The camera's truth per frame: dropped, occluded, blur, rolling-shutter rows.
            write(
                &out.join(format!("truth/{id}.frames.csv")),
                frames_csv(&frames).as_bytes(),
            )?;
            (Some(rel), None)
        }
    };
    // True trajectory at 100 Hz on both clocks.
    let csv = TruthTrack::of_recording(&rec).to_csv();
    write(&out.join(format!("truth/{id}.true.csv")), csv.as_bytes())?;
    let names: Vec<String> = (0..rec.runs.len())
        .map(|j| {
            if per == 1 {
                id.clone()
            } else {
                format!("{id}.{}", j + 1)
            }
        })
        .collect();
    let oracle = rec
        .runs
        .iter()
        .zip(&names)
        .map(|(t, name)| OracleRun {
            run_id: name.clone(),
            geometry: WheelGeometry {
                left_wheel_diameter_m: t.effective.left_wheel_diameter_m,
                right_wheel_diameter_m: t.effective.right_wheel_diameter_m,
                wheel_base_m: t.effective.wheel_base_m,
            },
            true_end_m: [t.end_in_start_frame.x_m, t.end_in_start_frame.y_m],
            clock_offset_s: rec.clock_offset_s,
        })
        .collect();
    let row = ManifestRow {
        id: id.clone(),
        video,
        trajectory,
        odometry: odo_rel,
        speed_mps: if per == 1 && plan.is_none() {
            Some(speeds[0])
        } else {
            None
        },
        comment: Default::default(),
        notes: Default::default(),
        description: Default::default(),
    };
    let truth = RecordingTruth {
        id,
        plan,
        clock_offset_s: rec.clock_offset_s,
        camera_end_s: rec.camera_end_s,
        runs: rec
            .runs
            .iter()
            .zip(names)
            .map(|(t, run_id)| NamedRun { run_id, truth: *t })
            .collect(),
    };
    Ok((row, truth, oracle))
}
