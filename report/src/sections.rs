//! The report's sections, each built from the outputs of one pipeline stage.

use odocal_core::{wrap_angle, Pose2};
use odocal_dataset::{RobotParams, Sample, WheelGeometry};
use odocal_lrf::TruthPose;
use odocal_trainer::SweepReport;

use crate::chart::{Chart, Mark, Series};
use crate::html::{Block, Section, Table};
use crate::inputs::{Clock, LaserPose, TrackFile};
use crate::ReportError;

fn figure(name: &str, caption: &str, chart: &Chart) -> Result<Block, ReportError> {
    Ok(Block::Figure {
        name: name.to_string(),
        caption: caption.to_string(),
        svg: chart.to_svg()?,
    })
}

fn rms(v: &[f64]) -> f64 {
    if v.is_empty() {
        return f64::NAN;
    }
    (v.iter().map(|x| x * x).sum::<f64>() / v.len() as f64).sqrt()
}

fn mean(v: &[f64]) -> f64 {
    if v.is_empty() {
        return f64::NAN;
    }
    v.iter().sum::<f64>() / v.len() as f64
}

// ---------------------------------------------------------------- calibration

/// One calibration view.
#[derive(Debug, Clone, PartialEq)]
pub struct CalibView {
    /// Image name.
    pub image: String,
    /// Reprojection RMS of the view, pixels (None when only the truth knows the view).
    pub rms_px: Option<f64>,
    /// Corner positions in the image, pixels (None = unknown).
    pub corners_px: Option<Vec<(f64, f64)>>,
}

/// What the calibration section shows.
#[derive(Debug, Clone, PartialEq)]
pub struct CalibInput {
    /// Image width and height, pixels.
    pub image_size_px: (u32, u32),
    /// Overall reprojection RMS, pixels.
    pub rms_px: f64,
    /// The views used, in calibration order.
    pub views: Vec<CalibView>,
    /// Views left out by the calibration: (image, reason).
    pub skipped: Vec<(String, String)>,
    /// Where the corner positions come from (e.g. "synthetic truth"), if any.
    pub corners_source: Option<String>,
    /// Extra lines (intrinsics, comparison with the truth).
    pub facts: Vec<String>,
}

/// Calibration: per-view residuals and the coverage of the image by corners.
pub fn calibration_section(c: &CalibInput) -> Result<Section, ReportError> {
    let mut s = Section::new("calibration", "Camera calibration");
    s.blocks.push(Block::Text(format!(
        "Zhang calibration from {} views ({} skipped): overall reprojection RMS {:.3} px; image {} × {} px.",
        c.views.len(),
        c.skipped.len(),
        c.rms_px,
        c.image_size_px.0,
        c.image_size_px.1
    )));
    for f in &c.facts {
        s.blocks.push(Block::Text(f.clone()));
    }
    let bars: Vec<(f64, f64)> = c
        .views
        .iter()
        .enumerate()
        .filter_map(|(i, v)| v.rms_px.map(|r| ((i + 1) as f64, r)))
        .collect();
    if bars.is_empty() {
        s.blocks.push(Block::Note(
            "camera.json has no per-view residuals: no per-view plot.".into(),
        ));
    } else {
        let mut ch = Chart::new(
            "Reprojection RMS per calibration view",
            "view number (1 = first view)",
            "reprojection RMS (px)",
        )
        .with(Series::new("per-view RMS", bars, Mark::Bars, 0));
        let n = c.views.len() as f64;
        ch = ch.with(Series::new(
            &format!("overall RMS {:.3} px", c.rms_px),
            vec![(0.5, c.rms_px), (n + 0.5, c.rms_px)],
            Mark::Line,
            1,
        ));
        s.blocks.push(figure(
            "calib-residuals",
            "Reprojection RMS of each view after calibration (pixels). A view far above the others has badly detected corners or moved during exposure.",
            &ch,
        )?);
    }
    let (w, h) = (f64::from(c.image_size_px.0), f64::from(c.image_size_px.1));
    let with_corners: Vec<(usize, &Vec<(f64, f64)>)> = c
        .views
        .iter()
        .enumerate()
        .filter_map(|(i, v)| v.corners_px.as_ref().map(|p| (i, p)))
        .collect();
    if with_corners.is_empty() || w <= 0.0 || h <= 0.0 {
        s.blocks.push(Block::Note(
            "Corner coverage is not shown: this camera.json has no corner positions (files from before odocal stored them); run odocal calibrate again to get them."
                .into(),
        ));
    } else {
        let (gx, gy) = (8usize, 6usize);
        let mut cells = vec![false; gx * gy];
        let mut ch = Chart::new(
            "Checkerboard corner coverage of the image",
            "image column u (px)",
            "image row v (px, down)",
        );
        ch.y_down = true;
        ch.equal_aspect = true;
        ch.x_range = Some((0.0, w));
        ch.y_range = Some((0.0, h));
        ch.size_px = (760, 500);
        for (i, pts) in &with_corners {
            for &(u, v) in pts.iter() {
                if (0.0..w).contains(&u) && (0.0..h).contains(&v) {
                    let cx = ((u / w) * gx as f64) as usize;
                    let cy = ((v / h) * gy as f64) as usize;
                    cells[cy.min(gy - 1) * gx + cx.min(gx - 1)] = true;
                }
            }
            ch.series
                .push(Series::new("", pts.to_vec(), Mark::Dots, *i));
        }
        ch.series.push(Series::new(
            "image border",
            vec![(0.0, 0.0), (w, 0.0), (w, h), (0.0, h), (0.0, 0.0)],
            Mark::Line,
            7,
        ));
        let covered = cells.iter().filter(|c| **c).count();
        s.blocks.push(figure(
            "calib-coverage",
            &format!(
                "Inner corners of all views in the image (one colour per view; {}). {} of {} cells of an {gx} × {gy} grid over the image hold corners ({:.0} %): corners near the border fix the distortion.",
                c.corners_source.as_deref().unwrap_or("detected corners"),
                covered,
                gx * gy,
                100.0 * covered as f64 / (gx * gy) as f64
            ),
            &ch,
        )?);
    }
    let mut t = Table {
        caption: "Calibration views".into(),
        header: vec![
            "view".into(),
            "image".into(),
            "reprojection RMS (px)".into(),
        ],
        rows: Vec::new(),
    };
    for (i, v) in c.views.iter().enumerate() {
        t.rows.push(vec![
            (i + 1).to_string(),
            v.image.clone(),
            v.rms_px.map_or("–".into(), |r| format!("{r:.3}")),
        ]);
    }
    for (img, why) in &c.skipped {
        t.rows
            .push(vec!["skipped".into(), img.clone(), why.clone()]);
    }
    s.blocks.push(Block::Table(t));
    Ok(s)
}

// ---------------------------------------------------------------- runs

/// One run prepared for the trajectory and heading figures (all in the run's start frame).
#[derive(Debug, Clone, PartialEq)]
pub struct RunView {
    /// Run id.
    pub run_id: String,
    /// Commanded speed, m/s.
    pub speed_mps: f64,
    /// Odometry times since the run start, seconds.
    pub odo_t_s: Vec<f64>,
    /// Dead-reckoned odometry poses (nominal geometry).
    pub odometry: Vec<Pose2>,
    /// Corrected track (raw track rotated and scaled so its end is the corrector's), metres.
    pub corrected: Option<Vec<(f64, f64)>>,
    /// Real end position, metres.
    pub target_m: [f64; 2],
    /// Real track: times since the run start (s) and poses.
    pub real: Option<(Vec<f64>, Vec<Pose2>)>,
    /// What the real track is.
    pub real_source: &'static str,
}

impl RunView {
    /// Builds the view of a sample: odometry from its logged revolutions, the corrected track
    /// from the corrector's end point, the real track from a floor-frame track file.
    pub fn new(
        sample: &Sample,
        robot: &RobotParams,
        corrected_end_m: Option<[f64; 2]>,
        track: Option<&TrackFile>,
    ) -> Self {
        let odometry = sample.odometry.poses(&WheelGeometry::nominal(robot));
        let t_b = sample.odometry.t_b();
        let t_e = sample.odometry.t_e();
        let odo_t_s = sample.odometry.t_s.iter().map(|t| t - t_b).collect();
        let raw = sample.raw_end_m;
        let corrected = corrected_end_m.map(|c| {
            // Similarity about the start mapping the raw end onto the corrected end.
            let r2 = raw[0] * raw[0] + raw[1] * raw[1];
            let (a, b) = if r2 > 1e-12 {
                (
                    (c[0] * raw[0] + c[1] * raw[1]) / r2,
                    (c[1] * raw[0] - c[0] * raw[1]) / r2,
                )
            } else {
                (1.0, 0.0)
            };
            odometry
                .iter()
                .map(|p| (a * p.x_m - b * p.y_m, b * p.x_m + a * p.y_m))
                .collect()
        });
        let real = track.map(|tr| {
            let shift = match tr.clock {
                Clock::Robot => 0.0,
                Clock::Camera => sample.clock_offset_s,
            };
            let mut ts = Vec::new();
            let mut ps = Vec::new();
            for (t, p) in tr.t_s.iter().zip(&tr.poses_floor) {
                let tr_s = t - shift;
                if tr_s >= t_b - 0.1 && tr_s <= t_e + 0.1 {
                    ts.push(tr_s - t_b);
                    ps.push(p.relative_to(&sample.start_pose_floor));
                }
            }
            (ts, ps)
        });
        let real = real.filter(|r| r.0.len() >= 2);
        Self {
            run_id: sample.run_id.clone(),
            speed_mps: sample.speed_mps,
            odo_t_s,
            odometry,
            corrected,
            target_m: sample.target_m,
            real_source: track.map_or("", |t| t.source),
            real,
        }
    }
}

/// Indices of up to `max` samples to draw: the first run of each commanded speed.
pub fn pick_runs(samples: &[Sample], max: usize) -> Vec<usize> {
    let mut speeds: Vec<f64> = Vec::new();
    let mut out = Vec::new();
    for (i, s) in samples.iter().enumerate() {
        if !speeds.iter().any(|v| (v - s.speed_mps).abs() < 1e-9) && !s.odometry.t_s.is_empty() {
            speeds.push(s.speed_mps);
            out.push(i);
        }
    }
    out.sort_by(|a, b| samples[*a].speed_mps.total_cmp(&samples[*b].speed_mps));
    out.truncate(max);
    out
}

/// Figure 5: real vs odometry vs corrected trajectories of a few runs.
pub fn trajectory_section(runs: &[RunView]) -> Result<Section, ReportError> {
    let mut s = Section::new(
        "trajectories",
        "Trajectories: real, odometry and corrected (Figure 5)",
    );
    s.blocks.push(Block::Text(
        "Each run in its start frame (x forward, y left, metres). The y axis is stretched to show the lateral drift.".into(),
    ));
    if runs.iter().all(|r| r.real.is_none()) {
        s.blocks.push(Block::Note(
            "No real trajectories were given (--experiment or --trajectories): only the real end point is drawn.".into(),
        ));
    }
    if runs.iter().all(|r| r.corrected.is_none()) {
        s.blocks.push(Block::Note(
            "No model was given (--model): no corrected trajectory.".into(),
        ));
    }
    for r in runs {
        let mut ch = Chart::new(
            &format!(
                "Run {} at {:.1} m/s: real vs odometry vs corrected",
                r.run_id, r.speed_mps
            ),
            "x, forward (m)",
            "y, left (m)",
        );
        if let Some((_, ps)) = &r.real {
            ch.series.push(Series::new(
                &format!("real ({})", r.real_source),
                ps.iter().map(|p| (p.x_m, p.y_m)).collect(),
                Mark::Line,
                6,
            ));
        }
        ch.series.push(Series::new(
            "raw odometry",
            r.odometry.iter().map(|p| (p.x_m, p.y_m)).collect(),
            Mark::Line,
            1,
        ));
        if let Some(c) = &r.corrected {
            ch.series
                .push(Series::new("corrected odometry", c.clone(), Mark::Line, 2));
        }
        ch.series.push(Series::new(
            "real end point",
            vec![(r.target_m[0], r.target_m[1])],
            Mark::Markers,
            6,
        ));
        let raw_end = r.odometry.last().map_or([f64::NAN; 2], |p| [p.x_m, p.y_m]);
        let err_raw = (raw_end[0] - r.target_m[0]).hypot(raw_end[1] - r.target_m[1]);
        let err_cor = r
            .corrected
            .as_ref()
            .and_then(|c| c.last())
            .map(|e| (e.0 - r.target_m[0]).hypot(e.1 - r.target_m[1]));
        s.blocks.push(figure(
            &format!("trajectory-{}", r.run_id),
            &format!(
                "Run {} ({:.1} m/s): end-point error of raw odometry {:.1} cm{}.",
                r.run_id,
                r.speed_mps,
                100.0 * err_raw,
                err_cor.map_or(String::new(), |e| format!(
                    ", of the corrected end point {:.1} cm",
                    100.0 * e
                ))
            ),
            &ch,
        )?);
    }
    Ok(s)
}

/// Figure 4: the heading oscillation along runs (real vs odometry). None when no run has a
/// real track.
pub fn heading_section(runs: &[RunView]) -> Result<Option<Section>, ReportError> {
    let with_real: Vec<&RunView> = runs.iter().filter(|r| r.real.is_some()).collect();
    if with_real.is_empty() {
        return Ok(None);
    }
    let mut s = Section::new("heading", "Heading oscillation along a run (Figure 4)");
    s.blocks.push(Block::Text(
        "Heading relative to the start heading (degrees, counter-clockwise positive) against the time since the run start. Small robots oscillate about their course; odometry at 12 counts per revolution sees the oscillation only coarsely.".into(),
    ));
    for r in with_real {
        let Some((ts, ps)) = &r.real else { continue };
        let real_deg: Vec<(f64, f64)> = ts
            .iter()
            .zip(ps)
            .map(|(t, p)| (*t, wrap_angle(p.theta_rad).to_degrees()))
            .collect();
        let osc = {
            let v: Vec<f64> = real_deg.iter().map(|p| p.1).collect();
            let m = mean(&v);
            rms(&v.iter().map(|x| x - m).collect::<Vec<_>>())
        };
        let ch = Chart::new(
            &format!("Heading along run {} at {:.1} m/s", r.run_id, r.speed_mps),
            "time since run start (s)",
            "heading (deg)",
        )
        .with(Series::new(
            &format!("real ({})", r.real_source),
            real_deg,
            Mark::Line,
            6,
        ))
        .with(Series::new(
            "raw odometry",
            r.odo_t_s
                .iter()
                .zip(&r.odometry)
                .map(|(t, p)| (*t, wrap_angle(p.theta_rad).to_degrees()))
                .collect(),
            Mark::Line,
            1,
        ));
        s.blocks.push(figure(
            &format!("heading-{}", r.run_id),
            &format!(
                "Run {}: real heading varies with an RMS of {:.2} deg about its mean.",
                r.run_id, osc
            ),
            &ch,
        )?);
    }
    Ok(Some(s))
}

// ---------------------------------------------------------------- corrector

/// Figures 6–7: the end-point errors of odometry across runs and the corrector's estimate.
pub fn corrector_section(
    samples: &[Sample],
    predicted_m: Option<&[[f64; 2]]>,
) -> Result<Section, ReportError> {
    let mut s = Section::new(
        "corrector",
        "End-point errors across runs (Figures 6 and 7)",
    );
    s.blocks.push(Block::Text(
        "Odometry error = real end − raw odometry end, per run, in the run's start frame (cm). The corrector's estimate of it = its corrected end − raw odometry end. The model was trained on all runs, so this is its fit, not a held-out test (Table 2 gives the cross-validated figures).".into(),
    ));
    if predicted_m.is_none() {
        s.blocks.push(Block::Note(
            "No model was given (--model): only the odometry errors are drawn.".into(),
        ));
    }
    for (axis, i, fig) in [("x", 0usize, 6), ("y", 1usize, 7)] {
        let real: Vec<(f64, f64)> = samples
            .iter()
            .enumerate()
            .map(|(k, sm)| ((k + 1) as f64, 100.0 * (sm.target_m[i] - sm.raw_end_m[i])))
            .collect();
        let mut ch = Chart::new(
            &format!("Figure {fig}: {axis} error of the end point across runs"),
            "run index",
            &format!("{axis} error (cm)"),
        )
        .with(Series::new("real − odometry (target)", real, Mark::Line, 6));
        if let Some(p) = predicted_m {
            ch.series.push(Series::new(
                "corrector − odometry (predicted)",
                samples
                    .iter()
                    .zip(p)
                    .enumerate()
                    .map(|(k, (sm, e))| ((k + 1) as f64, 100.0 * (e[i] - sm.raw_end_m[i])))
                    .collect(),
                Mark::Line,
                1,
            ));
        }
        s.blocks.push(figure(
            &format!("errors-{axis}"),
            &format!("The {axis} component of the end-point error per run (cm): target and the corrector's approximation."),
            &ch,
        )?);
    }
    let mut t = Table {
        caption: "End-point errors over all runs (in-sample)".into(),
        header: vec![
            "estimate".into(),
            "runs".into(),
            "MSE per coordinate (cm²)".into(),
            "RMS end error (cm)".into(),
            "mean relative error (% of path length)".into(),
        ],
        rows: Vec::new(),
    };
    let mut row = |name: &str, ends: Vec<[f64; 2]>| {
        let d: Vec<f64> = samples
            .iter()
            .zip(&ends)
            .map(|(sm, e)| (e[0] - sm.target_m[0]).hypot(e[1] - sm.target_m[1]))
            .collect();
        let rel: Vec<f64> = samples
            .iter()
            .zip(&d)
            .map(|(sm, e)| e / sm.path_length_m.max(1e-9))
            .collect();
        let mse = d.iter().map(|e| e * e).sum::<f64>() / (2.0 * d.len().max(1) as f64);
        t.rows.push(vec![
            name.to_string(),
            d.len().to_string(),
            format!("{:.2}", mse * 1e4),
            format!("{:.2}", 100.0 * rms(&d)),
            format!("{:.2}", 100.0 * mean(&rel)),
        ]);
    };
    row(
        "raw odometry",
        samples.iter().map(|s| s.raw_end_m).collect(),
    );
    if let Some(p) = predicted_m {
        row("corrected (model)", p.to_vec());
    }
    s.blocks.push(Block::Table(t));
    Ok(s)
}

// ---------------------------------------------------------------- training

/// Tables 1 and 2 of the trainer's sweep, with the baselines, and the MSE against k.
pub fn training_section(r: &SweepReport) -> Result<Section, ReportError> {
    let mut s = Section::new("training", "Training: Tables 1 and 2");
    s.blocks.push(Block::Text(format!(
        "{} samples, {}-fold cross-validation × {} restarts, seed {}. MSE is per coordinate, in cm² (1 cm² = 1e-4 m²); ± is one standard deviation over folds and restarts.",
        r.n_samples, r.settings.folds, r.settings.restarts, r.settings.seed
    )));
    let pm = |m: &odocal_trainer::MeanSd, k: f64, p: usize| {
        format!("{:.p$} ± {:.p$}", m.mean * k, m.sd * k, p = p)
    };
    let mut t1 = Table {
        caption: "Table 1: hidden-layer size sweep".into(),
        header: vec![
            "hidden neurons k".into(),
            "parameters".into(),
            "epochs".into(),
            "training MSE (cm²)".into(),
            "validation MSE (cm²)".into(),
            "validation relative error (%)".into(),
        ],
        rows: Vec::new(),
    };
    for row in &r.table1 {
        t1.rows.push(vec![
            if row.hidden == r.best_hidden {
                format!("{} (best)", row.hidden)
            } else {
                row.hidden.to_string()
            },
            row.n_params.to_string(),
            pm(&row.epochs, 1.0, 1),
            pm(&row.train_mse_m2, 1e4, 2),
            pm(&row.val_mse_m2, 1e4, 2),
            pm(&row.val_rel_error, 100.0, 2),
        ]);
    }
    s.blocks.push(Block::Table(t1));
    if !r.table1.is_empty() {
        let k = |f: fn(&odocal_trainer::crossval::Table1Row) -> f64| -> Vec<(f64, f64)> {
            r.table1
                .iter()
                .map(|row| (row.hidden as f64, f(row)))
                .collect()
        };
        let ch = Chart::new(
            "Training and validation MSE against hidden-layer size",
            "hidden neurons k",
            "MSE per coordinate (cm²)",
        )
        .with(Series::new(
            "training MSE",
            k(|r| r.train_mse_m2.mean * 1e4),
            Mark::Line,
            0,
        ))
        .with(Series::new(
            "training MSE",
            k(|r| r.train_mse_m2.mean * 1e4),
            Mark::Markers,
            0,
        ))
        .with(Series::new(
            "validation MSE",
            k(|r| r.val_mse_m2.mean * 1e4),
            Mark::Line,
            1,
        ))
        .with(Series::new(
            "",
            k(|r| r.val_mse_m2.mean * 1e4),
            Mark::Markers,
            1,
        ));
        let mut ch = ch;
        ch.series[1].label.clear();
        s.blocks.push(figure(
            "table1-mse",
            "Mean training and cross-validated MSE per hidden size (cm²): the gap grows when the network over-fits.",
            &ch,
        )?);
    }
    let mut t2 = Table {
        caption: "Table 2: cross-validated end-point errors with baselines".into(),
        header: vec![
            "method".into(),
            "MSE (m²)".into(),
            "MSE (cm²)".into(),
            "relative error (%)".into(),
            "RMS end error (cm)".into(),
            "dataset size (runs)".into(),
            "mean distance (m)".into(),
        ],
        rows: Vec::new(),
    };
    for m in &r.table2 {
        t2.rows.push(vec![
            m.method.clone(),
            format!("{:.6}", m.mse_m2.mean),
            pm(&m.mse_m2, 1e4, 2),
            pm(&m.rel_error, 100.0, 2),
            format!("{:.2}", 100.0 * m.rms_end_error_m),
            m.n_samples.to_string(),
            format!("{:.3}", m.mean_distance_m),
        ]);
    }
    t2.rows.push(vec![
        "source A (reported)".into(),
        "0.165 (unit not stated)".into(),
        "–".into(),
        "3.36 (raw odometry 8–10)".into(),
        "–".into(),
        "131 (161)".into(),
        "≈ 1.5".into(),
    ]);
    s.blocks.push(Block::Table(t2));
    if let Some(first) = r.table2.first() {
        if !first.per_speed.is_empty() {
            let mut header = vec!["method".to_string()];
            header.extend(
                first
                    .per_speed
                    .iter()
                    .map(|p| format!("{:.2} m/s (n = {}): rel. error (%)", p.speed_mps, p.n)),
            );
            let rows = r
                .table2
                .iter()
                .map(|m| {
                    let mut v = vec![m.method.clone()];
                    v.extend(
                        m.per_speed
                            .iter()
                            .map(|p| format!("{:.2}", 100.0 * p.rel_error)),
                    );
                    v
                })
                .collect();
            s.blocks.push(Block::Table(Table {
                caption: "Relative end-point error per commanded speed".into(),
                header,
                rows,
            }));
        }
    }
    if !r.verdict.is_empty() {
        s.blocks
            .push(Block::Text(format!("Verdict: {}", r.verdict)));
    }
    for w in &r.warnings {
        s.blocks.push(Block::Note(format!("Trainer warning: {w}")));
    }
    Ok(s)
}

// ---------------------------------------------------------------- laser

/// What the laser section shows.
#[derive(Debug, Clone, PartialEq)]
pub struct LaserInput {
    /// Poses from `odocal lrf localize`.
    pub poses: Vec<LaserPose>,
    /// True sensor poses.
    pub truth: Vec<TruthPose>,
    /// Landmark positions of the map (x, y), metres.
    pub landmarks_m: Vec<(f64, f64)>,
}

/// Laser positioning: estimated sensor poses against the truth.
pub fn laser_section(l: &LaserInput) -> Result<Section, ReportError> {
    let mut s = Section::new("laser", "Laser positioning against the truth");
    let key = |t: f64| (t * 1e6).round() as i64;
    let truth: std::collections::HashMap<i64, &TruthPose> =
        l.truth.iter().map(|p| (key(p.t_s), p)).collect();
    let count = |st: &str| l.poses.iter().filter(|p| p.status == st).count();
    let mut pos_err = Vec::new();
    let mut head_err = Vec::new();
    let mut err_series = Vec::new();
    for p in &l.poses {
        if let (Some(e), Some(tp)) = (p.pose, truth.get(&key(p.t_s))) {
            if p.status == "ok" {
                let d = (e.x_m - tp.pose.x_m).hypot(e.y_m - tp.pose.y_m);
                pos_err.push(d);
                head_err.push(wrap_angle(e.theta_rad - tp.pose.theta_rad));
                err_series.push((p.t_s, 1000.0 * d));
            }
        }
    }
    s.blocks.push(Block::Text(format!(
        "{} scans: {} ok, {} ambiguous, {} lost. Against the truth ({} ok scans with a true pose): position RMS {:.1} mm (max {:.1} mm), heading RMS {:.3} deg.",
        l.poses.len(),
        count("ok"),
        count("ambiguous"),
        count("lost"),
        pos_err.len(),
        1000.0 * rms(&pos_err),
        1000.0 * pos_err.iter().fold(0.0f64, |m, e| m.max(*e)),
        rms(&head_err).to_degrees()
    )));
    let mut ch = Chart::new(
        "Laser sensor positions: estimate vs truth",
        "x, map frame (m)",
        "y, map frame (m)",
    );
    ch.equal_aspect = true;
    ch.size_px = (760, 560);
    for (st, color) in [("ok", 0usize), ("ambiguous", 4usize)] {
        let pts: Vec<(f64, f64)> = l
            .poses
            .iter()
            .filter(|p| p.status == st)
            .filter_map(|p| p.pose.map(|q| (q.x_m, q.y_m)))
            .collect();
        if !pts.is_empty() {
            ch.series.push(Series::new(
                &format!("estimate ({st})"),
                pts,
                Mark::Dots,
                color,
            ));
        }
    }
    // The true path last, on top of the estimates.
    if !l.truth.is_empty() {
        ch.series.push(Series::new(
            "true path",
            l.truth.iter().map(|p| (p.pose.x_m, p.pose.y_m)).collect(),
            Mark::Line,
            6,
        ));
    }
    if !l.landmarks_m.is_empty() {
        ch.series.push(Series::new(
            "landmarks",
            l.landmarks_m.clone(),
            Mark::Markers,
            1,
        ));
    }
    if ch.n_points() > 0 {
        s.blocks.push(figure(
            "laser-poses",
            "Sensor positions in the map frame (metres): the true path, the estimates by status, and the reflective landmarks.",
            &ch,
        )?);
    }
    if !err_series.is_empty() {
        let ch = Chart::new(
            "Laser position error over time",
            "scan time (s)",
            "position error (mm)",
        )
        .with(Series::new(
            "|estimate − truth| (ok scans)",
            err_series,
            Mark::Dots,
            0,
        ));
        s.blocks.push(figure(
            "laser-error",
            "Distance between estimated and true sensor position per ok scan (mm).",
            &ch,
        )?);
    } else {
        s.blocks.push(Block::Note(
            "No ok scan has a true pose at its time: no error plot.".into(),
        ));
    }
    Ok(s)
}

#[cfg(test)]
mod tests {
    use super::*;
    use odocal_dataset::kinematics::RunOdometry;

    /// A straight run of 1 m (both wheels turn 1 / (pi d) revolutions) starting at a floor pose
    /// that is neither at the origin nor heading along x.
    fn sample() -> (Sample, RobotParams) {
        let robot = RobotParams::default();
        let rev_per_m = 1.0 / (std::f64::consts::PI * robot.wheel_diameter_m);
        let n = 6;
        let t_s: Vec<f64> = (0..n).map(|k| 10.0 + 0.2 * k as f64).collect();
        let rev = (0..n)
            .map(|k| {
                let r = rev_per_m * k as f64 / (n - 1) as f64;
                [r, r]
            })
            .collect();
        let s = Sample {
            run_id: "r1".into(),
            speed_mps: 0.5,
            target_m: [0.9, 0.1],
            raw_end_m: [1.0, 0.0],
            path_length_m: 0.91,
            clock_offset_s: 0.5,
            start_pose_floor: Pose2::new(2.0, 1.0, std::f64::consts::FRAC_PI_2),
            odometry: RunOdometry { t_s, rev },
            ..Sample::default()
        };
        (s, robot)
    }

    #[test]
    fn run_view_puts_everything_in_the_start_frame() {
        let (s, robot) = sample();
        // Camera track on the camera clock: the robot moves along +y of the floor (its +x).
        let start = s.start_pose_floor;
        let track = TrackFile {
            clock: Clock::Camera,
            t_s: (0..=12).map(|k| 10.0 + 0.5 + 0.1 * k as f64).collect(),
            poses_floor: (0..=12)
                .map(|k| start.compose(&Pose2::new(0.075 * k as f64, 0.01 * k as f64, 0.0)))
                .collect(),
            source: "camera trajectory",
        };
        let v = RunView::new(&s, &robot, Some([0.9, 0.1]), Some(&track));
        let last = v.odometry.last().unwrap();
        assert!(
            (last.x_m - 1.0).abs() < 1e-9 && last.y_m.abs() < 1e-9,
            "{last:?}"
        );
        assert_eq!(v.odo_t_s.first().copied(), Some(0.0));
        // The corrected track ends exactly on the corrector's end point.
        let c = *v.corrected.as_ref().unwrap().last().unwrap();
        assert!(
            (c.0 - 0.9).abs() < 1e-9 && (c.1 - 0.1).abs() < 1e-9,
            "{c:?}"
        );
        // The real track is shifted by the clock offset and expressed in the start frame.
        let (ts, ps) = v.real.as_ref().unwrap();
        assert!((ts[0]).abs() < 1e-9, "{ts:?}");
        assert!(
            (ps[4].x_m - 0.3).abs() < 1e-9 && (ps[4].y_m - 0.04).abs() < 1e-9,
            "{:?}",
            ps[4]
        );
        assert!(ts.iter().all(|t| *t <= 1.0 + 0.1 + 1e-9));
    }

    #[test]
    fn sections_have_figures_with_units() {
        let (s, robot) = sample();
        let v = RunView::new(&s, &robot, None, None);
        let sec = trajectory_section(std::slice::from_ref(&v)).unwrap();
        assert_eq!(sec.n_figures(), 1);
        assert!(
            heading_section(&[v]).unwrap().is_none(),
            "no real track, no heading figure"
        );
        let sec = corrector_section(&[s.clone(), s], Some(&[[0.9, 0.1], [0.8, 0.1]])).unwrap();
        assert_eq!(sec.n_figures(), 2);
        let Some(Block::Table(t)) = sec.blocks.last() else {
            panic!("no table")
        };
        // Raw odometry is 0.1414 m off, the first prediction exact, the second 0.1 m off.
        assert_eq!(t.rows[0][3], "14.14");
        assert_eq!(
            t.rows[1][3],
            format!("{:.2}", 100.0 * (0.01f64 / 2.0).sqrt())
        );
    }
}
