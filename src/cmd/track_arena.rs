//! `odocal track --tags 0,3,7` and `odocal track --arena arena.json a.mp4 b.mp4 …`: several
//! robots in one video, and robots tracked across the cameras of an arena, one trajectory
//! file per robot.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use anyhow::{bail, Context};
use odocal_arena::{
    fuse_all, track_cameras, ArenaError, ArenaFile, ArenaTrackFile, ClockRate, FuseOptions,
};
use odocal_calib::CameraFile;
use odocal_core::Trajectory;
use odocal_synth::arena::ArenaTruth;
use odocal_tracker::multi::{track_source_multi, TagSelection};
use odocal_tracker::{
    few_fixes_warning, fix_warnings, mount_warnings, open_source, quiet_video_logs,
    tag_shape_warnings, FoundFrames, SourceOptions, TimingReport, TrackOptions, TrackResult,
};

use crate::output::{
    check_output_file, check_output_not_input, commit, progress, write_atomic, write_json,
};

/// The clock offset between two arena cameras searched unless told, seconds either way.
pub(crate) const DEFAULT_MAX_CLOCK_OFFSET_S: f64 = 1.0;

/// The options of `odocal track` for several robots and several cameras.
#[derive(clap::Args)]
pub struct MultiArgs {
    /// Several robots: tag ids separated by commas (0,3,7), or all. One trajectory file per
    /// id: --out traj.csv writes traj_tag0.csv, traj_tag3.csv, … (a single id writes --out).
    /// Replaces --tag-id, which may not be given with it.
    #[arg(long, conflicts_with = "tag_id")]
    pub tags: Option<String>,
    /// arena.json from `odocal arena`: VIDEO and the videos after it are the arena's cameras
    /// in its order; one fused trajectory per robot (arena floor frame, first camera's
    /// clock). The cameras' clock offsets, and rates where the overlaps are long enough, are
    /// estimated from robots seen by two cameras at once.
    #[arg(long)]
    pub arena: Option<PathBuf>,
    /// The other cameras' videos or frame folders (with --arena).
    pub more_videos: Vec<PathBuf>,
    /// With --arena: also write the fusion's summary (clock offsets, cameras per pose,
    /// handoffs; `odocal.arena-track/1`) for `odocal report --arena-track`.
    #[arg(long)]
    pub arena_report: Option<PathBuf>,
    /// With --arena: the output folder of `odocal synth arena`; prints each robot's error
    /// against its true path and the clock offsets against the true ones.
    #[arg(long)]
    pub arena_truth: Option<PathBuf>,
    /// With --arena: the largest clock offset between two cameras searched, seconds (either
    /// way). Cameras started together are milliseconds apart; cameras started by hand can be
    /// seconds apart (the search takes longer the wider it is). [default: 1]
    #[arg(long)]
    pub max_clock_offset_s: Option<f64>,
}

impl MultiArgs {
    /// Refuses the arena's options without `--arena`: a second video or an arena report would
    /// be dropped unsaid. clap's `requires = "arena"` cannot say this: clap waives a required
    /// argument that conflicts with one given, and `--arena` conflicts with `--camera`, which
    /// every run without an arena gives.
    pub fn check_arena_options(&self) -> anyhow::Result<()> {
        if self.arena.is_some() {
            return Ok(());
        }
        if let Some(v) = self.more_videos.first() {
            anyhow::bail!(
                "{}: a second video is an arena camera's, and needs --arena arena.json (the cameras in its order); without it odocal tracks one video: run track once per video",
                v.display()
            );
        }
        for (given, flag) in [
            (self.arena_report.is_some(), "--arena-report"),
            (self.arena_truth.is_some(), "--arena-truth"),
            (self.max_clock_offset_s.is_some(), "--max-clock-offset-s"),
        ] {
            if given {
                anyhow::bail!("{flag} is for an arena's cameras and needs --arena arena.json");
            }
        }
        Ok(())
    }

    /// Whether this run tracks several tags or several cameras.
    pub fn wanted(&self) -> bool {
        self.tags.is_some() || self.arena.is_some()
    }
}

/// The widest clock search `--max-clock-offset-s` takes, seconds: a minute covers cameras
/// started by hand one after another; wider, trim the videos to a common start.
const MAX_CLOCK_OFFSET_S: f64 = 60.0;

/// The trajectory file of tag `id`: `--out` itself for a single id, else `STEM_tagID.EXT`.
fn out_path(out: &Path, id: u32, single: bool) -> PathBuf {
    if single {
        return out.to_path_buf();
    }
    let stem = out
        .file_stem()
        .and_then(|s| s.to_str())
        .unwrap_or("trajectory");
    let ext = out.extension().and_then(|s| s.to_str()).unwrap_or("csv");
    out.with_file_name(format!("{stem}_tag{id}.{ext}"))
}

/// Runs `odocal track` for several tags or an arena.
pub fn run(args: super::track::Args) -> anyhow::Result<()> {
    let m = &args.multi;
    let selection = match &m.tags {
        Some(s) => TagSelection::parse(s)?,
        None => TagSelection::Ids(vec![args.tag.tag_id]),
    };
    selection.check(&args.tag.family)?;
    let single = matches!(&selection, TagSelection::Ids(ids) if ids.len() == 1);
    if let TagSelection::Ids(ids) = &selection {
        for id in ids {
            check_output_file(&out_path(&args.out, *id, single), "--out")?;
        }
    }
    // A frame folder is read whole: an output inside it would be read as a frame next time,
    // as with one tag in one video.
    let folders: Vec<PathBuf> = std::iter::once(&args.video)
        .chain(&m.more_videos)
        .filter(|v| v.is_dir())
        .cloned()
        .collect();
    if !folders.is_empty() {
        let mut outputs: Vec<(PathBuf, &str)> = match &selection {
            TagSelection::Ids(ids) => ids
                .iter()
                .map(|id| (out_path(&args.out, *id, single), "--out"))
                .collect(),
            // Every id's file lands next to --out.
            _ => vec![(args.out.clone(), "--out")],
        };
        if let Some(r) = &m.arena_report {
            outputs.push((r.clone(), "--arena-report"));
        }
        for (path, option) in &outputs {
            check_output_not_input(path, option, &folders, "a frame folder tracked")?;
        }
    }
    for (flag, given) in [
        ("--tum", args.tum.is_some()),
        ("--overlay", args.overlay.is_some()),
        ("--report", args.report.is_some()),
        ("--truth", args.truth.is_some()),
    ] {
        if given {
            bail!("{flag} is for one tag in one video; with --arena use --arena-report and --arena-truth");
        }
    }
    quiet_video_logs();
    let opts = super::track::options(&args)?;
    let trajectories: Vec<(u32, Trajectory)> = match &m.arena {
        Some(arena_path) => track_arena(&args, arena_path, &opts, &selection)?,
        None => track_one_video(&args, &opts, &selection)?,
    };
    for (id, t) in &trajectories {
        let path = out_path(&args.out, *id, single);
        check_output_file(&path, "--out")?;
        write_atomic(&path, t.to_csv().as_bytes())?;
    }
    commit()?;
    for (id, t) in &trajectories {
        let path = out_path(&args.out, *id, single);
        tell!("tag {id}: {} poses → {}", t.rows.len(), path.display());
    }
    Ok(())
}

fn fixes_to_trajectories(
    results: BTreeMap<u32, TrackResult>,
) -> anyhow::Result<Vec<(u32, Trajectory)>> {
    let mut out = Vec::new();
    for (id, r) in results {
        if r.fixes().next().is_none() {
            tell!("warning: tag {id} never gave a confident fix; no file written for it");
            continue;
        }
        out.push((id, r.trajectory()?));
    }
    Ok(out)
}

/// What the frames' timing says about one video (dropped or repeated frames, a clock that
/// jumps, a file cut short): once for the video, or for the tags it concerns where it
/// differs between them (a fix repeated in one tag's frames). A tag never fixed has no
/// motion to place a repeated image by, so it is left out where others were fixed.
fn say_timing(video: &Path, per_tag: &BTreeMap<u32, TrackResult>) {
    let fixed: Vec<_> = per_tag
        .iter()
        .filter(|(_, r)| r.fixes().next().is_some())
        .collect();
    let judged = if fixed.is_empty() {
        per_tag.iter().collect()
    } else {
        fixed
    };
    let mut said: Vec<(String, Vec<String>)> = Vec::new();
    for (id, r) in &judged {
        for w in TimingReport::of(r).warnings() {
            match said.iter_mut().find(|(s, _)| *s == w) {
                Some((_, ids)) => ids.push(id.to_string()),
                None => said.push((w, vec![id.to_string()])),
            }
        }
    }
    for (w, ids) in said {
        if ids.len() == judged.len() {
            tell!("warning: {}: {w}", video.display());
        } else {
            tell!("warning: {}: tag {}: {w}", video.display(), ids.join(", "));
        }
    }
}

fn track_one_video(
    args: &super::track::Args,
    opts: &TrackOptions,
    selection: &TagSelection,
) -> anyhow::Result<Vec<(u32, Trajectory)>> {
    let camera_file = CameraFile::load(&args.camera)?;
    let floor = *camera_file.require_floor(&args.camera)?;
    opts.check(camera_file.floor.as_ref().map(|f| f.camera_height_m))?;
    let source = open_source(
        &args.video,
        &SourceOptions {
            fps: args.fps,
            timestamps: args.timestamps.clone(),
        },
    )?;
    let bar = progress(source.info().frame_count.unwrap_or(0) as u64, "tracking");
    let opts = &opts.clone().with_calibration(&camera_file);
    let results = track_source_multi(
        source,
        &camera_file.camera,
        &floor,
        opts,
        selection,
        &mut |_| bar.inc(1),
    );
    bar.finish_and_clear();
    let results = results?;
    say_timing(&args.video, &results);
    for (id, r) in &results {
        // The warnings name the tag by the options' id, which is --tag-id's, not this one.
        let opts = TrackOptions {
            tag_id: *id,
            ..opts.clone()
        };
        let others = r.other_tag_warning(*id);
        for w in others
            .into_iter()
            .chain(fix_warnings(r, &camera_file, &floor, &opts))
        {
            tell!("warning: {}: tag {id}: {w}", args.video.display());
        }
    }
    let why = why_no_fix(
        std::slice::from_ref(&results),
        std::slice::from_ref(&args.video),
        opts,
    );
    let out = fixes_to_trajectories(results)?;
    if out.is_empty() {
        bail!(
            "no selected tag gave a confident fix in {}: {why}",
            args.video.display()
        );
    }
    Ok(out)
}

/// Why no selected tag gave a fix, as the camera that saw a selected tag most explains it
/// (its rejection reasons and their figures), or that no camera saw one.
fn why_no_fix(
    results: &[odocal_arena::CameraResult],
    videos: &[PathBuf],
    opts: &TrackOptions,
) -> String {
    let seen = results
        .iter()
        .zip(videos)
        .flat_map(|(per_id, video)| {
            per_id
                .iter()
                .map(move |(id, r)| (r.seen_ids.get(id).copied().unwrap_or(0), *id, r, video))
        })
        .max_by_key(|(n, id, _, _)| (*n, std::cmp::Reverse(*id)));
    match seen {
        Some((n, id, r, video)) if n > 0 => {
            let opts = TrackOptions {
                tag_id: id,
                ..opts.clone()
            };
            r.no_fix_message(&opts, video)
        }
        _ => {
            let mut ids: Vec<u32> = results
                .iter()
                .flat_map(|per_id| per_id.values().flat_map(|r| r.seen_ids.keys().copied()))
                .collect();
            ids.sort_unstable();
            ids.dedup();
            let ids: Vec<String> = ids.iter().map(u32::to_string).collect();
            // A tag of another family is read in no frame, or as shapeless false codes: a few
            // frames of the first video are read with the other families, as `track` does.
            let family = videos
                .first()
                .and_then(|v| {
                    odocal_tracker::detect::probe_video_families(v, &SourceOptions::default(), &opts.family)
                        .ok()
                        .map(|p| (v, p))
                })
                .and_then(|(v, p)| {
                    let r = p.reading?;
                    Some(format!(
                        "; the tag in {} of {} frames tried of {} reads as {} id {} (every bit right): give --family {}",
                        r.frames,
                        p.frames_tried,
                        v.display(),
                        r.family,
                        r.id,
                        r.family
                    ))
                })
                .unwrap_or_default();
            format!(
                "no selected tag was seen in any frame of the {} video(s) (ids seen: {}); check --tags and --family{family}",
                videos.len(),
                if ids.is_empty() { "none".into() } else { ids.join(", ") }
            )
        }
    }
}

fn track_arena(
    args: &super::track::Args,
    arena_path: &Path,
    opts: &TrackOptions,
    selection: &TagSelection,
) -> anyhow::Result<Vec<(u32, Trajectory)>> {
    let m = &args.multi;
    if let Some(p) = &m.arena_report {
        check_output_file(p, "--arena-report")?;
    }
    if args.fps.is_some() || args.timestamps.is_some() {
        bail!("--fps and --timestamps are for one video; arena videos carry their own timestamps (a frame folder its timestamps.csv)");
    }
    let max_clock_offset_s = m.max_clock_offset_s.unwrap_or(DEFAULT_MAX_CLOCK_OFFSET_S);
    if !(max_clock_offset_s.is_finite()
        && max_clock_offset_s > 0.0
        && max_clock_offset_s <= MAX_CLOCK_OFFSET_S)
    {
        bail!(
            "--max-clock-offset-s {max_clock_offset_s}: the cameras' clocks are searched over 0 up to {MAX_CLOCK_OFFSET_S} s apart (even cameras started together are milliseconds apart); give the seconds between the cameras' starts, or less"
        );
    }
    let videos: Vec<PathBuf> = std::iter::once(args.video.clone())
        .chain(m.more_videos.iter().cloned())
        .collect();
    odocal_arena::check_frame_folders(&videos)?;
    let arena = ArenaFile::load(arena_path)?;
    // Judged before the tracking, which takes minutes.
    if let Some(dir) = &m.arena_truth {
        check_truth_of_arena(dir, &arena)?;
    }
    // Files from before the calibrations' covariance was carried through the shared boards
    // give σ that leave out what the calibrations share.
    if arena
        .cameras
        .iter()
        .skip(1)
        .any(|c| c.pose_covariance.is_none())
    {
        tell!(
            "note: {} carries no calibration covariance for its cameras after the first (written by an older odocal, or from camera files without one): the fused σ leave out the calibrations' shared error; run `odocal arena` again on camera files written by `odocal calibrate` (they carry it)",
            arena_path.display()
        );
    }
    let lowest = arena
        .cameras
        .iter()
        .map(|c| c.arena_to_camera.0.inverse().translation.vector.z)
        .fold(f64::INFINITY, f64::min);
    opts.check(Some(lowest))?;
    tell!("tracking {} videos in parallel", videos.len());
    let results = track_cameras(&arena, &videos, opts, selection, true)?;
    for ((cam, per_tag), video) in arena.cameras.iter().zip(&results).zip(&videos) {
        say_timing(video, per_tag);
        for (id, r) in per_tag {
            let shape = tag_shape_warnings(r, &cam.calibration, &cam.arena_to_camera, opts);
            let few = few_fixes_warning(r, *id);
            for w in r.other_tag_warning(*id).into_iter().chain(few).chain(shape) {
                tell!("warning: {}: tag {id}: {w}", video.display());
            }
        }
    }
    refuse_cameras_without_fixes(&results, &videos, arena_path)?;
    let fuse = FuseOptions {
        max_offset_s: max_clock_offset_s,
        max_speed_mps: opts.max_speed_mps,
        ..FuseOptions::default()
    };
    let mut tracking =
        fuse_all(&arena, &results, opts.marker_height_m, &fuse).map_err(|e| match e {
            ArenaError::Turned(t) => match videos.get(t.camera) {
                Some(v) => {
                    anyhow::anyhow!(t.message(&format!("{} (camera {})", v.display(), t.camera)))
                }
                None => ArenaError::Turned(t).into(),
            },
            e => e.into(),
        })?;
    // The cameras fuse the tags' positions; the robots' are taken off the mount after.
    for r in &mut tracking.robots {
        r.trajectory = opts.tag_to_robot.robot_trajectory(&r.trajectory);
    }
    if tracking.robots.is_empty() {
        bail!(
            "no robot gave a confident fix in any camera, so nothing was written: {}",
            why_no_fix(&results, &videos, opts)
        );
    }
    if let TagSelection::Ids(ids) = selection {
        for id in ids {
            if !tracking.robots.iter().any(|r| r.tag_id == *id) {
                tell!("warning: tag {id} never gave a confident fix in any camera; no file written for it");
            }
        }
    }
    // A tag mounted turned shows in the fused trajectory as in one camera's; cameras that
    // disagree put a sideways step into it that no mount explains.
    for r in &tracking.robots {
        say_disagreements(r, &tracking.offsets, &videos);
        if let Some(f) = &r.too_fast {
            tell!(
                "warning: tag {}: {} fused rows from {:.2} s to {:.2} s (arena clock) left out: the robot would have moved faster than --max-speed {} m/s to reach them from the rest of its trajectory (up to {:.0} mm in {:.0} ms); another tag {} in one camera's view, or a camera whose fixes are off there (see the warnings above): remove the other tag, or give --max-speed if the robot is that fast",
                r.tag_id,
                f.rows,
                f.from_s,
                f.to_s,
                opts.max_speed_mps,
                f.step_m * 1e3,
                f.step_s * 1e3,
                r.tag_id
            );
        }
        if r.disagreements.is_empty() {
            for w in mount_warnings(&r.trajectory, &opts.tag_to_robot) {
                tell!("warning: tag {}: {w}", r.tag_id);
            }
        }
    }
    say_frame_rates(&tracking);
    say_clocks(&tracking, &results, &videos, max_clock_offset_s);
    if tracking.offsets.pairs.is_empty() {
        say!("no two cameras saw a robot at the same time: nothing ties their positions or clocks together");
    } else {
        say!(
            "simultaneous fixes of two cameras after the offsets: {:.2} mm RMS apart ({} pairs of cameras)",
            tracking.offsets.rms_m * 1e3,
            tracking.offsets.pairs.len()
        );
    }
    for r in &tracking.robots {
        let jump = r.handoffs.iter().map(|h| h.jump_m).fold(0.0, f64::max);
        let dis = r
            .handoffs
            .iter()
            .map(|h| h.disagreement_m)
            .fold(0.0, f64::max);
        say!(
            "tag {}: {} fused poses over {:.2} s, {} handoffs, largest jump at a handoff {:.3} mm (the cameras disagreed by up to {:.2} mm there)",
            r.tag_id,
            r.trajectory.rows.len(),
            r.trajectory.end_s() - r.trajectory.start_s(),
            r.handoffs.len(),
            jump * 1e3,
            dis * 1e3
        );
        let a = &r.agreement;
        if a.fixes > 0 {
            say!(
                "tag {}: simultaneous fixes of different cameras {:.2} mm RMS apart, {:.2} mm at most; {:.2} σ RMS, {:.1} σ at most ({} fixes against the others' fused pose)",
                r.tag_id,
                a.rms_m * 1e3,
                a.max_m * 1e3,
                a.sigmas_rms,
                a.max_sigmas,
                a.fixes
            );
        }
    }
    if let Some(dir) = &m.arena_truth {
        print_against_truth(dir, &tracking, arena.frame_placement.as_ref())?;
    }
    let single = matches!(selection, TagSelection::Ids(ids) if ids.len() == 1);
    if let Some(p) = &m.arena_report {
        let files: Vec<String> = tracking
            .robots
            .iter()
            .map(|r| out_path(&args.out, r.tag_id, single).display().to_string())
            .collect();
        let arena_bytes = std::fs::read(arena_path)
            .with_context(|| format!("cannot read {}", arena_path.display()))?;
        let sha = odocal_core::sha256_hex(&arena_bytes);
        write_json(p, &ArenaTrackFile::of(&tracking, &files, sha))?;
    }
    Ok(tracking
        .robots
        .into_iter()
        .map(|r| (r.tag_id, r.trajectory))
        .collect())
}

/// Refuses a run in which most cameras (more than half) found a selected tag and kept no fix
/// of it while another camera did: the fused trajectories would be the few others' alone, and
/// geometry failing in most cameras at once says the arena's poses or calibrations are not
/// these cameras' (an arena.json of another rig put a camera's fixes 228 mm off with exit 0).
/// Where no camera gave a fix, the fusion's own refusal names the reason.
fn refuse_cameras_without_fixes(
    results: &[odocal_arena::CameraResult],
    videos: &[PathBuf],
    arena_path: &Path,
) -> anyhow::Result<()> {
    let counts: Vec<FoundFrames> = results
        .iter()
        .map(|per_tag| {
            per_tag
                .values()
                .map(FoundFrames::of)
                .fold(FoundFrames::default(), |mut all, c| {
                    all.found += c.found;
                    all.fixes += c.fixes;
                    for (reason, n) in c.left_out {
                        *all.left_out.entry(reason).or_default() += n;
                    }
                    all
                })
        })
        .collect();
    let failed: Vec<(usize, &FoundFrames)> = counts
        .iter()
        .enumerate()
        .filter(|(_, c)| c.judged() && c.fixes == 0)
        .collect();
    if 2 * failed.len() <= results.len() || counts.iter().all(|c| c.fixes == 0) {
        return Ok(());
    }
    let cameras: Vec<String> = failed
        .iter()
        .map(|(k, c)| {
            format!(
                "camera {k} ({}) found one in {} frames, left out: {}",
                videos
                    .get(*k)
                    .map_or(String::new(), |v| v.display().to_string()),
                c.found,
                c.left_out_text()
            )
        })
        .collect();
    bail!(
        "{} of the {} cameras found a selected tag but kept no fix of it ({}), so the trajectories would be the other cameras' alone: {} (or the camera.json files it was built from) is likely not of these cameras, or the videos are not in its camera order; build the arena from these cameras' calibrations (`odocal arena`) and give their videos in its order",
        failed.len(),
        results.len(),
        cameras.join("; "),
        arena_path.display()
    );
}

/// Every camera's clock: its offset and rate, and a note for a camera re-based because its
/// frames' times lie far from the first camera's.
fn say_clocks(
    tracking: &odocal_arena::ArenaTracking,
    results: &[odocal_arena::CameraResult],
    videos: &[PathBuf],
    max_offset_s: f64,
) {
    for (k, prior) in tracking.prior_s.iter().enumerate() {
        if *prior != 0.0 {
            tell!(
                "note: camera {k} ({}): its frames are timed {} from camera 0's, so it counts from another origin (epoch seconds against seconds from the recording's start); its first frame is taken as camera 0's first frame and its clock offset searched within ±{max_offset_s} s of that",
                videos.get(k).map_or(String::new(), |v| v.display().to_string()),
                long_time(prior.abs())
            );
        }
    }
    let offsets = &tracking.offsets;
    for k in 0..offsets.offset_s.len() {
        let (o, sd) = (offsets.offset_s[k], offsets.sigma_s[k]);
        if sd.is_nan() {
            // A camera whose every fix was rejected did see a robot: saying it saw none
            // hid the rejection.
            let counts: Vec<FoundFrames> = results.get(k).map_or(Vec::new(), |per_tag| {
                per_tag.values().map(FoundFrames::of).collect()
            });
            let found: usize = counts.iter().map(|c| c.found).sum();
            if found > 0 && counts.iter().all(|c| c.fixes == 0) {
                say!("camera {k} clock offset unknown: it found a selected tag in {found} frames but kept no fix (the warnings above say why)");
            } else {
                say!("camera {k} clock offset unknown: it saw no robot");
            }
            continue;
        }
        let rate = match offsets.rate[k] {
            ClockRate::None => String::new(),
            ClockRate::Untold { span_s } => format!(
                "; its rate taken as the arena clock's (its overlaps span {span_s:.1} s, too short to tell one)"
            ),
            ClockRate::Equal { sigma_ppm } => format!(
                "; its rate within ±{:.0} ppm of the arena clock's, taken as equal",
                3.0 * sigma_ppm
            ),
            ClockRate::Implausible { ppm } => {
                tell!(
                    "warning: camera {k} ({}): by the robots seen by it and another camera at once its clock runs {ppm:+.0} ppm off the arena clock, beyond any camera clock's ({} ppm): its frame times are not when its frames were taken (timestamps written at a nominal frame rate the camera did not keep, or a video re-timed), and its fixes are fused at those times; check its timestamps against its clock",
                    videos.get(k).map_or(String::new(), |v| v.display().to_string()),
                    odocal_arena::MAX_RATE_PPM
                );
                format!(
                    "; a rate of {ppm:+.0} ppm fitted, beyond any clock's ({} ppm): taken as the arena clock's",
                    odocal_arena::MAX_RATE_PPM
                )
            }
            ClockRate::Fitted { ppm, sigma_ppm } => {
                say!(
                    "camera {k} clock offset {} ± {:.3} ms at {:.3} s on its clock, rate {ppm:+.1} ppm ± {sigma_ppm:.1} ppm: its clock gains {:.3} ms a second on the arena clock (t_arena = t_camera + offset − rate·(t_camera − {:.3} s))",
                    offset_text(o),
                    sd * 1e3,
                    offsets.origin_s[k],
                    ppm * 1e-3,
                    offsets.origin_s[k]
                );
                continue;
            }
        };
        say!(
            "camera {k} clock offset {} ± {:.3} ms (t_arena = t_camera + offset){rate}",
            offset_text(o),
            sd * 1e3
        );
    }
}

/// An offset in milliseconds, or in seconds when it is a re-based clock's (epoch-sized).
fn offset_text(offset_s: f64) -> String {
    if offset_s.abs() < 60.0 {
        format!("{:+.3} ms", offset_s * 1e3)
    } else {
        format!("{offset_s:+.6} s")
    }
}

/// A span of time as a reader takes it in: seconds, hours or days.
fn long_time(s: f64) -> String {
    if s >= 2.0 * 86400.0 {
        format!("{:.0} days", s / 86400.0)
    } else if s >= 2.0 * 3600.0 {
        format!("{:.1} hours", s / 3600.0)
    } else {
        format!("{s:.1} s")
    }
}

/// Warns of every stretch in which a camera's fixes of a robot disagreed with the others far
/// beyond their σ, naming the camera's video and the stretch on both clocks.
fn say_disagreements(
    r: &odocal_arena::FusedTrack,
    offsets: &odocal_arena::ClockOffsets,
    videos: &[PathBuf],
) {
    for d in &r.disagreements {
        let own = |t_s: f64| offsets.to_camera(d.camera, t_s);
        let video = videos
            .get(d.camera)
            .map_or(String::new(), |v| format!(" ({})", v.display()));
        let done = if d.left_out {
            "left out of the fused poses there; where no other camera saw the robot its fixes are kept and may be as far off".to_string()
        } else {
            "which camera is wrong could not be told, so the fused σ there are widened to cover the cameras' spread".to_string()
        };
        // Where its rate was not fitted, a clock running at another rate is a third cause.
        let rate = match offsets.rate.get(d.camera) {
            Some(ClockRate::Untold { span_s }) => format!(
                "; or its clock runs at another rate than the others' (its overlaps span {span_s:.1} s, too short to fit one; 29.97 against 30 frames/s drifts 1 ms a second): drive a robot through its overlaps for longer"
            ),
            _ => String::new(),
        };
        tell!(
            "warning: tag {}: camera {}{video} disagrees with the other cameras seeing the robot by up to {:.1} mm ({:.0} σ) at {} instants from {:.2} s to {:.2} s (arena clock; {:.2}–{:.2} s on its own): {done}. Its clock jumped (frames dropped and the video re-encoded at a constant frame rate: track the original recording) or the camera moved since `odocal arena` (calibrate it and build the arena again){rate}",
            r.tag_id,
            d.camera,
            d.max_m * 1e3,
            d.max_sigmas,
            d.instants,
            d.from_s,
            d.to_s,
            own(d.from_s),
            own(d.to_s)
        );
    }
}

/// Each camera's frame rate, and the instants the fused rows fall on.
fn say_frame_rates(tracking: &odocal_arena::ArenaTracking) {
    let rates: Vec<String> = tracking
        .frame_period_s
        .iter()
        .map(|p| p.map_or("-".to_string(), |p| format!("{:.3}", 1.0 / p)))
        .collect();
    say!(
        "frame rates {} frames/s (cameras 0-{}); each camera's clock gets an offset, and a rate where its overlaps span {} s or more",
        rates.join(", "),
        rates.len().saturating_sub(1),
        odocal_arena::MIN_RATE_SPAN_S
    );
    let reference = tracking.offsets.reference;
    let whose = if reference == 0 {
        "the first camera's".to_string()
    } else {
        format!("camera {reference}'s, the first camera that saw a robot")
    };
    // The rows fall on the reference camera's frames when the fastest rate is a whole
    // multiple of its own.
    let per_frame = tracking
        .frame_period_s
        .get(reference)
        .copied()
        .flatten()
        .map(|p| p / tracking.grid.period_s)
        .filter(|n| (n - n.round()).abs() < 0.01)
        .map(f64::round);
    let placed = match per_frame {
        Some(n) if n <= 1.0 => "on its frames".to_string(),
        Some(n) => format!("on its frames and {} between each two", n - 1.0),
        None => "from its first frame".to_string(),
    };
    say!(
        "the arena clock is {whose}; the fused rows are {:.3} a second (the fastest camera's rate), {placed}",
        1.0 / tracking.grid.period_s
    );
}

/// The share of a fused row's weight from which a camera counts as one of the row's makers
/// (under it the row is the other camera's alone).
const SHARE_OF_A_ROW: f64 = 0.1;

/// Each robot's error against the synthetic truth, and the offsets against the true ones.
/// How far (metres) a camera's height, or two cameras' distance, may differ between the
/// arena file and a truth of it: the arena places cameras to millimetres.
const TRUTH_PLACEMENT_TOLERANCE_M: f64 = 0.1;

/// Refuses an `--arena-truth` of another arena: its cameras at other heights or distances
/// than the arena file's (compared without frames: heights above the floor, distances
/// between cameras). Another arena's truth read as clock offsets 90-106 ms off, a tracker
/// error, exit 0.
fn check_truth_of_arena(dir: &Path, arena: &ArenaFile) -> anyhow::Result<()> {
    let truth = ArenaTruth::read(&dir.join("truth.json"))?;
    let centres = |poses: Vec<nalgebra::Isometry3<f64>>| -> Vec<nalgebra::Vector3<f64>> {
        poses
            .iter()
            .map(|p| p.inverse().translation.vector)
            .collect()
    };
    let placed = centres(arena.cameras.iter().map(|c| c.arena_to_camera.0).collect());
    let true_ = centres(truth.cameras.iter().map(|c| c.arena_to_camera.0).collect());
    if placed.len() != true_.len() {
        bail!(
            "--arena-truth {}: the truth of an arena of {} cameras, where the arena file has {}: give the truth of this arena",
            dir.display(),
            true_.len(),
            placed.len()
        );
    }
    let n = placed.len();
    for k in 0..n {
        let (a, t) = (placed[k].z, true_[k].z);
        if (a - t).abs() > TRUTH_PLACEMENT_TOLERANCE_M {
            bail!(
                "--arena-truth {}: its camera {k} is {t:.2} m above the floor, where the arena file puts it {a:.2} m up: give the truth of this arena",
                dir.display()
            );
        }
        for j in k + 1..n {
            let (a, t) = ((placed[k] - placed[j]).norm(), (true_[k] - true_[j]).norm());
            if (a - t).abs() > TRUTH_PLACEMENT_TOLERANCE_M {
                bail!(
                    "--arena-truth {}: its cameras {k} and {j} are {t:.2} m apart, where the arena file puts them {a:.2} m apart: give the truth of this arena",
                    dir.display()
                );
            }
        }
    }
    Ok(())
}

fn print_against_truth(
    dir: &Path,
    tracking: &odocal_arena::ArenaTracking,
    frame: Option<&odocal_arena::FramePlacement>,
) -> anyhow::Result<()> {
    let truth = ArenaTruth::read(&dir.join("truth.json"))?;
    // The truth's clock is camera 0's; the arena's is the reference camera's.
    let to_truth_s = truth
        .cameras
        .get(tracking.offsets.reference)
        .map_or(0.0, |c| c.clock_offset_s);
    for (k, c) in truth.cameras.iter().enumerate() {
        match tracking.offsets.offset_s.get(k) {
            Some(_) if tracking.offsets.sigma_s[k].is_nan() => {}
            Some(o) => say!(
                "against the truth: camera {k} clock offset off by {:.3} ms",
                (o + to_truth_s - c.clock_offset_s).abs() * 1e3
            ),
            None => {}
        }
    }
    // Each robot's fused rows with the truth at their time.
    let mut robots = Vec::new();
    for r in &tracking.robots {
        let Some(rt) = truth.robots.iter().find(|t| t.tag_id == r.tag_id) else {
            say!(
                "against the truth: tag {} is no robot of the arena",
                r.tag_id
            );
            continue;
        };
        let tt = Trajectory::read_csv(&dir.join(&rt.trajectory))?;
        let truths: Vec<Option<nalgebra::Point2<f64>>> = r
            .trajectory
            .rows
            .iter()
            .map(|row| tt.position_at(row.t_s + to_truth_s, 0.01))
            .collect();
        robots.push((r, truths));
    }
    // How much of the error is one move of every fix: the floor frame's placement, and what
    // the cameras' calibrations move alike.
    let (truth_at, fixed_at): (Vec<_>, Vec<_>) = robots
        .iter()
        .flat_map(|(r, truths)| {
            r.trajectory
                .rows
                .iter()
                .zip(truths)
                .filter_map(|(row, t)| Some(((*t)?, row.pose.position())))
        })
        .unzip();
    let common = odocal_core::fit_rigid(&truth_at, &fixed_at).ok();
    if let Some(c) = &common {
        let placement = frame.map_or(
            "the arena file states no σ of the floor frame's placement".to_string(),
            |f| {
                let o = f.origin_sigma_m();
                format!(
                    "the floor frame's placement alone has σ {:.3} mrad and ({:.2}, {:.2}) mm",
                    f.heading_sigma_rad() * 1e3,
                    o.x * 1e3,
                    o.y * 1e3
                )
            },
        );
        say!(
            "against the truth: every robot's fixes together sit turned {:.3} mrad and shifted ({:.2}, {:.2}) mm from the truth, one move common to all ({placement}; the cameras' calibrations add to it)",
            c.pose.theta_rad * 1e3,
            c.pose.x_m * 1e3,
            c.pose.y_m * 1e3
        );
    }
    for (r, truths) in &robots {
        let rows = &r.trajectory.rows;
        let err = |i: usize| truths[i].map(|p| rows[i].pose.position() - p);
        let errs: Vec<_> = (0..rows.len()).filter_map(err).collect();
        // Each row's error over its σ on each axis, where the row has σ.
        let z_row: Vec<Option<[f64; 2]>> = (0..rows.len())
            .map(|i| {
                let (e, s) = (err(i)?, rows[i].sigma?);
                Some([e.x / s.x_m, e.y / s.y_m])
            })
            .collect();
        let z: Vec<f64> = z_row.iter().flatten().flatten().copied().collect();
        let rms_of = |v: &[nalgebra::Vector2<f64>]| {
            (v.iter().map(|e| e.norm_squared()).sum::<f64>() / v.len().max(1) as f64).sqrt()
        };
        let rms = rms_of(&errs);
        let apart: Vec<_> = (0..rows.len())
            .filter_map(|i| {
                let c = common.as_ref()?;
                Some(rows[i].pose.position() - c.pose.transform_point(&truths[i]?))
            })
            .collect();
        let max = errs.iter().map(|e| e.norm()).fold(0.0, f64::max);
        let mut step: f64 = 0.0;
        for h in &r.handoffs {
            if let Some(i) = rows.iter().position(|x| (x.t_s - h.t_s).abs() < 1e-9) {
                let (a, b) = if h.joins {
                    (i.saturating_sub(1), i)
                } else {
                    (i, (i + 1).min(rows.len() - 1))
                };
                if let (Some(ea), Some(eb)) = (err(a), err(b)) {
                    step = step.max((eb - ea).norm());
                }
            }
        }
        let z_rms = if z.is_empty() {
            String::new()
        } else {
            format!(
                "; error/σ RMS per axis {:.2} (1 when σ is honest)",
                (z.iter().map(|v| v * v).sum::<f64>() / z.len() as f64).sqrt()
            )
        };
        // Which camera's σ is off, when one is: the rows by the camera with the largest
        // share of each, and the rows two or more cameras share.
        let mut by_camera: BTreeMap<String, (f64, usize)> = BTreeMap::new();
        for (zr, parts) in z_row.iter().zip(&r.contributions) {
            let Some([zx, zy]) = zr else {
                continue;
            };
            let lead = parts.iter().max_by(|a, b| a.1.total_cmp(&b.1)).map(|p| p.0);
            let shared = parts.iter().filter(|p| p.1 >= SHARE_OF_A_ROW).count() >= 2;
            let key = match (lead, shared) {
                (_, true) => "two or more cameras".to_string(),
                (Some(k), false) => format!("camera {k} alone"),
                (None, false) => continue,
            };
            let v = by_camera.entry(key).or_default();
            v.0 += zx * zx + zy * zy;
            v.1 += 2;
        }
        if by_camera.len() > 1 {
            say!(
                "against the truth: tag {}'s error/σ (RMS per axis) by the cameras that made each row (another camera's share under {:.0} %: alone): {}",
                r.tag_id,
                SHARE_OF_A_ROW * 100.0,
                by_camera
                    .iter()
                    .map(|(k, (z2, n))| {
                        let rows = n / 2;
                        let s = if rows == 1 { "" } else { "s" };
                        format!("{k} {:.2} ({rows} row{s})", (z2 / *n as f64).sqrt())
                    })
                    .collect::<Vec<_>>()
                    .join(", ")
            );
        }
        say!(
            "against the truth: tag {} position RMS {:.3} mm, max {:.3} mm over {} poses ({:.3} mm RMS with the common move taken out); largest error step at a handoff {:.3} mm{z_rms}",
            r.tag_id,
            rms * 1e3,
            max * 1e3,
            errs.len(),
            rms_of(&apart) * 1e3,
            step * 1e3
        );
    }
    Ok(())
}
