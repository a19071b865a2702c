//! Glitches in an odometry log: a count a serial link garbled for one row, a counter that
//! jumps (or is reset) and counts on from there, a wheel speed that spikes. Read as motion,
//! one such step is a wheel at hundreds of metres a second, and it spoils the clock alignment
//! of the whole recording, whose other runs it does not touch.
//!
//! A count that leaves its neighbours and comes back faster than any wheel turns, while the
//! rows on both sides of it agree, is one garbled reading: told for certain, it is read
//! between its neighbours, and said. A step whose travel is lost (a jump the counts go on
//! from, a reset, a speed spike) is named; the run or window across it is rejected with that
//! reason, and the counts after it are re-based so that the recording's other runs align.
//! More than [`MAX_LOST_STEPS`] such steps are no glitches but the log's unit or the robot
//! file's parameters, and reject the whole recording.

use crate::lost_rows::fill_lost_rows;
use crate::odometry::{LogKind, OdometryLog, MAX_WHEEL_SPEED_MPS, TICKS_HEADER};
use crate::RobotParams;

/// Most steps with their travel lost that a log may hold and still be read around them: a
/// serial link's glitches are rare, while a unit error or a wrong `ticks_per_rev` makes every
/// fast step impossible.
pub const MAX_LOST_STEPS: usize = 3;

/// A step of a log whose wheel travel is unknown.
#[derive(Debug, Clone, PartialEq)]
pub struct LostStep {
    /// The row the step ends at, 0-based.
    pub row: usize,
    /// What is wrong with it, naming the file's lines.
    pub reason: String,
}

impl LostStep {
    /// Whether the step lies within rows `first..=last` or ends on the row after them: the
    /// counts after it were re-based on an estimate, so a run whose rest row borders it is
    /// not sure of its own travel either.
    pub fn touches(&self, first: usize, last: usize) -> bool {
        first <= self.row && self.row <= last + 1
    }
}

/// A log with its glitches taken out.
#[derive(Debug, Clone, PartialEq)]
pub struct MendedLog {
    /// The log: garbled readings read between their neighbours, the counts after a lost step
    /// re-based on the travel of the steps around it (a speed spike replaced by the speeds
    /// around it).
    pub log: OdometryLog,
    /// What was read in place of each garbled reading, naming its line (for the user).
    pub mended: Vec<String>,
    /// The steps whose travel is lost.
    pub lost: Vec<LostStep>,
}

/// What a log's impossible steps are.
#[derive(Debug, Clone, PartialEq)]
pub enum LogGlitches {
    /// Few enough to read the log around them (none at all, often).
    Mended(Box<MendedLog>),
    /// Too many to be glitches: what is wrong with the first, and how many there are.
    Everywhere(String),
}

/// `log` with the rows it lost while the wheels turned filled in and its garbled readings
/// read between their neighbours, and a note on each, when those are all its impossible
/// steps; else `log` as it is (no notes), for the log checks to refuse. A model applied to a whole log (`correct`, `evaluate`) can read around a garbled
/// count, but not across a step whose travel is lost.
pub fn mend_garbled_readings(log: &OdometryLog, robot: &RobotParams) -> (OdometryLog, Vec<String>) {
    // A log off the robot's period throughout is another robot's or logger's, not one that
    // lost rows: filled in, a 400 ms log on a 200 ms robot was "9 rows the logger lost" and
    // corrected as such; left as it is, the log check refuses it naming both periods, as
    // `dataset` does.
    if log.period_mismatch(robot.period_s).is_some() {
        return (log.clone(), Vec::new());
    }
    match mend_glitches(log, robot) {
        LogGlitches::Mended(m) if m.lost.is_empty() && !m.mended.is_empty() => (m.log, m.mended),
        _ => (log.clone(), Vec::new()),
    }
}

/// Finds the glitches of `log` (see the module's documentation).
pub fn mend_glitches(log: &OdometryLog, robot: &RobotParams) -> LogGlitches {
    // Rows lost while the wheels turned first: the steps across them would read as a wheel
    // at twice its speed.
    let (filled, rows) = fill_lost_rows(log, robot.period_s);
    let log = &filled;
    let mut out = log.clone();
    let mut mended: Vec<String> = (rows.rows() > 0)
        .then(|| rows.to_string())
        .into_iter()
        .collect();
    if log.kind == LogKind::Ticks {
        let metres_per_tick = std::f64::consts::PI * robot.wheel_diameter_m / robot.ticks_per_rev;
        for (w, name) in TICKS_HEADER[1..].iter().enumerate() {
            let column = if w == 0 {
                &mut out.left
            } else {
                &mut out.right
            };
            for k in 1..column.len().saturating_sub(1) {
                let Some(read_as) = garbled_reading(column, &log.t_s, k, metres_per_tick) else {
                    continue;
                };
                let line = log.line(k);
                let written = log
                    .count_beyond_counters
                    .as_ref()
                    .filter(|b| b.line == line && b.column == *name)
                    .map_or_else(|| log.count_text(w, column[k]), |b| b.written.clone());
                let speed = (column[k] - column[k - 1]).abs() * metres_per_tick
                    / (log.t_s[k] - log.t_s[k - 1]);
                mended.push(format!(
                    "line {line}: {name} reads {written} between {} and {} on the rows around it, {speed:.0} m/s there and back: a garbled reading, read as {}",
                    log.count_text(w, column[k - 1]),
                    log.count_text(w, column[k + 1]),
                    log.count_text(w, read_as)
                ));
                column[k] = read_as;
            }
        }
        // Every count no counter gives was read between its neighbours, or its steps are lost.
        out.count_beyond_counters = None;
    }
    let lost: Vec<LostStep> = out
        .implausible_steps(robot)
        .into_iter()
        .map(|(row, reason)| LostStep { row, reason })
        .collect();
    if lost.len() > MAX_LOST_STEPS {
        let first = log
            .implausible_step(robot)
            .unwrap_or_else(|| lost[0].reason.clone());
        return LogGlitches::Everywhere(format!(
            "{first}; and {} more such steps, too many for glitches",
            lost.len() - 1
        ));
    }
    for step in &lost {
        rebase(&mut out, step.row, &lost);
    }
    LogGlitches::Mended(Box::new(MendedLog {
        log: out,
        mended,
        lost,
    }))
}

/// The count read in place of row `k`'s of `column` (at times `t_s`) when it is a garbled
/// reading: it leaves the count of the row before and comes back to the row after's faster
/// than [`MAX_WHEEL_SPEED_MPS`] both ways, while those two rows are a wheel's travel apart.
/// The count between them, at row `k`'s time, is within a tick or two of the wheel's.
fn garbled_reading(column: &[f64], t_s: &[f64], k: usize, metres_per_tick: f64) -> Option<f64> {
    let speed = |a: usize, b: usize| (column[b] - column[a]) * metres_per_tick / (t_s[b] - t_s[a]);
    let (into, back, across) = (speed(k - 1, k), speed(k, k + 1), speed(k - 1, k + 1));
    let garbled = into.abs() > MAX_WHEEL_SPEED_MPS
        && back.abs() > MAX_WHEEL_SPEED_MPS
        && into.signum() != back.signum()
        && across.abs() <= MAX_WHEEL_SPEED_MPS;
    garbled.then(|| {
        let f = (t_s[k] - t_s[k - 1]) / (t_s[k + 1] - t_s[k - 1]);
        (column[k - 1] + f * (column[k + 1] - column[k - 1])).round()
    })
}

/// Sets the travel of the lost step ending at `row` to the mean of its neighbours' (those not
/// lost themselves; none at rest), moving every count after it by the difference (a speed log:
/// that step's speed).
fn rebase(log: &mut OdometryLog, row: usize, lost: &[LostStep]) {
    let n = log.len();
    let usable = |k: usize| k >= 1 && k < n && !lost.iter().any(|s| s.row == k);
    let neighbours: Vec<usize> = [row.wrapping_sub(1), row + 1]
        .into_iter()
        .filter(|&k| usable(k))
        .collect();
    for w in 0..2 {
        let column = if w == 0 {
            &mut log.left
        } else {
            &mut log.right
        };
        let step = |c: &[f64], k: usize| match log.kind {
            LogKind::Ticks => c[k] - c[k - 1],
            LogKind::Speeds => c[k],
        };
        let estimate = if neighbours.is_empty() {
            0.0
        } else {
            neighbours.iter().map(|&k| step(column, k)).sum::<f64>() / neighbours.len() as f64
        };
        match log.kind {
            LogKind::Ticks => {
                let shift = step(column, row) - estimate.round();
                column[row..].iter_mut().for_each(|c| *c -= shift);
            }
            LogKind::Speeds => column[row] = estimate,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A tick log of `counts` (both wheels alike) every 0.2 s.
    fn ticks(left: &[i64], right: &[i64]) -> OdometryLog {
        let t = (0..left.len()).map(|k| 0.2 * k as f64).collect();
        OdometryLog::from_ticks(t, left.to_vec(), right.to_vec()).expect("log")
    }

    fn mended(log: &OdometryLog) -> MendedLog {
        match mend_glitches(log, &RobotParams::default()) {
            LogGlitches::Mended(m) => *m,
            LogGlitches::Everywhere(why) => panic!("{why}"),
        }
    }

    #[test]
    fn a_garbled_count_is_read_between_its_neighbours() {
        let good: Vec<i64> = (0..12).map(|k| 10 * k).collect();
        let mut bad = good.clone();
        bad[5] += 40000;
        let m = mended(&ticks(&bad, &good));
        assert_eq!(
            m.log.left, m.log.right,
            "read back as the wheel's own count"
        );
        assert!(m.lost.is_empty(), "{:?}", m.lost);
        assert_eq!(
            m.mended,
            ["line 7: left_ticks reads 40050 between 40 and 60 on the rows around it, 2252 m/s there and back: a garbled reading, read as 50"]
        );
        // Clean logs are left as they are.
        let m = mended(&ticks(&good, &good));
        assert!(m.mended.is_empty() && m.lost.is_empty() && m.log == ticks(&good, &good));
    }

    #[test]
    fn a_jump_the_counts_go_on_from_loses_its_step_alone() {
        // At rest (rows 0-4), driving 10 ticks a row, the counter jumping by 40000 at row 7
        // and counting on from there.
        let good: Vec<i64> = [0, 0, 0, 0, 0]
            .into_iter()
            .chain((1..10).map(|k| 10 * k))
            .collect();
        let jumped: Vec<i64> = good
            .iter()
            .enumerate()
            .map(|(k, c)| if k >= 7 { c + 40000 } else { *c })
            .collect();
        let m = mended(&ticks(&jumped, &good));
        assert!(m.mended.is_empty(), "{:?}", m.mended);
        let [step] = &m.lost[..] else {
            panic!("{:?}", m.lost)
        };
        assert_eq!(step.row, 7);
        assert!(
            step.reason
                .starts_with("lines 8 and 9: the left wheel goes from 20 to 40030 ticks"),
            "{}",
            step.reason
        );
        // Re-based on the travel around it: the counts after it are the wheel's again.
        assert_eq!(m.log.left, m.log.right);
        assert!(step.touches(4, 13) && !step.touches(0, 5) && !step.touches(8, 13));
        // A reset at rest is lost too, and the counts after it go on from the rows before.
        let rest = [0, 0, 50, 50, 50, 0, 0, 5, 10];
        let m = mended(&ticks(&rest, &[0, 0, 50, 50, 50, 50, 50, 55, 60]));
        assert_eq!(m.lost.iter().map(|s| s.row).collect::<Vec<_>>(), [5]);
        assert!(m.lost[0].reason.contains("the counter was reset"));
        assert_eq!(m.log.left, [0., 0., 50., 50., 50., 50., 50., 55., 60.]);
    }

    #[test]
    fn impossible_steps_everywhere_are_no_glitches() {
        // A robot file of 12 ticks a revolution for an encoder of more: every step of 100
        // ticks is 5.6 m/s.
        let fast: Vec<i64> = (0..12).map(|k| 100 * k).collect();
        let LogGlitches::Everywhere(why) =
            mend_glitches(&ticks(&fast, &fast), &RobotParams::default())
        else {
            panic!("read as glitches")
        };
        assert!(
            why.starts_with("lines 2 and 3: the left wheel goes from 0 to 100 ticks")
                && why.ends_with("; and 10 more such steps, too many for glitches"),
            "{why}"
        );
    }

    #[test]
    fn a_log_of_another_period_is_left_for_the_period_check() {
        // Every other row of a 200 ms log: 0.4 s steps, read as a row lost at each.
        let counts: Vec<i64> = (0..20).map(|k| 20 * k).collect();
        let t = (0..20).map(|k| 0.4 * k as f64).collect();
        let log = OdometryLog::from_ticks(t, counts.clone(), counts).expect("log");
        let robot = RobotParams::default();
        assert_eq!(
            mend_garbled_readings(&log, &robot),
            (log.clone(), Vec::new())
        );
        assert_eq!(
            log.period_mismatch(robot.period_s).as_deref(),
            Some("rows are 0.400 s apart, but the robot logs every 0.200 s")
        );
    }

    #[test]
    fn a_speed_spike_loses_its_step() {
        let t: Vec<f64> = (0..8).map(|k| 0.2 * k as f64).collect();
        let v = vec![0.0, 0.3, 0.5, 0.5, 500.0, 0.5, 0.3, 0.0];
        let log = OdometryLog::from_speeds(t, v.clone(), v).expect("log");
        let m = mended(&log);
        assert_eq!(m.lost.iter().map(|s| s.row).collect::<Vec<_>>(), [4]);
        assert!(m.mended.is_empty());
        assert_eq!(m.log.left[4], 0.5);
    }
}
