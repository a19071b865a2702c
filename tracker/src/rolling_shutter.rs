//! Whether the video was read by a rolling shutter that was not named. Most USB and IP
//! cameras read their rows one after another over tens of milliseconds; each fix is then
//! timed up to that readout late or early (at 0.7 m/s, 30 ms is 21 mm along the path), and
//! nothing in the positions shows it. The tag's corners do: read at their own rows' times,
//! a moving square is sheared along its motion. The readout that makes the tags square
//! again (each fix's corners moved back along its image motion, as `--rolling-shutter-s`
//! does) is the camera's, and when it clearly does, the run says so. Both directions are
//! tried: a sensor mounted upside down, its image turned after readout, reads the rows from
//! the bottom of the image up, a negative readout. A readout the user gave is checked the
//! same way: the fixes' corners were unsheared by it, and the readout that fits them best
//! is searched around it, so a datasheet's wrong figure (or its wrong direction) is named.

use nalgebra::Point2;
use odocal_calib::{CameraModel, FloorToCamera};
use odocal_core::Pose2;

use crate::pose::planar_pose;
use crate::track::unshear;
use crate::{TrackOptions, TrackResult};

/// Fixes the estimate is taken over, at most, evenly over the run.
const MAX_SAMPLES: usize = 300;

/// Moving fixes needed: fewer say little about a shear.
const MIN_MOVING_FIXES: usize = 10;

/// A tag slower than this, m/s, is not sheared enough to weigh.
const MIN_SPEED_MPS: f64 = 0.05;

/// Readouts tried, seconds apart.
const READOUT_STEP_S: f64 = 0.0005;

/// A readout shorter than this, seconds, is not reported: its timing error stays within a
/// few millimetres at walking speed.
pub const MIN_REPORTED_READOUT_S: f64 = 0.003;

/// The corners' misfit must fall at least this many times, RMS, when unsheared: the shear
/// then explains most of it, rather than blur, compression or a lens model's error.
const MIN_IMPROVEMENT: f64 = 1.2;

/// A given readout the tags contradict must fit the corners this many times worse, RMS,
/// than theirs: the curve is flat near its best, and a clean video's misfit rises 8 % for
/// a readout 3.5 ms off (1 mm RMS at 0.7 m/s, 20 times the fixes' σ).
const MIN_GIVEN_IMPROVEMENT: f64 = 1.05;

/// The rolling-shutter readout a tracking run's tags show.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ShutterEstimate {
    /// The readout that fits the corners best, seconds (first row to last; negative when read
    /// from the bottom of the image up).
    pub readout_s: f64,
    /// The readout the run was tracked with (`--rolling-shutter-s`, 0 for none), seconds.
    pub given_s: f64,
    /// RMS misfit of the corners with the given readout undone (as read without one), pixels.
    pub rms_as_read_px: f64,
    /// RMS misfit with that readout undone, pixels.
    pub rms_unsheared_px: f64,
    /// Moving fixes the estimate rests on.
    pub fixes: usize,
    /// The fastest of those fixes, m/s.
    pub fastest_mps: f64,
}

impl ShutterEstimate {
    /// Estimates the readout from the fixes of `result`, tracked with `opts` (whose readout,
    /// if any, the fixes' corners were unsheared by) through `camera` over `floor`; None with
    /// too few moving fixes.
    pub fn of(
        result: &TrackResult,
        camera: &CameraModel,
        floor: &FloorToCamera,
        opts: &TrackOptions,
    ) -> Option<Self> {
        let fixes: Vec<(f64, Pose2, [Point2<f64>; 4])> = result
            .fixes()
            .map(|(_, f)| (f.t_s, f.pose, f.corners_px))
            .collect();
        let mut moving = Vec::new();
        let mut intervals = Vec::new();
        // A fix's motion is read off the two before it in its own run: across a jump it is
        // the leap's, metres a frame.
        let runs = result.continuous_runs();
        for w in runs.into_iter().flat_map(|r| fixes[r].windows(3)) {
            let [(t0, p0, _), (t1, p1, _), (t2, _, corners)] = w else {
                continue;
            };
            let (dt, dt2) = (t1 - t0, t2 - t1);
            if !(dt > 1e-6 && dt < 0.5 && dt2 > 1e-6 && dt2 < 0.5) {
                continue;
            }
            intervals.push(dt2);
            let speed = (p1.position() - p0.position()).norm() / dt;
            if speed >= MIN_SPEED_MPS {
                moving.push(([(*t0, *p0), (*t1, *p1)], *corners, speed));
            }
        }
        if moving.len() < MIN_MOVING_FIXES {
            return None;
        }
        let step = moving.len().div_ceil(MAX_SAMPLES).max(1);
        let sample: Vec<_> = moving.iter().step_by(step).collect();
        intervals.sort_by(f64::total_cmp);
        // A frame's rows are all read within the frame's own period.
        let period_s = intervals[intervals.len() / 2];
        let given_s = opts.rolling_shutter_s;
        // The unshearing is linear in the readout: the corners kept, already unsheared by the
        // given one, take the rest.
        let misfit = |readout_s: f64| -> Option<f64> {
            let mut sq = 0.0;
            for (past, corners, _) in &sample {
                let mut c = *corners;
                unshear(camera, floor, opts, *past, readout_s - given_s, &mut c);
                let p = planar_pose(camera, floor, &c, opts.tag_size_m, opts.marker_height_m)?;
                sq += p.reprojection_rms_px.powi(2);
            }
            Some((sq / sample.len() as f64).sqrt())
        };
        let as_read = misfit(given_s)?;
        let (mut best_s, mut best_px) = (given_s, as_read);
        let steps = (period_s / READOUT_STEP_S).floor() as i64;
        for k in -steps..=steps {
            let r = k as f64 * READOUT_STEP_S;
            if let Some(m) = misfit(r) {
                if m < best_px {
                    (best_s, best_px) = (r, m);
                }
            }
        }
        Some(Self {
            readout_s: best_s,
            given_s,
            rms_as_read_px: as_read,
            rms_unsheared_px: best_px,
            fixes: sample.len(),
            fastest_mps: moving.iter().map(|m| m.2).fold(0.0, f64::max),
        })
    }

    /// Whether the tags show a rolling shutter: a readout of at least
    /// [`MIN_REPORTED_READOUT_S`] that explains most of the corners' misfit.
    pub fn shows_rolling_shutter(&self) -> bool {
        self.readout_s.abs() >= MIN_REPORTED_READOUT_S
            && self.rms_as_read_px >= MIN_IMPROVEMENT * self.rms_unsheared_px
    }

    /// Whether the tags' readout differs from the one given: by more than
    /// [`MIN_REPORTED_READOUT_S`], with the corners fitting it clearly better.
    pub fn contradicts_given(&self) -> bool {
        self.given_s != 0.0
            && (self.readout_s - self.given_s).abs() > MIN_REPORTED_READOUT_S
            && self.rms_as_read_px >= MIN_GIVEN_IMPROVEMENT * self.rms_unsheared_px
    }

    /// A warning when the tags show a readout the run was not given: none given, or another.
    pub fn warning(&self) -> Option<String> {
        if self.given_s != 0.0 {
            return self.contradicts_given().then(|| self.given_warning());
        }
        self.shows_rolling_shutter().then(|| {
            format!(
                "the tags are sheared along their motion as a rolling shutter reading the frame {} over {:.1} ms would shear them (corners fit {:.3} px RMS as read, {:.3} px with that readout undone, over {} moving fixes): each fix's time is then off by up to that readout, {:.0} mm at this run's fastest {:.2} m/s; if the camera has a rolling shutter, give --rolling-shutter-s {:.4} (or its readout time from the datasheet{})",
                if self.readout_s < 0.0 { "from the bottom row up" } else { "from the top row down" },
                self.readout_s.abs() * 1e3,
                self.rms_as_read_px,
                self.rms_unsheared_px,
                self.fixes,
                self.readout_s.abs() * self.fastest_mps * 1e3,
                self.fastest_mps,
                self.readout_s,
                if self.readout_s < 0.0 { ", negative: the rows are read from the bottom up" } else { "" }
            )
        })
    }

    /// The warning for a given readout the tags contradict.
    fn given_warning(&self) -> String {
        let direction = |r: f64| {
            if r < 0.0 {
                "from the bottom row up"
            } else {
                "from the top row down"
            }
        };
        let error_s = self.readout_s - self.given_s;
        let flipped = if self.readout_s * self.given_s < 0.0 {
            " (the other direction: the rows are read the other way round)"
        } else {
            ""
        };
        format!(
            "--rolling-shutter-s {} is not the readout the tags show: their corners fit {:.3} px RMS (over {} moving fixes) with a readout {} over {:.1} ms{flipped}, against {:.3} px with the {:.1} ms {} given; each fix's time is then off by up to {:.1} ms, {:.1} mm at this run's fastest {:.2} m/s: give --rolling-shutter-s {:.4} (check the datasheet's readout time and the rows' direction)",
            self.given_s,
            self.rms_unsheared_px,
            self.fixes,
            direction(self.readout_s),
            self.readout_s.abs() * 1e3,
            self.rms_as_read_px,
            self.given_s.abs() * 1e3,
            direction(self.given_s),
            error_s.abs() * 1e3,
            error_s.abs() * self.fastest_mps * 1e3,
            self.fastest_mps,
            self.readout_s,
        )
    }
}
