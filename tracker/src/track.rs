//! Frame-by-frame tracking: search the tag in a region of interest around the
//! predicted position (full frame when lost), turn the corners into a planar
//! floor pose, grade it, reject impossible jumps, and never invent a pose for a
//! frame without a confident detection.
//!
//! A detection is judged by its geometry, not by the detector's decision margin: blur, dim
//! light and compression lower the margin of perfectly good detections (to 5–12 where a
//! sharp frame gives 60 and more), while a wrong detection shows itself in its shape. The
//! corners must fit a square of the tag's size lying flat at the marker height (reprojection
//! RMS), the square's size in the image must be what the camera's height implies (a tag of
//! another size, a reflection), and the pose must follow from the track's motion (a jump
//! faster than the robot can move is rejected).
//!
//! Each fix is timed where the tag was read: with a rolling shutter (`rolling_shutter_s`, the
//! time from reading the first row to reading the last) row y of a frame stamped t is read at
//! t + y / rows · readout, so the fix is at the frame time plus the tag centre's row over the
//! rows times the readout. A negative readout is a sensor read from the bottom row up (one
//! mounted upside down, its image turned after readout): row y is read at
//! t + (rows − 1 − y) / rows · |readout|. Frame times themselves are the container's (dropped frames leave
//! a gap in time).
//!
//! Every fix carries its σ (see `uncertainty.rs`); the corner noise behind it is pooled over
//! recent fixes from the planar fits' residuals.

use std::collections::BTreeMap;
use std::sync::mpsc;

use nalgebra::Point2;
use odocal_calib::{CameraModel, FloorToCamera};
use odocal_core::{wrap_angle, Pose2, PoseSigma};
use odocal_core::{TagToRobot, Trajectory, TrajectoryRow};

use crate::detect::{Roi, TagDetection, TagDetector};
use crate::marker_height::TAG_SIDE_TOLERANCE;
use crate::pose::{planar_pose, pnp_cross_check, PnpCheck};
use crate::source::{decode_into, Batch, Frame, FrameSource, GrayFrame, SourceInfo};
use crate::uncertainty::{
    calibration_covariance, corner_covariance, corner_covariance_from_sides, expected_residual_px2,
    sigma_of,
};
use crate::TrackError;

/// Fixes further apart than this, seconds, are not taken as one motion (the robot may have
/// done anything between them).
pub const MAX_CONTINUOUS_S: f64 = 0.5;

/// The highest a marker may sit, as a share of the camera's height above the floor.
const MAX_MARKER_SHARE: f64 = 0.8;

/// Tracking settings.
#[derive(Debug, Clone, PartialEq)]
pub struct TrackOptions {
    /// Tag family, e.g. "tag36h11".
    pub family: String,
    /// Id of the robot's tag.
    pub tag_id: u32,
    /// Side of the tag's black square, metres.
    pub tag_size_m: f64,
    /// Height of the marker plane above the floor, metres.
    pub marker_height_m: f64,
    /// Search a region of interest around the prediction (false: every frame full-frame).
    pub use_roi: bool,
    /// Quad decimation of the full-frame search while ROI tracking (the fix is
    /// then refined at full resolution in a ROI); 1 disables.
    pub search_decimate: f32,
    /// Largest number of corrected bits accepted.
    pub max_hamming: u32,
    /// Smallest decision margin accepted (0: none; detections are judged by their geometry).
    pub min_decision_margin: f32,
    /// Largest relative difference between the tag's fitted size on the floor and
    /// `tag_size_m` (0.15 = 15 %): a larger or smaller square is another tag or a reflection.
    pub max_size_error: f64,
    /// Rolling-shutter readout time, seconds: from reading the frame's first row to its last
    /// (0 for a global shutter; negative when the rows are read from the bottom of the image
    /// up). Each fix is then timed at the rows where the tag was read.
    pub rolling_shutter_s: f64,
    /// Covariance of the camera's intrinsic parameters (camera.json's `covariance`, in the
    /// order of `CameraModel::parameters`): added to every fix's σ when given.
    pub intrinsics_covariance: Option<nalgebra::DMatrix<f64>>,
    /// camera.json's floor-position uncertainty map: when given, the calibration's part of a
    /// fix's position σ is the map's at the tag (the floor plane located with the same
    /// intrinsics moves with them, which the intrinsics' covariance alone, carried with the
    /// floor held fixed, leaves out and so overstates many times over).
    pub floor_uncertainty: Option<odocal_calib::FloorUncertaintyMap>,
    /// Largest reprojection RMS accepted, pixels.
    pub max_reprojection_px: f64,
    /// Fastest plausible robot speed, m/s (faster apparent motion is a jump).
    pub max_speed_mps: f64,
    /// Fastest plausible turn rate, rad/s.
    pub max_turn_rate_rad_s: f64,
    /// Run the solvePnP (IPPE_SQUARE) cross-check on every fix.
    pub pnp_cross_check: bool,
    /// Where the tag sits on the robot. Fixes are the tag's poses; the trajectory is the
    /// robot's (its axle midpoint, heading forwards), as the wheel odometry is.
    pub tag_to_robot: TagToRobot,
    /// How the tag's plate leans on the robot: the angles, radians, by which it falls toward
    /// its own x axis and toward its y axis (zero: laid flat). Each corner then sits
    /// `−x·tan(x angle) − y·tan(y angle)` above the marker height, x and y its place on the
    /// tag, and its ray is met there.
    pub tag_tilt_rad: nalgebra::Vector2<f64>,
    /// Stop after this many frames when the tag's id was in none of them while another id of
    /// the family was in nearly all (the robot's tag given a wrong id: reading on would cost
    /// the whole video's time for the same error). `None` reads the whole video, for a tag
    /// that comes into view only later.
    pub wrong_id_after_frames: Option<usize>,
}

/// A tag tilted more than this on the robot is refused, degrees: the planar pose takes each
/// corner's height from the tilt given, and a plate leaning further is no marker plane.
pub const MAX_TAG_TILT_DEG: f64 = 10.0;

impl TrackOptions {
    /// These options with `camera`'s calibration uncertainty (camera.json's intrinsics
    /// covariance and floor-uncertainty map) added to every fix's σ.
    pub fn with_calibration(mut self, camera: &odocal_calib::CameraFile) -> Self {
        self.intrinsics_covariance = camera.covariance_matrix();
        self.floor_uncertainty = camera.floor_uncertainty.clone();
        self
    }

    /// Checks the options for physical sense (the message names the command-line option);
    /// with the camera's height above the floor, the marker must be below the camera.
    pub fn check(&self, camera_height_m: Option<f64>) -> Result<(), TrackError> {
        let bad = |m: String| Err(TrackError::Options(m));
        crate::detect::check_tag_id(&self.family, self.tag_id, "--tag-id")?;
        if !(self.tag_size_m > 0.0 && self.tag_size_m <= 1.0) {
            return bad(format!(
                "--tag-size {}: the tag's black square is 0 to 1 m across",
                self.tag_size_m
            ));
        }
        // A marker in the top fifth of the way up to the camera is no robot's: such a height
        // is the camera's own typed in, or centimetres read as metres.
        let top = camera_height_m.map_or(f64::INFINITY, |h| MAX_MARKER_SHARE * h);
        if !(self.marker_height_m >= 0.0 && self.marker_height_m < top.min(10.0)) {
            return bad(format!(
                "--marker-height {}: the marker is on the robot, 0 m or more above the floor and well below the camera{} (in metres)",
                self.marker_height_m,
                camera_height_m.map_or(String::new(), |h| format!(
                    ": under {:.2} m, {:.0} % of the camera's {h:.2} m",
                    MAX_MARKER_SHARE * h,
                    100.0 * MAX_MARKER_SHARE
                ))
            ));
        }
        if !(self.max_speed_mps > 0.0 && self.max_speed_mps.is_finite()) {
            return bad(format!(
                "--max-speed {}: must be a positive speed in m/s",
                self.max_speed_mps
            ));
        }
        if self.rolling_shutter_s.is_nan() || self.rolling_shutter_s.abs() >= 1.0 {
            return bad(format!(
                "--rolling-shutter-s {}: the readout time from the first row to the last is 0 (global shutter) to under 1 s (typically 0.01 to 0.04 s; negative when the rows are read from the bottom of the image up)",
                self.rolling_shutter_s
            ));
        }
        let m = &self.tag_to_robot.0;
        if !m.theta_rad.is_finite() {
            return bad(format!(
                "--tag-yaw {}: the angle from the robot's front to the tag's x axis is a number of degrees",
                m.theta_rad.to_degrees()
            ));
        }
        let tilt_deg = self.tag_tilt_rad.map(f64::to_degrees);
        if !tilt_deg.iter().all(|a| a.abs() <= MAX_TAG_TILT_DEG) {
            return bad(format!(
                "--tag-tilt {},{}: the tag's plate falls toward its x and y axes by a few degrees at most ({MAX_TAG_TILT_DEG}° each); a plate leaning further is no level marker, so lay it flat",
                tilt_deg.x, tilt_deg.y
            ));
        }
        let lever_m = m.x_m.hypot(m.y_m);
        if !(lever_m.is_finite() && lever_m <= MAX_TAG_OFFSET_M) {
            return bad(format!(
                "--tag-offset {},{}: the tag's centre {lever_m:.2} m from the robot's axle midpoint is not on a small wheeled robot; the offset is in metres, ahead and to the left of the axle (0.12,0 for 12 cm ahead)",
                m.x_m, m.y_m
            ));
        }
        if !(self.max_size_error > 0.0 && self.max_size_error < 1.0) {
            return bad(format!(
                "max size error {}: a relative difference between 0 and 1",
                self.max_size_error
            ));
        }
        if !(self.max_reprojection_px > 0.0 && self.max_reprojection_px.is_finite()) {
            return bad(format!(
                "--max-reprojection {}: must be a positive number of pixels",
                self.max_reprojection_px
            ));
        }
        Ok(())
    }
}

impl Default for TrackOptions {
    fn default() -> Self {
        Self {
            family: "tag36h11".into(),
            tag_id: 0,
            tag_size_m: 0.08,
            marker_height_m: 0.08,
            use_roi: true,
            search_decimate: 2.0,
            // AprilTag's own default: tag36h11 codes are 11 bits apart, so two corrected bits
            // leave a wrong id far away, and the geometric gates check every detection.
            max_hamming: 2,
            min_decision_margin: 0.0,
            max_size_error: 0.15,
            rolling_shutter_s: 0.0,
            intrinsics_covariance: None,
            floor_uncertainty: None,
            max_reprojection_px: 1.5,
            max_speed_mps: 2.0,
            max_turn_rate_rad_s: 8.0,
            pnp_cross_check: false,
            tag_to_robot: TagToRobot::IDENTITY,
            tag_tilt_rad: nalgebra::Vector2::zeros(),
            wrong_id_after_frames: Some(WRONG_ID_FRAMES),
        }
    }
}

/// Frames read before a tag id missing from all of them, beside another id in nearly every
/// one, is taken for a wrong --tag-id (3 s at 30 frames/s; a robot's tag hidden that long at
/// the start of a run, with another tag in plain view, is rare, and `--whole-video` waits).
pub const WRONG_ID_FRAMES: usize = 90;

/// The share of the frames read an id must be seen in to be taken for the robot's tag under
/// another number.
const NEARLY_EVERY_FRAME: f64 = 0.9;

/// The ids seen in nearly every one of `frames` frames (`seen`: frames per id), most seen
/// first: when the tracked id is in none of them, the robot's tag is most likely one of
/// these, given a wrong --tag-id.
fn ids_in_nearly_every_frame(seen: &BTreeMap<u32, usize>, frames: usize) -> Vec<(u32, usize)> {
    let mut ids: Vec<(u32, usize)> = seen
        .iter()
        .filter(|&(_, &n)| frames > 0 && n as f64 >= NEARLY_EVERY_FRAME * frames as f64)
        .map(|(&id, &n)| (id, n))
        .collect();
    ids.sort_by_key(|&(id, n)| (std::cmp::Reverse(n), id));
    ids
}

/// Why a frame has no pose.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub enum GapReason {
    /// No tag of the requested id was found.
    NotDetected,
    /// Found, but with too many corrected bits or too small a decision margin.
    LowConfidence,
    /// Found, but its corners do not fit a horizontal square of the tag's size at the marker
    /// height.
    BadGeometry,
    /// Found, but it moved impossibly far since the last fix.
    Jump,
    /// The frame's timestamp is not after the previous frame's (a duplicate or a step back in
    /// the container): a pose there would have no time of its own.
    DuplicateTime,
    /// The image is identical to the previous frame's, byte for byte (a camera that repeats a
    /// frame when it misses one), or its tag's pixels are, giving the very same pose (a
    /// damaged frame the decoder completed from the one before). A pose from it would belong
    /// to an earlier time.
    RepeatedImage,
    /// The frame was dropped and its slot filled with a later frame's image (a conversion to a
    /// constant frame rate, FFmpeg's default for MP4): that image was tracked at its own slot.
    FilledDrop,
    /// Tags of the tracked id were in view, but none the track could tell for the robot's:
    /// two or more with no track to pick one (at the start, or after it was lost), or only
    /// one lying where another tag of the id was seen beside the track. A robot carries one
    /// tag of its id, and a track started on the other one would follow it.
    OtherTagOfId,
}

impl GapReason {
    /// A short name for reports.
    pub fn as_str(&self) -> &'static str {
        match self {
            Self::NotDetected => "not detected",
            Self::LowConfidence => "low confidence",
            Self::BadGeometry => "bad geometry",
            Self::Jump => "impossible jump",
            Self::DuplicateTime => "duplicate timestamp",
            Self::RepeatedImage => "repeated image",
            Self::FilledDrop => "dropped, slot filled with the next image",
            Self::OtherTagOfId => "another tag of the id in view",
        }
    }
}

/// A confident pose for one frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Fix {
    /// Tag frame → floor frame (metres, radians).
    pub pose: Pose2,
    /// When the tag was read, seconds: the frame time, plus with a rolling shutter the time
    /// the sensor took to reach the tag centre's row.
    pub t_s: f64,
    /// Standard deviations of the pose (detection noise and, when the camera file has it, the
    /// calibration's covariance).
    pub sigma: PoseSigma,
    /// The corner noise behind `sigma`, pixels per coordinate (RMS over the eight).
    pub corner_sigma_px: f64,
    /// Quality in (0, 1]: 1 / (1 + reprojection RMS in pixels).
    pub quality: f64,
    /// RMS reprojection error of the corners, pixels.
    pub reprojection_rms_px: f64,
    /// RMS residual of the planar square fit, metres.
    pub fit_rms_m: f64,
    /// The detector's decision margin.
    pub decision_margin: f32,
    /// Corrected bits.
    pub hamming: u32,
    /// Detected corners, pixels.
    pub corners_px: [Point2<f64>; 4],
    /// Whether the fix came from the ROI search (false: full frame).
    pub from_roi: bool,
    /// The solvePnP cross-check, if run.
    pub pnp: Option<PnpCheck>,
}

/// The outcome of one frame.
#[derive(Debug, Clone, Copy, PartialEq)]
// Most frames are fixes: boxing them would cost an allocation per frame to save space on gaps.
#[allow(clippy::large_enum_variant)]
pub enum Outcome {
    /// A confident pose.
    Fix(Fix),
    /// No pose, and why.
    Gap(GapReason),
}

/// The figures of a detection that was rejected, so that a report can say why.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Rejected {
    /// The detector's decision margin.
    pub decision_margin: f32,
    /// Corrected bits.
    pub hamming: u32,
    /// RMS reprojection error of the corners under the planar pose, pixels (none when the
    /// corners fit no horizontal square at all).
    pub reprojection_px: Option<f64>,
    /// Side of the square the corners span on the marker plane, metres (none as above).
    pub side_m: Option<f64>,
}

/// One frame's record.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FrameRecord {
    /// Frame index in the source.
    pub index: usize,
    /// Frame time, seconds.
    pub t_s: f64,
    /// Fix or gap.
    pub outcome: Outcome,
    /// For a gap where the tag was detected but rejected: the detection's figures.
    pub rejected: Option<Rejected>,
    /// Another tag of the tracked id seen in this frame besides the one tracked (or, in an
    /// [`GapReason::OtherTagOfId`] gap, one of those in view).
    pub other_tag: Option<OtherTag>,
}

/// Where a second tag of the tracked id was seen.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OtherTag {
    /// Centre of its corners, pixels.
    pub centre_px: Point2<f64>,
    /// Its centre on the floor (at the marker height), metres.
    pub floor_m: Option<Point2<f64>>,
}

/// A run of consecutive frames without a pose.
#[derive(Debug, Clone, PartialEq)]
pub struct Gap {
    /// First frame of the gap.
    pub first_index: usize,
    /// Last frame of the gap.
    pub last_index: usize,
    /// Time of the first frame, seconds.
    pub start_s: f64,
    /// Time of the last frame, seconds.
    pub end_s: f64,
    /// Reasons and how many frames each.
    pub reasons: BTreeMap<&'static str, usize>,
}

/// The tracker's state for one video.
pub struct Tracker {
    camera: CameraModel,
    floor: FloorToCamera,
    opts: TrackOptions,
    detector: TagDetector,
    /// Last accepted fixes (time, pose, side in pixels), newest last, at most 2.
    history: Vec<(f64, Pose2, f64)>,
    /// Index of the frame of the last fix.
    last_fix_index: Option<usize>,
    consecutive_jumps: usize,
    seen: BTreeMap<u32, usize>,
    /// The ids the last frame given to [`Self::process`] showed.
    ids_in_last_frame: Vec<u32>,
    /// Frames given to [`Self::process`].
    frames_read: usize,
    /// Pooled corner residuals: decayed sums of each fix's squared residuals over what its
    /// corners' covariance expects of them, and of the weights.
    residual_pool: (f64, f64),
    /// Covariance of the intrinsics (camera.json), if known.
    intrinsics_covariance: Option<nalgebra::DMatrix<f64>>,
    /// Which of the search directions the whole-frame blurred search tries next.
    blurred_search_turn: usize,
    /// The time of the first frame searched whole for a smeared tag, seconds.
    first_blurred_search_s: Option<f64>,
    /// Frames searched whole for a smeared tag, counted until the first fix.
    blurred_searches_unfound: usize,
    /// Frames since the last whole-frame search.
    frames_since_search: usize,
    /// Where other tags of the tracked id were seen beside the track (pixels, newest last):
    /// a (re)start is never made on a tag there.
    other_places_px: Vec<Point2<f64>>,
    /// Where the tags of the id stood in the last frame that could not tell them apart.
    refused_places_px: Vec<Point2<f64>>,
}

/// While the ROI follows the tag, a whole-frame search runs every this many frames: a second
/// tag of the id coming into view is seen only by it, and known, it is never taken for the
/// robot when the track is lost (a third of a second at 30 frames/s, a tenth of a
/// whole-frame search's cost per frame).
const PATROL_FRAMES: usize = 10;

/// The most places of other tags of the id remembered.
const OTHER_PLACES: usize = 16;

/// Farthest a tag may sit from the robot's axle midpoint, metres: beyond it the offset is
/// not a small robot's (or was given in centimetres).
const MAX_TAG_OFFSET_M: f64 = 1.0;

/// Blur lengths (pixels), Wiener noise-to-signal ratios and quad blurs (σ, pixels) tried along
/// the track's motion when the tag is not found in the ROI: the likeliest first, smoother ones
/// last for noisy frames (the quad blur steadies the quad search on the restored image's noise
/// and ringing; the code is still read from the restored image itself).
const DEBLUR_TRIALS: [(f64, f64, f32); 10] = [
    (9.0, 0.003, 0.0),
    (6.0, 0.003, 0.0),
    (12.0, 0.003, 0.0),
    (9.0, 0.02, 0.0),
    (6.0, 0.02, 0.0),
    (4.0, 0.01, 0.0),
    (9.0, 0.003, 0.8),
    (6.0, 0.003, 0.8),
    (7.5, 0.01, 0.8),
    (7.5, 0.03, 0.0),
];

/// The quad decimation and quad blur (σ, pixels) of the searches in the region of interest,
/// in order.
const ROI_SEARCHES: [(f32, f32); 3] = [(2.0, 0.0), (1.0, 0.0), (1.0, 0.8)];

/// Directions of an unknown motion blur tried by the whole-frame search (unit image vectors:
/// right, down-right, down, down-left).
const SEARCH_DIRECTIONS: [[f64; 2]; 4] = [
    [1.0, 0.0],
    [
        std::f64::consts::FRAC_1_SQRT_2,
        std::f64::consts::FRAC_1_SQRT_2,
    ],
    [0.0, 1.0],
    [
        -std::f64::consts::FRAC_1_SQRT_2,
        std::f64::consts::FRAC_1_SQRT_2,
    ],
];

/// Share of the corners' noise that comes from their four fitted sides (the rest independent
/// per corner), chosen on synthetic truth: with independent corners alone heading σ came out
/// too small (error/σ 1.24–1.46 over 300-frame videos) and position σ too large (0.68–0.89);
/// with sides alone position σ far too small under motion blur (2.2), whose errors shift the
/// whole tag. 0.2 keeps every condition measured within 0.75–1.38 (the README's tables).
const SIDE_SHARE: f64 = 0.2;

/// The shape of the corners' covariance (mean variance 1 per coordinate): see [`SIDE_SHARE`].
fn corner_shape(corners_px: &[Point2<f64>; 4]) -> nalgebra::SMatrix<f64, 8, 8> {
    corner_covariance_from_sides(corners_px, crate::edges::FITTED_FRACTION) * SIDE_SHARE
        + nalgebra::SMatrix::<f64, 8, 8>::identity() * (1.0 - SIDE_SHARE)
}

/// Weight of older fixes in the pooled corner noise per new fix (about the last 30 fixes).
const POOL_DECAY: f64 = 0.97;
/// Corner σ per coordinate before any fix, pixels (what the edge refit gives a sharp tag).
const PRIOR_CORNER_SIGMA_PX: f64 = 0.05;
/// Weight of that prior, in fixes.
const PRIOR_FIXES: f64 = 2.0;
/// The 99.99 % point of χ² with 5 degrees of freedom over 5: a frame's corner residuals this
/// far above what the track's noise expects do not belong to a square of the tag's size.
const RESIDUAL_GATE: f64 = 25.7 / 5.0;

impl Tracker {
    /// A tracker for frames of `camera` above `floor`.
    pub fn new(
        camera: CameraModel,
        floor: FloorToCamera,
        opts: TrackOptions,
    ) -> Result<Self, TrackError> {
        opts.check(None)?;
        let detector = TagDetector::new(&opts.family, opts.max_hamming.min(3) as usize, 1.0)?;
        let covariance = opts.intrinsics_covariance.clone();
        let mut tracker = Self {
            camera,
            floor,
            opts,
            detector,
            history: Vec::with_capacity(3),
            last_fix_index: None,
            consecutive_jumps: 0,
            seen: BTreeMap::new(),
            ids_in_last_frame: Vec::new(),
            frames_read: 0,
            residual_pool: (0.0, 0.0),
            intrinsics_covariance: None,
            blurred_search_turn: 0,
            first_blurred_search_s: None,
            blurred_searches_unfound: 0,
            frames_since_search: 0,
            other_places_px: Vec::new(),
            refused_places_px: Vec::new(),
        };
        if let Some(cov) = covariance {
            tracker.set_intrinsics_covariance(cov)?;
        }
        Ok(tracker)
    }

    /// Adds the calibration's uncertainty to every fix's σ: `cov` is the covariance of the
    /// camera's intrinsic parameters in the order of [`CameraModel::parameters`] (camera.json's
    /// `covariance`). Refused when its size does not match the camera's lens model.
    pub fn set_intrinsics_covariance(
        &mut self,
        cov: nalgebra::DMatrix<f64>,
    ) -> Result<(), TrackError> {
        let n = self.camera.parameters().len();
        if cov.nrows() != n || cov.ncols() != n || !cov.iter().all(|v| v.is_finite()) {
            return Err(TrackError::Options(format!(
                "the camera's covariance is {}×{}, its lens model has {n} parameters: recalibrate to get a matching covariance",
                cov.nrows(),
                cov.ncols()
            )));
        }
        self.intrinsics_covariance = Some(cov);
        Ok(())
    }

    /// The factor (variance ratio) that scales the corners' covariance to the residuals seen
    /// over recent fixes, with this frame's `ratio` of squared residuals to their expectation
    /// (the prior keeps the first fixes from trusting 5 degrees of freedom).
    fn noise_scale(&self, ratio: Option<f64>) -> f64 {
        let (s, n) = self.residual_pool;
        let (r, k) = ratio.map_or((0.0, 0.0), |r| (r, 1.0));
        (s + r + PRIOR_FIXES) / (n + k + PRIOR_FIXES)
    }

    /// The time the tag centred at image row `row_px` was read, for a frame stamped `t_s`
    /// when the first row read (the top one, or the bottom one for a negative readout) was.
    fn read_time(&self, t_s: f64, row_px: f64) -> f64 {
        let rows = self.camera.height.max(1) as f64;
        let readout = self.opts.rolling_shutter_s;
        let first_row = if readout < 0.0 { rows - 1.0 } else { 0.0 };
        let read_fraction = ((row_px - first_row) / rows * readout.signum()).clamp(0.0, 1.0);
        t_s + read_fraction * readout.abs()
    }

    /// Counts the ids of the last frame tracked as seen once more: a frame repeating its
    /// pixels shows them too (a still robot's identical H.264 frames read "ids seen: 0 (13
    /// frames)" beside 90 fixes).
    pub(crate) fn seen_again(&mut self) {
        for &id in &self.ids_in_last_frame {
            *self.seen.entry(id).or_insert(0) += 1;
        }
    }

    /// Ids seen so far (any id of the family) and in how many frames.
    pub fn seen_ids(&self) -> &BTreeMap<u32, usize> {
        &self.seen
    }

    /// Whether the frames read so far show the robot's tag under another id: the options'
    /// [`TrackOptions::wrong_id_after_frames`] read, the tracked id in none of them, and
    /// another id in nearly all.
    pub fn wrong_id_evident(&self) -> bool {
        self.opts
            .wrong_id_after_frames
            .is_some_and(|limit| self.frames_read >= limit)
            && !self.seen.contains_key(&self.opts.tag_id)
            && !ids_in_nearly_every_frame(&self.seen, self.frames_read).is_empty()
    }

    fn predict(&self, t_s: f64) -> Option<(Pose2, f64, f64)> {
        let &(t1, p1, side) = self.history.last()?;
        if self.history.len() >= 2 {
            let (t0, p0, _) = self.history[self.history.len() - 2];
            if t1 - t0 > 1e-6 && t1 - t0 < 0.5 {
                let w = (t_s - t1) / (t1 - t0);
                // Extrapolates the last step: from p1 away from p0.
                let mut p = p1.lerp(&p0, -w);
                p.theta_rad = wrap_angle(p.theta_rad);
                let step = (p1.position() - p0.position()).norm() * w.abs();
                return Some((p, side, step));
            }
        }
        Some((p1, side, 0.0))
    }

    fn roi_around(&self, pose: &Pose2, side_px: f64, extra_px: f64, w: u32, h: u32) -> Option<Roi> {
        let c =
            self.camera
                .floor_to_pixel(&self.floor, &pose.position(), self.opts.marker_height_m)?;
        Roi::around(c, 0.95 * side_px + extra_px + 6.0, w, h)
    }

    /// A whole-frame search for a tag smeared by motion in an unknown direction: the blur is
    /// undone along the four [`SEARCH_DIRECTIONS`] (a smear within 22.5° of one is mostly
    /// undone) and the restored frame searched decimated. In the first second of searching
    /// before the first fix, and within a second of the last one, all four are tried; a track
    /// lost for longer (the robot out of view, a person in the way) tries one per frame in
    /// turn, so that a long gap costs one deconvolution per frame, not four; a tag not yet
    /// found beside others of the family is searched for more sparingly still.
    fn search_blurred(
        &mut self,
        frame: &Frame,
        ids: &mut Vec<u32>,
    ) -> Result<Vec<TagDetection>, TrackError> {
        let (w, h) = (frame.image.width, frame.image.height);
        let whole = Roi {
            x0: 0,
            y0: 0,
            width: w,
            height: h,
        };
        // Before the first fix, only the video's first second: a tag of the id that never
        // comes (a wrong --tag-id) cost four deconvolutions of every frame, minutes a video.
        let first_s = *self.first_blurred_search_s.get_or_insert(frame.t_s);
        let recently = match self.history.last() {
            None => frame.t_s - first_s < 1.0,
            Some(&(t, _, _)) => frame.t_s - t < 1.0,
        };
        // Never found yet while the plain search reads other ids in the frame (a wrong
        // --tag-id, or another robot): one direction per frame in that first second, then one
        // every eighth frame, so a smeared tag of the id is still found within a few frames
        // or a second; a sharp one the plain search finds at once.
        let others_seen = !ids.is_empty();
        let unfound = self.history.is_empty();
        if unfound {
            self.blurred_searches_unfound += 1;
            let every = match (others_seen, recently) {
                (true, false) => 8,
                (false, false) => 4,
                (_, true) => 1,
            };
            if !self.blurred_searches_unfound.is_multiple_of(every) {
                return Ok(Vec::new());
            }
        }
        let tries = if recently && !(unfound && others_seen) {
            4
        } else {
            1
        };
        self.detector
            .set_decimate(self.opts.search_decimate.max(1.0));
        let mut found = Vec::new();
        for _ in 0..tries {
            let dir = SEARCH_DIRECTIONS[self.blurred_search_turn % 4];
            self.blurred_search_turn += 1;
            let (len, nsr, _) = DEBLUR_TRIALS[0];
            let dets = self
                .detector
                .detect_deblurred(&frame.image, whole, dir.into(), len, nsr);
            let dets = match dets {
                Ok(d) => d,
                Err(e) => {
                    self.detector.set_decimate(1.0);
                    return Err(e);
                }
            };
            ids.extend(dets.iter().map(|d| d.id));
            found = self.of_id(&dets);
            if !found.is_empty() {
                break;
            }
        }
        self.detector.set_decimate(1.0);
        Ok(found)
    }

    /// The tags of the tracked id a whole-frame search finds (decimated; with `blurred`,
    /// through [`Self::search_blurred`] when none), every id seen added to `ids`.
    fn search_whole(
        &mut self,
        frame: &Frame,
        ids: &mut Vec<u32>,
        blurred: bool,
    ) -> Result<Vec<TagDetection>, TrackError> {
        self.frames_since_search = 0;
        self.detector
            .set_decimate(self.opts.search_decimate.max(1.0));
        let dets = self.detector.detect(&frame.image, None);
        self.detector.set_decimate(1.0);
        let dets = dets?;
        ids.extend(dets.iter().map(|d| d.id));
        let same = self.of_id(&dets);
        if same.is_empty() && blurred {
            return self.search_blurred(frame, ids);
        }
        Ok(same)
    }

    fn of_id(&self, dets: &[TagDetection]) -> Vec<TagDetection> {
        dets.iter()
            .filter(|d| d.id == self.opts.tag_id)
            .copied()
            .collect()
    }

    /// Which of the tags of the id a whole-frame search found (`same`) is the robot's, the
    /// others, and whether none was taken because another was in view. A tag where another
    /// of the id was seen beside the track is never taken: the ROI search, which follows the
    /// robot over that place, did not find it there. Of the rest the track's motion picks the
    /// one nearest `predicted_px`; without it (a start, a restart, a track lost for a while)
    /// one alone is taken: a robot carries one tag of its id, so with two in view which is
    /// the robot's cannot be told, and a track started on the other would follow it.
    fn choose(
        &self,
        same: Vec<TagDetection>,
        predicted_px: Option<Point2<f64>>,
    ) -> (Option<TagDetection>, Vec<TagDetection>, bool) {
        let (known, mut candidates): (Vec<_>, Vec<_>) =
            same.into_iter().partition(|d| self.at_other_place(d));
        if let Some(p) = predicted_px {
            let chosen = self.pick(&candidates, Some(p));
            candidates.retain(|d| chosen.is_none_or(|c| !same_place(d, &c.centre_px())));
            candidates.extend(known);
            let refused = chosen.is_none() && !candidates.is_empty();
            return (chosen, candidates, refused);
        }
        match candidates.len() {
            1 => (candidates.pop(), known, false),
            0 => {
                let refused = !known.is_empty();
                (None, known, refused)
            }
            _ => {
                candidates.extend(known);
                (None, candidates, true)
            }
        }
    }

    /// Whether `d` lies where another tag of the id was seen beside the track.
    fn at_other_place(&self, d: &TagDetection) -> bool {
        self.other_places_px.iter().any(|p| same_place(d, p))
    }

    fn remember_other_place(&mut self, d: &TagDetection) {
        if !self.at_other_place(d) {
            if self.other_places_px.len() >= OTHER_PLACES {
                self.other_places_px.remove(0);
            }
            self.other_places_px.push(d.centre_px());
        }
    }

    fn other_tag(&self, d: &TagDetection) -> OtherTag {
        let centre_px = d.centre_px();
        OtherTag {
            centre_px,
            floor_m: self
                .camera
                .pixel_to_floor(&self.floor, &centre_px, self.opts.marker_height_m),
        }
    }

    /// The unit image direction in which the tag moves, from the last fix to `predicted`.
    fn image_motion(&self, predicted: &Pose2) -> Option<nalgebra::Vector2<f64>> {
        let &(_, last, _) = self.history.last()?;
        let h = self.opts.marker_height_m;
        let a = self
            .camera
            .floor_to_pixel(&self.floor, &last.position(), h)?;
        let b = self
            .camera
            .floor_to_pixel(&self.floor, &predicted.position(), h)?;
        let d = b - a;
        (d.norm() > 0.5).then(|| d / d.norm())
    }

    fn pick(&self, dets: &[TagDetection], near: Option<Point2<f64>>) -> Option<TagDetection> {
        let mut best: Option<(f64, TagDetection)> = None;
        for d in dets.iter().filter(|d| d.id == self.opts.tag_id) {
            let score = match near {
                Some(p) => (d.centre_px() - p).norm(),
                None => -(d.decision_margin as f64),
            };
            if best.as_ref().is_none_or(|(s, _)| score < *s) {
                best = Some((score, *d));
            }
        }
        best.map(|(_, d)| d)
    }

    /// Tracks one frame.
    pub fn process(&mut self, frame: &Frame) -> Result<FrameRecord, TrackError> {
        let recent = self
            .last_fix_index
            .is_some_and(|i| frame.index.saturating_sub(i) <= 5);
        let prediction = if recent {
            self.predict(frame.t_s)
        } else {
            None
        };
        // Where the track's motion puts the tag: of several tags of the id, it picks one.
        let predicted_px = prediction.and_then(|(pose, _, _)| {
            self.camera
                .floor_to_pixel(&self.floor, &pose.position(), self.opts.marker_height_m)
        });
        self.frames_since_search += 1;
        self.frames_read += 1;
        let mut ids_in_frame: Vec<u32> = Vec::new();
        let mut found: Option<(TagDetection, bool)> = None;
        let mut others: Vec<TagDetection> = Vec::new();
        let mut refused = false;
        if self.opts.use_roi {
            if let Some((pose, side, step)) = prediction {
                found = self
                    .search_roi(frame, &pose, side, step, predicted_px, &mut ids_in_frame)?
                    .map(|d| (d, true));
            }
            let patrol = found.is_some() && self.frames_since_search >= PATROL_FRAMES;
            if let Some((d, _)) = found.filter(|_| patrol) {
                others = self
                    .search_whole(frame, &mut ids_in_frame, false)?
                    .into_iter()
                    .filter(|o| !same_place(o, &d.centre_px()))
                    .collect();
            } else if found.is_none() {
                // Lost: search the whole frame (decimated), then refine in a ROI at full resolution.
                let same = self.search_whole(frame, &mut ids_in_frame, true)?;
                let (chosen, rest, no_pick) = self.choose(same, predicted_px);
                (others, refused) = (rest, no_pick);
                if let Some(coarse) = chosen {
                    found = Some((self.refine(frame, coarse)?, false));
                }
            }
        } else {
            self.frames_since_search = 0;
            let dets = self.detector.detect(&frame.image, None)?;
            ids_in_frame.extend(dets.iter().map(|d| d.id));
            let (chosen, rest, no_pick) = self.choose(self.of_id(&dets), predicted_px);
            (others, refused) = (rest, no_pick);
            found = chosen.map(|d| (d, false));
        }
        ids_in_frame.sort_unstable();
        ids_in_frame.dedup();
        for &id in &ids_in_frame {
            *self.seen.entry(id).or_insert(0) += 1;
        }
        self.ids_in_last_frame = ids_in_frame;
        // With no track to tell two tags apart both are "others": the one named is the one
        // standing where a tag stood in the last such frame (a spare lies still, the robot
        // moves), else the median place mixed the robot's with the spare's.
        let other_tag = if refused && others.len() > 1 {
            let moved = |d: &TagDetection| {
                self.refused_places_px
                    .iter()
                    .map(|p| (d.centre_px() - p).norm())
                    .fold(f64::INFINITY, f64::min)
            };
            others
                .iter()
                .min_by(|a, b| moved(a).total_cmp(&moved(b)))
                .map(|d| self.other_tag(d))
        } else {
            others.first().map(|d| self.other_tag(d))
        };
        if refused {
            self.refused_places_px = others.iter().map(|d| d.centre_px()).collect();
        }
        let (outcome, rejected) = match found {
            None if refused => (Outcome::Gap(GapReason::OtherTagOfId), None),
            None => (Outcome::Gap(GapReason::NotDetected), None),
            Some((d, from_roi)) => {
                let graded = self.grade(frame, d, from_roi);
                if matches!(graded.0, Outcome::Fix(_)) {
                    for o in &others {
                        self.remember_other_place(o);
                    }
                }
                graded
            }
        };
        Ok(FrameRecord {
            index: frame.index,
            t_s: frame.t_s,
            outcome,
            rejected,
            other_tag,
        })
    }

    /// The tag in a region of interest around the predicted `pose` (decimated first, then at
    /// full resolution, then through a motion blur), the one nearest `predicted_px` when
    /// there are several.
    fn search_roi(
        &mut self,
        frame: &Frame,
        pose: &Pose2,
        side: f64,
        step: f64,
        predicted_px: Option<Point2<f64>>,
        ids_in_frame: &mut Vec<u32>,
    ) -> Result<Option<TagDetection>, TrackError> {
        let (w, h) = (frame.image.width, frame.image.height);
        let px_per_m = side / self.opts.tag_size_m;
        let Some(roi) = self.roi_around(pose, side, 0.5 * step * px_per_m, w, h) else {
            return Ok(None);
        };
        // Decimated first: a quarter of the pixels for the quad search, and the
        // corners come from the edge refit at full resolution all the same. Then
        // full resolution, then a quad blur against noise.
        for (decimate, sigma) in ROI_SEARCHES {
            self.detector.set_decimate(decimate);
            self.detector.set_quad_sigma(sigma);
            let dets = self.detector.detect(&frame.image, Some(roi));
            self.detector.set_decimate(1.0);
            self.detector.set_quad_sigma(0.0);
            let dets = dets?;
            ids_in_frame.extend(dets.iter().map(|d| d.id));
            if let Some(d) = self.pick(&dets, predicted_px) {
                return Ok(Some(d));
            }
        }
        // Along the track's motion with every trial first, then along each
        // search direction with the likeliest ones (the motion may have turned):
        // still far cheaper than a search of the whole frame.
        let mut dirs: Vec<(nalgebra::Vector2<f64>, usize)> = Vec::new();
        if let Some(d) = self.image_motion(pose) {
            dirs.push((d, DEBLUR_TRIALS.len()));
        }
        dirs.extend(SEARCH_DIRECTIONS.iter().map(|&d| (d.into(), 2)));
        for (dir, n_trials) in dirs {
            for &(len, nsr, sigma) in &DEBLUR_TRIALS[..n_trials] {
                self.detector.set_quad_sigma(sigma);
                let dets = self
                    .detector
                    .detect_deblurred(&frame.image, roi, dir, len, nsr);
                self.detector.set_quad_sigma(0.0);
                let dets = dets?;
                ids_in_frame.extend(dets.iter().map(|d| d.id));
                if let Some(d) = self.pick(&dets, predicted_px) {
                    return Ok(Some(d));
                }
            }
        }
        Ok(None)
    }

    /// A tag found by the decimated whole-frame search, read again at full resolution in a
    /// ROI around it (itself when that finds nothing).
    fn refine(&mut self, frame: &Frame, coarse: TagDetection) -> Result<TagDetection, TrackError> {
        let (w, h) = (frame.image.width, frame.image.height);
        if self.opts.search_decimate > 1.0 {
            if let Some(roi) = Roi::around(coarse.centre_px(), 1.1 * coarse.side_px() + 12.0, w, h)
            {
                let fine = self.detector.detect(&frame.image, Some(roi))?;
                if let Some(d) = self.pick(&fine, Some(coarse.centre_px())) {
                    return Ok(d);
                }
            }
        }
        Ok(coarse)
    }

    /// Under a rolling shutter each corner was read at its own row's time: see [`unshear`],
    /// with the tag's motion from the last two fixes.
    fn unshear(&self, d: &mut TagDetection) {
        let readout = self.opts.rolling_shutter_s;
        if readout == 0.0 || self.history.len() < 2 {
            return;
        }
        let (t0, p0, _) = self.history[self.history.len() - 2];
        let (t1, p1, _) = self.history[self.history.len() - 1];
        unshear(
            &self.camera,
            &self.floor,
            &self.opts,
            [(t0, p0), (t1, p1)],
            readout,
            &mut d.corners_px,
        );
    }

    fn grade(
        &mut self,
        frame: &Frame,
        mut d: TagDetection,
        from_roi: bool,
    ) -> (Outcome, Option<Rejected>) {
        // Under a rolling shutter the first fixes of a track have no image velocity to undo
        // the shear with: their misfit is shear, not noise, and stays out of the pool.
        let sheared = self.opts.rolling_shutter_s != 0.0 && self.history.len() < 2;
        self.unshear(&mut d);
        flatten(&self.camera, &self.floor, &self.opts, &mut d.corners_px);
        let o = &self.opts;
        let planar = planar_pose(
            &self.camera,
            &self.floor,
            &d.corners_px,
            o.tag_size_m,
            o.marker_height_m,
        );
        let reject = |reason| {
            let rejected = Rejected {
                decision_margin: d.decision_margin,
                hamming: d.hamming,
                reprojection_px: planar.as_ref().map(|p| p.reprojection_rms_px),
                side_m: planar.as_ref().map(|p| p.size_m),
            };
            (Outcome::Gap(reason), Some(rejected))
        };
        if d.hamming > o.max_hamming || d.decision_margin < o.min_decision_margin {
            return reject(GapReason::LowConfidence);
        }
        let Some(planar) = planar else {
            return reject(GapReason::BadGeometry);
        };
        // The corners' covariance at the prior σ; scaled below by the residuals.
        let base_cov = corner_shape(&d.corners_px) * PRIOR_CORNER_SIGMA_PX.powi(2);
        let sq = 4.0 * planar.reprojection_rms_px.powi(2);
        let expected = expected_residual_px2(
            &self.camera,
            &self.floor,
            &planar.pose,
            o.tag_size_m,
            o.marker_height_m,
            &base_cov,
        )
        .unwrap_or(f64::NAN);
        // The corners' misfit must be within what the track's own noise allows, and never
        // beyond the fixed limit on a clean track. NaN never passes.
        let allowed_px2 = RESIDUAL_GATE * self.noise_scale(None) * expected;
        let limit_px = o.max_reprojection_px.max((allowed_px2 / 4.0).sqrt());
        if planar.reprojection_rms_px.is_nan() || planar.reprojection_rms_px > limit_px {
            return reject(GapReason::BadGeometry);
        }
        // The square's size: the floor points' spread against the model's (side / √2 from the centre).
        if !(planar.size_m / o.tag_size_m - 1.0)
            .abs()
            .le(&o.max_size_error)
        {
            return reject(GapReason::BadGeometry);
        }
        let t_fix = self.read_time(frame.t_s, d.centre_px().y);
        if let Some(&(t_last, p_last, _)) = self.history.last() {
            let dt = (t_fix - t_last).abs();
            let dist = (planar.pose.position() - p_last.position()).norm();
            let turn = wrap_angle(planar.pose.theta_rad - p_last.theta_rad).abs();
            if dist > o.max_speed_mps * dt + 0.02 || turn > o.max_turn_rate_rad_s * dt + 0.2 {
                self.consecutive_jumps += 1;
                if self.consecutive_jumps >= 3 {
                    // The old track was the outlier: start again from here.
                    self.history.clear();
                    self.consecutive_jumps = 0;
                }
                return reject(GapReason::Jump);
            }
        }
        self.consecutive_jumps = 0;
        let pnp = if o.pnp_cross_check {
            pnp_cross_check(
                &self.camera,
                &self.floor,
                &d.corners_px,
                o.tag_size_m,
                &planar,
            )
            .ok()
        } else {
            None
        };
        let ratio = sq / expected;
        let scale = self.noise_scale(Some(ratio));
        if !sheared {
            let (s, n) = self.residual_pool;
            self.residual_pool = (POOL_DECAY * s + ratio, POOL_DECAY * n + 1.0);
        }
        let corner_cov = base_cov * scale;
        let corner_sigma_px = (corner_cov.trace() / 8.0).sqrt();
        let mut cov = corner_covariance(
            &self.camera,
            &self.floor,
            &d.corners_px,
            o.tag_size_m,
            o.marker_height_m,
            &corner_cov,
        )
        .unwrap_or_else(|| nalgebra::Matrix3::from_diagonal_element(f64::INFINITY));
        if let Some(ic) = &self.intrinsics_covariance {
            if let Some(c) = calibration_covariance(
                &self.camera,
                &self.floor,
                &d.corners_px,
                o.tag_size_m,
                o.marker_height_m,
                ic,
            ) {
                let mut c = c;
                let centre = d.centre_px();
                if let Some(mm2) = o
                    .floor_uncertainty
                    .as_ref()
                    .and_then(|m| m.covariance_at(&centre))
                {
                    // Position from the floor map; the heading's part stays: a turn of the tag
                    // does not move with the floor.
                    c.fixed_view_mut::<2, 2>(0, 0).copy_from(&(mm2 * 1e-6));
                    for k in 0..2 {
                        c[(k, 2)] = 0.0;
                        c[(2, k)] = 0.0;
                    }
                }
                cov += c;
            }
        }
        let sigma = sigma_of(&cov);
        if ![sigma.x_m, sigma.y_m, sigma.theta_rad]
            .iter()
            .all(|v| v.is_finite() && *v > 0.0)
        {
            return reject(GapReason::BadGeometry);
        }
        self.history.push((t_fix, planar.pose, d.side_px()));
        if self.history.len() > 2 {
            self.history.remove(0);
        }
        self.last_fix_index = Some(frame.index);
        let fix = Outcome::Fix(Fix {
            pose: planar.pose,
            t_s: t_fix,
            sigma,
            corner_sigma_px,
            quality: 1.0 / (1.0 + planar.reprojection_rms_px),
            reprojection_rms_px: planar.reprojection_rms_px,
            fit_rms_m: planar.fit_rms_m,
            decision_margin: d.decision_margin,
            hamming: d.hamming,
            corners_px: d.corners_px,
            from_roi,
            pnp,
        });
        (fix, None)
    }
}

/// Whether the tag `d` lies at `centre_px` (within half its side).
fn same_place(d: &TagDetection, centre_px: &Point2<f64>) -> bool {
    (d.centre_px() - centre_px).norm() < 0.5 * d.side_px()
}

/// Moves each corner of a tag read under a rolling shutter (`readout_s` from the first row
/// to the last, negative when read from the bottom up: a row below is then read earlier) back
/// along the tag's image motion to where it was when the tag centre's row
/// was read. The motion is that between two earlier fixes (time, pose) as a rigid image
/// motion: the centre's velocity and the turn of a point half a tag ahead along the heading.
/// That undoes the shear that would otherwise tilt the fitted heading, and the sideways shift
/// a turning tag shows (its upper and lower corners swing the same way across the image).
pub(crate) fn unshear(
    camera: &CameraModel,
    floor: &FloorToCamera,
    opts: &TrackOptions,
    fixes: [(f64, Pose2); 2],
    readout_s: f64,
    corners_px: &mut [Point2<f64>; 4],
) {
    let [(t0, p0), (t1, p1)] = fixes;
    let h = opts.marker_height_m;
    if !(t1 - t0 > 1e-6 && t1 - t0 < 0.5) {
        return;
    }
    let ahead = |p: &Pose2| {
        let r = 0.5 * opts.tag_size_m;
        Point2::new(p.x_m + r * p.theta_rad.cos(), p.y_m + r * p.theta_rad.sin())
    };
    let px = |q: &Point2<f64>| camera.floor_to_pixel(floor, q, h);
    let (Some(a), Some(b), Some(a2), Some(b2)) = (
        px(&p0.position()),
        px(&p1.position()),
        px(&ahead(&p0)),
        px(&ahead(&p1)),
    ) else {
        return;
    };
    let dt = t1 - t0;
    let v = (b - a) / dt;
    let (da, db) = (a2 - a, b2 - b);
    let omega = wrap_angle(db.y.atan2(db.x) - da.y.atan2(da.x)) / dt;
    let rows = camera.height.max(1) as f64;
    let centre = crate::detect::quad_centre(corners_px);
    for c in corners_px.iter_mut() {
        let r = *c - centre;
        let vc = v + nalgebra::Vector2::new(-r.y, r.x) * omega;
        *c -= vc * ((c.y - centre.y) / rows * readout_s);
    }
}

/// `corners_px` of a tag whose plate leans by `opts.tag_tilt_rad` moved to where the same
/// corners would be seen on a level plate at the marker height: each corner's ray is met at
/// the corner's own height, and that floor point seen at the marker height. Every later step
/// (the planar pose, its σ, the checks of the tag's shape and tilt) then takes the plate as
/// level, as it is built to. A corner whose ray misses is left as detected.
pub(crate) fn flatten(
    camera: &CameraModel,
    floor: &FloorToCamera,
    opts: &TrackOptions,
    corners_px: &mut [Point2<f64>; 4],
) {
    if opts.tag_tilt_rad == nalgebra::Vector2::zeros() {
        return;
    }
    let slope = opts.tag_tilt_rad.map(f64::tan);
    let h = opts.marker_height_m;
    for (c, m) in corners_px
        .iter_mut()
        .zip(crate::pose::tag_model(opts.tag_size_m))
    {
        let above_m = -(m.x * slope.x + m.y * slope.y);
        if let Some(level) = camera
            .pixel_to_floor(floor, c, h + above_m)
            .and_then(|q| camera.floor_to_pixel(floor, &q, h))
        {
            *c = level;
        }
    }
}

/// Everything a tracking run produced.
#[derive(Debug, Clone, PartialEq)]
pub struct TrackResult {
    /// Where the tag sits on the robot ([`TrackOptions::tag_to_robot`]): the fixes are the
    /// tag's poses, [`Self::trajectory`] the robot's.
    pub tag_to_robot: TagToRobot,
    /// One record per frame, in order.
    pub records: Vec<FrameRecord>,
    /// Frames lost inside the file, placed by the robot's motion and confirmed by the
    /// container's frame count: the records after each are timed past them.
    pub lost_in_file: Vec<crate::timing::DroppedFrames>,
    /// Frames dropped where nothing counts them (a file written at a constant rate after the
    /// recording dropped them), placed by the robot's motion alone: the records after each
    /// are timed past them.
    pub dropped_by_motion: Vec<crate::timing::DroppedFrames>,
    /// Ids seen (any id of the family) and in how many frames.
    pub seen_ids: BTreeMap<u32, usize>,
    /// Frame size, pixels.
    pub frame_size: (u32, u32),
    /// The source as it stood after the last frame (timing, frames announced).
    pub source: SourceInfo,
}

impl TrackResult {
    /// The fixes only.
    pub fn fixes(&self) -> impl Iterator<Item = (&FrameRecord, &Fix)> {
        self.records.iter().filter_map(|r| match &r.outcome {
            Outcome::Fix(f) => Some((r, f)),
            Outcome::Gap(_) => None,
        })
    }

    /// The trajectory file contents: the robot's pose at every fix (the tag's taken off its
    /// mount), gaps absent.
    pub fn trajectory(&self) -> Result<Trajectory, TrackError> {
        let rows = self
            .fixes()
            .map(|(_, f)| TrajectoryRow {
                t_s: f.t_s,
                pose: f.pose,
                quality: f.quality,
                sigma: Some(f.sigma),
            })
            .collect();
        let tag = Trajectory::new(rows)
            .map_err(|e| TrackError::Mismatch(format!("frame timestamps: {e}")))?;
        Ok(self.tag_to_robot.robot_trajectory(&tag))
    }

    /// The fixes in runs of one continuous motion, as ranges of their indices (in
    /// [`Self::fixes`], and the trajectory's rows). A run ends at a rejected jump (two
    /// recordings joined, a robot lifted and set down: the step across it is no motion of the
    /// robot, and its chord alone named a straight-mounted tag turned 50°) and where the fixes
    /// are more than [`MAX_CONTINUOUS_S`] apart. Fits over consecutive fixes take their steps
    /// within runs.
    pub fn continuous_runs(&self) -> Vec<std::ops::Range<usize>> {
        let mut runs = Vec::new();
        let (mut start, mut fixes) = (0, 0);
        let (mut last_s, mut jumped) = (f64::NEG_INFINITY, false);
        for r in &self.records {
            match &r.outcome {
                Outcome::Gap(reason) => jumped |= *reason == GapReason::Jump,
                Outcome::Fix(f) => {
                    if fixes > start && (jumped || f.t_s - last_s > MAX_CONTINUOUS_S) {
                        runs.push(start..fixes);
                        start = fixes;
                    }
                    (last_s, jumped) = (f.t_s, false);
                    fixes += 1;
                }
            }
        }
        if fixes > start {
            runs.push(start..fixes);
        }
        runs
    }

    /// Runs of frames without a pose.
    pub fn gaps(&self) -> Vec<Gap> {
        let mut gaps: Vec<Gap> = Vec::new();
        let mut prev_gap = false;
        for r in &self.records {
            if let Outcome::Gap(reason) = r.outcome {
                if prev_gap {
                    if let Some(g) = gaps.last_mut() {
                        g.last_index = r.index;
                        g.end_s = r.t_s;
                        *g.reasons.entry(reason.as_str()).or_insert(0) += 1;
                    }
                } else {
                    gaps.push(Gap {
                        first_index: r.index,
                        last_index: r.index,
                        start_s: r.t_s,
                        end_s: r.t_s,
                        reasons: BTreeMap::from([(reason.as_str(), 1)]),
                    });
                }
                prev_gap = true;
            } else {
                prev_gap = false;
            }
        }
        gaps
    }

    /// Why no frame gave a fix: the rejection reasons, most frequent first, with the figures
    /// that failed (median decision margin and reprojection error of the rejected detections
    /// against the limits in `opts`), and the ids seen.
    pub fn no_fix_message(&self, opts: &TrackOptions, path: &std::path::Path) -> String {
        self.no_fix_text(opts, path, None)
    }

    /// Whether a run without a fix may have a wrong --family: the tag's id never seen, or
    /// many ids, none with a tag's shape.
    pub fn family_in_doubt(&self, tag_id: u32) -> bool {
        (!self.seen_ids.contains_key(&tag_id) && self.ids_in_nearly_every_frame().is_empty())
            || self.wrong_family()
    }

    /// The ids seen in nearly every frame, most seen first (see [`WRONG_ID_FRAMES`]).
    fn ids_in_nearly_every_frame(&self) -> Vec<(u32, usize)> {
        ids_in_nearly_every_frame(&self.seen_ids, self.records.len())
    }

    /// Why the tracked id is taken for a wrong --tag-id: it was in none of the frames read,
    /// another id was in nearly all. `early`: the run stopped after
    /// [`TrackOptions::wrong_id_after_frames`] rather than at the video's end.
    pub fn wrong_id_text(
        &self,
        opts: &TrackOptions,
        path: &std::path::Path,
        early: bool,
    ) -> String {
        let n = self.records.len();
        let span_s = match (self.records.first(), self.records.last()) {
            (Some(a), Some(b)) => b.t_s - a.t_s,
            _ => 0.0,
        };
        let read = if early {
            format!("was not seen in the first {n} frames ({span_s:.1} s)")
        } else {
            format!("was never seen in {n} frames")
        };
        let ids = self.ids_in_nearly_every_frame();
        let (seen, advice) = match ids.as_slice() {
            [(id, k)] => (
                format!("tag {id} was seen in {k} of them"),
                format!("pass --tag-id {id} if that is the robot's tag"),
            ),
            _ => (
                format!(
                    "tags {} were each seen in nearly every one",
                    ids.iter()
                        .map(|(id, k)| format!("{id} ({k} frames)"))
                        .collect::<Vec<_>>()
                        .join(", ")
                ),
                "pass the robot's tag's id with --tag-id".to_string(),
            ),
        };
        let wait = if early {
            format!(
                " (or --whole-video, should tag {} come into view later)",
                opts.tag_id
            )
        } else {
            String::new()
        };
        format!(
            "tag {} ({}) {read} of {}, where {seen}: {advice}{wait}",
            opts.tag_id,
            opts.family,
            path.display()
        )
    }

    /// One robot carries one tag: many ids, and the tracked one never with a tag's shape,
    /// are another family's tags (or the floor's texture) read as this one's small codes.
    fn wrong_family(&self) -> bool {
        self.seen_ids.len() >= FALSE_FAMILY_IDS
            && self
                .records
                .iter()
                .any(|r| r.outcome == Outcome::Gap(GapReason::BadGeometry))
    }

    /// [`Self::no_fix_message`], with what the other families read in a few of the frames
    /// when the family is in doubt.
    pub fn no_fix_text(
        &self,
        opts: &TrackOptions,
        path: &std::path::Path,
        probe: Option<&crate::detect::FamilyProbe>,
    ) -> String {
        let n = self.records.len();
        let mut by_reason: BTreeMap<GapReason, Vec<&FrameRecord>> = BTreeMap::new();
        for r in &self.records {
            if let Outcome::Gap(reason) = r.outcome {
                by_reason.entry(reason).or_default().push(r);
            }
        }
        let read_as = probe
            .map(|p| format!(": {}", p.advice(opts.tag_id)))
            .unwrap_or_default();
        if !self.seen_ids.contains_key(&opts.tag_id) && !self.ids_in_nearly_every_frame().is_empty()
        {
            return self.wrong_id_text(opts, path, false);
        }
        if !self.seen_ids.contains_key(&opts.tag_id) {
            return format!(
                "tag {} ({}) was never seen in {n} frames of {}; {}: check --tag-id and --family{read_as}",
                opts.tag_id,
                opts.family,
                path.display(),
                self.seen_ids_text()
            );
        }
        let mut reasons: Vec<(GapReason, Vec<&FrameRecord>)> = by_reason.into_iter().collect();
        reasons.sort_by_key(|(_, frames)| std::cmp::Reverse(frames.len()));
        // A wrong family is said first, and the size the misread corners span is no tag size
        // to give (a tag36h11 video read as tag16h5 was told "give --tag-size 0.1310", still
        // refused).
        let wrong_family = self.wrong_family();
        let parts: Vec<String> = reasons
            .iter()
            .map(|(reason, frames)| {
                let rej: Vec<&Rejected> =
                    frames.iter().filter_map(|r| r.rejected.as_ref()).collect();
                let margin = median(rej.iter().map(|r| r.decision_margin as f64).collect());
                let reproj = median(rej.iter().filter_map(|r| r.reprojection_px).collect());
                let figures = match reason {
                    GapReason::NotDetected
                    | GapReason::DuplicateTime
                    | GapReason::RepeatedImage
                    | GapReason::FilledDrop => String::new(),
                    GapReason::LowConfidence => format!(
                        " (median decision margin {}, accepted from {}; median hamming {})",
                        fmt_opt(margin, 1),
                        opts.min_decision_margin,
                        fmt_opt(median(rej.iter().map(|r| r.hamming as f64).collect()), 0)
                    ),
                    GapReason::BadGeometry if wrong_family => format!(
                        " (median corner reprojection {} px, accepted up to {} px)",
                        fmt_opt(reproj, 2),
                        opts.max_reprojection_px,
                    ),
                    GapReason::BadGeometry => format!(
                        " (median corner reprojection {} px, accepted up to {} px: {})",
                        fmt_opt(reproj, 2),
                        opts.max_reprojection_px,
                        bad_geometry_advice(
                            median(rej.iter().filter_map(|r| r.side_m).collect()),
                            opts
                        )
                    ),
                    GapReason::Jump => format!(
                        " (faster than --max-speed {} m/s between detections)",
                        opts.max_speed_mps
                    ),
                    GapReason::OtherTagOfId => format!(
                        " (another tag {}{}: {})",
                        opts.tag_id,
                        self.other_tag_place(),
                        OTHER_TAG_ADVICE
                    ),
                };
                format!("{} {}{figures}", frames.len(), reason.as_str())
            })
            .collect();
        let family_hint = if wrong_family {
            format!(
                "{} different ids were seen, none with the tag's shape, where the robot carries one tag: they look like false readings of another family's tag, so check --family {}; ",
                self.seen_ids.len(),
                match probe {
                    Some(p) => format!("before anything else: {}", p.advice(opts.tag_id)),
                    None => "(tag36h11 unless the tag says otherwise) before anything else".into(),
                }
            )
        } else {
            String::new()
        };
        format!(
            "tag {} ({}) was detected but never accepted in {n} frames of {}: {family_hint}{}; {}",
            opts.tag_id,
            opts.family,
            path.display(),
            parts.join(", "),
            self.seen_ids_text()
        )
    }

    /// Where another tag of the tracked id lay: " at" its median place in pixels and on the
    /// floor.
    fn other_tag_place(&self) -> String {
        let others: Vec<&OtherTag> = self
            .records
            .iter()
            .filter_map(|r| r.other_tag.as_ref())
            .collect();
        let med = |f: &dyn Fn(&OtherTag) -> Option<f64>| {
            median(others.iter().filter_map(|o| f(o)).collect())
        };
        let (Some(u), Some(v)) = (med(&|o| Some(o.centre_px.x)), med(&|o| Some(o.centre_px.y)))
        else {
            return String::new();
        };
        let floor = match (
            med(&|o| o.floor_m.map(|p| p.x)),
            med(&|o| o.floor_m.map(|p| p.y)),
        ) {
            (Some(x), Some(y)) => format!(", floor ({x:.3}, {y:.3}) m"),
            _ => String::new(),
        };
        format!(" at pixel ({u:.0}, {v:.0}){floor} (median)")
    }

    /// The warning when another tag of the tracked id was seen: in how many frames, where it
    /// lay, and how many frames it left without a pose. A robot carries one tag of its id:
    /// fixes were taken only where the track's motion told the robot's apart.
    pub fn other_tag_warning(&self, tag_id: u32) -> Option<String> {
        let frames: Vec<usize> = self
            .records
            .iter()
            .filter(|r| r.other_tag.is_some())
            .map(|r| r.index)
            .collect();
        let (first, last) = (*frames.first()?, *frames.last()?);
        let refused = self
            .records
            .iter()
            .filter(|r| r.outcome == Outcome::Gap(GapReason::OtherTagOfId))
            .count();
        Some(format!(
            "another tag {tag_id} than the one tracked was seen in {} frames ({first} to {last}){}: a robot carries one tag of its id, so a fix was taken only where the track's motion told the robot's tag apart, and {refused} frames where it could not are gaps; {OTHER_TAG_ADVICE}",
            frames.len(),
            self.other_tag_place()
        ))
    }

    /// Describes the ids seen, for error messages ("ids seen: 3 (120 frames), 7 (2 frames)").
    pub fn seen_ids_text(&self) -> String {
        if self.seen_ids.is_empty() {
            return "no tag of this family was seen at all".into();
        }
        // The most seen first when there are many (false readings of another family give
        // dozens).
        let mut ids: Vec<(&u32, &usize)> = self.seen_ids.iter().collect();
        const SHOWN: usize = 8;
        if ids.len() > SHOWN {
            ids.sort_by(|a, b| b.1.cmp(a.1).then(a.0.cmp(b.0)));
        }
        let list: Vec<String> = ids
            .iter()
            .take(SHOWN)
            .map(|(id, n)| format!("{id} ({n} frames)"))
            .collect();
        let more = match ids.len().saturating_sub(SHOWN) {
            0 => String::new(),
            k => format!(" and {k} more"),
        };
        format!("ids seen: {}{more}", list.join(", "))
    }
}

/// What to do about a second tag of the tracked id.
const OTHER_TAG_ADVICE: &str =
    "remove or cover the other tag, or give the robot a tag of an id no other tag in view has (--tag-id)";

/// Distinct ids seen in a video of one robot, none accepted, that point at the wrong family.
const FALSE_FAMILY_IDS: usize = 4;

/// The video's frames must be the size the camera was calibrated at.
pub(crate) fn check_frame_size(info: &SourceInfo, camera: &CameraModel) -> Result<(), TrackError> {
    if (info.width, info.height) != (camera.width, camera.height) {
        return Err(TrackError::Mismatch(format!(
            "{} is {}×{} but the camera file describes {}×{} images: use the camera.json calibrated for this camera at this resolution",
            info.path.display(),
            info.width,
            info.height,
            camera.width,
            camera.height
        )));
    }
    Ok(())
}

/// Tracks a whole source: frames are decoded on one thread (and in parallel within a batch
/// where the source allows) and tracked on another, while the calling thread runs
/// `on_frame` for every frame in order (progress, overlays). Fails
/// if the frame size differs from the camera's, or if the tag never gives a
/// confident fix (naming the ids that were seen).
pub fn track_source(
    mut source: Box<dyn FrameSource>,
    camera: &CameraModel,
    floor: &FloorToCamera,
    opts: &TrackOptions,
    on_frame: &mut dyn FnMut(&Frame, &FrameRecord) -> Result<(), TrackError>,
) -> Result<TrackResult, TrackError> {
    let info = source.info().clone();
    check_frame_size(&info, camera)?;
    // Three threads: the decoder, the tracker, and this one (the caller's `on_frame`). The
    // tracker builds its detector while the first frames decode, and neither the tracker
    // nor the decoder waits for `on_frame` (overlays, progress).
    let (tx, rx) = mpsc::sync_channel::<Batch>(3);
    let (done_tx, done_rx) = mpsc::sync_channel::<Result<Vec<(Frame, FrameRecord)>, TrackError>>(3);
    let (mut records, (seen_ids, stopped_early), final_info, kept) =
        std::thread::scope(|scope| -> Result<_, TrackError> {
            let decoder = scope.spawn(move || decode_into(source.as_mut(), tx));
            let path = info.path.clone();
            let worker = scope.spawn(move || -> Option<(BTreeMap<u32, usize>, bool)> {
                let mut tracker = match Tracker::new(*camera, *floor, opts.clone()) {
                    Ok(t) => t,
                    Err(e) => {
                        let _ = done_tx.send(Err(e));
                        return None;
                    }
                };
                let mut previous: Option<Frame> = None;
                let mut repeated = RepeatedFixes::default();
                for batch in rx {
                    let out = batch.and_then(|batch| {
                        track_batch(
                            &mut tracker,
                            camera,
                            &path,
                            batch,
                            &mut previous,
                            &mut repeated,
                        )
                    });
                    let stop = !matches!(&out, Ok(b) if !b.is_empty());
                    if done_tx.send(out).is_err() || stop {
                        break;
                    }
                    if tracker.wrong_id_evident() {
                        return Some((tracker.seen_ids().clone(), true));
                    }
                }
                Some((tracker.seen_ids().clone(), false))
            });
            let mut records = Vec::with_capacity(info.frame_count.unwrap_or(0));
            let mut kept = KeptFrames::new(info.frame_count);
            let mut comb = crate::interlace::CombProbe::default();
            for batch in done_rx {
                let batch = batch?;
                if batch.is_empty() {
                    break;
                }
                for (frame, rec) in batch {
                    on_frame(&frame, &rec)?;
                    comb.offer(&frame, &rec);
                    kept.offer(frame, &rec);
                    records.push(rec);
                }
            }
            let seen_ids = worker
                .join()
                .map_err(|_| TrackError::bad_input(&info.path, "the tracker stopped on a panic"))?
                .unwrap_or_default();
            let final_info = decoder.join().map_err(|_| {
                TrackError::bad_input(&info.path, "the frame decoder stopped on a panic")
            })?;
            let mut final_info = final_info;
            final_info.interlace_comb = comb.ratio();
            Ok((records, seen_ids, final_info, kept.frames))
        })?;
    if records.is_empty() {
        return Err(TrackError::bad_input(&info.path, "contains no frames"));
    }
    if let Some(message) = time_restart(&records) {
        return Err(TrackError::bad_input(&info.path, message));
    }
    if let Some(ratio) = final_info
        .interlace_comb
        .filter(|r| *r >= crate::interlace::COMBED)
    {
        return Err(TrackError::bad_input(
            &info.path,
            crate::source::interlaced_advice(
                &info.path,
                &format!(
                    "the frames are interlaced, though the stream does not say so: around the moving tag, adjacent rows differ {ratio:.2} times as much as rows two apart (under 0.6 in a progressive frame), the comb of two fields woven together"
                ),
            ),
        ));
    }
    crate::repeats::place_repeated_images(&mut records);
    let (lost_in_file, dropped_by_motion) =
        crate::lost_frames::place_lost_frames_of(&mut records, &final_info);
    let result = TrackResult {
        tag_to_robot: opts.tag_to_robot,
        records,
        lost_in_file,
        dropped_by_motion,
        seen_ids,
        frame_size: (info.width, info.height),
        source: final_info,
    };
    if stopped_early {
        // No report nor timing warnings: the frames read are a video's start, not a run.
        return Err(TrackError::Mismatch(
            result.wrong_id_text(opts, &info.path, true),
        ));
    }
    if result.fixes().next().is_none() && result.seen_ids.is_empty() {
        // No tag of the family at all: a mirrored video (a camera's mirror setting) reads
        // none, whatever the id and family, and was blamed on them.
        let mirrored = crate::detect::read_mirrored(&kept, &opts.family)?;
        if !mirrored.is_empty() {
            let ids: Vec<String> = mirrored
                .iter()
                .map(|(id, n)| {
                    format!(
                        "{id} ({n} of {} frames)",
                        kept.len().min(crate::detect::FAMILY_PROBE_FRAMES)
                    )
                })
                .collect();
            return Err(TrackError::NoFix {
                message: format!(
                    "no {} tag was seen in {} frames of {}, but their mirror images show tag {}: the video is mirrored (a camera's or recording app's mirror or flip setting): turn the mirror setting off and record again, or unmirror this file (`ffmpeg -i IN -vf hflip OUT`); the camera must be calibrated from unmirrored images too",
                    opts.family,
                    result.records.len(),
                    info.path.display(),
                    ids.join(", ")
                ),
                result: Box::new(result),
            });
        }
    }
    if result.fixes().next().is_none() {
        // Only a run without a fix pays for reading its frames with the other families.
        let probe = if result.family_in_doubt(opts.tag_id) {
            Some(crate::detect::read_other_families(&kept, &opts.family)?)
        } else {
            None
        };
        return Err(TrackError::NoFix {
            message: result.no_fix_text(opts, &info.path, probe.as_ref()),
            result: Box::new(result),
        });
    }
    Ok(result)
}

/// Where the frames' time starts again: a step back of more than this many usual steps is no
/// repeated timestamp but a second recording's start.
const RESTART_STEPS: f64 = 3.0;

/// The error for frames whose time starts again partway (two recordings joined byte for
/// byte, as `cat a.ts b.ts` gives: MPEG-TS has no header to say where one ends). They gave
/// three contradictory messages, the last a trajectory row going back in time.
fn time_restart(records: &[FrameRecord]) -> Option<String> {
    let times: Vec<(usize, f64)> = records.iter().map(|r| (r.index, r.t_s)).collect();
    let step = crate::timing::find_drops(&times).0?;
    let w = times
        .windows(2)
        .find(|w| w[1].1 < w[0].1 - RESTART_STEPS * step)?;
    let ((before, t0), (at, t1)) = (w[0], w[1]);
    Some(format!(
        "the frames' time starts again at frame {at}, from {t0:.3} s back to {t1:.3} s after frame {before}: the file holds two recordings joined byte for byte (as `cat a.ts b.ts` makes), whose times cannot be told apart; track each recording from its own file, or join them with FFmpeg's concat demuxer, which times the second after the first (`ffmpeg -f concat -safe 0 -i list.txt -c copy joined.mp4`, list.txt naming each as file 'a.ts')"
    ))
}

/// A few frames without a fix, spread over the run, kept for [`crate::detect::read_other_families`]
/// should the run end without any fix (a wrong --family). A run with fixes keeps at most
/// these few copies.
struct KeptFrames {
    frames: Vec<GrayFrame>,
    /// Frames between two kept ones.
    stride: usize,
    last: Option<usize>,
}

impl KeptFrames {
    fn new(frame_count: Option<usize>) -> Self {
        let stride = frame_count
            .map(|n| n / crate::detect::FAMILY_PROBE_FRAMES)
            .unwrap_or(30)
            .max(1);
        Self {
            frames: Vec::new(),
            stride,
            last: None,
        }
    }

    fn offer(&mut self, frame: Frame, rec: &FrameRecord) {
        let useful = matches!(
            rec.outcome,
            Outcome::Gap(
                GapReason::NotDetected | GapReason::BadGeometry | GapReason::LowConfidence
            )
        );
        let due = self.last.is_none_or(|i| frame.index >= i + self.stride);
        if useful && due && self.frames.len() < crate::detect::FAMILY_PROBE_FRAMES {
            self.last = Some(frame.index);
            self.frames.push(frame.image);
        }
    }
}

/// Tracks one decoded batch: each frame's record, or a gap when the frame repeats the one
/// before it (same time or same pixels). `previous` is the last frame of the batch before.
fn track_batch(
    tracker: &mut Tracker,
    camera: &CameraModel,
    path: &std::path::Path,
    batch: Vec<Frame>,
    previous: &mut Option<Frame>,
    repeated: &mut RepeatedFixes,
) -> Result<Vec<(Frame, FrameRecord)>, TrackError> {
    let mut out: Vec<(Frame, FrameRecord)> = Vec::with_capacity(batch.len());
    for frame in batch {
        let before = out.last().map(|(f, _)| f).or(previous.as_ref());
        let unusable = unusable_frame(&frame, before, camera, path)?;
        if unusable == Some(GapReason::RepeatedImage) {
            tracker.seen_again();
        }
        let mut rec = match unusable {
            Some(reason) => FrameRecord {
                index: frame.index,
                t_s: frame.t_s,
                outcome: Outcome::Gap(reason),
                rejected: None,
                other_tag: None,
            },
            None => tracker.process(&frame)?,
        };
        repeated.screen(&mut rec);
        out.push((frame, rec));
    }
    if let Some((last, _)) = out.last() {
        *previous = Some(last.clone());
    }
    Ok(out)
}

/// Why `frame` cannot be tracked whatever its pixels show: its time repeats or goes back
/// from the frame `before` it, or its pixels repeat that frame's. A frame of another size
/// than the camera's is an error.
pub(crate) fn unusable_frame(
    frame: &Frame,
    before: Option<&Frame>,
    camera: &CameraModel,
    path: &std::path::Path,
) -> Result<Option<GapReason>, TrackError> {
    if (frame.image.width, frame.image.height) != (camera.width, camera.height) {
        return Err(TrackError::Mismatch(format!(
            "frame {} of {} is {}×{}, the camera file describes {}×{} images",
            frame.index,
            path.display(),
            frame.image.width,
            frame.image.height,
            camera.width,
            camera.height
        )));
    }
    Ok(match before {
        Some(b) if frame.t_s <= b.t_s => Some(GapReason::DuplicateTime),
        Some(b) if b.image.data == frame.image.data => Some(GapReason::RepeatedImage),
        _ => None,
    })
}

/// The last fix of a tag, to find a fix that repeats it (see [`same_pose`]).
#[derive(Debug, Default)]
pub(crate) struct RepeatedFixes {
    last: Option<Pose2>,
    /// Whether the last image not repeated showed no tag.
    last_blank: bool,
}

impl RepeatedFixes {
    /// Turns `rec` into a repeated-image gap when its fix equals the last fix before it (a
    /// run of repeated frames compares with the fix they repeat). An image repeating one
    /// where no tag was found is a still scene without the tag (100 black frames at a
    /// video's start were counted as frames where the tag was found, left out as repeats,
    /// and blamed on a damaged video): not detected.
    pub(crate) fn screen(&mut self, rec: &mut FrameRecord) {
        if let (Outcome::Fix(fix), Some(last)) = (&rec.outcome, self.last.as_ref()) {
            if same_pose(&fix.pose, last) {
                rec.outcome = Outcome::Gap(GapReason::RepeatedImage);
            }
        }
        if rec.outcome == Outcome::Gap(GapReason::RepeatedImage) && self.last_blank {
            rec.outcome = Outcome::Gap(GapReason::NotDetected);
        }
        match &rec.outcome {
            Outcome::Fix(fix) => self.last = Some(fix.pose),
            Outcome::Gap(GapReason::RepeatedImage) => {}
            _ => self.last = None,
        }
        self.last_blank = match rec.outcome {
            Outcome::Gap(GapReason::NotDetected) => true,
            Outcome::Gap(GapReason::RepeatedImage) => self.last_blank,
            _ => false,
        };
    }
}

/// Whether a fix repeats the previous frame's to rounding (1 nm, 1 nrad). The tag's pixels
/// of two real frames always differ by the sensor's noise, which moves a fix by micrometres
/// even when the robot stands still; an equal fix comes from the previous frame's pixels: a
/// damaged frame that FFmpeg's decoder completed from the frame before, or a camera that
/// repeated part of an image.
fn same_pose(a: &Pose2, b: &Pose2) -> bool {
    const SAME: f64 = 1e-9;
    (a.x_m - b.x_m).abs() < SAME
        && (a.y_m - b.y_m).abs() < SAME
        && odocal_core::wrap_angle(a.theta_rad - b.theta_rad).abs() < SAME
}

/// The median of `v` (none when empty).
pub(crate) fn median(mut v: Vec<f64>) -> Option<f64> {
    v.sort_by(f64::total_cmp);
    v.get(v.len() / 2).copied()
}

/// A tag side this far from --tag-size (a fraction) names the camera file first.
const CAMERA_FILE_SIDE_OFF: f64 = 0.10;

/// What to check when the corners fit no square of the tag's size: the side they do span,
/// when it is not `--tag-size`, names the size (or height) that would fit, since the
/// residual gate refuses a size a few percent off before the size check's wider bound.
fn bad_geometry_advice(side_m: Option<f64>, opts: &TrackOptions) -> String {
    let height = format!("--marker-height {} m", opts.marker_height_m);
    match side_m {
        // A print is scaled by a few percent, not a sixth: a size that far off is most often
        // another camera's calibration (its focal length scales every side), which a
        // --tag-size fitted to it only hides (101 mm RMS off, the tag read tilted).
        Some(side_m) if (side_m / opts.tag_size_m - 1.0).abs() > CAMERA_FILE_SIDE_OFF => format!(
            "the corners span a square of {:.1} mm on the marker plane (median), {:+.1} % from --tag-size {:.1} mm, further off than a print's scaling: check first that the camera file is this camera's, calibrated at this resolution, lens and zoom (a camera file of another camera scales every side so, as does a floor calibrated from a floor board whose squares were not calibrate's --square: recalibrate giving that board's side as --floor-square), then {height}; only if the tag's black square measures {:.1} mm, give --tag-size {:.4}",
            side_m * 1e3,
            100.0 * (side_m / opts.tag_size_m - 1.0),
            opts.tag_size_m * 1e3,
            side_m * 1e3,
            side_m
        ),
        Some(side_m) if (side_m / opts.tag_size_m - 1.0).abs() > TAG_SIDE_TOLERANCE => format!(
            "the corners span a square of {:.1} mm on the marker plane (median), {:+.1} % from --tag-size {:.1} mm: if the tag's black square measures that, give --tag-size {:.4}, else check {height} and the camera file",
            side_m * 1e3,
            100.0 * (side_m / opts.tag_size_m - 1.0),
            opts.tag_size_m * 1e3,
            side_m
        ),
        _ => format!(
            "check --tag-size {} m, {height} and the camera file",
            opts.tag_size_m
        ),
    }
}

fn fmt_opt(v: Option<f64>, digits: usize) -> String {
    v.map_or("–".into(), |x| format!("{x:.digits$}"))
}

#[cfg(test)]
mod tests {
    use super::{bad_geometry_advice, TrackOptions};

    /// Another camera's calibration (60° where the video's lens is wider) read the tag's
    /// side 16.9 % short, and the advice led with the --tag-size that would fit it, which
    /// gave a trajectory 101 mm RMS off; a print's few percent still lead with the size.
    #[test]
    fn a_side_far_off_names_the_camera_file_first() {
        let opts = TrackOptions::default();
        let far = bad_geometry_advice(Some(opts.tag_size_m * 0.831), &opts);
        assert!(
            far.contains("-16.9 % from --tag-size 80.0 mm, further off than a print's scaling: check first that the camera file is this camera's"),
            "{far}"
        );
        let near = bad_geometry_advice(Some(opts.tag_size_m * 0.97), &opts);
        assert!(
            near.contains("if the tag's black square measures that, give --tag-size 0.0776"),
            "{near}"
        );
    }
}
