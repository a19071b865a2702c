//! Whether the camera still looks at the floor it was calibrated over. The planar pose takes
//! the floor plane from the camera file, so a camera turned on its mount since (or an image
//! shifted or cropped after recording, which is the same to the mapping) moves every fix by
//! centimetres while each fix still fits its corners. A level square on the floor the file
//! describes reads level; a plane tilted against it does not: over a run the tilt against
//! the calibrated floor is known to a few hundredths of a degree.
//!
//! Each fix's tilt is read twice, each reading with its blind spot. solvePnP weighs the
//! square's side lengths, which a camera's tone curve or a motion smear shortens by a
//! fraction of a pixel (edges moved inward). The directions of the four edges alone keep no
//! such offset, but carry little of a tilt near the point under the camera, where a small
//! bias in them (a straight run keeps every edge at one angle to the pixel grid) reads as
//! degrees. A tilt is taken as far as both readings see it.
//!
//! A tag not quite flat on the robot tilts too, but its tilt turns with the robot, while a
//! camera's stays put on the floor: each fix's tilt is fitted as a part fixed in the floor
//! frame plus a part fixed in the robot's, which a run that turns tells apart.

use nalgebra::{Matrix2, Matrix4, Matrix4x2, Point2, Vector2, Vector4};
use odocal_calib::{CameraModel, FloorToCamera};
use odocal_core::{wrap_angle, Pose2};

use crate::pose::tag_model;
use crate::{TrackOptions, TrackResult};

/// Fixes sampled, evenly over the run.
const MAX_SAMPLES: usize = 600;

/// Fewer fixes than this say nothing about a tilt of a tenth of a degree.
const MIN_FIXES: usize = 30;

/// A tilt fixed in the floor frame beyond this is named, degrees: a camera turned so moves
/// the fixes under a 2.2 m ceiling by about 8 mm (0.1° is 3.8 mm). Floors are not planes
/// either, and the floor under the robot may slope against the calibrated one by about this.
pub const CAMERA_TILT_WARN_DEG: f64 = 0.2;

/// A tilt that the run's headings cannot assign to the camera or to the tag is named beyond
/// this, degrees: a tag glued a little off flat reads so, and does no harm.
pub const UNSEPARATED_TILT_WARN_DEG: f64 = 1.0;

/// A tag tilted on the robot is named when it turns the farthest fix's heading by more than
/// this, degrees: about three times a fix's heading σ from a 2.2 m ceiling.
pub const TAG_TILT_HEADING_WARN_DEG: f64 = 0.1;

/// A tag tilted on the robot is named only beyond this, degrees: a smear turns the edges a
/// little too, the faster side of a turning tag smeared more, and a camera's tone curve
/// moves a smeared edge the more the longer its smear (0.09° at 16 ms exposure and 0.5–0.7
/// m/s, corners smeared 4.5–6 px; 0.41° ± 0.07° so under a 2.2 tone curve).
pub const TAG_TILT_WARN_DEG: f64 = 0.75;

/// A tilt is the run's, not its noise, beyond this many standard errors.
const SIGNIFICANCE: f64 = 5.0;

/// The floor-fixed part is told apart from the tag's when its standard error is at most this
/// many times that of the plain mean tilt (runs that turn through a quarter turn or more).
const SEPARABLE_SE_RATIO: f64 = 3.0;

/// Fixes whose edges miss the fit by more than this many robust σ (RMS) are left out: a
/// corner caught on something else.
const OUTLIER_SIGMAS: f64 = 5.0;

/// Tilt step of the edges' derivatives, radians.
const TILT_STEP_RAD: f64 = 1e-4;

/// The tag's tilt against the calibrated floor over a run, in the floor frame (x, y: the
/// components of the tag's upward normal, radians for small tilts).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TagTilt {
    /// The tilt fixed in the floor frame (the camera's, or the floor's slope), radians.
    pub floor_fixed_rad: Vector2<f64>,
    /// Standard error of `floor_fixed_rad`'s length, radians.
    pub floor_fixed_se_rad: f64,
    /// Whether the run's headings told the floor-fixed tilt from the tag's on the robot
    /// (else `floor_fixed_rad` holds both).
    pub separated: bool,
    /// The tag's tilt on the robot, radians in the tag's frame (x along its heading); None
    /// when the run's headings do not tell it apart.
    pub tag_on_robot_rad: Option<Vector2<f64>>,
    /// Standard error of `tag_on_robot_rad`'s length, radians.
    pub tag_on_robot_se_rad: f64,
    /// The tilt on the robot given (`--tag-tilt`, [`TrackOptions::tag_tilt_rad`]), radians:
    /// the fixes' corners were taken off it, so `tag_on_robot_rad` is what it left.
    pub given_rad: Vector2<f64>,
    /// Fixes the fit used.
    pub fixes: usize,
    /// The side of the tag's black square, metres.
    pub tag_size_m: f64,
    /// The camera's height above the marker plane, metres.
    pub camera_above_marker_m: f64,
    /// The farthest fix from the point under the camera, metres.
    pub reach_m: f64,
}

impl TagTilt {
    /// The tilt of `result`'s fixes through `camera` over `floor`, the tag as `options` give
    /// it, from its edges' directions (None with fewer than 30 fixes to read).
    pub fn of(
        result: &TrackResult,
        camera: &CameraModel,
        floor: &FloorToCamera,
        options: &TrackOptions,
    ) -> Option<Self> {
        let (tag_size_m, marker_height_m) = (options.tag_size_m, options.marker_height_m);
        let fixes: Vec<_> = result.fixes().map(|(_, f)| f).collect();
        let step = fixes.len().div_ceil(MAX_SAMPLES).max(1);
        let sampled: Vec<_> = fixes.iter().step_by(step).collect();
        let edges: Vec<Sample> = sampled
            .iter()
            .filter_map(|f| {
                Sample::of(
                    f.pose,
                    &f.corners_px,
                    camera,
                    floor,
                    tag_size_m,
                    marker_height_m,
                )
            })
            .collect();
        let pnp: Vec<Sample> = sampled
            .iter()
            .filter_map(|f| Sample::of_pnp(f.pose, &f.corners_px, camera, floor, tag_size_m))
            .collect();
        let camera_in_floor = floor.0.inverse().translation.vector;
        let camera_above_marker_m = camera_in_floor.z - marker_height_m;
        let nadir = crate::marker_height::nadir(floor);
        let reach_m = fixes
            .iter()
            .map(|f| (f.pose.position() - nadir).norm())
            .fold(0.0, f64::max);
        // Each reading has its blind spot: solvePnP weighs the square's side lengths, which a
        // tone curve or a smear shortens by a fraction of a pixel (a level tag read 2.41°
        // tilted); the edges' directions alone carry little of a tilt near the point under
        // the camera, where a small bias in them (a straight run keeps every edge at one
        // angle to the pixel grid) read 2.37°. A tilt is taken as far as both see it.
        let by_edges = RunFit::of(&edges)?;
        let by_pnp = RunFit::of(&pnp)?;
        let (all, separated) = match (by_edges.both, by_pnp.both) {
            (Some(a), Some(b)) => (a.least(&b), true),
            _ => (by_edges.mean.least(&by_pnp.mean), false),
        };
        Some(Self {
            floor_fixed_rad: all.floor_rad,
            floor_fixed_se_rad: all.floor_se_rad,
            separated,
            tag_on_robot_rad: separated.then_some(all.robot_rad),
            tag_on_robot_se_rad: if separated {
                all.robot_se_rad
            } else {
                f64::INFINITY
            },
            given_rad: options.tag_tilt_rad,
            fixes: by_edges.fixes.min(by_pnp.fixes),
            tag_size_m,
            camera_above_marker_m,
            reach_m,
        })
    }

    /// The warnings the tilt gives: a camera that no longer looks at the floor it was
    /// calibrated over, and a tag tilted on the robot enough to turn the headings.
    pub fn warnings(&self) -> Vec<String> {
        [self.camera_warning(), self.tag_warning()]
            .into_iter()
            .flatten()
            .collect()
    }

    /// How far a tag tilted on the robot turns the heading at the farthest fix, radians: its
    /// raised edge sits nearer the camera and moves outward in the image by the parallax, its
    /// low edge inward.
    pub fn heading_bias_rad(&self) -> Option<f64> {
        let tilt = self.tag_on_robot_rad?.norm();
        Some(tilt * self.reach_m / self.camera_above_marker_m.max(1e-3))
    }

    /// A warning when the tag on the robot is tilted enough to turn the farthest fix's heading
    /// by more than [`TAG_TILT_HEADING_WARN_DEG`].
    fn tag_warning(&self) -> Option<String> {
        let on_robot = self.tag_on_robot_rad?;
        let bias_deg = self.heading_bias_rad()?.to_degrees();
        if bias_deg <= TAG_TILT_HEADING_WARN_DEG
            || on_robot.norm().to_degrees() <= TAG_TILT_WARN_DEG
            || on_robot.norm() <= SIGNIFICANCE * self.tag_on_robot_se_rad
        {
            return None;
        }
        let subject = if self.given_rad == Vector2::zeros() {
            "the tag"
        } else {
            "the tag, taken off the --tag-tilt given,"
        };
        // The normal's lean along an axis is the plate's fall towards it (sin against tan:
        // 0.5 % apart at 10°); what the fixes show adds to what was given.
        let total_rad = self.given_rad + on_robot.map(f64::asin);
        let advised_deg = total_rad.map(f64::to_degrees);
        let shim = format!(
            "a shim of about {:.1} mm under {} of the {:.0} mm plate's black square",
            total_rad.norm().tan() * self.tag_size_m * 1e3,
            lowest_edge(&total_rad),
            self.tag_size_m * 1e3,
        );
        Some(format!(
            "{subject} is tilted {:.2}° ± {:.3}° on the robot, lowest at {} ({} fixes, by solvePnP and by the edges' directions; the run's turns set it apart from a tilt of the camera or floor, {:.2}°): the raised edge sits nearer the camera and moves outward in the image, which turns the tracked heading by up to {bias_deg:.2}° at the farthest fix ({:.2} m from the point under the camera) and not in its σ, while the positions hold; give --tag-tilt {:.2},{:.2} (degrees the plate falls toward the tag's x axis, its heading, and toward its y axis) so each corner is met at its own height, or lay the tag flat on the robot ({shim})",
            on_robot.norm().to_degrees(),
            self.tag_on_robot_se_rad.to_degrees(),
            lowest_edge(&on_robot),
            self.fixes,
            self.floor_fixed_rad.norm().to_degrees(),
            self.reach_m,
            advised_deg.x,
            advised_deg.y,
        ))
    }

    /// A warning when the floor-fixed tilt says the camera no longer looks at the floor it was
    /// calibrated over (or, unseparated, when the tag or the camera is tilted beyond a degree).
    pub(crate) fn camera_warning(&self) -> Option<String> {
        let tilt_rad = self.floor_fixed_rad.norm();
        let tilt_deg = tilt_rad.to_degrees();
        let limit_deg = if self.separated {
            CAMERA_TILT_WARN_DEG
        } else {
            UNSEPARATED_TILT_WARN_DEG
        };
        if tilt_deg <= limit_deg || tilt_rad <= SIGNIFICANCE * self.floor_fixed_se_rad {
            return None;
        }
        // The floor frame's direction the tag's normal leans towards.
        let towards_deg = self
            .floor_fixed_rad
            .y
            .atan2(self.floor_fixed_rad.x)
            .to_degrees();
        let shift_mm = self.camera_above_marker_m * tilt_rad.tan() * 1e3;
        // A camera turned by δ maps a floor point at angle θ off the nadir to θ + δ: distances
        // there scale by about 1 + 2 tan θ · δ.
        let scale_pct = 200.0 * self.reach_m / self.camera_above_marker_m.max(1e-3) * tilt_rad;
        let consequence = format!(
            "every fix is about {shift_mm:.0} mm off and distances are scaled by up to {scale_pct:.2} % at the farthest fix ({:.2} m from the point under the camera)",
            self.reach_m
        );
        // A camera's mount turns by a fraction of a degree; a tilt moving every fix by
        // centimetres is as likely a camera file of another camera, whose tag side a
        // --tag-size was fitted to (1.10°, 41 mm: 101 mm RMS off the truth).
        let consequence = if shift_mm >= OTHER_CAMERA_SHIFT_MM {
            format!("{consequence}. A tilt that large is as often a camera file of another camera (with a --tag-size fitted to the side it reads): check first that the camera file is this camera's; the trajectory is not to be trusted until then")
        } else {
            consequence
        };
        // A tilt given with --tag-tilt was taken off the corners: a wrong one reads here.
        let given_clause = if self.given_rad == Vector2::zeros() {
            (String::new(), String::new())
        } else {
            let g = self.given_rad.map(f64::to_degrees);
            (
                ", taken off the --tag-tilt given,".to_string(),
                format!(
                    " as --tag-tilt {:.2},{:.2} says it lies (track without it to see the tilt the fixes show)",
                    g.x, g.y
                ),
            )
        };
        Some(match self.separated {
            true => format!(
                "the tag reads tilted {tilt_deg:.2}° ± {:.3}° against the camera file's floor plane (leaning towards {towards_deg:.0}° in the floor frame) whichever way the robot heads ({} fixes, by solvePnP and by the edges' directions; a tilt of the tag on the robot turns with it and is set apart): the camera has turned on its mount since its floor was calibrated, the image was shifted or cropped after recording, or the floor where the robot drives slopes that much against the floor calibrated; if the camera turned, {consequence}: calibrate the floor again with the camera as it is now (`odocal calibrate --floor`, the floor board where the robot drives; for an arena camera, then `odocal arena` again)",
                self.floor_fixed_se_rad.to_degrees(),
                self.fixes,
            ),
            false => format!(
                "the tag{} reads tilted {tilt_deg:.2}° ± {:.3}° against the camera file's floor plane (leaning towards {towards_deg:.0}° in the floor frame; {} fixes, by solvePnP and by the edges' directions), and the run's headings do not tell a tag off flat on the robot from a camera turned since its floor was calibrated: check that the tag lies flat on the robot{}; if it does, the camera has turned and {consequence}: calibrate the floor again with the camera as it is now (`odocal calibrate --floor`; for an arena camera, then `odocal arena` again). A run in which the robot turns through a quarter turn or more tells the two apart",
                given_clause.0,
                self.floor_fixed_se_rad.to_degrees(),
                self.fixes,
                given_clause.1,
            ),
        })
    }
}

/// The edge of the tag a lean `tilt` (the normal's, or the plate's fall, in the tag's frame,
/// x along its heading) lowers.
fn lowest_edge(tilt: &Vector2<f64>) -> &'static str {
    match tilt.y.atan2(tilt.x).to_degrees() {
        d if d.abs() <= 45.0 => "the edge its heading points to",
        d if d.abs() >= 135.0 => "the edge behind its heading",
        d if d > 0.0 => "its left edge (its heading pointing ahead)",
        _ => "its right edge (its heading pointing ahead)",
    }
}

/// A fitted tilt: the floor-fixed part, its standard error, and the robot-fixed part (zero
/// in a fit without it).
#[derive(Debug, Clone, Copy)]
struct TiltFit {
    floor_rad: Vector2<f64>,
    floor_se_rad: f64,
    robot_rad: Vector2<f64>,
    robot_se_rad: f64,
}

impl TiltFit {
    /// The tilt in the floor frame of a tag heading `heading_rad`.
    fn predict(&self, heading_rad: f64) -> Vector2<f64> {
        self.floor_rad + rotation(heading_rad) * self.robot_rad
    }
}

/// A floor-fixed tilt that moves every fix this far, millimetres, names another camera's file
/// among its causes first.
const OTHER_CAMERA_SHIFT_MM: f64 = 25.0;

/// The least turn of the robot over a run, radians, for the tilt on the robot to be told from
/// the floor-fixed one.
const MIN_SEPARATING_TURN_RAD: f64 = 0.35;

/// The angle the samples' headings span: the full turn less the widest gap between them.
fn heading_span_rad(samples: &[Sample]) -> f64 {
    let tau = std::f64::consts::TAU;
    let mut h: Vec<f64> = samples
        .iter()
        .map(|s| s.heading_rad.rem_euclid(tau))
        .collect();
    h.sort_by(f64::total_cmp);
    let (Some(&first), Some(&last)) = (h.first(), h.last()) else {
        return 0.0;
    };
    let widest = h
        .windows(2)
        .map(|w| w[1] - w[0])
        .fold(first + tau - last, f64::max);
    tau - widest
}

/// A run's tilt fitted from one kind of reading: the plain mean, and the floor-fixed and
/// tag-fixed parts when the run's headings tell them apart.
struct RunFit {
    mean: TiltFit,
    both: Option<TiltFit>,
    fixes: usize,
}

impl RunFit {
    /// None with fewer than [`MIN_FIXES`] readings.
    fn of(samples: &[Sample]) -> Option<Self> {
        if samples.len() < MIN_FIXES {
            return None;
        }
        // A first fit's residuals give the noise and the fixes whose corners went astray (or
        // whose solvePnP took the mirror solution).
        let first = fit(samples, true, None).or_else(|| fit(samples, false, None))?;
        let spread = robust_sigma(samples, &first);
        let kept: Vec<Sample> = samples
            .iter()
            .filter(|s| s.misfit_rad(&first) <= OUTLIER_SIGMAS * spread)
            .copied()
            .collect();
        if kept.len() < MIN_FIXES {
            return None;
        }
        // Neighbouring fixes share their errors (a smear that changes with the robot's speed,
        // a rolling shutter, a codec's blocks): counted as independent, they made a level tag
        // read tilted 2.84° ± 0.51° on a realistic camera. The noise is widened by what the
        // residuals' correlation from one fix to the next says a mean of them is worth.
        let spread = spread * correlation_inflation(&kept, &first);
        let mean = fit(&kept, false, Some(spread))?;
        // Identical fixes (a robot standing still, its H.264 frames decoded alike) leave no
        // spread to judge the fit by: a still robot's 0.49° was split off "whichever way the
        // robot heads" though it never turned. The headings must span a turn first.
        let both = (heading_span_rad(&kept) >= MIN_SEPARATING_TURN_RAD)
            .then(|| fit(&kept, true, Some(spread)))
            .flatten()
            .filter(|b| b.floor_se_rad <= SEPARABLE_SE_RATIO * mean.floor_se_rad);
        Some(Self {
            mean,
            both,
            fixes: kept.len(),
        })
    }
}

impl TiltFit {
    /// Each part as far as both fits see it: the smaller of the two, with its standard error.
    fn least(&self, other: &TiltFit) -> TiltFit {
        let (floor_rad, floor_se_rad) = if self.floor_rad.norm() <= other.floor_rad.norm() {
            (self.floor_rad, self.floor_se_rad)
        } else {
            (other.floor_rad, other.floor_se_rad)
        };
        let (robot_rad, robot_se_rad) = if self.robot_rad.norm() <= other.robot_rad.norm() {
            (self.robot_rad, self.robot_se_rad)
        } else {
            (other.robot_rad, other.robot_se_rad)
        };
        TiltFit {
            floor_rad,
            floor_se_rad,
            robot_rad,
            robot_se_rad,
        }
    }
}

fn rotation(heading_rad: f64) -> Matrix2<f64> {
    let (s, c) = heading_rad.sin_cos();
    Matrix2::new(c, -s, s, c)
}

/// One fix: how its four edges turn from the directions a level square at its pose would
/// show (radians, less their mean, which the pose's heading takes up), how they turn with
/// a tilt of the tag's plane (its upward normal's floor-frame x and y, radians), and the
/// tag's heading.
#[derive(Debug, Clone, Copy)]
struct Sample {
    turned_rad: Vector4<f64>,
    per_tilt: Matrix4x2<f64>,
    heading_rad: f64,
    /// Readings in `turned_rad` (the rest are zero), and the degrees of freedom they keep.
    rows: usize,
    dof: f64,
}

impl Sample {
    fn of(
        pose: Pose2,
        corners_px: &[Point2<f64>; 4],
        camera: &CameraModel,
        floor: &FloorToCamera,
        tag_size_m: f64,
        marker_height_m: f64,
    ) -> Option<Self> {
        let on_floor = tag_model(tag_size_m).map(|m| pose.transform_point(&m));
        let centre = pose.position();
        // The edges' directions of the square at `pose` on a plane tilted by `tilt`: the
        // plane falls the way its normal leans.
        let edges = |tilt: Vector2<f64>| -> Option<Vector4<f64>> {
            let mut px = [Point2::origin(); 4];
            for (p, q) in px.iter_mut().zip(&on_floor) {
                let above_m = -tilt.dot(&(q - centre));
                *p = camera.floor_to_pixel(floor, q, marker_height_m + above_m)?;
            }
            Some(directions(&px))
        };
        let level = edges(Vector2::zeros())?;
        let seen = directions(corners_px);
        let turned_rad = centred(seen.zip_map(&level, |a, b| wrap_angle(a - b)));
        let mut per_tilt = Matrix4x2::zeros();
        for k in 0..2 {
            let mut step = Vector2::zeros();
            step[k] = TILT_STEP_RAD;
            let d = edges(step)?.zip_map(&edges(-step)?, |a, b| wrap_angle(a - b));
            per_tilt.set_column(k, &centred(d / (2.0 * TILT_STEP_RAD)));
        }
        let ok = turned_rad
            .iter()
            .chain(per_tilt.iter())
            .all(|v| v.is_finite())
            && pose.theta_rad.is_finite();
        ok.then_some(Self {
            turned_rad,
            per_tilt,
            heading_rad: pose.theta_rad,
            rows: 4,
            dof: 3.0,
        })
    }

    /// One fix read by solvePnP (IPPE_SQUARE): the tag's upward normal's floor-frame x and y.
    fn of_pnp(
        pose: Pose2,
        corners_px: &[Point2<f64>; 4],
        camera: &CameraModel,
        floor: &FloorToCamera,
        tag_size_m: f64,
    ) -> Option<Self> {
        let tag = crate::pose::pnp_tag_to_floor(camera, floor, corners_px, tag_size_m).ok()?;
        let n = tag.rotation * nalgebra::Vector3::z();
        // The tag faces the camera: its normal is taken pointing up.
        let n = if n.z < 0.0 { -n } else { n };
        let ok = n.x.is_finite() && n.y.is_finite() && pose.theta_rad.is_finite();
        ok.then_some(Self {
            turned_rad: Vector4::new(n.x, n.y, 0.0, 0.0),
            per_tilt: Matrix4x2::new(1.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0),
            heading_rad: pose.theta_rad,
            rows: 2,
            dof: 2.0,
        })
    }

    /// RMS of the readings left by `fit`, radians.
    fn misfit_rad(&self, fit: &TiltFit) -> f64 {
        let left = self.turned_rad - self.per_tilt * fit.predict(self.heading_rad);
        (left.norm_squared() / self.dof).sqrt()
    }
}

/// The directions of a quadrilateral's four edges, radians.
fn directions(corners: &[Point2<f64>; 4]) -> Vector4<f64> {
    Vector4::from_fn(|j, _| {
        let d = corners[(j + 1) % 4] - corners[j];
        d.y.atan2(d.x)
    })
}

/// `v` less its mean.
fn centred(v: Vector4<f64>) -> Vector4<f64> {
    v.add_scalar(-v.mean())
}

/// Least squares of `turned = per_tilt · (floor + R(heading) robot)` (or without the robot
/// part), the edges' noise `sigma` radians (1 without it; then the standard errors are not
/// used).
fn fit(samples: &[Sample], with_robot: bool, sigma: Option<f64>) -> Option<TiltFit> {
    let w = sigma.unwrap_or(1.0);
    let mut normal = Matrix4::<f64>::zeros();
    let mut rhs = Vector4::<f64>::zeros();
    for s in samples {
        let r = if with_robot {
            rotation(s.heading_rad)
        } else {
            Matrix2::zeros()
        };
        let mut a = nalgebra::Matrix4::<f64>::zeros();
        a.fixed_view_mut::<4, 2>(0, 0).copy_from(&s.per_tilt);
        a.fixed_view_mut::<4, 2>(0, 2).copy_from(&(s.per_tilt * r));
        let a = a / w;
        normal += a.transpose() * a;
        rhs += a.transpose() * (s.turned_rad / w);
    }
    if !with_robot {
        // The robot part is not in the model: pin it at zero.
        normal[(2, 2)] = 1.0;
        normal[(3, 3)] = 1.0;
    }
    let cov = normal.try_inverse()?;
    let p = cov * rhs;
    let floor_rad = Vector2::new(p[0], p[1]);
    let robot_rad = Vector2::new(p[2], p[3]);
    let out = TiltFit {
        floor_rad,
        floor_se_rad: se_along(&cov.fixed_view::<2, 2>(0, 0).into_owned(), &floor_rad),
        robot_rad,
        robot_se_rad: se_along(&cov.fixed_view::<2, 2>(2, 2).into_owned(), &robot_rad),
    };
    out.floor_rad
        .iter()
        .chain(out.robot_rad.iter())
        .all(|v| v.is_finite())
        .then_some(out)
}

/// The standard error of a tilt along its own direction, which is what its length's is.
fn se_along(cov: &Matrix2<f64>, tilt: &Vector2<f64>) -> f64 {
    let dir = if tilt.norm() > 0.0 {
        tilt.normalize()
    } else {
        Vector2::new(1.0, 0.0)
    };
    (dir.transpose() * cov * dir)[0].max(0.0).sqrt()
}

/// How much wider a mean of the samples' residuals under `fit` is than if they were
/// independent: √((1 + ρ) / (1 − ρ)) for the correlation ρ of each sample's residuals with
/// the next's (an AR(1) series' variance of the mean); 1 when they do not follow each other.
fn correlation_inflation(samples: &[Sample], fit: &TiltFit) -> f64 {
    let left: Vec<Vector4<f64>> = samples
        .iter()
        .map(|s| s.turned_rad - s.per_tilt * fit.predict(s.heading_rad))
        .collect();
    let together: f64 = left.windows(2).map(|w| w[0].dot(&w[1])).sum();
    let alone: f64 = left.iter().map(|r| r.norm_squared()).sum();
    if !(alone > 0.0 && together.is_finite()) {
        return 1.0;
    }
    let rho = (together / alone).clamp(0.0, MAX_CORRELATION);
    ((1.0 + rho) / (1.0 - rho)).sqrt()
}

/// The largest correlation [`correlation_inflation`] takes from one fix to the next: beyond
/// it a run is one long drift, whose worth no neighbour-to-neighbour figure says.
const MAX_CORRELATION: f64 = 0.95;

/// The readings' noise from the median absolute residual `fit` leaves, radians (each fix's
/// four edge turns less their mean keep three of four degrees of freedom).
fn robust_sigma(samples: &[Sample], fit: &TiltFit) -> f64 {
    let mut r: Vec<f64> = samples
        .iter()
        .flat_map(|s| {
            let left = s.turned_rad - s.per_tilt * fit.predict(s.heading_rad);
            let scale = (s.rows as f64 / s.dof).sqrt();
            left.iter()
                .take(s.rows)
                .map(|v| v.abs() * scale)
                .collect::<Vec<_>>()
        })
        .collect();
    if r.is_empty() {
        return f64::NAN;
    }
    r.sort_by(f64::total_cmp);
    // A floor so the weights stay finite on noiseless corners.
    (1.4826 * r[r.len() / 2]).max(1e-9)
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;
    use rand_distr::{Distribution, Normal};

    /// Edge turns of a camera turned by `camera` and a tag tilted by `tag` (radians), read at
    /// the given headings with 0.05° of noise per edge; each fix's edges turn with the tilt
    /// as a square's do 1 m off the point under a 2 m high camera.
    fn samples(camera: Vector2<f64>, tag: Vector2<f64>, headings: &[f64]) -> Vec<Sample> {
        let mut rng = ChaCha8Rng::seed_from_u64(7);
        let noise = Normal::new(0.0, 0.05f64.to_radians()).unwrap();
        let truth = TiltFit {
            floor_rad: camera,
            floor_se_rad: 0.0,
            robot_rad: tag,
            robot_se_rad: 0.0,
        };
        headings
            .iter()
            .map(|&th| {
                let per_tilt = Matrix4x2::new(0.5, 0.1, -0.1, 0.5, -0.5, -0.1, 0.1, -0.5);
                let n = centred(Vector4::from_fn(|_, _| noise.sample(&mut rng)));
                Sample {
                    turned_rad: per_tilt * truth.predict(th) + n,
                    per_tilt,
                    heading_rad: th,
                    rows: 4,
                    dof: 3.0,
                }
            })
            .collect()
    }

    /// A tilt moving every fix by centimetres names another camera's file; the 0.3° of a
    /// camera turned on its mount (10 mm) does not.
    #[test]
    fn a_large_floor_tilt_names_another_cameras_file() {
        let tilt = |deg: f64| TagTilt {
            floor_fixed_rad: Vector2::new(deg.to_radians(), 0.0),
            floor_fixed_se_rad: 1e-4,
            separated: true,
            tag_on_robot_rad: None,
            tag_on_robot_se_rad: f64::INFINITY,
            given_rad: Vector2::zeros(),
            fixes: 89,
            tag_size_m: 0.0665,
            camera_above_marker_m: 2.1,
            reach_m: 0.72,
        };
        let large = tilt(1.1).warnings().join("\n");
        assert!(
            large.contains("every fix is about 40 mm off")
                && large.contains("check first that the camera file is this camera's"),
            "{large}"
        );
        let small = tilt(0.3).warnings().join("\n");
        assert!(
            small.contains("every fix is about 11 mm off") && !small.contains("check first"),
            "{small}"
        );
    }

    /// A robot standing still: two readings repeated over the run (the frames of a still
    /// scene H.264 decodes nearly alike), their headings apart by the fixes' noise alone.
    #[test]
    fn a_still_robot_does_not_set_the_tilts_apart() {
        let (camera, tag) = (Vector2::new(0.004, 0.0), Vector2::new(0.0, 0.006));
        let headings = [0.4, 0.4 + 1e-6];
        let distinct = samples(camera, tag, &headings);
        let still: Vec<Sample> = (0..90).map(|i| distinct[i % 2]).collect();
        let run = RunFit::of(&still).unwrap();
        assert!(run.both.is_none(), "{:?}", run.both);
    }

    /// Errors that drift from fix to fix (an AR(1) series, correlation 0.9, σ 0.05° per
    /// edge) over a level tag and an upright camera: counted as independent fixes, their
    /// standard error was three times too small and a drift read as a tilt; widened by their
    /// correlation, the tilt stays within its significance, and white noise is not widened.
    #[test]
    fn fixes_whose_errors_drift_together_are_worth_fewer() {
        let turning: Vec<f64> = (0..300).map(|i| f64::from(i) * 0.021).collect();
        let mut drifting = samples(Vector2::zeros(), Vector2::zeros(), &turning);
        let mut rng = ChaCha8Rng::seed_from_u64(11);
        let rho: f64 = 0.9;
        let step = Normal::new(0.0, 0.05f64.to_radians() * (1.0 - rho * rho).sqrt()).unwrap();
        let mut e = Vector4::zeros();
        for s in &mut drifting {
            e = e * rho + Vector4::from_fn(|_, _| step.sample(&mut rng));
            s.turned_rad = centred(e);
        }
        let first = fit(&drifting, true, None).unwrap();
        let widened = correlation_inflation(&drifting, &first);
        assert!((3.0..5.5).contains(&widened), "{widened}");
        let run = RunFit::of(&drifting).unwrap();
        let both = run.both.unwrap();
        assert!(
            both.robot_rad.norm() <= SIGNIFICANCE * both.robot_se_rad
                && both.floor_rad.norm() <= SIGNIFICANCE * both.floor_se_rad,
            "{both:?}"
        );
        let white = samples(Vector2::zeros(), Vector2::zeros(), &turning);
        let first = fit(&white, true, None).unwrap();
        assert!(correlation_inflation(&white, &first) < 1.2);
    }

    #[test]
    fn a_turning_run_sets_the_tags_tilt_apart_from_the_cameras() {
        let camera = Vector2::new(0.3f64.to_radians(), 0.0);
        let tag = Vector2::new(-1.5f64.to_radians(), 0.0);
        let turning: Vec<f64> = (0..300).map(|i| f64::from(i) * 0.021).collect();
        let s = samples(camera, tag, &turning);
        let sigma = robust_sigma(&s, &fit(&s, true, None).unwrap());
        assert!((sigma.to_degrees() / 0.05 - 1.0).abs() < 0.15, "{sigma}");
        let mean = fit(&s, false, Some(sigma)).unwrap();
        let both = fit(&s, true, Some(sigma)).unwrap();
        assert!(both.floor_se_rad <= SEPARABLE_SE_RATIO * mean.floor_se_rad);
        let se = both.floor_se_rad;
        assert!((both.floor_rad - camera).norm() < 4.0 * se, "{both:?}");
        assert!(
            (both.robot_rad - tag).norm() < 4.0 * both.robot_se_rad,
            "{both:?}"
        );
        // 0.05° on each edge over 300 fixes: the camera's part to about 0.01°.
        assert!(se.to_degrees() < 0.012, "{}", se.to_degrees());
        // The plain mean cannot: the tag's tilt turns through every heading and averages out
        // only over whole turns.
        let straight: Vec<f64> = (0..300).map(|i| 0.4 + f64::from(i) * 1e-4).collect();
        let s = samples(camera, tag, &straight);
        let sigma = robust_sigma(&s, &fit(&s, false, None).unwrap());
        let mean = fit(&s, false, Some(sigma)).unwrap();
        let both = fit(&s, true, Some(sigma));
        assert!(
            both.is_none_or(|b| b.floor_se_rad > SEPARABLE_SE_RATIO * mean.floor_se_rad),
            "{both:?}"
        );
        // What a straight run reads is the sum of the two.
        let sum = camera + nalgebra::Rotation2::new(0.415) * tag;
        assert!(
            (mean.floor_rad - sum).norm() < 4.0 * mean.floor_se_rad,
            "{mean:?}"
        );
    }

    /// The edges' directions alone carry the tilt: a square whose every edge is moved inward,
    /// as a tone curve or a smear moves a black square's, turns no edge; a tilted plane does.
    #[test]
    fn edges_moved_inward_turn_no_edge_and_a_tilt_does() {
        let mut camera = CameraModel::from_hfov(1280, 720, 70.0);
        camera.distortion = odocal_calib::Distortion::pinhole5(-0.1, 0.04, 3e-4, -2e-4, 0.0);
        let down = nalgebra::UnitQuaternion::from_axis_angle(
            &nalgebra::Vector3::x_axis(),
            std::f64::consts::PI,
        );
        let at = nalgebra::Vector3::new(0.1, -0.2, 2.2);
        let floor = FloorToCamera(nalgebra::Isometry3::from_parts(
            nalgebra::Translation3::from(-(down * at)),
            down,
        ));
        let pose = odocal_core::Pose2::new(0.9, 0.4, 0.6);
        let level = tag_model(0.08).map(|m| {
            camera
                .floor_to_pixel(&floor, &pose.transform_point(&m), 0.08)
                .unwrap()
        });
        // Each edge line moved 0.3 px toward the square's centre; the corners are where the
        // moved lines meet.
        let centre = level.iter().fold(Vector2::zeros(), |s, p| s + p.coords) / 4.0;
        let lines: Vec<(Vector2<f64>, Vector2<f64>)> = (0..4)
            .map(|j| {
                let (a, b) = (level[j].coords, level[(j + 1) % 4].coords);
                let along = (b - a).normalize();
                let mut inward = Vector2::new(-along.y, along.x);
                if inward.dot(&(centre - a)) < 0.0 {
                    inward = -inward;
                }
                (a + inward * 0.3, along)
            })
            .collect();
        let shrunk: [Point2<f64>; 4] = std::array::from_fn(|k| {
            // Corner k is where edge k−1 (ending there) meets edge k (starting there).
            let (p, u) = lines[(k + 3) % 4];
            let (q, v) = lines[k];
            let t = Matrix2::from_columns(&[u, -v]).try_inverse().unwrap() * (q - p);
            Point2::from(p + u * t[0])
        });
        assert!((shrunk[0] - level[0]).norm() > 0.3, "{shrunk:?}");
        let s = Sample::of(pose, &shrunk, &camera, &floor, 0.08, 0.08).unwrap();
        assert!(s.turned_rad.norm() < 1e-4, "{s:?}");
        // A plane tilted 0.5°: its edges turn by what the derivatives foretell.
        let tilt = Vector2::new(0.0, 0.5f64.to_radians());
        let tilted = tag_model(0.08).map(|m| {
            let q = pose.transform_point(&m);
            let above_m = -tilt.dot(&(q - pose.position()));
            camera.floor_to_pixel(&floor, &q, 0.08 + above_m).unwrap()
        });
        let s = Sample::of(pose, &tilted, &camera, &floor, 0.08, 0.08).unwrap();
        assert!(s.turned_rad.norm() > 1e-3, "{s:?}");
        assert!(
            (s.turned_rad - s.per_tilt * tilt).norm() < 0.02 * s.turned_rad.norm(),
            "{s:?}"
        );
    }
}
