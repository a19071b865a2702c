//! Tracking across cameras: the cameras' clock offsets from robots seen by two cameras at
//! once, and one trajectory per robot from all cameras' fixes.
//!
//! Time: every camera's fixes carry its own clock (seconds from its video's first frame).
//! Each camera's clock is related to the arena clock by an offset and, where the camera's
//! overlaps with the others span long enough to tell one ([`MIN_RATE_SPAN_S`]), a rate: a
//! 29.97 frames/s camera stamped as if at 30 drifts 1000 ppm, 60 ms a minute, which one
//! constant offset cannot follow ([`ClockRate`]). The reference camera's offset is 0 (the
//! arena clock is the first camera's, or the first camera's that saw a robot if it saw none).
//! A robot seen by two cameras gives their offset: the shift that best lays one camera's
//! interpolated track onto the other's fixes. A robot moving in a straight line at constant
//! speed cannot tell a time shift from a small disagreement in position along its path, so
//! the estimate needs turns or speed changes in the overlaps; its standard deviation is
//! reported.
//!
//! Each camera keeps its own frame rate (a 15 frames/s USB camera among 30 frames/s ones, or
//! a 60 among 30): what counts frames counts that camera's own ([`CameraTrack::period_s`]).
//!
//! Fusion: on a grid ([`FuseGrid`]) at the fastest camera's frame period from the reference
//! camera's first frame (its frame times when it is the fastest or a whole multiple of it),
//! each camera that saw the robot shortly before and after (within
//! [`FuseOptions::max_gap_frames`] of its own frames) contributes its pose interpolated to
//! that instant, weighted by [`fix_weight`]: the inverse variance of the fix, which fades to
//! nearly nothing towards the image border, so that a camera joining or leaving the fused set
//! moves the result by a negligible amount (the handoff has no jump). Each row's σ keeps the
//! fixes' calibration part whole ([`CameraFix::shared_m`]): the cameras' calibrations and
//! arena poses are tied through the shared boards, so their errors do not average out.
//! Simultaneous fixes of different cameras are judged against their σ: a camera far off the
//! others ([`DISAGREE_SIGMAS`]) is left out where it is, or the row's σ widened where which
//! camera is wrong cannot be told, and named ([`Disagreement`]).

use std::collections::BTreeMap;

use nalgebra::{DMatrix, Point2, Vector2};
use odocal_calib::{CameraModel, FloorToCamera};
use odocal_core::{wrap_angle, Pose2, PoseSigma, Trajectory, TrajectoryRow};

use crate::ArenaError;

/// The smallest relative weight a fix keeps at the image border, so that a robot seen by one
/// camera only, at the edge of its view, still has a pose.
const MIN_TAPER: f64 = 1e-3;

/// One camera's fix of one robot, in the arena's floor frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CameraFix {
    /// Time on the camera's own clock, seconds.
    pub t_s: f64,
    /// The robot's pose (body frame into the arena's floor frame).
    pub pose: Pose2,
    /// The fix's weight in the fusion ([`fix_weight`]), 1/m².
    pub weight: f64,
    /// The tracker's quality in (0, 1].
    pub quality: f64,
    /// The fix's standard deviations (corner noise and calibration), when known.
    pub sigma: Option<PoseSigma>,
    /// The part of `sigma`'s position σ, per axis (x, y), metres, that the calibrations put
    /// there: the same error in every fix of this camera nearby, and tied to the other
    /// cameras' through the shared boards, so it averages down neither over fixes nor between
    /// cameras. Per axis, because a turn of the floor frame moves a fix across the line to the
    /// origin, not along it.
    pub shared_m: Vector2<f64>,
}

/// One camera's fixes of one robot, in increasing time.
#[derive(Debug, Clone, PartialEq)]
pub struct CameraTrack {
    /// Index of the camera in the arena.
    pub camera: usize,
    /// The robot's tag id.
    pub tag_id: u32,
    /// The fixes, strictly increasing in time.
    pub fixes: Vec<CameraFix>,
    /// The camera's frame period, seconds (its median interval between frames): gaps and
    /// lags are counted in this camera's own frames.
    pub period_s: f64,
}

impl CameraTrack {
    /// Index i with fixes[i].t <= t < fixes[i+1].t, and where t lies between them; none
    /// across more than `max_gap_frames` of the camera's frames.
    fn bracket(&self, t: f64, max_gap_frames: f64) -> Option<(usize, f64)> {
        let f = &self.fixes;
        let n = f.len();
        if n < 2 || !(t >= f[0].t_s && t <= f[n - 1].t_s) {
            return None;
        }
        let i = f
            .partition_point(|x| x.t_s <= t)
            .saturating_sub(1)
            .min(n - 2);
        let span = f[i + 1].t_s - f[i].t_s;
        (span <= max_gap_frames * self.period_s).then(|| (i, (t - f[i].t_s) / span))
    }

    /// The fix at time `t` (own clock), interpolated; none outside or across a gap.
    fn at(&self, t: f64, max_gap_frames: f64) -> Option<CameraFix> {
        let (i, w) = self.bracket(t, max_gap_frames)?;
        let (a, b) = (&self.fixes[i], &self.fixes[i + 1]);
        let mix = |u: f64, v: f64| u + w * (v - u);
        Some(CameraFix {
            t_s: t,
            pose: a.pose.lerp(&b.pose, w),
            weight: mix(a.weight, b.weight),
            quality: mix(a.quality, b.quality),
            sigma: a.sigma.zip(b.sigma).map(|(p, q)| PoseSigma {
                x_m: mix(p.x_m, q.x_m),
                y_m: mix(p.y_m, q.y_m),
                theta_rad: mix(p.theta_rad, q.theta_rad),
            }),
            shared_m: a.shared_m + w * (b.shared_m - a.shared_m),
        })
    }

    /// Position at `t`, extrapolated from the nearest segment outside the track (for the
    /// offset fit, whose matched fixes stay fixed while the offset moves).
    fn position_extrapolated(&self, t: f64) -> Point2<f64> {
        let f = &self.fixes;
        let n = f.len();
        let i = f
            .partition_point(|x| x.t_s <= t)
            .saturating_sub(1)
            .min(n - 2);
        let (a, b) = (&f[i], &f[i + 1]);
        let p = a.pose.lerp(&b.pose, (t - a.t_s) / (b.t_s - a.t_s));
        p.position()
    }
}

/// How a fix weighs in the fusion, 1/m²: the inverse variance of its position, times a taper
/// that falls from 1 to nearly 0 over the last two tag sides before the image border.
///
/// `sigma_m` is the fix's position standard deviation when the tracker gives one; without it
/// the floor footprint of one pixel at the tag stands in (so a fix far off the camera's
/// axis, where a pixel covers more floor, weighs less).
pub fn fix_weight(
    camera: &CameraModel,
    arena_to_camera: &FloorToCamera,
    corners_px: &[Point2<f64>; 4],
    marker_height_m: f64,
    sigma_m: Option<f64>,
) -> f64 {
    let c = odocal_tracker::detect::quad_centre(corners_px);
    let sigma = sigma_m
        .filter(|s| s.is_finite() && *s > 0.0)
        .unwrap_or_else(|| {
            let at = |p: Point2<f64>| camera.pixel_to_floor(arena_to_camera, &p, marker_height_m);
            match (
                at(c),
                at(c + nalgebra::Vector2::new(1.0, 0.0)),
                at(c + nalgebra::Vector2::new(0.0, 1.0)),
            ) {
                (Some(a), Some(b), Some(d)) => 0.5 * ((b - a).norm() + (d - a).norm()),
                _ => 1.0,
            }
        });
    let side_px = (0..4)
        .map(|i| (corners_px[(i + 1) % 4] - corners_px[i]).norm())
        .sum::<f64>()
        / 4.0;
    let border_px = corners_px
        .iter()
        .map(|p| {
            p.x.min(p.y)
                .min(camera.width as f64 - 1.0 - p.x)
                .min(camera.height as f64 - 1.0 - p.y)
        })
        .fold(f64::INFINITY, f64::min);
    let ramp = ((border_px - 2.0) / (2.0 * side_px.max(1.0))).clamp(0.0, 1.0);
    // Smoothstep: the weight's rate of change is zero at both ends of the ramp.
    let taper = ramp * ramp * (3.0 - 2.0 * ramp);
    taper.max(MIN_TAPER) / (sigma * sigma)
}

/// Settings of the offset fit and the fusion.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FuseOptions {
    /// Longest gap between a camera's fixes that is interpolated across, in that camera's
    /// frame periods ([`CameraTrack::period_s`]).
    pub max_gap_frames: f64,
    /// Largest clock offset searched, seconds (either way).
    pub max_offset_s: f64,
    /// Fewest simultaneous fixes for a pair of cameras to give an offset, in frames of the
    /// faster camera of the pair (the slower one's fixes are matched, as many as fall in that
    /// time).
    pub min_matches: usize,
    /// Largest RMS distance between two cameras' simultaneous fixes at their best offset for
    /// the pair to count as having seen the robot at once, metres.
    pub max_pair_rms_m: f64,
    /// Fastest plausible robot speed, m/s: fused rows that would have the robot move faster
    /// to or from the rest of its trajectory are left out ([`FusedTrack::too_fast`]).
    pub max_speed_mps: f64,
}

impl Default for FuseOptions {
    /// Gaps up to 2.5 of a camera's frames bridged, offsets up to ±1 s searched, 10
    /// simultaneous fixes per pair agreeing within 20 mm RMS, robots at most 2 m/s (the
    /// tracker's default).
    fn default() -> Self {
        Self {
            max_gap_frames: 2.5,
            max_offset_s: 1.0,
            min_matches: 10,
            max_pair_rms_m: 0.02,
            max_speed_mps: 2.0,
        }
    }
}

/// The instants of the fused rows, arena clock: `origin_s + k · period_s`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FuseGrid {
    /// An instant of the grid, seconds: the reference camera's first frame time, so that the
    /// rows fall on its frames wherever its clock starts (a grid through 0 missed them by up
    /// to a frame with epoch timestamps).
    pub origin_s: f64,
    /// The rows' spacing, seconds: the fastest camera's frame period, so that no camera's
    /// frames are thinned out.
    pub period_s: f64,
}

/// A fitted clock rate needs the camera's matched fixes to span this long on its clock,
/// seconds: over a shorter stretch a rate and an offset cannot be told apart (1000 ppm, NTSC's
/// 29.97 against 30 frames/s, is 2 ms over it).
pub const MIN_RATE_SPAN_S: f64 = 2.0;

/// The largest clock rate taken for one, ppm: twice NTSC's 1000 ppm (crystals are within
/// 100). A fit asking for more is laying a clock jump (frames dropped) over a rate, and is not
/// taken.
pub const MAX_RATE_PPM: f64 = 2000.0;

/// A camera's clock rate against the arena clock's.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ClockRate {
    /// The reference camera, or a camera that saw no robot: no rate.
    None,
    /// The camera's matched fixes span too short a time to tell a rate (`span_s` seconds,
    /// [`MIN_RATE_SPAN_S`] needed): taken as the reference's.
    Untold {
        /// The span, seconds on the camera's clock.
        span_s: f64,
    },
    /// Fitted, but not told apart from the reference's (within 3 σ): taken as equal.
    Equal {
        /// The fitted rate's σ, ppm.
        sigma_ppm: f64,
    },
    /// Fitted beyond [`MAX_RATE_PPM`]: no clock runs so fast, so the fit was laying a jump
    /// over a rate; taken as equal.
    Implausible {
        /// The fitted rate, ppm.
        ppm: f64,
    },
    /// Fitted and used.
    Fitted {
        /// How much faster the camera's clock runs than the arena clock, ppm.
        ppm: f64,
        /// Its σ, ppm.
        sigma_ppm: f64,
    },
}

impl ClockRate {
    /// The rate used, ppm (0 unless fitted).
    pub fn ppm(&self) -> f64 {
        match self {
            ClockRate::Fitted { ppm, .. } => *ppm,
            _ => 0.0,
        }
    }
}

/// The cameras' clocks on the arena clock: t_arena = t_camera + offset_s[camera] −
/// rate·(t_camera − origin_s[camera]), rate in ppm ([`ClockRate`], 0 unless fitted).
#[derive(Debug, Clone, PartialEq)]
pub struct ClockOffsets {
    /// The camera whose clock is the arena's: the first camera that saw a robot (the first
    /// camera unless it saw none; a camera that saw no robot cannot be placed in time).
    pub reference: usize,
    /// Offset of each camera at its `origin_s`, seconds (the reference camera's is 0).
    pub offset_s: Vec<f64>,
    /// Standard deviation of each offset from the fit, seconds (0 for the reference camera;
    /// NaN for a camera that saw no robot, whose offset is unknown and unused).
    pub sigma_s: Vec<f64>,
    /// Each camera's clock rate against the reference's.
    pub rate: Vec<ClockRate>,
    /// The instant on each camera's clock at which its offset is `offset_s`: its first fix,
    /// seconds (0 for a camera that saw no robot).
    pub origin_s: Vec<f64>,
    /// Pairs of cameras that saw a robot at once, with how many fixes matched.
    pub pairs: Vec<(usize, usize, usize)>,
    /// RMS distance between matched fixes after the fit, metres.
    pub rms_m: f64,
}

impl ClockOffsets {
    /// Camera `k`'s time `t_s` (its own clock) on the arena clock.
    pub fn to_arena(&self, k: usize, t_s: f64) -> f64 {
        clock(
            self.offset_s[k],
            self.rate[k].ppm() * 1e-6,
            self.origin_s[k],
        )
        .0(t_s)
    }

    /// Arena time `t_s` on camera `k`'s clock.
    pub fn to_camera(&self, k: usize, t_s: f64) -> f64 {
        clock(
            self.offset_s[k],
            self.rate[k].ppm() * 1e-6,
            self.origin_s[k],
        )
        .1(t_s)
    }
}

/// A camera clock's map to the arena clock and back, for an offset, a rate (a fraction: the
/// camera's clock gains `rate` seconds a second) and the origin at which the offset holds. The
/// differences from the origin keep epoch times exact.
fn clock(offset_s: f64, rate: f64, origin_s: f64) -> (impl Fn(f64) -> f64, impl Fn(f64) -> f64) {
    (
        move |t: f64| t + offset_s - rate * (t - origin_s),
        move |t: f64| origin_s + (t - offset_s - origin_s) / (1.0 - rate),
    )
}

/// The matched fixes of a pair: (track of camera j, fix index, track of camera i).
type Matches = Vec<(usize, usize, usize)>;

/// Fixes of camera j's track `tj` that camera i's track `ti` brackets when j's clock is
/// shifted by `d` = offset_j − offset_i.
fn matches(
    ti: &CameraTrack,
    tj: &CameraTrack,
    d: f64,
    max_gap_frames: f64,
) -> Vec<(usize, Point2<f64>)> {
    tj.fixes
        .iter()
        .enumerate()
        .filter_map(|(f, fix)| {
            ti.at(fix.t_s + d, max_gap_frames)
                .map(|at| (f, at.pose.position()))
        })
        .collect()
}

/// Coarse offset and matched fixes of every pair (i < j) of cameras that saw a robot at once:
/// offsets searched within ±`opts.max_offset_s` of `prior_s[j] − prior_s[i]` (a camera's
/// prior is 0 where not given).
fn coarse_pairs(
    tracks: &[CameraTrack],
    opts: &FuseOptions,
    prior_s: &[f64],
) -> BTreeMap<(usize, usize), (f64, Matches)> {
    let prior = |k: usize| prior_s.get(k).copied().unwrap_or(0.0);
    let mut pair_best: BTreeMap<(usize, usize), (f64, Matches)> = BTreeMap::new();
    for (a, ta) in tracks.iter().enumerate() {
        for (b, tb) in tracks.iter().enumerate() {
            if ta.tag_id != tb.tag_id || ta.camera >= tb.camera {
                continue;
            }
            // The slower camera's fixes are laid on the faster one's track, interpolated over
            // its shorter frames; the overlap must last `min_matches` of the faster frames.
            // Shifts are scanned as d = offset_b − offset_a either way.
            let (fast, slow, sign) = if tb.period_s >= ta.period_s {
                ((a, ta), (b, tb), 1.0)
            } else {
                ((b, tb), (a, ta), -1.0)
            };
            let need =
                (opts.min_matches as f64 * fast.1.period_s / slow.1.period_s).ceil() as usize;
            let lay = |d: f64| matches(fast.1, slow.1, sign * d, opts.max_gap_frames);
            // An eighth of the faster camera's frame: the scan does not step over its best.
            let step = 0.002_f64.min(fast.1.period_s / 8.0);
            let steps = (opts.max_offset_s / step).ceil() as i64;
            let centre = prior(tb.camera) - prior(ta.camera);
            let mut best: Option<(f64, f64, usize)> = None;
            for s in -steps..=steps {
                let d = centre + s as f64 * step;
                let m = lay(d);
                if m.len() < need.max(1) {
                    continue;
                }
                let cost = m
                    .iter()
                    .map(|(f, p)| (p - slow.1.fixes[*f].pose.position()).norm_squared())
                    .sum::<f64>()
                    / m.len() as f64;
                if best.is_none_or(|(c, _, _)| cost < c) {
                    best = Some((cost, d, m.len()));
                }
            }
            // A shift that lays the tracks on each other leaves only the fixes' noise and the
            // cameras' disagreement; more means the two never saw the robot at once.
            let best = best.filter(|(cost, _, _)| cost.sqrt() <= opts.max_pair_rms_m);
            if let Some((_, d, _)) = best {
                let m: Matches = lay(d)
                    .into_iter()
                    .map(|(f, _)| (slow.0, f, fast.0))
                    .collect();
                let e = pair_best
                    .entry((ta.camera, tb.camera))
                    .or_insert((d, vec![]));
                // Pairs seeing several robots: the coarse offset of the best-matched robot.
                if m.len() > e.1.len() {
                    e.0 = d;
                }
                e.1.extend(m);
            }
        }
    }
    pair_best
}

/// Estimates every camera's clock offset, and its rate where its overlaps span long enough,
/// from the tracks (all cameras, all robots): a coarse scan per pair of cameras (around
/// `prior_s`, each camera's offset guessed beforehand, 0 where not given), chained from the
/// reference camera (the first that saw a robot), then one least-squares fit of all offsets
/// and rates together over every pair's matched fixes; a rate not told apart from 0, or beyond
/// [`MAX_RATE_PPM`], is dropped and the rest fitted again.
pub fn estimate_clock_offsets(
    tracks: &[CameraTrack],
    cameras: usize,
    opts: &FuseOptions,
    prior_s: &[f64],
) -> Result<ClockOffsets, ArenaError> {
    let pair_best = coarse_pairs(tracks, opts, prior_s);
    // Chain the coarse offsets from the reference camera.
    let saw = |k: usize| tracks.iter().any(|t| t.camera == k && !t.fixes.is_empty());
    let reference = (0..cameras).find(|&k| saw(k)).unwrap_or(0);
    let mut offset: Vec<Option<f64>> = vec![None; cameras];
    offset[reference] = Some(0.0);
    loop {
        let mut progress = false;
        for (&(i, j), (d, _)) in &pair_best {
            match (offset[i], offset[j]) {
                (Some(oi), None) => {
                    offset[j] = Some(oi + d);
                    progress = true;
                }
                (None, Some(oj)) => {
                    offset[i] = Some(oj - d);
                    progress = true;
                }
                _ => {}
            }
        }
        if !progress {
            break;
        }
    }
    // A camera that saw no robot needs no offset; one that saw a robot but never at once with
    // a camera tied to the reference cannot be placed in time.
    let missing: Vec<String> = (0..cameras)
        .filter(|&k| offset[k].is_none() && saw(k))
        .map(|k| k.to_string())
        .collect();
    if !missing.is_empty() {
        return Err(ArenaError::Refused(format!(
            "{} {} never saw a robot at the same time as a camera tied to {} (simultaneous fixes over {} frames of the faster camera needed, clock offsets within ±{} s searched): {} unknown; drive a robot through its overlap with another camera, give the videos in the order of the arena's cameras (a video given in another camera's place is mapped through that camera's calibration, so no robot lines up), check that the arena file places it where it hangs (a camera moved since `odocal arena`, or an arena.json edited, puts its fixes away from the others': run `odocal arena` again), and if the cameras were started further apart, widen the search (--max-clock-offset-s)",
            if missing.len() == 1 { "camera" } else { "cameras" },
            missing.join(", "),
            if reference == 0 {
                "the first".to_string()
            } else {
                format!("camera {reference}, whose clock is the arena's (cameras before it saw no robot)")
            },
            opts.min_matches,
            opts.max_offset_s,
            if missing.len() == 1 {
                "its clock offset is"
            } else {
                "their clock offsets are"
            }
        )));
    }
    // The fitted offsets: every camera but the reference that has a first guess.
    let free: Vec<usize> = (0..cameras)
        .filter(|&k| k != reference && offset[k].is_some())
        .collect();
    let init: Vec<f64> = free.iter().filter_map(|&k| offset[k]).collect();
    let all: Matches = pair_best.values().flat_map(|(_, m)| m.clone()).collect();
    let coarse: Vec<f64> = offset.iter().map(|o| o.unwrap_or(0.0)).collect();
    let spans = matched_spans(tracks, &all, &coarse, cameras);
    let origin_s: Vec<f64> = (0..cameras)
        .map(|k| {
            tracks
                .iter()
                .filter(|t| t.camera == k)
                .filter_map(|t| t.fixes.first().map(|f| f.t_s))
                .fold(f64::INFINITY, f64::min)
        })
        .map(|t| if t.is_finite() { t } else { 0.0 })
        .collect();
    let mut rate = vec![ClockRate::None; cameras];
    for &k in &free {
        rate[k] = ClockRate::Untold { span_s: spans[k] };
    }
    let rated: Vec<usize> = free
        .iter()
        .copied()
        .filter(|&k| spans[k] >= MIN_RATE_SPAN_S)
        .collect();
    let fit_with = |rated: &[usize]| fit_clocks(tracks, &all, &free, rated, &origin_s, &init);
    let mut fit = fit_with(&rated);
    let n = free.len();
    let mut told = Vec::new();
    for (i, &k) in rated.iter().enumerate() {
        let (r, s) = (fit.p[n + i] * 1e6, fit.sigma[n + i] * 1e6);
        if r.abs() > MAX_RATE_PPM {
            rate[k] = ClockRate::Implausible { ppm: r };
        } else if r.abs() <= 3.0 * s {
            rate[k] = ClockRate::Equal { sigma_ppm: s };
        } else {
            told.push(k);
        }
    }
    if told.len() < rated.len() {
        fit = fit_with(&told);
    }
    for (i, &k) in told.iter().enumerate() {
        rate[k] = ClockRate::Fitted {
            ppm: fit.p[n + i] * 1e6,
            sigma_ppm: fit.sigma[n + i] * 1e6,
        };
    }
    // Cameras that saw no robot keep offset 0 with an unknown (NaN) standard deviation.
    let mut offset_s = vec![0.0; cameras];
    let mut sigma_s = vec![f64::NAN; cameras];
    sigma_s[reference] = 0.0;
    for (i, &k) in free.iter().enumerate() {
        offset_s[k] = fit.p[i];
        sigma_s[k] = fit.sigma[i];
    }
    Ok(ClockOffsets {
        reference,
        offset_s,
        sigma_s,
        rate,
        origin_s,
        pairs: pair_best
            .iter()
            .map(|(&(i, j), (_, m))| (i, j, m.len()))
            .collect(),
        rms_m: fit.rms_m,
    })
}

/// How long each camera's matched fixes span on its own clock, seconds (a match's time on
/// the other camera's clock through the coarse offsets).
fn matched_spans(
    tracks: &[CameraTrack],
    all: &Matches,
    coarse_s: &[f64],
    cameras: usize,
) -> Vec<f64> {
    let mut range = vec![(f64::INFINITY, f64::NEG_INFINITY); cameras];
    for &(tj, f, ti) in all {
        let (a, b) = (tracks[ti].camera, tracks[tj].camera);
        let t = tracks[tj].fixes[f].t_s;
        for (k, t) in [(b, t), (a, t + coarse_s[b] - coarse_s[a])] {
            range[k] = (range[k].0.min(t), range[k].1.max(t));
        }
    }
    range.iter().map(|(lo, hi)| (hi - lo).max(0.0)).collect()
}

/// The least-squares fit of the clocks: the offsets of `free` (after `init`) and the rates of
/// `rated` (fractions), each with its σ, and the matched fixes' RMS distance, metres.
struct ClockFit {
    p: Vec<f64>,
    sigma: Vec<f64>,
    rms_m: f64,
}

fn fit_clocks(
    tracks: &[CameraTrack],
    all: &Matches,
    free: &[usize],
    rated: &[usize],
    origin_s: &[f64],
    init: &[f64],
) -> ClockFit {
    let n = free.len();
    // The offsets are fitted as steps from their first guesses, so that epoch-sized offsets
    // do not make the numeric derivatives' steps seconds long.
    let at = |p: &[f64], k: usize| {
        let o = free
            .iter()
            .position(|&f| f == k)
            .map_or(0.0, |i| init[i] + p[i]);
        let r = rated.iter().position(|&f| f == k).map_or(0.0, |i| p[n + i]);
        clock(o, r, origin_s[k])
    };
    let residuals = |p: &[f64]| -> Vec<f64> {
        let mut r = Vec::with_capacity(all.len() * 2);
        for &(tj, f, ti) in all {
            let (a, b) = (&tracks[ti], &tracks[tj]);
            let fix = &b.fixes[f];
            let t = at(p, a.camera).1(at(p, b.camera).0(fix.t_s));
            let d = a.position_extrapolated(t) - fix.pose.position();
            r.push(d.x);
            r.push(d.y);
        }
        r
    };
    let (p, _) = odocal_core::lsq::minimize(&residuals, vec![0.0; n + rated.len()], 100);
    let r = residuals(&p);
    let m = r.len();
    let ssr: f64 = r.iter().map(|v| v * v).sum();
    // Covariance s²(JᵀJ)⁻¹ from a central-difference Jacobian at the optimum.
    let np = p.len();
    let mut jac = DMatrix::zeros(m, np);
    for c in 0..np {
        let h = 1e-5;
        let (mut a, mut b) = (p.clone(), p.clone());
        a[c] += h;
        b[c] -= h;
        let (ra, rb) = (residuals(&a), residuals(&b));
        for row in 0..m {
            jac[(row, c)] = (ra[row] - rb[row]) / (2.0 * h);
        }
    }
    // The residuals of nearby frames are alike (each camera's calibration places the robot a
    // little off in the same way all through an overlap), so they are fewer independent
    // measurements than there are fixes: the variance grows by their integrated
    // autocorrelation time τ = 1 + 2 Σ ρ(L) over frame lags L up to half a second, summed
    // while ρ stays positive.
    let half_second: Vec<usize> = tracks
        .iter()
        .map(|t| (0.5 / t.period_s).round().max(1.0) as usize)
        .collect();
    let s2 =
        ssr / (m.saturating_sub(np)).max(1) as f64 * autocorrelation_time(all, &r, &half_second);
    let cov = (jac.transpose() * &jac).try_inverse();
    let sigma = (0..np)
        .map(|i| {
            cov.as_ref()
                .map_or(f64::INFINITY, |cv| (s2 * cv[(i, i)]).sqrt())
        })
        .collect();
    let p = p
        .iter()
        .enumerate()
        .map(|(i, v)| if i < n { init[i] + v } else { *v })
        .collect();
    ClockFit {
        p,
        sigma,
        rms_m: (ssr / (m / 2).max(1) as f64).sqrt(),
    }
}

/// The integrated autocorrelation time of the matched fixes' residuals `r` (x and y of each
/// match of `all`, in order), over lags of 1 to `max_lag[track]` frames between matches of the
/// same pair of tracks (the lag in frames of the track whose fixes were matched, each camera
/// at its own frame rate); 1 for independent residuals, at most 100.
fn autocorrelation_time(all: &[(usize, usize, usize)], r: &[f64], max_lag: &[usize]) -> f64 {
    let norm: f64 = r.iter().map(|v| v * v).sum();
    if norm <= 0.0 {
        return 1.0;
    }
    let mut tau = 1.0;
    for lag in 1..=max_lag.iter().copied().max().unwrap_or(0) {
        let mut sum = 0.0;
        // Pooled over the pairs, ρ(L) is their residuals' energy-weighted mean, and so is τ.
        for (k, a) in all.iter().enumerate().filter(|(_, a)| lag <= max_lag[a.0]) {
            // Matches of one pair are in frame order, so the one `lag` frames on is at most
            // `lag` places on.
            for (l, b) in all.iter().enumerate().skip(k + 1).take(lag) {
                if a.0 == b.0 && a.2 == b.2 && b.1 == a.1 + lag {
                    sum += r[2 * k] * r[2 * l] + r[2 * k + 1] * r[2 * l + 1];
                }
            }
        }
        let rho = sum / norm;
        if rho <= 0.0 {
            break;
        }
        tau += 2.0 * rho;
    }
    tau.min(100.0)
}

/// A camera joining or leaving a robot's fused set.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Handoff {
    /// Arena time, seconds.
    pub t_s: f64,
    /// The camera.
    pub camera: usize,
    /// True when it joins, false when it leaves.
    pub joins: bool,
    /// How far the fused position moves because of it: the fused position with the camera
    /// against without it, at the instant it is in the set, metres.
    pub jump_m: f64,
    /// How far that camera's own position is from the others' fused one then, metres.
    pub disagreement_m: f64,
}

/// Simultaneous fixes of different cameras this many σ apart (RMS per axis, each fix against
/// the others' fused pose, their σ combined) disagree: a camera's clock that jumped or a
/// camera moved since the arena was built. The synthetic arena's largest is 2.0 σ; a camera
/// turned 0.4° gives 10-38 σ.
pub const DISAGREE_SIGMAS: f64 = 8.0;

/// A camera whose fixes of a robot disagree with the other cameras' far beyond their σ over
/// a stretch of time ([`DISAGREE_SIGMAS`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Disagreement {
    /// The camera.
    pub camera: usize,
    /// The stretch, arena clock, seconds (first and last fused instant).
    pub from_s: f64,
    /// End of the stretch, seconds.
    pub to_s: f64,
    /// Fused instants in the stretch at which it disagreed.
    pub instants: usize,
    /// Largest distance from the other cameras' fused position, metres.
    pub max_m: f64,
    /// Largest distance in σ (RMS per axis).
    pub max_sigmas: f64,
    /// True when the camera was left out of the fusion there (it disagrees with the others
    /// much more often than they do among themselves); false when which camera is wrong could
    /// not be told, so all were kept and the rows' σ widened to cover their spread.
    pub left_out: bool,
}

/// How far apart the cameras that saw a robot at once put it: every camera's fix against the
/// others' fused pose, over every fused instant with two cameras or more (before any camera
/// is left out).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Agreement {
    /// Comparisons (a camera at an instant).
    pub fixes: usize,
    /// RMS distance, metres.
    pub rms_m: f64,
    /// Largest distance, metres.
    pub max_m: f64,
    /// RMS of the distance in σ (RMS per axis); NaN without σ.
    pub sigmas_rms: f64,
    /// Largest distance in σ.
    pub max_sigmas: f64,
}

/// One robot's fused trajectory.
#[derive(Debug, Clone, PartialEq)]
pub struct FusedTrack {
    /// The robot's tag id.
    pub tag_id: u32,
    /// The fused trajectory (arena clock, arena floor frame).
    pub trajectory: Trajectory,
    /// For each row, the cameras that contributed and their share of the weight.
    pub contributions: Vec<Vec<(usize, f64)>>,
    /// Every change of the set of contributing cameras.
    pub handoffs: Vec<Handoff>,
    /// The agreement of the cameras' simultaneous fixes.
    pub agreement: Agreement,
    /// Stretches in which a camera disagreed with the others far beyond σ.
    pub disagreements: Vec<Disagreement>,
    /// The rows left out for a speed no robot has, if any.
    pub too_fast: Option<TooFast>,
}

/// Fused rows left out because reaching them from the rest of the trajectory takes more
/// than [`FuseOptions::max_speed_mps`]: where one camera alone saw a robot, its fixes are
/// kept however far they lie from the others' (another tag of the id in its view, or its
/// fixes off), and a small σ would vouch for the teleport.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TooFast {
    /// Rows left out.
    pub rows: usize,
    /// The first and last of them, arena clock, seconds.
    pub from_s: f64,
    pub to_s: f64,
    /// The largest step between two consecutive fused rows beyond the speed: its length,
    /// metres, and its time, seconds.
    pub step_m: f64,
    pub step_s: f64,
}

/// Slack on the distance a robot may cover at [`FuseOptions::max_speed_mps`], metres: the
/// tracker's own jump test allows as much for the fixes' noise.
const SPEED_SLACK_M: f64 = 0.02;

/// Which of `rows` to keep: the most rows that a robot at `max_speed_mps` could have passed
/// through one after the other. The rows are cut into runs at every step too fast, and the
/// runs chained by the longest-path rule (each run joined to the best earlier one it can be
/// reached from), so a stray run is dropped whether it comes first, last or between.
fn plausible_rows(rows: &[TrajectoryRow], max_speed_mps: f64) -> Vec<bool> {
    let reach = |a: &TrajectoryRow, b: &TrajectoryRow| {
        (b.pose.position() - a.pose.position()).norm()
            <= max_speed_mps * (b.t_s - a.t_s).abs() + SPEED_SLACK_M
    };
    let mut runs: Vec<(usize, usize)> = Vec::new();
    for i in 0..rows.len() {
        match runs.last_mut() {
            Some(run) if reach(&rows[i - 1], &rows[i]) => run.1 = i,
            _ => runs.push((i, i)),
        }
    }
    // best[j]: the most rows of a chain ending with run j, and the run before it.
    let mut best: Vec<(usize, Option<usize>)> = Vec::with_capacity(runs.len());
    for (j, &(first, last)) in runs.iter().enumerate() {
        let before = (0..j)
            .filter(|&i| reach(&rows[runs[i].1], &rows[first]))
            .max_by_key(|&i| (best[i].0, std::cmp::Reverse(i)));
        let rows_before = before.map_or(0, |i| best[i].0);
        best.push((rows_before + last - first + 1, before));
    }
    let mut keep = vec![false; rows.len()];
    let mut at = (0..runs.len()).max_by_key(|&j| (best[j].0, std::cmp::Reverse(j)));
    while let Some(j) = at {
        keep[runs[j].0..=runs[j].1]
            .iter_mut()
            .for_each(|k| *k = true);
        at = best[j].1;
    }
    keep
}

/// One camera's part in a fused row: its index and its fix at that instant.
type Part = (usize, CameraFix);

/// The weighted mean of the parts' poses (all but camera `skip`), their weighted quality, and
/// the mean's σ when every part has one. Each fix's corner noise is its own, so it averages
/// down: √(Σ w² σ²) / Σ w; its calibration part (`CameraFix::shared_m`) is taken as common to
/// all the cameras (a calibration's error reaches its neighbours through the shared boards),
/// so it is the weighted mean Σ w s / Σ w and never shrinks with more cameras.
fn weighted_pose(parts: &[Part], skip: Option<usize>) -> Option<(Pose2, f64, Option<PoseSigma>)> {
    let (mut sw, mut x, mut y, mut s, mut c, mut q) = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0);
    let mut shared = Vector2::zeros();
    let mut var = Some([0.0; 3]);
    for (k, f) in parts {
        if Some(*k) == skip {
            continue;
        }
        let (p, w) = (&f.pose, f.weight);
        sw += w;
        x += w * p.x_m;
        y += w * p.y_m;
        s += w * p.theta_rad.sin();
        c += w * p.theta_rad.cos();
        q += w * f.quality;
        shared += w * f.shared_m;
        let own = |sigma: f64, part: f64| (sigma * sigma - part * part).max(0.0);
        var = var.zip(f.sigma).map(|(v, e)| {
            [
                v[0] + w * w * own(e.x_m, f.shared_m.x),
                v[1] + w * w * own(e.y_m, f.shared_m.y),
                v[2] + (w * e.theta_rad).powi(2),
            ]
        });
    }
    (sw > 0.0).then(|| {
        let common = (shared / sw).map(|v| v * v);
        (
            Pose2::new(x / sw, y / sw, wrap_angle(s.atan2(c))),
            q / sw,
            var.map(|v| PoseSigma {
                x_m: (v[0] / (sw * sw) + common.x).sqrt(),
                y_m: (v[1] / (sw * sw) + common.y).sqrt(),
                theta_rad: v[2].sqrt() / sw,
            }),
        )
    })
}

/// How far camera `camera`'s fix in `parts` is from the others' fused pose: metres, and in σ
/// (RMS per axis, the fix's σ and the others' mean's combined; NaN without σ).
fn apart(parts: &[Part], camera: usize) -> Option<(f64, f64)> {
    let (_, fix) = parts.iter().find(|(c, _)| *c == camera)?;
    let (others, _, others_sigma) = weighted_pose(parts, Some(camera))?;
    let d = fix.pose.position() - others.position();
    let z = match (fix.sigma, others_sigma) {
        (Some(a), Some(b)) => {
            let (vx, vy) = (a.x_m.powi(2) + b.x_m.powi(2), a.y_m.powi(2) + b.y_m.powi(2));
            (0.5 * (d.x * d.x / vx + d.y * d.y / vy)).sqrt()
        }
        _ => f64::NAN,
    };
    Some((d.norm(), z))
}

/// Every camera's distance from the others at one instant ([`apart`]), with two or more.
fn judge(parts: &[Part]) -> Vec<(usize, f64, f64)> {
    if parts.len() < 2 {
        return Vec::new();
    }
    parts
        .iter()
        .filter_map(|(c, _)| apart(parts, *c).map(|(d, z)| (*c, d, z)))
        .collect()
}

/// The cameras' parts of one robot on the fused grid: each instant and every camera's fix
/// then.
fn grid(
    tag_id: u32,
    tracks: &[CameraTrack],
    offsets: &ClockOffsets,
    opts: &FuseOptions,
    on: &FuseGrid,
) -> Vec<(f64, Vec<Part>)> {
    let mine: Vec<&CameraTrack> = tracks
        .iter()
        .filter(|t| t.tag_id == tag_id && !t.fixes.is_empty())
        .filter(|t| offsets.sigma_s.get(t.camera).is_some_and(|s| !s.is_nan()))
        .collect();
    let span = mine
        .iter()
        .filter(|t| t.camera < offsets.offset_s.len())
        .map(|t| {
            let arena = |t_s: f64| offsets.to_arena(t.camera, t_s);
            (arena(t.fixes[0].t_s), arena(t.fixes[t.fixes.len() - 1].t_s))
        })
        .fold((f64::INFINITY, f64::NEG_INFINITY), |a, b| {
            (a.0.min(b.0), a.1.max(b.1))
        });
    if !span.0.is_finite() {
        return Vec::new();
    }
    // Counted from the grid's origin, so that instants far from 0 (epoch timestamps) keep
    // their place to the nanosecond.
    let origin = on.origin_s;
    let k0 = ((span.0 - origin) / on.period_s).ceil() as i64;
    let k1 = ((span.1 - origin) / on.period_s).floor() as i64;
    (k0..=k1)
        .map(|k| {
            let t = origin + k as f64 * on.period_s;
            let parts = mine
                .iter()
                .filter_map(|tr| {
                    let fix = tr.at(offsets.to_camera(tr.camera, t), opts.max_gap_frames)?;
                    Some((tr.camera, fix))
                })
                .collect();
            (t, parts)
        })
        .collect()
}

/// The camera whose leaving out makes the others agree, when exactly one does (three
/// cameras or more).
fn odd_one_out(parts: &[Part]) -> Option<usize> {
    if parts.len() < 3 {
        return None;
    }
    let mut agree = parts.iter().map(|(c, _)| *c).filter(|c| {
        let rest: Vec<Part> = parts.iter().filter(|(d, _)| d != c).copied().collect();
        judge(&rest).iter().all(|(_, _, z)| *z <= DISAGREE_SIGMAS)
    });
    let one = agree.next()?;
    agree.next().is_none().then_some(one)
}

/// How often each camera is to blame, over every robot: the share of its instants with other
/// cameras at which it disagreed with them. Where three or more saw a robot the one whose
/// leaving out makes the others agree takes the whole blame; where the wrong one cannot be
/// told, each that disagreed takes a share. A camera at fault is blamed wherever it shares a
/// robot, its neighbours only where they share it with that camera.
fn blame(
    tracks: &[CameraTrack],
    offsets: &ClockOffsets,
    opts: &FuseOptions,
    on: &FuseGrid,
) -> BTreeMap<usize, f64> {
    let mut ids: Vec<u32> = tracks.iter().map(|t| t.tag_id).collect();
    ids.sort_unstable();
    ids.dedup();
    // (instants with other cameras, blame)
    let mut count: BTreeMap<usize, (f64, f64)> = BTreeMap::new();
    for id in ids {
        for (_, parts) in grid(id, tracks, offsets, opts, on) {
            let judged = judge(&parts);
            let bad: Vec<usize> = judged
                .iter()
                .filter(|(_, _, z)| *z > DISAGREE_SIGMAS)
                .map(|(c, ..)| *c)
                .collect();
            let odd = odd_one_out(&parts);
            for (c, ..) in &judged {
                let e = count.entry(*c).or_default();
                e.0 += 1.0;
                e.1 += match odd {
                    Some(o) => f64::from(u8::from(o == *c)),
                    None if bad.contains(c) => 1.0 / bad.len() as f64,
                    None => 0.0,
                };
            }
        }
    }
    count
        .into_iter()
        .map(|(c, (n, b))| (c, b / n.max(1.0)))
        .collect()
}

/// The parts kept at one instant: while some disagree beyond [`DISAGREE_SIGMAS`], the camera
/// whose leaving out makes the others agree is left out, or else the disagreeing camera most
/// to blame overall ([`blame`]) if clearly more than the others (1.5 times); else all are
/// kept, and the spread the σ are widened to is returned. Also each disagreeing camera:
/// (camera, metres, σ, left out).
type Judged = (Vec<Part>, Option<(f64, f64)>, Vec<(usize, f64, f64, bool)>);

fn keep(parts: &[Part], blamed: &BTreeMap<usize, f64>) -> Judged {
    let mut kept = parts.to_vec();
    let mut flagged: Vec<(usize, f64, f64, bool)> = Vec::new();
    loop {
        let bad: Vec<(usize, f64, f64)> = judge(&kept)
            .into_iter()
            .filter(|(_, _, z)| *z > DISAGREE_SIGMAS)
            .collect();
        if bad.is_empty() {
            return (kept, None, flagged);
        }
        let of = |c: usize| blamed.get(&c).copied().unwrap_or(0.0);
        let worst = odd_one_out(&kept).or_else(|| {
            let (w, ..) = *bad.iter().max_by(|a, b| of(a.0).total_cmp(&of(b.0)))?;
            bad.iter()
                .all(|o| o.0 == w || of(w) > 1.5 * of(o.0))
                .then_some(w)
        });
        let Some(worst) = worst else {
            for &(c, d, z) in &bad {
                flagged.push((c, d, z, false));
            }
            let (mean, ..) = weighted_pose(&kept, None).unwrap_or((Pose2::default(), 0.0, None));
            let spread = kept.iter().fold((0.0_f64, 0.0_f64), |s, (_, f)| {
                (
                    s.0.max((f.pose.x_m - mean.x_m).abs()),
                    s.1.max((f.pose.y_m - mean.y_m).abs()),
                )
            });
            return (kept, Some(spread), flagged);
        };
        let (d, z) = apart(&kept, worst).unwrap_or((0.0, f64::NAN));
        flagged.push((worst, d, z, true));
        kept.retain(|(c, _)| *c != worst);
    }
}

/// Joins the instants at which a camera disagreed into stretches (instants at most three
/// of the fused grid's periods apart).
fn stretches(flags: &[(f64, usize, f64, f64, bool)], period_s: f64) -> Vec<Disagreement> {
    let mut out: Vec<Disagreement> = Vec::new();
    for &(t, camera, d, z, left_out) in flags {
        match out
            .iter_mut()
            .rev()
            .find(|s| s.camera == camera && s.left_out == left_out)
            .filter(|s| t - s.to_s <= 3.5 * period_s)
        {
            Some(s) => {
                s.to_s = t;
                s.instants += 1;
                s.max_m = s.max_m.max(d);
                s.max_sigmas = s.max_sigmas.max(z);
            }
            None => out.push(Disagreement {
                camera,
                from_s: t,
                to_s: t,
                instants: 1,
                max_m: d,
                max_sigmas: z,
                left_out,
            }),
        }
    }
    out
}

/// The agreement of the cameras' simultaneous fixes over every instant.
fn agreement(grid: &[(f64, Vec<Part>)]) -> Agreement {
    let all: Vec<(f64, f64)> = grid
        .iter()
        .flat_map(|(_, parts)| judge(parts).into_iter().map(|(_, d, z)| (d, z)))
        .collect();
    agreement_of(&all)
}

/// How camera `camera`'s fixes of every robot compare with the other cameras' fused pose at
/// the same instants, before any camera is left out: the figures, and how many of its
/// comparisons lie beyond [`DISAGREE_SIGMAS`] (beyond `opts.max_pair_rms_m` where the fixes
/// carry no σ).
pub(crate) fn camera_agreement(
    camera: usize,
    tracks: &[CameraTrack],
    offsets: &ClockOffsets,
    opts: &FuseOptions,
    on: &FuseGrid,
) -> (Agreement, usize) {
    let mut ids: Vec<u32> = tracks
        .iter()
        .filter(|t| t.camera == camera)
        .map(|t| t.tag_id)
        .collect();
    ids.sort_unstable();
    ids.dedup();
    let all: Vec<(f64, f64)> = ids
        .into_iter()
        .flat_map(|id| grid(id, tracks, offsets, opts, on))
        .filter(|(_, parts)| parts.len() >= 2)
        .filter_map(|(_, parts)| apart(&parts, camera))
        .collect();
    let beyond = all
        .iter()
        .filter(|(d, z)| {
            if z.is_nan() {
                *d > opts.max_pair_rms_m
            } else {
                *z > DISAGREE_SIGMAS
            }
        })
        .count();
    (agreement_of(&all), beyond)
}

/// [`Agreement`] of comparisons (metres, σ).
fn agreement_of(all: &[(f64, f64)]) -> Agreement {
    let n = all.len().max(1) as f64;
    Agreement {
        fixes: all.len(),
        rms_m: (all.iter().map(|(d, _)| d * d).sum::<f64>() / n).sqrt(),
        max_m: all.iter().map(|(d, _)| *d).fold(0.0, f64::max),
        sigmas_rms: (all.iter().map(|(_, z)| z * z).sum::<f64>() / n).sqrt(),
        max_sigmas: all.iter().map(|(_, z)| *z).fold(0.0, f64::max),
    }
}

/// Fuses one robot's tracks from every camera (times shifted by the offsets) into one
/// trajectory on the grid `on` ([`FuseGrid`]).
///
/// Simultaneous fixes of different cameras are judged against their σ: a camera that
/// disagrees with the others beyond [`DISAGREE_SIGMAS`] is left out where it does, if it
/// disagrees wherever it shares a robot more often than the others do; where which camera is
/// wrong cannot be told, the row's σ is widened to cover the cameras' spread. Either is
/// reported in [`FusedTrack::disagreements`].
pub fn fuse_robot(
    tag_id: u32,
    tracks: &[CameraTrack],
    offsets: &ClockOffsets,
    opts: &FuseOptions,
    on: &FuseGrid,
) -> Result<FusedTrack, ArenaError> {
    let grid = grid(tag_id, tracks, offsets, opts, on);
    if grid.is_empty() {
        return Err(ArenaError::Refused(format!(
            "tag {tag_id} was never seen by any camera"
        )));
    }
    let blamed = blame(tracks, offsets, opts, on);
    let mut rows = Vec::new();
    let mut contributions = Vec::new();
    let mut handoffs = Vec::new();
    let mut flags = Vec::new();
    let mut prev: Option<Vec<Part>> = None;
    for (t, all) in &grid {
        let t = *t;
        let (parts, widen, flagged) = keep(all, &blamed);
        flags.extend(flagged.into_iter().map(|(c, d, z, out)| (t, c, d, z, out)));
        let Some((pose, quality, mut sigma)) = weighted_pose(&parts, None) else {
            prev = None;
            continue;
        };
        if let (Some(s), Some((dx, dy))) = (sigma.as_mut(), widen) {
            s.x_m = s.x_m.max(dx);
            s.y_m = s.y_m.max(dy);
        }
        if let Some(before) = &prev {
            let changed = |now: &[Part], then: &[Part], joins: bool, at: f64| {
                now.iter()
                    .filter(|(c, ..)| !then.iter().any(|(d, ..)| d == c))
                    .filter_map(|(c, fix)| {
                        let (with, ..) = weighted_pose(now, None)?;
                        let (without, ..) = weighted_pose(now, Some(*c))?;
                        Some(Handoff {
                            t_s: at,
                            camera: *c,
                            joins,
                            jump_m: (with.position() - without.position()).norm(),
                            disagreement_m: (fix.pose.position() - without.position()).norm(),
                        })
                    })
                    .collect::<Vec<_>>()
            };
            handoffs.extend(changed(&parts, before, true, t));
            handoffs.extend(changed(before, &parts, false, t - on.period_s));
        }
        let sw: f64 = parts.iter().map(|(_, f)| f.weight).sum();
        contributions.push(parts.iter().map(|(c, f)| (*c, f.weight / sw)).collect());
        rows.push(TrajectoryRow {
            t_s: t,
            pose,
            quality: quality.clamp(0.0, 1.0),
            // The blend of the cameras' σ; the clock offsets' own σ (reported with them) is
            // not in it.
            sigma,
        });
        prev = Some(parts);
    }
    let keep = plausible_rows(&rows, opts.max_speed_mps);
    let too_fast = keep.iter().any(|k| !k).then(|| {
        let gone: Vec<f64> = rows
            .iter()
            .zip(&keep)
            .filter(|(_, k)| !**k)
            .map(|(r, _)| r.t_s)
            .collect();
        let (step_m, step_s) = rows
            .windows(2)
            .map(|w| {
                let d = (w[1].pose.position() - w[0].pose.position()).norm();
                (d, w[1].t_s - w[0].t_s)
            })
            .filter(|(d, dt)| *d > opts.max_speed_mps * dt + SPEED_SLACK_M)
            .fold((0.0, 0.0), |a, b| if b.0 > a.0 { b } else { a });
        TooFast {
            rows: gone.len(),
            from_s: gone[0],
            to_s: gone[gone.len() - 1],
            step_m,
            step_s,
        }
    });
    let mut kept = keep.iter();
    rows.retain(|_| kept.next().copied().unwrap_or(true));
    let mut kept = keep.iter();
    contributions.retain(|_| kept.next().copied().unwrap_or(true));
    // A file has σ on every row or on none.
    if rows.iter().any(|r| r.sigma.is_none()) {
        rows.iter_mut().for_each(|r| r.sigma = None);
    }
    let trajectory = Trajectory::new(rows)?;
    Ok(FusedTrack {
        tag_id,
        trajectory,
        contributions,
        handoffs,
        agreement: agreement(&grid),
        disagreements: stretches(&flags, on.period_s),
        too_fast,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    /// Rows at 30 frames/s from 0 s.
    const AT_30: FuseGrid = FuseGrid {
        origin_s: 0.0,
        period_s: 1.0 / 30.0,
    };

    /// A robot on a circle of 1 m at 1 rad/s, seen by three cameras whose views cover
    /// overlapping arcs of x, each on its own clock, with 0.3 mm of noise per axis, at 30
    /// frames/s for 10 s.
    fn tracks(offsets: &[f64], seed: u64) -> Vec<CameraTrack> {
        tracks_at(offsets, &[30.0; 3], seed)
    }

    /// [`tracks`] with each camera at its own frame rate.
    fn tracks_at(offsets: &[f64], fps: &[f64], seed: u64) -> Vec<CameraTrack> {
        let truth = |t: f64| Pose2::new(t.cos(), t.sin(), t + std::f64::consts::FRAC_PI_2);
        let views = [(-1.5, -0.2), (-0.5, 0.5), (0.2, 1.5)];
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        views
            .iter()
            .zip(offsets)
            .zip(fps)
            .enumerate()
            .map(|(k, ((&(x0, x1), &o), &fps))| {
                let fixes = (0..(10.0 * fps).round() as usize)
                    .filter_map(|j| {
                        let t = j as f64 / fps;
                        let mut p = truth(t + o);
                        if !(x0..=x1).contains(&p.x_m) {
                            return None;
                        }
                        // The weight fades towards the view's ends, as near an image border.
                        let edge = (p.x_m - x0).min(x1 - p.x_m);
                        p.x_m += rng.gen_range(-5e-4..5e-4);
                        p.y_m += rng.gen_range(-5e-4..5e-4);
                        Some(CameraFix {
                            t_s: t,
                            pose: p,
                            weight: (edge / 0.2).clamp(MIN_TAPER, 1.0),
                            quality: 0.9,
                            sigma: None,
                            shared_m: Vector2::zeros(),
                        })
                    })
                    .collect();
                CameraTrack {
                    camera: k,
                    tag_id: 7,
                    fixes,
                    period_s: 1.0 / fps,
                }
            })
            .collect()
    }

    #[test]
    fn offsets_and_fusion_recover_the_truth() {
        let offsets = [0.0, 0.0137, -0.0461];
        let tr = tracks(&offsets, 3);
        let opts = FuseOptions::default();
        let found = estimate_clock_offsets(&tr, 3, &opts, &[]).unwrap();
        for (k, want) in offsets.iter().enumerate() {
            let err = (found.offset_s[k] - want).abs();
            assert!(err < 3e-4, "camera {k}: {err} s, {found:?}");
            assert!(found.sigma_s[k] < 3e-4, "{:?}", found.sigma_s);
        }
        let fused = fuse_robot(7, &tr, &found, &opts, &AT_30).unwrap();
        let mut sq = 0.0;
        for r in &fused.trajectory.rows {
            let t = r.t_s;
            sq += (r.pose.position() - Point2::new(t.cos(), t.sin())).norm_squared();
        }
        let rms = (sq / fused.trajectory.rows.len() as f64).sqrt();
        // Linear interpolation between frames 33 ms apart on a 1 m circle costs ≈0.1 mm.
        assert!(rms < 6e-4, "fused RMS {rms}");
        assert!(fused.handoffs.len() >= 4, "{:?}", fused.handoffs);
        for h in &fused.handoffs {
            assert!(h.jump_m < 2e-4, "{h:?}");
        }
        // The same fixes with the offsets ignored give a worse fusion: the offsets matter.
        let zero = ClockOffsets {
            offset_s: vec![0.0; 3],
            ..found.clone()
        };
        let naive = fuse_robot(7, &tr, &zero, &opts, &AT_30).unwrap();
        let worst = naive
            .handoffs
            .iter()
            .map(|h| h.disagreement_m)
            .fold(0.0, f64::max);
        assert!(worst > 0.02, "{worst}");
    }

    /// A second tag of the robot's id parked at (5, 5) m in camera 0's view, followed by
    /// camera 0 for five frames while no other camera saw the robot: those rows are left out
    /// and counted, and no step of the fused trajectory is faster than the robot can drive
    /// (before: the rows were kept, an 8 m step in 33 ms).
    #[test]
    fn rows_no_robot_could_reach_are_left_out() {
        let mut tr = tracks(&[0.0; 3], 5);
        let parked = 120..125;
        let in_window = |t: f64| parked.contains(&((t * 30.0).round() as usize));
        for track in &mut tr {
            track
                .fixes
                .retain(|f| !in_window(f.t_s) || track.camera == 0);
        }
        for f in tr[0].fixes.iter_mut().filter(|f| in_window(f.t_s)) {
            f.pose = Pose2::new(5.0, 5.0, 0.0);
        }
        assert_eq!(tr[0].fixes.iter().filter(|f| in_window(f.t_s)).count(), 5);
        let opts = FuseOptions::default();
        let found = estimate_clock_offsets(&tr, 3, &opts, &[]).unwrap();
        let fused = fuse_robot(7, &tr, &found, &opts, &AT_30).unwrap();
        let rows = &fused.trajectory.rows;
        assert_eq!(rows.len(), fused.contributions.len());
        assert!(rows.iter().all(|r| !in_window(r.t_s)));
        for w in rows.windows(2) {
            let d = (w[1].pose.position() - w[0].pose.position()).norm();
            assert!(d <= 2.0 * (w[1].t_s - w[0].t_s) + SPEED_SLACK_M, "{w:?}");
        }
        let too_fast = fused.too_fast.expect("the parked tag's rows are counted");
        assert_eq!(too_fast.rows, 5, "{too_fast:?}");
        assert!(
            (too_fast.from_s - 4.0).abs() < 1e-9 && (too_fast.to_s - 124.0 / 30.0).abs() < 1e-9,
            "{too_fast:?}"
        );
        assert!(
            too_fast.step_m > 6.0 && too_fast.step_s < 0.04,
            "{too_fast:?}"
        );
        // Without the parked tag nothing is left out.
        let clean = tracks(&[0.0; 3], 5);
        let fused = fuse_robot(7, &clean, &found, &opts, &AT_30).unwrap();
        assert_eq!(fused.too_fast, None);
    }

    /// Cameras at 30, 10 and 60 frames/s (a USB camera dropped to 10 among 30, a 60 among
    /// them): each bridges gaps and counts lags in its own frames, so the offsets come out as
    /// at one rate and the rows, at 60 a second, as close to the truth as the 10 frames/s
    /// camera's linear interpolation allows (before: its frames 100 ms apart were gaps of more
    /// than 2.5 frames of 30 a second, and its offset was refused).
    #[test]
    fn cameras_at_their_own_frame_rates_fuse_as_at_one() {
        let offsets = [0.0, 0.0137, -0.0461];
        let opts = FuseOptions::default();
        let rms = |fps: &[f64; 3], on: &FuseGrid| {
            let tr = tracks_at(&offsets, fps, 3);
            let found = estimate_clock_offsets(&tr, 3, &opts, &[]).unwrap();
            // Each offset within 3 σ of the truth, σ under 0.3 ms (camera 1's 10 frames/s give
            // fewer matches, so a larger σ than at one rate).
            for (k, want) in offsets.iter().enumerate() {
                let (err, sigma) = ((found.offset_s[k] - want).abs(), found.sigma_s[k]);
                assert!(
                    err <= 3.0 * sigma && sigma < 3e-4,
                    "{fps:?}: camera {k}: {found:?}"
                );
            }
            eprintln!(
                "{fps:?}: offsets σ {:?} ms",
                found.sigma_s.iter().map(|s| s * 1e3).collect::<Vec<_>>()
            );
            let fused = fuse_robot(7, &tr, &found, &opts, on).unwrap();
            let rows = &fused.trajectory.rows;
            assert!(rows
                .windows(2)
                .all(|w| (w[1].t_s - w[0].t_s - on.period_s).abs() < 1e-9));
            assert!(fused.disagreements.is_empty(), "{:?}", fused.disagreements);
            let sq: f64 = rows
                .iter()
                .map(|r| (r.pose.position() - Point2::new(r.t_s.cos(), r.t_s.sin())).norm_squared())
                .sum();
            (sq / rows.len() as f64).sqrt()
        };
        let one = rms(&[30.0; 3], &AT_30);
        let at_60 = FuseGrid {
            origin_s: 0.0,
            period_s: 1.0 / 60.0,
        };
        let mixed = rms(&[30.0, 10.0, 60.0], &at_60);
        eprintln!(
            "fused RMS {:.3} mm at 30 frames/s, {:.3} mm at 30, 10 and 60",
            one * 1e3,
            mixed * 1e3
        );
        assert!(mixed < one + 3e-4, "{mixed} against {one}");
    }

    /// Two cameras see the robot at once, each with a calibration error tied to the other's
    /// through the shared boards (one draw per instant, the same for both) and corner noise of
    /// its own: the fused σ keeps the calibration's part whole (as independent errors it was
    /// 1/√2 of it, error/σ 1.4).
    #[test]
    fn a_calibration_error_both_cameras_share_is_not_averaged_down() {
        let (shared_m, corner_m): (f64, f64) = (4e-4, 5e-5);
        let total = (shared_m * shared_m + corner_m * corner_m).sqrt();
        let sigma = PoseSigma {
            x_m: total,
            y_m: total,
            theta_rad: 1e-3,
        };
        let mut rng = ChaCha8Rng::seed_from_u64(9);
        let mut normal = || {
            // Irwin-Hall: the sum of twelve uniforms less six has unit variance.
            (0..12).map(|_| rng.gen::<f64>()).sum::<f64>() - 6.0
        };
        let mut z2 = 0.0;
        let trials = 400;
        for _ in 0..trials {
            let common = shared_m * normal();
            let parts: Vec<Part> = (0..2)
                .map(|k| {
                    let fix = CameraFix {
                        t_s: 0.0,
                        pose: Pose2::new(common + corner_m * normal(), 0.0, 0.0),
                        weight: 1.0 / (total * total),
                        quality: 1.0,
                        sigma: Some(sigma),
                        shared_m: Vector2::repeat(shared_m),
                    };
                    (k, fix)
                })
                .collect();
            let (pose, _, s) = weighted_pose(&parts, None).unwrap();
            let s = s.unwrap();
            assert!(s.x_m >= shared_m, "{s:?}");
            z2 += (pose.x_m / s.x_m).powi(2);
        }
        let z_rms = (z2 / trials as f64).sqrt();
        assert!((0.85..=1.15).contains(&z_rms), "error/σ RMS {z_rms:.2}");
    }

    /// A turn of the floor frame moves a fix 3 m out along y, not x: the row's σ keeps the
    /// calibration's part on the axis it is on (as one figure for both axes it was 0.71 mm on
    /// each, the y error 1.4 σ).
    #[test]
    fn the_calibrations_part_of_sigma_stays_on_its_axis() {
        let (shared, corner_m): (Vector2<f64>, f64) = (Vector2::new(1e-4, 1e-3), 5e-5);
        let sigma = PoseSigma {
            x_m: shared.x.hypot(corner_m),
            y_m: shared.y.hypot(corner_m),
            theta_rad: 1e-3,
        };
        let parts: Vec<Part> = (0..2)
            .map(|k| {
                let fix = CameraFix {
                    t_s: 0.0,
                    pose: Pose2::new(3.0, 0.0, 0.0),
                    weight: 1.0,
                    quality: 1.0,
                    sigma: Some(sigma),
                    shared_m: shared,
                };
                (k, fix)
            })
            .collect();
        let s = weighted_pose(&parts, None).unwrap().2.unwrap();
        assert!((s.y_m - 1e-3).abs() < 2e-6, "{s:?}");
        assert!((s.x_m - 1e-4).abs() < 1e-5, "{s:?}");
    }

    /// The same tracks with every fix's σ (the noise is uniform over ±0.5 mm: σ 0.29 mm).
    fn tracks_with_sigma(offsets: &[f64], seed: u64) -> Vec<CameraTrack> {
        let mut tr = tracks(offsets, seed);
        for f in tr.iter_mut().flat_map(|t| t.fixes.iter_mut()) {
            f.sigma = Some(PoseSigma {
                x_m: 3e-4,
                y_m: 3e-4,
                theta_rad: 1e-3,
            });
        }
        tr
    }

    /// Camera 2's clock jumps 8 frames late after 5 s (frames dropped, the video re-encoded at
    /// a constant rate): its fixes there disagree with camera 1's by centimetres, while
    /// cameras 0 and 1 agree. Camera 2 is named and left out there, and the agreement figure
    /// shows the disagreement (before: fused 1.1 cm RMS off in the overlap, named nowhere).
    #[test]
    fn a_camera_whose_clock_jumped_is_named_and_left_out() {
        let offsets = [0.0, 0.0137, -0.0461];
        let mut tr = tracks_with_sigma(&offsets, 3);
        let opts = FuseOptions::default();
        let found = estimate_clock_offsets(&tr, 3, &opts, &[]).unwrap();
        let clean = fuse_robot(7, &tr, &found, &opts, &AT_30).unwrap();
        assert!(clean.disagreements.is_empty(), "{:?}", clean.disagreements);
        assert!(clean.agreement.sigmas_rms < 3.0, "{:?}", clean.agreement);
        for f in tr[2].fixes.iter_mut().filter(|f| f.t_s > 5.0) {
            f.t_s += 8.0 / 30.0;
        }
        let fused = fuse_robot(7, &tr, &found, &opts, &AT_30).unwrap();
        eprintln!("{:?}\n{:?}", fused.agreement, fused.disagreements);
        assert!(fused.agreement.max_m > 0.1, "{:?}", fused.agreement);
        let d = &fused.disagreements;
        assert!(
            !d.is_empty()
                && d.iter()
                    .all(|d| d.camera == 2 && d.left_out && d.from_s > 5.0),
            "{d:?}"
        );
        // Where cameras 1 and 2 both saw the robot after the jump, the fused pose is camera 1's.
        let truth = |t: f64| Point2::new(t.cos(), t.sin());
        let worst = fused
            .trajectory
            .rows
            .iter()
            .zip(&fused.contributions)
            .filter(|(r, c)| r.t_s > 5.0 && r.pose.x_m > 0.0 && c.iter().any(|(k, _)| *k == 1))
            .map(|(r, c)| {
                assert!(c.iter().all(|(k, _)| *k != 2), "{c:?}");
                (r.pose.position() - truth(r.t_s)).norm()
            })
            .fold(0.0, f64::max);
        assert!(worst < 2e-3, "{worst}");
    }

    /// Camera 0 saw no robot: the arena clock is camera 1's, and the fused rows fall on its
    /// frames, even with epoch timestamps (a grid through 0 put them 24.7 ms off its frames).
    #[test]
    fn the_first_camera_that_saw_a_robot_keeps_the_clock() {
        let mut tr = tracks_with_sigma(&[0.0, 0.0137, -0.0461], 5);
        tr.retain(|t| t.camera != 0);
        let epoch = 1_764_000_123.45;
        for f in tr.iter_mut().flat_map(|t| t.fixes.iter_mut()) {
            f.t_s += epoch;
        }
        let found = estimate_clock_offsets(&tr, 3, &FuseOptions::default(), &[]).unwrap();
        assert_eq!(found.reference, 1);
        assert!(found.sigma_s[0].is_nan(), "{found:?}");
        assert!(
            (found.offset_s[2] - (-0.0461 - 0.0137)).abs() < 3e-4,
            "{found:?}"
        );
        // The frame rate as measured from epoch timestamps, 1 in 10⁵ off (their ulp is 0.24 µs).
        let on = FuseGrid {
            origin_s: epoch,
            period_s: 1.0 / (30.0 * (1.0 + 7e-6)),
        };
        let fused = fuse_robot(7, &tr, &found, &FuseOptions::default(), &on).unwrap();
        for r in &fused.trajectory.rows {
            let frames = (r.t_s - epoch) * 30.0;
            assert!((frames - frames.round()).abs() < 0.01, "{}", r.t_s);
        }
    }

    #[test]
    fn a_camera_that_saw_no_robot_needs_no_offset() {
        let mut tr = tracks(&[0.0, 0.01, 0.02], 5);
        tr.truncate(2);
        let found = estimate_clock_offsets(&tr, 3, &FuseOptions::default(), &[]).unwrap();
        assert!((found.offset_s[1] - 0.01).abs() < 3e-4, "{found:?}");
        assert!(found.sigma_s[2].is_nan() && found.sigma_s[1].is_finite());
    }

    #[test]
    fn a_camera_that_never_shares_a_robot_is_refused() {
        let mut tr = tracks(&[0.0, 0.01, 0.02], 4);
        tr[2].tag_id = 8;
        let e = estimate_clock_offsets(&tr, 3, &FuseOptions::default(), &[])
            .unwrap_err()
            .to_string();
        assert!(e.contains("camera 2 never saw a robot"), "{e}");
    }

    /// Camera 1's clock runs 1000 ppm fast (a 29.97 frames/s camera stamped as 30, or the
    /// reverse): over 10 s it drifts 10 ms, 10 mm on the robot's path. Its rate is fitted and
    /// the fusion holds (before: one constant offset, camera 1 and its good neighbours named
    /// as disagreeing beyond 8 σ, "its clock jumped … or the camera moved").
    #[test]
    fn a_camera_clock_running_fast_gets_its_rate() {
        let offsets = [0.0, 0.0137, -0.0461];
        let mut tr = tracks_with_sigma(&offsets, 3);
        let opts = FuseOptions::default();
        let clean = estimate_clock_offsets(&tr, 3, &opts, &[]).unwrap();
        assert!(
            clean.rate.iter().all(|r| r.ppm() == 0.0),
            "{:?}",
            clean.rate
        );
        for f in tr[1].fixes.iter_mut() {
            f.t_s *= 1.001;
        }
        let found = estimate_clock_offsets(&tr, 3, &opts, &[]).unwrap();
        let ClockRate::Fitted { ppm, sigma_ppm } = found.rate[1] else {
            panic!("{:?}", found.rate);
        };
        assert!(
            (ppm - 1000.0).abs() < 30.0 && sigma_ppm < 30.0,
            "{ppm} ± {sigma_ppm}"
        );
        assert_eq!(found.rate[2].ppm(), 0.0, "{:?}", found.rate);
        // Camera 1's true offset at its first fix (stamped t·1.001, true time t).
        let t0 = found.origin_s[1];
        let want = t0 / 1.001 + offsets[1] - t0;
        assert!((found.offset_s[1] - want).abs() < 3e-4, "{found:?} {want}");
        let fused = fuse_robot(7, &tr, &found, &opts, &AT_30).unwrap();
        assert!(fused.disagreements.is_empty(), "{:?}", fused.disagreements);
        assert!(fused.agreement.sigmas_rms < 3.0, "{:?}", fused.agreement);
    }

    /// Camera 2 stamps its frames in epoch seconds, the others from their recordings' start:
    /// its recording lies years from camera 0's, so it is re-based to start with camera 0 and
    /// its offset found around that (before: "never saw a robot at the same time … widen the
    /// search", which no width up to its limit could satisfy).
    #[test]
    fn a_camera_on_another_clock_is_re_based() {
        let offsets = [0.0, 0.0137, -0.0461];
        let mut tr = tracks_with_sigma(&offsets, 3);
        let epoch = 1_764_180_000.25;
        for f in tr[2].fixes.iter_mut() {
            f.t_s += epoch;
        }
        let opts = FuseOptions::default();
        let e = estimate_clock_offsets(&tr, 3, &opts, &[]).unwrap_err();
        assert!(e.to_string().contains("camera 2 never saw"), "{e}");
        // Each camera's recording: 10 s from its clock's start.
        let spans = [(0.0, 10.0), (0.0, 10.0), (epoch, epoch + 10.0)];
        let prior = crate::track::priors_of_spans(&spans, opts.max_offset_s);
        assert_eq!(prior, vec![0.0, 0.0, -epoch]);
        let found = estimate_clock_offsets(&tr, 3, &opts, &prior).unwrap();
        let err = found.offset_s[2] - (offsets[2] - epoch);
        assert!(err.abs() < 3e-4, "{err} s: {found:?}");
        let fused = fuse_robot(7, &tr, &found, &opts, &AT_30).unwrap();
        assert!(fused.disagreements.is_empty(), "{:?}", fused.disagreements);
        // Cameras on one clock, started seconds apart, are not re-based.
        let near = [(0.0, 10.0), (0.0, 10.0), (10.5, 20.0)];
        assert_eq!(
            crate::track::priors_of_spans(&near, opts.max_offset_s),
            vec![0.0; 3]
        );
    }
}
