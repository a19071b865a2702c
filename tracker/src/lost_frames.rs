//! Frames lost inside a video file. A damaged file's demuxer skips what it cannot read, and a
//! container that times frames by their count (AVI, whose index gives the n-th frame the n-th
//! slot) then times every later frame early by the frames lost: a file with 100 kB zeroed in
//! its middle put every later pose 2 frames early, 11 mm RMS from the truth, with no word but
//! a repeated image. The loss shows in the robot's motion: across it, the robot moves as far
//! in one frame's step as in several. Where the container's frame count confirms that many
//! frames are missing, the later frames are timed past them.

use crate::repeats::fix_position;
use crate::timing::DroppedFrames;
use crate::{FrameRecord, Outcome};

/// Steps shorter than this, metres, tell nothing of lost frames against the fixes' noise
/// (0.1–0.3 mm): 2 mm is 6 cm/s at 30 frames/s.
const MIN_STEP_M: f64 = 2e-3;

/// The steps on either side of a loss agree within this ratio: a robot changes speed by a few
/// percent a frame, and the lost frames' time lies between them (4 frames lost while braking
/// left 11.5 and 8.9 mm steps on either side). Their mean is the speed across the loss.
const STEADY_RATIO: f64 = 1.5;

/// How far a step, in its neighbours' lengths, may lie from a whole number of frames' motion.
const WHOLE_FRAMES: f64 = 0.2;

/// The most frame slots between the fixes on either side of a loss.
const MAX_SLOTS_ACROSS: usize = 3;

/// A step in time within this share of the usual step is one frame's.
const ONE_STEP: f64 = 0.2;

/// [`place_lost_frames`] for the frames of `source`: the frames unaccounted for are those its
/// container announces beyond those read and those the times show missing. Where no count
/// confirms a loss, [`place_unannounced_drops`] places those whose motion leaves no doubt.
/// Returns the losses the count confirms and those the motion alone shows.
pub(crate) fn place_lost_frames_of(
    records: &mut [FrameRecord],
    source: &crate::source::SourceInfo,
) -> (Vec<DroppedFrames>, Vec<DroppedFrames>) {
    let times: Vec<(usize, f64)> = records.iter().map(|r| (r.index, r.t_s)).collect();
    let (Some(step_s), dropped) = crate::timing::find_drops(&times) else {
        return (Vec::new(), Vec::new());
    };
    // Under --fps the container's own times show the frames it knows dropped, and the
    // timing warnings name the shift counting gives: the motion is not asked again.
    let own = crate::timing::container_times(&times, source);
    let dropped = match &own {
        Some(own) => crate::timing::find_drops(own).1,
        None => dropped,
    };
    let timed_missing: usize = dropped.iter().map(|d| d.missing).sum();
    let unaccounted = source.frame_count.map_or(0, |announced| {
        announced.saturating_sub(records.len() + timed_missing)
    });
    let lost = place_lost_frames(records, unaccounted, step_s);
    if !lost.is_empty() || own.is_some() {
        return (lost, Vec::new());
    }
    (Vec::new(), place_unannounced_drops(records, step_s))
}

/// Without a frame count to confirm a loss (a recording that dropped frames and was then
/// written at a constant rate: three drops in 87 frames put the trajectory 30 mm RMS off in
/// silence), the single steps around it lie on a line (the robot's speed changing evenly)
/// within this share of their mean and [`NOISE_M`]: a robot does not double its speed for
/// one frame.
const UNANNOUNCED_LINE_SHARE: f64 = 0.05;

/// The fixes' noise in a step's length, metres.
const NOISE_M: f64 = 0.3e-3;

/// How far such a step, in the speed the line gives there, may lie from a whole number of
/// frames: this many frames, or this share of the number where a longer loss lets the speed
/// change more across it (6 frames dropped as a robot braked from 8.0 to 6.7 mm steps left a
/// step of 6.85 of their mean).
const UNANNOUNCED_WHOLE_FRAMES: f64 = 0.15;
const UNANNOUNCED_WHOLE_SHARE: f64 = 0.05;

/// How many steps on each side of a step are searched for the single steps it is measured
/// against: drops two or three frames apart (frames 40 and 42 of 150) leave a double step
/// beside a double step, and measured only against its immediate neighbours neither was
/// found (27.8 mm RMS in silence).
const NEIGHBOUR_WINDOW: usize = 5;

/// Single steps wanted on each side of a step; on one side only at the start or end of a run
/// of fixes (a frame dropped after frame 0 or 1: 15 mm RMS in silence), that many.
const SINGLES_PER_SIDE: usize = 2;
const ONE_SIDED_SINGLES: usize = 4;

/// Fixes of consecutive frames: (record position, frame, time, place).
type Placed = (usize, usize, f64, nalgebra::Point2<f64>);

/// The line through the points (x, y) by least squares: its value at 0 and the largest
/// distance of a point from it.
fn line_at_zero(points: &[(f64, f64)]) -> (f64, f64) {
    let n = points.len() as f64;
    let (mx, my) = points
        .iter()
        .fold((0.0, 0.0), |(a, b), p| (a + p.0 / n, b + p.1 / n));
    let (sxy, sxx) = points.iter().fold((0.0, 0.0), |(a, b), p| {
        (a + (p.0 - mx) * (p.1 - my), b + (p.0 - mx).powi(2))
    });
    let slope = if sxx > 0.0 { sxy / sxx } else { 0.0 };
    let worst = points
        .iter()
        .map(|p| (p.1 - my - slope * (p.0 - mx)).abs())
        .fold(0.0, f64::max);
    (my - slope * mx, worst)
}

/// Finds the places where, between two frames one step apart in index and time, the robot
/// moved a whole number (two or more) of the steps its speed around gives: the speed is the
/// line through the nearest single steps on either side (two each), passing over steps of
/// several frames' motion themselves, so that drops close together are each measured against
/// the robot's speed, not against one another. At the start or end of a run of fixes, four
/// single steps on one side serve. Times every frame after each place past the frames the
/// step holds beyond one. Losses recurring at a fixed period all through the video are a
/// frame-rate conversion, named by the timing report, and are left alone. Returns the losses
/// placed.
pub(crate) fn place_unannounced_drops(
    records: &mut [FrameRecord],
    step_s: f64,
) -> Vec<DroppedFrames> {
    if step_s.is_nan() || step_s <= 0.0 {
        return Vec::new();
    }
    let fixes: Vec<Placed> = records
        .iter()
        .enumerate()
        .filter_map(|(i, r)| Some((i, r.index, r.t_s, fix_position(r)?)))
        .collect();
    let one_step =
        |a: &Placed, b: &Placed| b.1 == a.1 + 1 && ((b.2 - a.2) / step_s - 1.0).abs() <= ONE_STEP;
    // The length of each step between fixes one frame apart; None across a break.
    let steps: Vec<Option<f64>> = fixes
        .windows(2)
        .map(|w| one_step(&w[0], &w[1]).then(|| (w[1].3 - w[0].3).norm()))
        .collect();
    // The steps beside step j on the side `dir`, nearest first, up to a break: (offset, m).
    let side = |j: usize, dir: isize| -> Vec<(isize, f64)> {
        (1..=NEIGHBOUR_WINDOW as isize)
            .map_while(|k| {
                let at = j.checked_add_signed(dir * k)?;
                Some((dir * k, (*steps.get(at)?)?))
            })
            .collect()
    };
    // Steps of one frame's motion: those below one and a half of the lower third of the
    // steps around them (a braking robot's speed changes too much across them for a whole
    // number of one speed, but not by half; where a conversion doubles every other step,
    // their median may be a double).
    let single: Vec<bool> = (0..steps.len())
        .map(|j| {
            let Some(s) = steps[j] else { return false };
            let mut around: Vec<f64> = side(j, -1)
                .into_iter()
                .chain(side(j, 1))
                .filter(|p| p.0.abs() <= 3)
                .map(|p| p.1)
                .collect();
            around.push(s);
            around.sort_by(f64::total_cmp);
            s < 1.5 * around[around.len() / 3]
        })
        .collect();
    let mut losses: Vec<(usize, usize)> = Vec::new();
    for (j, step) in steps.iter().enumerate() {
        let Some(step) = *step else { continue };
        if single[j] {
            continue;
        }
        let singles = |dir: isize, want: usize| -> Vec<(f64, f64)> {
            side(j, dir)
                .into_iter()
                .filter(|p| single[j.saturating_add_signed(p.0)])
                .take(want)
                .map(|p| (p.0 as f64, p.1))
                .collect()
        };
        let (before, after) = (singles(-1, SINGLES_PER_SIDE), singles(1, SINGLES_PER_SIDE));
        let points = if before.len() == SINGLES_PER_SIDE && after.len() == SINGLES_PER_SIDE {
            [before, after].concat()
        } else if side(j, -1).len() < SINGLES_PER_SIDE || side(j, 1).len() < SINGLES_PER_SIDE {
            // At the start or end of a run: the long side's singles, and the short side's.
            let dir = if side(j, -1).len() < side(j, 1).len() {
                1
            } else {
                -1
            };
            let long = singles(dir, ONE_SIDED_SINGLES);
            if long.len() < ONE_SIDED_SINGLES {
                continue;
            }
            [long, singles(-dir, 1)].concat()
        } else {
            continue;
        };
        let (speed, worst) = line_at_zero(&points);
        let low = points.iter().map(|p| p.1).fold(f64::INFINITY, f64::min);
        if low < MIN_STEP_M || worst > UNANNOUNCED_LINE_SHARE * speed + NOISE_M {
            continue;
        }
        let frames = step / speed;
        let whole = frames.round();
        let tolerance = UNANNOUNCED_WHOLE_FRAMES.max(UNANNOUNCED_WHOLE_SHARE * whole);
        if whole >= 2.0 && (frames - whole).abs() <= tolerance {
            losses.push((fixes[j + 1].0, whole as usize - 1));
        }
    }
    // A conversion leaves steps out at a fixed period all through the video; a few drops at
    // a period over a stretch of it (frames 20, 23, 26, 29 of 150) are drops: the pattern
    // carried on both ways finds single steps where its steps of several frames would be.
    let regular = losses.len() >= 3
        && losses.windows(3).all(|l| {
            let (a, b) = (l[1].0 - l[0].0, l[2].0 - l[1].0);
            a.abs_diff(b) <= 1
        });
    let periodic = regular && {
        let at: Vec<usize> = losses
            .iter()
            .filter_map(|l| fixes.iter().position(|f| f.0 == l.0)?.checked_sub(1))
            .collect();
        let period = (at[at.len() - 1] - at[0]) as f64 / (at.len() - 1) as f64;
        let single_near = |j: f64| {
            let j = j.round() as usize;
            (j.saturating_sub(1)..=j + 1).all(|k| steps.get(k).is_some_and(|s| s.is_some()))
                && (j.saturating_sub(1)..=j + 1).all(|k| single[k])
        };
        let (first, last) = (at[0] as f64, at[at.len() - 1] as f64);
        let mut before = (1..)
            .map(|k| first - k as f64 * period)
            .take_while(|&j| j >= 1.0);
        let mut after = (1..)
            .map(|k| last + k as f64 * period)
            .take_while(|&j| j + 1.0 < steps.len() as f64);
        // A conversion may start a few frames in (FFmpeg's -r keeps the first frames): the
        // pattern broken on one side only is still one.
        !(before.any(single_near) && after.any(single_near))
    };
    if periodic {
        return Vec::new();
    }
    retime(records, &losses, step_s)
}

/// Finds the places where the robot moved several frames' distance over one frame's step in
/// time, and when their lost frames add up to no more than `unaccounted` (the frames the
/// container announces beyond those read and those whose absence the times show), times every
/// frame after each place past its lost frames (`step_s` each). Returns the losses placed;
/// none when the count does not confirm them.
pub(crate) fn place_lost_frames(
    records: &mut [FrameRecord],
    unaccounted: usize,
    step_s: f64,
) -> Vec<DroppedFrames> {
    if unaccounted == 0 || step_s.is_nan() || step_s <= 0.0 {
        return Vec::new();
    }
    // Fixes of consecutive frames one step apart in time: (record position, frame, time, place).
    let fixes: Vec<(usize, usize, f64, nalgebra::Point2<f64>)> = records
        .iter()
        .enumerate()
        .filter_map(|(i, r)| Some((i, r.index, r.t_s, fix_position(r)?)))
        .collect();
    let one_step = |a: &(usize, usize, f64, nalgebra::Point2<f64>),
                    b: &(usize, usize, f64, nalgebra::Point2<f64>)| {
        b.1 == a.1 + 1 && ((b.2 - a.2) / step_s - 1.0).abs() <= ONE_STEP
    };
    let mut losses: Vec<(usize, usize)> = Vec::new();
    for w in fixes.windows(4) {
        // Across the loss, the decoder may have given a damaged frame completed from the one
        // before (a repeated image, not tracked): a few slots without a fix are taken.
        let slots = w[2].1 - w[1].1;
        let spans = (1..=MAX_SLOTS_ACROSS).contains(&slots)
            && ((w[2].2 - w[1].2) / (slots as f64 * step_s) - 1.0).abs() <= ONE_STEP;
        if !(one_step(&w[0], &w[1]) && spans && one_step(&w[2], &w[3])) {
            continue;
        }
        let (before, across, after) = (
            (w[1].3 - w[0].3).norm(),
            (w[2].3 - w[1].3).norm(),
            (w[3].3 - w[2].3).norm(),
        );
        if before.min(after) < MIN_STEP_M || before.max(after) > STEADY_RATIO * before.min(after) {
            continue;
        }
        let frames = across / (0.5 * (before + after));
        let whole = frames.round();
        if whole > slots as f64 && (frames - whole).abs() <= WHOLE_FRAMES {
            losses.push((w[2].0, whole as usize - slots));
        }
    }
    if losses.is_empty() || losses.iter().map(|l| l.1).sum::<usize>() > unaccounted {
        return Vec::new();
    }
    retime(records, &losses, step_s)
}

/// Times every record from each loss's (record position, frames missing) on past the frames
/// missing there and before. Returns the losses as placed.
fn retime(
    records: &mut [FrameRecord],
    losses: &[(usize, usize)],
    step_s: f64,
) -> Vec<DroppedFrames> {
    let mut placed = Vec::with_capacity(losses.len());
    let mut shift_s = 0.0;
    let mut next = losses.iter().peekable();
    for i in 0..records.len() {
        if let Some(&&(at, missing)) = next.peek() {
            if at == i {
                next.next();
                shift_s += missing as f64 * step_s;
                let before = &records[i - 1];
                placed.push(DroppedFrames {
                    after_frame: before.index,
                    after_s: before.t_s,
                    next_s: records[i].t_s + shift_s,
                    missing,
                });
            }
        }
        if shift_s > 0.0 {
            let r = &mut records[i];
            r.t_s += shift_s;
            if let Outcome::Fix(f) = &mut r.outcome {
                f.t_s += shift_s;
            }
        }
    }
    placed
}

#[cfg(test)]
mod tests {
    use super::place_unannounced_drops;
    use crate::repeats::tests::record;

    const STEP_S: f64 = 1.0 / 30.0;

    /// Records of consecutive frames at the places `x` (metres along a line).
    fn records(x: &[f64]) -> Vec<crate::FrameRecord> {
        x.iter().enumerate().map(|(i, &x)| record(i, x)).collect()
    }

    /// Places of a robot stepping `step(k)` metres in frame k's step.
    fn path(n: usize, step: impl Fn(usize) -> f64) -> Vec<f64> {
        (0..n)
            .scan(0.0, |x, k| {
                *x += step(k);
                Some(*x)
            })
            .collect()
    }

    #[test]
    fn frames_dropped_in_steady_motion_are_timed_past() {
        // 7 mm a frame; two frames missing between 10 and 11 of those read.
        let mut x = path(30, |_| 7e-3);
        for v in x.iter_mut().skip(11) {
            *v += 14e-3;
        }
        let mut r = records(&x);
        let placed = place_unannounced_drops(&mut r, STEP_S);
        assert_eq!(placed.len(), 1, "{placed:?}");
        assert_eq!((placed[0].after_frame, placed[0].missing), (10, 2));
        assert!((r[11].t_s - 13.0 * STEP_S).abs() < 1e-9);
        assert!((r[29].t_s - 31.0 * STEP_S).abs() < 1e-9);
    }

    /// The places of a robot at `x`, read with the frames `dropped` left out.
    fn dropped(x: &[f64], dropped: &[usize]) -> Vec<crate::FrameRecord> {
        let x: Vec<f64> = (0..x.len())
            .filter(|k| !dropped.contains(k))
            .map(|k| x[k])
            .collect();
        records(&x)
    }

    #[test]
    fn drops_close_together_and_at_the_start_are_each_timed_past() {
        // Drops two and three frames apart were measured against each other's double steps
        // and missed (27.8 mm RMS); one after frame 0 or 1 had no steps before it to compare.
        for drops in [
            vec![40, 42],
            vec![40, 43],
            vec![20, 23, 26, 29],
            vec![100, 102, 104],
            vec![1],
            vec![2],
            vec![147],
        ] {
            // Steady at 7 mm a frame, and braking 1 % a frame from 13 mm.
            for x in [
                path(150, |_| 7e-3),
                path(150, |k| 13e-3 * 0.99_f64.powi(k as i32)),
            ] {
                let mut r = dropped(&x, &drops);
                let placed = place_unannounced_drops(&mut r, STEP_S);
                let missing: usize = placed.iter().map(|d| d.missing).sum();
                assert_eq!(missing, drops.len(), "{drops:?}: {placed:?}");
                for (i, k) in (0..150).filter(|k| !drops.contains(k)).enumerate() {
                    assert!(
                        (r[i].t_s - k as f64 * STEP_S).abs() < 1e-9,
                        "{drops:?}: {k}"
                    );
                }
            }
        }
    }

    #[test]
    fn smooth_acceleration_braking_and_rest_are_not_drops() {
        // Accelerating 8 % a frame, braking as hard, and standing still (the fixes' noise).
        let cases = [
            path(40, |k| 2e-3 * 1.08_f64.powi(k as i32)),
            path(40, |k| 30e-3 * 0.92_f64.powi(k as i32)),
            path(40, |k| if k % 2 == 0 { 1e-4 } else { -1e-4 }),
        ];
        for x in cases {
            let mut r = records(&x);
            assert!(place_unannounced_drops(&mut r, STEP_S).is_empty());
            assert!((r[39].t_s - 39.0 * STEP_S).abs() < 1e-9);
        }
    }

    #[test]
    fn a_regular_pattern_of_double_steps_is_left_to_the_conversion_report() {
        // Every tenth frame left out (30 to 27 fps), the rest on an even grid.
        let x = path(40, |k| if k % 10 == 5 { 14e-3 } else { 7e-3 });
        let mut r = records(&x);
        assert!(place_unannounced_drops(&mut r, STEP_S).is_empty());
        // 30 to 20 fps from the sixth frame on, as FFmpeg's -r converts.
        let x = path(24, |k| if k >= 6 && k % 2 == 0 { 14e-3 } else { 7e-3 });
        let mut r = records(&x);
        assert!(place_unannounced_drops(&mut r, STEP_S).is_empty());
    }
}
