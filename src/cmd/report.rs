//! `odocal report`: one self-contained HTML file (inline SVG plots, no scripts, no network)
//! from whatever stage outputs are given; sections without inputs are left out with a note.

use std::path::{Path, PathBuf};

use anyhow::{bail, Context};
use odocal_calib::CameraFile;
use odocal_dataset::Dataset;
use odocal_report::{
    calibration_section, corrector_section, heading_section, laser_section,
    parse_track_csv, pick_runs, training_section, trajectory_section, CalibInput, CalibView,
    LaserInput, Report, RunView, TrackFile,
};
use odocal_synth::board::{true_corners, CalibTruth};
use odocal_trainer::{ModelFile, SweepReport};

use crate::output::write_atomic;

/// Arguments of this subcommand.
#[derive(clap::Args)]
pub struct Args {
    /// Where to write the HTML report.
    #[arg(long)]
    pub out: PathBuf,
    /// Output folder of scripts/demo.sh: every input below is looked up there at its standard
    /// place (camera.json, calib/truth.json, experiment/, dataset.json, model.json,
    /// train/report.json, lrf/{poses.csv,truth.csv,map.json}); missing files are left out.
    #[arg(long)]
    pub demo_dir: Option<PathBuf>,
    /// camera.json from `odocal calibrate`.
    #[arg(long)]
    pub camera: Option<PathBuf>,
    /// truth.json from `odocal synth calib` (corner positions for the coverage plot).
    #[arg(long)]
    pub calib_truth: Option<PathBuf>,
    /// dataset.json from `odocal dataset`.
    #[arg(long)]
    pub dataset: Option<PathBuf>,
    /// model.json from `odocal train`.
    #[arg(long)]
    pub model: Option<PathBuf>,
    /// report.json from `odocal train --sweep A..B --report DIR`.
    #[arg(long)]
    pub train_report: Option<PathBuf>,
    /// Output folder of `odocal synth experiment` (real tracks: truth/<id>.true.csv or
    /// runs/<id>.trajectory.csv).
    #[arg(long)]
    pub experiment: Option<PathBuf>,
    /// Folder of camera trajectories `<recording id>.trajectory.csv` (from `odocal track`).
    #[arg(long)]
    pub trajectories: Option<PathBuf>,
    /// Sensor poses from `odocal lrf localize --out`.
    #[arg(long)]
    pub lrf_poses: Option<PathBuf>,
    /// True sensor poses (truth.csv from `odocal synth lrf`).
    #[arg(long)]
    pub lrf_truth: Option<PathBuf>,
    /// Landmark map (map.json) to draw the landmarks.
    #[arg(long)]
    pub lrf_map: Option<PathBuf>,
    /// Also write every plot as its own SVG file into this folder.
    #[arg(long)]
    pub svg_dir: Option<PathBuf>,
    /// Runs drawn in the trajectory and heading figures (one per commanded speed).
    #[arg(long, default_value_t = 3)]
    pub runs: usize,
    /// Report title.
    #[arg(long, default_value = "odocal report")]
    pub title: String,
}

/// An input: the explicit path (must exist) or the demo folder's standard file (may be absent).
fn input(
    explicit: &Option<PathBuf>,
    demo: &Option<PathBuf>,
    rel: &str,
) -> anyhow::Result<Option<PathBuf>> {
    if let Some(p) = explicit {
        if !p.exists() {
            bail!("{}: no such file or folder", p.display());
        }
        return Ok(Some(p.clone()));
    }
    Ok(demo.as_ref().map(|d| d.join(rel)).filter(|p| p.exists()))
}

fn read(p: &Path) -> anyhow::Result<String> {
    std::fs::read_to_string(p).with_context(|| format!("cannot read {}", p.display()))
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
    }
}

/// The real track of a recording from the experiment or trajectory folders, if there is one.
fn find_track(
    rec: &str,
    experiment: Option<&Path>,
    trajectories: Option<&Path>,
) -> anyhow::Result<Option<TrackFile>> {
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
            let text = read(&c)?;
            return Ok(Some(parse_track_csv(&text, &c.display().to_string())?));
        }
    }
    Ok(None)
}

/// Runs the subcommand.
pub fn run(a: Args) -> anyhow::Result<()> {
    let demo = &a.demo_dir;
    if let Some(d) = demo {
        if !d.is_dir() {
            bail!("--demo-dir {}: no such folder", d.display());
        }
    }
    let camera = input(&a.camera, demo, "camera.json")?;
    let calib_truth = input(&a.calib_truth, demo, "calib/truth.json")?;
    let dataset = input(&a.dataset, demo, "dataset.json")?;
    let model = input(&a.model, demo, "model.json")?;
    let train_report = input(&a.train_report, demo, "train/report.json")?;
    let experiment = input(&a.experiment, demo, "experiment")?;
    let trajectories = input(&a.trajectories, demo, "trajectories")?;
    let lrf_poses = input(&a.lrf_poses, demo, "lrf/poses.csv")?;
    let lrf_truth = input(&a.lrf_truth, demo, "lrf/truth.csv")?;
    let lrf_map = input(&a.lrf_map, demo, "lrf/map.json")?;

    let mut report = Report {
        title: a.title.clone(),
        ..Report::default()
    };
    let mut used = Vec::new();
    let omit = |r: &mut Report, title: &str, why: &str| {
        r.omitted.push((title.to_string(), why.to_string()))
    };

    // Calibration.
    match &camera {
        Some(p) => {
            let cam = CameraFile::load(p)?;
            let truth = calib_truth.as_deref().map(CalibTruth::read).transpose()?;
            used.push(format!("camera {}", p.display()));
            if let Some(t) = &calib_truth {
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
    let ds = dataset
        .as_deref()
        .map(|p| Dataset::read(p).with_context(|| format!("cannot use {}", p.display())))
        .transpose()?;
    let mdl = match &model {
        Some(p) => {
            let m = ModelFile::read(p)?;
            used.push(format!("model {}", p.display()));
            Some(m)
        }
        None => None,
    };
    match &ds {
        Some(ds) if !ds.samples.is_empty() => {
            if let Some(p) = &dataset {
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
                            m.correct(&s.inputs).with_context(|| {
                                format!("model does not fit run {} of the dataset", s.run_id)
                            })
                        })
                        .collect::<anyhow::Result<Vec<[f64; 2]>>>()?,
                ),
                None => None,
            };
            let mut views = Vec::new();
            for i in pick_runs(&ds.samples, a.runs) {
                let s = &ds.samples[i];
                let rec = if s.recording_id.is_empty() {
                    &s.run_id
                } else {
                    &s.recording_id
                };
                let track = find_track(rec, experiment.as_deref(), trajectories.as_deref())?;
                views.push(RunView::new(
                    s,
                    &ds.robot,
                    preds.as_ref().map(|p| p[i]),
                    track.as_ref(),
                ));
            }
            report.sections.push(trajectory_section(&views)?);
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
    match &train_report {
        Some(p) => {
            let rep = SweepReport::read(p)?;
            used.push(format!("training report {}", p.display()));
            report.sections.push(training_section(&rep)?);
        }
        None => omit(
            &mut report,
            "Training: Tables 1 and 2",
            "no training report given (--train-report DIR/report.json)",
        ),
    }

    // Laser.
    match (&lrf_poses, &lrf_truth) {
        (Some(pp), tp) => {
            let poses = odocal_lrf::PoseLog::read(pp)?.rows;
            let truth = match tp {
                Some(t) => odocal_lrf::read_truth_csv(t)?,
                None => Vec::new(),
            };
            let landmarks_m = match &lrf_map {
                Some(m) => odocal_lrf::Map::read(m)?
                    .landmarks
                    .iter()
                    .map(|l| (l.position.x, l.position.y))
                    .collect(),
                None => Vec::new(),
            };
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
    write_atomic(&a.out, report.to_html().as_bytes())?;
    if let Some(dir) = &a.svg_dir {
        for (name, svg) in report.figures() {
            write_atomic(&dir.join(format!("{name}.svg")), svg.as_bytes())?;
        }
    }
    let n_fig = report.figures().len();
    println!(
        "report: {} sections, {} plots -> {}{}",
        report.sections.len(),
        n_fig,
        a.out.display(),
        a.svg_dir
            .as_ref()
            .map_or(String::new(), |d| format!(" (SVGs in {})", d.display()))
    );
    for (t, why) in &report.omitted {
        println!("  left out: {t}: {why}");
    }
    Ok(())
}
