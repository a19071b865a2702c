//! The runs: real, odometry and corrected trajectories in each run's start frame, and the
//! heading oscillation.

use super::*;

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

impl RunView {
    /// How far the real track's pose at the run's end lies from the dataset's end point,
    /// metres: millimetres when both come from one recording, more when the track is another
    /// recording's of the same run id. None without a real pose within 0.1 s of the end.
    pub fn real_end_off_m(&self) -> Option<f64> {
        let end = *self.odo_t_s.last()?;
        let (ts, ps) = self.real.as_ref()?;
        let (t, p) = ts
            .iter()
            .zip(ps)
            .min_by(|a, b| (a.0 - end).abs().total_cmp(&(b.0 - end).abs()))?;
        ((t - end).abs() <= 0.1).then(|| (p.x_m - self.target_m[0]).hypot(p.y_m - self.target_m[1]))
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
