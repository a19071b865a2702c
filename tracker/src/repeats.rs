//! Which frame slot a repeated image belongs to. A video holds one image in two or more slots
//! in a row when the camera repeated a frame it missed (the image belongs to the first slot),
//! when a conversion to a constant frame rate filled a dropped frame's slot with the next
//! frame's image (FFmpeg's default MP4: the image belongs to the last slot), or when nothing
//! moved (H.264 decodes a still scene's frames identical: the pose is right at every slot).
//! The robot's motion tells them apart: the steps into the image and out of it are in the
//! proportion of the frame times between them.

use crate::{Fix, FrameRecord, GapReason, Outcome};
use odocal_core::{wrap_angle, Pose2};

/// Below this step expected from the robot's speed (metres) a repeat cannot be told from the
/// fixes' noise (about 0.04 mm).
pub(crate) const MIN_EXPECTED_STEP_M: f64 = 0.5e-3;

/// A fix standing within this fraction of a frame's motion from the image before it is that
/// image again (re-encoded): a robot cannot stop for one frame.
const COPY_FRACTION: f64 = 0.2;

/// The next distinct fix is looked for this many frames on.
const WITHIN_FRAMES: usize = 3;

/// A slot this many frame steps off the time the motion gives the image, or a time that
/// uncertain, leaves the slot in doubt: σ is widened by a frame's motion.
const SLOT_DOUBT_STEPS: f64 = 0.3;

/// A run of one image this long that the fixes start with, the robot moving off at its last
/// slot, is a robot waiting (a conversion fills two or three slots, a camera repeats one).
const STILL_AT_START_SLOTS: usize = 4;

/// The position of a record's fix.
pub(crate) fn fix_position(r: &FrameRecord) -> Option<nalgebra::Point2<f64>> {
    match &r.outcome {
        Outcome::Fix(f) => Some(f.pose.position()),
        _ => None,
    }
}

fn fix_of(r: &FrameRecord) -> Option<&Fix> {
    match &r.outcome {
        Outcome::Fix(f) => Some(f),
        _ => None,
    }
}

/// Runs of records holding one image: a fix, then the frames repeating it (byte for byte, or
/// a fix standing where it stood while the robot moves on). Each run is the records'
/// positions, the fix first.
fn runs_of_one_image(records: &[FrameRecord]) -> Vec<Vec<usize>> {
    let mut runs: Vec<Vec<usize>> = Vec::new();
    let mut open = false;
    for i in 0..records.len() {
        match records[i].outcome {
            Outcome::Gap(GapReason::RepeatedImage) if open => {
                if let Some(run) = runs.last_mut() {
                    run.push(i);
                }
            }
            Outcome::Fix(_) => {
                let copy = open && repeats_fix(records, &runs, i);
                match runs.last_mut() {
                    Some(run) if copy => run.push(i),
                    _ => runs.push(vec![i]),
                }
                open = true;
            }
            _ => open = false,
        }
    }
    runs
}

/// Whether the fix at `i` stands where the last run's image stood, within a fifth of a frame's
/// motion at the speed into that image, while the next fix that moves on does so at about that
/// speed or more (a stop is not a repeat).
fn repeats_fix(records: &[FrameRecord], runs: &[Vec<usize>], i: usize) -> bool {
    let Some(run) = runs.last() else { return false };
    let head = &records[run[0]];
    let (Some(a), Some(p)) = (fix_position(head), fix_position(&records[i])) else {
        return false;
    };
    let prev = runs
        .len()
        .checked_sub(2)
        .map(|k| &runs[k])
        .filter(|r| r.last().is_some_and(|&l| l + 1 == run[0]))
        .and_then(|r| Some((records[r[0]].t_s, fix_position(&records[r[0]])?)));
    let frame_s = records[i].t_s - records[i - 1].t_s;
    let moving_on = |speed: f64| {
        records[i + 1..]
            .iter()
            .take(WITHIN_FRAMES)
            .filter_map(|x| Some((x.t_s, fix_position(x)?)))
            .find(|(_, q)| (q - a).norm() >= COPY_FRACTION * speed * frame_s)
    };
    let speed = match prev {
        Some((tb, b)) if head.t_s > tb => (a - b).norm() / (head.t_s - tb),
        _ => match moving_on(0.0) {
            Some((tq, q)) if tq > head.t_s => (q - a).norm() / (tq - head.t_s),
            _ => return false,
        },
    };
    // The video's last frame has no motion after it to tell a stop: the placement tells it
    // (a stop places the image at the earlier slot, and the last frame is then left out).
    let last = i + 1 == records.len();
    speed * frame_s >= MIN_EXPECTED_STEP_M
        && (p - a).norm() < COPY_FRACTION * speed * frame_s
        && (last || moving_on(speed).is_some_and(|(_, q)| (q - a).norm() >= 0.4 * speed * frame_s))
}

/// A distinct image next to a run: its time and pose.
type Neighbour = (f64, Pose2);

/// The robot's speed (m/s) and turn rate (rad/s) from `a` to `b`.
fn rates(a: Neighbour, b: Neighbour) -> Option<(f64, f64)> {
    let dt = (b.0 - a.0).abs();
    (dt > 0.0).then(|| {
        (
            (b.1.position() - a.1.position()).norm() / dt,
            wrap_angle(b.1.theta_rad - a.1.theta_rad).abs() / dt,
        )
    })
}

/// Puts each repeated image's fix at the slot the robot's motion gives it: the slots before
/// it are [`GapReason::FilledDrop`] gaps, those after [`GapReason::RepeatedImage`] gaps; where
/// the tag stands still (its neighbours' fixes agree with it within the noise) every slot
/// keeps the pose. A slot the motion leaves in doubt has σ widened by a frame's motion.
pub(crate) fn place_repeated_images(records: &mut [FrameRecord]) {
    let runs = runs_of_one_image(records);
    // Where each run's image was placed: the neighbour before the next run.
    let mut at: Vec<Option<Neighbour>> = Vec::with_capacity(runs.len());
    for (k, run) in runs.iter().enumerate() {
        let Some(fix) = fix_of(&records[run[0]]).copied() else {
            at.push(None);
            continue;
        };
        let adjacent_before =
            |j: usize| j < k && runs[j].last().is_some_and(|&l| l + 1 == runs[j + 1][0]);
        let adjacent_after = |j: usize| {
            j < runs.len() && runs[j][0] == runs[j - 1].last().map_or(usize::MAX, |l| l + 1)
        };
        let before = |d: usize| {
            (d <= k && (1..=d).all(|e| adjacent_before(k - e)))
                .then(|| at[k - d])
                .flatten()
        };
        let after = |d: usize| {
            ((1..=d).all(|e| adjacent_after(k + e)))
                .then(|| {
                    Some((
                        records[runs[k + d][0]].t_s,
                        fix_of(&records[runs[k + d][0]])?.pose,
                    ))
                })
                .flatten()
        };
        let slots: Vec<f64> = run.iter().map(|&i| records[i].t_s).collect();
        let here = (slots[0], fix.pose);
        if run.len() == 1 {
            at.push(Some(here));
            continue;
        }
        let (prev, next) = (before(1), after(1));
        let step = |n: Option<Neighbour>| n.map(|n| (n.1.position() - fix.pose.position()).norm());
        let noise_m = 3.0 * fix.sigma.x_m.hypot(fix.sigma.y_m);
        let steps: Vec<f64> = [step(prev), step(next)].into_iter().flatten().collect();
        // With no fix on either side nothing tells a repeat from a still scene, and a camera
        // repeats a frame or two, not a whole video: the video's one image stands in every
        // slot (a 3 s still video kept 1 fix of 90).
        if steps.is_empty() || steps.iter().all(|&s| s <= noise_m) {
            // A still scene: the pose is right at every slot, to the neighbours' steps.
            let widen = steps.iter().copied().fold(0.0, f64::max);
            for &i in &run[1..] {
                records[i] = shifted(&records[run[0]], &records[i], widen, 0.0);
            }
            at.push(Some(here));
            continue;
        }
        // The image's time and the robot's speed and turn rate around it.
        let estimate = match (prev, next) {
            (Some(p), Some(n)) => {
                let (a, b) = (step(prev).unwrap_or(0.0), step(next).unwrap_or(0.0));
                rates(p, n).map(|r| (p.0 + a / (a + b) * (n.0 - p.0), r))
            }
            (Some(p), None) => before(2)
                .and_then(|p2| rates(p2, p))
                .filter(|r| r.0 > 0.0)
                .map(|r| (p.0 + step(prev).unwrap_or(0.0) / r.0, r)),
            (None, Some(n)) => after(2)
                .and_then(|n2| rates(n, n2))
                .filter(|r| r.0 > 0.0)
                .map(|r| (n.0 - step(next).unwrap_or(0.0) / r.0, r)),
            (None, None) => None,
        };
        let Some((t_image, (speed, turn))) = estimate else {
            at.push(Some(here));
            continue;
        };
        let frame_s = (slots[slots.len() - 1] - slots[0]) / (slots.len() - 1) as f64;
        let j = (0..slots.len())
            .min_by(|&a, &b| {
                (slots[a] - t_image)
                    .abs()
                    .total_cmp(&(slots[b] - t_image).abs())
            })
            .unwrap_or(0);
        // Held from the start of the fixes until the robot moves off: nothing before it says
        // the robot moved during the slots, and a robot waiting at the start is likelier than
        // its first frames all lost (a robot waiting 2 s had its 60 frames taken as dropped).
        if prev.is_none() && j + 1 == slots.len() && slots.len() >= STILL_AT_START_SLOTS {
            for &i in &run[1..] {
                records[i] = shifted(&records[run[0]], &records[i], 0.0, 0.0);
            }
            at.push(Some((slots[j], fix.pose)));
            continue;
        }
        let doubt = (slots[j] - t_image).abs() > SLOT_DOUBT_STEPS * frame_s
            || noise_m / speed > SLOT_DOUBT_STEPS * frame_s;
        let (widen_m, widen_rad) = if doubt {
            (speed * frame_s, turn * frame_s)
        } else {
            (0.0, 0.0)
        };
        let head = records[run[0]];
        for (n, &i) in run.iter().enumerate() {
            records[i] = if n == j {
                shifted(&head, &records[i], widen_m, widen_rad)
            } else {
                FrameRecord {
                    outcome: Outcome::Gap(if n < j {
                        GapReason::FilledDrop
                    } else {
                        GapReason::RepeatedImage
                    }),
                    rejected: None,
                    other_tag: None,
                    ..records[i]
                }
            };
        }
        at.push(Some((slots[j], fix.pose)));
    }
}

/// `head`'s record moved to `slot`'s frame: its fix at the slot's time, σ widened (in
/// quadrature) by `widen_m` and `widen_rad`.
fn shifted(head: &FrameRecord, slot: &FrameRecord, widen_m: f64, widen_rad: f64) -> FrameRecord {
    let mut out = FrameRecord {
        index: slot.index,
        t_s: slot.t_s,
        ..*head
    };
    if let Outcome::Fix(f) = &mut out.outcome {
        f.t_s += slot.t_s - head.t_s;
        f.sigma.x_m = f.sigma.x_m.hypot(widen_m);
        f.sigma.y_m = f.sigma.y_m.hypot(widen_m);
        f.sigma.theta_rad = f.sigma.theta_rad.hypot(widen_rad);
    }
    out
}

#[cfg(test)]
pub(crate) mod tests {
    use super::place_repeated_images;
    use crate::{Fix, FrameRecord, GapReason, Outcome};
    use odocal_core::{Pose2, PoseSigma};

    const FPS: f64 = 30.0;

    /// A fix of the tag at `x_m` (σ 0.1 mm) in frame `index`.
    pub(crate) fn record(index: usize, x_m: f64) -> FrameRecord {
        let t_s = index as f64 / FPS;
        let corner = nalgebra::Point2::new(0.0, 0.0);
        FrameRecord {
            index,
            t_s,
            outcome: Outcome::Fix(Fix {
                pose: Pose2::new(x_m, 0.2, 0.1),
                t_s,
                sigma: PoseSigma {
                    x_m: 1e-4,
                    y_m: 1e-4,
                    theta_rad: 1e-3,
                },
                corner_sigma_px: 0.1,
                quality: 1.0,
                reprojection_rms_px: 0.1,
                fit_rms_m: 1e-5,
                decision_margin: 100.0,
                hamming: 0,
                corners_px: [corner; 4],
                from_roi: true,
                pnp: None,
            }),
            rejected: None,
            other_tag: None,
        }
    }

    /// 12 frames of a tag at `x_m(frame)`; `image_of(slot)` names the frame whose image each
    /// slot holds, a copy of the slot before it a byte-identical gap (`reencoded`: a fix 0.02 mm
    /// off).
    fn video(x_m: impl Fn(usize) -> f64, image_of: &[usize], reencoded: bool) -> Vec<FrameRecord> {
        let mut records: Vec<FrameRecord> = (0..image_of.len())
            .map(|slot| {
                let mut r = record(slot, x_m(image_of[slot]));
                if let Outcome::Fix(f) = &mut r.outcome {
                    f.t_s = r.t_s;
                }
                r
            })
            .collect();
        for slot in 1..image_of.len() {
            if image_of[slot] == image_of[slot - 1] {
                if reencoded {
                    records[slot] = record(slot, x_m(image_of[slot]) + 2e-5);
                } else {
                    records[slot].outcome = Outcome::Gap(GapReason::RepeatedImage);
                }
            }
        }
        records
    }

    fn x_at(r: &FrameRecord) -> Option<f64> {
        match r.outcome {
            Outcome::Fix(f) => Some(f.pose.x_m),
            Outcome::Gap(_) => None,
        }
    }

    /// At 0.6 m/s, 20 mm a frame.
    fn driving(frame: usize) -> f64 {
        0.6 * frame as f64 / FPS
    }

    /// A dropped frame's slot filled with the next frame's image (FFmpeg converting to a
    /// constant rate) was kept in the slot of the dropped frame, a frame early (20 mm off), and
    /// the image's own slot left out: the motion puts it in its own slot.
    #[test]
    fn a_dropped_frames_slot_filled_with_the_next_image_places_it_later() {
        // Frames 4 and 10 of 12 dropped, each slot holding the next frame's image.
        let image_of = [0, 1, 2, 3, 5, 5, 6, 7, 8, 9, 11, 11];
        for reencoded in [false, true] {
            let mut r = video(driving, &image_of, reencoded);
            place_repeated_images(&mut r);
            for (slot, rec) in r.iter().enumerate() {
                if slot == 4 || slot == 10 {
                    assert_eq!(rec.outcome, Outcome::Gap(GapReason::FilledDrop), "{slot}");
                } else {
                    let x = x_at(rec).expect("a fix");
                    assert!((x - driving(slot)).abs() < 1e-4, "slot {slot}: {x}");
                    assert!(matches!(rec.outcome, Outcome::Fix(f) if f.t_s == rec.t_s));
                }
            }
        }
        // A camera repeating a frame it missed: the image belongs to the first slot.
        let mut r = video(driving, &[0, 1, 2, 3, 4, 4, 6, 7, 8, 9, 10, 11], true);
        place_repeated_images(&mut r);
        assert!((x_at(&r[4]).expect("kept") - driving(4)).abs() < 1e-4);
        assert_eq!(r[5].outcome, Outcome::Gap(GapReason::RepeatedImage));
    }

    /// A robot resting at the start of an H.264 video: its frames decode identical and were
    /// all left out as repeats. They are the robot's pose at every slot, and kept.
    #[test]
    fn a_still_scene_keeps_its_identical_frames() {
        // Resting to frame 6, then starting off at 2 m/s².
        let resting = |frame: usize| (frame.saturating_sub(6) as f64 / FPS).powi(2);
        let image_of = [0, 0, 0, 0, 0, 0, 6, 7, 8, 9, 10, 11];
        let mut r = video(resting, &image_of, false);
        place_repeated_images(&mut r);
        for (slot, rec) in r.iter().enumerate() {
            let x = x_at(rec).expect("every slot a fix");
            assert!((x - resting(slot)).abs() < 1e-4, "slot {slot}: {x}");
        }
    }

    /// A tracking run of `records` from `path`, whose container announces `announced` frames
    /// (at 30 frames/s for a video).
    pub(crate) fn track_result(
        records: Vec<FrameRecord>,
        path: &str,
        announced: usize,
    ) -> crate::TrackResult {
        let video = path.ends_with(".avi");
        crate::TrackResult {
            tag_to_robot: odocal_core::TagToRobot::IDENTITY,
            records,
            lost_in_file: Vec::new(),
            dropped_by_motion: Vec::new(),
            seen_ids: Default::default(),
            frame_size: (1280, 720),
            source: crate::source::SourceInfo {
                path: path.into(),
                width: 1280,
                height: 720,
                frame_count: Some(announced),
                kind: if video { "video MJPG" } else { "image folder" }.into(),
                timing: "container timestamps".into(),
                extrapolated_times: 0,
                overridden_fps: None,
                container_fps: video.then_some(FPS),
                interlace_comb: None,
                first_frame_clock_s: None,
                display_rotation: None,
                container_times_s: None,
                corrupt_frames: Vec::new(),
                corrupt_files: Vec::new(),
            },
        }
    }

    /// The robot out of view over a still scene: 21 identical frames without the tag were
    /// named as a camera repeating frames and as a frame rate converted from 20 fps. Repeats
    /// of a tagged image still count.
    #[test]
    fn identical_frames_without_the_tag_are_no_repeats_to_name() {
        let driving = |frame: usize| 0.01 * frame as f64;
        let mut records: Vec<FrameRecord> = (0..60).map(|i| record(i, driving(i))).collect();
        for r in &mut records[20..41] {
            r.outcome = Outcome::Gap(if r.index == 20 {
                GapReason::NotDetected
            } else {
                GapReason::RepeatedImage
            });
        }
        let result = |records: Vec<FrameRecord>| track_result(records, "frames", 60);
        let still = crate::timing::TimingReport::of(&result(records.clone()));
        assert_eq!(still.repeated_images, 0);
        assert!(
            still.converted_from_fps.is_none() && still.warnings().is_empty(),
            "{:?}",
            still.warnings()
        );
        // A tagged image repeated every third frame from frame 45: counted.
        for r in records.iter_mut().skip(45).step_by(3) {
            r.outcome = Outcome::Gap(GapReason::RepeatedImage);
        }
        let repeated = crate::timing::TimingReport::of(&result(records));
        assert_eq!(repeated.repeated_images, 5);
    }
}
