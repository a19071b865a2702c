//! 200 ms odometry logs (the format README.md documents): `t,left_ticks,right_ticks` (cumulative encoder
//! counts) or `t,v_left,v_right` (wheel speeds, m/s), `t` in seconds on the robot's clock.

use std::path::Path;

use odocal_core::{csv_table, numeric_row};

use crate::counter_wrap::{unwrap_counts, CountBeyondCounters, CounterWrap};
use crate::error::{read_text, DatasetError};
use crate::twitch::{remove_twitches, Twitch};
use crate::RobotParams;

/// Header of a tick log.
pub const TICKS_HEADER: [&str; 3] = ["t", "left_ticks", "right_ticks"];
/// Header of a wheel-speed log.
pub const SPEEDS_HEADER: [&str; 3] = ["t", "v_left", "v_right"];

/// Speed below which a wheel-speed log row counts as standing still, m/s.
pub const SPEED_REST_THRESHOLD_MPS: f64 = 0.005;

/// How far, in log periods, a step may be off the robot's period before samples refuse it: a
/// logger's jitter stays well inside, a lost row (twice the period) or an extra one (half)
/// does not.
pub const STEP_TOLERANCE_PERIODS: f64 = 0.5;

/// How far, as a fraction, a log's mean period may be off the robot's before the log is taken
/// for another robot's or logger's.
pub const PERIOD_TOLERANCE: f64 = 0.05;

/// A step this many times a log's median step or longer is rows lost, when the log's own
/// period is measured: a logger's jitter moves single rows by well under half a period.
const GAP_STEPS: f64 = 1.75;

/// A count falling back to about 0 by more than this many times the wheel's steps around it
/// (and [`RESET_SLACK_TICKS`]) is a reset counter, not the wheel: a wheel driven backwards
/// counts down step by step, at a speed it changes gradually.
const RESET_STEPS: f64 = 3.0;

/// See [`RESET_STEPS`]: a wheel at rest nudged by a tick or two is no reset.
const RESET_SLACK_TICKS: f64 = 2.0;

/// The largest count a double holds exactly (2⁵³): a tick column with a count beyond it is
/// taken relative to its median count, in integers.
pub const EXACT_COUNT: i128 = 1 << 53;

/// What a counter reset's reason says after naming it: the advice for a run across it.
pub const RESET_ADVICE: &str = "; the counts after it do not continue the run's";

/// The fastest a small wheeled robot's wheel surface moves, m/s: the reference robot drives
/// at 0.1-0.7 m/s; a faster step is a glitch or a unit error.
pub const MAX_WHEEL_SPEED_MPS: f64 = 5.0;

/// What the two wheel columns of a log hold.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LogKind {
    /// Cumulative encoder counts per wheel.
    Ticks,
    /// Wheel surface speed in m/s over the interval ending at the row's time.
    Speeds,
}

/// An odometry log: strictly increasing robot-clock times and two wheel columns.
#[derive(Debug, Clone, PartialEq)]
pub struct OdometryLog {
    /// Column meaning.
    pub kind: LogKind,
    /// Robot-clock times, seconds, strictly increasing.
    pub t_s: Vec<f64>,
    /// Left wheel: cumulative ticks or speed (m/s), per [`LogKind`].
    pub left: Vec<f64>,
    /// Right wheel: cumulative ticks or speed (m/s), per [`LogKind`].
    pub right: Vec<f64>,
    /// The encoder-counter wraps taken out of the counts as read (`left`, `right` hold the
    /// unwrapped counts).
    pub counter_wraps: Vec<CounterWrap>,
    /// The encoder twitches at rest set back to the count around them (see
    /// [`crate::twitch`]).
    pub twitches: Vec<Twitch>,
    /// The first count of a tick log that no wheel's counter reaches from its column's
    /// other counts, as written.
    pub count_beyond_counters: Option<CountBeyondCounters>,
    /// The count each tick column's values (`left`, `right`) are taken from: 0, or for a
    /// column holding a count beyond [`EXACT_COUNT`] (a 64-bit counter's) its median count, so
    /// that its steps, taken between integers, are exact: as numbers, counts near 10¹⁶ are 2
    /// ticks apart and near 2⁶² 1024, and every step read as noise or as rest.
    pub count_origin: [i128; 2],
    /// The file's line of each row (the header is line 1), for messages; a row filled in
    /// where the logger lost one ([`crate::lost_rows`]) carries the line of the row after it.
    pub lines: Vec<u64>,
}

/// Cumulative wheel revolutions at the log's times, relative to the first row.
#[derive(Debug, Clone, PartialEq)]
pub struct WheelRevs {
    /// Robot-clock times, seconds.
    pub t_s: Vec<f64>,
    /// Cumulative revolutions [left, right] since the first row.
    pub rev: Vec<[f64; 2]>,
}

impl OdometryLog {
    /// A tick log from cumulative counts; checks times and lengths.
    pub fn from_ticks(
        t_s: Vec<f64>,
        left: Vec<i64>,
        right: Vec<i64>,
    ) -> Result<Self, DatasetError> {
        let wide = |c: Vec<i64>| counts_from(&c.into_iter().map(i128::from).collect::<Vec<_>>());
        let ((lo, left), (ro, right)) = (wide(left), wide(right));
        let log = Self {
            kind: LogKind::Ticks,
            t_s,
            left,
            right,
            counter_wraps: Vec::new(),
            twitches: Vec::new(),
            count_beyond_counters: None,
            count_origin: [lo, ro],
            lines: Vec::new(),
        };
        log.validate("<ticks>", |i| i as u64 + 2)?;
        Ok(log)
    }

    /// A wheel-speed log (m/s per wheel over the interval ending at each row); checks times.
    pub fn from_speeds(
        t_s: Vec<f64>,
        v_left: Vec<f64>,
        v_right: Vec<f64>,
    ) -> Result<Self, DatasetError> {
        let log = Self {
            kind: LogKind::Speeds,
            t_s,
            left: v_left,
            right: v_right,
            counter_wraps: Vec::new(),
            twitches: Vec::new(),
            count_beyond_counters: None,
            count_origin: [0, 0],
            lines: Vec::new(),
        };
        log.validate("<speeds>", |i| i as u64 + 2)?;
        Ok(log)
    }

    /// The file's line of row `k` (0-based): as read, or the row's place after a header
    /// for a log made in memory.
    pub fn line(&self, k: usize) -> u64 {
        self.lines.get(k).copied().unwrap_or(k as u64 + 2)
    }

    /// Count `v` of wheel `w` (0 left, 1 right) as the file writes it: `v` is taken from the
    /// column's [`Self::count_origin`].
    pub fn count_text(&self, w: usize, v: f64) -> String {
        match self.count_origin[w] {
            0 => v.to_string(),
            origin => origin.saturating_add(v as i128).to_string(),
        }
    }

    /// Number of rows.
    pub fn len(&self) -> usize {
        self.t_s.len()
    }

    /// True when the log has no rows.
    pub fn is_empty(&self) -> bool {
        self.t_s.is_empty()
    }

    /// The median interval between rows, seconds: the logger's period, which a dropped row
    /// does not move. `None` for fewer than two rows.
    pub fn median_period_s(&self) -> Option<f64> {
        let mut d: Vec<f64> = self.t_s.windows(2).map(|w| w[1] - w[0]).collect();
        if d.is_empty() {
            return None;
        }
        d.sort_by(f64::total_cmp);
        Some(d[d.len() / 2])
    }

    /// The log's mean period, seconds: its span over the periods it holds, so a logger's
    /// jitter (steps of 0.11 to 0.29 s on a 200 ms log) does not move it as it moves the
    /// median step. A step of [`GAP_STEPS`] mean steps or more is rows lost, and counts as the
    /// periods it spans. `None` for fewer than two rows.
    pub fn mean_period_s(&self) -> Option<f64> {
        let median = self.median_period_s()?;
        let steps = || self.t_s.windows(2).map(|w| w[1] - w[0]);
        let regular: Vec<f64> = steps().filter(|&dt| dt < GAP_STEPS * median).collect();
        let step_s = regular.iter().sum::<f64>() / regular.len() as f64;
        let periods: f64 = steps()
            .map(|dt| {
                if dt < GAP_STEPS * median {
                    1.0
                } else {
                    (dt / step_s).round()
                }
            })
            .sum();
        Some((self.t_s[self.t_s.len() - 1] - self.t_s[0]) / periods)
    }

    /// What is wrong when the log's mean period ([`Self::mean_period_s`]) is more than
    /// [`PERIOD_TOLERANCE`] off the robot's `period_s`, either way (rows logged by another
    /// robot or logger, times in another unit, or a robot file that describes another robot);
    /// `None` when it fits. Every feature and speed odocal derives assumes the rows are
    /// `period_s` apart.
    pub fn period_mismatch(&self, period_s: f64) -> Option<String> {
        // The margin keeps a period exactly at the tolerance on the same side both ways
        // (0.19 and 0.21 s against 0.2 s differ from it by 0.01 s only up to rounding).
        let p = self
            .mean_period_s()
            .filter(|p| (p / period_s - 1.0).abs() > PERIOD_TOLERANCE + 1e-9)?;
        let unit = match Self::unit_of(p, period_s) {
            Some((unit, k)) => {
                format!(" ({k:.0} times that: are the times in {unit}? they must be in seconds)")
            }
            None => String::new(),
        };
        Some(format!(
            "rows are {p:.3} s apart, but the robot logs every {period_s:.3} s{unit}"
        ))
    }

    /// Whether the log's mean period is `period_s` in milliseconds, so that
    /// [`Self::period_mismatch`] is the log's unit, which no robot file mends.
    pub fn times_in_milliseconds(&self, period_s: f64) -> bool {
        self.time_unit(period_s).is_some_and(|(_, k)| k == 1e3)
    }

    /// The unit the log's times are in when its mean period is `period_s` in milliseconds,
    /// microseconds or nanoseconds (its name and how many make a second): a logger stamping
    /// `micros()` wrote rows "200000 s apart", and was told to give another robot file.
    pub fn time_unit(&self, period_s: f64) -> Option<(&'static str, f64)> {
        let p = self.mean_period_s()?;
        Self::unit_of(p, period_s)
    }

    fn unit_of(mean_period_s: f64, period_s: f64) -> Option<(&'static str, f64)> {
        [
            ("milliseconds", 1e3),
            ("microseconds", 1e6),
            ("nanoseconds", 1e9),
        ]
        .into_iter()
        .find(|&(_, k)| (mean_period_s / period_s / k - 1.0).abs() < 0.05)
    }

    /// The first step among rows `first..=last` (0-based) whose interval is off the robot's
    /// `period_s` by more than `tolerance` periods, as the row it ends at and its interval:
    /// every per-step input and correction takes a step for one period, so a lost row (a
    /// 1.4 s step counted as one 200 ms step reads as seven times the speed) or an extra
    /// one would pass for a step of the robot's. A row logged late or early whose next row is
    /// back on time (steps of 1.6 and 0.4 periods: a logger's jitter, its counts read when
    /// it was stamped) is no such step: the two steps span two periods, as they should. Nor
    /// is a step the wheels stand still across ([`Self::rests_across`]): no travel is misread
    /// there, and every pose odocal takes from a log is placed by time, so a row lost at rest
    /// changes no dead reckoning, feature or window.
    pub fn off_period_step(
        &self,
        first: usize,
        last: usize,
        period_s: f64,
        tolerance: f64,
    ) -> Option<(usize, f64)> {
        let last = last.min(self.t_s.len().saturating_sub(1));
        let step = |k: usize| self.t_s[k] - self.t_s[k - 1];
        let off = |dt: f64, periods: f64| (dt - periods * period_s).abs() > tolerance * period_s;
        let mut k = first + 1;
        while k <= last {
            if off(step(k), 1.0) && !self.rests_across(k) {
                if k + 1 < self.t_s.len() && !off(step(k) + step(k + 1), 2.0) {
                    k += 2;
                    continue;
                }
                return Some((k, step(k)));
            }
            k += 1;
        }
        None
    }

    /// What is wrong with the step of [`Self::off_period_step`] ending at row `k` (0-based),
    /// naming its rows by the file's lines.
    pub fn step_message(&self, k: usize, dt: f64, period_s: f64) -> String {
        format!(
            "lines {} and {} are {dt:.3} s apart, but the robot logs every {period_s:.3} s (a dropped or extra row?)",
            self.line(k - 1),
            self.line(k)
        )
    }

    /// What reading the log took out of its counts, for the user: the encoder-counter wraps
    /// unwrapped and the twitches at rest set back (None when there were none).
    pub fn count_note(&self) -> Option<String> {
        let more = |n: usize, one: &str, many: &str| match n {
            0 | 1 => String::new(),
            2 => format!(" and 1 more {one}"),
            n => format!(" and {} more {many}", n - 1),
        };
        let wraps = self.counter_wraps.first().map(|first| {
            format!(
                "encoder counts unwrapped: {first}{}; check that the robot's counter is {} bits wide",
                more(self.counter_wraps.len(), "wrap", "wraps"),
                first.bits
            )
        });
        let twitches = self.twitches.first().map(|first| {
            format!(
                "encoder counts flickering by a tick at rest read as rest: {first}{}",
                more(self.twitches.len(), "twitch", "twitches"),
            )
        });
        match (wraps, twitches) {
            (Some(w), Some(t)) => Some(format!("{w}; {t}")),
            (w, t) => w.or(t),
        }
    }

    /// Reads a log CSV; the header decides the kind.
    pub fn read_csv(path: &Path) -> Result<Self, DatasetError> {
        let text = read_text(path)?;
        Self::parse_csv(&text, &path.display().to_string())
    }

    /// Parses log CSV text; `name` is used in error messages.
    pub fn parse_csv(text: &str, name: &str) -> Result<Self, DatasetError> {
        let Some(table) = csv_table(text, name)? else {
            return Err(DatasetError::content(
                name,
                "empty odometry log (no header, no rows)",
            ));
        };
        let (line, header) = &table.header;
        let fields: Vec<&str> = header.iter().collect();
        let kind = if fields == TICKS_HEADER {
            LogKind::Ticks
        } else if fields == SPEEDS_HEADER {
            LogKind::Speeds
        } else if fields.len() == 1 && fields[0].contains('\t') {
            // A spreadsheet's or a logger's tab-separated export reads as one column.
            return Err(DatasetError::parse(
                name,
                *line,
                1,
                format!(
                    "the header \"{}\" is separated by tabs, but odocal reads comma-separated CSV; separate the columns with commas (\"t,left_ticks,right_ticks\" or \"t,v_left,v_right\"), e.g. tr '\\t' ',' < log.tsv > log.csv",
                    fields[0].replace('\t', "\\t")
                ),
            ));
        } else {
            return Err(DatasetError::parse(
                name,
                *line,
                1,
                format!(
                    "header is \"{}\", expected \"t,left_ticks,right_ticks\" or \"t,v_left,v_right\"",
                    fields.join(",")
                ),
            ));
        };
        let mut t_s = Vec::new();
        let mut left = Vec::new();
        let mut right = Vec::new();
        let mut raw: [Vec<i128>; 2] = [Vec::new(), Vec::new()];
        let mut lines = Vec::new();
        for &(line, ref rec) in &table.rows {
            if let Some(t) = rec.get(0).filter(|t| looks_like_a_date(t)) {
                return Err(DatasetError::parse(
                    name,
                    line,
                    1,
                    format!(
                        "\"{t}\" is a date or clock time, but t must be seconds (a number, e.g. seconds since the log's start or Unix time): convert the times to seconds"
                    ),
                ));
            }
            let vals: [f64; 3] = numeric_row(name, line, rec)?;
            if kind == LogKind::Ticks {
                if let Some(c) = (1..3).find(|&c| vals[c].fract() != 0.0) {
                    return Err(DatasetError::parse(
                        name,
                        line,
                        c as u64 + 1,
                        format!("\"{}\" is not a whole tick count", &rec[c]),
                    ));
                }
            }
            if kind == LogKind::Ticks {
                // A 64-bit count is read as an integer: as a number it is rounded to the
                // nearest of doubles up to 1024 apart. "1e30" and the like are numbers only.
                for c in 1..3 {
                    raw[c - 1].push(rec[c].parse::<i128>().unwrap_or(vals[c] as i128));
                }
            }
            t_s.push(vals[0]);
            left.push(vals[1]);
            right.push(vals[2]);
            lines.push(line);
        }
        let mut counter_wraps = Vec::new();
        let mut twitches = Vec::new();
        let mut count_origin = [0, 0];
        let mut count_beyond_counters = None;
        if kind == LogKind::Ticks {
            let ((lo, l), (ro, r)) = (counts_from(&raw[0]), counts_from(&raw[1]));
            (left, right, count_origin) = (l, r, [lo, ro]);
            count_beyond_counters = (0..raw[0].len())
                .flat_map(|k| [(k, 0), (k, 1)])
                .find(|&(k, w)| {
                    raw[w][k].saturating_sub(count_origin[w]).unsigned_abs()
                        > EXACT_COUNT.unsigned_abs()
                })
                .map(|(k, w)| CountBeyondCounters {
                    column: TICKS_HEADER[w + 1],
                    line: lines[k],
                    written: table.rows[k].1[w + 1].to_string(),
                    median: count_origin[w],
                });
            // A column beyond a double's integers is no 16- or 32-bit counter: it does not
            // wrap.
            if count_origin[0] == 0 {
                counter_wraps.extend(unwrap_counts(&mut left, TICKS_HEADER[1], &lines));
            }
            if count_origin[1] == 0 {
                counter_wraps.extend(unwrap_counts(&mut right, TICKS_HEADER[2], &lines));
            }
            twitches = remove_twitches(&mut left, &mut right, &lines);
        }
        let log = Self {
            kind,
            t_s,
            left,
            right,
            counter_wraps,
            twitches,
            count_beyond_counters,
            count_origin,
            lines,
        };
        log.validate(name, |i| log.line(i))?;
        Ok(log)
    }

    /// Checks lengths, finiteness and strictly increasing times; `line_of(i)` locates row i.
    fn validate(&self, name: &str, line_of: impl Fn(usize) -> u64) -> Result<(), DatasetError> {
        if self.left.len() != self.t_s.len() || self.right.len() != self.t_s.len() {
            return Err(DatasetError::content(name, "columns differ in length"));
        }
        if self.t_s.len() < 2 {
            return Err(DatasetError::content(
                name,
                format!(
                    "odometry log has {} data rows; need at least 2",
                    self.t_s.len()
                ),
            ));
        }
        for i in 0..self.t_s.len() {
            for (c, v) in [self.t_s[i], self.left[i], self.right[i]]
                .iter()
                .enumerate()
            {
                if !v.is_finite() {
                    return Err(DatasetError::parse(
                        name,
                        line_of(i),
                        c as u64 + 1,
                        "value is not a finite number",
                    ));
                }
            }
            if i > 0 {
                let (a, b) = (self.t_s[i - 1], self.t_s[i]);
                if b == a {
                    return Err(DatasetError::parse(
                        name,
                        line_of(i),
                        1,
                        format!(
                            "duplicated timestamp {b} (same as line {}); remove the repeated row",
                            line_of(i - 1)
                        ),
                    ));
                }
                if b < a {
                    return Err(DatasetError::parse(
                        name,
                        line_of(i),
                        1,
                        format!(
                            "timestamp {b} goes back in time (line {} has {a}); rows must be in time order",
                            line_of(i - 1)
                        ),
                    ));
                }
            }
        }
        Ok(())
    }

    /// The log as CSV text with its header (full round-trip precision).
    pub fn to_csv(&self) -> String {
        let header = match self.kind {
            LogKind::Ticks => TICKS_HEADER,
            LogKind::Speeds => SPEEDS_HEADER,
        };
        let mut s = header.join(",");
        s.push('\n');
        for i in 0..self.t_s.len() {
            let (l, r) = match self.kind {
                LogKind::Ticks => (
                    self.count_text(0, self.left[i]),
                    self.count_text(1, self.right[i]),
                ),
                LogKind::Speeds => (self.left[i].to_string(), self.right[i].to_string()),
            };
            s.push_str(&format!("{},{l},{r}\n", self.t_s[i]));
        }
        s
    }

    /// Whether the wheels stand still across the step ending at row `k` (k ≥ 1), however
    /// long it is: a tick log's counts do not change over it; a speed log's rows on both
    /// sides of it read rest, since its speeds hold nothing of the rows lost in between.
    pub fn rests_across(&self, k: usize) -> bool {
        let rest = |i: usize| {
            self.left[i].abs() <= SPEED_REST_THRESHOLD_MPS
                && self.right[i].abs() <= SPEED_REST_THRESHOLD_MPS
        };
        match self.kind {
            LogKind::Ticks => !self.moving_at(k),
            LogKind::Speeds => rest(k - 1) && rest(k),
        }
    }

    /// Whether the robot moved in the interval ending at row `i` (i ≥ 1).
    pub fn moving_at(&self, i: usize) -> bool {
        match self.kind {
            LogKind::Ticks => {
                self.left[i] != self.left[i - 1] || self.right[i] != self.right[i - 1]
            }
            LogKind::Speeds => {
                self.left[i].abs() > SPEED_REST_THRESHOLD_MPS
                    || self.right[i].abs() > SPEED_REST_THRESHOLD_MPS
            }
        }
    }

    /// The first step in which a wheel's surface moves faster than
    /// [`MAX_WHEEL_SPEED_MPS`], as what is wrong with it (its rows numbered as the file's
    /// lines): a counter glitch or a spike in a speed column, which the alignment would
    /// otherwise only see as speed profiles that do not match. A count no 16- or 32-bit
    /// counter gives is named first, as written.
    pub fn implausible_step(&self, robot: &RobotParams) -> Option<String> {
        if let Some(beyond) = &self.count_beyond_counters {
            return Some(beyond.to_string());
        }
        if let Some(reset) = self.counter_reset() {
            return Some(reset);
        }
        (1..self.len()).find_map(|k| self.too_fast_at(k, robot))
    }

    /// Every step of [`Self::implausible_step`] but counts beyond any counter (whose steps
    /// are too fast anyway), as the row it ends at (0-based) and what is wrong with it: a
    /// counter reset's step is named as one.
    pub fn implausible_steps(&self, robot: &RobotParams) -> Vec<(usize, String)> {
        let mut resets = self.counter_resets().into_iter().peekable();
        (1..self.len())
            .filter_map(|k| {
                let reset = resets.next_if(|(r, _)| *r == k).map(|(_, why)| why);
                reset
                    .or_else(|| self.too_fast_at(k, robot))
                    .map(|why| (k, why))
            })
            .collect()
    }

    /// The travel of wheel `w` (0 left, 1 right) over the step ending at row `k` (k ≥ 1),
    /// metres on the nominal wheel.
    pub fn step_travel_m(&self, k: usize, w: usize, robot: &RobotParams) -> f64 {
        let column = [&self.left, &self.right][w];
        match self.kind {
            LogKind::Ticks => {
                (column[k] - column[k - 1]) / robot.ticks_per_rev
                    * std::f64::consts::PI
                    * robot.wheel_diameter_m
            }
            LogKind::Speeds => column[k] * (self.t_s[k] - self.t_s[k - 1]),
        }
    }

    /// What is wrong with the step ending at row `k` (k ≥ 1) when a wheel's surface moves
    /// faster than [`MAX_WHEEL_SPEED_MPS`] over it (its rows numbered as the file's lines).
    pub fn too_fast_at(&self, k: usize, robot: &RobotParams) -> Option<String> {
        let dt = self.t_s[k] - self.t_s[k - 1];
        (0..2).find_map(|w| {
            let v = self.step_travel_m(k, w, robot) / dt;
            (v.abs() > MAX_WHEEL_SPEED_MPS).then(|| {
                let (side, column) = [("left", &self.left), ("right", &self.right)][w];
                // A speed is the log's own figure; ticks say the speed they make.
                let what = match self.kind {
                    LogKind::Ticks => format!(
                        "goes from {} to {} ticks, {:.1} m/s",
                        self.count_text(w, column[k - 1]),
                        self.count_text(w, column[k]),
                        v.abs()
                    ),
                    LogKind::Speeds => format!("reads {} m/s", column[k]),
                };
                // A speed log's speeds use neither robot parameter: its unit is the
                // suspect, not the robot file.
                let suspects = match self.kind {
                    LogKind::Ticks => "a glitch or a reset counter in the log, or ticks_per_rev and wheel_diameter_m not the robot's?",
                    LogKind::Speeds => "a glitch in the log, or speeds not in m/s? mm/s read 1000 times too fast",
                };
                format!(
                    "lines {} and {}: the {side} wheel {what} over {dt:.3} s, where a small robot's wheels turn at {MAX_WHEEL_SPEED_MPS} m/s at most ({suspects})",
                    self.line(k - 1),
                    self.line(k),
                )
            })
        })
    }

    /// The first row of a tick log where a wheel's count falls back to about 0 in one step far
    /// beyond the wheel's steps around it (a motor board restarted, its counters reset), as what
    /// is wrong with it, naming the file's line. Read as motion, the drop is one step of
    /// the wheel driven backwards: at a few dozen ticks it is no impossible speed, and it
    /// only spoiled the alignment ("speed-profile correlation 0.30") or the model's domain.
    /// A wheel driven backwards counts down step by step, and a wrap is unwrapped before.
    pub fn counter_reset(&self) -> Option<String> {
        self.counter_resets().into_iter().next().map(|(_, why)| why)
    }

    /// Every step of [`Self::counter_reset`], as the row it ends at (0-based) and what is
    /// wrong with it.
    pub fn counter_resets(&self) -> Vec<(usize, String)> {
        if self.kind != LogKind::Ticks {
            return Vec::new();
        }
        let n = self.len();
        // The wheel's largest step on either side of row k's.
        let around = |c: &[f64], k: usize| {
            let step = |j: usize| {
                if j >= 1 && j < n {
                    (c[j] - c[j - 1]).abs()
                } else {
                    0.0
                }
            };
            step(k - 1).max(step(k + 1))
        };
        // The count lands where a counter started at 0 would be a step later, after a fall
        // no step of the wheel around it comes near.
        let columns = [&self.left, &self.right];
        let reset_at = |w: usize, k: usize| {
            let c = columns[w];
            (c[k] - c[k - 1]).abs() > RESET_STEPS * around(c, k) + RESET_SLACK_TICKS
                && (c[k] + self.count_origin[w] as f64).abs() <= around(c, k) + 1.0
        };
        (1..n)
            .filter(|&k| reset_at(0, k) || reset_at(1, k))
            .map(|k| {
                let line = self.line(k);
                let drops: Vec<String> = (0..2)
                    .filter(|&w| reset_at(w, k))
                    .map(|w| {
                        let c = columns[w];
                        format!(
                            "{} drops from {} to {} in one step where the wheel moves {} ticks a step around it",
                            TICKS_HEADER[w + 1],
                            self.count_text(w, c[k - 1]),
                            self.count_text(w, c[k]),
                            around(c, k)
                        )
                    })
                    .collect();
                let cause = match self.counts_per_period(k) {
                    Some(hint) => format!("counts per period? {hint}; or the counter was reset (motor board restarted?)"),
                    None => "the counter was reset (motor board restarted?)".into(),
                };
                (k, format!(
                    "line {line}: {}: {cause}{RESET_ADVICE}: cut the log before line {line}, or record the run again",
                    drops.join(", and ")
                ))
            })
            .collect()
    }

    /// Why the counts look like counts per period rather than cumulative ones, for a drop at
    /// row `k`: before it, a column rises and falls back three times or more, as a counter of
    /// a wheel turning one way never does, and no count passes three of its largest rises (a
    /// counter's counts add up over a run). `None` otherwise.
    fn counts_per_period(&self, k: usize) -> Option<String> {
        [&self.left, &self.right].into_iter().find_map(|c| {
            let steps: Vec<f64> = (1..k).map(|j| c[j] - c[j - 1]).collect();
            let rises = steps.iter().filter(|d| **d > 0.0).count();
            let falls = steps.iter().filter(|d| **d < 0.0).count();
            let largest = c[..k].iter().fold(0.0, |m: f64, v| m.max(v.abs()));
            let rise = steps.iter().fold(0.0, |m: f64, d| m.max(*d));
            (rises >= 3 && falls >= 3 && largest <= 3.0 * rise).then(|| {
                format!(
                    "they rise and fall back {falls} times before it and never pass {largest}, where odocal reads cumulative counts, a running total: add them up"
                )
            })
        })
    }

    /// Cumulative wheel revolutions relative to the first row. Speeds are converted with the
    /// nominal wheel diameter (the robot computed them with it), ticks with `ticks_per_rev`.
    pub fn wheel_revs(&self, robot: &RobotParams) -> WheelRevs {
        let mut rev = Vec::with_capacity(self.len());
        match self.kind {
            LogKind::Ticks => {
                for i in 0..self.len() {
                    rev.push([
                        (self.left[i] - self.left[0]) / robot.ticks_per_rev,
                        (self.right[i] - self.right[0]) / robot.ticks_per_rev,
                    ]);
                }
            }
            LogKind::Speeds => {
                let circ = std::f64::consts::PI * robot.wheel_diameter_m;
                let mut acc = [0.0, 0.0];
                rev.push(acc);
                for i in 1..self.len() {
                    let dt = self.t_s[i] - self.t_s[i - 1];
                    acc[0] += self.left[i] * dt / circ;
                    acc[1] += self.right[i] * dt / circ;
                    rev.push(acc);
                }
            }
        }
        WheelRevs {
            t_s: self.t_s.clone(),
            rev,
        }
    }
}

/// A tick column's counts as doubles, and the count they are taken from
/// ([`OdometryLog::count_origin`]): 0 while every count is exact as a double, else the
/// column's median count, the steps taken between integers.
fn counts_from(raw: &[i128]) -> (i128, Vec<f64>) {
    let origin = if raw
        .iter()
        .all(|c| c.unsigned_abs() <= EXACT_COUNT.unsigned_abs())
    {
        0
    } else {
        let mut sorted = raw.to_vec();
        sorted.sort_unstable();
        sorted[sorted.len() / 2]
    };
    (
        origin,
        raw.iter()
            .map(|&c| c.saturating_sub(origin) as f64)
            .collect(),
    )
}

/// Whether a log's time field is a date or a clock time (`2024-05-01T12:00:00.000`,
/// `12:00:00.2`) rather than a number of seconds.
fn looks_like_a_date(field: &str) -> bool {
    field.parse::<f64>().is_err()
        && field.chars().any(|c| c.is_ascii_digit())
        && (field.contains(':') || field.matches('-').count() >= 2)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_ticks_and_speeds() {
        let log = OdometryLog::parse_csv(
            "t,left_ticks,right_ticks\n0,0,0\n0.2,3,4\n0.4,7,7\n",
            "a.csv",
        )
        .unwrap();
        assert_eq!(log.kind, LogKind::Ticks);
        assert_eq!(log.left, vec![0.0, 3.0, 7.0]);
        let revs = log.wheel_revs(&RobotParams::default());
        assert!((revs.rev[2][1] - 7.0 / 12.0).abs() < 1e-12);
        let sp = OdometryLog::parse_csv("t,v_left,v_right\n0,0,0\n0.2,0.5,0.5\n", "b.csv").unwrap();
        assert_eq!(sp.kind, LogKind::Speeds);
        let r = sp.wheel_revs(&RobotParams::default());
        assert!((r.rev[1][0] - 0.1 / (std::f64::consts::PI * 0.043)).abs() < 1e-12);
        let back = OdometryLog::parse_csv(&log.to_csv(), "c").unwrap();
        assert_eq!(back, log);
        assert_eq!(log.count_note(), None);
    }

    /// A tick log at times `t_s`, both wheels 3 ticks a row.
    fn moving_log(t_s: Vec<f64>) -> OdometryLog {
        let ticks: Vec<i64> = (0..t_s.len() as i64).map(|i| 3 * i).collect();
        OdometryLog::from_ticks(t_s, ticks.clone(), ticks).expect("log")
    }

    #[test]
    fn a_jittery_logger_on_the_robots_period_is_its_period() {
        // Rows stamped up to 40 ms early of a 200 ms grid: steps of 0.18, 0.18, 0.24 s,
        // a median step of 0.180 s (it was refused as 10 % off) and a mean of 0.200 s.
        let jittery: Vec<f64> = (0..60)
            .map(|k| 0.2 * k as f64 - [0.0, 0.02, 0.04][k % 3])
            .collect();
        let log = moving_log(jittery);
        assert!((log.median_period_s().expect("median") - 0.18).abs() < 1e-9);
        assert!((log.mean_period_s().expect("mean") - 0.2).abs() < 1e-3);
        assert_eq!(log.period_mismatch(0.2), None);
        // A few rows lost (steps of 0.4 and 0.6 s) leave the period alone.
        let mut gaps: Vec<f64> = (0..60).map(|k| 0.2 * k as f64).collect();
        gaps.retain(|t| ![1.0, 3.0, 3.2].iter().any(|g| (t - g).abs() < 1e-9));
        assert!((moving_log(gaps).mean_period_s().expect("mean") - 0.2).abs() < 1e-9);
        // Constant periods 5 % off either way are both inside (0.19 s was refused, 0.21 s
        // taken); 10 %, a 400 ms logger and milliseconds are refused.
        let every = |p: f64| moving_log((0..30).map(|k| p * k as f64).collect());
        assert_eq!(every(0.19).period_mismatch(0.2), None);
        assert_eq!(every(0.21).period_mismatch(0.2), None);
        let off = every(0.22).period_mismatch(0.2).expect("10 % off");
        assert!(
            off.starts_with("rows are 0.220 s apart, but the robot logs every 0.200 s"),
            "{off}"
        );
        assert!(every(0.4).period_mismatch(0.2).is_some());
        let ms = every(200.0).period_mismatch(0.2).expect("ms");
        assert!(ms.contains("are the times in milliseconds?"), "{ms}");
        assert!(every(200.0).times_in_milliseconds(0.2));
        // A logger stamping micros() or a nanosecond clock was told to give another robot file.
        for (p, unit, k) in [(2e5, "microseconds", 1e6), (2e8, "nanoseconds", 1e9)] {
            let log = every(p);
            let why = log.period_mismatch(0.2).expect("off");
            assert!(why.contains(&format!("are the times in {unit}?")), "{why}");
            assert_eq!(log.time_unit(0.2), Some((unit, k)));
            assert!(!log.times_in_milliseconds(0.2));
        }
        assert!(!every(0.4).times_in_milliseconds(0.2) && !every(0.2).times_in_milliseconds(0.2));
    }

    #[test]
    fn a_counter_reset_mid_run_is_named_not_a_backward_drive_nor_a_wrap() {
        let robot = RobotParams::default();
        // Both counters reset at line 12 (row 10) while driving 4 ticks a row: 40 ticks back
        // in 0.2 s is 2.3 m/s, no impossible speed; it was left to fail the alignment.
        let csv = |l: &[i64], r: &[i64]| {
            let mut s = String::from("t,left_ticks,right_ticks\n");
            for (i, (a, b)) in l.iter().zip(r).enumerate() {
                s.push_str(&format!("{:.1},{a},{b}\n", 0.2 * i as f64));
            }
            OdometryLog::parse_csv(&s, "r.csv").expect("log")
        };
        let up: Vec<i64> = (0..20).map(|i| 4 * i).collect();
        let reset: Vec<i64> = up
            .iter()
            .map(|&c| if c >= 40 { c - 40 } else { c })
            .collect();
        let why = csv(&reset, &reset).implausible_step(&robot).expect("reset");
        assert!(
            why.starts_with("line 12: left_ticks drops from 36 to 0 in one step where the wheel moves 4 ticks a step around it, and right_ticks drops from 36 to 0")
                && why.contains("the counter was reset (motor board restarted?)")
                && why.contains("cut the log before line 12"),
            "{why}"
        );
        // One counter reset at rest, a tick after the reset.
        let rest = [0, 0, 50, 50, 50, 51, 51, 55, 60];
        let still = [0, 0, 50, 50, 50, 50, 50, 54, 59];
        let one: Vec<i64> = rest
            .iter()
            .enumerate()
            .map(|(i, &c)| if i >= 5 { c - 50 } else { c })
            .collect();
        let why = csv(&one, &still).counter_reset().expect("reset at rest");
        assert!(why.starts_with("line 7: left_ticks drops from 50 to 1 in one step where the wheel moves 0 ticks a step around it: the counter was reset"), "{why}");
        // Counts per period, rising and falling about 8 ticks and back to 0 at the end: named
        // as such, where a counter's reset alone was named before.
        let period = [0, 0, 1, 5, 7, 9, 8, 9, 8, 9, 9, 8, 9, 8, 9, 1, 0, 0];
        let why = csv(&period, &period).counter_reset().expect("a drop");
        assert!(
            why.contains(
                "counts per period? they rise and fall back 4 times before it and never pass 9"
            ) && why.contains("add them up"),
            "{why}"
        );
        // Driven backwards (counting down through 0), turning round, or wrapping: no reset.
        let down: Vec<i64> = (0..20).map(|i| 30 - 4 * i).collect();
        let back_and_forth: Vec<i64> = [0, 4, 8, 12, 8, 4, 0, -4, -8].to_vec();
        let wrap: Vec<i64> = (0..10).map(|i| (65520 + 4 * i) % 65536).collect();
        for (l, r) in [
            (&down, &down),
            (&back_and_forth, &back_and_forth),
            (&wrap, &wrap),
        ] {
            let log = csv(l, r);
            assert_eq!(log.counter_reset(), None, "{l:?}");
            assert_eq!(log.implausible_step(&robot), None, "{l:?}");
        }
    }

    #[test]
    fn a_late_row_back_on_time_is_jitter_not_a_lost_row() {
        // The wheels turn 3 ticks a row: every step is motion.
        let log = |t: &[f64]| {
            let ticks: Vec<i64> = (0..t.len() as i64).map(|i| 3 * i).collect();
            OdometryLog::from_ticks(t.to_vec(), ticks.clone(), ticks).unwrap()
        };
        let step = |t: &[f64]| log(t).off_period_step(0, t.len(), 0.2, STEP_TOLERANCE_PERIODS);
        // 120 ms late, then back on time; 150 ms early likewise.
        assert_eq!(step(&[0.0, 0.2, 0.52, 0.6, 0.8]), None);
        assert_eq!(step(&[0.0, 0.2, 0.25, 0.6, 0.8]), None);
        // A lost row stays off: its next step does not take the grid back.
        assert_eq!(step(&[0.0, 0.2, 0.6, 0.8]).map(|s| s.0), Some(2));
        // An extra row: two half steps span one period, not two.
        assert_eq!(step(&[0.0, 0.2, 0.3, 0.4, 0.6]).map(|s| s.0), Some(2));
        // Late on the last row, with no row to take it back.
        assert_eq!(step(&[0.0, 0.2, 0.52]).map(|s| s.0), Some(2));
    }

    #[test]
    fn a_row_lost_while_the_wheels_stand_still_is_no_gap() {
        let t = vec![0.0, 0.6, 0.8, 1.0, 1.6, 1.8];
        let step = |log: OdometryLog| log.off_period_step(0, 6, 0.2, STEP_TOLERANCE_PERIODS);
        // Counts unchanged across the 0.6 s step at the start: no travel is misread; the one
        // while moving (rows 4 and 5) is refused.
        let ticks = |l: Vec<i64>| OdometryLog::from_ticks(t.clone(), l.clone(), l).unwrap();
        assert_eq!(step(ticks(vec![0, 0, 0, 3, 9, 12])).map(|s| s.0), Some(4));
        // Moving across it, the first is refused as the second is.
        assert_eq!(
            step(ticks(vec![0, 9, 12, 15, 21, 24])).map(|s| s.0),
            Some(1)
        );
        // A speed log holds nothing of the rows lost: rest on both sides of the step.
        let speeds = |v: Vec<f64>| OdometryLog::from_speeds(t.clone(), v.clone(), v).unwrap();
        assert_eq!(
            step(speeds(vec![0.0, 0.0, 0.1, 0.1, 0.1, 0.1])).map(|s| s.0),
            Some(4)
        );
        assert_eq!(
            step(speeds(vec![0.1, 0.0, 0.1, 0.1, 0.1, 0.1])).map(|s| s.0),
            Some(1)
        );
    }

    #[test]
    fn wrapped_counts_are_read_unwrapped_with_a_note() {
        let log = OdometryLog::parse_csv(
            "t,left_ticks,right_ticks\n0,65530,65531\n0.2,65535,0\n0.4,4,6\n",
            "w.csv",
        )
        .unwrap();
        assert_eq!(log.left, vec![65530.0, 65535.0, 65540.0]);
        assert_eq!(log.right, vec![65531.0, 65536.0, 65542.0]);
        assert_eq!(
            log.count_note().unwrap(),
            "encoder counts unwrapped: left_ticks wraps as a 16-bit counter at line 4 (65535 → 4) and 1 more wrap; check that the robot's counter is 16 bits wide"
        );
    }

    /// A 64-bit glitch read as a number is a whole number of 2³² turns: it was "unwrapped" to
    /// 0, noted as a 32-bit wrap "(18 → 18446744073709552000)", and the run rejected for a
    /// step "from 95 to 0 ticks", a count nowhere in the file.
    #[test]
    fn a_count_no_counter_reaches_is_named_as_written() {
        let log = OdometryLog::parse_csv(
            "t,left_ticks,right_ticks\n0,90,90\n0.2,95,95\n0.4,99,18446744073709551615\n0.6,104,104\n",
            "g.csv",
        )
        .unwrap();
        assert_eq!(log.count_note(), None);
        assert_eq!(log.right[1], -9.0, "taken from the median count, 104");
        assert_eq!(
            log.implausible_step(&RobotParams::default()).unwrap(),
            "line 4: right_ticks is 18446744073709551615, more than 2^53 ticks from the column's other counts (around 104), farther than any wheel turns: a glitch in the log?"
        );
    }

    /// A 64-bit counter's counts were read as doubles: near 10¹⁶ two ticks apart (every step
    /// off by up to a tick, raw odometry's error read as 31 % where it is 10 %), near 2⁶² 1024
    /// apart (every run at rest); counts past 32 bits were refused as glitches by `correct`.
    #[test]
    fn sixty_four_bit_counts_are_read_exactly() {
        let steps: Vec<i64> = (0..30).map(|k| (k * k) % 7 + 3 * k).collect();
        let t: Vec<f64> = (0..30).map(|k| 0.2 * k as f64).collect();
        // Counts from `offset`, the left jumping by `jump` at row 10.
        let counts = |offset: i128, jump: i128| {
            let mut s = String::from("t,left_ticks,right_ticks\n");
            for (k, c) in steps.iter().enumerate() {
                let c = *c as i128 + offset;
                let j = if k >= 10 { jump } else { 0 };
                s.push_str(&format!("{},{},{}\n", t[k], c + 1 + j, c + 3));
            }
            s
        };
        let csv = |offset: i128| counts(offset, 0);
        let base = OdometryLog::parse_csv(&csv(0), "a.csv").unwrap();
        let robot = RobotParams::default();
        for offset in [5_000_000_000, 10_i128.pow(16), 1 << 62, (1 << 64) - 1000] {
            let log = OdometryLog::parse_csv(&csv(offset), "b.csv").unwrap();
            assert_eq!(log.wheel_revs(&robot), base.wheel_revs(&robot), "{offset}");
            assert_eq!(log.implausible_step(&robot), None, "{offset}");
            assert_eq!(log.count_note(), None, "{offset}");
            assert_eq!(OdometryLog::parse_csv(&log.to_csv(), "c").unwrap(), log);
            assert!(
                log.to_csv().contains(&format!(",{},", offset + 1)),
                "{offset}"
            );
        }
        // Its counts named as written where a step is impossible.
        let jump = counts(10_i128.pow(16), 900_000);
        let log = OdometryLog::parse_csv(&jump, "j.csv").unwrap();
        let why = log.implausible_step(&robot).expect("a jump");
        assert!(
            why.starts_with("lines 11 and 12: the left wheel goes from 10000000000000032 to 10000000000900033 ticks"),
            "{why}"
        );
        let from_ints = OdometryLog::from_ticks(
            t.clone(),
            steps.iter().map(|c| c + (1 << 62)).collect(),
            steps.clone(),
        )
        .unwrap();
        let (a, b) = (from_ints.wheel_revs(&robot), base.wheel_revs(&robot));
        assert!(a.rev.iter().zip(&b.rev).all(|(a, b)| a[0] == b[0]));
    }

    fn err(text: &str) -> String {
        OdometryLog::parse_csv(text, "log.csv")
            .unwrap_err()
            .to_string()
    }

    #[test]
    fn bad_input_is_located() {
        assert_eq!(
            err("t,left_ticks,right_ticks\n0,0,0\n0.2,x,1\n"),
            "log.csv:3:2: \"x\" is not a number"
        );
        assert!(err("t,left_ticks,right_ticks\n0,0,0\n0.2,1,NaN\n").starts_with("log.csv:3:3:"));
        assert!(err("t,left_ticks,right_ticks\n0,0,0\n0,1,1\n")
            .contains("log.csv:3:1: duplicated timestamp"));
        assert!(err("t,left_ticks,right_ticks\n0.2,0,0\n0.1,1,1\n").contains("goes back in time"));
        assert!(err("t,left_ticks,right_ticks\n0,0,0\n0.2,1\n")
            .starts_with("log.csv:3:3: expected 3 fields"));
        assert!(err("time,a,b\n0,0,0\n").starts_with("log.csv:1:1: header"));
        assert!(err("t,left_ticks,right_ticks\n0,0,0\n0.2,1.5,1\n").contains("whole tick count"));
        assert!(err("").contains("empty odometry log"));
        // Tabs and dates were "header is …, expected …" and "is not a number", no more.
        let tabs = err("t\tleft_ticks\tright_ticks\n0\t0\t0\n");
        assert!(
            tabs.starts_with("log.csv:1:1: the header") && tabs.contains("separated by tabs"),
            "{tabs}"
        );
        let date = err("t,left_ticks,right_ticks\n2024-05-01T12:00:00.000,0,0\n");
        assert!(
            date.starts_with("log.csv:2:1:") && date.contains("t must be seconds"),
            "{date}"
        );
        assert!(err("t,left_ticks,right_ticks\n12:00:00.2,0,0\n").contains("t must be seconds"));
        assert!(err("t,left_ticks,right_ticks\n0,0,0\n").contains("need at least 2"));
    }
}
