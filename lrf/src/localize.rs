//! Localising a whole recording: scan files read and checked together, then every scan
//! localised (tracking, or each scan on its own) into a [`PoseLog`].

use std::path::PathBuf;

use nalgebra::{Matrix2, Matrix3, Vector2, Vector3};
use odocal_core::Pose2;

use crate::pose_fit::{fit_pose_weighted, mahalanobis2, pose_shift, Observation};
use crate::pose_log::{PoseLog, PoseLogRow};
use crate::scan::{read_scans_csv, Scan, SensorConfig};
use crate::scan_track::ScanTracker;
use crate::search::{Hypothesis, Localizer, Status};
use crate::LrfError;

/// Reads scan files; all must share one angular step (one sensor setting). Files with times
/// are taken in the order given, and each file's times must follow the previous file's, as
/// they do within a file. Files without times (one scan per file, say) are taken in natural
/// name order (`scan2.csv` before `scan10.csv`), the order a logger numbers them in: the
/// shell lists them alphabetically, `scan10.csv` between `scan1.csv` and `scan2.csv`, and
/// nothing else would show the scrambled time.
pub fn read_scan_files(paths: &[PathBuf]) -> Result<ScanFiles, LrfError> {
    for (k, p) in paths.iter().enumerate() {
        if let Some(q) = paths[..k].iter().find(|q| same_file(q, p)) {
            let also = if q == p {
                String::new()
            } else {
                format!(" (also as {})", q.display())
            };
            return Err(LrfError::Config(format!(
                "{} is given twice{also}; give each scan file once",
                p.display()
            )));
        }
    }
    let mut reversed: Option<(usize, &PathBuf)> = None;
    let mut files: Vec<(&PathBuf, Vec<Scan>)> = Vec::with_capacity(paths.len());
    let mut truncated_notes = Vec::new();
    for p in paths {
        let f = read_scans_csv(p)?;
        if let Some(line) = f.truncated_line {
            truncated_notes.push(format!(
                "{}: its last line ({line}) is cut short with no line end (a logger stopped while writing it) and was left out; the scan it belongs to is read without that beam",
                p.display()
            ));
        }
        if f.n_reversed > 0 {
            let (n, first) = reversed.unwrap_or((0, p));
            reversed = Some((n + f.n_reversed, first));
        }
        files.push((p, f.scans));
    }
    // Timed and untimed files have no common order: the untimed ones' poses would be put
    // among the timed ones' wherever they were given, times going backwards.
    let timed = files
        .iter()
        .find(|(_, s)| s.first().is_some_and(|s| s.t_s.is_some()));
    let untimed = files
        .iter()
        .find(|(_, s)| s.first().is_some_and(|s| s.t_s.is_none()));
    if let (Some((t, _)), Some((u, _))) = (timed, untimed) {
        return Err(LrfError::Config(format!(
            "{} has scan times (a t column) but {} has none; give all the scan files times, or none",
            t.display(),
            u.display()
        )));
    }
    // Files of timed scans go in the order of their times, whatever order a shell glob gave
    // them in (scan10.csv before scan2.csv); untimed ones in natural name order. Files whose
    // times interleave are refused below.
    if files.iter().all(|(_, s)| s.iter().all(|s| s.t_s.is_none())) {
        files.sort_by(|(a, _), (b, _)| odocal_core::natural_path_cmp(a, b));
    } else if files
        .iter()
        .all(|(_, s)| s.first().is_some_and(|s| s.t_s.is_some()))
    {
        files.sort_by(|(_, a), (_, b)| {
            let first = |s: &[Scan]| s.first().and_then(|s| s.t_s).unwrap_or(0.0);
            first(a).total_cmp(&first(b))
        });
    }
    let mut scans: Vec<Scan> = Vec::new();
    let mut step: Option<(f64, String)> = None;
    // The last timed scan so far and its file.
    let mut last: Option<(f64, &PathBuf)> = None;
    // Per file in the order taken: its path and how many scans it holds.
    let order: Vec<&PathBuf> = files.iter().map(|f| f.0).collect();
    let counts: Vec<usize> = files.iter().map(|f| f.1.len()).collect();
    for (p, s) in files {
        if let (Some((prev, prev_file)), Some(t)) = (last, s.first().and_then(|s| s.t_s)) {
            if t <= prev {
                // Sorted by their first times, files that still do not follow each other
                // overlap: both hold scans of the same stretch of time.
                let end = s.iter().rev().find_map(|s| s.t_s).unwrap_or(t);
                return Err(LrfError::Config(format!(
                    "{}: its scans from {t} s to {end} s overlap those of {}, which run to {prev} s: the two files hold scans of the same time (a recording split into files that overlap, or two recordings); give each scan once, cutting the overlap out of one file",
                    p.display(),
                    prev_file.display()
                )));
            }
        }
        if let Some(t) = s.iter().rev().find_map(|s| s.t_s) {
            last = Some((t, p));
        }
        let this = s.first().map_or(0.0, |s| s.step_rad());
        match &step {
            Some((st, first)) if (this - st).abs() > 0.01 * st.abs() => {
                return Err(LrfError::Config(format!(
                    "{}: angle step {this:.6} rad differs from {first}'s {st:.6} rad; mismatched angle steps — use scans of one sensor setting",
                    p.display()
                )))
            }
            Some(_) => {}
            None => step = Some((this, p.display().to_string())),
        }
        scans.extend(s);
    }
    // One scan per file without a `scan` column gives every scan the id 0: number them by
    // the numbers in the files' names when each file holds one untimed scan (a logger numbers
    // every scan it takes, so a number skipped is scans dropped, and the scans after it are
    // timed by their ids as such: timed by their order they were 0.5 s early after 5 files
    // missing), else in the order read, so the poses' `scan` column tells them apart.
    let mut ids: Vec<u64> = scans.iter().map(|s| s.id).collect();
    ids.sort_unstable();
    let mut numbered_by_name = false;
    if ids.windows(2).any(|w| w[0] == w[1]) {
        let by_name: Option<Vec<u64>> = (counts.iter().all(|&n| n == 1)
            && scans.iter().all(|s| s.t_s.is_none()))
        .then(|| order.iter().map(|p| number_in_name(p)).collect())
        .flatten();
        match by_name.filter(|n| n.windows(2).all(|w| w[0] < w[1])) {
            Some(numbers) => {
                numbered_by_name = true;
                for (s, n) in scans.iter_mut().zip(numbers) {
                    s.id = n;
                }
            }
            None => {
                for (k, s) in scans.iter_mut().enumerate() {
                    s.id = k as u64;
                }
            }
        }
    }
    // Angles are explicit, so a scan listed left to right is as good as one listed right to
    // left; the note says it was read so, once for the whole recording.
    let reversed_note = reversed.map(|(n, first)| {
        format!(
            "{n} of the {} scans (the first in {}) list their beams in decreasing angle order (a negative angle_increment); they were read in increasing order, each beam with its own angle",
            scans.len(),
            first.display()
        )
    });
    Ok(ScanFiles {
        scans,
        step_rad: step.map(|s| s.0),
        reversed_note,
        numbered_by_name,
        truncated_notes,
    })
}

/// The last number in a file's name (`scan14.csv`: 14), if it has one.
fn number_in_name(p: &std::path::Path) -> Option<u64> {
    let stem = p.file_stem()?.to_str()?;
    let end = stem.rfind(|c: char| c.is_ascii_digit())? + 1;
    let start = stem[..end]
        .rfind(|c: char| !c.is_ascii_digit())
        .map_or(0, |i| i + 1);
    stem[start..end].parse().ok()
}

/// Scans read from files by [`read_scan_files`].
#[derive(Debug, Clone, PartialEq)]
pub struct ScanFiles {
    /// The scans, in time order.
    pub scans: Vec<Scan>,
    /// Their common angle step, radians (None without scans).
    pub step_rad: Option<f64>,
    /// A note when scans listed their beams in decreasing angle order.
    pub reversed_note: Option<String>,
    /// The scans, one per file without ids, were numbered by the numbers in the files' names.
    pub numbered_by_name: bool,
    /// Per file whose last line was cut short and left out, a warning saying so.
    pub truncated_notes: Vec<String>,
}

/// A recording's scans may be logged sparser than the scanner sweeps (every few sweeps), but
/// not this many times sparser: scan times in milliseconds are a thousand times it.
const MAX_INTERVAL_PERIODS: f64 = 100.0;

/// A sweep at most this share longer than the median time between scans is taken for the
/// timing's jitter; beyond it, the scanner cannot have swept so slowly.
const SWEEP_SLACK: f64 = 1.1;

/// The scans' median time between scans may be this share off a whole number of scanner
/// periods and still be taken for that scanner's (timing jitter, a rate a little off its
/// nominal one): the sweep's time is then off by as much, which moved the poses little
/// (`synth lrf` seed 1, 300 scans re-timed: 10.5 Hz scans at --rate-hz 10 gave 1.04 and 1.23
/// times the bound against 0.97 and 1.04 at their rate, where 12.5 Hz scans gave 1.66 and 2.87).
const PERIOD_TOLERANCE: f64 = 0.05;

/// Refuses scans whose median time between scans is more than [`MAX_INTERVAL_PERIODS`] scan
/// periods at `sensor.rate_hz`: their times are not in seconds (milliseconds give a thousand
/// times the period), and a truth or a track in seconds would match almost none of them.
/// Refuses too scans closer together than a sweep of `sensor`: a scanner does not start a scan
/// before it ends the last, so its rate (or `sweep_s`) is not the scanner's, and the beams'
/// times with it were so wrong that de-skewing made confident poses up to 116 mm off (10 Hz
/// scans at --rate-hz 5). When the sweep follows from the rate (no `sweep_s`), scans whose
/// median spacing is not a whole number of periods (within [`PERIOD_TOLERANCE`]) are refused
/// as well: their scanner runs at another rate, and its sweep is another length (15 Hz scans
/// at --rate-hz 10 swept in 44 ms, not 67, and their poses were 3.6 times their bound off with
/// no word). Returns how many periods apart the scans are: 1, or more for a recording that
/// keeps every few scans (a throttled topic), whose sweep is the scanner's still; a scanner
/// that runs that many times slower cannot be told from it by the times.
pub fn check_scan_times(scans: &[Scan], sensor: &SensorConfig) -> Result<u32, LrfError> {
    let rate_hz = sensor.rate_hz;
    let t: Vec<f64> = scans.iter().filter_map(|s| s.t_s).collect();
    let mut dt: Vec<f64> = t.windows(2).map(|w| w[1] - w[0]).collect();
    if dt.is_empty() {
        return Ok(1);
    }
    dt.sort_by(f64::total_cmp);
    let median = dt[dt.len() / 2];
    let period = 1.0 / rate_hz;
    if median > MAX_INTERVAL_PERIODS * period {
        // The unit that brings the spacing nearest the scanner's period is the likely one:
        // ROS exports stamps in nanoseconds as often as in seconds.
        let (unit, abbr, per_s) = [
            ("milliseconds", "ms", 1e3),
            ("microseconds", "µs", 1e6),
            ("nanoseconds", "ns", 1e9),
        ]
        .into_iter()
        .min_by(|a, b| {
            let off = |per_s: f64| (median / per_s / period).ln().abs();
            off(a.2).total_cmp(&off(b.2))
        })
        .unwrap_or(("milliseconds", "ms", 1e3));
        let (m, p) = (six_digits(median), six_digits(period));
        return Err(LrfError::Config(format!(
            "the scans' median time between scans is {m} s, {:.0} times the scanner's period of {p} s at --rate-hz {rate_hz}: are the times in {unit}? Give t in seconds (if these are {unit}, {m} {abbr} is {} s), or the scanner's --rate-hz",
            median / period,
            six_digits(median / per_s)
        )));
    }
    let sweep_s = scans.first().map_or(0.0, |s| {
        sensor.beam_interval_s(s) * s.angles_rad.len().saturating_sub(1) as f64
    });
    if median > 0.0 && sweep_s > SWEEP_SLACK * median {
        let (m, sw) = (six_digits(median), six_digits(sweep_s));
        let given = match sensor.sweep_s {
            Some(_) => format!("--sweep-s {sw}"),
            None => format!(
                "a sweep of {sw} s (their {:.0}° at --rate-hz {rate_hz})",
                (sweep_s * rate_hz * 360.0)
            ),
        };
        return Err(LrfError::Config(format!(
            "the scans are {m} s apart (median), less than {given}, but a scanner does not start a scan before it ends the last: give the scanner's real --rate-hz (these scans come at {} Hz){}",
            six_digits(1.0 / median),
            if sensor.sweep_s.is_some() {
                " and --sweep-s at most the time between its scans"
            } else {
                ""
            }
        )));
    }
    let periods = median * rate_hz;
    let whole = periods.round().max(1.0);
    if sensor.sweep_s.is_none() && median > 0.0 && (periods / whole - 1.0).abs() > PERIOD_TOLERANCE
    {
        return Err(LrfError::Config(format!(
            "the scans are {} s apart (median), {periods:.2} times the period of {} s at --rate-hz {rate_hz} and not a whole number of periods: the scanner runs at another rate, and sweeps in another time than its beams would be given; give the scanner's real --rate-hz {} (or a whole multiple of it if the recording keeps every few of its scans), or the time from its first beam to its last with --sweep-s",
            six_digits(median),
            six_digits(period),
            significant(1.0 / median, 3)
        )));
    }
    Ok(whole as u32)
}

/// `x` rounded to six significant digits, shortest form: a difference of two times carries
/// the float's noise in its last digits (0.10000000000000009 for 0.1).
fn six_digits(x: f64) -> String {
    significant(x, 6)
}

/// `x` rounded to `digits` significant digits, shortest form.
fn significant(x: f64, digits: i32) -> String {
    if x == 0.0 || !x.is_finite() {
        return x.to_string();
    }
    let scale = 10f64.powi(digits - 1 - x.abs().log10().floor() as i32);
    ((x * scale).round() / scale).to_string()
}

/// True if `a` and `b` name one file (the same path, or two paths to it).
fn same_file(a: &std::path::Path, b: &std::path::Path) -> bool {
    match (a.canonicalize(), b.canonicalize()) {
        (Ok(a), Ok(b)) => a == b,
        _ => a == b,
    }
}

/// Refuses scans whose returns mostly lie beyond twice the scanner's `max_range_m`: their
/// ranges are in another unit (millimetres or centimetres), and every return would be
/// dropped as out of range, leaving every scan lost with nothing said.
pub fn check_range_unit(scans: &[Scan], max_range_m: f64) -> Result<(), LrfError> {
    let mut ranges: Vec<f64> = scans
        .iter()
        .flat_map(|s| s.ranges_m.iter().copied())
        .filter(|r| *r > 0.0 && r.is_finite())
        .collect();
    if ranges.is_empty() {
        return Ok(());
    }
    ranges.sort_by(f64::total_cmp);
    let median = ranges[ranges.len() / 2];
    if median > 2.0 * max_range_m {
        // The unit that brings the median inside the scanner's range is the likely one; a
        // median that no unit makes a room's distance is a --max-range-m too short.
        let (unit, per_m) = if median / 100.0 <= max_range_m {
            ("centimetres", 100.0)
        } else {
            ("millimetres", 1000.0)
        };
        let in_unit_m = median / per_m;
        if in_unit_m < MIN_MEDIAN_RANGE_M {
            return Err(LrfError::Config(format!(
                "the scans' median range is {median:.3} m, beyond twice --max-range-m {max_range_m} m, so most returns would be dropped as out of range: give the scanner's real --max-range-m (its data sheet's range)"
            )));
        }
        return Err(LrfError::Config(format!(
            "the scans' median range is {median:.3} (read as metres) against --max-range-m {max_range_m} m: ranges are in metres (if these are {unit}, {median:.3} is {in_unit_m:.3} m); give ranges in metres, or the scanner's real --max-range-m"
        )));
    }
    Ok(())
}

/// The shortest median range a scan of a room has, metres: a unit that makes the median
/// shorter is not the scans' unit.
const MIN_MEDIAN_RANGE_M: f64 = 0.2;

/// Refuses a field of view the scans' beams exceed (by more than a beam step): the view's
/// edges decide which landmarks a scan should have seen, and `--fov-deg 4.19` (240° typed in
/// radians) was taken with a 240° scan.
pub fn check_fov(scans: &[Scan], sensor: &SensorConfig) -> Result<(), LrfError> {
    let widest = scans
        .iter()
        .filter(|s| s.angles_rad.len() > 1)
        .map(|s| {
            let span = (s.angles_rad[s.angles_rad.len() - 1] - s.angles_rad[0]).abs();
            (span, span / (s.angles_rad.len() - 1) as f64)
        })
        .fold((0.0, 0.0), |a: (f64, f64), b| if b.0 > a.0 { b } else { a });
    let (span_rad, step_rad) = widest;
    if span_rad <= sensor.fov_rad + 1.5 * step_rad {
        return Ok(());
    }
    // Back from radians as the user typed it: 240, not 239.99999999999997.
    let fov_deg = six_digits(sensor.fov_rad.to_degrees());
    let as_radians = if sensor.fov_rad.to_degrees() <= std::f64::consts::TAU {
        format!(
            " (if {fov_deg} is in radians, it is {:.1}°)",
            sensor.fov_rad.to_degrees().to_degrees()
        )
    } else {
        String::new()
    };
    Err(LrfError::Config(format!(
        "--fov-deg {fov_deg}: the scans' beams span {:.1}°, wider than the field of view given{as_radians}; give the scanner's field of view in degrees, --fov-deg {:.0}",
        span_rad.to_degrees(),
        (span_rad + step_rad).to_degrees()
    )))
}

/// Turns every range at or beyond the scanner's `max_range_m` into 0, "no return": ROS's
/// LaserScan says a range outside [range_min, range_max] is to be discarded, and Gazebo and
/// many drivers write a beam without an echo as range_max itself (or a sentinel such as
/// 65.535). Read as returns, such beams went through the walls and made the right pose look
/// wrong: with 10 % of the beams so written, 198 (range_max) and 282 (65.535) of 300 scans
/// were lost. Call it after [`check_range_unit`], which must see the ranges as written.
pub fn drop_beyond_range(scans: &mut [Scan], max_range_m: f64) {
    for r in scans.iter_mut().flat_map(|s| s.ranges_m.iter_mut()) {
        if *r >= max_range_m {
            *r = 0.0;
        }
    }
}

/// Reflectors are narrow: even a room full of them gives a few percent of a scan's returns
/// (about 4 % in odocal's synthetic room). A threshold passed by more than this share of
/// the returns does not tell reflectors from walls.
const MAX_REFLECTOR_SHARE: f64 = 0.5;

/// Scans whose every range lies within this many metres are of no room: with intensities
/// beside them that spread like distances, the columns are swapped.
const MAX_SWAPPED_RANGE_M: f64 = 1.0;

/// Refuses scans whose returns mostly reach `sensor.intensity_min`: their intensities are on
/// another scale (0–255, or a scanner's raw counts, against the default 0.5 of a 0–1 scale),
/// and every wall would be taken for a reflector, leaving almost every scan lost. Refuses too
/// scans none of whose returns reach it (every intensity 0: a scanner that does not record
/// them; or a threshold above the scale), which lost every scan and were blamed on the map, and
/// scans whose range and intensity columns look swapped.
pub fn check_intensity_scale(scans: &[Scan], sensor: &SensorConfig) -> Result<(), LrfError> {
    let mut returns: Vec<f64> = scans
        .iter()
        .flat_map(|s| s.ranges_m.iter().zip(&s.intensities))
        .filter(|(r, i)| **r >= sensor.min_range_m && **r <= sensor.max_range_m && i.is_finite())
        .map(|(_, i)| *i)
        .collect();
    if returns.is_empty() {
        return Ok(());
    }
    returns.sort_by(f64::total_cmp);
    let median = returns[returns.len() / 2];
    let top = returns[(returns.len() * 99 / 100).min(returns.len() - 1)];
    let brightest = returns[returns.len() - 1];
    // Ranges that all lie within a metre beside "intensities" that spread like a room's
    // distances: the two columns were swapped, and the threshold asked for below would be a
    // typical range.
    let longest = scans
        .iter()
        .flat_map(|s| s.ranges_m.iter().copied())
        .filter(|r| r.is_finite())
        .fold(0.0, f64::max);
    if longest <= MAX_SWAPPED_RANGE_M && median >= MIN_MEDIAN_RANGE_M && median > longest {
        return Err(LrfError::Config(format!(
            "every range of the scans lies within {longest:.3} m, and their intensities spread like a room's distances (median {median}, up to {brightest}): are the range and intensity columns swapped? Put the ranges (metres) under the header's `range` and the returns' intensities under its `intensity`"
        )));
    }
    let bright = returns
        .iter()
        .filter(|i| **i >= sensor.intensity_min)
        .count();
    // No return bright enough: every scan would be lost, and read as a map of another room.
    if bright == 0 {
        if brightest == 0.0 {
            return Err(LrfError::Config(format!(
                "every intensity of the scans' {} returns is 0, so no return reaches --intensity-min {} and no reflector can be told from a wall: does the scanner record intensity? Record the scans with their intensities (some drivers publish them only when a parameter asks for them)",
                returns.len(),
                sensor.intensity_min
            )));
        }
        return Err(LrfError::Config(format!(
            "no return of the scans reaches --intensity-min {} (median return {median}, the brightest 1 % from {top}, the brightest {brightest}), so no reflector can be found: give --intensity-min on the scanner's intensity scale, between the walls' returns and the reflectors' (halfway between the median and the brightest 1 %: {})",
            sensor.intensity_min,
            (median + top) / 2.0
        )));
    }
    let share = bright as f64 / returns.len() as f64;
    if share <= MAX_REFLECTOR_SHARE {
        return Ok(());
    }
    Err(LrfError::Config(format!(
        "{:.0} % of the scans' returns are at or above --intensity-min {} (median return {median}, the brightest 1 % from {top}), but reflectors give a few percent of a scan: the threshold does not tell them from walls; give --intensity-min on the scanner's intensity scale, between the walls' returns and the reflectors' (halfway between those two: {})",
        share * 100.0,
        sensor.intensity_min,
        (median + top) / 2.0
    )))
}

/// A reflector hit by fewer beams than this (head-on, at the median range of the detections)
/// is placed along its strip only within a beam spacing, and a glint beside a landmark fits
/// in that slack: with every 4th beam of the default scanner (1.4°, 1.1 beams at 3 m), a
/// glint matched to a landmark 18 cm off gave a pose 14 cm off with a σ of 9 mm.
const MIN_BEAMS_PER_REFLECTOR: f64 = 2.0;

/// A warning when the scans' angle step is too coarse for the map's reflectors at the ranges
/// they are detected at (fewer than [`MIN_BEAMS_PER_REFLECTOR`] beams across one), saying
/// what step or reflector width would do; None when it is fine or nothing was detected.
pub fn check_beam_step(loc: &Localizer, scans: &[Scan]) -> Option<String> {
    let mut ranges: Vec<f64> = scans
        .iter()
        .flat_map(|s| loc.detections(s))
        .map(|d| d.range_m)
        .collect();
    if ranges.is_empty() {
        return None;
    }
    ranges.sort_by(f64::total_cmp);
    let range_m = ranges[ranges.len() / 2];
    let step_rad = loc.cfg.sensor.step_rad;
    let width_m = loc.map.reflector_width_m;
    let beams = width_m / (range_m * step_rad);
    (beams < MIN_BEAMS_PER_REFLECTOR).then(|| {
        format!(
            "the scans' angle step of {:.2}° puts beams {:.0} mm apart at the reflectors' median range of {range_m:.1} m, so a {:.0} mm reflector is hit by {beams:.1} beams: each is placed along its strip only within a beam spacing, so poses are less precise (their σ says by how much) and more scans are ambiguous or lost; record every beam the scanner has (an angle step of at most {:.2}° for these ranges), or use reflectors at least {:.0} mm wide",
            step_rad.to_degrees(),
            range_m * step_rad * 1e3,
            width_m * 1e3,
            (width_m / (MIN_BEAMS_PER_REFLECTOR * range_m)).to_degrees(),
            MIN_BEAMS_PER_REFLECTOR * range_m * step_rad * 1e3
        )
    })
}

/// Localises every scan: with the tracker (prediction from the previous poses, global search
/// as the fallback; the detections de-skewed with the tracked motion), or with `global_only`
/// each scan on its own. Scans without a time stamp are timed by [`untimed_times`]. A pose
/// refers to its scan's time, the first beam's. `on_scan` is called after each scan (for a
/// progress bar).
///
/// Landmarks moved since the map was made ([`MovedLandmark`]) are found from the poses'
/// residuals, and then every scan is localised again with a map without them: a moved
/// landmark does not only pull the poses that match it, it steers the tracking (the
/// associations, the motion the sweeps are de-skewed with), so poses fitted again from the
/// first pass's matches stayed up to 37 mm (6.6σ) off. A scan the second pass leaves without
/// a pose keeps the first pass's, its σ widened by what the moved landmarks' offsets did to it.
pub fn localize_scans(
    loc: &Localizer,
    scans: &[Scan],
    rate_hz: f64,
    global_only: bool,
    on_scan: &dyn Fn(),
) -> Localized {
    let first = localize_pass(loc, scans, rate_hz, global_only, on_scan);
    let Some(before) = systematic(loc, &first.log, &first.fitted, &[]).filter(calls_for_correction)
    else {
        return finish_passes(loc, scans, rate_hz, global_only, first);
    };
    // Fitted again after each correction: the gates dropped the matches the bias pushed
    // farthest, so one fit finds most of it (17 of 20 mm), not all.
    let (mut offset_m, mut scale) = (0.0, 1.0);
    let mut step = before;
    let mut best: Option<(Localizer, Vec<Scan>, Pass, Systematic)> = None;
    for _ in 0..MAX_CORRECTIONS {
        offset_m += step.range_offset_m.0;
        scale *= 1.0 + step.angle_scale.0;
        let corrected: Vec<Scan> = scans.iter().map(|s| s.corrected(offset_m, scale)).collect();
        let mut cfg = loc.cfg;
        cfg.sensor.step_rad /= scale;
        let again = Localizer::new(loc.map.clone(), cfg);
        let pass = localize_pass(&again, &corrected, rate_hz, global_only, &|| {});
        let Some(after) = systematic(&again, &pass.log, &pass.fitted, &[]) else {
            break;
        };
        // Once found, a bias is taken out while it is still significant, however little the
        // χ² shows of what is left.
        let more = bias_significant(&after);
        step = after;
        best = Some((again, corrected, pass, after));
        if !more {
            break;
        }
    }
    match best {
        Some((again, corrected, pass, after)) if after.ratio < CORRECTION_GAIN * before.ratio => {
            let mut out = finish_passes(&again, &corrected, rate_hz, global_only, pass);
            out.calibration = Some(Calibration {
                range_offset_m: offset_m,
                angle_scale: scale,
                ratio_before: before.ratio,
                ratio_after: after.ratio,
                residual: after,
            });
            out
        }
        _ => finish_passes(loc, scans, rate_hz, global_only, first),
    }
}

/// A range offset or angle scale is corrected only when the fit is this many standard errors
/// from none...
const SYSTEMATIC_SIGMAS: f64 = 6.0;
/// ... and the recording's residuals exceed the detections' noise by this factor (χ² over its
/// degrees of freedom; about 1.0 for the synthetic recordings).
const SYSTEMATIC_RATIO: f64 = 1.3;
/// ... and it is larger than this, metres (range) and parts (angle scale): below these the
/// poses move by less than their noise.
const MIN_RANGE_OFFSET_M: f64 = 0.001;
const MIN_ANGLE_SCALE: f64 = 2e-4;
/// Corrections fitted one after the other at most.
const MAX_CORRECTIONS: usize = 3;
/// The corrected scans are taken only if their χ² over its degrees of freedom is below this
/// share of the scans' as given.
const CORRECTION_GAIN: f64 = 0.8;

/// True if the residuals call for a range offset or angle scale (see [`SYSTEMATIC_SIGMAS`]).
fn calls_for_correction(s: &Systematic) -> bool {
    s.ratio > SYSTEMATIC_RATIO && bias_significant(s)
}

/// True if the range offset or the angle scale of `s` is beyond its noise and large enough to
/// matter.
fn bias_significant(s: &Systematic) -> bool {
    let (b, sb) = s.range_offset_m;
    let (k, sk) = s.angle_scale;
    (b.abs() > SYSTEMATIC_SIGMAS * sb && b.abs() > MIN_RANGE_OFFSET_M)
        || (k.abs() > SYSTEMATIC_SIGMAS * sk && k.abs() > MIN_ANGLE_SCALE)
}

/// A range offset and angle scale found in the scans and taken out of them before they were
/// localised ([`localize_scans`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Calibration {
    /// The ranges read this much long, metres; subtracted from every range.
    pub range_offset_m: f64,
    /// The angles read this many times the true ones; every angle divided by it.
    pub angle_scale: f64,
    /// The recording's χ² over its degrees of freedom before the correction ...
    pub ratio_before: f64,
    /// ... and after it.
    pub ratio_after: f64,
    /// What the corrected scans' residuals still show.
    pub residual: Systematic,
}

/// The rest of [`localize_scans`] once `first` is localised: moved landmarks found, and the
/// scans localised again without them.
fn finish_passes(
    loc: &Localizer,
    scans: &[Scan],
    rate_hz: f64,
    global_only: bool,
    mut first: Pass,
) -> Localized {
    let (mut moved, kept) = moved_landmarks(loc, &mut first.log, &first.fitted, &first.deskewed);
    let ids: Vec<u32> = moved.iter().map(|m| m.id).collect();
    let again = loc
        .map
        .without(&ids)
        .filter(|_| !ids.is_empty())
        .map(|map| Localizer::new(map, loc.cfg));
    let Some(again) = again else {
        widen_kept(loc, &mut first.log, &first.fitted, &kept, &moved);
        return first.localized(loc, moved);
    };
    let mut second = localize_pass(&again, scans, rate_hz, global_only, &|| {});
    // A landmark moved by less than the others hid behind their pull.
    let (more, kept_again) =
        moved_landmarks(&again, &mut second.log, &second.fitted, &second.deskewed);
    widen_kept(&again, &mut second.log, &second.fitted, &kept_again, &more);
    // The first pass's poses were pulled towards the moved landmarks, and their residuals with
    // them (38 mm for reflectors moved 50): measured at the second pass's poses, the offsets
    // are the landmarks' own.
    let moved_idx: Vec<usize> = moved
        .iter()
        .filter_map(|m| loc.map.landmarks.iter().position(|x| x.id == m.id))
        .collect();
    for m in &mut moved {
        let l = loc.map.landmarks.iter().position(|x| x.id == m.id);
        if let Some(better) = l.and_then(|l| {
            residual_mean(
                loc,
                &second.log,
                &first.fitted,
                &second.deskewed,
                l,
                &moved_idx,
            )
        }) {
            *m = better;
        }
    }
    widen_kept(loc, &mut first.log, &first.fitted, &kept, &moved);
    let ok = |r: &PoseLogRow| r.status == Status::Ok && r.pose.is_some();
    for k in 0..second.log.rows.len() {
        if !ok(&second.log.rows[k]) && ok(&first.log.rows[k]) {
            second.log.rows[k] = first.log.rows[k].clone();
            second.deskewed[k] = first.deskewed[k];
        }
    }
    let all: Vec<MovedLandmark> = moved.iter().chain(&more).cloned().collect();
    let mut out = second.localized(&again, more);
    out.moved = all;
    out
}

/// The landmarks the fits of `log`'s `ok` poses left out (`left_out`: row, landmark,
/// observation) in [`MIN_BIAS_SCANS`] scans or more, at least as often as they used them
/// (`fitted`), with their residuals' mean beyond [`MIN_BIAS_SIGMAS`] standard errors and
/// [`MIN_BIAS_MAP_SIGMAS`] of the map's σ: detected off their place every time, too far for
/// the fit to take (a reflector moved 5 cm was left out of every pose, and named nowhere).
fn left_out_landmarks(
    loc: &Localizer,
    log: &PoseLog,
    fitted: &[(usize, usize, Observation)],
    left_out: &[(usize, usize, Observation)],
) -> Vec<MovedLandmark> {
    let map_sigma_m = loc.map.position_sigma_m.unwrap_or(loc.cfg.map_sigma_m);
    let ok = |k: usize| log.rows[k].status == Status::Ok;
    let mut out = Vec::new();
    for l in 0..loc.map.landmarks.len() {
        let r: Vec<(Pose2, Vector2<f64>)> = left_out
            .iter()
            .filter(|f| f.1 == l && ok(f.0))
            .filter_map(|(k, _, o)| {
                let p = log.rows[*k].pose?;
                Some((p, p.isometry() * o.sensor - o.landmark))
            })
            .collect();
        let n = r.len();
        let used = fitted.iter().filter(|f| f.1 == l && ok(f.0)).count();
        if n < MIN_BIAS_SCANS || n < used {
            continue;
        }
        let mean = r.iter().map(|x| x.1).sum::<Vector2<f64>>() / n as f64;
        let Some(dir) = mean.try_normalize(0.0) else {
            continue;
        };
        let var = r
            .iter()
            .map(|x| (x.1 - mean).dot(&dir).powi(2))
            .sum::<f64>()
            / ((n - 1) as f64 * n as f64);
        let sigma_m = var.sqrt();
        let d = mean.norm();
        if d > MIN_BIAS_SIGMAS * sigma_m && d > MIN_BIAS_MAP_SIGMAS * map_sigma_m {
            let mut places: Vec<Pose2> = Vec::new();
            for (p, _) in &r {
                if !places
                    .iter()
                    .any(|q| (p.x_m - q.x_m).hypot(p.y_m - q.y_m) <= PLACE_M)
                {
                    places.push(*p);
                }
            }
            out.push(MovedLandmark {
                id: loc.map.landmarks[l].id,
                offset_m: mean,
                sigma_m,
                n_scans: n,
                n_places: places.len(),
            });
        }
    }
    out
}

/// Between two scans a small robot's speed and turn rate change by at most this much per
/// second squared (m/s², rad/s²): a pose may lie off the midpoint of its neighbours' by half
/// that times the scan period squared. `synth lrf` accelerates by less than 0.5 m/s² and
/// 0.2 rad/s².
const TRACK_ACCEL_M_S2: f64 = 2.0;
const TRACK_ACCEL_RAD_S2: f64 = 2.0;

/// A pose off the track by more than this Mahalanobis distance (x, y, θ) is off it.
const OFF_TRACK_SIGMAS: f64 = 5.0;

/// Widens the σ of every `ok` pose off the track its two `ok` neighbours give (their
/// interpolation at its time) by more than [`OFF_TRACK_SIGMAS`] of their σ and the robot's
/// acceleration, by how far off it is; returns how many. Three landmarks fit by a glint in
/// place of one of them fit as well as the right three, and a pose 88 mm off kept its σ of
/// 7 mm (11.5σ) while the scans either side agreed with each other. A pose off the track
/// pulls its neighbours' tests by half as much: only the one farthest off among them is taken.
fn widen_off_track(log: &mut PoseLog) -> usize {
    let rows = &log.rows;
    let ok = |r: &PoseLogRow| r.status == Status::Ok && r.pose.is_some() && r.pose_cov.is_some();
    // Per row, the nearest `ok` rows before and after it (a lost scan between them is no
    // reason to leave a pose unjudged).
    let (mut before, mut after) = (vec![None; rows.len()], vec![None; rows.len()]);
    for k in 1..rows.len() {
        before[k] = if ok(&rows[k - 1]) {
            Some(k - 1)
        } else {
            before[k - 1]
        };
    }
    for k in (0..rows.len().saturating_sub(1)).rev() {
        after[k] = if ok(&rows[k + 1]) {
            Some(k + 1)
        } else {
            after[k + 1]
        };
    }
    let off: Vec<Option<(f64, Vector3<f64>)>> = (0..rows.len())
        .map(|k| {
            let (a, r, b) = (&rows[before[k]?], &rows[k], &rows[after[k]?]);
            if !ok(r) {
                return None;
            }
            let (pa, p, pb) = (a.pose?, r.pose?, b.pose?);
            let span = b.t_s - a.t_s;
            if !(span > 1e-6 && span <= MAX_CENTRED_SPAN_S) {
                return None;
            }
            let w = (r.t_s - a.t_s) / span;
            let turn = odocal_core::wrap_angle(pb.theta_rad - pa.theta_rad);
            let d = Vector3::new(
                p.x_m - (pa.x_m + w * (pb.x_m - pa.x_m)),
                p.y_m - (pa.y_m + w * (pb.y_m - pa.y_m)),
                odocal_core::wrap_angle(p.theta_rad - (pa.theta_rad + w * turn)),
            );
            let dt2 = (r.t_s - a.t_s) * (b.t_s - r.t_s);
            let (sp, sh) = (0.5 * TRACK_ACCEL_M_S2 * dt2, 0.5 * TRACK_ACCEL_RAD_S2 * dt2);
            let cov = r.pose_cov?
                + a.pose_cov? * (1.0 - w).powi(2)
                + b.pose_cov? * (w * w)
                + Matrix3::from_diagonal(&Vector3::new(sp * sp, sp * sp, sh * sh));
            let z2 = d.dot(&(cov.try_inverse()? * d));
            Some((z2, d))
        })
        .collect();
    let mut n = 0;
    for k in 0..log.rows.len() {
        let Some((z2, d)) = off[k] else { continue };
        let beside = |i: Option<usize>| i.and_then(|i| off[i]).map_or(0.0, |x| x.0);
        if z2 <= OFF_TRACK_SIGMAS.powi(2) || z2 < beside(before[k]) || z2 < beside(after[k]) {
            continue;
        }
        if let Some(cov) = log.rows[k].pose_cov.as_mut() {
            *cov += d * d.transpose();
            n += 1;
        }
    }
    n
}

/// A pose's χ² beyond this quantile of its distribution is more than its detections' noise:
/// the standard normal quantile of 99 %.
const INCONSISTENT_Z: f64 = 2.326;

/// The quantile of the χ² distribution with `dof` degrees of freedom whose standard normal
/// quantile is `z` (Wilson–Hilferty: within a few percent from 1 degree of freedom on).
fn chi2_quantile(dof: f64, z: f64) -> f64 {
    let a = 2.0 / (9.0 * dof);
    dof * (1.0 - a + z * a.sqrt()).powi(3)
}

/// Judges every `ok` pose of `fitted` by the χ² of its matches (those of landmarks not in
/// `skip`) at its pose. A pose whose χ² lies beyond its 99 % quantile fits its landmarks
/// worse than their noise explains, and its Cramér–Rao σ does not hold: its covariance is
/// scaled by the χ² over its degrees of freedom, and the spread of the poses fitted with each
/// match left out is added (one landmark off its place pulls the pose by about as much as
/// leaving it out moves it).
fn judge_fits(
    loc: &Localizer,
    log: &mut PoseLog,
    fitted: &[(usize, usize, Observation)],
    skip: &[u32],
) -> FitQuality {
    let mut q = FitQuality::default();
    let (mut chi2_sum, mut dof_sum) = (0.0, 0.0);
    for_each_row(fitted, |k, row| {
        let r = &mut log.rows[k];
        let Some(pose) = r.pose.filter(|_| r.status == Status::Ok) else {
            return;
        };
        let obs: Vec<Observation> = row
            .iter()
            .filter(|(_, l, _)| !skip.contains(&loc.map.landmarks[*l].id))
            .map(|(_, _, o)| *o)
            .collect();
        if obs.len() < 2 {
            return;
        }
        let Some(chi2) = obs
            .iter()
            .map(|o| mahalanobis2(&pose, o))
            .sum::<Option<f64>>()
        else {
            return;
        };
        let dof = (2 * obs.len() - 3) as f64;
        q.n_poses += 1;
        chi2_sum += chi2;
        dof_sum += dof;
        if chi2 <= chi2_quantile(dof, INCONSISTENT_Z) {
            return;
        }
        let mut spread = Matrix3::zeros();
        for i in 0..obs.len() {
            let mut rest = obs.clone();
            rest.remove(i);
            if let Some((p, _)) = fit_pose_weighted(pose, &rest) {
                let dp = Vector3::new(
                    p.x_m - pose.x_m,
                    p.y_m - pose.y_m,
                    odocal_core::wrap_angle(p.theta_rad - pose.theta_rad),
                );
                spread += dp * dp.transpose();
            }
        }
        if let Some(cov) = r.pose_cov.as_mut() {
            *cov = *cov * (chi2 / dof) + spread;
            q.n_widened += 1;
        }
    });
    if dof_sum > 0.0 {
        q.ratio = chi2_sum / dof_sum;
    }
    q
}

/// A range offset and an angle scale common to every scan, fitted with the poses to the
/// matches of `fitted` at the `ok` poses of `log` (one Gauss–Newton step from none, the poses
/// eliminated scan by scan), with the recording's χ² over its degrees of freedom: a scanner
/// whose ranges read long or whose angle step is not the one logged leaves every landmark's
/// residuals off alike, and no landmark moved.
fn systematic(
    loc: &Localizer,
    log: &PoseLog,
    fitted: &[(usize, usize, Observation)],
    skip: &[u32],
) -> Option<Systematic> {
    let (mut s, mut t) = (Matrix2::zeros(), Vector2::zeros());
    let (mut chi2_sum, mut dof_sum) = (0.0, 0.0);
    for_each_row(fitted, |k, row| {
        let r = &log.rows[k];
        let Some(pose) = r.pose.filter(|_| r.status == Status::Ok) else {
            return;
        };
        let obs: Vec<&Observation> = row
            .iter()
            .filter(|(_, l, _)| !skip.contains(&loc.map.landmarks[*l].id))
            .map(|(_, _, o)| o)
            .collect();
        if obs.len() < 2 {
            return;
        }
        let inv = pose.isometry().inverse();
        let m = *nalgebra::Rotation2::new(-pose.theta_rad).matrix();
        let (mut hpp, mut hpg, mut hgg) = (
            Matrix3::zeros(),
            nalgebra::Matrix3x2::zeros(),
            Matrix2::zeros(),
        );
        let (mut bp, mut bg) = (Vector3::zeros(), Vector2::zeros());
        let mut chi2 = 0.0;
        for o in &obs {
            let Some(w) = o.cov.try_inverse() else {
                return;
            };
            // The detection predicted from the pose, sensor frame, and its derivatives by the
            // pose (x, y, θ) and by the range offset and the angle scale less 1.
            let h = inv * o.landmark;
            let range = h.coords.norm();
            let u = h.coords / range;
            let v = Vector2::new(-u.y, u.x);
            let e = o.sensor - h;
            let jp =
                nalgebra::Matrix2x3::new(-m[(0, 0)], -m[(0, 1)], h.y, -m[(1, 0)], -m[(1, 1)], -h.x);
            let jg = Matrix2::from_columns(&[u, v * (range * h.y.atan2(h.x))]);
            hpp += jp.transpose() * w * jp;
            hpg += jp.transpose() * w * jg;
            hgg += jg.transpose() * w * jg;
            bp += jp.transpose() * w * e;
            bg += jg.transpose() * w * e;
            chi2 += e.dot(&(w * e));
        }
        let Some(hpp_inv) = hpp.try_inverse() else {
            return;
        };
        s += hgg - hpg.transpose() * hpp_inv * hpg;
        t += bg - hpg.transpose() * hpp_inv * bp;
        chi2_sum += chi2;
        dof_sum += (2 * obs.len() - 3) as f64;
    });
    if dof_sum <= 0.0 {
        return None;
    }
    let ratio = chi2_sum / dof_sum;
    let s_inv = s.try_inverse()?;
    let g = s_inv * t;
    let cov = s_inv * ratio.max(1.0);
    Some(Systematic {
        ratio,
        range_offset_m: (g.x, cov[(0, 0)].sqrt()),
        angle_scale: (g.y, cov[(1, 1)].sqrt()),
    })
}

/// See [`systematic`].
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Systematic {
    /// The recording's χ² over its degrees of freedom (about 1 when the residuals are the
    /// detections' noise).
    pub ratio: f64,
    /// The range offset (ranges read this much long), metres, and its standard error.
    pub range_offset_m: (f64, f64),
    /// The angle scale less 1 (angles read 1 + this times the true ones), and its standard
    /// error.
    pub angle_scale: (f64, f64),
}

/// One pass of [`localize_scans`] over the scans, before moved landmarks are looked for.
struct Pass {
    log: PoseLog,
    /// Per row: its scan was de-skewed with a tracked motion.
    deskewed: Vec<bool>,
    /// Per row: its scan's sweep, seconds.
    sweeps_s: Vec<f64>,
    /// The matches of every `ok` pose, (row, landmark, observation), by row.
    fitted: Vec<(usize, usize, Observation)>,
    /// The matches its fit left out as beyond their noise, (row, landmark, observation).
    left_out: Vec<(usize, usize, Observation)>,
    n_repeated: usize,
    unseen: Vec<(u32, usize, usize)>,
    dim: Vec<(u32, usize, f64)>,
}

impl Pass {
    /// The pass's poses, with the σ of those left with their sweep's skew widened.
    fn localized(mut self, loc: &Localizer, moved: Vec<MovedLandmark>) -> Localized {
        let n_unsupported = drop_unsupported(&mut self.log);
        let skip: Vec<u32> = moved.iter().map(|m| m.id).collect();
        let fit = judge_fits(loc, &mut self.log, &self.fitted, &skip);
        let left_out = left_out_landmarks(loc, &self.log, &self.fitted, &self.left_out);
        let n_off_track = widen_off_track(&mut self.log);
        let skewed = widen_skewed(&mut self.log, &self.deskewed, &self.sweeps_s);
        Localized {
            log: self.log,
            skewed,
            n_repeated: self.n_repeated,
            unseen: self.unseen,
            dim: self.dim,
            moved,
            n_unsupported,
            fit,
            calibration: None,
            left_out,
            n_off_track,
        }
    }
}

/// Every scan localised against `loc`'s map as it is (see [`localize_scans`]).
fn localize_pass(
    loc: &Localizer,
    scans: &[Scan],
    rate_hz: f64,
    global_only: bool,
    on_scan: &dyn Fn(),
) -> Pass {
    let mut tracker = ScanTracker::new(loc);
    let mut rows = Vec::with_capacity(scans.len());
    let mut deskewed = Vec::with_capacity(scans.len());
    let mut sweeps_s = Vec::with_capacity(scans.len());
    let mut n_repeated = 0;
    let mut views = LandmarkViews::new(loc.map.landmarks.len());
    // The matches of every `ok` pose, (row, landmark, observation).
    let mut fitted: Vec<(usize, usize, Observation)> = Vec::new();
    let mut left_out: Vec<(usize, usize, Observation)> = Vec::new();
    let untimed = untimed_times(scans, rate_hz);
    for (k, scan) in scans.iter().enumerate() {
        let t_s = scan.t_s.unwrap_or(untimed[k]);
        sweeps_s.push(
            loc.cfg.sensor.beam_interval_s(scan) * scan.angles_rad.len().saturating_sub(1) as f64,
        );
        let row = if k > 0 && repeats(&scans[k - 1], scan) {
            n_repeated += 1;
            deskewed.push(false);
            PoseLogRow {
                t_s,
                pose: None,
                status: Status::Lost,
                n_landmarks: 0,
                n_detections: 0,
                n_hypotheses: 0,
                score: 0.0,
                mode: "repeated".into(),
                scan: scan.id,
                pose_cov: None,
            }
        } else if global_only {
            let dets = loc.detections(scan);
            let g = loc.global(scan, &dets);
            views.add(loc, scan, &g.hypotheses);
            let b = g.best();
            if let (Status::Ok, Some(h)) = (g.status, b) {
                add_fitted(&mut fitted, k, h);
                left_out.extend(h.outliers.iter().map(|(l, o)| (k, *l, *o)));
            }
            deskewed.push(false);
            PoseLogRow {
                t_s,
                pose: b.map(|h| h.pose),
                status: g.status,
                n_landmarks: b.map_or(0, |h| h.matches.len()),
                n_detections: dets.len(),
                n_hypotheses: g.hypotheses.len(),
                score: b.map_or(0.0, |h| h.score),
                mode: "global".into(),
                scan: scan.id,
                pose_cov: b.and_then(|h| h.cov),
            }
        } else {
            let r = tracker.process(scan, t_s);
            views.add(loc, scan, &r.hypotheses);
            deskewed.push(r.deskewed);
            if let (Status::Ok, Some(h)) = (r.status, r.hypotheses.first()) {
                add_fitted(&mut fitted, k, h);
                left_out.extend(h.outliers.iter().map(|(l, o)| (k, *l, *o)));
            }
            PoseLogRow {
                t_s,
                pose: r.pose,
                status: r.status,
                n_landmarks: r.n_landmarks,
                n_detections: r.n_detections,
                n_hypotheses: r.n_hypotheses,
                score: r.score,
                mode: r.mode.into(),
                scan: scan.id,
                pose_cov: r.pose_cov,
            }
        };
        rows.push(row);
        on_scan();
    }
    let mut log = PoseLog { rows };
    if !global_only {
        deskew_track_starts(loc, scans, &mut log, &mut deskewed, &mut fitted);
        deskew_centred(loc, scans, &mut log, &deskewed, &mut fitted);
    }
    Pass {
        log,
        deskewed,
        sweeps_s,
        fitted,
        left_out,
        n_repeated,
        unseen: views.unseen(loc),
        dim: views.dim(loc),
    }
}

/// The times of `scans` for those without a `t` column, seconds: each id's periods of
/// `rate_hz` after the first scan's when the ids increase (a logger numbers every scan it
/// takes, so a gap in them is scans dropped; timed by their order, scans after a drop were
/// de-skewed with a motion too fast, 38 of 173 poses beyond 5σ), else each scan's place.
pub fn untimed_times(scans: &[Scan], rate_hz: f64) -> Vec<f64> {
    let by_id = scans.windows(2).all(|w| w[0].id < w[1].id);
    let first = scans.first().map_or(0, |s| s.id);
    scans
        .iter()
        .enumerate()
        .map(|(k, s)| {
            let n = if by_id { s.id - first } else { k as u64 };
            n as f64 / rate_hz
        })
        .collect()
}

/// An `ok` pose looks for support among the `ok` poses of this many scans either side.
pub const SUPPORT_ROWS: usize = 5;

/// Poses of two scans agree when they are no farther apart than a small robot drives and
/// turns between them (generously: 2 m/s and 360°/s, where `synth lrf` drives 0.5 m/s and
/// 12°/s) plus the poses' own noise many times over.
const SUPPORT_SPEED_M_S: f64 = 2.0;
const SUPPORT_TURN_RAD_S: f64 = std::f64::consts::TAU;
const SUPPORT_SLACK_M: f64 = 0.05;
const SUPPORT_SLACK_RAD: f64 = 0.1;

/// In a recording where most scans (repeats aside) are lost, takes the pose from every `ok`
/// row that no `ok` pose of the [`SUPPORT_ROWS`] scans either side agrees with (status lost,
/// mode `unsupported`), and returns how many. Scans that fit the map nowhere are of another
/// room or read wrongly, and the few that pass the chance test among them are coincidences:
/// a scanner mounted upside down gave one `ok` pose 4.2 m off with a σ of 3 mm among 93 lost
/// scans. The right poses of such a recording come in runs, each agreeing with the next. In a
/// recording mostly localised the same is done to a pose between two scans without one: a
/// robot driven out of the mapped area gave one `ok` pose 4.7 m and 180° off (100σ) among
/// lost and ambiguous scans, with no word. A lone pose beside `ok` ones is left to
/// [`widen_off_track`].
fn drop_unsupported(log: &mut PoseLog) -> usize {
    let judged = log.rows.iter().filter(|r| r.mode != "repeated").count();
    let lost = log
        .rows
        .iter()
        .filter(|r| r.status == Status::Lost && r.mode != "repeated")
        .count();
    let mostly_lost = lost * 2 > judged;
    let ok: Vec<usize> = (0..log.rows.len())
        .filter(|&k| log.rows[k].status == Status::Ok && log.rows[k].pose.is_some())
        .collect();
    let is_ok = |k: usize| {
        log.rows
            .get(k)
            .is_some_and(|r| r.status == Status::Ok && r.pose.is_some())
    };
    let agree = |a: &PoseLogRow, b: &PoseLogRow| {
        let (Some(p), Some(q)) = (a.pose, b.pose) else {
            return false;
        };
        let dt = (a.t_s - b.t_s).abs();
        let dist = ((p.x_m - q.x_m).powi(2) + (p.y_m - q.y_m).powi(2)).sqrt();
        let turn = odocal_core::wrap_angle(p.theta_rad - q.theta_rad).abs();
        dist <= SUPPORT_SPEED_M_S * dt + SUPPORT_SLACK_M
            && turn <= SUPPORT_TURN_RAD_S * dt + SUPPORT_SLACK_RAD
    };
    let lone: Vec<usize> = ok
        .iter()
        .copied()
        .filter(|&k| {
            !ok.iter().any(|&j| {
                j != k && j.abs_diff(k) <= SUPPORT_ROWS && agree(&log.rows[k], &log.rows[j])
            })
        })
        .filter(|&k| {
            // Between two scans: the one scan of a file has no neighbours to be lost.
            let between = k > 0 && k + 1 < log.rows.len();
            mostly_lost || (between && !is_ok(k - 1) && !is_ok(k + 1))
        })
        .collect();
    for &k in &lone {
        let r = &mut log.rows[k];
        r.status = Status::Lost;
        r.pose = None;
        r.pose_cov = None;
        r.mode = "unsupported".into();
    }
    lone.len()
}

/// Adds the matches of `h`, the pose of row `k`, to `fitted` (row, landmark, observation).
fn add_fitted(fitted: &mut Vec<(usize, usize, Observation)>, k: usize, h: &Hypothesis) {
    let obs = h.matches.iter().zip(&h.observations);
    fitted.extend(obs.map(|(&(_, l), o)| (k, l, *o)));
}

/// A landmark's mean residual must be at least this many standard errors of that mean to be
/// taken for a bias: over the seeds 1–4 of `synth lrf` the largest was 3.6 (the standard
/// error is from the residuals' scatter, and scans in a row share some of their errors, so
/// this is more than a Gaussian's tail would need). Reflectors moved 5 cm gave 12–20.
const MIN_BIAS_SIGMAS: f64 = 5.0;

/// ... and at least this many times the map's survey σ: a landmark surveyed within its σ has
/// its residuals' mean within it too.
const MIN_BIAS_MAP_SIGMAS: f64 = 3.0;

/// A landmark matched in fewer scans than this has no mean worth judging.
const MIN_BIAS_SCANS: usize = 10;

/// A landmark whose detections sit off its mapped position, the same way, scan after scan.
#[derive(Debug, Clone, PartialEq)]
pub struct MovedLandmark {
    /// The landmark's id.
    pub id: u32,
    /// The mean of its detections minus its mapped position, map frame, metres.
    pub offset_m: Vector2<f64>,
    /// The standard error of that mean along it, metres.
    pub sigma_m: f64,
    /// The `ok` scans it was matched in.
    pub n_scans: usize,
    /// The places those scans were taken from (poses 2 cm and a beam step apart or more).
    pub n_places: usize,
}

/// The landmarks whose residuals at the poses of `fitted` (row, landmark, observation) have a
/// mean far beyond both its standard error and the map's σ: moved after the map was made (a
/// reflector re-stuck 5 cm along its wall left poses 40 mm, 10σ, off). The most biased one is
/// taken first and the poses that matched it fitted again without it: a moved landmark pulls
/// the poses, and with them the residuals of the landmarks seen beside it. Also returns the
/// rows that matched a moved landmark and keep their pose, too few others left to fit it
/// again ([`widen_kept`] says by how much they may be off).
fn moved_landmarks(
    loc: &Localizer,
    log: &mut PoseLog,
    fitted: &[(usize, usize, Observation)],
    deskewed: &[bool],
) -> (Vec<MovedLandmark>, Vec<usize>) {
    let map_sigma_m = loc.map.position_sigma_m.unwrap_or(loc.cfg.map_sigma_m);
    let original = log.rows.clone();
    let mut moved: Vec<usize> = Vec::new();
    let mut kept = Vec::new();
    loop {
        let worst = (0..loc.map.landmarks.len())
            .filter(|l| !moved.contains(l))
            .filter_map(|l| Some((l, residual_mean(loc, log, fitted, deskewed, l, &moved)?)))
            .filter(|(_, m)| {
                let d = m.offset_m.norm();
                d > MIN_BIAS_SIGMAS * m.sigma_m && d > MIN_BIAS_MAP_SIGMAS * map_sigma_m
            })
            .max_by(|a, b| {
                let z = |m: &MovedLandmark| m.offset_m.norm() / m.sigma_m;
                z(&a.1).total_cmp(&z(&b.1))
            });
        let Some((l, _)) = worst else { break };
        moved.push(l);
        kept = refit_without(loc, log, fitted, &moved, &original);
    }
    let out = moved
        .iter()
        .filter_map(|&l| residual_mean(loc, log, fitted, deskewed, l, &moved))
        .collect();
    (out, kept)
}

/// Widens the σ of the `kept` rows of `fitted` (poses that matched a `moved` landmark and
/// could not be fitted again without it) by how far the moved landmarks' offsets pull the pose,
/// in heading too: the offsets alone, added to the position's σ, left such poses 3.8σ off in
/// heading.
fn widen_kept(
    loc: &Localizer,
    log: &mut PoseLog,
    fitted: &[(usize, usize, Observation)],
    kept: &[usize],
    moved: &[MovedLandmark],
) {
    for_each_row(fitted, |k, row| {
        let Some(pose) = log.rows[k].pose.filter(|_| kept.contains(&k)) else {
            return;
        };
        let offsets: Vec<Vector2<f64>> = row
            .iter()
            .map(|(_, l, _)| {
                let id = loc.map.landmarks[*l].id;
                moved
                    .iter()
                    .find(|m| m.id == id)
                    .map_or(Vector2::zeros(), |m| m.offset_m)
            })
            .collect();
        let obs: Vec<Observation> = row.iter().map(|(_, _, o)| *o).collect();
        if let (Some(cov), Some(shift)) = (
            log.rows[k].pose_cov.as_mut(),
            pose_shift(&pose, &obs, &offsets),
        ) {
            *cov += shift * shift.transpose();
        }
    });
}

/// The mean of landmark `l`'s residuals (detection minus mapped position, map frame) at the
/// `deskewed` `ok` poses of `fitted` (one not de-skewed carries its sweep's skew in its residuals,
/// which is no landmark's), each at the pose its row's other matches give, those of the `skip`
/// landmarks (moved ones) left out too; None when matched in fewer than [`MIN_BIAS_SCANS`] scans.
fn residual_mean(
    loc: &Localizer,
    log: &PoseLog,
    fitted: &[(usize, usize, Observation)],
    deskewed: &[bool],
    l: usize,
    skip: &[usize],
) -> Option<MovedLandmark> {
    // Each residual at the pose the row's other matches give: at the row's own pose, the
    // landmark pulls the pose towards itself, and its residual shows a part of its offset
    // (12 of 50 mm with three landmarks in view), too little to name it.
    let seen: Vec<(Pose2, &Observation, Matrix3<f64>)> = fitted
        .iter()
        .filter(|f| f.1 == l && deskewed[f.0] && log.rows[f.0].status == Status::Ok)
        .filter_map(|(k, _, o)| {
            let pose = log.rows[*k].pose?;
            let start = fitted.partition_point(|f| f.0 < *k);
            let end = fitted.partition_point(|f| f.0 <= *k);
            let others: Vec<Observation> = fitted[start..end]
                .iter()
                .filter(|f| f.1 != l && !skip.contains(&f.1))
                .map(|f| f.2)
                .collect();
            let (p, cov) = fit_pose_weighted(pose, &others)?;
            Some((p, o, cov))
        })
        .collect();
    let r: Vec<Vector2<f64>> = seen
        .iter()
        .map(|(p, o, _)| p.isometry() * o.sensor - o.landmark)
        .collect();
    let n = r.len();
    if n < MIN_BIAS_SCANS {
        return None;
    }
    let mean = r.iter().sum::<Vector2<f64>>() / n as f64;
    let scatter = r
        .iter()
        .map(|v| (v - mean) * (v - mean).transpose())
        .sum::<Matrix2<f64>>()
        / (n - 1) as f64;
    let dir = mean.try_normalize(0.0)?;
    // Scans from one place share which beams hit the strip, and so the error of its centre
    // along it, which their scatter does not show: the mean is known no better than the
    // detections' own σ over the places they were seen from (a still robot's 55 scans gave
    // 0.4 mm, and a correct map was called moved).
    let step_rad = loc.cfg.sensor.step_rad;
    let mut places: Vec<Pose2> = Vec::new();
    for (p, _, _) in &seen {
        let same = |q: &Pose2| {
            (p.x_m - q.x_m).hypot(p.y_m - q.y_m) <= PLACE_M
                && odocal_core::wrap_angle(p.theta_rad - q.theta_rad).abs() <= step_rad
        };
        if !places.iter().any(same) {
            places.push(*p);
        }
    }
    let own = seen
        .iter()
        .map(|(p, o, cov)| {
            let rot = nalgebra::Rotation2::new(p.theta_rad);
            let d = rot.inverse() * dir;
            let rz = rot * o.sensor.coords;
            let j = nalgebra::Matrix2x3::new(1.0, 0.0, -rz.y, 0.0, 1.0, rz.x);
            d.dot(&(o.cov * d)) + dir.dot(&(j * cov * j.transpose() * dir))
        })
        .sum::<f64>()
        / n as f64;
    let var = (dir.dot(&(scatter * dir)) / n as f64).max(own / places.len() as f64);
    Some(MovedLandmark {
        id: loc.map.landmarks[l].id,
        offset_m: mean,
        sigma_m: var.sqrt(),
        n_scans: n,
        n_places: places.len(),
    })
}

/// Poses closer than this (and turned less than a beam step) see a landmark from one place:
/// a reflector's beams at a few metres are about 2 cm apart, so nearer poses hit it with the
/// same beams.
const PLACE_M: f64 = 0.02;

/// Calls `f` with each row of `fitted` and that row's matches.
fn for_each_row(
    fitted: &[(usize, usize, Observation)],
    mut f: impl FnMut(usize, &[(usize, usize, Observation)]),
) {
    let mut start = 0;
    while start < fitted.len() {
        let k = fitted[start].0;
        let end = start + fitted[start..].iter().take_while(|x| x.0 == k).count();
        f(k, &fitted[start..end]);
        start = end;
    }
}

/// Fits again from its `original` row, without the `moved` landmarks, every pose of `fitted`
/// that matched one and keeps enough others to fit; the others keep (or get back) their
/// original row and are returned.
fn refit_without(
    loc: &Localizer,
    log: &mut PoseLog,
    fitted: &[(usize, usize, Observation)],
    moved: &[usize],
    original: &[PoseLogRow],
) -> Vec<usize> {
    let mut kept = Vec::new();
    for_each_row(fitted, |k, row| {
        let rest: Vec<Observation> = row
            .iter()
            .filter(|(_, l, _)| !moved.contains(l))
            .map(|(_, _, o)| *o)
            .collect();
        let (Some(pose), true) = (original[k].pose, rest.len() < row.len()) else {
            return;
        };
        let refit = if rest.len() < loc.cfg.min_matches {
            None
        } else {
            fit_pose_weighted(pose, &rest)
        };
        let r = &mut log.rows[k];
        match refit {
            Some((p, cov)) => {
                r.pose = Some(p);
                r.pose_cov = Some(cov);
                r.n_landmarks = rest.len();
            }
            // A row fitted again without the first moved landmark but not without the second
            // is the original's: its σ is widened for both.
            None => {
                *r = original[k].clone();
                kept.push(k);
            }
        }
    });
    kept
}

/// A landmark missed in at least this many scans, and in [`MIN_UNSEEN_SHARE`] of those it was
/// in view in, is named: one scan in ten misses a reflector (the synthetic rooms' landmarks
/// are missed in 2–20 % of the scans they are in view in), so ten misses in a row happen by
/// chance once in ten billion.
const MIN_UNSEEN_SCANS: usize = 10;

/// See [`MIN_UNSEEN_SCANS`]: a spurious return now and then may be taken for the landmark (25
/// of 26 for a reflector gone from a symmetric room).
const MIN_UNSEEN_SHARE: f64 = 0.9;

/// For every landmark, in how many scans some hypothesis had it in view, and in how many one
/// that had it in view did not see it. Judged so, a reflector gone from a symmetric room is
/// missed in every scan: the mirror pose matches the reflector opposite it in its place.
struct LandmarkViews {
    in_view: Vec<usize>,
    missed: Vec<usize>,
    /// Per landmark, the brightest return at its place in each scan it was missed in, where
    /// a return lay there (a reflector too dim for `--intensity-min` is still there).
    dim: Vec<Vec<f64>>,
}

impl LandmarkViews {
    fn new(n_landmarks: usize) -> Self {
        LandmarkViews {
            in_view: vec![0; n_landmarks],
            missed: vec![0; n_landmarks],
            dim: vec![Vec::new(); n_landmarks],
        }
    }

    /// Counts the landmarks `hyps` (the hypotheses of `scan`) matched or should have seen.
    fn add(&mut self, loc: &Localizer, scan: &Scan, hyps: &[Hypothesis]) {
        let n = self.in_view.len();
        let (mut in_view, mut missed) = (vec![false; n], vec![false; n]);
        let mut brightest: Vec<Option<f64>> = vec![None; n];
        for h in hyps {
            let mut matched = vec![false; n];
            for &(_, l) in &h.matches {
                matched[l] = true;
                in_view[l] = true;
            }
            loc.for_each_missing(scan, &h.pose, &matched, |l| {
                in_view[l] = true;
                missed[l] = true;
                let at = return_at(loc, scan, &h.pose, l);
                brightest[l] = match (brightest[l], at) {
                    (Some(b), Some(i)) => Some(b.max(i)),
                    (b, i) => b.or(i),
                };
            });
        }
        for l in 0..n {
            self.in_view[l] += usize::from(in_view[l]);
            self.missed[l] += usize::from(missed[l]);
            if let (true, Some(i)) = (missed[l], brightest[l]) {
                self.dim[l].push(i);
            }
        }
    }

    /// The unseen landmarks (id, scans missed in with a return at its place, the median
    /// intensity of those returns) that returned at their place in most scans they were
    /// missed in: there, but too dim for `--intensity-min`.
    fn dim(&self, loc: &Localizer) -> Vec<(u32, usize, f64)> {
        self.unseen(loc)
            .into_iter()
            .filter_map(|(id, _, missed)| {
                let l = loc.map.landmarks.iter().position(|x| x.id == id)?;
                let mut i = self.dim[l].clone();
                if i.len() * 2 <= missed {
                    return None;
                }
                i.sort_by(f64::total_cmp);
                Some((id, i.len(), i[i.len() / 2]))
            })
            .collect()
    }

    /// The landmarks (id, scans in view, scans missed) missed in [`MIN_UNSEEN_SCANS`] scans or
    /// more, nearly every time they were in view.
    fn unseen(&self, loc: &Localizer) -> Vec<(u32, usize, usize)> {
        (0..self.in_view.len())
            .filter(|&l| {
                let (n, missed) = (self.in_view[l], self.missed[l]);
                missed >= MIN_UNSEEN_SCANS && missed as f64 >= MIN_UNSEEN_SHARE * n as f64
            })
            .map(|l| (loc.map.landmarks[l].id, self.in_view[l], self.missed[l]))
            .collect()
    }
}

/// The brightest return of `scan` at landmark `l`'s place seen from `pose` (within half a
/// reflector's width and a beam step of its bearing, and 5 cm of its range), if any.
fn return_at(loc: &Localizer, scan: &Scan, pose: &Pose2, l: usize) -> Option<f64> {
    let p = pose.isometry().inverse() * loc.map.landmarks[l].position;
    let range = p.coords.norm();
    let bearing = p.y.atan2(p.x);
    let half = 0.5 * loc.map.reflector_width_m / range.max(0.1) + loc.cfg.sensor.step_rad.abs();
    let a = &scan.angles_rad;
    let (lo, hi) = (
        a.partition_point(|x| *x < bearing - half),
        a.partition_point(|x| *x <= bearing + half),
    );
    let brightest = (lo..hi)
        .filter(|&k| scan.ranges_m[k] > 0.0 && (scan.ranges_m[k] - range).abs() <= 0.05)
        .map(|k| scan.intensities[k])
        .max_by(f64::total_cmp)?;
    // A wall returns at a wall-mounted reflector's place too: only a return clearly brighter
    // than the wall beside it is the reflector's.
    let (flank_lo, flank_hi) = (
        a.partition_point(|x| *x < bearing - 3.0 * half),
        a.partition_point(|x| *x <= bearing + 3.0 * half),
    );
    let mut beside: Vec<f64> = (flank_lo..lo)
        .chain(hi..flank_hi)
        .filter(|&k| scan.ranges_m[k] > 0.0 && (scan.ranges_m[k] - range).abs() <= 0.2)
        .map(|k| scan.intensities[k])
        .collect();
    if beside.len() < 2 {
        return None;
    }
    beside.sort_by(f64::total_cmp);
    (brightest >= BRIGHTER_THAN_WALL * beside[beside.len() / 2]).then_some(brightest)
}

/// A return this many times as bright as the wall beside it is a reflector's.
const BRIGHTER_THAN_WALL: f64 = 1.3;

/// True if `scan` has the very ranges and intensities of `prev`, the scan before it, with
/// some return among them: a driver republishing its last scan under a new time. The range
/// noise of a real sweep (millimetres at the least) never repeats over all its beams, and a
/// repeat localised at its new time gave a pose 50 mm (45σ) off while the robot moved.
fn repeats(prev: &Scan, scan: &Scan) -> bool {
    scan.ranges_m.iter().any(|r| *r > 0.0)
        && scan.ranges_m == prev.ranges_m
        && scan.intensities == prev.intensities
}

/// The next two `ok` poses after this one must follow within this time for their motion to
/// stand for the motion during its sweep, seconds.
const MAX_START_GAP_S: f64 = 0.5;

/// Fits again, de-skewed, the first poses of every track: the first two had no motion to
/// de-skew them by, and the third one the motion between those two, each off by its own
/// sweep's skew (seed 1 of `synth lrf`: 40 % too fast, its pose 9–12σ off). Going backwards,
/// each takes the motion between the two poses after it, already fitted de-skewed.
fn deskew_track_starts(
    loc: &Localizer,
    scans: &[Scan],
    log: &mut PoseLog,
    deskewed: &mut [bool],
    fitted: &mut Vec<(usize, usize, Observation)>,
) {
    let rows = &mut log.rows;
    let ok = |r: &PoseLogRow| r.status == Status::Ok && r.pose.is_some();
    for k in (0..rows.len()).rev() {
        let start = !deskewed[k] || k == 0 || !deskewed[k - 1];
        if !start || !ok(&rows[k]) || loc.cfg.sensor.beam_interval_s(&scans[k]) <= 0.0 {
            continue;
        }
        let next: Vec<usize> = (k + 1..rows.len())
            .filter(|&i| ok(&rows[i]) && deskewed[i])
            .take(2)
            .collect();
        let (Some(&i), Some(&j)) = (next.first(), next.get(1)) else {
            continue;
        };
        let (Some(pi), Some(pj)) = (rows[i].pose, rows[j].pose) else {
            continue;
        };
        let dt = rows[j].t_s - rows[i].t_s;
        if dt <= 1e-6 || rows[j].t_s - rows[k].t_s > MAX_START_GAP_S {
            continue;
        }
        let vel = [
            (pj.x_m - pi.x_m) / dt,
            (pj.y_m - pi.y_m) / dt,
            odocal_core::wrap_angle(pj.theta_rad - pi.theta_rad) / dt,
        ];
        if refit_deskewed(loc, &scans[k], k, &mut rows[k], fitted, vel) {
            deskewed[k] = true;
        }
    }
    // The rows' matches together, as [`moved_landmarks`] takes them.
    fitted.sort_by_key(|f| f.0);
}

/// Fits `row` (scan `k`, `scan`) again from its pose with its detections de-skewed for the
/// sensor moving at `vel` (map frame: m/s, m/s, rad/s), and keeps that fit, with its matches
/// in `fitted`, when it uses as many landmarks as the row did; returns whether it was kept.
fn refit_deskewed(
    loc: &Localizer,
    scan: &Scan,
    k: usize,
    row: &mut PoseLogRow,
    fitted: &mut Vec<(usize, usize, Observation)>,
    vel: [f64; 3],
) -> bool {
    let Some(p) = row.pose else {
        return false;
    };
    let dets = crate::scan_track::deskewed(&loc.detections(scan), vel, &p);
    let Some(h) = loc.track(scan, &dets, p, 0.03, 0.01) else {
        return false;
    };
    if h.matches.len() < row.n_landmarks {
        return false;
    }
    row.pose = Some(h.pose);
    row.pose_cov = h.cov;
    row.n_landmarks = h.matches.len();
    row.score = h.score;
    fitted.retain(|f| f.0 != k);
    add_fitted(fitted, k, &h);
    true
}

/// The two poses either side of a scan must lie within this time of each other for their
/// motion to stand for the motion during its sweep, seconds (two scan periods at 10 Hz, with
/// room for a scan lost between them).
const MAX_CENTRED_SPAN_S: f64 = 0.35;

/// Fits every de-skewed pose again with the turn rate between the poses before and after it.
/// While tracking, a sweep is de-skewed with the motion from the pose before to the scan's own
/// fit, which is the turn rate half a scan period before the sweep began, and which carries
/// the fit's own error into its de-skew (pulling it towards the pose before: a smoothing its
/// σ do not know). A robot whose turn rate changes by 10°/s² then left its poses 4–6σ off in
/// heading for a second at a time (`synth lrf --seed 2`, t = 12–16 s). The turn rate between
/// the neighbours is the one at the scan's time and owes nothing to its fit. The translation
/// keeps the motion from the pose before: a small robot's speed changes slowly, and the
/// neighbours' would add their noise.
fn deskew_centred(
    loc: &Localizer,
    scans: &[Scan],
    log: &mut PoseLog,
    deskewed: &[bool],
    fitted: &mut Vec<(usize, usize, Observation)>,
) {
    let ok = |r: &PoseLogRow| r.status == Status::Ok && r.pose.is_some();
    let before: Vec<Option<odocal_core::Pose2>> = log
        .rows
        .iter()
        .zip(deskewed)
        .map(|(r, &d)| if ok(r) && d { r.pose } else { None })
        .collect();
    let rows = &mut log.rows;
    for k in 1..rows.len().saturating_sub(1) {
        let (Some(p), Some(pa), Some(pb)) = (before[k], before[k - 1], before[k + 1]) else {
            continue;
        };
        let dt = rows[k + 1].t_s - rows[k - 1].t_s;
        if !(dt > 1e-6 && dt <= MAX_CENTRED_SPAN_S)
            || loc.cfg.sensor.beam_interval_s(&scans[k]) <= 0.0
        {
            continue;
        }
        let dt_back = rows[k].t_s - rows[k - 1].t_s;
        if dt_back <= 1e-6 {
            continue;
        }
        let vel = [
            (p.x_m - pa.x_m) / dt_back,
            (p.y_m - pa.y_m) / dt_back,
            odocal_core::wrap_angle(pb.theta_rad - pa.theta_rad) / dt,
        ];
        refit_deskewed(loc, &scans[k], k, &mut rows[k], fitted, vel);
    }
    fitted.sort_by_key(|f| f.0);
}

/// The poses of [`localize_scans`], and what it could not de-skew or localise.
#[derive(Debug, Clone, PartialEq)]
pub struct Localized {
    /// One row per scan.
    pub log: PoseLog,
    /// The poses left with their sweep's skew, if any moved enough to matter.
    pub skewed: Option<Skewed>,
    /// Scans that repeat the scan before them beam for beam, left without a pose (status
    /// lost, mode `repeated`).
    pub n_repeated: usize,
    /// Landmarks (id, scans in view, scans missed) that a hypothesis had in view and did not
    /// see nearly every time: gone from the room, or covered, and evidence against the right
    /// pose alone.
    pub unseen: Vec<(u32, usize, usize)>,
    /// Of those, (id, scans missed in with a return at its place, the median intensity of
    /// those returns): returning where the landmark is, too dim for `--intensity-min`.
    pub dim: Vec<(u32, usize, f64)>,
    /// Landmarks whose detections sit off their mapped positions the same way scan after
    /// scan: moved since the map was made. The poses that matched them were fitted again
    /// without them.
    pub moved: Vec<MovedLandmark>,
    /// `ok` poses of a mostly lost recording that no neighbouring scan's pose agreed with,
    /// left without a pose (status lost, mode `unsupported`).
    pub n_unsupported: usize,
    /// How well the `ok` poses fit their landmarks against the detections' own noise.
    pub fit: FitQuality,
    /// The range offset and angle scale taken out of the scans, when their residuals showed
    /// one.
    pub calibration: Option<Calibration>,
    /// Landmarks detected off their mapped position the same way scan after scan, too far to
    /// be used: each fit left them out as beyond their noise (a reflector moved 4–10 cm).
    pub left_out: Vec<MovedLandmark>,
    /// `ok` poses off the track their neighbours give by more than their σ and the robot's
    /// acceleration allow: their σ were widened to cover how far off they are.
    pub n_off_track: usize,
}

/// How well the `ok` poses fit their matched landmarks, against the noise the detections'
/// covariances say (χ²): a landmark off its mapped place, a range offset or an angle step
/// that is not the scanner's leaves residuals beyond that noise, and the pose off by more
/// than its σ says.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct FitQuality {
    /// `ok` poses judged (with at least two matches).
    pub n_poses: usize,
    /// Of those, the poses whose χ² lay beyond its 99 % quantile: their σ were widened by the
    /// χ² over its degrees of freedom and by how far leaving out each match moves the pose.
    pub n_widened: usize,
    /// The recording's χ² over its degrees of freedom: about 1 when the residuals are the
    /// detections' noise.
    pub ratio: f64,
}

/// Poses whose scans were not de-skewed (no motion was tracked yet, or `--global-only`)
/// while the sensor moved.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Skewed {
    /// How many `ok` poses.
    pub n_poses: usize,
    /// Of those, how many had their σ at least doubled in position or heading.
    pub n_widened: usize,
    /// The largest motion over a sweep among them, metres and radians.
    pub max_sweep_motion: (f64, f64),
    /// Poses not de-skewed with no `ok` neighbour to tell the sensor's motion by (a single
    /// scan, or one alone among lost scans): their σ leave out whatever the sensor moved.
    pub n_motion_unknown: usize,
}

/// Widens the covariance of every pose whose scan was not de-skewed by the motion over half its
/// sweep: its beams were taken up to a sweep after the scan's time, so the pose lies somewhere
/// along that motion (the fit of beams spread over the sweep lands near its middle; 11.6 mm
/// RMS against a σ of 2.8 mm for a sensor at 0.5 m/s and 12°/s over a 67 ms sweep). The motion
/// is the one between the pose and its nearest `ok` neighbour (by time).
fn widen_skewed(log: &mut PoseLog, deskewed: &[bool], sweeps_s: &[f64]) -> Option<Skewed> {
    let ok: Vec<usize> = (0..log.rows.len())
        .filter(|&k| log.rows[k].status == Status::Ok && log.rows[k].pose.is_some())
        .collect();
    let mut skewed = Skewed {
        n_poses: 0,
        n_widened: 0,
        max_sweep_motion: (0.0, 0.0),
        n_motion_unknown: 0,
    };
    for (j, &k) in ok.iter().enumerate() {
        if deskewed[k] || sweeps_s[k] <= 0.0 {
            continue;
        }
        let neighbours = [j.checked_sub(1), Some(j + 1)];
        let nearest = neighbours
            .into_iter()
            .flatten()
            .filter_map(|i| ok.get(i))
            .min_by(|&&a, &&b| {
                let gap = |i: usize| (log.rows[i].t_s - log.rows[k].t_s).abs();
                gap(a).total_cmp(&gap(b))
            });
        let (Some(&n), Some(p)) = (nearest, log.rows[k].pose) else {
            skewed.n_motion_unknown += 1;
            continue;
        };
        let Some(q) = log.rows[n].pose else { continue };
        let dt = log.rows[n].t_s - log.rows[k].t_s;
        if dt.abs() < 1e-9 {
            continue;
        }
        let half = 0.5 * sweeps_s[k] / dt;
        let shift = nalgebra::Vector3::new(
            (q.x_m - p.x_m) * half,
            (q.y_m - p.y_m) * half,
            odocal_core::wrap_angle(q.theta_rad - p.theta_rad) * half,
        );
        skewed.n_poses += 1;
        let motion = (2.0 * shift.xy().norm(), 2.0 * shift.z.abs());
        skewed.max_sweep_motion.0 = skewed.max_sweep_motion.0.max(motion.0);
        skewed.max_sweep_motion.1 = skewed.max_sweep_motion.1.max(motion.1);
        if let Some(cov) = log.rows[k].pose_cov.as_mut() {
            let widening = shift * shift.transpose();
            let doubled = widening[(0, 0)] + widening[(1, 1)] >= 3.0 * (cov[(0, 0)] + cov[(1, 1)])
                || widening[(2, 2)] >= 3.0 * cov[(2, 2)];
            skewed.n_widened += usize::from(doubled);
            *cov += widening;
        }
    }
    (skewed.n_poses > 0 || skewed.n_motion_unknown > 0).then_some(skewed)
}

#[cfg(test)]
mod tests {
    use super::*;
    use odocal_core::Pose2;

    /// A log of `n` scans 0.1 s apart, `ok` where `pose_at` gives a pose, lost elsewhere.
    fn log_of(n: usize, pose_at: impl Fn(usize) -> Option<Pose2>) -> PoseLog {
        let rows = (0..n)
            .map(|k| {
                let pose = pose_at(k);
                PoseLogRow {
                    t_s: k as f64 * 0.1,
                    pose,
                    status: if pose.is_some() {
                        Status::Ok
                    } else {
                        Status::Lost
                    },
                    n_landmarks: if pose.is_some() { 4 } else { 0 },
                    n_detections: 4,
                    n_hypotheses: usize::from(pose.is_some()),
                    score: 4.0,
                    mode: "global".into(),
                    scan: k as u64,
                    pose_cov: None,
                }
            })
            .collect();
        PoseLog { rows }
    }

    /// A scanner mounted upside down lost 93 of 100 scans and wrote one `ok` pose 4.2 m off
    /// with a σ of 3 mm as ground truth: a pose no neighbour agrees with, in a recording
    /// mostly lost, is taken away; a run of poses that agree with each other is kept.
    #[test]
    fn a_lone_pose_among_lost_scans_is_left_out() {
        let along = |k: usize| Pose2::new(1.0 + 0.05 * k as f64, 2.0, 0.3);
        let mut log = log_of(100, |k| match k {
            40 => Some(Pose2::new(5.2, 1.0, 2.0)),
            70..=74 => Some(along(k)),
            // A neighbour in time that is somewhere else entirely supports nothing.
            20 | 22 => Some(Pose2::new(k as f64 * 0.3, 0.0, 0.0)),
            _ => None,
        });
        assert_eq!(drop_unsupported(&mut log), 3);
        for k in [20, 22, 40] {
            let r = &log.rows[k];
            assert_eq!(
                (r.status, r.pose, r.mode.as_str()),
                (Status::Lost, None, "unsupported")
            );
        }
        assert!((70..=74).all(|k| log.rows[k].status == Status::Ok));
        // In a recording mostly localised, a lone pose between scans without one is taken
        // away too (a robot driven out of the mapped area); one beside `ok` poses is left to
        // the track's test.
        let mut log = log_of(100, |k| match k {
            30 => Some(Pose2::new(5.2, 1.0, 2.0)),
            80 => Some(Pose2::new(5.2, 1.0, 2.0)),
            k if k < 60 => Some(along(k)),
            _ => None,
        });
        assert_eq!(drop_unsupported(&mut log), 1);
        assert_eq!(log.rows[80].mode, "unsupported");
        assert_eq!(log.rows[30].status, Status::Ok);
    }
    /// Three landmarks fit by a glint in place of one of them put a pose 88 mm off the track
    /// with a σ of 7 mm (11.5σ) while the scans either side agreed with each other: its σ is
    /// widened to cover how far off it is, and its neighbours', pulled half as far in their
    /// own test, are left alone; a robot driving and turning steadily widens nothing.
    #[test]
    fn a_pose_off_the_track_of_its_neighbours_has_its_sigma_widened() {
        let cov = Matrix3::from_diagonal(&Vector3::new(
            0.007f64.powi(2),
            0.004f64.powi(2),
            0.0025f64.powi(2),
        ));
        let along = |k: usize| {
            let t = k as f64 * 0.1;
            Pose2::new(1.0 + 0.5 * t, 2.0 + 0.1 * t * t, 0.2 * t)
        };
        let mut log = log_of(20, |k| Some(along(k)));
        for r in &mut log.rows {
            r.pose_cov = Some(cov);
        }
        assert_eq!(widen_off_track(&mut log), 0);
        assert!(log.rows.iter().all(|r| r.pose_cov == Some(cov)));
        let p = along(10);
        log.rows[10].pose = Some(Pose2::new(p.x_m - 0.08, p.y_m + 0.037, p.theta_rad + 0.026));
        assert_eq!(widen_off_track(&mut log), 1);
        let c = log.rows[10].pose_cov.expect("a covariance");
        assert!(
            0.08 <= 1.1 * c[(0, 0)].sqrt() && 0.037 <= 1.1 * c[(1, 1)].sqrt(),
            "{c}"
        );
        assert_eq!(
            (log.rows[9].pose_cov, log.rows[11].pose_cov),
            (Some(cov), Some(cov))
        );
    }
}
