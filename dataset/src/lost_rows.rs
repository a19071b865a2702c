//! Rows a logger lost while the wheels turned (a serial link's dropped line, a busy logger
//! thread). Every per-step input and correction takes a step for one period, so a step of
//! two periods read as one is a wheel at twice its speed. A tick log's counts are
//! cumulative, though: the row after the gap still holds all the travel, and only how it
//! split between the periods is unknown. Over one or two periods a small robot's wheel
//! speed changes little, so the lost rows are filled in on the straight line between the
//! rows around them, and said. A longer gap, or one in a wheel-speed log (whose lost rows
//! held travel no other row has), stays a gap for the runs across it to be rejected.

use std::fmt;

use crate::odometry::{LogKind, OdometryLog, STEP_TOLERANCE_PERIODS};

/// Most rows filled in where a logger lost several in a row: beyond this the wheels'
/// speed may have changed too much between the rows around the gap to share the travel
/// out evenly.
pub const MAX_ROWS_FILLED_PER_GAP: usize = 2;

/// One gap in a tick log filled in.
#[derive(Debug, Clone, PartialEq)]
pub struct FilledGap {
    /// The file's lines of the rows on either side of the gap.
    pub lines: (u64, u64),
    /// The step across the gap, seconds.
    pub step_s: f64,
    /// How many rows were filled in.
    pub rows: usize,
}

/// The gaps one log had filled in, for the user.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct FilledRows(pub Vec<FilledGap>);

impl FilledRows {
    /// Rows filled in over all gaps.
    pub fn rows(&self) -> usize {
        self.0.iter().map(|g| g.rows).sum()
    }
}

impl fmt::Display for FilledRows {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let rows = self.rows();
        let gaps: Vec<String> = self
            .0
            .iter()
            .take(3)
            .map(|g| {
                format!(
                    "lines {} and {} are {:.3} s apart",
                    g.lines.0, g.lines.1, g.step_s
                )
            })
            .collect();
        let more = match self.0.len() {
            n if n > 3 => format!(", and {} more gaps", n - 3),
            _ => String::new(),
        };
        write!(
            f,
            "{rows} row{} the logger lost while the wheels turned ({}{more}) filled in on the straight line between the counts around {}: the cumulative counts keep the travel, only its split between the periods is interpolated",
            if rows == 1 { "" } else { "s" },
            gaps.join("; "),
            if self.0.len() == 1 { "it" } else { "each" },
        )
    }
}

/// `log` with the rows it lost while the wheels turned filled in, where it is a tick log and
/// a gap spans a whole number of the robot's `period_s` (within the tolerance `dataset` gives
/// any step) with at most [`MAX_ROWS_FILLED_PER_GAP`] rows lost; other gaps are left for the
/// runs across them to be rejected. A row stamped late whose next row is back on time is a
/// logger's jitter, not a lost row, as [`OdometryLog::off_period_step`] takes it.
pub fn fill_lost_rows(log: &OdometryLog, period_s: f64) -> (OdometryLog, FilledRows) {
    let mut out = log.clone();
    let mut filled = FilledRows::default();
    if log.kind != LogKind::Ticks || period_s.is_nan() || period_s <= 0.0 {
        return (out, filled);
    }
    let mut first = 0;
    while let Some((k, dt)) =
        out.off_period_step(first, out.len(), period_s, STEP_TOLERANCE_PERIODS)
    {
        first = k;
        let periods = (dt / period_s).round();
        let lost = (periods as usize).saturating_sub(1);
        let whole = (dt - periods * period_s).abs() <= STEP_TOLERANCE_PERIODS * period_s;
        if !(whole && (1..=MAX_ROWS_FILLED_PER_GAP).contains(&lost)) {
            continue;
        }
        if out.lines.len() != out.len() {
            out.lines = (0..out.len()).map(|k| log.line(k)).collect();
        }
        let t0 = out.t_s[k - 1];
        let line = out.lines[k];
        let left = gap_counts(&out.t_s, &out.left, k, lost);
        let right = gap_counts(&out.t_s, &out.right, k, lost);
        for j in (0..lost).rev() {
            out.t_s.insert(k, t0 + (j + 1) as f64 / periods * dt);
            out.left.insert(k, left[j]);
            out.right.insert(k, right[j]);
            out.lines.insert(k, line);
        }
        filled.0.push(FilledGap {
            lines: (out.lines[k - 1], line),
            step_s: dt,
            rows: lost,
        });
        first = k + lost;
    }
    (out, filled)
}

/// The counts of `column` (at times `t_s`) at the `lost` times evenly between rows `k - 1`
/// and `k`: on the monotone cubic (Fritsch–Carlson) through the two rows with the wheel's
/// speed at each, so a wheel speeding up or braking across the gap
/// (a run's start and end) is followed, and a wheel turning one way never counts back. Not
/// rounded to whole counts: on a coarse encoder (12 ticks a turn) half a tick is a
/// centimetre of travel.
fn gap_counts(t_s: &[f64], column: &[f64], k: usize, lost: usize) -> Vec<f64> {
    let (t0, t1, c0, c1) = (t_s[k - 1], t_s[k], column[k - 1], column[k]);
    let dt = t1 - t0;
    let secant = (c1 - c0) / dt;
    // The speed at row `i` from the parabola through it and its neighbours (exact for a
    // wheel speeding up evenly); at the log's ends the gap's own mean speed.
    let speed_at = |i: usize| {
        if i == 0 || i + 1 >= column.len() {
            return secant;
        }
        let (h0, h1) = (t_s[i] - t_s[i - 1], t_s[i + 1] - t_s[i]);
        (h0 * h0 * column[i + 1] - h1 * h1 * column[i - 1] + (h1 * h1 - h0 * h0) * column[i])
            / (h0 * h1 * (h0 + h1))
    };
    let (mut v0, mut v1) = (speed_at(k - 1), speed_at(k));
    if secant == 0.0 {
        (v0, v1) = (0.0, 0.0);
    } else {
        let (a, b) = ((v0 / secant).max(0.0), (v1 / secant).max(0.0));
        let scale = (3.0 / a.hypot(b)).min(1.0);
        (v0, v1) = (a * scale * secant, b * scale * secant);
    }
    (1..=lost)
        .map(|j| {
            let s = j as f64 / (lost + 1) as f64;
            let (s2, s3) = (s * s, s * s * s);
            (2.0 * s3 - 3.0 * s2 + 1.0) * c0
                + (s3 - 2.0 * s2 + s) * dt * v0
                + (-2.0 * s3 + 3.0 * s2) * c1
                + (s3 - s2) * dt * v1
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::odometry::STEP_TOLERANCE_PERIODS;

    /// A log of a wheel pair at 10 and 12 ticks a row, every 0.2 s, with the rows `lost`
    /// (0-based) taken out.
    fn log_losing(n: usize, lost: &[usize]) -> OdometryLog {
        let text: String = std::iter::once("t,left_ticks,right_ticks\n".to_string())
            .chain(
                (0..n)
                    .filter(|k| !lost.contains(k))
                    .map(|k| format!("{:.1},{},{}\n", 0.2 * k as f64, 10 * k, 12 * k)),
            )
            .collect();
        OdometryLog::parse_csv(&text, "log.csv").expect("log")
    }

    #[test]
    fn one_or_two_rows_lost_while_moving_are_filled_in_as_the_full_log() {
        let full = log_losing(20, &[]);
        let (filled, said) = fill_lost_rows(&log_losing(20, &[6, 13, 14]), 0.2);
        assert_eq!(filled.t_s.len(), 20);
        for k in 0..20 {
            assert!((filled.t_s[k] - full.t_s[k]).abs() < 1e-9, "row {k}");
            assert!((filled.left[k] - full.left[k]).abs() < 1e-9, "row {k}");
            assert!((filled.right[k] - full.right[k]).abs() < 1e-9, "row {k}");
        }
        assert_eq!(
            filled.off_period_step(0, 20, 0.2, STEP_TOLERANCE_PERIODS),
            None
        );
        assert_eq!(said.rows(), 3);
        // Rows 5 and 7 are lines 7 and 8 once row 6 is gone; rows 12 and 15 lines 13 and 14.
        assert_eq!(said.0[0].lines, (7, 8));
        assert_eq!(said.0[1].lines, (13, 14));
        assert_eq!(said.0[1].rows, 2);
        assert_eq!(filled.line(6), 8, "a filled row carries the line after it");
        assert_eq!(filled.line(16), 15);
        assert!(
            said.to_string().starts_with(
                "3 rows the logger lost while the wheels turned (lines 7 and 8 are 0.400 s apart; lines 13 and 14 are 0.600 s apart) filled in"
            ),
            "{said}"
        );
    }

    #[test]
    fn a_wheel_speeding_up_across_the_gap_is_followed() {
        // Counts 50 t², every 0.2 s; rows 5 and 6 lost (t 1.0 and 1.2 s: 50 and 72 ticks).
        let text: String = std::iter::once("t,left_ticks,right_ticks\n".to_string())
            .chain((0..12).filter(|k| ![5, 6].contains(k)).map(|k| {
                let t = 0.2 * k as f64;
                format!(
                    "{t:.1},{},{}\n",
                    (50.0 * t * t).round(),
                    (50.0 * t * t).round()
                )
            }))
            .collect();
        let (out, said) = fill_lost_rows(&OdometryLog::parse_csv(&text, "l.csv").unwrap(), 0.2);
        assert_eq!(said.rows(), 2);
        // The straight line between 32 and 98 ticks gives 54 and 76: 4 ticks off each.
        assert!((out.left[5] - 50.0).abs() < 1.0, "{}", out.left[5]);
        assert!((out.left[6] - 72.0).abs() < 1.0, "{}", out.left[6]);
    }

    #[test]
    fn longer_gaps_speed_logs_and_jitter_are_left_alone() {
        // Three rows lost: the wheels' speed may have changed over 0.8 s.
        let (out, said) = fill_lost_rows(&log_losing(20, &[6, 7, 8]), 0.2);
        assert_eq!((out.len(), said.rows()), (17, 0));
        assert!(out
            .off_period_step(0, 17, 0.2, STEP_TOLERANCE_PERIODS)
            .is_some());
        // A row stamped 0.12 s late and the next on time.
        let mut late = log_losing(10, &[]);
        late.t_s[4] += 0.12;
        assert_eq!(fill_lost_rows(&late, 0.2).1.rows(), 0);
        // A speed log's lost rows held travel no other row has.
        let speeds = OdometryLog::parse_csv(
            "t,v_left,v_right\n0,0.1,0.1\n0.2,0.1,0.1\n0.6,0.1,0.1\n0.8,0.1,0.1\n",
            "s.csv",
        )
        .expect("speeds");
        assert_eq!(fill_lost_rows(&speeds, 0.2).1.rows(), 0);
    }
}
