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
            let truth = match tp {
                Some(t) => {
                    let truth = odocal_lrf::read_truth_csv(t)?;
                    check_laser_truth(&log, &truth, t)?;
                    used.push(format!("laser truth {}", t.display()));
                    truth
                }
                None => odocal_lrf::LaserTruth::default(),
            };
            let landmarks_m = match &inp.lrf_map {
                Some(m) => {
                    let map = odocal_lrf::Map::read(m)?;
                    check_laser_map(&log, &map, m)?;
                    map.landmarks
                        .iter()
                        .map(|l| (l.position.x, l.position.y))
                        .collect()
                }
                None => Vec::new(),
            };
            let poses = log.rows;
            used.push(format!("laser poses {}", pp.display()));
            let sec = laser_section(&LaserInput {
                poses,
                truth,
                landmarks_m,
            })?;
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

/// The farthest a reflector navigator sees a reflector, metres (SICK's NAV350: 70 m).
const LONGEST_REFLECTOR_RANGE_M: f64 = 70.0;

/// Refuses a landmark map the poses were not localised against: most confident poses
/// matched more of its landmarks than lie within any scanner's reach of them (a map of
/// another room, in another frame or in millimetres). Drawn, the poses would sit among
/// landmarks they never saw.
fn check_laser_map(
    log: &odocal_lrf::PoseLog,
    map: &odocal_lrf::Map,
    path: &Path,
) -> Result<(), ReportError> {
    let confident: Vec<(odocal_core::Pose2, usize)> = log
        .rows
        .iter()
        .filter(|r| r.status == odocal_lrf::Status::Ok)
        .filter_map(|r| r.pose.map(|p| (p, r.n_landmarks)))
        .collect();
    let out_of_reach = confident
        .iter()
        .filter(|(p, matched)| {
            let within = map
                .landmarks
                .iter()
                .filter(|l| {
                    (l.position.x - p.x_m).hypot(l.position.y - p.y_m) <= LONGEST_REFLECTOR_RANGE_M
                })
                .count();
            within < *matched
        })
        .count();
    if out_of_reach * 2 > confident.len() {
        return Err(ReportError::Mismatch(format!(
            "--lrf-map {}: {out_of_reach} of the {} confident laser poses matched more landmarks than it has within {LONGEST_REFLECTOR_RANGE_M:.0} m of them ({} landmarks in all): the poses were localised against another map; give the map given to `odocal lrf localize` (in metres)",
            path.display(),
            confident.len(),
            map.landmarks.len()
        )));
    }
    Ok(())
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
