//! Splitting an odometry log into runs by motion detection.
//!
//! A run is a burst of log intervals with encoder changes (or wheel speed above
//! [`crate::odometry::SPEED_REST_THRESHOLD_MPS`]); bursts separated by less than `min_gap_s`
//! of rest belong to the same run. t_b is the last row at rest before the burst, t_e the first
//! row at rest after its last change (one full interval without encoder change, so sub-tick
//! creeping has ended).

use crate::kinematics::RunOdometry;
use crate::odometry::{OdometryLog, WheelRevs};

/// One detected run: row indices into the log.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct RunSegment {
    /// Row of t_b (last row at rest before motion).
    pub start_row: usize,
    /// Row of t_e (first row at rest after the last change); equals the last moving row when
    /// the log ends during motion.
    pub end_row: usize,
    /// First row of the context window belonging to this run (rest before it).
    pub window_first: usize,
    /// Last row of the context window belonging to this run (rest after it).
    pub window_last: usize,
    /// The log starts during this run's motion (no rest row before it).
    pub starts_in_motion: bool,
    /// The log ends during this run's motion (no rest row after it).
    pub ends_in_motion: bool,
}

impl RunSegment {
    /// The run's odometry: rows start_row..=end_row, revolutions relative to start_row.
    pub fn odometry(&self, revs: &WheelRevs) -> RunOdometry {
        let r0 = revs.rev[self.start_row];
        RunOdometry {
            t_s: revs.t_s[self.start_row..=self.end_row].to_vec(),
            rev: revs.rev[self.start_row..=self.end_row]
                .iter()
                .map(|r| [r[0] - r0[0], r[1] - r0[1]])
                .collect(),
        }
    }
}

/// Detects the runs in a log; rest gaps shorter than `min_gap_s` do not split a run.
pub fn split_runs(log: &OdometryLog, min_gap_s: f64) -> Vec<RunSegment> {
    let n = log.len();
    // Bursts as (first moving row, last moving row); row i moving = interval (i-1, i].
    let mut bursts: Vec<(usize, usize)> = Vec::new();
    for i in 1..n {
        if !log.moving_at(i) {
            continue;
        }
        match bursts.last_mut() {
            // Rest gap from row `last` (motion ended there) to row i-1 (motion starts after it).
            Some((_, last)) if log.t_s[i - 1] - log.t_s[*last] < min_gap_s => *last = i,
            _ => bursts.push((i, i)),
        }
    }
    let mut out: Vec<RunSegment> = Vec::with_capacity(bursts.len());
    for (j, &(k0, k1)) in bursts.iter().enumerate() {
        let start_row = k0 - 1;
        let ends_in_motion = k1 + 1 >= n;
        let end_row = if ends_in_motion { k1 } else { k1 + 1 };
        // Rest rows between two runs are shared out: the earlier run takes the first half.
        let window_first = out.last().map(|p| p.window_last + 1).unwrap_or(0);
        let window_last = if j + 1 == bursts.len() {
            n - 1
        } else {
            (end_row + bursts[j + 1].0 - 1) / 2
        };
        out.push(RunSegment {
            start_row,
            end_row,
            window_first: window_first.min(start_row),
            window_last: window_last.max(end_row),
            starts_in_motion: k0 == 1,
            ends_in_motion,
        });
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn log(ticks: &[i64]) -> OdometryLog {
        let t: Vec<f64> = (0..ticks.len()).map(|i| 0.2 * i as f64).collect();
        OdometryLog::from_ticks(t, ticks.to_vec(), ticks.to_vec()).unwrap()
    }

    #[test]
    fn splits_on_long_rest_only() {
        // rest, run (rows 3..5), short pause (1 interval), more motion, long rest, second run.
        let l = log(&[0, 0, 0, 2, 4, 4, 6, 6, 6, 6, 6, 6, 6, 6, 8, 9, 9, 9]);
        let runs = split_runs(&l, 1.0);
        assert_eq!(runs.len(), 2);
        assert_eq!((runs[0].start_row, runs[0].end_row), (2, 7));
        assert_eq!((runs[1].start_row, runs[1].end_row), (13, 16));
        assert!(runs[0].window_last < runs[1].window_first);
        assert_eq!(runs[1].window_last, 17);
        assert!(!runs[0].starts_in_motion && !runs[1].ends_in_motion);
        let o = runs[0].odometry(&l.wheel_revs(&crate::RobotParams::default()));
        assert_eq!(o.t_s.len(), 6);
        assert_eq!(o.rev[0], [0.0, 0.0]);
        assert!((o.rev[5][0] - 0.5).abs() < 1e-12);
    }

    #[test]
    fn flags_runs_cut_by_the_log() {
        let runs = split_runs(&log(&[0, 1, 2, 2, 2, 2, 2, 2, 2, 3, 4]), 1.0);
        assert_eq!(runs.len(), 2);
        assert!(runs[0].starts_in_motion);
        assert!(runs[1].ends_in_motion);
        assert!(split_runs(&log(&[5, 5, 5]), 1.0).is_empty());
    }
}
