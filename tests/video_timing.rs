//! A video's timeline as a real camera records it: frames dropped (a gap in the container's
//! timestamps), a frame repeated, a file cut short. Frames are timed by the container's
//! presentation timestamps, so a drop leaves a gap in the trajectory instead of shifting every
//! later pose; every such event is named on stderr and in `--report`.
//!
//! A video's rotate tag and a photo's EXIF orientation only say how to show it: frames and
//! calibration views are read as the sensor recorded them, the layout camera.json describes.
//!
//! The damaged videos are made from a rendered one by FFmpeg's command-line tool (installed by
//! `make deps`), which writes real containers with real timestamps: MJPG in Matroska and AVI,
//! and H.264 in MP4.

mod common;

use std::path::Path;
use std::process::Command;

use common::{odocal, p, succeeded, with_exif_orientation};
use odocal_core::Trajectory;

/// Frames 8, 9 and 10 of 24 are dropped.
const DROPPED: [usize; 3] = [8, 9, 10];
const FRAMES: usize = 24;

fn ffmpeg(args: &[&str]) {
    let out = Command::new("ffmpeg")
        .args(["-loglevel", "error", "-y"])
        .args(args)
        .output()
        .expect("ffmpeg is needed for this test: `make deps` installs it");
    assert!(
        out.status.success(),
        "ffmpeg {args:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
}

/// A rendered 24-frame MJPG video with its camera and truth.
fn rendered(d: &Path) {
    succeeded(&odocal(&[
        "synth",
        "track",
        "--out",
        p(d),
        "--frames",
        &FRAMES.to_string(),
        "--seed",
        "6",
    ]));
}

/// Position RMS (m) of `est` against the truth rows at the same times, and rows matched.
fn position_rms(est: &Trajectory, truth: &Trajectory) -> (f64, usize) {
    let mut s = 0.0;
    let mut n = 0;
    for r in &est.rows {
        if let Some(t) = truth.rows.iter().find(|t| (t.t_s - r.t_s).abs() < 1e-6) {
            s += (r.pose.position() - t.pose.position()).norm_squared();
            n += 1;
        }
    }
    ((s / n.max(1) as f64).sqrt(), n)
}

/// Tracks `video`; returns (trajectory, stderr, report JSON).
fn track(d: &Path, video: &Path, extra: &[&str]) -> (Trajectory, String, serde_json::Value) {
    let out = d.join("traj.csv");
    let report = d.join("report.json");
    let camera = d.join("camera.json");
    let mut args = vec![
        "track",
        p(video),
        "--camera",
        p(&camera),
        "--out",
        p(&out),
        "--report",
        p(&report),
    ];
    args.extend_from_slice(extra);
    let o = odocal(&args);
    succeeded(&o);
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&report).unwrap()).unwrap();
    (
        Trajectory::read_csv(&out).unwrap(),
        String::from_utf8_lossy(&o.stderr).into_owned(),
        report,
    )
}

/// ffprobe's presentation time of every frame of `video`, seconds from the first.
fn ffprobe_times(video: &Path) -> Vec<f64> {
    let probe = Command::new("ffprobe")
        .args(["-v", "error", "-select_streams", "v:0", "-show_entries"])
        .args(["frame=pts_time", "-of", "csv=p=0", p(video)])
        .output()
        .expect("ffprobe comes with ffmpeg");
    let pts: Vec<f64> = String::from_utf8_lossy(&probe.stdout)
        .split(|c: char| c == ',' || c.is_whitespace())
        .filter_map(|x| x.parse().ok())
        .collect();
    pts.iter().map(|t| t - pts[0]).collect()
}

/// Every row of `est` (a fix at every frame) at its frame's presentation time, to the
/// millisecond the container rounds to.
fn assert_times_are_ffprobes(name: &str, est: &Trajectory, video: &Path) {
    let pts = ffprobe_times(video);
    assert_eq!(pts.len(), est.rows.len(), "{name}: ffprobe frames");
    for (r, t) in est.rows.iter().zip(&pts) {
        assert!((r.t_s - t).abs() < 1e-3, "{name}: {} vs ffprobe {t}", r.t_s);
    }
}

#[test]
fn dropped_frames_leave_a_gap_in_time_not_a_shift() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    rendered(d);
    let truth = Trajectory::read_csv(&d.join("truth.csv")).unwrap();
    let (clean, err, report) = track(d, &d.join("video.avi"), &[]);
    assert_eq!(clean.rows.len(), FRAMES);
    assert!(!err.contains("warning"), "{err}");
    assert_eq!(report["timing"]["dropped_frames"], 0);
    assert_eq!(report["timing"]["timing"], "container timestamps");
    let (clean_rms, _) = position_rms(&clean, &truth);

    let select = format!(
        "select='not(between(n\\,{}\\,{}))'",
        DROPPED[0],
        DROPPED[DROPPED.len() - 1]
    );
    let source = d.join("video.avi");
    for (name, codec) in [
        ("gap.mkv", ["-c:v", "mjpeg", "-q:v", "2"]),
        ("gap.avi", ["-c:v", "mjpeg", "-q:v", "2"]),
        ("gap.mp4", ["-c:v", "libx264", "-crf", "12"]),
    ] {
        let video = d.join(name);
        let mut args = vec!["-i", p(&source), "-vf", &select];
        args.extend_from_slice(&["-fps_mode", "passthrough"]);
        args.extend_from_slice(&codec);
        args.push(p(&video));
        ffmpeg(&args);

        let (est, err, report) = track(d, &video, &[]);
        let (rms, n) = position_rms(&est, &truth);
        println!(
            "{name}: {n} frames at their true times, position RMS {:.3} mm (clean video {:.3} mm)",
            rms * 1e3,
            clean_rms * 1e3
        );
        assert_eq!(
            n,
            FRAMES - DROPPED.len(),
            "{name}: every frame at its true time"
        );
        assert!(rms < 0.5e-3, "{name}: position RMS {rms} m");
        assert!(
            err.contains("warning:")
                && err.contains("3 frames dropped in 1 place (3 after frame 7"),
            "{name}: {err}"
        );
        // The times are FFmpeg's own: ffprobe's presentation time of every frame (from the
        // first), which the container stores to the millisecond in Matroska.
        assert_times_are_ffprobes(name, &est, &video);
        let timing = &report["timing"];
        assert_eq!(timing["dropped_frames"], 3, "{name}: {timing}");
        assert_eq!(timing["dropped"][0]["after_frame"], 7, "{name}: {timing}");
        assert_eq!(timing["missing_at_end"], 0, "{name}: {timing}");

        // Timed by counting at --fps, the frames after the drop shift by three frames, whatever
        // the rate given: at the container's step (30), and at the average rate an MP4 states
        // for what it holds (21 frames over 24 frames' time), which was said nothing of.
        let average = if name == "gap.mp4" {
            let probe = Command::new("ffprobe")
                .args(["-v", "error", "-select_streams", "v:0", "-show_entries"])
                .args(["stream=avg_frame_rate", "-of", "csv=p=0", p(&video)])
                .output()
                .expect("ffprobe comes with ffmpeg");
            let text = String::from_utf8_lossy(&probe.stdout).trim().to_string();
            let (a, b) = text.split_once('/').expect("a rate a/b");
            let fps = a.parse::<f64>().unwrap() / b.parse::<f64>().unwrap();
            assert!((fps - 26.25).abs() < 0.01, "{text}");
            Some(format!("{fps}"))
        } else {
            None
        };
        for fps in std::iter::once("30".to_string()).chain(average) {
            let (counted, err, report) = track(d, &video, &["--fps", &fps]);
            let (rms, _) = position_rms(&counted, &truth);
            println!(
                "{name} timed by counting at {fps} fps: position RMS {:.1} mm",
                rms * 1e3
            );
            assert!(
                err.contains(&format!(
                    "3 frames dropped in 1 place (3 after frame 7 (0.233 s)), as the video's timestamps show; --fps {fps} times the frames by counting"
                )) && err.contains("leave --fps out"),
                "{name} --fps {fps}: {err}"
            );
            assert_eq!(report["timing"]["dropped_frames"], 3, "{name}");
            // Neither a rate to "correct" towards the average nor a missing-frames count that
            // contradicts the frames read.
            assert!(
                !err.contains("are missing") && !err.contains("replaces the timestamps"),
                "{name} --fps {fps}: {err}"
            );
            assert_eq!(
                err.contains("overrides the video's own rate (its timestamps step at 30 fps)"),
                fps != "30",
                "{name} --fps {fps}: {err}"
            );
        }
    }
}

/// H.264 with B-frames (FFmpeg's default) ends with frames the decoder gives out after the last
/// packet, which OpenCV gives no time: they were timed a step after the frame before, so a
/// frame dropped among the last put them a frame late (22.9 mm at the robot's speed, with no
/// warning) and a drop just before them made a second drop up and a time past the video's end.
/// They are timed by their packets' presentation times, as ffprobe reads them.
#[test]
fn the_last_frames_of_a_video_with_b_frames_keep_their_times() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    rendered(d);
    let truth = Trajectory::read_csv(&d.join("truth.csv")).unwrap();
    for (name, dropped, bframes) in [
        ("drop21.mp4", FRAMES - 3, "3"),
        ("drop22.mkv", FRAMES - 2, "3"),
        ("drop22.mp4", FRAMES - 2, "0"),
        ("none.mp4", FRAMES, "3"),
    ] {
        let video = d.join(name);
        let select = format!("select='not(eq(n\\,{dropped}))'");
        ffmpeg(&[
            "-i",
            p(&d.join("video.avi")),
            "-vf",
            &select,
            "-fps_mode",
            "passthrough",
            "-c:v",
            "libx264",
            "-bf",
            bframes,
            "-crf",
            "12",
            "-pix_fmt",
            "yuv420p",
            p(&video),
        ]);
        let (est, err, report) = track(d, &video, &[]);
        let (rms, n) = position_rms(&est, &truth);
        println!(
            "{name}: {n} frames at their true times, position RMS {:.3} mm",
            rms * 1e3
        );
        assert_times_are_ffprobes(name, &est, &video);
        let expected = if dropped < FRAMES { FRAMES - 1 } else { FRAMES };
        assert!(
            n == expected && rms < 0.5e-3,
            "{name}: {n} frames, {rms} m: {err}"
        );
        let timing = &report["timing"];
        assert_eq!(timing["extrapolated_times"], 0, "{name}: {timing}");
        assert_eq!(
            timing["dropped_frames"],
            usize::from(dropped < FRAMES),
            "{name}: {timing}"
        );
    }
}

#[test]
fn a_repeated_image_is_not_tracked_and_a_cut_file_is_named() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    rendered(d);
    // A camera that repeats frame 5 in the place of frame 6, with frame 6's timestamp.
    let frames = d.join("frames");
    std::fs::create_dir(&frames).unwrap();
    let pattern = frames.join("f%03d.png");
    ffmpeg(&["-i", p(&d.join("video.avi")), p(&pattern)]);
    std::fs::copy(frames.join("f006.png"), frames.join("f007.png")).unwrap();
    let (est, err, report) = track(d, &frames, &["--fps", "30"]);
    assert_eq!(est.rows.len(), FRAMES - 1);
    assert!(
        est.rows.iter().all(|r| (r.t_s - 6.0 / 30.0).abs() > 1e-9),
        "the repeated frame has no pose"
    );
    assert!(
        err.contains("1 frame repeats the previous frame's image"),
        "{err}"
    );
    assert_eq!(report["timing"]["repeated_images"], 1);
    assert_eq!(report["per_frame"][6]["reason"], "repeated image");

    // The second half of the file is lost: the frames that are there are tracked, and the
    // loss is named.
    let bytes = std::fs::read(d.join("video.avi")).unwrap();
    let cut = d.join("cut.avi");
    std::fs::write(&cut, &bytes[..bytes.len() / 2]).unwrap();
    let (est, err, report) = track(d, &cut, &[]);
    let read = report["timing"]["frames_read"].as_u64().unwrap() as usize;
    // The cut goes through the last frame read: FFmpeg completes it from the frame before,
    // whose pose it would repeat, so it is a gap.
    assert!(
        read < FRAMES && est.rows.len() + 1 == read,
        "{read} frames read, {} poses: {err}",
        est.rows.len()
    );
    assert!(
        err.contains("1 frame repeats the previous frame's image"),
        "{err}"
    );
    assert!(
        err.contains(&format!(
            "the container announces {FRAMES} frames but only {read} were read"
        )) && err.contains("cut short"),
        "{err}"
    );
    assert_eq!(
        report["timing"]["missing_at_end"].as_u64(),
        Some((FRAMES - read) as u64)
    );
}

/// A 30 fps recording kept in a 60 fps AVI (FFmpeg writes each frame twice, the repeat as an
/// empty chunk): the container announces twice the frames read, which was reported as a file
/// cut short with half its frames missing ("(0 dropped)"). The frames span the container's
/// whole duration, so nothing is missing, and nothing is said.
#[test]
fn a_container_counting_repeats_is_not_cut_short() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    rendered(d);
    let doubled = d.join("doubled.avi");
    ffmpeg(&[
        "-i",
        p(&d.join("video.avi")),
        "-r",
        "60",
        "-c:v",
        "mjpeg",
        "-q:v",
        "2",
        p(&doubled),
    ]);
    let (est, err, report) = track(d, &doubled, &[]);
    assert_eq!(est.rows.len(), FRAMES, "{err}");
    assert!(!err.contains("cut short"), "{err}");
    assert_eq!(report["timing"]["missing_at_end"].as_u64(), Some(0));
    assert!(
        report["timing"]["frames_announced"].as_u64().unwrap_or(0) > FRAMES as u64 + 10,
        "{report}"
    );
}

/// Two complete videos were reported cut short: a Matroska file whose timestamps start late
/// (remuxed with an offset: it states the segment's end time, 5 s past the frames, as its
/// duration) and a copy cut from an H.264 MP4 by stream copy (its samples before the cut
/// point kept, and left out by an edit list); the cut copy's last frames, which the decoder
/// gives out after the last packet, were also timed from the first packet left out, a cut's
/// length early. Both hold every frame at its time; the same files truly cut short are still
/// named.
#[test]
fn a_late_start_or_a_copy_cut_by_stream_copy_is_not_cut_short() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    rendered(d);
    let truth = Trajectory::read_csv(&d.join("truth.csv")).unwrap();
    let h264 = d.join("h264.mp4");
    ffmpeg(&[
        "-i",
        p(&d.join("video.avi")),
        "-c:v",
        "libx264",
        "-crf",
        "12",
        "-pix_fmt",
        "yuv420p",
        p(&h264),
    ]);
    let late = d.join("late.mkv");
    ffmpeg(&[
        "-i",
        p(&h264),
        "-output_ts_offset",
        "5",
        "-c",
        "copy",
        p(&late),
    ]);
    // The moov box first, so that a file cut short still opens.
    let cut = d.join("cut.mp4");
    ffmpeg(&[
        "-ss",
        "0.2",
        "-i",
        p(&h264),
        "-t",
        "0.5",
        "-c",
        "copy",
        "-movflags",
        "+faststart",
        p(&cut),
    ]);
    for (video, from_s) in [(late, 0.0), (cut, 0.2)] {
        let name = video.file_name().unwrap().to_string_lossy().into_owned();
        let (mut est, err, report) = track(d, &video, &[]);
        assert!(!err.contains("cut short"), "{name}: {err}");
        assert_eq!(report["timing"]["missing_at_end"], 0, "{name}");
        assert_times_are_ffprobes(&name, &est, &video);
        // The first frame is the original's at `from_s`.
        for r in &mut est.rows {
            r.t_s += from_s;
        }
        let (rms, n) = position_rms(&est, &truth);
        println!(
            "{name}: {n} frames at their true times, position RMS {:.3} mm",
            rms * 1e3
        );
        assert!(
            n == est.rows.len() && n >= 14 && rms < 0.5e-3,
            "{name}: {n} of {} frames at their times, {rms} m",
            est.rows.len()
        );

        let bytes = std::fs::read(&video).unwrap();
        let truncated = d.join(format!("truncated_{name}"));
        std::fs::write(&truncated, &bytes[..bytes.len() * 3 / 5]).unwrap();
        let (_, err, report) = track(d, &truncated, &[]);
        assert!(err.contains("the file looks cut short"), "{name}: {err}");
        assert!(
            report["timing"]["missing_at_end"].as_u64().unwrap_or(0) > 2,
            "{name}: {}",
            report["timing"]
        );
    }

    // The first frame dropped before the file was written, the others' times kept: the file
    // starts at 0.033 s. Fixes count from the first frame, and were 33 ms early against a
    // clock started with the container (15.3 mm RMS) in silence: the start is named, with
    // the time to add, and recorded.
    let late_first = d.join("late_first.mp4");
    ffmpeg(&[
        "-i",
        p(&d.join("video.avi")),
        "-vf",
        "select='gte(n,1)'",
        "-fps_mode",
        "passthrough",
        "-c:v",
        "libx264",
        "-crf",
        "12",
        "-pix_fmt",
        "yuv420p",
        p(&late_first),
    ]);
    let (mut est, err, report) = track(d, &late_first, &[]);
    assert!(
        err.contains("the video's first frame is at 0.033 s on its container's clock (its start time), and the fixes count from that frame (t = 0): against a clock that started with the container (frames cut or dropped before the first one kept), add 0.033 s to the fixes' times"),
        "{err}"
    );
    let clock_s = report["timing"]["first_frame_clock_s"].as_f64().unwrap();
    assert!((clock_s - 1.0 / 30.0).abs() < 1e-3, "{clock_s}");
    assert!(est.rows[0].t_s == 0.0);
    // The truth is at whole frames; the container's start is rounded to its time base.
    for r in &mut est.rows {
        r.t_s = ((r.t_s + clock_s) * 30.0).round() / 30.0;
    }
    let (rms, n) = position_rms(&est, &truth);
    assert!(n + 1 >= FRAMES && rms < 0.5e-3, "{n} rows, {rms} m");
}

/// A 30 fps recording converted by FFmpeg: to 60 fps each frame is repeated, and H.264 makes the
/// repeat differ a little, so 36 of 90 repeats were tracked at a time 16.7 ms after their image
/// (11.3 mm off); to 20 fps every third frame is left out and the rest re-timed on the new
/// grid (34 mm RMS off), with no word of it. The robot's motion shows both: a repeat stands
/// where the frame before it stood while the robot moves, and a re-timed frame steps two
/// frames' motion in a regular pattern.
#[test]
fn a_converted_frame_rate_is_named() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    rendered(d);
    let truth = Trajectory::read_csv(&d.join("truth.csv")).unwrap();
    for (fps, repeats) in [("60", true), ("20", false)] {
        let video = d.join(format!("r{fps}.mp4"));
        ffmpeg(&[
            "-i",
            p(&d.join("video.avi")),
            "-r",
            fps,
            "-c:v",
            "libx264",
            "-crf",
            "12",
            "-pix_fmt",
            "yuv420p",
            p(&video),
        ]);
        let (est, err, report) = track(d, &video, &[]);
        let (rms, n) = position_rms(&est, &truth);
        println!(
            "-r {fps}: {} rows, {n} at a true time, position RMS there {:.3} mm",
            est.rows.len(),
            rms * 1e3
        );
        assert!(
            err.contains(&format!(
                "the frame rate converted to {fps}.0 fps from about"
            )),
            "-r {fps}: {err}"
        );
        assert!(
            report["timing"]["converted_from_fps"].is_number(),
            "{report}"
        );
        if repeats {
            // Every repeat but the last frame's (no motion after it to tell) is screened,
            // and each frame left sits at its image's true time.
            let repeated = report["timing"]["repeated_images"].as_u64().unwrap() as usize;
            assert!(repeated >= 2 * FRAMES - FRAMES - 1, "{repeated}: {err}");
            assert!(n >= FRAMES - 1 && rms < 0.5e-3, "{n} rows, {rms} m");
        }
    }
}

/// A rotate tag (180° and 90°) on an MP4, an EXIF orientation of 3 (turn 180°) on a folder's
/// JPEG frames and on a calibration view: OpenCV applied both, and the 180° video was tracked
/// 1253 mm RMS from its truth with exit 0, the 90° one refused as 720×1280, the frames
/// 1502 mm off, and the views calibrated turned. Each is now read as recorded, with a note.
#[test]
fn display_rotation_metadata_is_not_applied() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    rendered(d);
    let truth = Trajectory::read_csv(&d.join("truth.csv")).unwrap();
    let base = d.join("base.mp4");
    let avi = d.join("video.avi");
    ffmpeg(&[
        "-i",
        p(&avi),
        "-c:v",
        "libx264",
        "-crf",
        "12",
        "-pix_fmt",
        "yuv420p",
        p(&base),
    ]);
    let (est, _, _) = track(d, &base, &[]);
    let (base_rms, _) = position_rms(&est, &truth);
    for deg in [180, 90] {
        let turned = d.join(format!("rot{deg}.mp4"));
        let tag = format!("rotate={deg}");
        ffmpeg(&[
            "-i",
            p(&base),
            "-c",
            "copy",
            "-metadata:s:v:0",
            &tag,
            p(&turned),
        ]);
        let (est, err, _) = track(d, &turned, &[]);
        let (rms, n) = position_rms(&est, &truth);
        println!(
            "rotate={deg}: position RMS {:.3} mm (untagged {:.3} mm)",
            rms * 1e3,
            base_rms * 1e3
        );
        assert!(
            n == FRAMES && (rms - base_rms).abs() < 1e-6,
            "rotate={deg}: {n} frames, {rms} m: {err}"
        );
        assert!(
            err.contains(&format!(
                "its rotate tag asks for a turn of {deg}° on display, which is not applied"
            )),
            "{err}"
        );
    }

    let frames = d.join("frames");
    std::fs::create_dir(&frames).unwrap();
    ffmpeg(&["-i", p(&avi), "-q:v", "2", p(&frames.join("f%03d.jpg"))]);
    let plain = d.join("plain.jpg");
    std::fs::copy(frames.join("f001.jpg"), &plain).unwrap();
    for f in std::fs::read_dir(&frames).unwrap() {
        let f = f.unwrap().path();
        let bytes = std::fs::read(&f).unwrap();
        std::fs::write(&f, with_exif_orientation(&bytes, 3)).unwrap();
    }
    let (est, err, _) = track(d, &frames, &["--fps", "30"]);
    let (rms, n) = position_rms(&est, &truth);
    println!(
        "JPEG frames with EXIF orientation 3: position RMS {:.3} mm",
        rms * 1e3
    );
    assert!(n == FRAMES && rms < 0.5e-3, "{n} frames, {rms} m: {err}");
    assert!(
        err.contains("its first image carries EXIF orientation 3 (turn 180°) for display, which is not applied"),
        "{err}"
    );

    // A calibration view: the same pixels as without the tag, and a note naming it.
    use opencv::prelude::*;
    let tagged = frames.join("f001.jpg");
    let read = |path: &Path| {
        let m = odocal_calib::detect::read_gray(path).unwrap();
        (m.cols(), m.rows(), m.data_bytes().unwrap().to_vec())
    };
    assert!(read(&tagged) == read(&plain), "the view is read turned");
    let note = odocal_calib::detect::display_rotation_note([plain.as_path(), tagged.as_path()])
        .expect("a note");
    assert!(
        note.contains("f001.jpg: EXIF orientation 3 (turn 180°)") && !note.contains("more"),
        "{note}"
    );
}

/// A raw MJPEG stream has no timestamps and no rate: FFmpeg's guessed 25 fps timed a 30 fps
/// video's frames 1.2 times too late with exit 0 (120 mm RMS); it is refused without --fps,
/// and with --fps 30 it is the truth's trajectory, with no advice to leave --fps out.
#[test]
fn a_raw_mjpeg_stream_needs_fps() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    rendered(d);
    let raw = d.join("raw.mjpeg");
    ffmpeg(&[
        "-i",
        p(&d.join("video.avi")),
        "-c:v",
        "copy",
        "-f",
        "mjpeg",
        p(&raw),
    ]);
    let (out, camera) = (d.join("t.csv"), d.join("camera.json"));
    let track = |extra: &[&str]| {
        let mut args = vec!["track", p(&raw), "--camera", p(&camera), "--out", p(&out)];
        args.extend(extra);
        odocal(&args)
    };
    common::fails_with(
        &track(&[]),
        "a raw mjpeg stream holds no timestamps nor a frame rate (FFmpeg would guess 25 fps",
    );
    let res = track(&["--fps", "30"]);
    succeeded(&res);
    let err = String::from_utf8_lossy(&res.stderr);
    assert!(!err.contains("warning"), "{err}");
    let truth = Trajectory::read_csv(&d.join("truth.csv")).unwrap();
    let (rms, n) = position_rms(&Trajectory::read_csv(&out).unwrap(), &truth);
    assert!(n == FRAMES && rms < 2e-4, "{n} fixes, {:.3} mm", rms * 1e3);
}

/// Black frames at a video's start (14 of 24) repeat one image without the tag: they were
/// counted as frames where the tag was found, left out as repeated images, and blamed on a
/// damaged video. They are frames where it was not detected.
#[test]
fn black_frames_are_not_detected_not_repeats_of_the_tag() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    rendered(d);
    let black = d.join("black.avi");
    ffmpeg(&[
        "-i",
        p(&d.join("video.avi")),
        "-vf",
        "drawbox=x=0:y=0:w=iw:h=ih:color=black:t=fill:enable='lt(n,14)'",
        "-c:v",
        "mjpeg",
        "-q:v",
        "2",
        p(&black),
    ]);
    let (est, err, report) = track(d, &black, &[]);
    assert!(!err.contains("repeat"), "{err}");
    assert!(!err.contains("gave a fix"), "{err}");
    assert_eq!(report["timing"]["repeated_images"], 0, "{report}");
    assert_eq!(est.rows.len(), FRAMES - 14);
    let truth = Trajectory::read_csv(&d.join("truth.csv")).unwrap();
    let (rms, n) = position_rms(&est, &truth);
    assert!(n == FRAMES - 14 && rms < 0.5e-3, "{n} rows, {rms} m");
}
