//! The video's timeline as tracking found it: how frames were timed, frames dropped (a step in
//! time longer than the usual one), duplicate timestamps, repeated images, and a file that
//! ends before the frames its container announces. Ground truth timed wrongly is wrong, so
//! each of these is reported on stderr and in the track report.

use crate::repeats::{fix_position, MIN_EXPECTED_STEP_M};
use crate::{GapReason, Outcome, TrackResult};

/// A run of frames missing from the video between two frames that are there.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct DroppedFrames {
    /// The frame (decode order, from 0) after which frames are missing.
    pub after_frame: usize,
    /// Its time, seconds.
    pub after_s: f64,
    /// The next frame's time, seconds.
    pub next_s: f64,
    /// Frames missing (the step in time over the usual step, minus one).
    pub missing: usize,
}

/// How the frames were timed and what is wrong with the timeline.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct TimingReport {
    /// Where the frame times come from ("container timestamps", "frame count at 30 fps").
    pub timing: String,
    /// Frames decoded.
    pub frames_read: usize,
    /// Frames the container announces (its own estimate for some formats).
    pub frames_announced: Option<usize>,
    /// The usual step between frames (median), seconds.
    pub frame_step_s: Option<f64>,
    /// Runs of dropped frames.
    pub dropped: Vec<DroppedFrames>,
    /// Dropped frames in all (those of `dropped` and of `dropped_by_motion`).
    pub dropped_frames: usize,
    /// Steps in time of several frames across which the robot moved as far as in one frame:
    /// the camera's clock jumped (every later time is off by the jump), no frame was lost.
    pub clock_jumps: Vec<DroppedFrames>,
    /// Frames lost inside the file where its container times frames by their count: the
    /// robot moved several frames' distance in one frame's step there, and the container's
    /// frame count says that many are missing; the later frames were timed past them.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub lost_in_file: Vec<DroppedFrames>,
    /// Frames dropped where neither the times nor a frame count show them (a recording that
    /// dropped frames, then written at a constant rate): the robot moved a whole number of its
    /// steady steps, two or more, in one frame's time there; the later frames were timed past
    /// them. They are counted in `dropped_frames`.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub dropped_by_motion: Vec<DroppedFrames>,
    /// Frames whose timestamp is not after the previous one (not tracked).
    pub duplicate_times: usize,
    /// Frames identical to the previous one, or whose fix stands where the previous one's
    /// stood while the robot moves, that the motion places after the image's own slot (not
    /// tracked). A still scene's identical frames are tracked and not counted.
    pub repeated_images: usize,
    /// Slots of dropped frames filled with the next frame's image (a conversion to a constant
    /// frame rate): the motion places the image at the later slot, where it was tracked.
    pub filled_drops: usize,
    /// The rate the frames were recorded at, frames/s, when the robot's motion shows the
    /// video's rate converted from it (frames repeated or left out in a regular pattern, the
    /// rest timed on the new rate's grid): the times are then not the camera's.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub converted_from_fps: Option<f64>,
    /// Frames of the file that could not be decoded whole (damaged JPEG data), left out: they
    /// are among the dropped frames.
    pub corrupt_frames: Vec<usize>,
    /// An image folder's frame files among `corrupt_frames`, each with what is wrong with it.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub corrupt_files: Vec<String>,
    /// Frames without a container timestamp that ffprobe could not time either (the last
    /// frames of a video with B-frames), timed one step after the previous.
    pub extrapolated_times: usize,
    /// Frames the container announces beyond those read and those dropped: the file ends early.
    pub missing_at_end: usize,
    /// The video's own frame rate when `--fps` overrode it with another, frames/s: the step
    /// between its timestamps' when it has them (an MP4 states the average rate of the frames
    /// it holds, which drops lower), else the rate its container states.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub overridden_fps: Option<f64>,
    /// `--fps` when it timed a video's frames by counting in the place of the container's
    /// timestamps, frames/s; the step and the frames dropped above are then the timestamps'.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub fps_over_timestamps: Option<f64>,
    /// The first frame's time on the container's own clock (its start time), seconds, when
    /// it is not 0: the fixes count from the first frame, so a clock that started with the
    /// container reads this much more.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub first_frame_clock_s: Option<f64>,
}

/// The usual step between `times` (their median step forward) and the runs of frames missing
/// between them: a step longer than [`DROP_STEP_FACTOR`] usual ones. `times` are (frame index,
/// seconds) in decode order.
pub(crate) fn find_drops(times: &[(usize, f64)]) -> (Option<f64>, Vec<DroppedFrames>) {
    let mut steps: Vec<f64> = times
        .windows(2)
        .map(|w| w[1].1 - w[0].1)
        .filter(|d| *d > 0.0)
        .collect();
    steps.sort_by(f64::total_cmp);
    let Some(step) = steps.get(steps.len() / 2).copied() else {
        return (None, Vec::new());
    };
    let mut dropped = Vec::new();
    let mut last = times.first().copied();
    for &(index, t) in times.iter().skip(1) {
        if let Some((last_index, last_t)) = last {
            let d = t - last_t;
            if d > DROP_STEP_FACTOR * step {
                dropped.push(DroppedFrames {
                    after_frame: last_index,
                    after_s: last_t,
                    next_s: t,
                    missing: ((d / step).round() as usize).saturating_sub(1).max(1),
                });
            }
            if d <= 0.0 {
                continue; // a duplicate time: the next step counts from the last good one
            }
        }
        last = Some((index, t));
    }
    (Some(step), dropped)
}

/// Whether the robot's fixes on both sides of the time step `d` lie as close as one frame
/// apart, where its fixes elsewhere show it moving: then the step is the clock's, not lost
/// frames'. Needs fixes at both frames and a robot moving at least 0.5 mm a frame around.
fn is_clock_jump(r: &TrackResult, d: &DroppedFrames) -> bool {
    const MIN_FRAMES: usize = 3;
    if d.missing < MIN_FRAMES {
        return false;
    }
    let fix_at = |index: usize| {
        r.records
            .iter()
            .find(|x| x.index == index)
            .and_then(|x| match &x.outcome {
                Outcome::Fix(f) => Some(f.pose.position()),
                _ => None,
            })
    };
    let (Some(a), Some(b)) = (fix_at(d.after_frame), fix_at(d.after_frame + 1)) else {
        return false;
    };
    // The robot's motion per frame over the few frames before the step.
    let before: Vec<f64> = (d.after_frame.saturating_sub(5)..d.after_frame)
        .filter_map(|k| Some((fix_at(k + 1)? - fix_at(k)?).norm()))
        .collect();
    if before.is_empty() {
        return false;
    }
    let per_frame = before.iter().sum::<f64>() / before.len() as f64;
    per_frame >= 0.0005 && (b - a).norm() <= 2.0 * per_frame
}

/// Steps between the fixes of consecutive frames over which the robot moved twice as far as
/// its speed on the slower step beside gives (the times stepping evenly), and the steps
/// measured: a video whose frame rate was lowered by leaving frames out and timing the rest
/// on an even grid.
fn double_steps(r: &TrackResult) -> (usize, usize) {
    let fixes: Vec<(usize, f64, nalgebra::Point2<f64>)> = r
        .records
        .iter()
        .filter_map(|x| Some((x.index, x.t_s, fix_position(x)?)))
        .collect();
    // Speeds over steps between consecutive frames: (frame, m/s, step m).
    let steps: Vec<(usize, f64, f64)> = fixes
        .windows(2)
        .filter(|w| w[1].0 == w[0].0 + 1 && w[1].1 > w[0].1)
        .map(|w| {
            let d = (w[1].2 - w[0].2).norm();
            (w[1].0, d / (w[1].1 - w[0].1), d)
        })
        .collect();
    let (mut doubled, mut measured) = (0, 0);
    for w in steps.windows(3) {
        let consecutive = w[1].0 == w[0].0 + 1 && w[2].0 == w[1].0 + 1;
        if !consecutive || w[0].2.min(w[2].2) < MIN_EXPECTED_STEP_M {
            continue;
        }
        measured += 1;
        // Against the slower side: steps of one and two frames' motion may alternate.
        let ratio = w[1].1 / w[0].1.min(w[2].1);
        if (1.6..2.4).contains(&ratio) {
            doubled += 1;
        }
    }
    (doubled, measured)
}

/// How many frames fewer than its container announces a video may hold unremarked: an AVI's
/// index counts its frames exactly (a file with 2 of 60 frames lost inside, where the robot
/// rested, said nothing), while other containers may only estimate theirs from a duration.
fn count_tolerance(r: &TrackResult, announced: usize) -> usize {
    let avi = r
        .source
        .path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("avi"));
    if avi {
        0
    } else {
        2.max(announced / 50)
    }
}

/// Frames repeating an image that held a fix: a still stretch without the tag (the robot out
/// of view over a still scene, frames a codec repeats whole) is no camera repeating frames
/// nor a frame-rate conversion, and tracking it would find nothing either (21 such frames
/// were named as both).
fn repeats_of_tagged_images(r: &TrackResult) -> usize {
    let mut tagged = false;
    let mut n = 0;
    for x in &r.records {
        match x.outcome {
            Outcome::Gap(GapReason::RepeatedImage) => n += usize::from(tagged),
            Outcome::Gap(GapReason::FilledDrop) => {}
            Outcome::Fix(_) => tagged = true,
            Outcome::Gap(_) => tagged = false,
        }
    }
    n
}

/// The container's own times of the frames `times` lists (frame index, seconds) when `--fps`
/// timed them by counting in their place; `None` when the frames carry the container's times.
pub(crate) fn container_times(
    times: &[(usize, f64)],
    source: &crate::source::SourceInfo,
) -> Option<Vec<(usize, f64)>> {
    source.container_times_s.as_ref().map(|own| {
        times
            .iter()
            .filter_map(|&(index, _)| Some((index, *own.get(index)?)))
            .collect()
    })
}

/// A step longer than this many usual steps means frames were dropped.
const DROP_STEP_FACTOR: f64 = 1.5;

impl TimingReport {
    /// The timeline of a tracking run.
    pub fn of(r: &TrackResult) -> Self {
        let times: Vec<(usize, f64)> = r.records.iter().map(|x| (x.index, x.t_s)).collect();
        // Under --fps the container's own times are what shows frames dropped: counted times
        // never step over one.
        let own_times = container_times(&times, &r.source);
        let fps_over_timestamps = own_times
            .as_ref()
            .and_then(|_| find_drops(&times).0)
            .map(|counted_step| 1.0 / counted_step);
        let times = own_times.unwrap_or(times);
        let (step, dropped) = find_drops(&times);
        let overridden_fps = match (fps_over_timestamps, step) {
            (Some(given), Some(own_step)) => {
                ((given * own_step - 1.0).abs() > 0.01).then_some(1.0 / own_step)
            }
            _ => r.source.overridden_fps,
        };
        // A time step of many frames across which the robot moved as far as in one frame is
        // the camera's clock jumping, not frames lost: told apart where the robot moves.
        let (clock_jumps, dropped): (Vec<DroppedFrames>, Vec<DroppedFrames>) =
            dropped.into_iter().partition(|d| is_clock_jump(r, d));
        // Frames lost inside the file or placed by the motion were timed past by tracking, not
        // by the container.
        let dropped: Vec<DroppedFrames> = dropped
            .into_iter()
            .filter(|d| {
                !r.lost_in_file
                    .iter()
                    .chain(&r.dropped_by_motion)
                    .any(|l| l.after_frame == d.after_frame)
            })
            .collect();
        let count = |reason| {
            r.records
                .iter()
                .filter(|x| x.outcome == Outcome::Gap(reason))
                .count()
        };
        let dropped_frames: usize = dropped
            .iter()
            .chain(&r.dropped_by_motion)
            .map(|d| d.missing)
            .sum();
        let frames_read = r.records.len();
        let lost_frames: usize = r.lost_in_file.iter().map(|d| d.missing).sum();
        let announced = r.source.frame_count;
        // Some containers only estimate their frame count: a few frames either way are normal.
        // Where the container states its rate, the frames missing are those its duration holds
        // beyond the last frame read: a container counting frames at twice the rate the
        // frames come at (an AVI of repeated frames written as empty chunks) is not cut short.
        let span = match (times.first(), times.last(), step) {
            (Some(a), Some(b), Some(s)) => Some((b.1 - a.1 + s, s)),
            _ => None,
        };
        let missing_at_end = announced.map_or(0, |a| {
            let missing = match (r.source.container_fps, span) {
                (Some(fps), Some((covered, s))) if fps > 0.0 => {
                    let beyond = (a as f64 / fps - covered) / s;
                    if beyond > 0.0 {
                        beyond.round() as usize
                    } else {
                        0
                    }
                }
                _ => a.saturating_sub(frames_read + dropped_frames + lost_frames),
            };
            if missing > count_tolerance(r, a) {
                missing
            } else {
                0
            }
        });
        let repeated_images = repeats_of_tagged_images(r);
        let filled_drops = count(GapReason::FilledDrop);
        let converted_from_fps = step.and_then(|step| {
            // One frame in ten or more repeated, or one step in twenty or more doubled, is a
            // pattern: a camera missing a frame now and then does neither so often.
            let (doubled, measured) = double_steps(r);
            let fps = 1.0 / step;
            let repeats = repeated_images + filled_drops;
            if repeats >= 3 && repeats * 10 >= frames_read {
                Some(fps * (1.0 - repeats as f64 / frames_read as f64))
            } else if doubled >= 3 && doubled * 20 >= measured {
                Some(fps * (1.0 + doubled as f64 / measured as f64))
            } else {
                None
            }
        });
        Self {
            timing: r.source.timing.clone(),
            frames_read,
            frames_announced: announced,
            frame_step_s: step,
            dropped,
            dropped_frames,
            clock_jumps,
            lost_in_file: r.lost_in_file.clone(),
            dropped_by_motion: r.dropped_by_motion.clone(),
            duplicate_times: count(GapReason::DuplicateTime),
            repeated_images,
            filled_drops,
            converted_from_fps,
            corrupt_frames: r.source.corrupt_frames.clone(),
            corrupt_files: r.source.corrupt_files.clone(),
            extrapolated_times: r.source.extrapolated_times,
            missing_at_end,
            overridden_fps,
            fps_over_timestamps,
            first_frame_clock_s: r.source.first_frame_clock_s,
        }
    }

    /// The warning for an `--fps` that is not the video's own rate.
    fn overridden_fps_warning(&self) -> Option<String> {
        let own = self.overridden_fps?;
        let given = self
            .fps_over_timestamps
            .or(self.frame_step_s.map(|s| 1.0 / s))?;
        let round = |f: f64| (f * 1e3).round() / 1e3;
        // Without timestamps to tell, some percent off is as likely a video of that rate whose
        // container averaged in dropped or doubled frames: counting frames then shifts every
        // frame after one.
        if self.fps_over_timestamps.is_none() && (own / given - 1.0).abs() < 0.15 {
            return Some(format!(
                "--fps {} replaces the timestamps of a video whose container averages {} fps, as a {} fps recording with dropped or repeated frames does: counting frames shifts every frame after such a drop by a frame or more; leave --fps out to time the frames by their timestamps",
                round(given),
                round(own),
                round(given)
            ));
        }
        let source = match self.fps_over_timestamps {
            Some(_) => "its timestamps step at",
            None => "its container states",
        };
        Some(format!(
            "--fps {} overrides the video's own rate ({source} {} fps): every time is {:.3} times what the video says, and every speed {:.3} times; leave --fps out to time the frames by the video",
            round(given),
            round(own),
            own / given,
            given / own
        ))
    }

    /// The warning naming the frames dropped: a gap in the trajectory when the frames are timed
    /// by their timestamps, a shift of every later frame when `--fps` counts them instead.
    fn dropped_warning(&self) -> String {
        let runs: Vec<String> = self
            .dropped
            .iter()
            .take(5)
            .map(|d| {
                format!(
                    "{} after frame {} ({:.3} s)",
                    d.missing, d.after_frame, d.after_s
                )
            })
            .collect();
        let more = if self.dropped.len() > 5 { ", …" } else { "" };
        let places = match self.dropped.len() {
            1 => "1 place".to_string(),
            n => format!("{n} places"),
        };
        let dropped = format!(
            "{} frames dropped in {places} ({}{more})",
            self.dropped_frames,
            runs.join(", ")
        );
        if let Some(fps) = self.fps_over_timestamps {
            return format!(
                "{dropped}, as the video's timestamps show; --fps {} times the frames by counting instead, which puts every frame after a drop as many frames early as were dropped before it, so the trajectory is mistimed from frame {} on: leave --fps out to time the frames by their timestamps",
                (fps * 1e3).round() / 1e3,
                self.dropped[0].after_frame + 1
            );
        }
        format!(
            "{dropped}; the times of the frames after them come from the {}, so the trajectory has gaps there, not shifts",
            self.timing
        )
    }

    /// The warning naming the frames the robot's motion shows dropped where the times do not.
    fn dropped_by_motion_warning(&self) -> String {
        let n: usize = self.dropped_by_motion.iter().map(|d| d.missing).sum();
        let places: Vec<String> = self
            .dropped_by_motion
            .iter()
            .map(|d| {
                format!(
                    "{} after frame {} ({:.3} s)",
                    d.missing, d.after_frame, d.after_s
                )
            })
            .collect();
        format!(
            "{n} frame{} look{} dropped where the file's times step evenly ({}): the robot moved 2 or more of its steady steps in one frame's time there, as a recording that dropped frames and was then written at a constant rate shows; the frames after each were timed past the frames dropped. Check the recording for dropped frames (record with timestamps, or at a rate the camera keeps up with)",
            if n == 1 { "" } else { "s" },
            if n == 1 { "s" } else { "" },
            places.join(", ")
        )
    }

    /// The warning naming the dropped frames whose slots hold the next frame's image.
    fn filled_drops_warning(&self) -> String {
        let n = self.filled_drops;
        format!(
            "{n} {} dropped and {} filled with the next frame's image (a conversion to a constant frame rate, as FFmpeg's default MP4 output does): the robot's motion places each such image at the later slot, where it was tracked, and the dropped {} left as {}",
            if n == 1 { "frame was" } else { "frames were" },
            if n == 1 { "its slot" } else { "their slots" },
            if n == 1 { "frame is" } else { "frames are" },
            if n == 1 { "a gap" } else { "gaps" },
        )
    }

    /// One warning line per problem with the timeline (none for a clean video).
    pub fn warnings(&self) -> Vec<String> {
        let mut w = Vec::new();
        if self.extrapolated_times > 0 {
            w.push(format!(
                "the last {} frames come without a timestamp from OpenCV (frames a decoder reordering B-frames gives out at the end) and ffprobe could not read their packets' times, so each was timed one step after the frame before: a frame dropped among them would put them a step early; install FFmpeg's ffprobe (`make deps`) to time them by the video",
                self.extrapolated_times
            ));
        }
        w.extend(self.overridden_fps_warning());
        // A file whose first frames were cut or dropped before it was written keeps their
        // time as its start: tracked from t = 0, every fix was 33 ms early against the truth
        // (15.3 mm RMS) in silence.
        if let Some(c) = self.first_frame_clock_s {
            w.push(format!(
                "the video's first frame is at {c:.3} s on its container's clock (its start time), and the fixes count from that frame (t = 0): against a clock that started with the container (frames cut or dropped before the first one kept), add {c:.3} s to the fixes' times"
            ));
        }
        for l in &self.lost_in_file {
            w.push(format!(
                "{} frame{} lost inside the file after frame {} ({:.3} s): the robot moved {} frames' distance further there than the frames' times allow, and the container announces {} frames where {} were read; the frames after it were timed {} frame{} later than the container times them (a damaged file read past what could not be read)",
                l.missing,
                if l.missing == 1 { " was" } else { "s were" },
                l.after_frame,
                l.after_s,
                l.missing,
                self.frames_announced.unwrap_or(0),
                self.frames_read,
                l.missing,
                if l.missing == 1 { "" } else { "s" },
            ));
        }
        if !self.dropped_by_motion.is_empty() {
            w.push(self.dropped_by_motion_warning());
        }
        if !self.dropped.is_empty() {
            w.push(self.dropped_warning());
        }
        for j in &self.clock_jumps {
            let off = j.next_s - j.after_s - self.frame_step_s.unwrap_or(0.0);
            let advice = match self.fps_over_timestamps {
                Some(_) => "--fps times the frames by counting, which leaves the jump out".to_string(),
                None => format!("every later time is about {off:.3} s off; mend the timestamps (or time the frames by counting, --fps)"),
            };
            w.push(format!(
                "the timestamps jump {:.3} s after frame {} ({:.3} s), yet the robot moved there as far as in one frame: the camera's clock jumped, no frame was lost; {advice}",
                j.next_s - j.after_s,
                j.after_frame,
                j.after_s,
            ));
        }
        if !self.corrupt_files.is_empty() {
            let n = self.corrupt_files.len();
            w.push(format!(
                "{n} frame {} could not be decoded whole ({}{}) and {} left out as {}; a frame decoded in part holds grey or leftover rows where its data is missing, and a tag there would be read wrong",
                if n == 1 { "file" } else { "files" },
                self.corrupt_files.iter().take(5).cloned().collect::<Vec<_>>().join(", "),
                if n > 5 { ", …" } else { "" },
                if n == 1 { "was" } else { "were" },
                if n == 1 { "a gap" } else { "gaps" },
            ));
        } else if !self.corrupt_frames.is_empty() {
            let list: Vec<String> = self
                .corrupt_frames
                .iter()
                .take(5)
                .map(|i| i.to_string())
                .collect();
            w.push(format!(
                "{} {} of the file could not be decoded whole (damaged JPEG data: frame {}{}) and {} left out as {}; a damaged frame decodes as leftover memory, often the frame before, whose tag would be an earlier pose under a later time",
                self.corrupt_frames.len(),
                if self.corrupt_frames.len() == 1 { "frame" } else { "frames" },
                list.join(", "),
                if self.corrupt_frames.len() > 5 { ", …" } else { "" },
                if self.corrupt_frames.len() == 1 { "was" } else { "were" },
                if self.corrupt_frames.len() == 1 { "a gap" } else { "gaps" },
            ));
        }
        if self.duplicate_times > 0 {
            w.push(format!(
                "{} frames have a timestamp that is not after the previous frame's; they were not tracked",
                self.duplicate_times
            ));
        }
        if self.repeated_images > 0 {
            w.push(format!(
                "{} the previous frame's image, byte for byte or where the tag is (giving its pose, to the fixes' noise while the robot moves), and the robot's motion places the image at the earlier frame (a camera repeating a frame it missed, a damaged frame the decoder completed from the one before, or a frame rate raised by repeating frames); {} not tracked",
                if self.repeated_images == 1 {
                    "1 frame repeats".to_string()
                } else {
                    format!("{} frames repeat", self.repeated_images)
                },
                if self.repeated_images == 1 { "it was" } else { "they were" }
            ));
        }
        if self.filled_drops > 0 {
            w.push(self.filled_drops_warning());
        }
        if let (Some(from), Some(step)) = (self.converted_from_fps, self.frame_step_s) {
            w.push(format!(
                "the robot's motion shows the frame rate converted to {:.1} fps from about {from:.0} fps ({}): the timestamps are the conversion's grid, not the camera's, so a frame's time can be up to a frame off its image (at 1 m/s, {:.0} mm); track the video as the camera recorded it",
                1.0 / step,
                if self.repeated_images + self.filled_drops > 0 {
                    "frames repeated in a regular pattern"
                } else {
                    "steps of two frames' motion in a regular pattern: frames left out and the rest re-timed"
                },
                1e3 * step
            ));
        }
        if self.missing_at_end > 0 {
            let announced = format!(
                "the container announces {} frames but only {} were read",
                self.frames_announced.unwrap_or(0),
                self.frames_read
            );
            // Under --fps the timestamps' own timeline counted the drops: what is left is a cut.
            w.push(if self.timing.starts_with("frame count") && self.fps_over_timestamps.is_none() {
                format!(
                    "{announced}: {} frames are missing (dropped, or the file is cut short), and frames timed by counting shift after every drop: track without --fps to use the container's timestamps",
                    self.missing_at_end
                )
            } else {
                format!(
                    "{announced} ({} dropped): the file looks cut short, about {} frames are missing, at its end or inside it where the robot's motion could not place them (at rest, or without fixes around them); frames after a loss inside are timed early by it",
                    self.dropped_frames, self.missing_at_end
                )
            });
        }
        w
    }
}

#[cfg(test)]
mod tests {
    use super::TimingReport;
    use crate::repeats::tests::{record, track_result};

    /// Frames lost inside an AVI where the robot rests leave nothing for its motion to place:
    /// 2 of 60 were said nothing of, the tolerance for containers that estimate their count.
    #[test]
    fn an_avi_missing_frames_it_announces_is_named() {
        let resting: Vec<_> = (0..58).map(|i| record(i, 0.5)).collect();
        let avi = TimingReport::of(&track_result(resting.clone(), "run.avi", 60));
        assert_eq!(avi.missing_at_end, 2);
        assert!(
            avi.warnings().iter().any(|w| w.contains(
                "the container announces 60 frames but only 58 were read (0 dropped): the file looks cut short, about 2 frames are missing, at its end or inside it"
            )),
            "{:?}",
            avi.warnings()
        );
        // A Matroska file's count may be estimated from its duration: 2 in 60 pass.
        let mkv = TimingReport::of(&track_result(resting, "run.mkv", 60));
        assert_eq!(mkv.missing_at_end, 0);
    }
}
