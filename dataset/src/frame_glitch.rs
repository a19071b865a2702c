//! Frames of a trajectory file that are no pose of the robot: a motion capture that loses
//! its body for an instant and writes a wrong fit (a jump of half a metre and back), a
//! symmetric marker set read as its turned self (the heading flipped by π for a frame or two
//! and back), or lost frames written as zeros (a jump to exactly (0, 0, 0) and back). Kept,
//! one jump every 3 s put tour windows' targets 11.8 mm RMS from the truth (max 107 mm)
//! where the dataset's own error is 3.1 mm, every window accepted; two-frame flips rejected
//! every straight run as "not a straight run" and every tour window as off the clock. No
//! robot moves so far within a frame and back: such frames are dropped as lost, and said.

use odocal_core::{wrap_angle, Trajectory, TrajectoryRow};

/// A step between frames is a jump when the position moves further than this, metres (a
/// robot's step between frames is centimetres, its tracking noise a millimetre)...
const JUMP_M: f64 = 0.05;
/// ...and faster than this, metres per second (no small robot drives at 3 m/s; a frame
/// of a glitch jumping 0.6 m at 30 frames/s moves at 18 m/s)...
const JUMP_MPS: f64 = 3.0;
/// ...or the heading turns by more than this, radians (17°)...
const JUMP_RAD: f64 = 0.3;
/// ...and faster than this, radians per second.
const JUMP_RAD_PER_S: f64 = 6.0;

/// Most frames in a row dropped as one glitch: beyond this, a jump away and back is more
/// likely a stretch the source tracked elsewhere than one wrong fit.
const MAX_GLITCH_FRAMES: usize = 5;

/// Longest time between the frames around a glitch, seconds: over a longer gap the robot may
/// well have moved as far as the jump.
const MAX_GLITCH_SPAN_S: f64 = 0.5;

/// A heading within this of π from the frames around it, with the position in place, is a
/// flip, radians (20°).
const FLIP_TOLERANCE_RAD: f64 = 0.35;

/// Whether the step from `a` to `b` is no motion of a robot.
fn is_jump(a: &TrajectoryRow, b: &TrajectoryRow) -> bool {
    let dt = (b.t_s - a.t_s).max(1e-9);
    let moved = (b.pose.x_m - a.pose.x_m).hypot(b.pose.y_m - a.pose.y_m);
    let turned = wrap_angle(b.pose.theta_rad - a.pose.theta_rad).abs();
    (moved > JUMP_M && moved / dt > JUMP_MPS) || (turned > JUMP_RAD && turned / dt > JUMP_RAD_PER_S)
}

/// Whether a row is exactly the origin, as a source writes a frame it lost.
fn is_zero(r: &TrajectoryRow) -> bool {
    r.pose.x_m == 0.0 && r.pose.y_m == 0.0 && r.pose.theta_rad == 0.0
}

/// The kinds of frames dropped, counted.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct DroppedFrames {
    /// Frames written as exactly (0, 0, 0) away from where the robot was.
    pub zeros: usize,
    /// Frames whose heading flipped by π, the position in place.
    pub flips: usize,
    /// Other frames that jumped away and back.
    pub jumps: usize,
    /// Largest distance of a jumping frame from the frames around it, metres.
    pub max_jump_m: f64,
    /// Largest heading difference of a jumping frame from the frames around it, radians.
    pub max_jump_rad: f64,
    /// Time of the first frame dropped, seconds.
    pub first_s: f64,
}

impl DroppedFrames {
    /// Frames dropped in all.
    pub fn total(&self) -> usize {
        self.zeros + self.flips + self.jumps
    }

    /// What was dropped, for the user (`rows`: the file's rows), or `None` when nothing was.
    pub fn note(&self, rows: usize) -> Option<String> {
        if self.total() == 0 {
            return None;
        }
        let mut kinds = Vec::new();
        if self.zeros > 0 {
            kinds.push(format!(
                "{} written as (0, 0, 0) away from where the robot was (lost frames written as zeros)",
                self.zeros
            ));
        }
        if self.flips > 0 {
            kinds.push(format!(
                "{} whose heading flipped by 180° and back, the position in place (a symmetric marker set read as its turned self)",
                self.flips
            ));
        }
        if self.jumps > 0 {
            kinds.push(format!(
                "{} that jumped up to {:.3} m and {:.0}° from the frames around them and back (a wrong fit for an instant)",
                self.jumps,
                self.max_jump_m,
                self.max_jump_rad.to_degrees()
            ));
        }
        Some(format!(
            "{} of {rows} frames dropped as lost, the first at {:.2} s: {}; no robot moves so far within a frame and back",
            self.total(),
            self.first_s,
            kinds.join("; ")
        ))
    }
}

/// `trajectory` without its frames that are no pose of the robot (see the module), and what
/// was dropped.
pub fn drop_glitch_frames(trajectory: &Trajectory) -> (Trajectory, DroppedFrames) {
    let rows = &trajectory.rows;
    let n = rows.len();
    let mut dropped = vec![false; n];
    let mut counts = DroppedFrames::default();
    // Zeros first, however many in a row: a source writes every frame it lost so.
    if !rows.iter().all(is_zero) {
        let near_origin = |r: &TrajectoryRow| r.pose.x_m.hypot(r.pose.y_m) <= JUMP_M;
        let mut i = 0;
        while i < n {
            if !is_zero(&rows[i]) {
                i += 1;
                continue;
            }
            let end = (i..n).find(|&j| !is_zero(&rows[j])).unwrap_or(n);
            let before = i.checked_sub(1).map(|j| &rows[j]);
            let after = rows.get(end);
            // A robot that stands at the origin writes zeros too; only a jump there is lost.
            if before.or(after).is_some_and(|r| !near_origin(r)) {
                for d in &mut dropped[i..end] {
                    *d = true;
                }
                counts.zeros += end - i;
            }
            i = end;
        }
    }
    // Then stretches of a few frames jumping away from the last good frame and back to one
    // that follows on from it.
    let mut last_good: Option<usize> = None;
    let mut i = 0;
    while i < n {
        if dropped[i] {
            i += 1;
            continue;
        }
        let Some(a) = last_good else {
            last_good = Some(i);
            i += 1;
            continue;
        };
        if !is_jump(&rows[a], &rows[i]) {
            last_good = Some(i);
            i += 1;
            continue;
        }
        // The frames from i on, skipping those already dropped, up to the first that
        // follows on from `a`.
        let mut stretch = Vec::new();
        let mut back = None;
        for j in i..n {
            if dropped[j] {
                continue;
            }
            if rows[j].t_s - rows[a].t_s > MAX_GLITCH_SPAN_S {
                break;
            }
            if !stretch.is_empty() && !is_jump(&rows[a], &rows[j]) {
                back = Some(j);
                break;
            }
            if stretch.len() == MAX_GLITCH_FRAMES {
                break;
            }
            stretch.push(j);
        }
        let Some(b) = back else {
            // No way back: the robot (or the source's frame) is elsewhere from here on.
            last_good = Some(i);
            i += 1;
            continue;
        };
        let (ra, rb) = (&rows[a], &rows[b]);
        for &j in &stretch {
            let r = &rows[j];
            let f = (r.t_s - ra.t_s) / (rb.t_s - ra.t_s);
            let x = ra.pose.x_m + f * (rb.pose.x_m - ra.pose.x_m);
            let y = ra.pose.y_m + f * (rb.pose.y_m - ra.pose.y_m);
            let theta = ra.pose.theta_rad + f * wrap_angle(rb.pose.theta_rad - ra.pose.theta_rad);
            let off_m = (r.pose.x_m - x).hypot(r.pose.y_m - y);
            let off_rad = wrap_angle(r.pose.theta_rad - theta).abs();
            if off_m <= JUMP_M && off_rad >= std::f64::consts::PI - FLIP_TOLERANCE_RAD {
                counts.flips += 1;
            } else {
                counts.jumps += 1;
                counts.max_jump_m = counts.max_jump_m.max(off_m);
                counts.max_jump_rad = counts.max_jump_rad.max(off_rad);
            }
            dropped[j] = true;
        }
        last_good = Some(b);
        i = b + 1;
    }
    counts.first_s = rows
        .iter()
        .zip(&dropped)
        .find(|(_, d)| **d)
        .map_or(f64::NAN, |(r, _)| r.t_s);
    let kept = Trajectory {
        rows: rows
            .iter()
            .zip(&dropped)
            .filter(|(_, d)| !**d)
            .map(|(r, _)| *r)
            .collect(),
    };
    (kept, counts)
}

/// Reads a trajectory file. A `t,x,y,theta` export (no quality column) marks the frames it
/// lost with NaN or empty x, y and theta; they are read as lost frames, as rows of quality 0
/// are where the quality column exists, instead of refusing the file ("NaN is not a finite
/// number"). Returns the trajectory and the note on the rows so read, if any.
pub fn read_trajectory(
    path: &std::path::Path,
) -> Result<(Trajectory, Option<String>), crate::DatasetError> {
    let text = crate::error::read_text(path)?;
    let name = path.display().to_string();
    let mut lines = text.lines();
    let header: Vec<String> = lines
        .next()
        .unwrap_or("")
        .trim_start_matches('\u{feff}')
        .split(',')
        .map(|f| f.trim().to_ascii_lowercase())
        .collect();
    if header != ["t", "x", "y", "theta"] {
        return Ok((Trajectory::parse_csv(&text, &name)?, None));
    }
    let no_value = |f: &str| {
        let f = f.trim();
        f.is_empty() || f.eq_ignore_ascii_case("nan")
    };
    let (mut rows, mut lost) = (0usize, 0usize);
    let mut with_quality = String::from("t,x,y,theta,quality\n");
    for line in lines {
        let fields: Vec<&str> = line.split(',').collect();
        let is_lost = fields.len() == 4
            && fields[0].trim().parse::<f64>().is_ok_and(f64::is_finite)
            && fields[1..].iter().all(|f| no_value(f));
        if !line.trim().is_empty() {
            rows += 1;
            lost += usize::from(is_lost);
        }
        with_quality.push_str(line);
        if !line.trim().is_empty() {
            with_quality.push_str(if is_lost { ",0" } else { ",1" });
        }
        with_quality.push('\n');
    }
    if lost == 0 {
        return Ok((Trajectory::parse_csv(&text, &name)?, None));
    }
    if lost == rows {
        return Err(crate::DatasetError::content(
            &name,
            "every row has no pose (NaN or empty x, y and theta, as a motion capture writes the frames it lost): give the trajectory of a recording the source tracked",
        ));
    }
    let trajectory = Trajectory::parse_csv(&with_quality, &name)?;
    Ok((
        trajectory,
        Some(format!(
            "{lost} of {rows} rows have no pose (NaN or empty x, y and theta): read as lost frames, as a motion capture writes them"
        )),
    ))
}

#[cfg(test)]
mod tests {
    use super::*;
    use odocal_core::Pose2;

    /// 300 frames at 30 frames/s of a robot driving at 0.3 m/s while turning at 0.5 rad/s.
    fn drive() -> Trajectory {
        Trajectory {
            rows: (0..300)
                .map(|i| {
                    let t_s = i as f64 / 30.0;
                    let theta = 0.5 * t_s;
                    TrajectoryRow {
                        t_s,
                        pose: Pose2::new(0.6 * theta.sin() + 1.0, 0.6 * (1.0 - theta.cos()), theta),
                        quality: 1.0,
                        sigma: None,
                    }
                })
                .collect(),
        }
    }

    #[test]
    fn a_clean_drive_keeps_every_frame() {
        let (kept, d) = drop_glitch_frames(&drive());
        assert_eq!((kept.rows.len(), d.total()), (300, 0));
        assert_eq!(d.note(300), None);
    }

    #[test]
    fn jumps_flips_and_zeros_are_dropped_and_named() {
        let mut t = drive();
        for i in [45, 135, 225] {
            t.rows[i].pose.x_m += 0.6;
            t.rows[i].pose.theta_rad += 0.5;
        }
        for i in [90, 91] {
            t.rows[i].pose.theta_rad += std::f64::consts::PI;
        }
        for i in [180, 181, 182, 183, 184, 185, 186, 187] {
            t.rows[i].pose = Pose2::new(0.0, 0.0, 0.0);
        }
        let (kept, d) = drop_glitch_frames(&t);
        assert_eq!((d.jumps, d.flips, d.zeros), (3, 2, 8), "{d:?}");
        assert_eq!(kept.rows.len(), 300 - 13);
        assert!((d.max_jump_m - 0.6).abs() < 0.01, "{d:?}");
        let note = d.note(300).expect("said");
        assert!(
            note.starts_with("13 of 300 frames dropped as lost, the first at 1.50 s")
                && note.contains("2 whose heading flipped by 180°")
                && note.contains("8 written as (0, 0, 0)"),
            "{note}"
        );
    }

    #[test]
    fn a_robot_at_the_origin_and_a_lasting_move_are_kept() {
        // Standing at the origin for a second before driving off from there.
        let mut t = drive();
        for r in &mut t.rows {
            r.t_s += 1.0;
            r.pose.x_m -= 1.0;
        }
        let rest = (0..30).map(|i| TrajectoryRow {
            t_s: i as f64 / 30.0,
            pose: Pose2::new(0.0, 0.0, 0.0),
            quality: 1.0,
            sigma: None,
        });
        t.rows = rest.chain(t.rows).collect();
        // A frame shift that stays: no way back, nothing dropped.
        for r in &mut t.rows[150..] {
            r.pose.x_m += 1.0;
        }
        let (kept, d) = drop_glitch_frames(&t);
        assert_eq!((kept.rows.len(), d.total()), (330, 0), "{d:?}");
    }
}
