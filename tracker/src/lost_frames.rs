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
/// container announces beyond those read and those the times show missing.
pub(crate) fn place_lost_frames_of(
    records: &mut [FrameRecord],
    source: &crate::source::SourceInfo,
) -> Vec<DroppedFrames> {
    let Some(announced) = source.frame_count else {
        return Vec::new();
    };
    let times: Vec<(usize, f64)> = records.iter().map(|r| (r.index, r.t_s)).collect();
    let (Some(step_s), dropped) = crate::timing::find_drops(&times) else {
        return Vec::new();
    };
    // Under --fps the container's own times show the frames it knows dropped.
    let dropped = match crate::timing::container_times(&times, source) {
        Some(own) => crate::timing::find_drops(&own).1,
        None => dropped,
    };
    let timed_missing: usize = dropped.iter().map(|d| d.missing).sum();
    let unaccounted = announced.saturating_sub(records.len() + timed_missing);
    place_lost_frames(records, unaccounted, step_s)
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
