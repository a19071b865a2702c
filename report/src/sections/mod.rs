//! The report's sections, each built from the outputs of one pipeline stage.

mod arena;
mod calibration;
mod conditions;
mod corrector;
mod laser;
mod runs;
mod training;

pub use arena::{arena_section, ArenaInput};
pub use calibration::{calibration_section, CalibInput, CalibView};
pub use conditions::{conditions_section, target_sigma_section, ConditionRow};
pub use corrector::corrector_section;
pub use laser::{laser_section, LaserInput};
pub use runs::{heading_section, pick_runs, trajectory_section, RunView};
pub use training::training_section;

use odocal_core::{wrap_angle, Pose2};
use odocal_dataset::{RobotParams, Sample, WheelGeometry};
use odocal_lrf::LaserTruth;
use odocal_trainer::SweepReport;

use crate::chart::{Cells, Chart, Mark, Series};
use crate::html::{Block, Section, Table};
use crate::inputs::{Clock, TrackFile};
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

/// The most points a plot draws per series: thousands of dots already fill a plot, and more
/// only make the page heavier (a million laser poses were a 100 MB page).
const MAX_DRAWN: usize = 5000;

/// Every n-th point, n the smallest that keeps at most `max`; with "every n-th of N" when
/// any were left out.
fn every_nth(pts: Vec<(f64, f64)>, max: usize) -> (Vec<(f64, f64)>, Option<String>) {
    let n = pts.len();
    if n <= max {
        return (pts, None);
    }
    let step = n.div_ceil(max.max(1));
    let kept = pts.into_iter().step_by(step).collect();
    (kept, Some(format!("every {} of the {n}", ordinal(step))))
}

/// The point of largest y of each run of k consecutive points, k the smallest that keeps at
/// most `max`; with k when it is above 1. An error plot thinned by taking every k-th point
/// would hide the spikes it is read for.
fn largest_of_each(pts: Vec<(f64, f64)>, max: usize) -> (Vec<(f64, f64)>, Option<usize>) {
    let n = pts.len();
    if n <= max {
        return (pts, None);
    }
    let k = n.div_ceil(max.max(1));
    let kept = pts
        .chunks(k)
        .filter_map(|c| c.iter().copied().max_by(|a, b| a.1.total_cmp(&b.1)))
        .collect();
    (kept, Some(k))
}

/// "2nd", "3rd", "11th", "21st".
fn ordinal(n: usize) -> String {
    let suffix = match (n % 10, n % 100) {
        (_, 11..=13) => "th",
        (1, _) => "st",
        (2, _) => "nd",
        (3, _) => "rd",
        _ => "th",
    };
    format!("{n}{suffix}")
}

// ---------------------------------------------------------------- calibration

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

    /// Plots of many points draw every n-th (said), an error plot each run's largest: a
    /// lone spike among 10 001 points stays drawn.
    #[test]
    fn many_points_are_thinned_and_said() {
        let pts: Vec<(f64, f64)> = (0..10_001).map(|k| (k as f64, 1.0)).collect();
        let (kept, said) = every_nth(pts.clone(), 5000);
        assert_eq!(kept.len(), 3334);
        assert_eq!(said.as_deref(), Some("every 3rd of the 10001"));
        assert_eq!(every_nth(pts[..5000].to_vec(), 5000).1, None);
        let mut spiky = pts;
        spiky[4321].1 = 250.0;
        let (kept, k) = largest_of_each(spiky, 5000);
        assert_eq!(k, Some(3));
        assert!(
            kept.contains(&(4321.0, 250.0)),
            "the spike was thinned away"
        );
        assert_eq!(ordinal(21), "21st");
        assert_eq!(ordinal(112), "112th");
    }

    /// Ambiguous poses alone against a truth read "position RMS NaN mm (max 0.0 mm)".
    #[test]
    fn laser_section_without_an_ok_pose_gives_no_error_figure() {
        let row = |k: usize, status| odocal_lrf::PoseLogRow {
            t_s: 0.1 * k as f64,
            pose: Some(Pose2::new(1.0 + 0.01 * k as f64, 2.0, 0.3)),
            status,
            n_landmarks: 4,
            n_detections: 5,
            n_hypotheses: 2,
            score: 4.0,
            mode: "global".into(),
            scan: k as u64,
            pose_cov: None,
        };
        let truth = LaserTruth::new(
            (0..5)
                .map(|k| odocal_lrf::TruthPose {
                    t_s: 0.1 * k as f64,
                    pose: Pose2::new(1.0 + 0.01 * k as f64, 2.0, 0.3),
                    n_detected: None,
                })
                .collect(),
        )
        .unwrap();
        let text = |poses| {
            let s = laser_section(&LaserInput {
                poses,
                truth: truth.clone(),
                landmarks_m: vec![],
            })
            .unwrap();
            match &s.blocks[0] {
                Block::Text(t) => t.clone(),
                _ => panic!("no text"),
            }
        };
        let amb = text(
            (0..5)
                .map(|k| row(k, odocal_lrf::Status::Ambiguous))
                .collect(),
        );
        assert!(!amb.contains("NaN") && !amb.contains("max 0.0"), "{amb}");
        assert!(amb.contains("No scan is ok"), "{amb}");
        // The same poses ok are exact: 0.0 mm over 5 scans.
        let ok = text((0..5).map(|k| row(k, odocal_lrf::Status::Ok)).collect());
        assert!(
            ok.contains("(5 ok scans with a true pose): position RMS 0.0 mm"),
            "{ok}"
        );
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
