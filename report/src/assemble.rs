//! The whole report from the files of a pipeline run: each section built from the outputs of
//! its stage, left out (with the reason) where they are missing.

use std::path::{Path, PathBuf};

use odocal_calib::CameraFile;
use odocal_core::TextFormat;
use odocal_dataset::Dataset;
use odocal_synth::board::{true_corners, CalibTruth};
use odocal_trainer::{sha256_hex, ModelFile, SweepReport};

use crate::{
    calibration_section, corrector_section, heading_section, laser_section, parse_track_csv,
    pick_runs, training_section, trajectory_section, CalibInput, CalibView, LaserInput, Report,
    ReportError, RunView, TrackFile,
};

/// The files a report is made from; any may be absent.
#[derive(Debug, Clone, Default)]
pub struct ReportInputs {
    /// camera.json from `odocal calibrate`.
    pub camera: Option<PathBuf>,
    /// truth.json from `odocal synth calib`.
    pub calib_truth: Option<PathBuf>,
    /// dataset.json from `odocal dataset`.
    pub dataset: Option<PathBuf>,
    /// model.json from `odocal train`.
    pub model: Option<PathBuf>,
    /// report.json from `odocal train --sweep`.
    pub train_report: Option<PathBuf>,
    /// Output folder of `odocal synth experiment`.
    pub experiment: Option<PathBuf>,
    /// Folder of camera trajectories `<recording id>.trajectory.csv`.
    pub trajectories: Option<PathBuf>,
    /// Pose log of `odocal lrf localize`.
    pub lrf_poses: Option<PathBuf>,
    /// True sensor poses of `odocal synth lrf`.
    pub lrf_truth: Option<PathBuf>,
    /// The landmark map.
    pub lrf_map: Option<PathBuf>,
    /// The scanner's range the poses were localised with (`lrf localize --max-range-m`),
    /// metres; None: that command's default.
    pub lrf_max_range_m: Option<f64>,
    /// The scanner's field of view (`lrf localize --fov-deg`), degrees; None: that command's
    /// default.
    pub lrf_fov_deg: Option<f64>,
    /// The arena file and, optionally, the arena tracking summary.
    pub arena: Option<(PathBuf, Option<PathBuf>)>,
    /// Track reports of `odocal track --truth … --report` (one tracking condition each).
    pub track_reports: Vec<PathBuf>,
    /// Runs drawn in the trajectory and heading figures.
    pub runs: usize,
    /// The report's title.
    pub title: String,
}

/// Builds the report from `inp`: every section whose inputs are there, the others listed as
/// left out with the reason.
pub fn assemble(inp: &ReportInputs) -> Result<Report, ReportError> {
    let mut report = Report {
        title: inp.title.clone(),
        ..Report::default()
    };
    let mut used = Vec::new();
    let omit = |r: &mut Report, title: &str, why: &str| {
        r.omitted.push((title.to_string(), why.to_string()))
    };

    // Calibration.
    match &inp.camera {
        Some(p) => {
            let cam = CameraFile::load(p)?;
            // A known camera (synth calib's camera_true.json, an arena's) has no views: its
            // section read "Zhang calibration from 0 views: reprojection RMS 0.000 px".
            if cam.views.is_empty() {
                return Err(ReportError::Mismatch(format!(
                    "--camera {}: has no calibration views (reprojection RMS {} px from none): it is a known camera's file, such as `synth calib`'s camera_true.json, not a calibration; give the camera.json `odocal calibrate` wrote",
                    p.display(),
                    cam.rms_px
                )));
            }
            let truth = inp
                .calib_truth
                .as_deref()
                .map(|t| CalibTruth::read_for_file(t, &cam))
                .transpose()?;
            used.push(format!("camera {}", p.display()));
            if let Some(t) = &inp.calib_truth {
                used.push(format!("calibration truth {}", t.display()));
            }
            report
                .sections
                .push(calibration_section(&calib_input(&cam, truth.as_ref()))?);
        }
        None => omit(
            &mut report,
            "Camera calibration",
            "no camera.json given (--camera)",
        ),
    }

    // Runs: trajectories, heading, corrector.
    let ds = match &inp.dataset {
        Some(p) => {
            let text = odocal_core::read_text(p)?;
            let ds = Dataset::parse(&text, &p.display().to_string())?;
            // What `odocal train` records of the file it trained on.
            Some((ds, sha256_hex(text.as_bytes())))
        }
        None => None,
    };
    let mdl = match &inp.model {
        Some(p) => {
            let m = ModelFile::read(p)?;
            used.push(format!("model {}", p.display()));
            Some(m)
        }
        None => None,
    };
    let sweep = inp
        .train_report
        .as_deref()
        .map(SweepReport::read)
        .transpose()?;
    if let (Some(dp), Some((_, sha))) = (&inp.dataset, &ds) {
        if let (Some(mp), Some(m)) = (&inp.model, &mdl) {
            check_same_dataset(
                mp,
                &m.dataset_sha256,
                dp,
                sha,
                "the model was trained",
                "its corrections of these runs would be drawn as its fit to them; give the dataset.json it was trained on, or retrain it on this one with `odocal train`",
            )?;
        }
        if let (Some(rp), Some(r)) = (&inp.train_report, &sweep) {
            check_same_dataset(
                rp,
                &r.dataset_sha256,
                dp,
                sha,
                "the sweep ran",
                "its Tables 1 and 2 would be shown beside runs they were not computed on; give the report.json of a sweep on this dataset, or rerun `odocal train --sweep` on it",
            )?;
        }
    }
    match &ds {
        Some((ds, _)) if !ds.samples.is_empty() => {
            if let Some(p) = &inp.dataset {
                used.push(format!(
                    "dataset {} ({} runs)",
                    p.display(),
                    ds.samples.len()
                ));
            }
            let preds = match &mdl {
                Some(m) => Some(
                    ds.samples
                        .iter()
                        .map(|s| {
                            m.correct(&s.inputs).map_err(|e| {
                                ReportError::Mismatch(format!(
                                    "the model does not fit run {} of the dataset: {e}",
                                    s.run_id
                                ))
                            })
                        })
                        .collect::<Result<Vec<[f64; 2]>, ReportError>>()?,
                ),
                None => None,
            };
            let picked = pick_runs(&ds.samples, inp.runs);
            let views_with = |experiment: Option<&Path>, trajectories: Option<&Path>| {
                picked
                    .iter()
                    .map(|&i| {
                        let s = &ds.samples[i];
                        let rec = if s.recording_id.is_empty() {
                            &s.run_id
                        } else {
                            &s.recording_id
                        };
                        let track = find_track(rec, experiment, trajectories)?;
                        Ok(RunView::new(
                            s,
                            &ds.robot,
                            preds.as_ref().map(|p| p[i]),
                            track.as_ref(),
                        ))
                    })
                    .collect::<Result<Vec<RunView>, ReportError>>()
            };
            // Each folder given is checked on its own: the first holding a run's track is
            // drawn, so another experiment's tracks given beside the right ones passed unseen.
            let sources = [
                (
                    inp.experiment.as_deref(),
                    None,
                    "--experiment",
                    "experiment",
                ),
                (
                    None,
                    inp.trajectories.as_deref(),
                    "--trajectories",
                    "trajectories",
                ),
            ];
            for (experiment, trajectories, option, what) in sources {
                let Some(folder) = experiment.or(trajectories) else {
                    continue;
                };
                let own = views_with(experiment, trajectories)?;
                check_tracks_fit(&own, &format!("{option} {}", folder.display()))?;
                if own.iter().any(|v| v.real_end_off_m().is_some()) {
                    used.push(format!("{what} {}", folder.display()));
                } else if own.iter().any(|v| !v.real_source.is_empty()) {
                    // The files are there but reach no run's end: "holds the track of none"
                    // sent the user looking for files that were there.
                    let n_found = own.iter().filter(|v| !v.real_source.is_empty()).count();
                    return Err(ReportError::Mismatch(format!(
                        "{option} {}: it has the tracks of {n_found} of the {} runs drawn from the dataset, but none reaches its run's end (no pose within 0.1 s of it on the robot's clock): are they empty, cut short, or on another clock? Give the {what} the dataset was built from",
                        folder.display(),
                        own.len()
                    )));
                } else {
                    // Given and matching nothing used to read as not given at all.
                    let looked_for = if experiment.is_some() {
                        "truth/RUN.true.csv or runs/RUN.trajectory.csv"
                    } else {
                        "RUN.trajectory.csv or RUN.csv"
                    };
                    return Err(ReportError::Mismatch(format!(
                        "{option} {}: it holds the track of none of the {} runs drawn from the dataset (looked for {looked_for}, RUN a run's recording id, e.g. {}): give the {what} folder the dataset was built from",
                        folder.display(),
                        own.len(),
                        picked
                            .first()
                            .map(|&i| {
                                let s = &ds.samples[i];
                                if s.recording_id.is_empty() {
                                    s.run_id.as_str()
                                } else {
                                    s.recording_id.as_str()
                                }
                            })
                            .unwrap_or("?")
                    )));
                }
            }
            let views = views_with(inp.experiment.as_deref(), inp.trajectories.as_deref())?;
            report.sections.push(trajectory_section(&views)?);
            report
                .sections
                .extend(crate::sections::target_sigma_section(&ds.samples));
            match heading_section(&views)? {
                Some(sec) => report.sections.push(sec),
                None => omit(
                    &mut report,
                    "Heading oscillation (Figure 4)",
                    "no real trajectories of the runs (--experiment or --trajectories)",
                ),
            }
            report
                .sections
                .push(corrector_section(&ds.samples, preds.as_deref())?);
        }
        Some(_) => omit(
            &mut report,
            "Trajectories and end-point errors",
            "the dataset has no samples",
        ),
        None => omit(
            &mut report,
            "Trajectories, heading and end-point errors (Figures 4–7)",
            "no dataset.json given (--dataset)",
        ),
    }

    // Tables 1 and 2.
    match (&inp.train_report, &sweep) {
        (Some(p), Some(rep)) => {
            used.push(format!("training report {}", p.display()));
            report.sections.push(training_section(rep)?);
        }
        _ => omit(
            &mut report,
            "Training: Tables 1 and 2",
            "no training report given (--train-report DIR/report.json)",
        ),
    }

    // Laser.
    match (&inp.lrf_poses, &inp.lrf_truth) {
        (Some(pp), tp) => {
            let log = odocal_lrf::PoseLog::read(pp)?;
            check_laser_poses(&log, pp)?;
            let truth = match tp {
                Some(t) => {
                    check_not_pose_log(t)?;
                    let truth = odocal_lrf::read_truth_csv(t)?;
                    check_laser_truth(&log, &truth, t)?;
                    used.push(format!("laser truth {}", t.display()));
                    truth
                }
                None => odocal_lrf::LaserTruth::default(),
            };
            let mut map_note = None;
            let landmarks_m = match &inp.lrf_map {
                Some(m) => {
                    let map = odocal_lrf::Map::read(m)?;
                    let range_m = inp
                        .lrf_max_range_m
                        .unwrap_or(odocal_lrf::SensorConfig::default().max_range_m);
                    let fov_rad = inp
                        .lrf_fov_deg
                        .map_or(odocal_lrf::SensorConfig::default().fov_rad, f64::to_radians);
                    map_note = check_laser_map(&log, &map, m, range_m, fov_rad)?;
                    used.push(format!("landmark map {}", m.display()));
                    map.landmarks
                        .iter()
                        .map(|l| (l.position.x, l.position.y))
                        .collect()
                }
                None => Vec::new(),
            };
            let poses = log.rows;
            used.push(format!("laser poses {}", pp.display()));
            let mut sec = laser_section(&LaserInput {
                poses,
                truth,
                landmarks_m,
            })?;
            if let Some(n) = map_note {
                sec.blocks
                    .insert(1.min(sec.blocks.len()), crate::Block::Note(n));
            }
            report.sections.push(sec);
            if tp.is_none() {
                omit(
                    &mut report,
                    "Laser error against the truth",
                    "no laser truth given (--lrf-truth)",
                );
            }
        }
        (None, _) => omit(
            &mut report,
            "Laser positioning",
            "no laser poses given (--lrf-poses from `odocal lrf localize --out`)",
        ),
    }

    // Tracking conditions: each track report compared with its video's truth.
    if inp.track_reports.is_empty() {
        omit(
            &mut report,
            "Tracking under real-camera conditions",
            "no track reports given (--track-report: `odocal track --truth frames.csv --report`)",
        );
    } else {
        let mut rows = Vec::new();
        for p in &inp.track_reports {
            let r = odocal_tracker::TrackReportTruth::load(p)?;
            let Some(a) = r.against_truth else {
                return Err(ReportError::Mismatch(format!(
                    "{}: this track report of {} has no comparison with the truth: run `odocal track` with --truth (the video's frames.csv or truth.csv) and --report",
                    p.display(),
                    r.video
                )));
            };
            used.push(format!("track report {} ({})", p.display(), a.condition));
            rows.push(crate::sections::ConditionRow {
                condition: a.condition,
                frames: a.frames,
                fixes: a.fixes,
                position_rms_m: a.errors.position_rms_m,
                position_max_m: a.errors.position_max_m,
                heading_rms_rad: a.errors.heading_rms_rad,
                normalised_xy: a.errors.error_over_sigma_xy.unwrap_or(f64::NAN),
                normalised_theta: a.errors.error_over_sigma_theta.unwrap_or(f64::NAN),
                apriltag3_rate: a.apriltag3_rate,
                warnings: r.warnings,
            });
        }
        report.sections.push(crate::conditions_section(&rows)?);
    }

    if let Some((a, t)) = &inp.arena {
        used.push(format!("arena {}", a.display()));
        let arena = crate::sections::ArenaInput::read(a, t.as_deref())?;
        report
            .sections
            .push(crate::sections::arena_section(&arena)?);
    }

    report.intro.push(format!(
        "Inputs: {}.",
        if used.is_empty() {
            "none".to_string()
        } else {
            used.join("; ")
        }
    ));
    report
        .intro
        .push("Units: metres (m), centimetres (cm), millimetres (mm), pixels (px), degrees (deg), seconds (s).".into());
    Ok(report)
}

/// Refuses a model or sweep report (`file`, whose `dataset_sha256` is `its_sha`) made from
/// another dataset than the report's (`dataset`, hashed `sha` as `odocal train` hashes it):
/// the report would present its figures as this dataset's with nothing to tell them apart.
/// `made` says how the file came from its dataset, `then` what would go wrong and what to do.
fn check_same_dataset(
    file: &Path,
    its_sha: &str,
    dataset: &Path,
    sha: &str,
    made: &str,
    then: &str,
) -> Result<(), ReportError> {
    if its_sha == sha {
        return Ok(());
    }
    // Enough digits to tell the two apart at a glance; a hand-edited hash may be anything.
    let short = |h: &str| h.chars().take(12).collect::<String>();
    Err(ReportError::Mismatch(format!(
        "{}: {made} on another dataset than {} (its dataset_sha256 {}…, the dataset's SHA-256 {}…): {then}",
        file.display(),
        dataset.display(),
        short(its_sha),
        short(sha)
    )))
}

fn file_name(s: &str) -> &str {
    Path::new(s)
        .file_name()
        .and_then(|n| n.to_str())
        .unwrap_or(s)
}

fn calib_input(cam: &CameraFile, truth: Option<&CalibTruth>) -> CalibInput {
    let views = cam
        .views
        .iter()
        .map(|v| {
            let detected = (!v.corners_px.is_empty())
                .then(|| v.corners_px.iter().map(|p| (p[0], p[1])).collect());
            let corners_px = detected.or_else(|| {
                truth.and_then(|t| {
                    t.views
                        .iter()
                        .chain(&t.floor_views)
                        .find(|tv| file_name(&tv.image) == file_name(&v.image))
                        .map(|tv| {
                            true_corners(&t.camera, &tv.board_to_camera, &t.scene.board)
                                .iter()
                                .map(|p| (p.x, p.y))
                                .collect()
                        })
                })
            });
            CalibView {
                image: v.image.clone(),
                rms_px: Some(v.rms_px),
                corners_px,
            }
        })
        .collect::<Vec<_>>();
    let k = cam.camera.intrinsics;
    let mut facts = vec![format!(
        "Intrinsics: fx {:.2} px, fy {:.2} px, cx {:.2} px, cy {:.2} px{}.",
        k.fx,
        k.fy,
        k.cx,
        k.cy,
        cam.std.as_ref().map_or(String::new(), |s| format!(
            " (standard deviations {:.2}, {:.2}, {:.2}, {:.2} px)",
            s.fx, s.fy, s.cx, s.cy
        ))
    )];
    if let Some(f) = &cam.floor {
        facts.push(format!(
            "Floor plane: camera {:.4} m above the floor, plane fit RMS {:.2} mm from {} floor views.",
            f.camera_height_m,
            1000.0 * f.plane_rms_m,
            f.views.len()
        ));
        if let Some(r) = cam
            .floor_uncertainty
            .as_ref()
            .and_then(|m| m.vouched_reach(&cam.camera, &f.floor_to_camera))
        {
            let text = r.sentence(cam.model_comparison.is_empty());
            let mut chars = text.chars();
            let first = chars.next().map(|c| c.to_uppercase().to_string());
            facts.push(format!("{}{}.", first.unwrap_or_default(), chars.as_str()));
        }
    }
    if let Some(t) = truth {
        let tk = t.camera.intrinsics;
        facts.push(format!(
            "Against the synthetic truth: fx {:+.3} % , fy {:+.3} %, cx {:+.2} px, cy {:+.2} px.",
            100.0 * (k.fx - tk.fx) / tk.fx,
            100.0 * (k.fy - tk.fy) / tk.fy,
            k.cx - tk.cx,
            k.cy - tk.cy
        ));
    }
    let any_corners = views.iter().any(|v| v.corners_px.is_some());
    let detected = cam.views.iter().any(|v| !v.corners_px.is_empty());
    CalibInput {
        image_size_px: (cam.camera.width, cam.camera.height),
        rms_px: cam.rms_px,
        views,
        skipped: cam
            .skipped
            .iter()
            .map(|s| (s.image.clone(), s.reason.clone()))
            .collect(),
        corners_source: any_corners.then(|| {
            if detected {
                "corners as detected, from camera.json".to_string()
            } else {
                "true corner positions from the synthetic truth".to_string()
            }
        }),
        facts,
        projection_sigma: cam.covariance_matrix().map(|cov| {
            odocal_calib::UncertaintyMap::new(&cam.camera, &cov, (cam.camera.width / 32).max(8))
        }),
        floor_sigma: cam.floor_uncertainty.clone(),
    }
}

/// Real tracks farther than this from the dataset's end points (median over the runs drawn,
/// metres) are another recording's: a track and the camera's end point of one recording agree
/// to millimetres.
const TRACK_END_MISMATCH_M: f64 = 0.05;

/// Refuses real tracks (--experiment, --trajectories) that are not of the recordings the
/// dataset was built from: they are found by run id alone, and another experiment's runs
/// share the ids.
fn check_tracks_fit(views: &[RunView], source: &str) -> Result<(), ReportError> {
    let mut off: Vec<f64> = views.iter().filter_map(RunView::real_end_off_m).collect();
    if off.is_empty() {
        return Ok(());
    }
    off.sort_by(f64::total_cmp);
    let median = off[off.len() / 2];
    if median <= TRACK_END_MISMATCH_M {
        return Ok(());
    }
    let how_far = match off.len() {
        1 => format!(
            "its track ends {:.0} mm from the end point the dataset has for the same run id",
            median * 1e3
        ),
        n => format!(
            "its tracks end {:.0} mm (median over {n} runs) from the end points the dataset has for the same run ids",
            median * 1e3
        ),
    };
    Err(ReportError::Mismatch(format!(
        "{source}: {how_far}, where one recording's agree to millimetres: give the experiment or trajectories the dataset was built from"
    )))
}

/// The real track of a recording from the experiment or trajectory folders, if there is one.
fn find_track(
    rec: &str,
    experiment: Option<&Path>,
    trajectories: Option<&Path>,
) -> Result<Option<TrackFile>, ReportError> {
    let mut candidates = Vec::new();
    if let Some(e) = experiment {
        candidates.push(e.join("truth").join(format!("{rec}.true.csv")));
        candidates.push(e.join("runs").join(format!("{rec}.trajectory.csv")));
    }
    if let Some(t) = trajectories {
        candidates.push(t.join(format!("{rec}.trajectory.csv")));
        candidates.push(t.join(format!("{rec}.csv")));
    }
    for c in candidates {
        if c.exists() {
            let text = odocal_core::read_text(&c)?;
            return Ok(Some(parse_track_csv(&text, &c.display().to_string())?));
        }
    }
    Ok(None)
}

/// How far past the scanner's range a matched landmark may lie, metres: a pose is
/// centimetres off, and a strip's centre lies behind the edge the scanner reaches.
const REACH_SLACK_M: f64 = 0.1;

/// How far behind a strip's plane a scanner that saw it may seem (as a fraction of its
/// distance, about 3°): a pose is centimetres off, a surveyed facing a degree or two.
const FRONT_SLACK: f64 = 0.05;

/// How far past the edge of the scanner's field of view a matched landmark may lie (1°): a
/// pose's heading is a fraction of a degree off.
const VIEW_SLACK_RAD: f64 = 1.0 * std::f64::consts::PI / 180.0;

/// Refuses a pose log with no pose to draw (a header only, every scan lost): a laser section
/// asked for and empty is most likely the wrong file, or a localisation that failed.
fn check_laser_poses(log: &odocal_lrf::PoseLog, path: &Path) -> Result<(), ReportError> {
    if log.rows.is_empty() {
        return Err(ReportError::Mismatch(format!(
            "--lrf-poses {}: has no scans (a header only): give the --out of `odocal lrf localize` run on the recording's scans",
            path.display()
        )));
    }
    if log.rows.iter().all(|r| r.pose.is_none()) {
        return Err(ReportError::Mismatch(format!(
            "--lrf-poses {}: all {} scans are lost, so the laser section would show nothing: localise them again with `odocal lrf localize` against the room's map (with the scanner's --max-range-m and --fov-deg), or leave --lrf-poses out",
            path.display(),
            log.rows.len()
        )));
    }
    Ok(())
}

/// Refuses a pose log given as the truth (`--lrf-truth poses.csv`, or another run's poses):
/// its `t,x,y,theta` read as true poses, and the poses were judged against an estimate.
fn check_not_pose_log(path: &Path) -> Result<(), ReportError> {
    let text = odocal_core::read_text(path)?;
    let header = text.lines().next().unwrap_or("");
    let cols: Vec<&str> = header
        .split(',')
        .map(str::trim)
        .filter(|c| matches!(*c, "status" | "mode" | "n_hypotheses"))
        .collect();
    if !cols.is_empty() {
        return Err(ReportError::Mismatch(format!(
            "--lrf-truth {}: has the column{} {} of a pose log of `odocal lrf localize`, not true poses: give the true sensor poses (truth.csv of `odocal synth lrf`, or a motion-capture track, columns t,x,y,theta)",
            path.display(),
            if cols.len() > 1 { "s" } else { "" },
            cols.join(", ")
        )));
    }
    Ok(())
}

/// Refuses a landmark map the poses were not localised against (another room's, in another
/// frame, shifted, of another layout): confident poses matched more landmarks than the map has
/// facing them, unhidden by its walls, within the scanner's range `range_m` and field of
/// view `fov_rad`, which a pose of this map cannot. Drawn, the poses would sit among
/// landmarks they never saw. A few such poses (wrong ones) are said in a note (returned).
fn check_laser_map(
    log: &odocal_lrf::PoseLog,
    map: &odocal_lrf::Map,
    path: &Path,
    range_m: f64,
    fov_rad: f64,
) -> Result<Option<String>, ReportError> {
    let reach = range_m + REACH_SLACK_M;
    let half_fov = 0.5 * fov_rad + VIEW_SLACK_RAD;
    // The landmarks a scanner at `s` heading `theta` can see: facing it (a pose is
    // centimetres off: 5 cm on the visible side's line), in its field of view and not behind
    // a wall, as `lrf localize` counts them.
    let seen = |s: &nalgebra::Point2<f64>, theta: f64, l: &odocal_lrf::Landmark| {
        let d = l.position - s;
        let in_view = fov_rad >= std::f64::consts::TAU
            || odocal_core::wrap_angle(d.y.atan2(d.x) - theta).abs() <= half_fov;
        // In front of the strip: a strip is matched even seen edge-on, past its acceptance
        // cone, but never from behind.
        let in_front = l
            .facing
            .is_none_or(|f| f.dot(&(-d)) >= -FRONT_SLACK * d.norm());
        in_view && in_front && !map.occluded(s, &l.position, 0.05)
    };
    let mut n_confident = 0usize;
    let mut short: Vec<(nalgebra::Point2<f64>, f64, usize)> = Vec::new();
    for r in &log.rows {
        let (odocal_lrf::Status::Ok, Some(p), true) = (r.status, r.pose, r.n_landmarks > 0) else {
            continue;
        };
        n_confident += 1;
        let s = nalgebra::Point2::new(p.x_m, p.y_m);
        let mut n = 0;
        map.for_each_within(&s, reach, |i| {
            let l = &map.landmarks[i];
            if (l.position - s).norm() <= reach && seen(&s, p.theta_rad, l) {
                n += 1;
            }
        });
        // Only the landmarks matched: the score's count of those missed is of the
        // hypothesis, and a tracked pose's refit may match more than it.
        let in_view = r.n_landmarks;
        if n < in_view {
            short.push((s, p.theta_rad, in_view));
        }
    }
    if short.is_empty() {
        return Ok(None);
    }
    // How far the map says the poses would have had to see: the distance to the k-th
    // nearest landmark in view, k the landmarks matched (median over a sample of them).
    let mut needed: Vec<f64> = short
        .iter()
        .step_by(short.len().div_ceil(200))
        .map(|(s, theta, k)| {
            let mut d: Vec<f64> = map
                .landmarks
                .iter()
                .filter(|l| seen(s, *theta, l))
                .map(|l| (l.position - s).norm())
                .collect();
            d.sort_by(f64::total_cmp);
            d.get(k - 1).copied().unwrap_or(f64::INFINITY)
        })
        .collect();
    needed.sort_by(f64::total_cmp);
    let median = needed[needed.len() / 2];
    let how_far = if median.is_finite() {
        format!("{median:.1} m (median)")
    } else {
        "farther than any landmark facing them".to_string()
    };
    let fov_deg = fov_rad.to_degrees();
    // A pose this map cannot have is a wrong pose or another map's: one in twenty is more
    // wrong poses than `lrf localize` calls ok, over five maps of one room tried against
    // another's poses, a third were let through at one in ten.
    if short.len() * 20 > n_confident {
        return Err(ReportError::Mismatch(format!(
            "--lrf-map {}: {} of the {n_confident} confident laser poses matched more landmarks than it has facing them within the scanner's range ({range_m} m) and field of view ({fov_deg:.0}°) (it would have had to reach {how_far}): the poses were localised against another map or frame; give the map given to `odocal lrf localize`, or its --max-range-m and --fov-deg as --lrf-max-range-m and --lrf-fov-deg",
            path.display(),
            short.len(),
        )));
    }
    Ok(Some(format!(
        "WARNING: {} of the {n_confident} ok poses matched more landmarks than the map {} has facing them within the scanner's range ({range_m} m) and field of view ({fov_deg:.0}°) (they would have had to reach {how_far}): those poses are wrong, or the map was changed since they were localised.",
        short.len(),
        path.display()
    )))
}

/// Refuses a laser truth that is not the truth of the poses, as `lrf localize --truth` does:
/// one with no row at (or around) any scan's time, or against which most confident poses
/// are wrong. Drawn, it would read as the poses' accuracy.
fn check_laser_truth(
    log: &odocal_lrf::PoseLog,
    truth: &odocal_lrf::LaserTruth,
    path: &Path,
) -> Result<(), ReportError> {
    let e = odocal_lrf::evaluate(&log.for_evaluation(), truth);
    if e.n_scans == 0 {
        return Err(ReportError::Mismatch(format!(
            "--lrf-truth {}: no row has the time of a laser pose, nor are two rows around one: give the truth of these scans (on the scans' clock, in seconds)",
            path.display()
        )));
    }
    // A figure over a few poses reads like one over them all: a truth that times fewer than
    // half of the confident poses is on another clock or of another part of the recording.
    let n_ok = log
        .rows
        .iter()
        .filter(|r| r.status == odocal_lrf::Status::Ok)
        .count();
    if e.n_ok * 2 < n_ok {
        return Err(ReportError::Mismatch(format!(
            "--lrf-truth {}: it has the time of only {} of the {n_ok} confident laser poses, so the figures against it would be over those alone: are the scans and the truth timed on one clock, in seconds? (For a truth of part of the recording, localise that part's scans.)",
            path.display(),
            e.n_ok
        )));
    }
    // Most poses far off is another recording's truth; positions that agree with headings
    // that do not are the truth's headings in another unit or convention, refused as `lrf
    // localize --truth` refuses them (a few headings off are said in the laser section).
    let headings_only = e.n_accuracy > 0 && e.position_rms_m <= odocal_lrf::CORRECT_POS_M;
    if e.n_ok > 0 && e.n_wrong_ok * 2 > e.n_ok && headings_only {
        return Err(ReportError::Mismatch(format!(
            "--lrf-truth {}: {} of the {} confident laser poses it has a time for are wrong against it in heading only (position RMS {:.1} mm, heading RMS {:.1}°): is its theta in radians (not degrees), counter-clockwise, and the heading of the scanner rather than of the robot it rides on?",
            path.display(),
            e.n_wrong_ok,
            e.n_ok,
            e.position_rms_m * 1e3,
            e.heading_rms_rad.to_degrees()
        )));
    }
    if e.n_ok > 0 && e.n_wrong_ok * 2 > e.n_ok {
        return Err(ReportError::Mismatch(format!(
            "--lrf-truth {}: {} of the {} confident laser poses it has a time for are wrong against it (position RMS {:.1} mm):{} is it the truth of these scans?",
            path.display(),
            e.n_wrong_ok,
            e.n_ok,
            e.position_rms_m * 1e3,
            odocal_lrf::truth_unit_hint(e.position_rms_m)
        )));
    }
    Ok(())
}
